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
from _reference import diagonal_forgetting_profile_loglik as reference_loglik
from numpy.testing import assert_allclose, assert_array_equal

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
    assert fit.loglik >= ref.llf - 1e-9                      # ours is at least as high
    # the standard errors from the exact Hessian: statsmodels' from its numerical Hessian
    # of the log-likelihood on the same scale (q itself; its "oim", Harvey's formula,
    # differs by a few per cent here)
    bse = mod.filter(fit.estimate, cov_type="approx").bse
    assert_allclose(fit.stderr, bse, rtol=1e-4)


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


def test_arx_q_tune_applied_runs_the_fits_random_walk(rng):
    """ARX.fit tunes Q in its record's power-of-two units: `tune_.apply` on a filter in the
    signals' units sets the image of that random walk (filter_.Q, with the estimated R)."""
    from scipy.signal import lfilter

    from rlsfilt import ARX

    u = 8.0 * rng.standard_normal(800)                        # regressor columns of other
    y = lfilter([0, 0.5], [1, -0.9], u) / 64 + 0.01 * rng.standard_normal(800)   # sizes
    model = ARX(1, 1).fit(u, y, "rls", Q="tune")
    c = np.array([np.frexp(np.max(np.abs(x)))[1] for x in (y, u)])   # column exponents
    assert_array_equal(model.tune_.Q_shape, np.ldexp(1.0, -2 * c))
    assert_allclose(model.filter_.Q, model.tune_.estimate * np.diag(np.ldexp(1.0, -2 * c)),
                    rtol=1e-15)                                       # R = 1, the option
    rls = model.tune_.apply(RecursiveLeastSquares(2))
    assert_allclose(rls.Q, model.filter_.Q * model.tune_.R, rtol=1e-15)
    assert rls.R == model.tune_.R
    # a tune of the filter's own (no other units) keeps Q = q R I
    fit = RecursiveLeastSquares(2).tune(y[1:], np.column_stack([-y[:-1], u[:-1]]), "q")
    assert fit.Q_shape is None
    assert_allclose(fit.apply(RecursiveLeastSquares(2)).Q, fit.estimate * fit.R * np.eye(2),
                    rtol=1e-15)


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


@pytest.mark.parametrize("param", ["q", "lam"])
def test_scalar_record_screened_as_batch_filter_validates_it(rng, param):
    """A plain float64 record skips the Python validation (the kernel screens it): a bad
    entry is still named as batch_filter names it, missing samples (NaN in zs) still
    pass, and any other form of the record gives the same estimate to the last bit."""
    H, z = drifting_record(rng, N=300)
    rls = RecursiveLeastSquares(3, R=2.0, Q=0.02)
    z = z.copy()
    z[17] = np.nan                                         # a missing sample: allowed
    fit = rls.tune(z, H, param)
    for zs, Hs in ((list(z), H.tolist()), (z[:, None], np.asfortranarray(H)),
                   (np.repeat(z, 2)[::2], np.repeat(H, 2, axis=0)[::2])):
        other = rls.tune(zs, Hs, param)
        assert (other.estimate, other.loglik, other.R, other.n_evals) == \
            (fit.estimate, fit.loglik, fit.R, fit.n_evals)
    for bad_z, bad_H, match in ((np.inf, None, r"`zs` must be finite; got inf at index \(5, 0\)"),
                                (None, np.nan, r"`Hs` must be finite; got nan at index \(9, 2\)"),
                                (None, -np.inf, r"`Hs` must be finite; got -inf")):
        zb, Hb = z.copy(), H.copy()
        if bad_z is not None:
            zb[5] = bad_z
        else:
            Hb[9, 2] = bad_H
        with pytest.raises(ValueError, match=match):
            rls.tune(zb, Hb, param)
    assert fit._gradient.shape == (1,) and fit._hessian.shape == (1, 1)


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
    from rlsfilt.filters._kernels_tuning import profile_derivs

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
        k0 = np.zeros((0, 3, 3))
        slog, sq, count, *_ = profile_derivs(x0, 20.0 * np.eye(3), Z, H,
                                             np.full((3, 3), 1.0 / lam), Q, k0, k0,
                                             np.zeros((0, 0, 3, 3)), np.zeros((0, 0, 3, 3)),
                                             4, 0)
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


def test_bank_lam_diag_is_estimated_and_refused_by_apply(rng):
    """The bank tunes lam_diag channel by channel as single filters; it has no diagonal
    forgetting, so applying it is refused (a channel's estimate applies to a filter)."""
    from rlsfilt import RLSBank

    C, N, n = 2, 300, 2
    Hs = rng.standard_normal((N, C, n))
    zs = np.einsum("tcn,tcn->tc", Hs, 1.0 + np.cumsum(0.03 * rng.standard_normal((N, C, n)),
                                                      0)) + 0.1 * rng.standard_normal((N, C))
    bank = RLSBank(C, n, P0=50.0)
    fits = bank.tune(zs, Hs, "lam_diag")
    assert fits.estimate.shape == (C, n)
    with pytest.raises(ValueError, match="no forgetting='diagonal'"):
        fits.apply(bank)
    f = RecursiveLeastSquares(n, P0=50.0)
    one = f.tune(zs[:, 1], Hs[:, 1], "lam_diag")
    assert_allclose(fits.channel(1).estimate, one.estimate, rtol=0, atol=0)
    fits.channel(1).apply(f)
    assert f.forgetting == "diagonal"


@pytest.mark.parametrize("param, v", [("q", [-4.0]), ("lam", [0.97]),
                                      ("q_diag", [-5.0, -3.0, -4.0]),
                                      ("lam_diag", [0.95, 0.99, 0.9])])
def test_sensitivity_derivatives_equal_finite_differences(rng, param, v):
    """The gradient and the Hessian of the profile log-likelihood that the compiled
    sensitivity recursions return, against central differences of the likelihood
    (rtol 1e-6; Richardson-extrapolated differences), with missing samples, a burn-in
    and two outputs."""
    from rlsfilt.filters.tuning import _model, _profile

    H, z = drifting_record(rng, N=400)
    z[[11, 200]] = np.nan
    Z = np.column_stack([z, 0.3 * z + 0.1 * rng.standard_normal(400)])
    x0, P0, Q_rel = np.zeros((3, 2)), 30.0 * np.eye(3), 1e-3 * np.eye(3)
    v = np.array(v)

    def run(w, order):
        return _profile(x0, P0, Z, H, _model(param, w, 3, 0.98, Q_rel), 2, 2, order)

    def richardson(f, h):                # central difference, error O(h^4)
        d1, d2 = (f(h) - f(-h)) / (2 * h), (f(h / 2) - f(-h / 2)) / h
        return (4 * d2 - d1) / 3

    ll, _, _, grad, hess = run(v, 2)
    assert run(v, 1)[0] == ll
    assert_allclose(run(v, 1)[3], grad, rtol=1e-14)
    h = 1e-3 if param.startswith("q") else 1e-4
    for a in range(len(v)):
        e = np.zeros(len(v))
        e[a] = 1.0
        assert_allclose(richardson(lambda t, e=e: run(v + t * e, 0)[0], h), grad[a], rtol=1e-6,
                        atol=1e-9 * abs(ll))
        assert_allclose(richardson(lambda t, e=e: run(v + t * e, 1)[3], h), hess[a], rtol=1e-6,
                        atol=1e-9 * abs(ll))


def test_diagonal_forgetting_equals_the_numpy_reference_and_its_maximum(rng):
    """``lam_diag``: the profile log-likelihood of P^- = L^-1/2 P L^-1/2 + Q equals the
    plain NumPy recursion of tests/_reference.py (1e-9) at equal parameters; with equal
    entries, the scalar ``lam``'s; its maximum equals scipy's search on the reference;
    a drifting and a constant parameter get different factors."""
    from scipy.optimize import minimize

    from rlsfilt.filters.tuning import _model, _profile

    N, n = 800, 2
    H = rng.standard_normal((N, n))
    x = np.column_stack([np.full(N, 1.0), np.cumsum(0.04 * rng.standard_normal(N))])
    z = np.sum(H * x, axis=1) + 0.1 * rng.standard_normal(N)
    z[50] = np.nan
    P0, Q = 10.0 * np.eye(n), 1e-6 * np.eye(n)
    rls = RecursiveLeastSquares(n, P0=P0, Q=Q)
    lam = np.array([0.995, 0.93])
    ll = _profile(np.zeros((n, 1)), P0, z[:, None], H, _model("lam_diag", lam, n, 1.0, Q),
                  0, 1, 0)[0]
    assert_allclose(ll, reference_loglik(z, H, lam, Q, P0, np.zeros(n)), rtol=0, atol=1e-9)
    same = rls.tune(z, H, "lam", bounds=(0.95, 0.95 + 1e-13))
    assert_allclose(_profile(np.zeros((n, 1)), P0, z[:, None], H,
                             _model("lam_diag", np.full(n, 0.95), n, 1.0, Q), 0, 1, 0)[0],
                    same.loglik, rtol=0, atol=1e-8)
    fit = rls.tune(z, H, "lam_diag")
    ref = minimize(lambda v: -reference_loglik(z, H, v, Q, P0, np.zeros(n)), fit.estimate * 0.999,
                   method="L-BFGS-B", bounds=[(0.5, 1.0)] * n,
                   options={"ftol": 1e-15, "gtol": 1e-9})
    assert fit.estimate.shape == (n,) and fit.estimate[0] > fit.estimate[1]
    assert_allclose(fit.estimate, ref.x, rtol=1e-5)
    assert fit.loglik >= -ref.fun - 1e-8
    assert fit.loglik >= rls.tune(z, H, "lam").loglik            # a larger model
    lo, hi = fit.interval()
    free = ~np.isnan(fit.stderr)
    assert free[1] and np.all(lo[free] < fit.estimate[free]) and np.all(hi <= 1.0)
    assert "lam[1]" in str(fit.summary()) and "lam[1]" in fit.summary().as_html()


def _innovation_loglik(f, Z, H, burn=0):
    """The Gaussian log-likelihood of `f`'s innovations over the record, from what
    ``batch_filter`` stores: y_t = z_t - H_t x^-_t, S_t = H_t P^-_t H_t^T + R."""
    _, _, Xp, Pp = f.batch_filter(Z, H)
    y = Z - np.einsum("kn,knm->km", H, Xp)
    S = np.einsum("ki,kij,kj->k", H, Pp, H) + f.R
    keep = ~np.isnan(y).any(axis=1)
    keep[:burn] = False
    m = Z.shape[1]
    return -0.5 * np.sum(m * np.log(2 * np.pi) + m * np.log(S[keep])
                         + np.sum(y[keep] ** 2, axis=1) / S[keep])


@pytest.mark.parametrize("m, burn", [(1, 0), (2, 3)])
def test_apply_lam_diag_runs_the_likelihoods_recursion(rng, m, burn):
    """``TuneResult.apply`` of ``"lam_diag"`` gives a filter with forgetting="diagonal" at
    the estimate whose innovations have the tuned log-likelihood (1e-12 relative), in
    batch_filter and streamed (filterpy's per-step ``log_likelihood``); the filter tuned
    with ``apply=True`` switches mode in place, its state kept."""
    N, n = 600, 3
    H = rng.standard_normal((N, n))
    x = np.column_stack([np.full(N, 1.0), np.cumsum(0.04 * rng.standard_normal(N)),
                         np.cumsum(0.01 * rng.standard_normal(N))])
    Z = (np.sum(H * x, axis=1)[:, None] * np.arange(1, m + 1)
         + 0.1 * rng.standard_normal((N, m)))
    Z[[10, 200]] = np.nan
    R0, P0, Q = 2.0, 20.0 * np.eye(n), 1e-6 * np.diag([1.0, 2.0, 3.0])
    x0 = 0.1 * np.ones((n, m))
    rls = RecursiveLeastSquares(n, m, P0=P0, R=R0, Q=Q, x0=x0)
    fit = rls.tune(Z, H, "lam_diag", burn=burn)
    assert fit.estimate.shape == (n,) and fit.estimate[1] < fit.estimate[0]
    # a new filter from the same start, relative to the estimated R (P0 = p0 R)
    f = RecursiveLeastSquares(n, m, P0=P0 / R0 * fit.R, R=R0, Q=Q, x0=x0)
    assert fit.apply(f) is f
    assert f.forgetting == "diagonal" and f.R == fit.R
    assert_allclose(f.lam, fit.estimate, rtol=0, atol=0)
    assert_allclose(f.Q, Q / R0 * fit.R, rtol=1e-15)
    g = f.copy()
    assert_allclose(_innovation_loglik(f, Z, H, burn), fit.loglik, rtol=1e-12)
    streamed = 0.0
    for k in range(N):
        g.predict()
        g.update(Z[k], H[k])
        streamed += g.log_likelihood if k >= burn else 0.0
    assert_allclose(streamed, fit.loglik, rtol=1e-12)
    assert_array_equal(g.x, f.x)                          # streaming = batch
    # tune(apply=True): the exponential filter becomes a diagonal one, state kept
    x_before, P_before = rls.x.copy(), rls.P.copy()
    again = rls.tune(Z, H, "lam_diag", burn=burn, apply=True)
    assert rls.forgetting == "diagonal" and np.array_equal(rls.lam, again.estimate)
    assert_array_equal(rls.x, x_before)
    assert_array_equal(rls.P, P_before)
    # a diagonal filter tunes lam_diag (from its state) and nothing else
    assert rls.tune(Z, H, "lam_diag", burn=burn).estimate.shape == (n,)
    with pytest.raises(ValueError, match="estimates param='lam_diag' only; got 'q'"):
        rls.tune(Z, H, "q")
    with pytest.raises(ValueError, match="forgetting='exponential' or 'diagonal'; got "
                                         "forgetting='directional'"):
        fit.apply(RecursiveLeastSquares(n, m, lam=0.98, forgetting="directional"))


def drifting_plant(rng, N=1500, C=None):
    """A first-order plant whose gain drifts (random walk); `C` channels of it."""
    shape = (N,) if C is None else (N, C)
    u = rng.standard_normal(shape)
    b = 1.0 + np.cumsum(0.01 * rng.standard_normal(shape), axis=0)
    y = np.zeros(shape)
    e = 0.05 * rng.standard_normal(shape)
    for t in range(1, N):
        y[t] = 0.6 * y[t - 1] + b[t] * u[t - 1] + e[t]
    return u, y


@pytest.mark.parametrize("param", ["lam", "Q"])
def test_arx_fit_tunes_on_its_regressor_rows(rng, param):
    """``ARX.fit(method="rls", lam="tune")`` (or ``Q="tune"``) equals tuning a filter on
    ``model.regressors`` by hand in the record's power-of-two units (columns and output
    divided by ``2^c``, ``2^e``; ``P0`` mapped to ``2^(c_k + c_l) P0``), then fitting with
    the estimate (``Q = q R I`` in those units: ``2^-(c_k + c_l) q R`` in the signals')."""
    from rlsfilt import ARX
    from rlsfilt._scale import pow2_exponent

    u, y = drifting_plant(rng)
    model = ARX(1, 1).fit(u, y, "rls", **{param: "tune"}, P0=100.0)
    Phi, target = ARX(1, 1).regressors(u, y)
    c = np.array([pow2_exponent(y), pow2_exponent(u)])
    assert c.any()                       # (the units matter: not the identity map)
    cc = c[:, None] + c[None, :]
    by_hand = RecursiveLeastSquares(2, P0=np.ldexp(100.0 * np.eye(2), cc)).tune(
        np.ldexp(target, -c[0]), np.ldexp(Phi, -c), param.lower(), burn=2)
    assert model.tune_.estimate == by_hand.estimate and model.tune_.loglik == by_hand.loglik
    assert model.tune_.R == np.ldexp(by_hand.R, 2 * c[0])
    if param == "lam":
        assert by_hand.estimate < 0.999 and model.lam_ == by_hand.estimate
        ref = ARX(1, 1).fit(u, y, "rls", lam=by_hand.estimate, P0=100.0)
    else:
        Q = np.ldexp(by_hand.estimate * np.eye(2), -cc)
        assert_array_equal(model.filter_.Q, Q)
        ref = ARX(1, 1).fit(u, y, "rls", Q=Q, P0=100.0)
    assert_allclose(model.theta_history_, ref.theta_history_, rtol=0, atol=0)
    with pytest.raises(ValueError, match="only applies to method='rls'"):
        ARX(1, 1).fit(u, y, "riv", lam="tune")
    with pytest.raises(ValueError, match="tune one of `lam` and `Q`"):
        ARX(1, 1).fit(u, y, "rls", lam="tune", Q="tune")
    with pytest.raises(ValueError, match="`lam` must be a number or 'tune'; got 'auto'"):
        ARX(1, 1).fit(u, y, "rls", lam="auto")


@pytest.mark.parametrize("scale", [1.0, 1e-6])
def test_arx_fit_runs_a_tuned_diagonal_forgetting(rng, scale, tmp_path):
    """``ARX.fit(method="rls", forgetting="diagonal", lam=estimate)`` with the estimate of
    ``tune(..., "lam_diag")`` on the model's rows equals that filter run by hand on them
    (batch start on the first rows, then batch_filter; bit for bit, in any units), and
    the per-parameter ``lam_`` is kept by save/load; an array `lam` without it is refused
    naming `lam`."""
    from rlsfilt import ARX, load_model, save_model

    u, y = drifting_plant(rng)
    y = scale * y
    Phi, target = ARX(1, 1).regressors(u, y)
    lam = RecursiveLeastSquares(2, P0=100.0).tune(target, Phi, "lam_diag", burn=2).estimate
    model = ARX(1, 1).fit(u, y, "rls", forgetting="diagonal", lam=lam)
    f = RecursiveLeastSquares(2, lam=lam, forgetting="diagonal", check_every=0)
    f.initialize(target[:2], Phi[:2])
    f.batch_filter(target[2:], Phi[2:])
    assert_array_equal(model.theta_, f.x[:, 0])
    assert_array_equal(model.lam_, lam)
    assert model.filter_.forgetting == "diagonal"
    assert "lam=[" in str(model.summary()) and model.to_dict()["lam"] == list(lam)
    save_model(model, tmp_path / "m.json")
    assert_array_equal(load_model(tmp_path / "m.json").lam_, lam)
    with pytest.raises(ValueError, match=r"`lam` must be a number for forgetting='exponential'"
                                         r"; got an array of shape \(2,\)"):
        ARX(1, 1).fit(u, y, "rls", lam=lam)


@pytest.mark.parametrize("param", ["lam", "Q"])
def test_fit_many_tunes_every_channel_as_arx_fit(rng, param):
    """``fit_many(..., lam="tune")``: each channel's estimate and fit equal
    ``ARX.fit(u[:, c], y[:, c], "rls", lam="tune")``."""
    from rlsfilt import ARX
    from rlsfilt.models import fit_many

    u, y = drifting_plant(rng, N=600, C=3)
    fleet = fit_many(ARX(1, 1), u, y, "rls", **{param: "tune"}, residual_tests=False)
    assert fleet.tune_.estimate.shape == (3,)
    for c in range(3):
        one = ARX(1, 1).fit(u[:, c], y[:, c], "rls", **{param: "tune"})
        assert_allclose(fleet.tune_.estimate[c], one.tune_.estimate, rtol=1e-12)
        assert_allclose(fleet.theta_[c], one.theta_, rtol=1e-9)
        assert_allclose(fleet.model(c).theta_, one.theta_, rtol=1e-9)


def test_profile_and_likelihood_interval_against_statsmodels(rng):
    """``TuneResult.profile`` equals statsmodels' concentrated log-likelihood at each q
    (1e-8); the ends of ``likelihood_interval`` lie 1.92 below the maximum; on a long
    record it is close to the Wald interval; ``plot_profile`` draws both."""
    import matplotlib.pyplot as plt
    from scipy.stats import chi2

    H, z = drifting_record(rng, N=1500)
    x0, P0 = np.zeros(3), 100.0 * np.eye(3)
    mod = statsmodels_model(z, H, x0, P0)
    fit = RecursiveLeastSquares(3, P0=P0, x0=x0).tune(z, H, "q")
    qs = fit.estimate * np.array([0.5, 1.0, 2.0])
    assert_allclose(fit.profile(qs), [mod.loglike([q]) for q in qs], rtol=0, atol=1e-8)
    assert_allclose(fit.profile(fit.estimate), fit.loglik, rtol=0, atol=1e-10)
    lo, hi = fit.likelihood_interval()
    assert_allclose(fit.profile([lo, hi]) - fit.loglik, -0.5 * chi2.ppf(0.95, 1), rtol=1e-7)
    assert_allclose([lo, hi], fit.interval(), rtol=0.05)
    lam = RecursiveLeastSquares(3, P0=P0, x0=x0).tune(z, H, "lam")
    lo, hi = lam.likelihood_interval(0.9)
    assert lo < lam.estimate < hi < 1.0
    assert_allclose(lam.profile([lo, hi]) - lam.loglik, -0.5 * chi2.ppf(0.9, 1), rtol=1e-7)
    ax = lam.plot_profile()
    assert ax.get_xlabel() == r"$\lambda$" and len(ax.get_lines()) >= 3
    assert "likelihood interval" in " ".join(t.get_text() for t in ax.get_legend().get_texts())
    plt.close("all")
    # on the bound lam = 1 the interval ends there
    H2, z2 = drifting_record(rng, N=500, q_std=0.0)
    one = RecursiveLeastSquares(3, P0=100.0).tune(z2, H2, "lam")
    lo, hi = one.likelihood_interval()
    assert one.at_bound and hi == 1.0 and lo < 1.0
    with pytest.raises(ValueError, match="`values` of lam must be in"):
        one.profile([1.5])
    from rlsfilt import RLSBank
    bank_fit = RLSBank(2, 3, P0=100.0).tune(np.column_stack([z, z]), np.stack([H, H], 1))
    with pytest.raises(ValueError, match="the profile needs the record"):
        bank_fit.channel(0).plot_profile()


@pytest.mark.parametrize("param", ["q", "lam"])
def test_scalar_kernel_equals_the_general_one(rng, param):
    """The fused one-variable pass of the compiled search (`scalar_profile`) returns the
    profile log-likelihood, its gradient and second derivative of the general
    sensitivity kernel (`_profile`, checked against finite differences above) to
    round-off, with missing samples, a burn-in and two outputs, at every order."""
    from rlsfilt.filters import _kernels_tuning as kernels
    from rlsfilt.filters.tuning import _dims, _model, _profile

    H, z = drifting_record(rng, N=300)
    z[[4, 150]] = np.nan
    Z = np.column_stack([z, 0.3 * z + 0.1 * rng.standard_normal(300)])
    x0, P0 = 0.1 * np.ones((3, 2)), 30.0 * np.eye(3)
    Q_rel = 1e-3 * np.array([[1.0, 0.2, 0.0], [0.2, 2.0, 0.1], [0.0, 0.1, 0.5]])
    P0 = P0 + np.array([[0.0, 1.0, -2.0], [1.0, 0.0, 0.5], [-2.0, 0.5, 0.0]])
    kind, Qb = (0, None) if param == "q" else (1, Q_rel)      # None: the identity
    work = kernels.scalar_work(3, 2)
    for v in ((-6.0, -2.0) if param == "q" else (math.log(0.1), math.log(0.005))):
        for order in (0, 1, 2):
            ref = _profile(x0, P0, Z, H, _model(param, np.array([v]), 3, 0.98, Q_rel), 3, 2,
                           order)
            got = kernels.scalar_profile(x0, P0, Z, H, Qb, kind, v, 0.98, 3, order, work,
                                         _dims(3))
            # the loop for every size: the same numbers to the last bit
            assert got == kernels.scalar_profile(x0, P0, Z, H, Qb, kind, v, 0.98, 3, order,
                                                 work, np.zeros(3, dtype=np.int8))
            if Qb is None:                   # the lean pass of Q = c I: the same bits
                assert got == kernels.scalar_profile(x0, P0, Z, H, np.eye(3), kind, v, 0.98, 3,
                                                     order, work, _dims(3))
            assert got[2] == ref[2]
            assert_allclose(got[:2], ref[:2], rtol=1e-13)
            if order >= 1:
                assert_allclose(got[3], ref[3][0], rtol=1e-10)
            if order == 2:
                assert_allclose(got[4], ref[4][0, 0], rtol=1e-10)


def test_diagonal_kernel_equals_the_general_one(rng):
    """The pass of the compiled ``q_diag`` search (`diag_profile`, ``Q = diag(exp(v))``)
    returns the profile log-likelihood, its gradient and Hessian of the general
    sensitivity kernel (`_profile`, checked against finite differences above) to
    round-off, with missing samples, a burn-in and two outputs, at every order; the
    loop for every size gives the same bits as the one unrolled for ``dim_x = 3``."""
    from rlsfilt.filters import _kernels_tuning as kernels
    from rlsfilt.filters.tuning import _dims, _model, _profile

    H, z = drifting_record(rng, N=300)
    z[[4, 150]] = np.nan
    Z = np.column_stack([z, 0.3 * z + 0.1 * rng.standard_normal(300)])
    x0 = 0.1 * np.ones((3, 2))
    P0 = 30.0 * np.eye(3) + np.array([[0.0, 1.0, -2.0], [1.0, 0.0, 0.5], [-2.0, 0.5, 0.0]])
    for v in (np.array([-5.0, -3.0, -4.0]), np.array([-12.0, -1.0, -2.5])):
        for order in (0, 1, 2):
            ref = _profile(x0, P0, Z, H, _model("q_diag", v, 3, 0.98, None), 3, 2, order)
            got = kernels.diag_profile(x0, P0, Z, H, 1.0 / 0.98, v, 3, order, _dims(3))
            loop = kernels.diag_profile(x0, P0, Z, H, 1.0 / 0.98, v, 3, order,
                                        np.zeros(3, dtype=np.int8))
            assert all(np.array_equal(a, b) for a, b in zip(got, loop, strict=True))
            assert got[2] == ref[2]
            assert_allclose(got[:2], ref[:2], rtol=1e-13)
            if order >= 1:
                assert_allclose(got[3], ref[3], rtol=1e-10, atol=1e-12 * abs(ref[0]))
            if order == 2:
                assert_allclose(got[4], ref[4], rtol=1e-10, atol=1e-12 * abs(ref[0]))


@pytest.mark.parametrize("seed", [0, 3])
def test_diagonal_q_with_a_constant_parameter_equals_lbfgsb(seed):
    """``q_diag`` with one constant parameter: its ``q`` ends tiny (seed 0) or on the
    lower bound, held there (seed 3: ``at_bound``, no standard error for it); the compiled
    projected Newton search reaches the likelihood of L-BFGS-B over the general
    sensitivity pass (scipy, from the same start) or higher, with the same estimates."""
    from scipy.optimize import minimize

    from rlsfilt.filters.tuning import _model, _profile

    rng = np.random.default_rng(seed)
    N, n = 1500, 3
    H = rng.standard_normal((N, n))
    x = np.column_stack([np.full(N, 1.0), 1.0 + np.cumsum(0.03 * rng.standard_normal(N)),
                         np.cumsum(0.01 * rng.standard_normal(N))])
    z = np.sum(H * x, axis=1) + 0.1 * rng.standard_normal(N)
    rls = RecursiveLeastSquares(n, P0=100.0)
    fit = rls.tune(z, H, "q_diag")

    def negll(v):
        out = _profile(np.zeros((n, 1)), 100.0 * np.eye(n), z[:, None], H,
                       _model("q_diag", v, n, 1.0, None), 0, 1, 1)
        return -out[0], -out[3]

    v0 = np.full(n, math.log(rls.tune(z, H, "q").estimate))
    ref = minimize(negll, v0, jac=True, method="L-BFGS-B",
                   bounds=[(math.log(1e-12), math.log(1e2))] * n,
                   options={"ftol": 1e-15, "gtol": 1e-10, "maxiter": 1000})
    assert fit.loglik >= -ref.fun - 1e-9
    q_ref = np.exp(ref.x)
    assert_allclose(fit.estimate[1:], q_ref[1:], rtol=1e-5)
    if seed == 3:
        assert fit.at_bound and not fit.converged and q_ref[0] < 1e-10
        assert_allclose(fit.estimate[0], 1e-12, rtol=1e-12)         # exp(log(1e-12))
        assert np.isnan(fit.stderr[0]) and np.all(np.isfinite(fit.stderr[1:]))
    else:
        assert not fit.at_bound and fit.converged
        assert_allclose(fit.estimate[0], q_ref[0], rtol=1e-4)
