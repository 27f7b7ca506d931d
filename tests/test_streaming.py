"""The streaming ``predict()``/``update()`` of `RecursiveLeastSquares`.

Each call validates, makes one compiled call into new arrays and commits, so:
streaming equals ``batch_filter`` bit for bit in every configuration, the
time update is the textbook one, arrays handed out are never written later,
a call that fails leaves every attribute as it was, and copies carry
the state. ``_streaming`` itself only loads the kernels lazily.
"""

import copy
import pickle
import warnings

import _reference as ref
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import RecursiveLeastSquares
from rlsfilt.filters import _streaming

STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H")
COUNTERS = ("n_updates", "n_gated", "n_capped", "gated", "lam_t")
N = 80

CONFIGS = {
    "exponential": lambda: RecursiveLeastSquares(4, lam=0.95),
    "lam1": lambda: RecursiveLeastSquares(4),
    "Q": lambda: RecursiveLeastSquares(4, lam=0.98, Q=1e-4),
    "directional-gate": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="directional",
                                                      gate=3.0),
    "constant_trace": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="constant_trace"),
    "efra": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="efra"),
    "variable": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="variable"),
    "two-outputs": lambda: RecursiveLeastSquares(4, dim_z=2, lam=0.97),
    "three-outputs-Q": lambda: RecursiveLeastSquares(4, dim_z=3, lam=0.97, Q=1e-5),
    "constrained": lambda: RecursiveLeastSquares(4, lam=0.97, Q=1e-6).constrain(
        [1.0, 0.0, 1.0, 0.0], 0.5),
    "windup-cap": lambda: RecursiveLeastSquares(4, lam=0.9, P0=1.0,
                                                forgetting_params={"spread_max": 10.0}),
}


def _record(rng, dim_z=1):
    """Regressors with a held stretch (the windup cap acts there), an outlier and
    missing samples."""
    Hs = rng.standard_normal((N, 4))
    Hs[30:50] = Hs[29]
    zs = Hs @ rng.standard_normal((4, dim_z)) + 0.05 * rng.standard_normal((N, dim_z))
    zs[60] += 50.0
    zs[[10, 45]] = np.nan
    return Hs, (zs[:, 0] if dim_z == 1 else zs)


def _z(zs, k):
    return float(zs[k]) if np.ndim(zs) == 1 else zs[k]


def _same(a, b):
    for name in STATE:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in COUNTERS:
        assert getattr(a, name) == getattr(b, name), name


def _snapshot(f):
    return {name: np.array(getattr(f, name), copy=True) for name in STATE}


@pytest.fixture(params=sorted(CONFIGS))
def config(request):
    return request.param


def test_streaming_equals_batch_bit_for_bit(config, rng):
    make = CONFIGS[config]
    Hs, zs = _record(rng, dim_z=make().dim_z)
    stream, batch = make(), make()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        means, covs, means_p, covs_p = batch.batch_filter(zs, Hs)
        for k in range(N):
            stream.predict()
            assert_array_equal(stream.P, covs_p[k])
            stream.update(_z(zs, k), Hs[k])
            assert_array_equal(stream.x, means[k])
            assert_array_equal(stream.P, covs[k])
    _same(stream, batch)
    if config == "windup-cap":
        assert stream.n_capped > 0
    if config == "directional-gate":
        assert stream.n_gated > 0


def test_the_time_update_is_the_textbook_one(rng):
    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, lam=0.95, Q=1e-3)
    for k in range(20):
        f.predict_update(zs[k], Hs[k])
    P, x = f.P.copy(), f.x.copy()
    f.predict()
    assert_allclose(f.P, ref.rls_predict(P, 0.95, f.Q), rtol=1e-14)
    assert_array_equal(f.x_prior, x)
    assert_array_equal(f.P_prior, f.P)
    assert f.P_prior is not f.P and f.x_prior is not f.x


def test_predict_twice_forgets_twice(rng):
    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, lam=0.9, Q=1e-4)
    f.predict_update(zs[0], Hs[0])
    P = f.P.copy()
    f.predict()
    f.predict(Q=2e-4)
    assert_allclose(f.P, ref.rls_predict(ref.rls_predict(P, 0.9, f.Q), 0.9, 2e-4 * np.eye(4)),
                    rtol=1e-14)


@pytest.mark.parametrize("copier", [copy.copy, copy.deepcopy,
                                    lambda f: pickle.loads(pickle.dumps(f))])
def test_copies_after_predict_continue_as_the_original(config, rng, copier):
    make = CONFIGS[config]
    Hs, zs = _record(rng, dim_z=make().dim_z)
    f = make()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for k in range(40):
            f.predict_update(_z(zs, k), Hs[k])
        f.predict()
        g = copier(f)
        _same(f, g)
        for k in range(40, N):
            f.update(_z(zs, k), Hs[k])
            g.update(_z(zs, k), Hs[k])
            f.predict()
            g.predict()
    _same(f, g)


def test_a_failed_update_after_predict_changes_nothing(rng):
    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, lam=0.95)
    f.predict_update(zs[0], Hs[0])
    f.predict()
    before = _snapshot(f)
    for bad in ([1.0, np.nan, 0.0, 0.0], [1.0, 2.0]):
        with pytest.raises(ValueError, match="`H`"):
            f.update(1.0, bad)
    with pytest.raises(ValueError, match="`z`"):
        f.update(np.inf, Hs[1])
    for name, value in before.items():
        assert_array_equal(getattr(f, name), value, err_msg=name)
    assert f.n_updates == 1


def test_rows_of_every_layout_give_the_same_bits(rng):
    Hs, zs = _record(rng)
    a, b, c = (RecursiveLeastSquares(4, lam=0.95) for _ in range(3))
    F = np.asfortranarray(np.repeat(Hs, 2, axis=1))[:, ::2]     # strided rows
    R = Hs.copy()
    R.flags.writeable = False
    for k in range(N):
        a.predict_update(_z(zs, k), Hs[k])
        b.predict_update(_z(zs, k), F[k])
        c.predict_update(_z(zs, k), list(R[k]))
    _same(a, b)
    _same(a, c)
    assert not R.flags.writeable


def test_held_diagnostics_are_never_overwritten(rng):
    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, lam=0.95)
    history = []
    for k in range(N):
        f.predict()
        f.update(_z(zs, k), Hs[k])
        history.append({name: getattr(f, name) for name in STATE})
    snapshot = [{name: v.copy() for name, v in h.items()} for h in history]
    f.predict_update(1.0, Hs[0])
    for h, s in zip(history, snapshot):
        for name in STATE:
            assert_array_equal(h[name], s[name], err_msg=name)


def test_kernels_load_lazily_and_c_array_copies_only_when_needed():
    assert _streaming.kernels().update_kernel is not None
    assert _streaming.window_kernels().sr_update_kernel is not None
    a = np.zeros((3, 2))
    assert _streaming.c_array(a) is a
    assert _streaming.c_array(a.T).flags.c_contiguous
    ro = np.zeros(3)
    ro.flags.writeable = False
    assert _streaming.c_array(ro) is not ro
    assert _streaming.c_array([1, 2]).dtype == np.float64


def test_fast_path_rows_and_measurements_give_the_same_bits(rng):
    """The fast path (a float64 row of shape (dim_x,), a float z) hands the compiled
    step a new C-contiguous row whatever the caller's layout, and the same bits as
    the general validation (byte-swapped, read-only, 2-D, strided rows; NumPy and
    Python floats, 1-element arrays)."""
    Hs, zs = _record(rng)
    ref, *others = (RecursiveLeastSquares(4, lam=0.95) for _ in range(5))
    swapped = Hs.astype(">f8")
    ro = Hs.copy()
    ro.flags.writeable = False
    col = np.asfortranarray(Hs.T.copy()).T                     # rows with stride 8 * N
    for k in range(N):
        z = _z(zs, k)
        ref.predict_update(z, Hs[k])
        zf = None if z is None else float(z)
        za = None if z is None else np.array([z])
        others[0].predict_update(zf, swapped[k])
        others[1].predict_update(za, ro[k])
        others[2].predict_update(z, Hs[k:k + 1])
        others[3].predict_update(zf, col[k])
        for f in others:
            assert f.H.flags.c_contiguous and f.H.shape == (1, 4)
            assert f.z.flags.c_contiguous and f.z.shape == (1, 1)
    for f in others:
        _same(ref, f)
    assert not ro.flags.writeable
    assert_array_equal(swapped, Hs)                            # no caller array written
