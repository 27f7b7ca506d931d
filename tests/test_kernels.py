"""The compiled kernels of `RecursiveLeastSquares` against the textbook reference.

Every public method runs the compiled kernels (``rlsfilt.filters._kernels``);
the readable recursion is ``tests/_reference.py``. The two must agree
to 1e-12 (relative to each step's largest entry), step by step, on
well-conditioned data for every forgetting mode with and without the gate,
the constraints, a random walk ``Q``, per-sample ``Rs``, missing samples,
``update_first``, several outputs and covariance histories on or off; the
streaming ``predict``/``update`` must reproduce ``batch_filter`` bit for bit
(they run the same compiled step; the fused default loop gives the same
bits).
"""

import re
import warnings

import numpy as np
import pytest
from conftest import arx_record
from conftest import assert_close_steps as _close
from numpy.testing import assert_allclose, assert_array_equal
from reference_runs import rls_run

from rlsfilt import NumericalWarning, RecursiveLeastSquares
from rlsfilt.filters import _health, _kernels_shared, forgetting

STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H")
MODES = list(forgetting.MODES)      # derived: a new mode is covered without editing this file
A_C = np.array([[1.0, 1.0, 0.0, 0.0]])      # a1 + a2 = -0.8, true for arx_record's plant
B_C = np.array([-0.8])
OUTLIERS = (40, 90, 91)


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


def _compare_with_reference(f, out, ref, name=""):
    """`batch_filter`'s histories and the filter's last step against the reference run."""
    for label, c, r in zip(("means", "covariances", "means_p", "covariances_p"), out,
                           (ref.means, ref.covs, ref.means_p, ref.covs_p)):
        if c is not None and len(c):
            _close(c, r, f"{label} {name}")
    if len(ref.means):
        _close(f.x, ref.means[-1], f"x {name}")
        _close(f.P, (ref.covs_p if len(ref.covs_p) and _last_predicted(f) else ref.covs)[-1],
               f"P {name}")
        _close(f.x_post, ref.means[-1], f"x_post {name}")
        _close(f.P_post, ref.covs[-1], f"P_post {name}")
        _close(f.y, ref.ys[-1].reshape(-1, 1), f"y {name}")
        _close(f.K, ref.K, f"K {name}")
        assert f.S[0, 0] == pytest.approx(ref.ss[-1], rel=1e-12), name
        assert f.gated == ref.gated[-1] and f.n_gated == ref.gated.sum(), name
        assert f.lam_t == pytest.approx(ref.lam_t[-1], rel=1e-12), name


def _last_predicted(f):
    return f._updates_since_predict == 0


# ----------------------------------------------------------------------
# kernels == reference, step by step
# ----------------------------------------------------------------------
OPTIONS = [
    # lam, Q, use_Rs, update_first, store_covariances, dim_z, missing
    (1.0, 0.0, False, False, True, 1, ()),
    (0.95, 0.0, False, False, True, 1, ()),
    (0.95, 0.0, False, False, False, 1, ()),            # the fused default loop
    (0.95, 1e-4, True, False, True, 1, (0, 5, 299)),     # fused, with covariance histories
    (0.95, 0.0, False, True, True, 1, ()),
    (0.95, 0.0, False, True, False, 1, (0, 7, 150, 299)),
    (0.97, 1e-4, False, False, True, 1, ()),
    (0.97, "matrix", True, True, True, 1, ()),
    (0.9, 0.0, True, False, False, 1, (0, 7, 150, 299)),
    (0.9, 1e-3, False, True, False, 1, (3, 4, 5, 299)),
    (1.0, 1e-5, True, False, True, 3, (10, 298)),
    (0.98, 0.0, False, True, True, 3, (0, 1, 200)),
    (1.0, 0.0, True, True, False, 2, (150,)),
]


@pytest.mark.parametrize("lam, Q, use_Rs, update_first, store, dim_z, missing", OPTIONS)
def test_batch_equals_reference(rng, lam, Q, use_Rs, update_first, store, dim_z, missing):
    Hs, zs = _record(rng, 300, dim_z, missing)
    if isinstance(Q, str):
        A = rng.standard_normal((4, 4))
        Q = 1e-4 * (A @ A.T) / 4
    Rs = rng.uniform(0.5, 2.0, len(zs)) if use_Rs else None
    f = RecursiveLeastSquares(4, dim_z, lam=lam, Q=Q, P0=100.0, R=0.7)
    ref = rls_run(f, zs, Hs, Rs, update_first)
    out = f.batch_filter(zs, Hs, Rs=Rs, update_first=update_first, store_covariances=store)
    assert (out[1] is None) == (not store) and (out[3] is None) == (not store)
    _compare_with_reference(f, out, ref)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("n_samples", [0, 1, 2])
def test_batch_equals_reference_on_tiny_records(rng, update_first, n_samples):
    Hs, zs = _record(rng, 5)
    Hs, zs = Hs[:n_samples], zs[:n_samples]
    for store in (False, True):
        f = RecursiveLeastSquares(4, lam=0.9, Q=1e-3)
        ref = rls_run(f, zs, Hs, None, update_first)
        out = f.batch_filter(zs, Hs, update_first=update_first, store_covariances=store)
        assert out[0].shape == (n_samples, 4, 1) and out[2].shape == (n_samples, 4, 1)
        _compare_with_reference(f, out, ref)
        assert f.n_updates == n_samples


def _robust_record(rng, dim_z, missing):
    Hs, zs = _record(rng, 120, dim_z, missing)
    zs[list(OUTLIERS)] += 25.0                   # gross outliers for the gate
    return Hs, zs


#: The forgetting factors of a mode whose `lam` is not one number (the diagonal mode: one
#: per parameter, all different, so that no test sees only its exponential special case).
MODE_LAM = {"diagonal": np.array([0.99, 0.9, 0.95, 0.97])}


def _make_filter(mode, gate, constrained, Q, dim_z):
    rls = RecursiveLeastSquares(4, dim_z, lam=MODE_LAM.get(mode, 0.95), Q=Q, P0=100.0, R=0.5,
                                forgetting=mode, gate=4.0 if gate else None, check_every=10)
    if constrained:
        rls.constrain(A_C, B_C)
    return rls


@pytest.mark.parametrize("Q", [0.0, 1e-4])
@pytest.mark.parametrize("constrained", [False, True])
@pytest.mark.parametrize("gate", [False, True])
@pytest.mark.parametrize("mode", MODES)
def test_every_mode_gate_and_constraint_batch_equals_reference(rng, mode, gate, constrained, Q):
    """batch_filter against the reference for every missing x update_first x
    store_covariances x dim_z combination of one mode/gate/constraint/Q setting."""
    for dim_z in (1, 2):
        for missing in ((), (0, 7, 60, 119)):
            Hs, zs = _robust_record(rng, dim_z, missing)
            for update_first in (False, True):
                for store in (False, True):
                    Rs = rng.uniform(0.3, 0.8, len(zs)) if update_first else None
                    f = _make_filter(mode, gate, constrained, Q, dim_z)
                    ref = rls_run(f, zs, Hs, Rs, update_first)
                    out = f.batch_filter(zs, Hs, Rs=Rs, update_first=update_first,
                                         store_covariances=store)
                    tag = f"dim_z={dim_z} missing={missing} uf={update_first} store={store}"
                    _compare_with_reference(f, out, ref, tag)
                    assert f.n_updates == len(zs)
                    if gate and not missing:
                        assert f.n_gated >= len(OUTLIERS), tag
                    if constrained:
                        assert_allclose(A_C @ f.x, np.tile(B_C, (1, dim_z)), atol=1e-10)


@pytest.mark.parametrize("robust", [False, True])
@pytest.mark.parametrize("mode", MODES)
def test_every_mode_streaming_equals_reference_and_batch(rng, mode, robust):
    """predict()/update() run the compiled step: equal to the reference step by step to
    1e-12 and to batch_filter bit for bit, with Q and missing samples, with and without
    the gate and the constraints."""
    Hs, zs = _robust_record(rng, 2, (5, 70))
    f = _make_filter(mode, robust, robust, 1e-4, 2)
    ref = rls_run(f, zs, Hs)
    steps = []
    for k in range(len(zs)):
        f.predict()
        _close(f.P, ref.covs_p[k], f"P_prior {k}")
        f.update(zs[k], Hs[k])
        _close(f.x, ref.means[k], f"x {k}")
        _close(f.P, ref.covs[k], f"P {k}")
        assert f.lam_t == pytest.approx(ref.lam_t[k], rel=1e-12) and f.gated == ref.gated[k]
        steps.append((f.x, f.P))
    assert f.n_gated == ref.gated.sum() >= (len(OUTLIERS) if robust else 0)
    batch = _make_filter(mode, robust, robust, 1e-4, 2)
    means, covs, _, _ = batch.batch_filter(zs, Hs)
    for k, (x, P) in enumerate(steps):
        assert_array_equal(means[k], x)
        assert_array_equal(covs[k], P)
    for name in STATE:
        assert_array_equal(getattr(batch, name), getattr(f, name), err_msg=name)
    assert batch.n_gated == f.n_gated and batch.lam_t == f.lam_t


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("store", [False, True])
def test_fused_loop_equals_step_loop_bit_for_bit(rng, update_first, store):
    """The fused default loop (one output, no histories of P) and the step loop (a gate
    that never fires) give the same bits, also with Q and missing samples."""
    Hs, zs = _record(rng, 500, missing=(0, 3, 250, 499))
    for Q in (0.0, 1e-5):
        a = RecursiveLeastSquares(4, lam=0.97, Q=Q, check_every=7)
        b = RecursiveLeastSquares(4, lam=0.97, Q=Q, check_every=7, gate=1e300)
        ma, ca, mpa, cpa = a.batch_filter(zs, Hs, update_first=update_first,
                                          store_covariances=store)
        mb, cb, mpb, cpb = b.batch_filter(zs, Hs, update_first=update_first)
        assert_array_equal(ma, mb)
        assert_array_equal(mpa, mpb)
        if store:
            assert_array_equal(ca, cb)
            assert_array_equal(cpa, cpb)
        for name in STATE:
            assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("dim_x", [1, 2, 3, 4, 5, 8, 9, 12])
def test_fused_loop_equals_step_loop_at_every_size(rng, dim_x, update_first):
    """At every size (compiled with ``dim_x`` a constant up to 8, as a run-time number
    above) the fused loop and the step loop give the same bits, through every step the
    fused loop hands back to its caller: the windup cap (excitation lost in all
    directions but one), due and failed health checks, missing samples, ``Q``, the end
    of the record."""
    N = 700
    Hs = rng.standard_normal((N, dim_x))
    Hs[N // 3:, 1:] *= 1e-9                        # P winds up off the first direction
    zs = Hs @ rng.standard_normal(dim_x) + 0.1 * rng.standard_normal(N)
    zs[[0, 5, 6, 255, 256, N - 1]] = np.nan
    capped = 0
    for Q in (0.0, 1e-6):
        a = RecursiveLeastSquares(dim_x, lam=0.9, Q=Q, check_every=5)
        b = RecursiveLeastSquares(dim_x, lam=0.9, Q=Q, check_every=5, gate=1e300)
        with warnings.catch_warnings(record=True) as wa:
            warnings.simplefilter("always")
            ma, _, mpa, _ = a.batch_filter(zs, Hs, update_first=update_first,
                                           store_covariances=False)
        with warnings.catch_warnings(record=True) as wb:
            warnings.simplefilter("always")
            mb, _, mpb, _ = b.batch_filter(zs, Hs, update_first=update_first)
        assert_array_equal(ma, mb)
        assert_array_equal(mpa, mpb)
        for name in STATE:
            assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
        assert a.n_capped == b.n_capped
        assert [str(w.message) for w in wa] == [str(w.message) for w in wb]
        capped += a.n_capped
    if dim_x > 1:
        assert capped > 0                          # the cap's steps were taken


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("gate, Q, dim_z", [(None, 0.0, 1), (None, 1e-5, 1), (1e300, 0.0, 1),
                                            (None, 0.0, 2)],
                         ids=["fused", "fused-Q", "step-loop", "two-outputs"])
def test_scaled_run_equals_run_on_scaled_copies_bit_for_bit(rng, update_first, gate, Q, dim_z):
    """``_run_batch(scales=...)`` (``ARX.fit``'s recursion in scaled units, on the rows as
    they are) gives the bits of the run on copies scaled by the same powers of two, its
    histories mapped back by them: estimates, residuals written into the caller's array,
    and the filter's state (which stays in the scaled units)."""
    Hs, zs = _record(rng, 700, dim_z=dim_z, missing=(5, 256, 699))  # blocks of 256 rows
    zs = zs.reshape(len(zs), -1)
    c, ey = np.array([3, -2, 0, 7]), np.array([-5, 4])[:dim_z]
    hsc, zsc = np.ldexp(1.0, -c), np.ldexp(1.0, -ey)
    msc, ysc = np.ldexp(1.0, ey[None, :] - c[:, None]), np.ldexp(1.0, ey)
    kw = dict(dim_z=dim_z, lam=0.98, Q=Q, gate=gate, check_every=7)
    a, b = RecursiveLeastSquares(4, **kw), RecursiveLeastSquares(4, **kw)
    Rv = a._as_batch_variances(None, len(zs))
    resid = np.full_like(zs, 7.0)
    Hs0, zs0 = Hs.copy(), zs.copy()
    out = a._run_batch(zs, Hs, Rv, update_first, False, lead=3, residuals=resid,
                       scales=(hsc, zsc, msc, ysc))
    ref = b._run_batch(zs * zsc, Hs * hsc, Rv, update_first, False, lead=3, residuals=True)
    assert_array_equal(Hs, Hs0)                   # the caller's record is read, not written
    assert_array_equal(zs, zs0)
    assert out.ys is resid
    assert_array_equal(resid, ref.ys * ysc)
    assert_array_equal(out.buffer[:3], np.full((3, 4, dim_z), np.nan))
    assert_array_equal(out.buffer, ref.buffer * msc)
    for name in STATE:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


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


def test_streaming_keeps_counters_and_health_check_with_and_without_gate(rng):
    """Without a gate and with one that never fires: the same counters and warning."""
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


def test_streaming_never_overwrites_arrays_anybody_holds(rng):
    """Arrays held by the caller (directly, in a list, as a view) are never overwritten:
    every step writes new arrays."""
    Hs, zs = _record(rng, 40)
    rls = RecursiveLeastSquares(4, lam=0.95, Q=1e-4)
    for k in range(4):
        rls.predict_update(zs[k], Hs[k])
    held = {"x": rls.x, "P_post": rls.P_post, "K": rls.K, "y": rls.y, "P_prior": rls.P_prior}
    snapshot = {k: v.copy() for k, v in held.items()}
    row_view = rls.P[0]
    row = row_view.copy()
    history = []
    for k in range(4, len(zs)):
        rls.predict()
        rls.update(zs[k], Hs[k])
        history.append(rls.x)
        if k == 20:
            first = rls.x.copy()
    for name, value in held.items():
        assert_array_equal(value, snapshot[name], err_msg=name)
    assert_array_equal(row_view, row)
    assert_array_equal(history[16], first)
    assert len({id(h) for h in history}) == len(history)
    # the filter itself followed the recursion exactly
    ref = RecursiveLeastSquares(4, lam=0.95, Q=1e-4)
    ref.batch_filter(zs, Hs)
    assert_array_equal(rls.x, ref.x)
    assert_array_equal(rls.P, ref.P)


def test_assigned_state_is_copied_never_written(rng):
    """Assigning x or P copies (#18): the caller's arrays, even views, never change."""
    Hs, zs = _record(rng, 30)
    x0 = np.zeros(4)
    P0 = 100.0 * np.eye(4)
    rls = RecursiveLeastSquares(4, lam=0.95)
    rls.x = x0.reshape(-1, 1)              # a view of the caller's array
    rls.P = P0
    for k in range(len(zs)):
        rls.predict_update(zs[k], Hs[k])
    assert_array_equal(x0, 0.0)
    assert_array_equal(P0, 100.0 * np.eye(4))
    assert not np.shares_memory(rls.x, x0) and not np.shares_memory(rls.P, P0)
    ref = RecursiveLeastSquares(4, lam=0.95, P0=100.0)
    ref.batch_filter(zs, Hs)
    assert_array_equal(rls.x, ref.x)


# ----------------------------------------------------------------------
# the health check
# ----------------------------------------------------------------------
@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("store", [False, True])
@pytest.mark.parametrize("step0", [0, 37])
def test_health_check_reports_the_same_step_in_every_path(update_first, store, step0):
    """Windup (constant regressor, lam = 0.9) makes P ill-conditioned: the fused loop, the
    step loop (a gate that never fires) and the streaming steps name one update."""
    Hs = np.tile([1.0, 1.0], (400, 1))
    zs = np.ones(400)
    messages = []
    for gate in (None, 1e300):
        rls = RecursiveLeastSquares(2, lam=0.9, P0=1.0, check_every=10, gate=gate)
        if step0:
            rls.batch_filter(zs[:step0], Hs[:step0])     # healthy so far
        with pytest.warns(NumericalWarning) as record:
            rls.batch_filter(zs[step0:], Hs[step0:], update_first=update_first,
                             store_covariances=store)
        messages.append(str(record[0].message))
        assert len(record) == 1 and rls.n_updates == 400
    assert "ill-conditioned" in messages[0]
    assert re.search(r"at step \d+ of batch_filter \(update \d+ since reset\)", messages[0])
    update = lambda msg: re.search(r"\(update (\d+)", msg).group(1)   # noqa: E731
    assert update(messages[0]) == update(messages[1])
    stream = RecursiveLeastSquares(2, lam=0.9, P0=1.0, check_every=10)
    with pytest.warns(NumericalWarning, match=rf"at update {update(messages[0])} since reset"):
        for k in range(400):
            if update_first:
                stream.update(zs[k], Hs[k])
                stream.predict()
            else:
                stream.predict_update(zs[k], Hs[k])


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
        expected = _health.symmetric_problem(A, cond_max) is not None
        assert _kernels_shared.unhealthy(A, cond_max) == expected
        decided[expected] += 1
    assert min(decided.values()) > 200
    assert _kernels_shared.unhealthy(np.array([[1.0, np.nan], [np.nan, 1.0]]), 1e12)


def test_compiled_health_decision_on_a_subspace():
    """Under constraints P is judged on the null space of A, as the NumPy check does."""
    rng = np.random.default_rng(6)
    for _ in range(300):
        n = int(rng.integers(2, 6))
        A = rng.standard_normal((int(rng.integers(1, n)), n))
        from scipy.linalg import null_space

        basis = null_space(A)
        Qo, _ = np.linalg.qr(rng.standard_normal((n, n)))
        P = (Qo * 10.0 ** rng.uniform(-13, 2, n)) @ Qo.T
        P = basis @ basis.T @ P @ basis @ basis.T
        P = 0.5 * (P + P.T)
        cond_max = 10.0 ** rng.uniform(2, 12)
        expected = _health.symmetric_problem(P, cond_max, basis) is not None
        assert _kernels_shared.unhealthy_on(P, basis, cond_max) == expected


def test_constrained_health_check_names_the_same_step_in_every_path():
    """Windup under a constraint: the batch loop and the streaming steps agree."""
    Hs = np.tile([1.0, 1.0, 0.0], (400, 1))
    zs = np.ones(400)
    messages = []
    for stream in (False, True):
        rls = RecursiveLeastSquares(3, lam=0.9, P0=1.0, check_every=10, gate=1e6)
        rls.constrain([0.0, 0.0, 1.0], 0.0)
        with pytest.warns(NumericalWarning) as record:
            if stream:
                for k in range(len(zs)):
                    rls.predict_update(zs[k], Hs[k])
            else:
                rls.batch_filter(zs, Hs)
        messages.append(str(record[0].message))
    assert "ill-conditioned" in messages[0]
    update = lambda msg: re.search(r"update (\d+) since reset", msg).group(1)   # noqa: E731
    assert update(messages[0]) == update(messages[1])


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


# ----------------------------------------------------------------------
# memory: one estimate history, and records larger than memory in chunks
# ----------------------------------------------------------------------
@pytest.mark.parametrize("update_first", [False, True])
def test_estimate_histories_share_one_buffer(rng, update_first):
    """Without covariance histories batch_filter keeps one N x dim_x x dim_z array:
    means_p is a read-only view of the buffer behind means."""
    Hs, zs = _record(rng, 200)
    for gate in (None, 1e300):                    # the fused loop and the step loop
        f = RecursiveLeastSquares(4, lam=0.95, gate=gate)
        x0 = f.x.copy()
        means, covs, means_p, covs_p = f.batch_filter(zs, Hs, update_first=update_first,
                                                      store_covariances=False)
        assert covs is None and covs_p is None
        assert np.shares_memory(means, means_p) and not means_p.flags.writeable
        expected = means if update_first else np.concatenate([x0[None], means[:-1]])
        assert_array_equal(means_p, expected)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("gate, Q", [(None, 0.0), (None, 1e-6), (1e300, 0.0)])
def test_chunks_give_the_bits_of_one_run(update_first, gate, Q):
    """A record larger than memory runs in chunks (e.g. from ``np.load(..., mmap_mode='r')``):
    successive batch_filter calls give exactly the numbers of one call."""
    rng = np.random.default_rng(8)
    Hs, zs = _record(rng, 5000, missing=(0, 999, 1000, 4321))
    whole = RecursiveLeastSquares(4, lam=0.97, Q=Q, gate=gate, check_every=7)
    m_whole = whole.batch_filter(zs, Hs, update_first=update_first, store_covariances=False)[0]
    parts = RecursiveLeastSquares(4, lam=0.97, Q=Q, gate=gate, check_every=7)
    cuts = np.r_[0, np.sort(rng.choice(np.arange(1, len(zs)), 12, replace=False)), len(zs)]
    m_parts = [parts.batch_filter(zs[a:b], Hs[a:b], update_first=update_first,
                                  store_covariances=False)[0] for a, b in zip(cuts, cuts[1:])]
    assert_array_equal(np.concatenate(m_parts), m_whole)
    for name in STATE:
        assert_array_equal(getattr(parts, name), getattr(whole, name), err_msg=name)
    assert parts.n_updates == whole.n_updates == len(zs)
