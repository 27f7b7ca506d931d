"""The compiled (numba) recursion against the pure-NumPy reference path.

`batch_filter`, ``predict`` and ``update`` run compiled kernels;
``rlsfilt.filters.rls._COMPILED = False`` switches them to the NumPy code
(``_batch_reference``, ``_measurement_step``). The two must agree to 1e-12 on
well-conditioned data for every option (every forgetting mode, the gate, the
constraints), and the streaming ``predict``/``update`` must reproduce the
batch run bit for bit (they run the same compiled step).
"""

import functools
import re

import numpy as np
import pytest
from conftest import arx_record
from conftest import assert_close_steps as _close
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import NumericalWarning, RecursiveLeastSquares
from rlsfilt.filters import _kernels
from rlsfilt.filters import rls as rls_module

STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H")


def _record(rng, n_samples, dim_z=1, missing=(), scale=1.0):
    Hs, zs = arx_record(rng, n_samples=n_samples + 2)
    if dim_z > 1:
        extra = [Hs @ rng.standard_normal(4) + 0.1 * rng.standard_normal(len(zs))
                 for _ in range(dim_z - 1)]
        zs = np.column_stack([zs] + extra)
    zs = scale * zs.astype(float)
    for k in missing:
        zs[k] = np.nan
    return Hs, zs




def _run_both(monkeypatch, make, zs, Hs, **kwargs):
    a, b = make(), make()
    out_c = a.batch_filter(zs, Hs, **kwargs)
    monkeypatch.setattr(rls_module, "_COMPILED", False)
    out_r = b.batch_filter(zs, Hs, **kwargs)
    monkeypatch.setattr(rls_module, "_COMPILED", True)
    return a, b, out_c, out_r


OPTIONS = [
    # lam, Q, use_Rs, update_first, store_covariances, dim_z, missing
    (1.0, 0.0, False, False, True, 1, ()),
    (0.95, 0.0, False, False, True, 1, ()),
    (0.95, 0.0, False, True, True, 1, ()),
    (0.97, 1e-4, False, False, True, 1, ()),
    (0.97, "matrix", True, True, True, 1, ()),
    (0.9, 0.0, True, False, False, 1, (0, 7, 150, 299)),
    (0.9, 1e-3, False, True, False, 1, (3, 4, 5, 299)),
    (1.0, 1e-5, True, False, True, 3, (10, 298)),
    (0.98, 0.0, False, True, True, 3, (0, 1, 200)),
    (1.0, 0.0, True, True, False, 2, (150,)),
]


@pytest.mark.parametrize("lam, Q, use_Rs, update_first, store, dim_z, missing", OPTIONS)
def test_compiled_equals_reference(rng, monkeypatch, lam, Q, use_Rs, update_first, store,
                                   dim_z, missing):
    Hs, zs = _record(rng, 300, dim_z, missing)
    if isinstance(Q, str):
        A = rng.standard_normal((4, 4))
        Q = 1e-4 * (A @ A.T) / 4
    kwargs = {"update_first": update_first, "store_covariances": store}
    if use_Rs:
        kwargs["Rs"] = rng.uniform(0.5, 2.0, len(zs))

    def make():
        return RecursiveLeastSquares(4, dim_z, lam=lam, Q=Q, P0=100.0, R=0.7)

    a, b, out_c, out_r = _run_both(monkeypatch, make, zs, Hs, **kwargs)
    for name, c, r in zip(("means", "covariances", "means_p", "covariances_p"), out_c, out_r):
        if r is None:
            assert c is None, name
        else:
            _close(c, r, name)
    for name in STATE:
        _close(getattr(a, name), getattr(b, name), name)
    assert a.log_likelihood == pytest.approx(b.log_likelihood, rel=1e-12)
    assert a.mahalanobis == pytest.approx(b.mahalanobis, rel=1e-12, abs=1e-300, nan_ok=True)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("n_samples", [0, 1, 2])
def test_compiled_equals_reference_on_tiny_records(rng, monkeypatch, update_first, n_samples):
    Hs, zs = _record(rng, 5)
    Hs, zs = Hs[:n_samples], zs[:n_samples]

    def make():
        return RecursiveLeastSquares(4, lam=0.9, Q=1e-3)

    a, b, out_c, out_r = _run_both(monkeypatch, make, zs, Hs, update_first=update_first)
    for c, r in zip(out_c, out_r):
        assert c.shape == r.shape
        assert_allclose(c, r, rtol=1e-12, atol=1e-12)
    for name in STATE:
        assert_allclose(getattr(a, name), getattr(b, name), rtol=1e-12, atol=1e-12,
                        err_msg=name)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("store", [False, True])
def test_residual_and_variance_histories(rng, update_first, store):
    """The kernel's residuals ``ys`` and innovation variances ``ss`` match the reference."""
    Hs, zs = _record(rng, 200, dim_z=2, missing=(5, 100, 199))
    Z = zs.reshape(len(zs), -1)
    x0, P0 = np.zeros((4, 2)), 50.0 * np.eye(4)
    Q = 1e-4 * np.eye(4)
    Rv = rng.uniform(0.5, 2.0, len(Z))
    args = (x0, P0, Z, Hs, Rv, 0.95, Q, update_first, store)
    ref = rls_module._batch_reference(*args)
    out = _kernels.batch_compiled(*args)
    _close(out.ys, ref.ys, "ys")
    _close(out.ss, ref.ss, "ss")
    assert np.isnan(out.ys[[5, 100, 199]]).all() and not np.isnan(np.delete(out.ys, [5, 100, 199],
                                                                         axis=0)).any()
    for name in ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "K_last"):
        _close(getattr(out, name), getattr(ref, name), name)
    assert out.s_last == pytest.approx(ref.s_last, rel=1e-12)
    # the caller's arrays are untouched
    assert_array_equal(x0, 0.0)
    assert_array_equal(P0, 50.0 * np.eye(4))


def test_compiled_covariance_is_exactly_symmetric(rng):
    Hs, zs = _record(rng, 3000)
    rls = RecursiveLeastSquares(4, lam=0.95, Q=1e-6)
    _, covs, _, covs_p = rls.batch_filter(zs, Hs)
    assert_array_equal(covs, covs.transpose(0, 2, 1))
    assert_array_equal(covs_p, covs_p.transpose(0, 2, 1))
    assert np.all(np.linalg.eigvalsh(covs[-100:]) > 0)


def test_compiled_matches_lstsq_on_a_long_record(rng):
    """An independent oracle for the compiled path: lam = 1 with the batch start is OLS."""
    n_samples = 20000
    Hs, zs = _record(rng, n_samples)
    rls = RecursiveLeastSquares(4)
    rls.initialize(zs[:8], Hs[:8])
    rls.batch_filter(zs[8:], Hs[8:], store_covariances=False)
    theta, *_ = np.linalg.lstsq(Hs, zs, rcond=None)
    assert_allclose(rls.x.ravel(), theta, rtol=1e-9, atol=1e-12)
    assert_allclose(rls.P, np.linalg.inv(Hs.T @ Hs), rtol=1e-8)


# ----------------------------------------------------------------------
# the streaming fast path
# ----------------------------------------------------------------------
@pytest.mark.parametrize("dim_z", [1, 2])
def test_streaming_equals_batch_bit_for_bit(rng, dim_z):
    Hs, zs = _record(rng, 150, dim_z=dim_z, missing=(20, 149))
    a = RecursiveLeastSquares(4, dim_z, lam=0.96, Q=1e-5)
    b = a.copy()
    m, c, mp, cp = a.batch_filter(zs, Hs)
    for k in range(len(zs)):
        b.predict()
        assert_array_equal(cp[k], b.P)
        b.update(zs[k] if dim_z > 1 else float(zs[k]), Hs[k])
        assert_array_equal(m[k], b.x)
        assert_array_equal(c[k], b.P)
    for name in STATE:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_streaming_accepts_every_regressor_layout(rng):
    """Rows that are lists, ints, strided views or (1, n) all give the same step."""
    Hs, zs = _record(rng, 30)
    Hs = np.round(Hs * 4)                    # integers, exactly representable
    Hf = np.asfortranarray(Hs)               # rows are strided views
    Hi = Hs.astype(int)
    Hr = Hs.copy()
    Hr.setflags(write=False)                 # read-only rows
    ref = RecursiveLeastSquares(4, lam=0.97)
    others = [RecursiveLeastSquares(4, lam=0.97) for _ in range(5)]
    for k in range(len(zs)):
        ref.predict_update(zs[k], Hs[k])
        others[0].predict_update(zs[k], Hf[k])
        others[1].predict_update(zs[k], list(Hs[k]))
        others[2].predict_update(np.array([[zs[k]]]), Hs[k].reshape(1, -1))
        others[3].predict_update(int(round(zs[k])) if k % 2 else zs[k], Hi[k])
        others[4].predict_update(np.float64(zs[k]), Hr[k])
    for o in others[:3] + others[4:]:
        assert_array_equal(o.x, ref.x)
        assert_array_equal(o.P, ref.P)
    assert_array_equal(others[3].P, ref.P)      # P does not depend on the measurements


def test_streaming_uses_user_assigned_state(rng):
    """A state assigned by the user (any dtype, layout) is validated and used once."""
    Hs, zs = _record(rng, 20)
    a, b = RecursiveLeastSquares(4, lam=0.9), RecursiveLeastSquares(4, lam=0.9)
    a.predict_update(zs[0], Hs[0])
    b.predict_update(zs[0], Hs[0])
    P = np.asfortranarray(a.P * 2.0)
    a.P = P
    b.P = np.ascontiguousarray(P)
    a.x = np.array([[1], [2], [3], [4]])          # integers
    b.x = np.array([[1.0], [2.0], [3.0], [4.0]])
    for k in range(1, len(zs)):
        a.predict_update(zs[k], Hs[k])
        b.predict_update(zs[k], Hs[k])
    assert_array_equal(a.x, b.x)
    assert_array_equal(a.P, b.P)
    assert_array_equal(P, np.asfortranarray(b.P) * 0 + P)   # the assigned array is untouched
    a.P = np.eye(3)
    with pytest.raises(ValueError, match=r"`P` must be an array of shape \(4, 4\)"):
        a.predict()
    a.P = np.eye(4)
    a.x = np.zeros(3)
    with pytest.raises(ValueError, match=r"`x` must be an array of shape \(4, 1\)"):
        a.update(1.0, Hs[0])


def test_streaming_never_reuses_arrays(rng):
    """Each step makes new arrays, so ``history.append(rls.x)`` works as with filterpy."""
    Hs, zs = _record(rng, 10)
    rls = RecursiveLeastSquares(4, lam=0.9)
    seen = []
    for k in range(len(zs)):
        rls.predict()
        rls.update(zs[k], Hs[k])
        seen.append({name: getattr(rls, name) for name in STATE})
    ids = [id(v) for step in seen for v in step.values()]
    assert len(set(ids)) == len(ids)
    assert not np.shares_memory(rls.x, rls.x_post) and not np.shares_memory(rls.P, rls.P_post)
    assert not np.shares_memory(rls.H, Hs)


@pytest.mark.parametrize("bad, match", [(np.inf, r"`z` must be finite or NaN"),
                                        (-np.inf, r"`z` must be finite or NaN")])
def test_streaming_rejects_infinite_measurement_without_changing_state(rng, bad, match):
    rls = RecursiveLeastSquares(2)
    rls.update(1.0, [1.0, 0.5])
    before = {name: getattr(rls, name).copy() for name in STATE}
    with pytest.raises(ValueError, match=match):
        rls.update(bad, np.array([1.0, 2.0]))
    for name in STATE:
        assert_array_equal(getattr(rls, name), before[name], err_msg=name)


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_streaming_rejects_non_finite_regressor_without_changing_state(bad):
    rls = RecursiveLeastSquares(2)
    rls.update(1.0, [1.0, 0.5])
    before = {name: getattr(rls, name).copy() for name in STATE}
    with pytest.raises(ValueError, match=r"`H` must be finite; got (nan|inf) at index 1"):
        rls.update(2.0, np.array([1.0, bad]))
    for name in STATE:
        assert_array_equal(getattr(rls, name), before[name], err_msg=name)


def test_import_does_not_load_numba():
    """``import rlsfilt`` stays light: numba loads on the first compiled call."""
    import subprocess
    import sys

    code = ("import sys, rlsfilt; assert 'numba' not in sys.modules, 'numba imported'; "
            "r = rlsfilt.RecursiveLeastSquares(2); r.update(1.0, [1.0, 2.0]); "
            "assert 'numba' in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=_root(), env=_env())


def _root():
    import pathlib

    return str(pathlib.Path(__file__).resolve().parents[1])


def _env(**extra):
    import os

    env = dict(os.environ)
    env["PYTHONPATH"] = _root() + os.pathsep + env.get("PYTHONPATH", "")
    env.update(extra)
    return env


def test_streaming_recycles_only_arrays_nobody_else_holds(rng):
    """Arrays held by the caller (directly, in a list, as a view) are never overwritten."""
    Hs, zs = _record(rng, 40)
    rls = RecursiveLeastSquares(4, lam=0.95, Q=1e-4)
    rls.predict_update(zs[0], Hs[0])
    if rls_module._FREE is not None:          # recycling is on: the same objects are reused
        ids = {name: id(getattr(rls, name)) for name in STATE}
        rls.predict_update(zs[1], Hs[1])
        assert ids == {name: id(getattr(rls, name)) for name in STATE}
    held = {"x": rls.x, "P_post": rls.P_post, "K": rls.K, "y": rls.y, "P_prior": rls.P_prior}
    snapshot = {k: v.copy() for k, v in held.items()}
    row_view = rls.P[0]
    row = row_view.copy()
    history = []
    for k in range(2, len(zs)):
        rls.predict()
        rls.update(zs[k], Hs[k])
        history.append(rls.x)
        if k == 20:
            first = rls.x.copy()
    for name, value in held.items():
        assert_array_equal(value, snapshot[name], err_msg=name)
    assert_array_equal(row_view, row)
    assert_array_equal(history[18], first)
    assert len({id(h) for h in history}) == len(history)
    # the filter itself followed the recursion exactly
    ref = RecursiveLeastSquares(4, lam=0.95, Q=1e-4)
    ref.batch_filter(zs, Hs)
    assert_array_equal(rls.x, ref.x)
    assert_array_equal(rls.P, ref.P)


def test_streaming_never_overwrites_a_replaced_attribute_the_caller_kept(rng):
    """Replacing ``rls.y`` (or any diagnostic) while keeping the old array leaves the
    reference count unchanged: the filter must still not recycle the kept array."""
    Hs, zs = _record(rng, 12)
    rls = RecursiveLeastSquares(4, lam=0.95)
    ref = RecursiveLeastSquares(4, lam=0.95)
    for k in range(3):
        rls.predict_update(zs[k], Hs[k])
        ref.predict_update(zs[k], Hs[k])
    kept = {name: getattr(rls, name) for name in STATE[2:]}
    snapshot = {name: v.copy() for name, v in kept.items()}
    for name in STATE[2:]:
        setattr(rls, name, np.zeros_like(kept[name]))
    for k in range(3, len(zs)):
        rls.predict_update(zs[k], Hs[k])
        ref.predict_update(zs[k], Hs[k])
        for name in STATE:
            assert_array_equal(getattr(rls, name), getattr(ref, name), err_msg=name)
    for name, value in kept.items():
        assert_array_equal(value, snapshot[name], err_msg=name)


# ----------------------------------------------------------------------
# the compiled paths keep the health check and counters of the NumPy paths
# ----------------------------------------------------------------------
@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("store", [False, True])
@pytest.mark.parametrize("step0", [0, 37])
def test_compiled_health_check_reports_the_same_step(monkeypatch, update_first, store, step0):
    """Windup (constant regressor, lam = 0.9) makes P ill-conditioned: both paths name one step."""
    Hs = np.tile([1.0, 1.0], (400, 1))
    zs = np.ones(400)
    messages = []
    for compiled in (True, False):
        monkeypatch.setattr(rls_module, "_COMPILED", compiled)
        rls = RecursiveLeastSquares(2, lam=0.9, P0=1.0, check_every=10)
        if step0:
            rls.batch_filter(zs[:step0], Hs[:step0])     # healthy so far
        with pytest.warns(NumericalWarning) as record:
            rls.batch_filter(zs[step0:], Hs[step0:], update_first=update_first,
                             store_covariances=store)
        messages.append(str(record[0].message))
        assert rls.n_updates == 400
    assert "ill-conditioned" in messages[0]
    assert re.search(r"at step \d+ of batch_filter \(update \d+ since reset\)", messages[0])
    step = lambda msg: re.search(r"at step (\d+)", msg).group(1)   # noqa: E731
    assert step(messages[0]) == step(messages[1])


def test_streaming_fast_path_keeps_counters_and_health_check(rng):
    """The exponential fast path and the general path (a gate that never fires) agree."""
    Hs, zs = _record(rng, 300, missing=(50, 51))
    fast = RecursiveLeastSquares(4, lam=0.95, Q=1e-6, check_every=7)
    general = RecursiveLeastSquares(4, lam=0.95, Q=1e-6, check_every=7, gate=1e300)
    for k in range(len(zs)):
        for f in (fast, general):
            f.predict()
            f.update(zs[k], Hs[k])
        assert fast.n_updates == general.n_updates == k + 1
        assert fast.gated is general.gated is False
        assert fast.lam_t == general.lam_t
    for name in STATE:
        assert_allclose(getattr(fast, name), getattr(general, name), rtol=1e-10, atol=1e-12,
                        err_msg=name)
    # windup: both warn once, at the same update
    Hw = np.tile([1.0, 1.0, 0.0, 0.0], (400, 1))
    caught = []
    for f in (RecursiveLeastSquares(4, lam=0.9, P0=1.0, check_every=10),
              RecursiveLeastSquares(4, lam=0.9, P0=1.0, check_every=10, gate=1e300)):
        with pytest.warns(NumericalWarning) as record:
            for k in range(len(Hw)):
                f.predict_update(1.0, Hw[k])
        assert len(record) == 1
        caught.append(str(record[0].message))
    assert caught[0] == caught[1]


def test_compiled_health_decision_equals_health_problem():
    """The kernel's shortcut (Cholesky, trace bound) decides as ``eigvalsh`` does."""
    rng = np.random.default_rng(5)
    decided = {True: 0, False: 0}
    for _ in range(2000):
        n = int(rng.integers(1, 8))
        Qo, _ = np.linalg.qr(rng.standard_normal((n, n)))
        w = 10.0 ** rng.uniform(-14, 3, n)
        if rng.random() < 0.2:
            w[0] = -abs(w[0]) * rng.random()
        A = (Qo * w) @ Qo.T
        A = 0.5 * (A + A.T)
        if rng.random() < 0.05:
            A[0, -1] += 1e-3 * np.abs(A).max()          # not symmetric
        cond_max = 10.0 ** rng.uniform(2, 13) if rng.random() < 0.9 else np.inf
        expected = rls_module._health_problem(A, None, cond_max) is not None
        assert _kernels._unhealthy(A, cond_max) == expected
        decided[expected] += 1
    assert min(decided.values()) > 200
    assert _kernels._unhealthy(np.array([[1.0, np.nan], [np.nan, 1.0]]), 1e12)


def test_streaming_without_recycling_is_identical(rng, monkeypatch):
    """With recycling off (as where reference counts cannot be trusted) nothing changes."""
    Hs, zs = _record(rng, 60, missing=(7,))
    a = RecursiveLeastSquares(4, lam=0.95)
    for k in range(len(zs)):
        a.predict_update(zs[k], Hs[k])
    monkeypatch.setattr(rls_module, "_FREE", None)
    b = RecursiveLeastSquares(4, lam=0.95)
    ids = set()
    for k in range(len(zs)):
        b.predict_update(zs[k], Hs[k])
        ids.add(id(b.x))
    assert len(ids) > 1                               # fresh arrays each step
    for name in STATE:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


# ----------------------------------------------------------------------
# every forgetting mode, the gate and the constraints
# ----------------------------------------------------------------------
MODES = ["exponential", "directional", "constant_trace", "efra", "variable"]
A_C = np.array([[1.0, 1.0, 0.0, 0.0]])      # a1 + a2 = -0.8, true for arx_record's plant
B_C = np.array([-0.8])
OUTLIERS = (40, 90, 91)


def _robust_record(rng, dim_z, missing):
    Hs, zs = _record(rng, 120, dim_z, missing)
    zs[list(OUTLIERS)] += 25.0                   # gross outliers for the gate
    return Hs, zs


def _make_filter(mode, gate, constrained, Q, dim_z):
    rls = RecursiveLeastSquares(4, dim_z, lam=0.95, Q=Q, P0=100.0, R=0.5, forgetting=mode,
                                gate=4.0 if gate else None, check_every=10)
    if constrained:
        rls.constrain(A_C, B_C)
    return rls


@pytest.mark.parametrize("Q", [0.0, 1e-4])
@pytest.mark.parametrize("constrained", [False, True])
@pytest.mark.parametrize("gate", [False, True])
@pytest.mark.parametrize("mode", MODES)
def test_every_mode_gate_and_constraint_compiled_equals_reference(rng, monkeypatch, mode,
                                                                   gate, constrained, Q):
    """batch_filter, compiled against NumPy, for every missing x update_first x
    store_covariances x dim_z combination of one mode/gate/constraint/Q setting."""
    for dim_z in (1, 2):
        for missing in ((), (0, 7, 60, 119)):
            Hs, zs = _robust_record(rng, dim_z, missing)
            for update_first in (False, True):
                for store in (False, True):
                    kwargs = {"update_first": update_first, "store_covariances": store}
                    if update_first:
                        kwargs["Rs"] = rng.uniform(0.3, 0.8, len(zs))

                    make = functools.partial(_make_filter, mode, gate, constrained, Q, dim_z)
                    a, b, out_c, out_r = _run_both(monkeypatch, make, zs, Hs, **kwargs)
                    tag = f"dim_z={dim_z} missing={missing} uf={update_first} store={store}"
                    for name, c, r in zip(("means", "covariances", "means_p", "covariances_p"),
                                          out_c, out_r):
                        if r is None:
                            assert c is None, name
                        else:
                            _close(c, r, f"{name} {tag}")
                    for name in STATE:
                        _close(getattr(a, name), getattr(b, name), f"{name} {tag}")
                    assert a.n_gated == b.n_gated, tag
                    assert a.n_updates == b.n_updates == len(zs)
                    assert a.gated == b.gated
                    assert a.lam_t == pytest.approx(b.lam_t, rel=1e-12), tag
                    assert a.log_likelihood == pytest.approx(b.log_likelihood, rel=1e-12)
                    assert a.mahalanobis == pytest.approx(b.mahalanobis, rel=1e-12,
                                                          nan_ok=True)
                    if gate and not missing:
                        assert a.n_gated >= len(OUTLIERS), tag
                    if constrained:
                        assert_allclose(A_C @ a.x, np.tile(B_C, (1, dim_z)), atol=1e-10)


@pytest.mark.parametrize("robust", [False, True])
@pytest.mark.parametrize("mode", MODES)
def test_every_mode_streaming_compiled_equals_reference_and_batch(rng, monkeypatch, mode,
                                                                  robust):
    """predict()/update() run the compiled step: equal to the NumPy step to 1e-12 and to
    the compiled batch_filter bit for bit, with Q and missing samples, with and without the
    gate and constraints (without them, the exponential mode runs the fused fast path)."""
    Hs, zs = _robust_record(rng, 2, (5, 70))
    runs = {}
    for compiled in (True, False):
        monkeypatch.setattr(rls_module, "_COMPILED", compiled)
        rls = _make_filter(mode, robust, robust, 1e-4, 2)
        steps = []
        for k in range(len(zs)):
            rls.predict()
            rls.update(zs[k], Hs[k])
            steps.append((rls.x.copy(), rls.P.copy(), rls.lam_t, rls.gated))
        runs[compiled] = rls, steps
    monkeypatch.setattr(rls_module, "_COMPILED", True)
    (c, steps_c), (r, steps_r) = runs[True], runs[False]
    for (xc, Pc, lc, gc), (xr, Pr, lr, gr) in zip(steps_c, steps_r, strict=True):
        _close(xc, xr, "x")
        _close(Pc, Pr, "P")
        assert lc == pytest.approx(lr, rel=1e-12) and gc == gr
    for name in STATE:
        _close(getattr(c, name), getattr(r, name), name)
    assert c.n_gated == r.n_gated >= (len(OUTLIERS) if robust else 0)
    batch = _make_filter(mode, robust, robust, 1e-4, 2)
    means, covs, _, _ = batch.batch_filter(zs, Hs)
    for k, (xc, Pc, _, _) in enumerate(steps_c):
        assert_array_equal(means[k], xc)
        assert_array_equal(covs[k], Pc)
    for name in STATE:
        assert_array_equal(getattr(batch, name), getattr(c, name), err_msg=name)
    assert batch.n_gated == c.n_gated and batch.lam_t == c.lam_t


def test_constrained_health_check_is_compiled_and_reports_the_same_step(monkeypatch):
    """Windup under a constraint: the compiled check (on the null space of A) names the
    same step as the NumPy check."""
    Hs = np.tile([1.0, 1.0, 0.0], (400, 1))
    zs = np.ones(400)
    messages = []
    for compiled in (True, False):
        monkeypatch.setattr(rls_module, "_COMPILED", compiled)
        rls = RecursiveLeastSquares(3, lam=0.9, P0=1.0, check_every=10, gate=1e6)
        rls.constrain([0.0, 0.0, 1.0], 0.0)
        with pytest.warns(NumericalWarning) as record:
            rls.batch_filter(zs, Hs)
        messages.append(str(record[0].message))
    assert "ill-conditioned" in messages[0]
    assert messages[0] == messages[1]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("bad_H, bad_z, match", [
    ([1.0, np.nan, 0.0, 0.0], 1.0, r"`H` must be finite; got nan at index 1"),
    (np.array([1.0, 0.0, np.inf, 0.0]), 1.0, r"`H` must be finite; got inf at index 2"),
    ([1.0, 0.0, 0.0, 0.0], np.inf, r"`z` must be finite or NaN"),
])
def test_general_streaming_rejects_bad_input_without_changing_state(mode, bad_H, bad_z, match):
    """The compiled general step raises before anything changes, also before EFRA's
    first step (whose start clipping is a state change)."""
    rls = _make_filter(mode, True, True, 1e-4, 1)
    before = {name: getattr(rls, name).copy() for name in STATE}
    counters = (rls.n_updates, rls.n_gated, rls.lam_t)
    for _ in range(2):
        with pytest.raises(ValueError, match=match):
            rls.update(bad_z, bad_H)
        for name in STATE:
            assert_array_equal(getattr(rls, name), before[name], err_msg=name)
        assert (rls.n_updates, rls.n_gated, rls.lam_t) == counters
        rls.predict_update(1.0, [1.0, 0.5, 0.0, 0.2])       # a good step, then again
        before = {name: getattr(rls, name).copy() for name in STATE}
        counters = (rls.n_updates, rls.n_gated, rls.lam_t)
