"""RecursiveLeastSquares against its oracles: filterpy's KalmanFilter, lstsq, weighted LS."""

import warnings

import numpy as np
import pytest
from conftest import arx_record
from filterpy.common import Saver
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import ForgettingSkippedWarning, RecursiveLeastSquares


def _kalman_as_rls(dim_x, lam, q, r, P0):
    kf = KalmanFilter(dim_x=dim_x, dim_z=1)
    kf.F = np.eye(dim_x)
    kf.Q = q * np.eye(dim_x)
    kf.R = np.array([[r]])
    kf.P = P0 * np.eye(dim_x)
    kf.alpha = np.sqrt(1.0 / lam)   # filterpy's fading memory: P <- alpha^2 P
    return kf


# ----------------------------------------------------------------------
# the exactness contract with filterpy's KalmanFilter
# ----------------------------------------------------------------------
@pytest.mark.parametrize("lam, q, r", [(1.0, 0.0, 1.0), (0.97, 1e-4, 0.3), (0.9, 0.0, 2.0)])
def test_equals_filterpy_kalman_filter(rng, lam, q, r):
    Hs, zs = arx_record(rng, n_samples=402)
    kf = _kalman_as_rls(4, lam, q, r, 100.0)
    rls = RecursiveLeastSquares(4, lam=lam, Q=q, R=r, P0=100.0)
    for z, phi in zip(zs, Hs):
        kf.predict()
        kf.update(np.array([[z]]), H=phi.reshape(1, -1))
        rls.predict()
        rls.update(z, H=phi)
        assert_allclose(rls.x, kf.x, rtol=1e-8, atol=1e-12)
        assert_allclose(rls.P, kf.P, rtol=1e-8, atol=1e-12 * np.abs(kf.P).max())
        assert_allclose(rls.y, kf.y, rtol=1e-8, atol=1e-12)
        assert_allclose(rls.S, kf.S, rtol=1e-8)
        assert_allclose(rls.SI, kf.SI, rtol=1e-8)
        assert_allclose(rls.K, kf.K, rtol=1e-8, atol=1e-14)
        assert_allclose(rls.log_likelihood, kf.log_likelihood, rtol=1e-8)
        assert_allclose(rls.likelihood, kf.likelihood, rtol=1e-8)
        assert_allclose(rls.mahalanobis, kf.mahalanobis, rtol=1e-8)
        assert_allclose(rls.x_prior, kf.x_prior, rtol=1e-8, atol=1e-12)
        assert_allclose(rls.P_prior, kf.P_prior, rtol=1e-8, atol=1e-12 * np.abs(kf.P).max())
    assert rls.H.shape == (1, 4) and rls.z.shape == (1, 1)


def test_recursive_residuals_are_brown_durbin_evans(rng):
    """y / sqrt(S), R = 1, exact start: w_t = (z_t - h_t b_{t-1}) / sqrt(1 + h_t (X'X)^-1 h_t')."""
    Hs, zs = arx_record(rng, n_samples=60)
    k0 = 4
    rls = RecursiveLeastSquares(4)
    rls.initialize(zs[:k0], Hs[:k0])
    for t in range(k0, len(zs)):
        X = Hs[:t]
        b = np.linalg.lstsq(X, zs[:t], rcond=None)[0]
        h = Hs[t]
        w = (zs[t] - h @ b) / np.sqrt(1.0 + h @ np.linalg.solve(X.T @ X, h))
        rls.predict_update(zs[t], Hs[t])
        assert_allclose(rls.y[0, 0] / np.sqrt(rls.S[0, 0]), w, rtol=1e-8)


# ----------------------------------------------------------------------
# least-squares identities
# ----------------------------------------------------------------------
def test_initialize_then_update_is_lstsq_at_every_step(rng):
    Hs, zs = arx_record(rng, n_samples=300)
    k0 = 6
    rls = RecursiveLeastSquares(4, R=0.5)
    rls.initialize(zs[:k0], Hs[:k0])
    assert_allclose(rls.x[:, 0], np.linalg.lstsq(Hs[:k0], zs[:k0], rcond=None)[0], rtol=1e-10)
    assert_allclose(rls.P, 0.5 * np.linalg.inv(Hs[:k0].T @ Hs[:k0]), rtol=1e-8)
    for t in range(k0, len(zs)):
        rls.predict_update(zs[t], Hs[t])
        ls = np.linalg.lstsq(Hs[:t + 1], zs[:t + 1], rcond=None)[0]
        assert_allclose(rls.x[:, 0], ls, rtol=1e-8, atol=1e-10)
    assert_allclose(rls.P, 0.5 * np.linalg.inv(Hs.T @ Hs), rtol=1e-7)


def test_initialize_uses_qr_not_normal_equations():
    """A regressor with condition number 1e8: normal equations (cond 1e16) lose every digit."""
    rng = np.random.default_rng(1)
    U, _ = np.linalg.qr(rng.standard_normal((40, 3)))
    V, _ = np.linalg.qr(rng.standard_normal((3, 3)))
    Hs = U @ np.diag([1.0, 1e-4, 1e-8]) @ V.T
    theta = np.array([1.0, -2.0, 3.0])
    zs = Hs @ theta
    rls = RecursiveLeastSquares(3)
    rls.initialize(zs, Hs)
    assert_allclose(rls.x[:, 0], theta, rtol=1e-6)


def _badly_scaled_arx(n_samples=600):
    """An ARX(2, 2) record with u ~ 1e-8 (say amperes of a nA sensor) and y ~ 1e6,
    the transient dropped so that y is large from the first row on."""
    rng = np.random.default_rng(7)
    N = n_samples + 300
    u = 1e-8 * rng.standard_normal(N)
    y = np.zeros(N)
    for t in range(2, N):
        y[t] = (1.5 * y[t - 1] - 0.7 * y[t - 2] + 1e14 * (u[t - 1] + 0.5 * u[t - 2])
                + 1e4 * rng.standard_normal())
    return u[300:], y[300:]


def test_initialize_rank_decision_ignores_column_units():
    """Columns of 1e6 beside columns of 1e-8 are full rank; the start is exact LS."""
    u, y = _badly_scaled_arx(40)
    Hs = np.column_stack([-y[1:-1], -y[:-2], u[1:-1], u[:-2]])
    zs = y[2:]
    k0 = 30
    assert np.linalg.matrix_rank(Hs[:k0]) < 4          # the unscaled decision is wrong
    rls = RecursiveLeastSquares(4, R=2.0)
    rls.initialize(zs[:k0], Hs[:k0])
    d = np.linalg.norm(Hs[:k0], axis=0)
    theta = np.linalg.lstsq(Hs[:k0] / d, zs[:k0], rcond=None)[0] / d
    assert_allclose(rls.x[:, 0], theta, rtol=1e-10)
    Ps = np.linalg.inv((Hs[:k0] / d).T @ (Hs[:k0] / d))
    assert_allclose(rls.P * np.outer(d, d), 2.0 * Ps, rtol=1e-9)
    assert_array_equal(rls.P, rls.P.T)


def test_arx_rls_equals_ls_with_regressors_in_very_different_units():
    from rlsfilt import ARX

    u, y = _badly_scaled_arx()
    ls = ARX(2, 2).fit(u, y, method="ls")
    # P is ill-conditioned in these units (cond ~ 1e28) although the estimate is exact:
    # the health check is switched off
    rls = ARX(2, 2).fit(u, y, method="rls", check_every=0)
    assert rls.k0_ == 4
    assert_allclose(rls.theta_, ls.theta_, rtol=1e-9)
    assert_allclose(ls.theta_, [-1.5, 0.7, 1e14, 0.5e14], rtol=0.05)


def test_ridge_identity_for_diffuse_prior(rng):
    """lam = 1, P0 = d I, x0 = 0: x = (Phi'Phi + I/d)^-1 Phi'Y exactly."""
    Hs, zs = arx_record(rng, n_samples=100)
    d = 10.0
    rls = RecursiveLeastSquares(4, P0=d)
    rls.batch_filter(zs, Hs)
    ridge = np.linalg.solve(Hs.T @ Hs + np.eye(4) / d, Hs.T @ zs)
    assert_allclose(rls.x[:, 0], ridge, rtol=1e-9)
    assert_allclose(rls.P, np.linalg.inv(Hs.T @ Hs + np.eye(4) / d), rtol=1e-8)


@pytest.mark.parametrize("lam", [0.99, 0.9])
def test_forgetting_is_exponentially_weighted_least_squares(rng, lam):
    Hs, zs = arx_record(rng, n_samples=200)
    k0 = 8
    rls = RecursiveLeastSquares(4, lam=lam)
    rls.initialize(zs[:k0], Hs[:k0])
    for t in range(k0, len(zs)):
        rls.predict_update(zs[t], Hs[t])
        w = np.sqrt(lam ** np.arange(t, -1, -1.0))
        ewls = np.linalg.lstsq(Hs[:t + 1] * w[:, None], zs[:t + 1] * w, rcond=None)[0]
        assert_allclose(rls.x[:, 0], ewls, rtol=1e-8, atol=1e-10)


def test_forgetting_with_prior_weights_prior_by_lam_power(rng):
    """From P0 = d I the prior is weighted by lam^t in the normal equations."""
    Hs, zs = arx_record(rng, n_samples=80)
    lam, d = 0.95, 50.0
    rls = RecursiveLeastSquares(4, lam=lam, P0=d)
    rls.batch_filter(zs, Hs)
    t = len(zs)
    w = lam ** np.arange(t - 1, -1, -1.0)
    A = (Hs * w[:, None]).T @ Hs + lam ** t * np.eye(4) / d
    assert_allclose(rls.x[:, 0], np.linalg.solve(A, (Hs * w[:, None]).T @ zs), rtol=1e-8)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 6), extra=st.integers(0, 30),
       r=st.floats(0.01, 100.0))
def test_property_lstsq_equivalence(seed, n, extra, r):
    rng = np.random.default_rng(seed)
    N = n + 2 + extra
    Hs = rng.standard_normal((N, n))
    zs = Hs @ rng.standard_normal(n) + rng.standard_normal(N)
    rls = RecursiveLeastSquares(n, R=r)
    rls.initialize(zs[:n + 2], Hs[:n + 2])
    rls.batch_filter(zs[n + 2:], Hs[n + 2:])
    assert_allclose(rls.x[:, 0], np.linalg.lstsq(Hs, zs, rcond=None)[0], rtol=1e-7, atol=1e-9)
    assert_allclose(rls.P, r * np.linalg.inv(Hs.T @ Hs), rtol=1e-6, atol=1e-12)


# ----------------------------------------------------------------------
# several outputs sharing one regressor
# ----------------------------------------------------------------------
def test_multi_output_equals_separate_filters(rng):
    Hs, _ = arx_record(rng, n_samples=150)
    Z = Hs @ rng.standard_normal((4, 3)) + 0.1 * rng.standard_normal((len(Hs), 3))
    multi = RecursiveLeastSquares(4, dim_z=3, lam=0.98, Q=1e-5, R=0.2)
    singles = [RecursiveLeastSquares(4, lam=0.98, Q=1e-5, R=0.2) for _ in range(3)]
    for z, phi in zip(Z, Hs):
        multi.predict_update(z, phi)
        for j, f in enumerate(singles):
            f.predict_update(z[j], phi)
    for j, f in enumerate(singles):
        assert_allclose(multi.x[:, j], f.x[:, 0], rtol=1e-10, atol=1e-13)
        assert_allclose(multi.P, f.P, rtol=1e-12)
        assert_allclose(multi.y[j, 0], f.y[0, 0], rtol=1e-10, atol=1e-13)
    assert multi.x.shape == (4, 3) and multi.y.shape == (3, 1) and multi.S.shape == (3, 3)
    assert multi.K.shape == (4, 1)


def test_multi_output_equals_kalman_filter_of_stacked_parameters(rng):
    """Shared P with one R: the KF of vec(X) with H = kron(I, phi) and P = kron(I, P)."""
    Hs, _ = arx_record(rng, n_samples=60)
    Z = Hs @ rng.standard_normal((4, 2)) + 0.1 * rng.standard_normal((len(Hs), 2))
    rls = RecursiveLeastSquares(4, dim_z=2, R=0.5, P0=10.0, lam=0.95)
    kf = KalmanFilter(dim_x=8, dim_z=2)
    kf.P, kf.R, kf.Q = 10.0 * np.eye(8), 0.5 * np.eye(2), np.zeros((8, 8))
    kf.alpha = np.sqrt(1 / 0.95)
    for z, phi in zip(Z, Hs):
        rls.predict_update(z, phi)
        kf.predict()
        kf.update(z.reshape(2, 1), H=np.kron(np.eye(2), phi.reshape(1, -1)))
        assert_allclose(rls.x.T.reshape(-1, 1), kf.x, rtol=1e-8, atol=1e-11)
        assert_allclose(rls.log_likelihood, kf.log_likelihood, rtol=1e-8)
        assert_allclose(rls.mahalanobis, kf.mahalanobis, rtol=1e-8)
        assert_allclose(np.kron(np.eye(2), rls.P), kf.P, rtol=1e-8, atol=1e-12)


# ----------------------------------------------------------------------
# batch_filter
# ----------------------------------------------------------------------
@pytest.mark.parametrize("update_first", [False, True])
def test_batch_filter_equals_filterpy_batch_filter(rng, update_first):
    Hs, zs = arx_record(rng, n_samples=120)
    lam, q = 0.95, 1e-4
    kf = _kalman_as_rls(4, lam, q, 1.0, 1e4)
    rls = RecursiveLeastSquares(4, lam=lam, Q=q)
    Hk = [h.reshape(1, -1) for h in Hs]
    kfm, kfc, kfmp, kfcp = kf.batch_filter([np.array([[z]]) for z in zs], Hs=Hk,
                                           update_first=update_first)
    m, c, mp, cp = rls.batch_filter(zs, Hs, update_first=update_first)
    assert m.shape == kfm.shape == (len(zs), 4, 1) and c.shape == (len(zs), 4, 4)
    assert_allclose(m, kfm, rtol=1e-8, atol=1e-10)
    assert_allclose(mp, kfmp, rtol=1e-8, atol=1e-10)
    scale = np.abs(kfc).max(axis=(1, 2))[:, None, None]
    assert np.all(np.abs(c - kfc) <= 1e-8 * scale)
    assert np.all(np.abs(cp - kfcp) <= 1e-8 * np.abs(kfcp).max(axis=(1, 2))[:, None, None])


@pytest.mark.parametrize("update_first", [False, True])
def test_batch_filter_equals_stepwise_loop_exactly(rng, update_first):
    Hs, zs = arx_record(rng, n_samples=100)
    zs = zs.copy()
    zs[[10, 55, len(zs) - 1]] = np.nan
    a = RecursiveLeastSquares(4, lam=0.97, Q=1e-6)
    b = a.copy()
    m, c, mp, cp = a.batch_filter(zs, Hs, update_first=update_first)
    for k, (z, phi) in enumerate(zip(zs, Hs)):
        if not update_first:
            b.predict()
            assert_array_equal(mp[k], b.x)
            assert_array_equal(cp[k], b.P)
        b.update(z, phi)
        assert_array_equal(m[k], b.x)
        assert_array_equal(c[k], b.P)
        if update_first:
            b.predict()
            assert_array_equal(mp[k], b.x)
            assert_array_equal(cp[k], b.P)
    for name in ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z",
                 "H"):
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.log_likelihood == b.log_likelihood


def test_batch_filter_without_covariances(rng):
    Hs, zs = arx_record(rng, n_samples=50)
    a, b = RecursiveLeastSquares(4), RecursiveLeastSquares(4)
    m, c, mp, cp = a.batch_filter(zs, Hs, store_covariances=False)
    m2, _, mp2, _ = b.batch_filter(zs, Hs)
    assert c is None and cp is None
    assert_array_equal(m, m2)
    assert_array_equal(mp, mp2)


def test_batch_filter_accepts_rs_and_list_rows(rng):
    Hs, zs = arx_record(rng, n_samples=40)
    Rs = rng.uniform(0.5, 2.0, len(zs))
    a, b = RecursiveLeastSquares(4), RecursiveLeastSquares(4)
    a.batch_filter(list(zs), [h.reshape(1, -1) for h in Hs], Rs=Rs)
    for z, phi, r in zip(zs, Hs, Rs):
        b.predict_update(z, phi, R=r)
    assert_array_equal(a.x, b.x)


# ----------------------------------------------------------------------
# missing measurements
# ----------------------------------------------------------------------
@pytest.mark.parametrize("missing", [None, np.nan, [np.nan]])
@pytest.mark.parametrize("gate", [None, 1e300])
def test_missing_measurement_keeps_estimate(rng, missing, gate):
    """Without and with a gate (that never fires) the documented diagnostics are left."""
    Hs, zs = arx_record(rng, n_samples=20)
    rls = RecursiveLeastSquares(4, lam=0.9, gate=gate)
    rls.batch_filter(zs[:10], Hs[:10])
    rls.predict()
    x, P = rls.x.copy(), rls.P.copy()
    rls.update(missing, Hs[10])
    assert_array_equal(rls.x, x)
    assert_array_equal(rls.P, P)
    assert_array_equal(rls.x_post, x)
    assert np.isnan(rls.y).all() and np.isnan(rls.z).all()
    assert_array_equal(rls.K, 0.0)
    assert rls.S[0, 0] == pytest.approx(Hs[10] @ P @ Hs[10] + 1.0, rel=1e-12)
    assert rls.log_likelihood == 0.0 and rls.likelihood == 1.0
    assert np.isnan(rls.mahalanobis)


@pytest.mark.parametrize("store", [True, False])
@pytest.mark.parametrize("gate", [None, 1e300])
def test_missing_last_sample_of_batch_diagnostics(rng, store, gate):
    """The fused loop (no gate, no covariance histories) and the step loop alike."""
    Hs, zs = arx_record(rng, n_samples=20)
    zs[-1] = np.nan
    rls = RecursiveLeastSquares(4, lam=0.9, gate=gate)
    rls.batch_filter(zs, Hs, store_covariances=store)
    assert rls.log_likelihood == 0.0 and rls.likelihood == 1.0
    assert np.isnan(rls.mahalanobis)
    assert np.isnan(rls.y).all() and np.isnan(rls.z).all()
    assert_array_equal(rls.K, 0.0)


def test_missing_in_batch_equals_skipping_the_update(rng):
    Hs, zs = arx_record(rng, n_samples=60)
    zm = list(zs)
    zm[30] = None
    a, b = RecursiveLeastSquares(4, lam=0.95), RecursiveLeastSquares(4, lam=0.95)
    m, *_ = a.batch_filter(zm, Hs)
    for k in range(len(zs)):
        b.predict()
        if k != 30:
            b.update(zs[k], Hs[k])
    assert_allclose(a.x, b.x, rtol=0, atol=0)
    assert_array_equal(m[30], m[29])


def test_multi_output_nan_in_one_output_skips_sample(rng):
    rls = RecursiveLeastSquares(2, dim_z=2)
    rls.update([1.0, np.nan], [1.0, 2.0])
    assert_array_equal(rls.x, 0.0)


# ----------------------------------------------------------------------
# filterpy's tools and helpers
# ----------------------------------------------------------------------
def test_saver_round_trip(rng):
    Hs, zs = arx_record(rng, n_samples=30)
    rls = RecursiveLeastSquares(4, lam=0.98)
    saver = Saver(rls)
    xs, Ps, ys, Ks, lls = [], [], [], [], []
    for z, phi in zip(zs, Hs):
        rls.predict_update(z, phi)
        saver.save()
        xs.append(rls.x.copy())
        Ps.append(rls.P.copy())
        ys.append(rls.y.copy())
        Ks.append(rls.K.copy())
        lls.append(rls.log_likelihood)
    saver.to_array()
    assert saver.x.shape == (len(zs), 4, 1) and saver.P.shape == (len(zs), 4, 4)
    assert_array_equal(saver.x, np.array(xs))
    assert_array_equal(saver.P, np.array(Ps))
    assert_array_equal(saver.y, np.array(ys))
    assert_array_equal(saver.K, np.array(Ks))
    assert_array_equal(saver.log_likelihood, np.array(lls))
    assert_array_equal(saver.lam, 0.98)


def test_saver_through_batch_filter(rng):
    Hs, zs = arx_record(rng, n_samples=25)
    rls = RecursiveLeastSquares(4)
    saver = Saver(rls)
    m, *_ = rls.batch_filter(zs, Hs, saver=saver)
    saver.to_array()
    assert_array_equal(saver.x, m)
    assert len(saver) == len(zs)


def test_helpers(rng):
    Hs, zs = arx_record(rng, n_samples=40)
    rls = RecursiveLeastSquares(4, lam=0.9, Q=1e-3)
    rls.batch_filter(zs[:30], Hs[:30])
    x, P = rls.get_prediction()
    assert_array_equal(x, rls.x)
    assert_allclose(P, rls.P / 0.9 + 1e-3 * np.eye(4), rtol=1e-15)
    phi = Hs[30]
    assert_allclose(rls.measurement_of_state(rls.x, phi), [[phi @ rls.x[:, 0]]], rtol=1e-14)
    assert_allclose(rls.residual_of(zs[30], phi), [[zs[30] - phi @ rls.x[:, 0]]], rtol=1e-14)
    s = phi @ rls.P @ phi + rls.R
    expected = -0.5 * (np.log(2 * np.pi * s) + (zs[30] - phi @ rls.x[:, 0]) ** 2 / s)
    assert_allclose(rls.log_likelihood_of(zs[30], phi), expected, rtol=1e-12)
    c = rls.copy()
    c.predict_update(zs[31], Hs[31])
    assert not np.array_equal(c.x, rls.x)
    assert "RecursiveLeastSquares object" in repr(rls) and "lam = 0.9" in repr(rls)


def test_reset_returns_to_construction_state(rng):
    Hs, zs = arx_record(rng, n_samples=20)
    rls = RecursiveLeastSquares(4, P0=5.0, x0=[1.0, 2.0, 3.0, 4.0])
    rls.batch_filter(zs, Hs)
    rls.reset()
    assert_array_equal(rls.x, [[1.0], [2.0], [3.0], [4.0]])
    assert_array_equal(rls.P, 5.0 * np.eye(4))
    assert_array_equal(rls.y, 0.0)


def test_callers_arrays_are_not_modified(rng):
    Hs, zs = arx_record(rng, n_samples=30)
    Hs0, zs0 = Hs.copy(), zs.copy()
    P0 = 3.0 * np.eye(4)
    x0 = np.ones((4, 1))
    Q = 1e-3 * np.eye(4)
    rls = RecursiveLeastSquares(4, lam=0.9, P0=P0, x0=x0, Q=Q)
    rls.initialize(zs[:5], Hs[:5])
    rls.batch_filter(zs, Hs)
    for z, phi in zip(zs, Hs):
        rls.predict_update(z, phi)
    rls.reset()
    assert_array_equal(Hs, Hs0)
    assert_array_equal(zs, zs0)
    assert_array_equal(P0, 3.0 * np.eye(4))
    assert_array_equal(x0, 1.0)
    assert_array_equal(Q, 1e-3 * np.eye(4))
    phi = Hs[0].copy()
    rls.update(zs[0], phi)
    rls.H[0, 0] = 123.0   # the filter's own copy, not the caller's row
    assert_array_equal(phi, Hs0[0])


def test_accepted_shapes(rng):
    rls = RecursiveLeastSquares(2, R=np.array([[2.0]]))
    assert rls.R == 2.0
    rls.update(np.array([1.0]), np.array([[1.0, 0.5]]))
    rls.update(np.array([[1.0]]), [1.0, 0.5])
    one = RecursiveLeastSquares(1)
    one.update(2.0, 1.0)
    assert one.x.shape == (1, 1)


# ----------------------------------------------------------------------
# warnings and numerical health
# ----------------------------------------------------------------------
def test_warns_once_when_forgetting_is_skipped():
    rls = RecursiveLeastSquares(2, lam=0.9)
    rls.predict()
    rls.update(1.0, [1.0, 0.0])
    with pytest.warns(ForgettingSkippedWarning, match="predict_update"):
        rls.update(1.0, [0.0, 1.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rls.update(1.0, [1.0, 1.0])   # only once


def test_no_warning_without_forgetting():
    rls = RecursiveLeastSquares(2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _ in range(3):
            rls.update(1.0, [1.0, 0.5])


def test_long_run_keeps_P_symmetric_positive_definite():
    rng = np.random.default_rng(7)
    N = 100_000
    Hs, zs = arx_record(rng, n_samples=N + 2, noise_std=0.05)
    rls = RecursiveLeastSquares(4, lam=0.95)
    m, *_ = rls.batch_filter(zs, Hs, store_covariances=False)
    P = rls.P
    assert_array_equal(P, P.T)
    assert np.linalg.eigvalsh(P)[0] > 0
    assert np.all(np.isfinite(m))
    assert_allclose(rls.x[:, 0], [-1.5, 0.7, 1.0, 0.5], atol=0.05)
