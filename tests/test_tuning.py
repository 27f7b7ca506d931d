"""Maximum-likelihood tuning of lam and of the random walk Q against its oracles.

* statsmodels' state-space model of the same random-walk coefficients (an
  ``MLEModel`` with time-varying design, known initialization, the scale
  concentrated out): the profile log-likelihood at equal parameters (1e-8) and
  the maximum-likelihood estimates (1e-4 relative);
* exponential forgetting: the log-likelihood of filterpy's fading-memory
  Kalman filter (``alpha**2 = 1 / lam``) written out, and its maximum;
* recovery: the true q inside its 95 % interval in at least 90 % of 200 seeds.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rlsfilt import RecursiveLeastSquares
from rlsfilt.filters.tuning import TuneResult, tune


def drifting_record(rng, N=1000, n=3, q_std=0.02, r_std=0.1):
    H = rng.standard_normal((N, n))
    x = np.array([1.0, -0.5, 0.3])[:n] + np.cumsum(q_std * rng.standard_normal((N, n)), 0)
    z = np.sum(H * x, axis=1) + r_std * rng.standard_normal(N)
    return H, z


def statsmodels_model(z, H, x0, P0, diagonal=False, burn=0):
    """The random-walk coefficient model in statsmodels, scale concentrated out, with
    ``Q = q I`` (or ``diag(q)``) relative to the scale; its initial state is the
    prior of the first observation, so the first time update ``P0 + Q`` is in it."""
    from statsmodels.tsa.statespace.mlemodel import MLEModel

    n = H.shape[1]

    class RandomWalkCoefficients(MLEModel):
        def __init__(self):
            super().__init__(z, k_states=n, k_posdef=n, initialization="known",
                             initial_state=x0, initial_state_cov=P0,
                             loglikelihood_burn=burn)
            self.ssm.filter_concentrated = True
            self["design"] = H.T[None]
            self["transition"] = np.eye(n)
            self["selection"] = np.eye(n)
            self["obs_cov"] = np.array([[1.0]])

        @property
        def param_names(self):
            return [f"q{i}" for i in range(n)] if diagonal else ["q"]

        @property
        def start_params(self):
            return np.full(n if diagonal else 1, 0.01)

        def transform_params(self, unconstrained):
            return unconstrained ** 2

        def untransform_params(self, constrained):
            return constrained ** 0.5

        def update(self, params, **kwargs):
            params = super().update(params, **kwargs)
            Q = np.diag(params) if diagonal else params[0] * np.eye(n)
            self["state_cov"] = Q
            self.ssm.initialize_known(x0, P0 + Q)

    return RandomWalkCoefficients()


@pytest.mark.parametrize("burn", [0, 3])
def test_loglik_equals_statsmodels_at_equal_parameters(rng, burn):
    H, z = drifting_record(rng, N=600)
    z[[20, 300]] = np.nan
    n = 3
    x0, P0 = np.array([0.5, 0.0, 0.0]), 50.0 * np.eye(n)
    mod = statsmodels_model(z, H, x0, P0, burn=burn)
    rls = RecursiveLeastSquares(n, P0=P0, x0=x0)
    for q in (1e-4, 0.01, 0.5):
        fit = tune(rls, z, H, "q", bounds=(q * (1 - 1e-12), q * (1 + 1e-12)), burn=burn)
        assert_allclose(fit.loglik, mod.loglike([q]), rtol=0, atol=1e-8)
    # R, x0 and P0 relative to R: the same likelihood with R = 4 and P0 = 4 * 50 I
    fit4 = RecursiveLeastSquares(n, P0=4 * P0, x0=x0, R=4.0).tune(z, H, "q", burn=burn,
                                                                  bounds=(0.01, 0.0100001))
    assert_allclose(fit4.loglik, mod.loglike([fit4.estimate]), rtol=0, atol=1e-8)


def test_scalar_q_equals_statsmodels_maximum_likelihood(rng):
    H, z = drifting_record(rng, N=1500)
    n = 3
    x0, P0 = np.zeros(n), 100.0 * np.eye(n)
    mod = statsmodels_model(z, H, x0, P0)
    ref = mod.fit(disp=0, method="nm", maxiter=4000, xtol=1e-12, ftol=1e-14)
    rls = RecursiveLeastSquares(n, P0=P0, x0=x0)
    fit = rls.tune(z, H, "q")
    assert fit.converged and not fit.at_bound
    assert_allclose(fit.estimate, ref.params[0], rtol=1e-4)
    assert_allclose(fit.R, ref.scale, rtol=1e-4)
    assert_allclose(fit.loglik, ref.llf, rtol=0, atol=1e-6)
    assert fit.loglik >= ref.llf - 1e-9                      # ours is at least as high
    # the standard error: statsmodels' observed information on the same scale (q itself)
    bse = mod.filter([fit.estimate], cov_type="oim").bse[0]
    assert_allclose(fit.stderr, bse, rtol=2e-2)
    # the filter is left alone, unless asked
    assert rls.R == 1.0 and not rls.Q.any()
    fit.apply(rls)
    assert_allclose(rls.Q, fit.estimate * fit.R * np.eye(n), rtol=1e-15)
    assert rls.R == fit.R


def test_diagonal_q_equals_statsmodels_maximum_likelihood(rng):
    H, z = drifting_record(rng, N=1500)
    n = 3
    x0, P0 = np.zeros(n), 100.0 * np.eye(n)
    mod = statsmodels_model(z, H, x0, P0, diagonal=True)
    ref = mod.fit(disp=0, method="nm", maxiter=20000, xtol=1e-12, ftol=1e-14)
    ref = mod.fit(disp=0, start_params=ref.params, method="nm", maxiter=20000, xtol=1e-12,
                  ftol=1e-14)
    fit = RecursiveLeastSquares(n, P0=P0, x0=x0).tune(z, H, "q_diag")
    assert fit.converged and fit.estimate.shape == (3,)
    assert_allclose(fit.estimate, ref.params, rtol=1e-4)
    assert_allclose(fit.loglik, ref.llf, rtol=0, atol=1e-6)


def fading_memory_loglik(z, H, lam, Q_rel, P0_rel):
    """Profile log-likelihood of filterpy's fading-memory Kalman filter (alpha^2 = 1/lam,
    R = 1 relative): the innovations and their variances step by step."""
    from filterpy.kalman import KalmanFilter

    n = H.shape[1]
    kf = KalmanFilter(dim_x=n, dim_z=1)
    kf.x, kf.P, kf.F, kf.Q, kf.R = np.zeros((n, 1)), P0_rel.copy(), np.eye(n), Q_rel, 1.0
    kf.alpha = math.sqrt(1.0 / lam)
    ys, ss = [], []
    for zt, h in zip(z, H, strict=True):
        kf.predict()
        kf.update(zt, H=h.reshape(1, n))
        ys.append(kf.y[0, 0])
        ss.append(kf.S[0, 0])
    y, s = np.array(ys), np.array(ss)
    sigma2 = np.mean(y * y / s)
    N = len(y)
    return -0.5 * (N * (math.log(2 * math.pi) + math.log(sigma2) + 1) + np.log(s).sum())


def test_lam_equals_the_fading_memory_likelihood_and_its_maximum(rng):
    from scipy.optimize import minimize_scalar

    H, z = drifting_record(rng, N=400, n=2, q_std=0.03)
    n, P0 = 2, 10.0 * np.eye(2)
    rls = RecursiveLeastSquares(n, P0=P0)
    for lam in (0.9, 0.97):
        fit = rls.tune(z, H, "lam", bounds=(lam, lam + 1e-13))
        assert_allclose(fit.loglik, fading_memory_loglik(z, H, lam, np.zeros((n, n)), P0),
                        rtol=0, atol=1e-8)
    fit = rls.tune(z, H, "lam")
    ref = minimize_scalar(lambda lam: -fading_memory_loglik(z, H, lam, np.zeros((n, n)), P0),
                          bounds=(0.5, 1.0), method="bounded", options={"xatol": 1e-9})
    assert fit.converged
    assert_allclose(fit.estimate, ref.x, rtol=1e-6)
    lo, hi = fit.interval()
    assert lo < fit.estimate < hi <= 1.0


def test_constant_parameters_end_on_the_bound(rng):
    H, z = drifting_record(rng, N=500, q_std=0.0)
    fit = RecursiveLeastSquares(3, P0=100.0).tune(z, H, "lam")
    assert fit.at_bound and not fit.converged and np.isnan(fit.stderr)
    assert fit.estimate > 1 - 1e-5
    assert "at a bound" in str(fit.summary())


def test_apply_lam_and_validation(rng):
    H, z = drifting_record(rng, N=300)
    rls = RecursiveLeastSquares(3, R=2.0, Q=0.02)
    fit = rls.tune(z, H, "lam", apply=True)
    assert isinstance(fit, TuneResult) and rls.lam == fit.estimate and rls.R == fit.R
    assert_allclose(rls.Q, 0.01 * fit.R * np.eye(3), rtol=1e-15)   # Q / R kept
    assert "lam=" in repr(fit)
    with pytest.raises(ValueError, match="`param` must be one of"):
        rls.tune(z, H, "R")
    with pytest.raises(ValueError, match="`bounds` must satisfy 0 < low < high <= 1"):
        rls.tune(z, H, "lam", bounds=(0.5, 1.5))
    with pytest.raises(TypeError, match="`bounds` must be a pair"):
        rls.tune(z, H, "q", bounds=1.0)
    with pytest.raises(ValueError, match="forgetting='exponential'"):
        RecursiveLeastSquares(3, lam=0.98, forgetting="directional").tune(z, H)
    with pytest.raises(ValueError, match="no measurement left"):
        rls.tune(np.full(300, np.nan), H)
    with pytest.raises(ValueError, match="`level` must be in"):
        fit.interval(1.5)


@pytest.mark.slow
def test_true_q_inside_its_interval_in_90_percent_of_200_seeds():
    """Coverage of the 95 % interval of q (log scale, observed information): at least
    180 of 200 fixed seeds."""
    q_true, n, N = 0.04, 2, 800                  # Q = q R, R = 0.01
    inside = 0
    for seed in range(200):
        rng = np.random.default_rng(1000 + seed)
        H = rng.standard_normal((N, n))
        x = np.cumsum(math.sqrt(q_true) * 0.1 * rng.standard_normal((N, n)), 0)
        z = np.sum(H * x, axis=1) + 0.1 * rng.standard_normal(N)
        fit = RecursiveLeastSquares(n, P0=100.0).tune(z, H, "q")
        lo, hi = fit.interval(0.95)
        inside += bool(lo <= q_true <= hi)
    assert inside >= 180, inside


def test_compiled_terms_equal_the_innovations_of_batch_filter(rng):
    """The likelihood kernel runs the filter's recursion: its sums equal those of
    batch_filter's innovations y_t = z_t - H_t x^-_t, s_t = H_t P^-_t H_t^T + 1."""
    from rlsfilt.filters._kernels_tuning import profile_terms

    H, z = drifting_record(rng, N=500)
    z[[7, 99]] = np.nan
    Z2 = np.column_stack([z, 0.5 * z + rng.standard_normal(500)])
    for lam, q, Z in ((1.0, 0.01, z[:, None]), (0.97, 0.0, z[:, None]), (0.99, 1e-3, Z2)):
        m = Z.shape[1]
        Q = q * np.diag([1.0, 2.0, 0.5])
        x0 = np.ones((3, m))
        rls = RecursiveLeastSquares(3, m, lam=lam, R=1.0, Q=Q, P0=20.0, x0=x0)
        _, _, Xp, Pp = rls.batch_filter(Z, H)
        y = Z - np.einsum("kn,knm->km", H, Xp)
        s = np.einsum("ki,kij,kj->k", H, Pp, H) + 1.0
        keep = ~np.isnan(y).any(axis=1)
        keep[:4] = False
        slog, sq, count = profile_terms(x0, 20.0 * np.eye(3), Z, H, 1.0 / lam, Q, 4)
        assert count == keep.sum() * m
        assert_allclose(slog, np.log(s[keep]).sum(), rtol=1e-12)
        assert_allclose(sq, np.sum(y[keep] ** 2 / s[keep, None]), rtol=1e-12)


@pytest.mark.parametrize("param", ["q", "lam"])
def test_bank_channels_equal_single_filters(rng, param):
    from rlsfilt import RLSBank

    C, N, n = 3, 400, 2
    Hs = rng.standard_normal((N, C, n))
    x = np.cumsum(0.03 * rng.standard_normal((N, C, n)), 0) + 1.0
    zs = np.einsum("tcn,tcn->tc", Hs, x) + 0.1 * rng.standard_normal((N, C))
    zs[7, 1] = np.nan
    bank = RLSBank(C, n, Q=np.array([0.0, 1e-3, 0.0]), R=np.array([1.0, 2.0, 0.5]),
                   P0=50.0, lam=np.array([1.0, 1.0, 0.99]))
    fits = bank.tune(zs, Hs, param)
    assert fits.estimate.shape == (C,) and "3 channels" in repr(fits)
    for c in range(C):
        one = bank.channel(c).tune(zs[:, c], Hs[:, c], param)
        assert fits.channel(c).estimate == one.estimate
        assert fits.loglik[c] == one.loglik and fits.R[c] == one.R
    lo, hi = fits.interval()
    assert np.all(lo < fits.estimate) and np.all(fits.estimate < hi)
    fits.apply(bank)
    assert_allclose(bank.R, fits.R, rtol=0)
    if param == "q":
        assert_allclose(bank.Q[1], fits.estimate[1] * fits.R[1] * np.eye(n), rtol=1e-15)
    else:
        assert_allclose(bank.lam, fits.estimate, rtol=0)
