"""RLSBank: C channels in one compiled call equal C separate RecursiveLeastSquares.

Oracles: one `RecursiveLeastSquares` per channel (run step by step), the
NumPy textbook recursion of `tests/_reference_bank.py`, and
`RecursiveLeastSquares.initialize` for the batch start. Tolerance 1e-12
relative (the arithmetic is the same, operation by operation, so in
practice the numbers agree bit for bit, which some tests pin).
"""

import copy
import doctest
import pickle
import re
import warnings

import numpy as np
import pytest
from _reference_bank import bank_batch_reference
from conftest import assert_close_steps
from numpy.testing import assert_allclose, assert_array_equal

import rlsfilt
from rlsfilt import ForgettingSkippedWarning, NumericalWarning, RecursiveLeastSquares, RLSBank
from rlsfilt.filters import _kernels_bank

MODES = list(rlsfilt.filters.bank.MODES)      # the modes the bank runs


def _record(rng, N=120, C=23, n=3, missing=0.06, bad_rows=0.03):
    """Regressors and measurements of C noisy linear regressions, with NaN
    measurements and NaN regressor rows scattered over the channels."""
    theta = rng.standard_normal((C, n))
    H = rng.standard_normal((N, C, n))
    Z = np.einsum("kci,ci->kc", H, theta) + 0.1 * rng.standard_normal((N, C))
    Z[rng.random((N, C)) < missing] = np.nan
    rows = rng.random((N, C)) < bad_rows
    H[rows, rng.integers(0, n, rows.sum())] = np.nan
    return Z, H


def _options(rng, C, mode):
    lam = rng.uniform(0.9, 1.0, C)
    if mode != "constant_trace":          # (whose default trace needs lam < 1)
        lam[0] = 1.0
    return dict(lam=lam, R=rng.uniform(0.5, 2.0, C), Q=rng.uniform(0.0, 1e-4, C),
                P0=rng.uniform(10.0, 1e3, C), forgetting=mode)


def _separate(Z, H, opts, update_first=False):
    """One RecursiveLeastSquares per channel, step by step (NaN regressor: no update)."""
    N, C, n = H.shape
    means, covs = np.empty((N, C, n)), np.empty((N, C, n, n))
    covs_p = np.empty((N, C, n, n))
    ys, ss = np.full((N, C), np.nan), np.full((N, C), np.nan)
    filters = []
    for c in range(C):
        f = RecursiveLeastSquares(n, lam=opts["lam"][c], R=opts["R"][c], Q=opts["Q"][c],
                                  P0=opts["P0"][c], forgetting=opts["forgetting"])
        for k in range(N):
            if not update_first:
                f.predict()
                covs_p[k, c] = f.P
            if not np.isnan(H[k, c]).any():
                f.update(Z[k, c], H[k, c])
                ys[k, c], ss[k, c] = f.y[0, 0], f.S[0, 0]
            means[k, c], covs[k, c] = f.x[:, 0], f.P
            if update_first:
                f.predict()
                covs_p[k, c] = f.P
        filters.append(f)
    return filters, means, covs, covs_p, ys, ss


# ----------------------------------------------------------------------
# equality with C separate filters and with the NumPy reference
# ----------------------------------------------------------------------
@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("mode", MODES)
def test_batch_filter_equals_separate_filters(rng, mode, update_first):
    Z, H = _record(rng)
    N, C, n = H.shape
    opts = _options(rng, C, mode)
    bank = RLSBank(C, n, **opts)
    hist = bank.batch_filter(Z, H, update_first=update_first)
    filters, means, covs, covs_p, ys, ss = _separate(Z, H, opts, update_first)
    assert_close_steps(hist.means, means, "means")
    assert_close_steps(hist.covariances.reshape(N, C, n * n), covs.reshape(N, C, n * n), "P")
    assert_close_steps(hist.covariances_p.reshape(N, C, n * n), covs_p.reshape(N, C, n * n),
                       "P prior")
    assert_close_steps(hist.residuals[:, :, None], ys[:, :, None], "residuals")
    ok = ~np.isnan(ys)                     # S of a missing z is the predictive variance
    assert_allclose(hist.innovation_variances[ok], ss[ok], rtol=1e-12)
    for c, f in enumerate(filters):
        assert_allclose(bank.x[c], f.x[:, 0], rtol=1e-12, atol=1e-12 * np.abs(f.x).max())
        assert_allclose(bank.P[c], f.P, rtol=1e-12, atol=1e-12 * np.abs(f.P).max())
        if not np.isnan(H[-1, c]).any():     # (a NaN regressor: the filter made no update)
            assert_allclose(bank.lam_t[c], f.lam_t, rtol=1e-12)
    # the arithmetic is the same operation by operation: in fact bitwise equal (the
    # constant-trace rescaling is ordered differently in RecursiveLeastSquares' kernel:
    # round-off there, held to 1e-12 above)
    if mode != "constant_trace":
        assert_array_equal(bank.x, np.array([f.x[:, 0] for f in filters]))
        assert_array_equal(bank.P, np.array([f.P for f in filters]))


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("mode", MODES)
def test_batch_filter_equals_numpy_reference(rng, mode, update_first):
    Z, H = _record(rng, N=150, C=41, n=4)
    N, C, n = H.shape
    opts = _options(rng, C, mode)
    bank = RLSBank(C, n, **opts)
    x0, P0 = bank.x.copy(), bank.P.copy()
    hist = bank.batch_filter(Z, H, update_first=update_first)
    params = np.column_stack([bank.forgetting_params.get(k, np.zeros(C))
                              for k in {"exponential": ("", ""), "directional": ("eps", ""),
                                        "constant_trace": ("trace", "ratio")}[mode]])
    means, covs, ys, x, P = bank_batch_reference(x0, P0, Z, H, opts["R"], opts["lam"],
                                                 bank.Q, mode, params, update_first)
    assert_close_steps(hist.means, means, "means")
    assert_close_steps(hist.covariances.reshape(N, C, n * n), covs.reshape(N, C, n * n), "P")
    assert_close_steps(hist.residuals[:, :, None], ys[:, :, None], "residuals")
    assert_close_steps(bank.P.reshape(1, C, n * n), P.reshape(1, C, n * n), "final P")


@pytest.mark.parametrize("mode", MODES)
def test_histories_off_and_streaming_give_the_same_bits(rng, mode):
    """The fused sweep (no covariance history), the unfused one and the
    streaming predict/update pair run the same arithmetic."""
    Z, H = _record(rng, C=45, n=4)
    N, C, n = H.shape
    opts = _options(rng, C, mode)
    full = RLSBank(C, n, **opts)
    hist = full.batch_filter(Z, H)
    lean = RLSBank(C, n, **opts)
    out = lean.batch_filter(Z, H, store_covariances=False, store_means=False)
    assert out.means is None and out.covariances is None and out.covariances_p is None
    assert_array_equal(lean.x, full.x)
    assert_array_equal(lean.P, full.P)
    assert_array_equal(out.residuals, hist.residuals)
    stream = RLSBank(C, n, **opts)
    for k in range(N):
        stream.predict()
        stream.update(Z[k], H[k])
        assert_array_equal(stream.x, hist.means[k])
        assert_array_equal(stream.y, hist.residuals[k])
    assert_array_equal(stream.P, full.P)
    for name in ("x_prior", "P_prior", "x_post", "P_post", "y", "S", "K", "lam_t", "z", "H"):
        assert_array_equal(getattr(stream, name), getattr(full, name), err_msg=name)
    assert stream.n_updates == full.n_updates == N


@pytest.mark.parametrize("mode", MODES)
def test_clean_and_masked_steps_give_the_bits_of_separate_filters(rng, mode):
    """Most steps of most blocks hold no missing data (the kernel's unmasked path),
    a few hold one NaN (the masked path for that block and step): every channel
    still equals its own filter bit for bit, and the residual histories off keep
    the state and the last step's diagnostics."""
    N, C, n = 90, 70, 3
    Z, H = _record(rng, N=N, C=C, n=n, missing=0.0, bad_rows=0.0)
    Z[[5, 40, 88], [3, 66, 12]] = np.nan
    H[[17, 60], [50, 1], [0, 2]] = np.nan
    opts = _options(rng, C, mode)
    filters, means, covs, covs_p, ys, ss = _separate(Z, H, opts)
    bank = RLSBank(C, n, **opts)
    hist = bank.batch_filter(Z, H, store_covariances=False)
    # bit for bit, except the constant-trace rescaling (round-off, as above)
    same = assert_array_equal if mode != "constant_trace" else (
        lambda a, b: assert_allclose(a, b, rtol=1e-12, atol=1e-12))
    same(hist.means, means)
    same(hist.residuals, ys)
    ok = ~np.isnan(ss)
    same(hist.innovation_variances[ok], ss[ok])
    same(bank.x, np.array([f.x[:, 0] for f in filters]))
    same(bank.P, np.array([f.P for f in filters]))
    same(bank.K, np.array([f.K[:, 0] for f in filters]))
    # one more channel, missing at every step, sends every step down the masked
    # path: the other channels keep their bits
    more = {k: np.r_[v, v[:1]] if isinstance(v, np.ndarray) else v for k, v in opts.items()}
    masked = RLSBank(C + 1, n, **more)
    hm = masked.batch_filter(np.c_[Z, np.full(N, np.nan)], np.concatenate([H, H[:, :1]], 1),
                             store_covariances=False)
    assert_array_equal(hm.means[:, :C], hist.means)
    assert_array_equal(hm.residuals[:, :C], hist.residuals)
    assert_array_equal(hm.innovation_variances[:, :C], hist.innovation_variances)
    for name in ("x", "P", "K", "lam_t", "x_prior", "P_prior"):
        assert_array_equal(getattr(masked, name)[:C], getattr(bank, name), err_msg=name)
    lean = RLSBank(C, n, **opts)
    out = lean.batch_filter(Z, H, store_covariances=False, store_means=False,
                            store_residuals=False)
    assert out.residuals is None and out.innovation_variances is None
    assert repr(out) == f"<BankHistory: {N} steps of {C} channels>"
    for name in ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "S", "SI", "K",
                 "lam_t", "z", "H"):
        assert_array_equal(getattr(lean, name), getattr(bank, name), err_msg=name)
    with pytest.raises(TypeError, match="`store_residuals` must be True or False"):
        lean.batch_filter(Z, H, store_residuals="no")


def test_parallel_kernel_gives_the_same_bits(rng):
    Z, H = _record(rng, N=60, C=70, n=3)
    N, C, n = H.shape
    serial, parallel = RLSBank(C, n, lam=0.97), RLSBank(C, n, lam=0.97, parallel=True)
    a = serial.batch_filter(Z, H)
    b = parallel.batch_filter(Z, H)
    for u, v in zip([*a, a.residuals], [*b, b.residuals]):
        assert_array_equal(u, v)
    assert_array_equal(serial.P, parallel.P)
    with pytest.raises(TypeError, match="`parallel` must be True or False; got 1"):
        RLSBank(2, 2, parallel=1)


def test_regressors_stored_channel_last_give_the_same_bits(rng):
    """An (N, dim_x, C) array passed as its transposed view (as fit_many does) is
    read in place and gives the bits of the (N, C, dim_x) copy."""
    Z, H = _record(rng, N=50, C=37, n=3)
    Ht = np.ascontiguousarray(H.transpose(0, 2, 1))          # (N, n, C)
    a, b = RLSBank(37, 3, lam=0.98), RLSBank(37, 3, lam=0.98)
    ha = a.batch_filter(Z, H)
    hb = b.batch_filter(Z, Ht.transpose(0, 2, 1))
    assert_array_equal(a.x, b.x)
    assert_array_equal(ha.residuals, hb.residuals)
    assert_array_equal(ha.covariances, hb.covariances)
    assert_array_equal(a.H, b.H)


def test_per_step_noise_variances(rng):
    Z, H = _record(rng, C=7, missing=0.0, bad_rows=0.0)
    N, C, n = H.shape
    Rs = rng.uniform(0.5, 2.0, (N, C))
    bank = RLSBank(C, n, lam=0.98)
    hist = bank.batch_filter(Z, H, Rs=Rs)
    for c in range(C):
        f = RecursiveLeastSquares(n, lam=0.98)
        means = f.batch_filter(Z[:, c], H[:, c], Rs=Rs[:, c])[0]
        assert_allclose(hist.means[:, c], means[:, :, 0], rtol=1e-12, atol=1e-12)
    shared = RLSBank(C, n, lam=0.98, R=Rs[0])
    shared.batch_filter(Z[:1], H[:1])
    per_channel = RLSBank(C, n, lam=0.98)
    per_channel.batch_filter(Z[:1], H[:1], Rs=Rs[0])
    assert_array_equal(shared.x, per_channel.x)


def test_nan_skips_only_that_channel(rng):
    Z, H = _record(rng, N=1, C=5, missing=0.0, bad_rows=0.0)
    Z[0, 1] = np.nan          # missing measurement
    H[0, 3, 2] = np.nan       # missing regressor entry
    bank = RLSBank(5, 3, lam=0.9)
    x0, P0 = bank.x.copy(), bank.P.copy()
    bank.predict()
    bank.update(Z[0], H[0])
    for c in (1, 3):
        assert_array_equal(bank.x[c], x0[c])
        assert_array_equal(bank.P[c], P0[c] / 0.9)          # the time update still applies
        assert np.isnan(bank.y[c]) and not bank.K[c].any()
    assert np.isnan(bank.S[3]) and np.isfinite(bank.S[1])   # S of a missing z is predictive
    for c in (0, 2, 4):
        f = RecursiveLeastSquares(3, lam=0.9)
        f.predict_update(Z[0, c], H[0, c])
        assert_array_equal(bank.x[c], f.x[:, 0])
        assert_array_equal(bank.P[c], f.P)
    assert bank.log_likelihood[1] == 0.0 and np.isnan(bank.mahalanobis[1])


def test_filterpy_diagnostics_per_channel(rng):
    Z, H = _record(rng, N=30, C=6, missing=0.0, bad_rows=0.0)
    bank = RLSBank(6, 3, lam=0.95)
    assert_array_equal(bank.log_likelihood, np.log(np.finfo(float).tiny))
    bank.batch_filter(Z, H)
    for c in range(6):
        f = RecursiveLeastSquares(3, lam=0.95)
        f.batch_filter(Z[:, c], H[:, c])
        assert_allclose(bank.log_likelihood[c], f.log_likelihood, rtol=1e-12)
        assert_allclose(bank.likelihood[c], f.likelihood, rtol=1e-12)
        assert_allclose(bank.mahalanobis[c], f.mahalanobis, rtol=1e-12)
        assert_allclose(bank.SI[c], f.SI[0, 0], rtol=1e-12)


# ----------------------------------------------------------------------
# channel(i)
# ----------------------------------------------------------------------
@pytest.mark.parametrize("mode", MODES)
def test_channel_continues_exactly_like_the_bank(rng, mode):
    Z, H = _record(rng, N=80, C=9, n=3)
    opts = _options(rng, 9, mode)
    bank = RLSBank(9, 3, **opts, x0=rng.standard_normal((9, 3)))
    bank.batch_filter(Z[:40], H[:40])
    channels = [bank.channel(i) for i in range(9)]
    assert isinstance(channels[0], RecursiveLeastSquares)
    for i, f in enumerate(channels):
        assert_array_equal(f.x[:, 0], bank.x[i])
        assert_array_equal(f.P, bank.P[i])
        assert f.n_updates == bank.n_updates and f.lam == bank.lam[i]
        assert_array_equal(f.y[0], bank.y[i:i + 1])
    for k in range(40, 80):
        bank.predict()
        bank.update(Z[k], H[k])
        for i, f in enumerate(channels):
            f.predict()
            if not np.isnan(H[k, i]).any():
                f.update(Z[k, i], H[k, i])
    same = (assert_array_equal if mode != "constant_trace"     # see the batch test above
            else lambda a, b: assert_allclose(a, b, rtol=1e-12, atol=1e-15))
    for i, f in enumerate(channels):
        same(f.x[:, 0], bank.x[i])
        same(f.P, bank.P[i])
    # its reset returns to the channel's own x0 and P0
    f = bank.channel(-1)
    f.reset()
    assert_array_equal(f.x[:, 0], bank._x0[8])
    assert_array_equal(f.P, opts["P0"][8] * np.eye(3))


def test_channel_index_errors():
    bank = RLSBank(4, 2)
    with pytest.raises(ValueError, match=r"`i` must be a channel index in \[-4, 4\); got 4"):
        bank.channel(4)
    with pytest.raises(TypeError, match="`i` must be an integer"):
        bank.channel(1.0)


# ----------------------------------------------------------------------
# batch start
# ----------------------------------------------------------------------
def test_initialize_equals_rls_initialize(rng):
    Z, H = _record(rng, N=12, C=8, n=3, missing=0.0, bad_rows=0.0)
    Z[2, 5] = np.nan                       # dropped rows, per channel
    H[7, 1, 0] = np.nan
    lam = rng.uniform(0.9, 1.0, 8)
    R = rng.uniform(0.5, 2.0, 8)
    bank = RLSBank(8, 3, lam=lam, R=R)
    bank.initialize(Z, H)
    for c in range(8):
        f = RecursiveLeastSquares(3, lam=lam[c], R=R[c])
        bad = np.isnan(H[:, c]).any(axis=1)      # a NaN regressor drops its row, as a NaN z
        f.initialize(np.where(bad, np.nan, Z[:, c]), np.where(bad[:, None], 0.0, H[:, c]))
        assert_allclose(bank.x[c], f.x[:, 0], rtol=1e-12, atol=1e-13)
        assert_allclose(bank.P[c], f.P, rtol=1e-11, atol=1e-14)
    assert_array_equal(bank.P, bank.P.transpose(0, 2, 1))


def test_initialize_rank_check_equals_matrix_rank(rng):
    """The QR bound that settles most ranks of `initialize` gives exactly the ranks
    of numpy's matrix_rank (SVD), near the threshold too."""
    from rlsfilt.filters.bank import full_rank as _full_rank

    mats = []
    for k0, n in ((6, 3), (3, 3), (8, 4)):
        for gap in (0.0, 1e-20, 1e-15, 1e-14, 1e-13, 1e-12, 1e-9, 1e-3, 1.0):
            A = rng.standard_normal((k0, n))
            A[:, -1] = A[:, 0] + gap * rng.standard_normal(k0)   # near-dependent column
            mats.append(A)
        A = rng.standard_normal((k0, n))
        A[:, 1] = 0.0
        mats.append(A)
        mats.append(np.zeros((k0, n)))
        mats.append(rng.standard_normal((k0, n)) * np.r_[1e-150, 1.0, 1e150, 1.0][:n])
        stack = np.array(mats[-12:])
        stack /= np.maximum(np.linalg.norm(stack, axis=1), 1e-300)[:, None, :]
        rank, Rinv = _full_rank(stack, np.linalg.qr(stack, mode="r"))
        assert_array_equal(rank, np.linalg.matrix_rank(stack))
        assert Rinv is None                                      # (a zero column)
    short = rng.standard_normal((4, 2, 3))                       # fewer rows than columns
    assert_array_equal(_full_rank(short, None)[0], np.linalg.matrix_rank(short))
    assert _full_rank(np.empty((3, 0, 2)), None)[0].tolist() == [0, 0, 0]
    full = rng.standard_normal((5, 6, 3))
    R = np.linalg.qr(full, mode="r")
    rank, Rinv = _full_rank(full, R)
    assert_array_equal(rank, 3)
    assert_array_equal(Rinv, np.linalg.inv(R))


def test_initialize_names_rank_deficient_channels(rng):
    Z, H = _record(rng, N=5, C=4, n=3, missing=0.0, bad_rows=0.0)
    H[:, 2, 1] = H[:, 2, 0]                # channel 2: two equal columns
    bank = RLSBank(4, 3)
    x, P = bank.x.copy(), bank.P.copy()
    with pytest.raises(ValueError, match=r"rank-deficient in 1 channel\(s\) \[2\]: channel 2 "
                                         r"has 2 linearly independent rows in 5 usable"):
        bank.initialize(Z, H)
    assert_array_equal(bank.x, x)
    assert_array_equal(bank.P, P)


# ----------------------------------------------------------------------
# health check
# ----------------------------------------------------------------------
def _windup_record(N=120):
    """Channel 2 sees only its first regressor: under forgetting the other
    direction of its P winds up; channels 0, 1, 3 are well excited."""
    rng = np.random.default_rng(5)
    H = rng.standard_normal((N, 4, 2))
    H[:, 2] = [1.0, 0.0]
    return rng.standard_normal((N, 4)), H


def _health_cases(rng, n):
    """Matrices on both sides of every decision of the health check: well and
    badly conditioned (around the bound's limit and `cond_max`), singular,
    indefinite, a negative or zero diagonal, NaN, inf, huge finite entries and
    (for the public-P check) a matrix that is not exactly symmetric."""
    mats = []
    for cond in (1.0, 1e3, 1e6, 1e9, 2e9, 1e11, 4e11, 5e11, 6e11, 1e12, 2e12, 1e14):
        Qm, _ = np.linalg.qr(rng.standard_normal((n, n)))
        d = np.geomspace(1.0, cond, n) * rng.uniform(1e-3, 1e3)
        A = (Qm * d) @ Qm.T
        mats.append(0.5 * (A + A.T))
    A = rng.standard_normal((n, n))
    mats += [A @ A.T + np.eye(n), np.zeros((n, n)), -np.eye(n),
             np.diag(np.r_[1.0, -1.0, 1.0, 2.0][:n])]
    v = rng.standard_normal(n)
    mats.append(np.outer(v, v))                                 # singular
    for bad in (np.nan, np.inf, -np.inf, 1e308):
        M = np.eye(n)
        M[0, n - 1] = M[n - 1, 0] = bad
        mats.append(M)
        M = np.eye(n)
        M[1, 1] = bad
        mats.append(M)
    return np.array(mats)


def test_vectorized_health_check_decides_as_unhealthy(rng):
    """The bank's health checks (`_check_block` in the record kernel,
    `bank_unhealthy` on the public P) decide every channel exactly as
    `unhealthy`, the check of `RecursiveLeastSquares`, decides it."""
    from rlsfilt.filters._kernels_shared import unhealthy

    n = 4
    P = _health_cases(rng, n)
    with np.errstate(over="ignore"):                            # 1e308 * 1e100: inf
        P = np.concatenate([P, P * 1e-200, P * 1e100])          # scales near the ends
    asym = P[:3].copy()
    asym[:, 0, 1] += 1e-3                                       # not exactly symmetric
    P_pub = np.concatenate([P, asym])
    for cond_max in (1e12, 1e9, 1.0 + 1e-9, 1e300):
        expected = np.array([unhealthy(M, cond_max) for M in P_pub])
        assert 0 < expected.sum() < len(P_pub)
        bad = np.zeros(len(P_pub), dtype=bool)
        _kernels_bank.bank_unhealthy(np.ascontiguousarray(P_pub.T), cond_max, bad)
        assert_array_equal(bad, expected)
        # the record kernel's check reads the packed upper triangle, channel last
        C = len(P)
        iu, ju, tri = _kernels_bank._triangle(n)
        Pb = np.ascontiguousarray(P[:, iu, ju].T)
        k_fail = np.full(C, -1, dtype=np.int64)
        k_fail[5] = 3                                           # already failed: kept
        B = C + 3
        work = (np.empty((n, n, B)), np.empty((n, n, B)), np.empty(B), np.empty(B),
                np.empty(B), np.empty(B, dtype=bool), np.empty((n, n)))
        _kernels_bank._check_block(Pb, C, tri, cond_max, 0, 7, k_fail, *work)
        want = np.where(expected[:C], 7, -1)
        want[5] = 3
        assert_array_equal(k_fail, want)
        proved = work[5][:C]                    # the lanes the cheap bound settled
        assert not (proved & expected[:C]).any()
        assert proved[:2].all() or cond_max < 1e6             # (conditions 1 and 1e3)


def test_health_check_names_the_failing_channels_in_batch():
    Z, H = _windup_record()
    bank = RLSBank(4, 2, lam=[1.0, 1.0, 0.7, 1.0])
    with pytest.warns(NumericalWarning, match=r"health check in 1 of 4 channel\(s\) \[2\] at "
                                              r"step 99 of batch_filter .*ill-conditioned"):
        bank.batch_filter(Z, H)
    assert_array_equal(bank.failed_channels, [2])
    with warnings.catch_warnings():        # warned once per channel until reset
        warnings.simplefilter("error")
        bank.batch_filter(Z, H)
    bank.reset()
    assert bank.failed_channels.size == 0


def test_health_check_names_the_failing_channels_when_streaming():
    """The bank warns at the update where channel 2's own filter warns."""
    Z, H = _windup_record()
    f = RecursiveLeastSquares(2, lam=0.7, check_every=10)
    with pytest.warns(NumericalWarning) as record:
        for k in range(len(Z)):
            f.predict_update(Z[k, 2], H[k, 2])
    update = re.search(r"at update (\d+) since reset", str(record[0].message)).group(1)
    bank = RLSBank(4, 2, lam=[1.0, 1.0, 0.7, 1.0], check_every=10)
    with pytest.warns(NumericalWarning, match=rf"\[2\] at update {update} since reset; "
                                              "channel 2: `P` is ill-conditioned"):
        for k in range(len(Z)):
            bank.predict_update(Z[k], H[k])
    assert_array_equal(bank.failed_channels, [2])


def test_warnings_point_at_the_callers_line():
    Z, H = _windup_record()
    for call in (lambda b: b.batch_filter(Z, H),
                 lambda b: [b.predict_update(Z[k], H[k]) for k in range(len(Z))],
                 lambda b: [(b.predict(), b.update(Z[k], H[k])) for k in range(len(Z))]):
        bank = RLSBank(4, 2, lam=[1.0, 1.0, 0.7, 1.0], check_every=10)
        with pytest.warns(NumericalWarning) as record:
            call(bank)
        assert record[0].filename == __file__
    bank = RLSBank(3, 2, lam=0.9)
    bank.update(np.ones(3), np.ones((3, 2)))
    with pytest.warns(ForgettingSkippedWarning) as record:
        bank.update(np.ones(3), np.ones((3, 2)))
    assert record[0].filename == __file__


def test_directional_forgetting_keeps_the_bank_healthy():
    Z, H = _windup_record()
    bank = RLSBank(4, 2, lam=[1.0, 1.0, 0.7, 1.0], forgetting="directional")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        bank.batch_filter(Z, H)
    assert bank.failed_channels.size == 0


def test_update_twice_without_predict_warns():
    bank = RLSBank(3, 2, lam=0.9)
    bank.update(np.ones(3), np.ones((3, 2)))
    with pytest.warns(ForgettingSkippedWarning, match="without predict"):
        bank.update(np.ones(3), np.ones((3, 2)))


# ----------------------------------------------------------------------
# errors, no mutation, state kept by a failed call
# ----------------------------------------------------------------------
@pytest.mark.parametrize("kwargs, exc, match", [
    ({"lam": 1.5}, ValueError, r"`lam` must be in \(0, 1\]; got 1.5 for channel 0"),
    ({"lam": [1.0, 0.0, 1.0]}, ValueError, r"`lam` must be in \(0, 1\]; got 0.0 for channel 1"),
    ({"lam": [0.9, 0.9]}, ValueError, r"`lam` must be a scalar or have shape \(3,\) \(one value "
                                      r"per channel, n_channels = 3\); got shape \(2,\)"),
    ({"R": [1.0, -1.0, 1.0]}, ValueError, "`R` must be a positive finite variance; got -1.0 "
                                          "for channel 1"),
    ({"Q": np.zeros((2, 3))}, ValueError, r"`Q` must be a scalar or have shape \(3,\), \(2, 2\) "
                                          r"or \(3, 2, 2\)"),
    ({"Q": [0.0, -1.0, 0.0]}, ValueError, "`Q` must hold non-negative finite variances"),
    ({"P0": 0.0}, ValueError, "`P0` must be positive definite"),
    ({"x0": np.zeros(3)}, ValueError, r"`x0` must have shape \(2,\) or \(3, 2\)"),
    ({"forgetting": "efra"}, ValueError, "`forgetting` must be one of 'exponential', "
                                         "'directional', 'constant_trace' for RLSBank; got 'efra'"),
    ({"forgetting": "constant_trace", "lam": [0.9, 1.0, 0.9]}, ValueError,
     r"needs an explicit `forgetting_params\['trace'\]`.*\(channel 1\)"),
    ({"forgetting_params": {"eps": 1.0}}, ValueError,
     r"`forgetting_params` key 'eps' is not supported by RLSBank \(mode 'exponential'\); "
     "supported: 'spread_max', 'trace_max'"),
    ({"forgetting_params": [("eps", 1.0)]}, TypeError,
     "`forgetting_params` must be a dict or None; got list"),
    ({"P0": [1.0, 1e308, 1.0]}, ValueError, "`P0` must have entries of magnitude at most "
                                            r"1e\+150 .* got 1e\+308 for channel 1"),
    ({"Q": np.stack([np.eye(2), 1e200 * np.eye(2), np.eye(2)])}, ValueError,
     r"`Q` must have entries of magnitude at most 1e\+150 .* got 1e\+200 for channel 1"),
    ({"check_every": -1}, ValueError, "`check_every` must be >= 0"),
])
def test_constructor_errors_name_the_argument(kwargs, exc, match):
    with pytest.raises(exc, match=match):
        RLSBank(3, 2, **kwargs)


@pytest.mark.parametrize("mode, key, supported", [
    ("exponential", "eps", "'spread_max', 'trace_max'"),     # (the windup cap's: read)
    ("exponential", "lam_min", "'spread_max', 'trace_max'"),
    ("directional", "trace", "'eps'"),
    ("constant_trace", "eps", "'trace', 'ratio'"),
    ("constant_trace", "lam_min", "'trace', 'ratio'"),
])
def test_forgetting_params_the_bank_does_not_read_are_refused(mode, key, supported):
    """A constant only RecursiveLeastSquares reads would be silently ignored by the
    bank's kernels: it is refused, naming the key, the mode and what is supported."""
    params = {"trace": 0.1} if mode == "constant_trace" else {}
    params[key] = 10.0
    with pytest.raises(ValueError, match=re.escape(
            f"`forgetting_params` key '{key}' is not supported by RLSBank (mode '{mode}'); "
            f"supported: {supported}")):
        RLSBank(3, 2, lam=0.95, forgetting=mode, forgetting_params=params)


def test_supported_forgetting_params_reach_every_channel():
    bank = RLSBank(3, 2, lam=0.95, forgetting="constant_trace",
                   forgetting_params={"trace": 0.3, "ratio": 50.0})
    assert_array_equal(bank.forgetting_params["trace"], 0.3)
    assert_array_equal(bank.forgetting_params["ratio"], 50.0)
    bank = RLSBank(3, 2, lam=0.95, forgetting="directional", forgetting_params={"eps": 1e-9})
    assert_array_equal(bank.forgetting_params["eps"], 1e-9)
    assert bank.channel(1).forgetting_params == {"eps": 1e-9}


@pytest.mark.parametrize("Q", [2e-3, [1e-3, 0.0, 5e-3], np.diag([1e-3, 2e-3, 3e-3])])
def test_predict_with_a_random_walk_for_this_call(rng, Q):
    """``predict(Q)`` adds `Q` for that call only, as RecursiveLeastSquares.predict(Q) does
    for each channel."""
    Z, H = _record(rng, N=30, C=3, n=3, missing=0.0, bad_rows=0.0)
    bank = RLSBank(3, 3, lam=0.97, Q=1e-4)
    bank.batch_filter(Z[:20], H[:20])
    channels = [bank.channel(i) for i in range(3)]
    Qc = np.asarray(Q, dtype=float)
    Qc = [Qc[i] if Qc.shape == (3,) else Qc for i in range(3)]
    for k in range(20, 30):
        bank.predict(Q=Q if k % 2 else None)
        bank.update(Z[k], H[k])
        for i, f in enumerate(channels):
            f.predict(Q=Qc[i] if k % 2 else None)
            f.update(Z[k, i], H[k, i])
    for i, f in enumerate(channels):
        assert_allclose(bank.x[i], f.x[:, 0], rtol=1e-12, atol=1e-15)
        assert_allclose(bank.P[i], f.P, rtol=1e-12, atol=1e-18)
    assert_array_equal(bank.Q, np.broadcast_to(1e-4 * np.eye(3), (3, 3, 3)))  # kept


def test_assigning_x_and_P_stores_copies(rng):
    """``bank.x = X`` and ``bank.P = P`` copy: the caller's arrays can change later
    (or be read-only memory) without the bank seeing it."""
    Z, H = _record(rng, N=20, C=4, n=3, missing=0.0, bad_rows=0.0)
    bank = RLSBank(4, 3, lam=0.95)
    X, P = np.full((4, 3), 0.2), np.broadcast_to(20.0 * np.eye(3), (4, 3, 3)).copy()
    bank.x, bank.P = X, P
    X[:], P[:] = 7.0, 9.0
    assert_array_equal(bank.x, 0.2)
    assert_array_equal(bank.P, np.broadcast_to(20.0 * np.eye(3), (4, 3, 3)))
    frozen = np.broadcast_to(np.full(3, 0.1), (4, 3))   # read-only view
    bank.x = frozen
    bank.predict_update(Z[0], H[0])
    bank.batch_filter(Z[1:], H[1:])
    assert_array_equal(frozen, 0.1)
    with pytest.raises(TypeError, match="`x` must be real"):
        bank.x = np.full((4, 3), 1.0j)


def test_batch_filter_flags_and_saver_are_checked(rng):
    Z, H = _record(rng, N=5, C=2, n=2)
    bank = RLSBank(2, 2)
    for kw, match in [({"update_first": "no"}, "`update_first` must be True or False"),
                      ({"store_covariances": 2}, "`store_covariances` must be True or False"),
                      ({"store_means": None}, "`store_means` must be True or False"),
                      ({"saver": 1}, r"`saver` must be None or have a save\(\) method")]:
        with pytest.raises(TypeError, match=match):
            bank.batch_filter(Z, H, **kw)
    assert bank.n_updates == 0


def test_a_warning_turned_error_leaves_the_bank_unchanged(rng):
    """With warnings as errors, a health warning (raised after the step was
    computed) and the skipped-forgetting warning leave every channel as it was."""
    Z, H = _record(rng, N=10, C=4, n=3, missing=0.0, bad_rows=0.0)
    bank = RLSBank(4, 3, lam=0.95, check_every=1, cond_max=1.0 + 1e-9)
    bank.predict()
    calls = [lambda: bank.update(Z[0], H[0]), lambda: bank.predict_update(Z[0], H[0]),
             lambda: bank.batch_filter(Z, H)]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for i, call in enumerate(calls):
            before = pickle.dumps(bank)
            with pytest.raises(NumericalWarning):
                call()
            assert pickle.dumps(bank) == before, i
    quiet = RLSBank(4, 3, lam=0.95)
    quiet.predict()
    quiet.update(Z[0], H[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        before = pickle.dumps(quiet)
        with pytest.raises(ForgettingSkippedWarning):
            quiet.update(Z[1], H[1])
        assert pickle.dumps(quiet) == before


def test_shape_errors_name_the_argument_and_the_channel_count(rng):
    bank = RLSBank(4, 3)
    Z, H = _record(rng, N=10, C=4, n=3, missing=0.0, bad_rows=0.0)
    with pytest.raises(ValueError, match=r"`zs` must have shape \(N, 4\) \(one column per "
                                         r"channel, n_channels = 4\); got \(10, 5\)"):
        bank.batch_filter(np.zeros((10, 5)), H)
    with pytest.raises(ValueError, match=r"`Hs` must have shape \(10, 4, 3\) \(N = len\(zs\) "
                                         r"steps, n_channels = 4, dim_x = 3\); got \(10, 4, 2\)"):
        bank.batch_filter(Z, H[:, :, :2])
    with pytest.raises(ValueError, match=r"`Hs` must have shape \(10, 4, 3\).*got \(9, 4, 3\)"):
        bank.batch_filter(Z, H[:9])
    with pytest.raises(ValueError, match=r"`z` must have shape \(4,\) \(one measurement per "
                                         r"channel\); got \(3,\)"):
        bank.update(np.zeros(3), H[0])
    with pytest.raises(ValueError, match=r"`H` must have shape \(4, 3\)"):
        bank.update(Z[0], H[0, :3])
    with pytest.raises(ValueError, match=r"`Rs` must be a scalar or have shape \(4,\) or "
                                         r"\(10, 4\)"):
        bank.batch_filter(Z, H, Rs=np.ones((10, 3)))
    with pytest.raises(ValueError, match=r"`H` must be finite or NaN \(missing\); got inf at "
                                         r"index \(2, 1\)"):
        bad_H = H[0].copy()
        bad_H[2, 1] = np.inf
        bank.update(Z[0], bad_H)
    H_inf, Z_inf = H.copy(), Z.copy()
    H_inf[7, 3, 2] = -np.inf
    H_inf[9, 0, 0] = np.inf
    Z_inf[8, 1] = np.inf
    with pytest.raises(ValueError, match=r"`Hs` must be finite or NaN \(missing\); got -inf at "
                                         r"index \(7, 3, 2\)"):
        bank.batch_filter(Z_inf, H_inf)
    with pytest.raises(ValueError, match=r"`zs` must be finite or NaN \(missing\); got inf at "
                                         r"index \(8, 1\)"):
        bank.batch_filter(Z_inf, H)
    bank.x = np.zeros((3, 3))
    with pytest.raises(ValueError, match=r"`x` must be an array of shape \(4, 3\)"):
        bank.predict()


def test_failed_calls_leave_the_state_unchanged(rng):
    Z, H = _record(rng, N=20, C=4, n=3, missing=0.0, bad_rows=0.0)
    bank = RLSBank(4, 3, lam=0.95)
    bank.batch_filter(Z[:10], H[:10])
    before = copy.deepcopy(bank.__dict__)
    bad_H = H[10].copy()
    bad_H[1, 1] = np.inf
    calls = [lambda: bank.update(Z[10], bad_H),
             lambda: bank.update(Z[10], H[10], R=[1.0, 0.0, 1.0, 1.0]),
             lambda: bank.batch_filter(Z[10:], H[10:19]),
             lambda: bank.batch_filter(Z[10:], H[10:], Rs=-1.0),
             lambda: bank.batch_filter(Z[10:], np.where(np.arange(3) == 2, np.inf, H[10:])),
             lambda: bank.initialize(Z[:2], H[:2])]
    for call in calls:
        with pytest.raises(ValueError):
            call()
        for key, value in before.items():
            now = bank.__dict__[key]
            if isinstance(value, np.ndarray):
                assert_array_equal(now, value, err_msg=key)
            else:
                assert now == value, key


def test_no_caller_array_is_mutated(rng):
    Z, H = _record(rng, N=20, C=5, n=3)
    lam, R, P0, x0 = np.full(5, 0.9), np.ones(5), np.full(5, 10.0), np.ones((5, 3))
    inputs = [Z, H, lam, R, P0, x0]
    saved = [a.copy() for a in inputs]
    bank = RLSBank(5, 3, lam=lam, R=R, P0=P0, x0=x0)
    x_held, P_held = bank.x, bank.P          # arrays a user holds from the bank
    x_copy, P_copy = x_held.copy(), P_held.copy()
    bank.batch_filter(Z, H)
    bank.predict()
    bank.update(Z[0], H[0])
    bank.initialize(Z[:10], np.nan_to_num(H[:10]))
    lam[0] = 0.5                             # the bank kept its own copy
    assert bank.lam[0] == 0.9
    lam[0] = 0.9
    for a, b in zip(inputs, saved):
        assert_array_equal(a, b)
    assert_array_equal(x_held, x_copy)
    assert_array_equal(P_held, P_copy)
    bank.lam[1] = 0.1                        # the property returns a copy
    assert bank.lam[1] == 0.9


@pytest.mark.parametrize("how", ["copy", "deepcopy", "pickle"])
def test_copies_resume_identically(rng, how):
    Z, H = _record(rng, N=60, C=6, n=3)
    bank = RLSBank(6, 3, lam=0.97, forgetting="directional")
    bank.batch_filter(Z[:30], H[:30])
    twin = {"copy": bank.copy, "deepcopy": lambda: copy.deepcopy(bank),
            "pickle": lambda: pickle.loads(pickle.dumps(bank))}[how]()
    for b in (bank, twin):
        b.batch_filter(Z[30:45], H[30:45])
        for k in range(45, 60):
            b.predict_update(Z[k], H[k])
    assert_array_equal(twin.x, bank.x)
    assert_array_equal(twin.P, bank.P)
    assert twin.n_updates == bank.n_updates == 60


def test_reset_and_repr(rng):
    Z, H = _record(rng, N=10, C=3, n=2)
    bank = RLSBank(3, 2, x0=[1.0, 2.0], P0=5.0)
    bank.batch_filter(Z, H)
    bank.reset()
    assert_array_equal(bank.x, [[1.0, 2.0]] * 3)
    assert_array_equal(bank.P, np.broadcast_to(5.0 * np.eye(2), (3, 2, 2)))
    assert bank.n_updates == 0
    assert "RLSBank object" in repr(bank) and "n_channels = 3" in repr(bank)
    hist = bank.batch_filter(Z, H)
    assert repr(hist) == "<BankHistory: 10 steps of 3 channels>"
    means, covs, means_p, covs_p = hist
    assert means is hist[0] and covs_p is hist.covariances_p and len(hist) == 4
    assert_array_equal(means_p[1:], means[:-1])


def test_forgetting_params_and_exports():
    bank = RLSBank(3, 2, lam=[0.9, 0.8, 0.9], forgetting="constant_trace")
    params = bank.forgetting_params
    assert_allclose(params["trace"], 2 * (1 - np.array([0.9, 0.8, 0.9])))
    assert_array_equal(params["ratio"], 1e4)
    assert "RLSBank" in rlsfilt.__all__ and rlsfilt.RLSBank is RLSBank


def test_docstring_example_runs():
    from rlsfilt.filters import bank

    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for test in finder.find(bank, "rlsfilt.filters.bank", globs={}):
        runner.run(test)
    assert runner.summarize(verbose=False).failed == 0


def test_kernels_are_cached_on_disk():
    from numba.core.caching import FunctionCache  # (rlsfilt's: a subclass, _numba.py)

    for name in ("bank_batch", "bank_batch_parallel", "bank_predict", "bank_update",
                 "bank_unhealthy"):
        assert isinstance(getattr(_kernels_bank, name)._cache, FunctionCache), name


def test_benchmark_script_runs_in_smoke_mode(tmp_path):
    """benchmarks/bench_bank.py runs end to end (tiny sizes; timings are not tested)."""
    import os
    import pathlib
    import subprocess
    import sys

    root = pathlib.Path(__file__).resolve().parents[1]
    env = dict(os.environ, PYTHONPATH=str(root) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.run([sys.executable, str(root / "benchmarks" / "bench_bank.py"),
                           "--smoke"], env=env, cwd=str(tmp_path), capture_output=True,
                          text=True, timeout=600, check=True)
    for row in ("batch (bank)", "handwritten", "loop batch_filter", "prange 2 threads",
                "fit_many rls", "update (bank)", "loop predict+update"):
        assert row in proc.stdout, row


# ----------------------------------------------------------------------
# the deferred predict() and the lazy copies: the bits of the eager recursion
# ----------------------------------------------------------------------
_STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "S", "SI", "K", "lam_t",
          "z", "H")


def _assert_same_bits(a, b, where, order=_STATE):
    """Every attribute of bank `a` equals that of `b` bit for bit (NaN at the same places)."""
    for name in order:
        u, v = getattr(a, name), getattr(b, name)
        assert u.shape == v.shape, (where, name)
        assert_array_equal(u.view(np.int64), v.view(np.int64), err_msg=f"{where}: {name}")
    assert a.n_updates == b.n_updates, where


def _eager(bank):
    """`bank` whose every predict() runs at once: reading ``P`` after it runs
    the time update (`bank_predict`, then an update without a pending one)."""
    predict = bank.predict

    def eager_predict(Q=None):
        predict(Q)
        bank.P                                       # noqa: B018 (runs it now)
        assert bank._pending is None
    bank.predict = eager_predict
    return bank


def _script(Z, H, rng, C, n):
    """Calls on a bank: predicts (twice in a row, with a one-off Q), updates with
    missing data, a batch_filter after a predict, an assigned asymmetric P."""
    Q1 = rng.uniform(0.0, 1e-3, C)
    A = rng.standard_normal((C, n, n))
    P_asym = A @ A.transpose(0, 2, 1) + np.eye(n)
    P_asym[:, 0, 1] += rng.uniform(1e-9, 1e-3, C)   # (stored as given: not symmetric)
    return [
        lambda b: b.predict(), lambda b: b.update(Z[0], H[0]),
        lambda b: b.predict(), lambda b: b.update(Z[1], H[1], R=2.0),
        lambda b: b.predict(), lambda b: b.predict(Q1), lambda b: b.update(Z[2], H[2]),
        lambda b: b.predict(), lambda b: b.batch_filter(Z[3:8], H[3:8]),
        lambda b: b.predict(), lambda b: b.predict_update(Z[8], H[8]),
        lambda b: b.predict(), lambda b: setattr(b, "P", P_asym),
        lambda b: b.update(Z[9], H[9]),
        lambda b: setattr(b, "P", P_asym), lambda b: b.predict(),
        lambda b: b.update(Z[10], H[10]), lambda b: b.predict(),
        lambda b: b.update(Z[11], H[11]),
    ]


@pytest.mark.parametrize("mode", MODES)
def test_deferred_predict_equals_the_eager_one_bit_for_bit_after_every_call(rng, mode):
    """After every prefix of a script of calls, run without reading anything
    (so every predict() stays deferred and is fused into the next update's
    kernel, and no copy is made before it is read), every attribute has the
    bits of a bank whose predict() runs at once. 130 channels: two blocks of
    the streaming kernel. Read in two orders (a lazy copy read before or after
    the state that settles it)."""
    C, n = 130, 3
    Z, H = _record(rng, N=12, C=C, n=n)
    opts = _options(rng, C, mode)
    A = rng.standard_normal((C, n, n))
    opts["Q"] = 1e-3 * (A @ A.transpose(0, 2, 1))   # full matrices, off-diagonal terms
    script = _script(Z, H, np.random.default_rng(1), C, n)
    eager = _eager(RLSBank(C, n, check_every=0, **opts))
    deferred_seen = 0
    for k, call in enumerate(script):
        call(eager)
        lazy = RLSBank(C, n, check_every=0, **opts)
        for done in script[:k + 1]:
            done(lazy)
        deferred_seen += lazy._pending is not None
        order = _STATE if k % 2 else _STATE[::-1]
        _assert_same_bits(lazy, eager, f"after call {k}", order)
    assert deferred_seen >= 6                        # the deferral was exercised


def test_deferred_predict_matches_separate_filters(rng):
    """Streaming predict()/update() pairs equal one RecursiveLeastSquares per
    channel bit for bit (the oracle of the whole module), x_prior and P_post too."""
    C, n = 9, 3
    Z, H = _record(rng, N=30, C=C, n=n, missing=0.0, bad_rows=0.0)
    opts = _options(rng, C, "exponential")
    bank = RLSBank(C, n, **opts)
    filters = [RecursiveLeastSquares(n, lam=opts["lam"][c], R=opts["R"][c], Q=opts["Q"][c],
                                     P0=opts["P0"][c]) for c in range(C)]
    for k in range(30):
        bank.predict()
        bank.update(Z[k], H[k])
        for c, f in enumerate(filters):
            f.predict()
            f.update(Z[k, c], H[k, c])
    for c, f in enumerate(filters):
        assert_array_equal(bank.P_prior[c], f.P_prior)
        assert_array_equal(bank.x_prior[c], f.x_prior[:, 0])
        assert_array_equal(bank.P_post[c], f.P_post)
        assert_array_equal(bank.x[c], f.x[:, 0])
        assert_array_equal(bank.P[c], f.P)


@pytest.mark.parametrize("how", ["copy", "deepcopy", "pickle"])
def test_copies_carry_a_pending_predict(rng, how):
    C, n = 7, 3
    Z, H = _record(rng, N=6, C=C, n=n)
    opts = _options(rng, C, "exponential")
    bank, eager = RLSBank(C, n, **opts), _eager(RLSBank(C, n, **opts))
    for b in (bank, eager):
        b.batch_filter(Z[:3], H[:3])
        b.predict()
    assert bank._pending is not None
    twin = {"copy": bank.copy, "deepcopy": lambda: copy.deepcopy(bank),
            "pickle": lambda: pickle.loads(pickle.dumps(bank))}[how]()
    assert twin._pending is not None
    _assert_same_bits(twin, eager, "the copy, pending")
    for b in (bank, twin, eager):
        b.update(Z[3], H[3])
        b.predict()
        b.update(Z[4], H[4])
    _assert_same_bits(twin, eager, "the copy")
    _assert_same_bits(bank, eager, "the original")


def test_P_assigned_over_a_pending_predict(rng):
    """predict(); P = V; update(): the update starts from V (the time update
    is not applied on top of it), and P_prior is that of the predict."""
    C, n = 5, 2
    Z, H = _record(rng, N=4, C=C, n=n, missing=0.0, bad_rows=0.0)
    bank = RLSBank(C, n, lam=0.9, Q=1e-3, P0=100.0)
    bank.update(Z[0], H[0])
    P_before = bank.P.copy()
    bank.predict()
    V = np.tile(np.diag([3.0, 4.0]), (C, 1, 1))
    bank.P = V
    assert_array_equal(bank.P_prior, P_before * (1.0 / 0.9) + 1e-3 * np.eye(n))  # P il + Q
    bank.update(Z[1], H[1])
    fresh = RLSBank(C, n, lam=0.9, Q=1e-3, P0=V, x0=bank.x_prior)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForgettingSkippedWarning)
        fresh.update(Z[1], H[1])
    assert_array_equal(bank.P, fresh.P)
    assert_array_equal(bank.x, fresh.x)


def test_a_failed_update_leaves_the_predict_pending(rng):
    """A rejected update (an infinite regressor, a bad R, a warning turned into
    an error) leaves the time update pending; the next update then equals the
    eager bank's."""
    C, n = 6, 3
    Z, H = _record(rng, N=4, C=C, n=n, missing=0.0, bad_rows=0.0)
    opts = _options(rng, C, "exponential")
    bank, eager = RLSBank(C, n, **opts), _eager(RLSBank(C, n, **opts))
    for b in (bank, eager):
        b.update(Z[0], H[0])
        b.predict()
    bad_H = H[1].copy()
    bad_H[2, 1] = np.inf
    with pytest.raises(ValueError, match="`H` must be finite"):
        bank.update(Z[1], bad_H)
    assert bank._pending is not None
    with pytest.raises(ValueError, match="`R` must be a positive"):
        bank.update(Z[1], H[1], R=-1.0)
    assert bank._pending is not None
    strict = RLSBank(C, n, check_every=1, cond_max=1.0 + 1e-9, **opts)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        strict.update(Z[0], H[0])
    strict.failed_channels = np.zeros(0, dtype=np.int64)   # (warn again at the next)
    strict.predict()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(NumericalWarning):
            strict.update(Z[1], H[1])
    assert strict._pending is not None
    for b in (bank, eager):
        b.update(Z[1], H[1])
    _assert_same_bits(bank, eager, "after the failed calls")


def test_arrays_handed_out_are_not_lazy_sources(rng):
    """A user who holds ``bank.x`` or ``bank.P`` may write into them: the
    copies x_prior, P_prior, x_post, P_post keep the values of the eager bank."""
    C, n = 4, 3
    Z, H = _record(rng, N=4, C=C, n=n, missing=0.0, bad_rows=0.0)
    opts = _options(rng, C, "exponential")
    bank, eager = RLSBank(C, n, **opts), _eager(RLSBank(C, n, **opts))
    for b in (bank, eager):
        b.predict()
        b.update(Z[0], H[0])
    x_held, P_held = bank.x, bank.P         # before the predict: its sources
    bank.predict()
    bank.update(Z[1], H[1])
    x_held[...] = 7.0
    P_held[...] = 9.0
    eager.predict()
    eager.update(Z[1], H[1])
    _assert_same_bits(bank, eager, "held before the predict")
    for b in (bank, eager):                  # (nothing handed out since this update)
        b.predict()
        b.update(Z[2], H[2])
    bank.predict()
    x_now = bank.x                           # held between predict and update
    bank.update(Z[3], H[3])
    x_now[...] = -1.0
    P_now = bank.P                           # held after the update
    bank.predict()
    P_now[...] = -2.0
    for b in (eager,):
        b.predict()
        b.update(Z[3], H[3])
        b.predict()
    _assert_same_bits(bank, eager, "held after the predict")


# ----------------------------------------------------------------------
# the adaptation switch and frames of rows (#31; the contract suite checks
# them too, through a bank whose channels share one regressor)
# ----------------------------------------------------------------------
@pytest.mark.parametrize("mode", MODES)
def test_frozen_bank_equals_frozen_filters(rng, mode):
    """While frozen each channel gives the residual and innovation variance of
    its own frozen `RecursiveLeastSquares` (NaN where its sample is missing),
    and ``x``, ``P`` stay bit-unchanged; ``channel(i)`` of a frozen bank is a
    frozen filter; after ``unfreeze`` the bank continues as one that never saw
    the frozen rows."""
    Z, H = _record(rng, N=60, C=7)
    C, n = Z.shape[1], H.shape[2]
    opts = _options(rng, C, mode)
    bank = RLSBank(C, n, **opts)
    bank.update_block(Z[:30], H[:30])
    twin = bank.copy()
    filters = [bank.channel(c) for c in range(C)]
    x0, P0 = bank.x.copy(), bank.P.copy()
    assert bank.freeze() is bank and bank.frozen and not bank.adapt
    assert all(bank.channel(c).frozen for c in range(C))
    for f in filters:
        f.freeze()
    for k in range(30, 40):
        bank.predict_update(Z[k], H[k])
        for c, f in enumerate(filters):
            if np.isnan(H[k, c]).any():
                assert np.isnan(bank.y[c]) and np.isnan(bank.S[c])
                continue
            f.predict_update(Z[k, c], H[k, c])
            assert_allclose(bank.y[c], f.y[0, 0], rtol=1e-14, atol=1e-14)
            assert_allclose(bank.S[c], f.S[0, 0], rtol=1e-14)
        assert_array_equal(np.isnan(bank.y), np.isnan(Z[k]) | np.isnan(H[k]).any(axis=1))
        assert not bank.K.any()
        assert_array_equal(bank.x, x0)
        assert_array_equal(bank.P, P0)
    bank.update_block(Z[40:45], H[40:45])
    hist = bank.batch_filter(Z[45:50], H[45:50])
    assert_array_equal(hist.means, np.broadcast_to(x0, hist.means.shape))
    assert_array_equal(bank.P, P0)
    assert bank.n_updates == twin.n_updates
    bank.adapt = True
    for b in (bank, twin):
        b.update_block(Z[50:], H[50:])
    _assert_same_bits(bank, twin, "after unfreeze")


def test_update_block_equals_rows_per_channel(rng):
    """``update_block`` with channel-specific regressors, missing samples and
    variances per step and channel equals ``predict_update`` row by row, bit for
    bit; a rejected block changes nothing."""
    Z, H = _record(rng, N=50, C=9)
    C, n = Z.shape[1], H.shape[2]
    opts = _options(rng, C, "exponential")
    Rs = rng.uniform(0.5, 2.0, (50, C))
    a, b = RLSBank(C, n, **opts), RLSBank(C, n, **opts)
    for lo, hi in ((0, 1), (1, 20), (20, 50)):
        assert a.update_block(Z[lo:hi], H[lo:hi], Rs[lo:hi]) is a
        for k in range(lo, hi):
            b.predict_update(Z[k], H[k], Rs[k])
        _assert_same_bits(a, b, f"rows {lo}:{hi}")
    before = pickle.dumps(a)
    with pytest.raises(ValueError, match="`Hs` must have shape"):
        a.update_block(Z[:5], H[:4])
    assert pickle.dumps(a) == before


def test_a_read_only_record_is_copied_not_compiled_for():
    """A read-only record (a pandas frame's values, a memory map) gives the same numbers
    as a writable one and compiles no kernel of its own (numba types read-only arrays
    apart: about 20 s of CPU per kernel)."""
    from rlsfilt.filters import _kernels_bank as kb

    rng = np.random.default_rng(3)
    Z, H = rng.standard_normal((40, 3)), rng.standard_normal((40, 3, 2))
    writable = RLSBank(3, 2, lam=0.98)
    expected = writable.batch_filter(Z, H).means
    writable.predict_update(Z[0], H[0])
    counts = [len(kb.bank_batch.signatures), len(kb.bank_update.signatures)]
    for a in (Z, H):
        a.setflags(write=False)
    bank = RLSBank(3, 2, lam=0.98)
    assert_array_equal(bank.batch_filter(Z, H).means, expected)
    bank.predict_update(Z[0], H[0])
    assert_array_equal(bank.x, writable.x)
    assert [len(kb.bank_batch.signatures), len(kb.bank_update.signatures)] == counts


@pytest.mark.parametrize("C", [2, 3, 37])
@pytest.mark.parametrize("n, k0", [(1, 12), (3, 3), (6, 6), (4, 20)])
def test_initialize_gives_each_channel_the_bits_of_its_own_bank(C, n, k0):
    """The batch start of a channel does not depend on the other channels of the bank: a
    bank of 1 channel, or of a few, gets the bits of the same channel in a bank of C (it
    did not: the transposed (C, k0, n) views had strides that depend on C, and matmul took
    BLAS for 1 channel and NumPy's loop for more, 1 ulp apart; so a dask block of one
    channel differed from fit_many on the whole fleet)."""
    rng = np.random.default_rng(100 * C + 10 * n + k0)
    H = rng.standard_normal((k0, C, n)) * rng.uniform(0.5, 3.0, (1, C, n))
    z = rng.standard_normal((k0, C))
    lam = rng.uniform(0.9, 1.0, C)
    whole = RLSBank(C, n, lam=lam, R=rng.uniform(0.5, 2.0, C))
    whole.initialize(z, H)
    for sel in ([0], [C - 1], [C - 1, 0], list(range(1, C))):
        part = RLSBank(len(sel), n, lam=lam[sel], R=whole.R[sel])
        part.initialize(z[:, sel], H[:, sel])
        assert_array_equal(part.x, whole.x[sel])
        assert_array_equal(part.P, whole.P[sel])
