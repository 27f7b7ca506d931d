"""The Rauch-Tung-Striebel smoother of the parameter trajectory against its oracles.

* the closed-form solution: the smoothed trajectory of the random walk
  ``x_t = x_{t-1} + w_t``, ``z_t = H_t x_t + v_t`` is the least-squares solution
  of the stacked (banded) problem with the prior, and its covariances are the
  blocks of the inverse of the normal matrix (1e-10);
* statsmodels' ``smoothed_state`` of the same state-space model (1e-8);
* filterpy's ``KalmanFilter.rts_smoother`` with ``F = I`` (1e-12);
* exponential forgetting as its equivalent time-varying random walk
  ``Q_t = (1/lam - 1) P_t``;
* the bank: each channel equals its own filter.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rlsfilt import RecursiveLeastSquares, RLSBank
from rlsfilt.filters.smoother import SmoothedTrajectory, rts_smoother


def drifting_record(rng, N=120, n=3, q=0.05, r=0.1):
    """Regressors, measurements and the true random-walk trajectory."""
    H = rng.standard_normal((N, n))
    x = np.array([1.0, -0.5, 0.3, 0.2][:n]) + np.cumsum(q * rng.standard_normal((N, n)), 0)
    z = np.sum(H * x, axis=1) + r * rng.standard_normal(N)
    return H, z, x


def banded_least_squares(z, H, x0, P_first, Qs, Rs):
    """The smoothed trajectory as one least-squares problem in all states x_0..x_{N-1}:
    whitened rows for the prior ``x_0 ~ N(x0, P_first)``, the increments
    ``x_t - x_{t-1} ~ N(0, Qs[t])`` and the measurements ``z_t - H_t x_t ~ N(0, Rs[t])``.
    Returns the solution ``(N, n)`` and the covariance blocks ``(N, n, n)`` of the
    inverse normal matrix (missing measurements, NaN, contribute no row)."""
    N, n = H.shape
    rows, rhs = [], []

    def block(cov, coefs, target):
        Li = np.linalg.inv(np.linalg.cholesky(cov))          # whitening: L^-1 r
        A = np.zeros((n, N * n))
        for t, c in coefs:
            A[:, t * n:(t + 1) * n] += c * Li
        rows.append(A)
        rhs.append(Li @ target)

    block(P_first, [(0, 1.0)], x0)
    for t in range(1, N):
        block(Qs[t], [(t, 1.0), (t - 1, -1.0)], np.zeros(n))
    for t in range(N):
        if np.isnan(z[t]):
            continue
        A = np.zeros((1, N * n))
        A[0, t * n:(t + 1) * n] = H[t] / np.sqrt(Rs[t])
        rows.append(A)
        rhs.append(np.array([z[t] / np.sqrt(Rs[t])]))
    A, b = np.vstack(rows), np.concatenate(rhs)
    Qf, Rf = np.linalg.qr(A)
    sol = np.linalg.solve(Rf, Qf.T @ b)
    Rinv = np.linalg.inv(Rf)
    cov = Rinv @ Rinv.T                                      # (A^T A)^-1
    blocks = np.array([cov[t * n:(t + 1) * n, t * n:(t + 1) * n] for t in range(N)])
    return sol.reshape(N, n), blocks


def test_random_walk_equals_banded_least_squares(rng):
    H, z, _ = drifting_record(rng)
    N, n = H.shape
    z[[10, 57]] = np.nan                                     # missing samples
    Q = np.diag([0.05, 0.02, 0.08]) ** 2
    Rs = 0.1 ** 2 * (1.0 + rng.random(N))                    # a variance per step
    x0, P0 = np.array([0.5, 0.0, 0.0]), np.diag([2.0, 1.0, 3.0])
    rls = RecursiveLeastSquares(n, R=0.01, Q=Q, P0=P0, x0=x0)
    out = rls.smooth(z, H, Rs)
    means, covs = banded_least_squares(z, H, x0, P0 + Q, np.broadcast_to(Q, (N, n, n)), Rs)
    assert_allclose(out.means[:, :, 0], means, rtol=0, atol=1e-10 * np.abs(means).max())
    assert_allclose(out.covariances, covs, rtol=0, atol=1e-10 * np.abs(covs).max())
    # the last smoothed state is the last filtered one
    assert_allclose(out.means[-1], out.filtered_means[-1], rtol=0, atol=0)


@pytest.mark.parametrize("Q", [0.0, 1e-4])
def test_forgetting_is_its_time_varying_random_walk(rng, Q):
    """Exponential forgetting: P^-_{t+1} = P_t / lam + Q, i.e. the random walk
    Q_t = (1/lam - 1) P_{t-1} + Q; the smoother of that state-space model is the
    banded least-squares solution with those Q_t."""
    H, z, _ = drifting_record(rng, N=90)
    N, n = H.shape
    lam, R, P0 = 0.95, 0.01, 10.0 * np.eye(n)
    rls = RecursiveLeastSquares(n, lam=lam, R=R, Q=Q, P0=P0)
    out = rls.smooth(z, H)
    Pf = out.filtered_covariances
    Qs = np.empty((N, n, n))
    Qs[1:] = (1.0 / lam - 1.0) * Pf[:-1] + Q * np.eye(n)
    means, covs = banded_least_squares(z, H, np.zeros(n), P0 / lam + Q * np.eye(n), Qs,
                                       np.full(N, R))
    assert_allclose(out.means[:, :, 0], means, rtol=0, atol=1e-10 * np.abs(means).max())
    assert_allclose(out.covariances, covs, rtol=0, atol=1e-10 * np.abs(covs).max())
    if Q == 0.0:    # with Q = 0 the gain is lam I
        assert_allclose(out.gains[:-1], np.broadcast_to(lam * np.eye(n), (N - 1, n, n)),
                        rtol=0, atol=1e-12)


def test_constant_parameters_smooth_to_the_last_estimate(rng):
    H, z, _ = drifting_record(rng, q=0.0)
    out = RecursiveLeastSquares(3, R=0.01).smooth(z, H)
    assert_allclose(out.means, np.broadcast_to(out.means[-1], out.means.shape), rtol=1e-9)
    last = out.covariances[-1]
    # (the first steps cancel the broad prior P0 = 1e4 I against itself)
    assert_allclose(out.covariances, np.broadcast_to(last, out.covariances.shape), rtol=0,
                    atol=1e-7 * np.abs(last).max())


def test_equals_statsmodels_smoothed_state(rng):
    from statsmodels.tsa.statespace.mlemodel import MLEModel

    H, z, _ = drifting_record(rng, N=200)
    N, n = H.shape
    z[[3, 150]] = np.nan
    Q, R = np.diag([0.05, 0.03, 0.04]) ** 2, 0.02
    x0, P0 = np.array([1.0, 0.0, 0.0]), 5.0 * np.eye(n)
    out = RecursiveLeastSquares(n, R=R, Q=Q, P0=P0, x0=x0).smooth(z, H)
    # statsmodels' initial state is the prior of the first observation: one predict
    mod = MLEModel(z, k_states=n, k_posdef=n, initialization="known", initial_state=x0,
                   initial_state_cov=P0 + Q)
    mod["design"] = H.T[None]                                # time-varying (1, n, N)
    mod["transition"] = np.eye(n)
    mod["selection"] = np.eye(n)
    mod["state_cov"] = Q
    mod["obs_cov"] = np.array([[R]])
    ref = mod.ssm.smooth()
    assert_allclose(out.means[:, :, 0], ref.smoothed_state.T, rtol=0, atol=1e-8)
    assert_allclose(out.covariances, ref.smoothed_state_cov.transpose(2, 0, 1), rtol=0,
                    atol=1e-8 * np.abs(ref.smoothed_state_cov).max())


def test_equals_filterpy_rts_smoother(rng):
    from filterpy.kalman import KalmanFilter

    H, z, _ = drifting_record(rng, N=150)
    N, n = H.shape
    Q, R = 0.04 ** 2 * np.eye(n), 0.01
    rls = RecursiveLeastSquares(n, R=R, Q=Q, P0=3.0)
    Xs, Ps, _, _ = rls.batch_filter(z, H)
    kf = KalmanFilter(dim_x=n, dim_z=1)
    kf.x, kf.P, kf.F, kf.Q, kf.R = np.zeros((n, 1)), 3.0 * np.eye(n), np.eye(n), Q, R
    fx, fP, _, _ = kf.batch_filter(z, Hs=[h.reshape(1, n) for h in H])
    ref = kf.rts_smoother(fx, fP)
    ours = rls.rts_smoother(Xs, Ps)
    for a, b, name in zip(ours, ref, ("x", "P", "K", "Pp"), strict=True):
        assert_allclose(a, b, rtol=0, atol=1e-12 * max(1.0, np.abs(b).max()), err_msg=name)
    # filterpy's smoother on our filtered run: the recursion alone
    ref2 = kf.rts_smoother(Xs, Ps)
    for a, b, name in zip(ours, ref2, ("x", "P", "K", "Pp"), strict=True):
        assert_allclose(a, b, rtol=0, atol=1e-13 * max(1.0, np.abs(b).max()), err_msg=name)
    # and smooth() agrees with rts_smoother on the posteriors
    out = RecursiveLeastSquares(n, R=R, Q=Q, P0=3.0).smooth(z, H)
    assert_allclose(out.means, ours[0], rtol=0, atol=1e-13)


def test_several_outputs_share_the_gain(rng):
    H, z, _ = drifting_record(rng, N=80)
    z2 = np.column_stack([z, 2.0 * z + 0.1 * rng.standard_normal(len(z))])
    out = RecursiveLeastSquares(3, 2, R=0.01, Q=1e-3).smooth(z2, H)
    one = RecursiveLeastSquares(3, R=0.01, Q=1e-3).smooth(z2[:, 1], H)
    assert out.means.shape == (80, 3, 2)
    assert_allclose(out.means[:, :, 1], one.means[:, :, 0], rtol=0, atol=1e-12)
    assert_allclose(out.covariances, one.covariances, rtol=0, atol=1e-12)


def test_bank_channels_equal_single_filters(rng):
    C, N, n = 4, 100, 3
    Hs = rng.standard_normal((N, C, n))
    x = np.cumsum(0.05 * rng.standard_normal((N, C, n)), 0) + 1.0
    zs = np.einsum("tcn,tcn->tc", Hs, x) + 0.1 * rng.standard_normal((N, C))
    zs[5, 2] = np.nan
    lam, Q, R = np.array([1.0, 0.98, 1.0, 0.99]), np.array([1e-3, 0.0, 1e-4, 1e-3]), 0.01
    out = RLSBank(C, n, lam, Q=Q, R=R, P0=10.0).smooth(zs, Hs)
    assert out.means.shape == (N, C, n) and out.covariances.shape == (N, C, n, n)
    for c in range(C):
        one = RecursiveLeastSquares(n, lam=lam[c], Q=Q[c], R=R, P0=10.0).smooth(zs[:, c], Hs[:, c])
        assert_allclose(out.means[:, c], one.means[:, :, 0], rtol=0, atol=1e-12)
        assert_allclose(out.covariances[:, c], one.covariances, rtol=0, atol=1e-12)


def test_result_unpacks_like_filterpy_and_validates(rng):
    H, z, _ = drifting_record(rng, N=30)
    run = RecursiveLeastSquares(3, Q=1e-3).batch_filter(z, H)
    out = rts_smoother(*run)
    assert isinstance(out, SmoothedTrajectory) and len(out) == 4
    x, P, K, Pp = out
    assert x.shape == (30, 3, 1) and P.shape == K.shape == Pp.shape == (30, 3, 3)
    assert not K[-1].any()
    assert "30 steps" in repr(out)
    with pytest.raises(ValueError, match="`means_prior` must have the shape"):
        rts_smoother(run[0], run[1], run[0][:5], run[3])
    with pytest.raises(ValueError, match="`means` must have shape"):
        rts_smoother(run[0][:10], run[1], run[2], run[3])
    with pytest.raises(ValueError, match="forgetting='exponential'"):
        RecursiveLeastSquares(3, lam=0.98, forgetting="directional").smooth(z, H)
    with pytest.raises(ValueError, match="`Qs` must have shape"):
        RecursiveLeastSquares(3).rts_smoother(run[0], run[1], Qs=np.eye(2))


def test_plot_smoothed(rng):
    import matplotlib.pyplot as plt

    from rlsfilt.plotting import plot_smoothed

    H, z, x = drifting_record(rng, N=100)
    out = RecursiveLeastSquares(3, R=0.01, Q=0.05 ** 2).smooth(z, H)
    ax = out.plot(names=["a", "b", "c"], true_values=x)
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["a", "b", "c", "smoothed", "filtered", "true"]
    assert len(ax.collections) == 6                          # two bands per parameter
    bank = RLSBank(2, 3, Q=1e-3).smooth(np.column_stack([z, z]), np.stack([H, H], axis=1))
    ax2 = plot_smoothed(bank, channel=1, filtered=False)
    assert len(ax2.collections) == 3
    with pytest.raises(ValueError, match="`channel` must be < 2"):
        plot_smoothed(bank, channel=2)
    plt.close("all")
