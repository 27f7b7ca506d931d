"""Batch prediction-error core of the model family (rlsfilt.models._pem and friends).

Oracles: the predictor against the pseudo-linear difference equations written
out here; the gradient against central differences; the minimizer against
``scipy.optimize.minimize`` on the criterion written with ``scipy.signal.lfilter``;
ARX structures against ``numpy.linalg.lstsq``; the covariance by z-scores
over repeated experiments.
"""

import numpy as np
import pytest
from scipy.optimize import minimize
from scipy.signal import lfilter

from rlsfilt.models import arx_regressors
from rlsfilt.models._family import family_structure, join_theta, param_names, split_theta
from rlsfilt.models._initial import initial_estimate
from rlsfilt.models._long_ar import levinson_ar
from rlsfilt.models._pem import criterion, pem, prediction_errors, predictor_gradient
from rlsfilt.models._stability import is_stable, predictor_is_stable, reflect

# (structure kwargs, true theta) for the shapes the family must handle
CASES = {
    "armax": (dict(na=2, nb=2, nc=2, nk=1), [-1.5, 0.7, 1.0, 0.5, -1.0, 0.2]),
    "oe": (dict(nb=2, nf=2, nk=1), [1.0, 0.5, -1.5, 0.7]),
    "bj": (dict(nb=2, nc=1, nd=1, nf=2, nk=1), [1.0, 0.5, 0.5, -0.9, -1.5, 0.7]),
    "arma": (dict(na=2, nc=1, n_inputs=0), [-1.2, 0.5, 0.6]),
    "miso_oe_nk0": (dict(nb=(1, 2), nf=(1, 1), nk=(0, 2), n_inputs=2),
                    [0.8, 1.0, 0.5, -0.7, -0.5]),
    "general": (dict(na=1, nb=1, nc=1, nd=1, nf=1, nk=1), [-0.5, 1.0, 0.3, -0.6, -0.4]),
}


def simulate(s, theta, N, rng, noise_std=1.0):
    """``y = B/F u / A + C/(D A) e`` with white inputs, written with lfilter."""
    A, B, C, D, F = split_theta(np.asarray(theta, float), s)
    U = rng.standard_normal((N, s.n_inputs))
    e = noise_std * rng.standard_normal(N)
    x = sum((lfilter(B[i], F[i], U[:, i]) for i in range(s.n_inputs)), np.zeros(N))
    y = lfilter([1.0], A, x + lfilter(C, D, e))
    return U, y, e


def direct_prediction_errors(theta, s, U, y):
    """The pseudo-linear predictor written as a loop over its difference equations."""
    A, B, C, D, F = split_theta(np.asarray(theta, float), s)
    N = len(y)

    def lag(x, t, k):
        return x[t - k] if t >= k else 0.0

    w = np.zeros((N, s.n_inputs))
    v, eps = np.zeros(N), np.zeros(N)
    for t in range(N):
        for i in range(s.n_inputs):      # F w = B u
            w[t, i] = (sum(B[i][k] * lag(U[:, i], t, k) for k in range(len(B[i])))
                       - sum(F[i][k] * lag(w[:, i], t, k) for k in range(1, len(F[i]))))
        v[t] = sum(A[k] * lag(y, t, k) for k in range(len(A))) - w[t].sum()
        eps[t] = (sum(D[k] * lag(v, t, k) for k in range(len(D)))     # C eps = D v
                  - sum(C[k] * lag(eps, t, k) for k in range(1, len(C))))
    return eps


@pytest.mark.parametrize("name", list(CASES))
def test_prediction_errors_equal_the_difference_equations(name, rng):
    kw, theta = CASES[name]
    s = family_structure(**kw)
    U, y, _ = simulate(s, theta, 300, rng)
    th = np.asarray(theta) + 0.05 * rng.standard_normal(len(theta))
    np.testing.assert_allclose(prediction_errors(th, s, U, y),
                               direct_prediction_errors(th, s, U, y), rtol=1e-11, atol=1e-11)


@pytest.mark.parametrize("name", list(CASES))
def test_gradient_equals_central_differences(name, rng):
    kw, theta = CASES[name]
    s = family_structure(**kw)
    U, y, _ = simulate(s, theta, 400, rng)
    th = np.asarray(theta) + 0.05 * rng.standard_normal(len(theta))
    psi = predictor_gradient(th, s, U, y)
    h = 1e-6
    for k in range(s.n_params):
        d = np.zeros(s.n_params)
        d[k] = h
        num = -(prediction_errors(th + d, s, U, y) - prediction_errors(th - d, s, U, y)) / (2 * h)
        scale = np.max(np.abs(num)) + 1.0
        assert np.max(np.abs(psi[:, k] - num)) < 1e-7 * scale, (name, k)


def test_the_true_system_gives_the_innovations(rng):
    """At the true parameters the prediction error is e(t) once the start transient decays."""
    kw, theta = CASES["bj"]
    s = family_structure(**kw)
    U, y, e = simulate(s, theta, 3000, rng)
    eps = prediction_errors(np.asarray(theta), s, U, y)
    np.testing.assert_allclose(eps, e, atol=1e-12)      # every filter starts from rest


def _lfilter_criterion(theta, s, U, y):
    """The criterion written independently: sum over t >= t0 of (D/C (A y - sum B/F u))^2 / 2."""
    A, B, C, D, F = split_theta(np.asarray(theta, float), s)
    if s.nc and np.max(np.abs(np.roots(C))) >= 1 or s.nd and np.max(np.abs(np.roots(D))) >= 1 \
            or any(len(f) > 1 and np.max(np.abs(np.roots(f))) >= 1 for f in F):
        return 1e30
    v = lfilter(A, [1.0], y) - sum((lfilter(B[i], F[i], U[:, i]) for i in range(s.n_inputs)),
                                   np.zeros(len(y)))
    e = lfilter(D, C, v)[s.t0:]
    return 0.5 * e @ e


@pytest.mark.parametrize("name", ["armax", "oe", "bj", "miso_oe_nk0"])
def test_pem_equals_a_direct_minimization_of_the_criterion(name, rng):
    kw, theta = CASES[name]
    s = family_structure(**kw)
    U, y, _ = simulate(s, theta, 3000, rng, noise_std=0.5)
    fit = pem(U, y, s)
    # an independent search: Nelder-Mead from the truth on the lfilter criterion
    ref = minimize(_lfilter_criterion, np.asarray(theta, float), args=(s, U, y),
                   method="Nelder-Mead",
                   options=dict(xatol=1e-10, fatol=1e-12, maxiter=40000, maxfev=40000))
    assert ref.success
    assert fit.cost <= ref.fun * (1 + 1e-12)
    assert abs(fit.cost - criterion(fit.theta, s, U, y)) <= 1e-9 * fit.cost
    np.testing.assert_allclose(fit.theta, ref.x, atol=2e-7)
    assert predictor_is_stable(fit.theta, s)


def test_arx_structure_is_least_squares(rng):
    s = family_structure(na=2, nb=(2, 1), nk=(1, 0), n_inputs=2)
    U = rng.standard_normal((500, 2))
    y = lfilter([1.0], [1, -0.5, 0.2], U[:, 0] + rng.standard_normal(500))
    Phi, target = arx_regressors(U, y, 2, (2, 1), (1, 0))
    fit = pem(U, y, s)
    np.testing.assert_allclose(fit.theta, np.linalg.lstsq(Phi, target, rcond=None)[0],
                               rtol=1e-10, atol=1e-12)
    resid = target - Phi @ fit.theta
    sigma2 = resid @ resid / (len(target) - s.n_params)
    np.testing.assert_allclose(fit.cov, sigma2 * np.linalg.inv(Phi.T @ Phi), rtol=1e-8)


def test_non_invertible_truth_is_reflected(rng):
    """y = e(t) + 2 e(t-1) has the same spectrum as 2 (e'(t) + 0.5 e'(t-1)): the
    prediction-error model is the invertible one, whatever the start."""
    s = family_structure(nc=1, n_inputs=0)
    e = rng.standard_normal(20000)
    y = lfilter([1.0, 2.0], [1.0], e)
    fit = pem(np.zeros((len(y), 0)), y, s, theta0=np.array([2.0]))
    assert fit.theta0[0] == pytest.approx(0.5)          # the start was reflected
    se = np.sqrt(fit.cov[0, 0])
    assert abs(fit.theta[0] - 0.5) < 3 * se
    assert fit.noise_variance == pytest.approx(4.0, rel=0.05)


def test_initial_estimate_is_consistent_and_stable(rng):
    for name in ("armax", "oe", "bj", "arma"):
        kw, theta = CASES[name]
        s = family_structure(**kw)
        U, y, _ = simulate(s, theta, 40000, rng, noise_std=0.5)
        th0 = initial_estimate(U, y, s)
        assert predictor_is_stable(th0, s)
        np.testing.assert_allclose(th0, theta, atol=0.05, err_msg=name)


@pytest.mark.slow
def test_covariance_is_calibrated(rng):
    """z-scores (estimate - truth) / standard error over repeated ARMAX and OE
    experiments have zero mean and unit spread."""
    for name, reps in (("armax", 150), ("oe", 150)):
        kw, theta = CASES[name]
        s = family_structure(**kw)
        z = []
        for _ in range(reps):
            U, y, _ = simulate(s, theta, 1000, rng, noise_std=0.5)
            fit = pem(U, y, s)
            z.append((fit.theta - theta) / np.sqrt(np.diag(fit.cov)))
        z = np.array(z)
        # spread of reps * n_params z-scores: sd(std) about 1/sqrt(2 * 150) ~ 0.06 per column
        assert 0.85 < np.std(z) < 1.15, (name, np.std(z, axis=0))
        assert np.all(np.abs(np.mean(z, axis=0)) < 0.35), (name, np.mean(z, axis=0))
        assert np.all((np.std(z, axis=0) > 0.75) & (np.std(z, axis=0) < 1.25)), name


def test_too_short_record_is_an_error(rng):
    s = family_structure(na=2, nb=2, nc=2, nk=1)
    with pytest.raises(ValueError, match="more than t0 \\+ n_params = 2 \\+ 6 = 8 samples"):
        pem(rng.standard_normal((8, 1)), rng.standard_normal(8), s)


# ----------------------------------------------------------------------
# structure, polynomials, stability, long AR
# ----------------------------------------------------------------------
def test_structure_layout_and_names():
    s = family_structure(na=1, nb=(2, 1), nc=1, nd=2, nf=(1, 0), nk=(1, 0), n_inputs=2)
    assert s.n_params == 1 + 3 + 1 + 2 + 1
    assert param_names(s) == ["a1", "b1[u1]", "b2[u1]", "b1[u2]", "c1", "d1", "d2", "f1[u1]"]
    theta = np.arange(1.0, 9.0)
    A, B, C, D, F = split_theta(theta, s)
    np.testing.assert_array_equal(B[0], [0, 2, 3])
    np.testing.assert_array_equal(B[1], [4])
    np.testing.assert_array_equal(F[1], [1])
    np.testing.assert_array_equal(join_theta(s, A, B, C, D, F), theta)
    assert s.t0 == 2


@pytest.mark.parametrize("kw, match", [
    (dict(na=-1), "`na` must be >= 0; got -1"),
    (dict(nb=0), "`nb` must be >= 1; got 0"),
    (dict(nb=(1, 2)), "`nb` must be an integer or have one entry per input \\(1\\); got 2"),
    (dict(nc=1.5), "`nc` must be an integer; got 1.5"),
    (dict(na=0, nb=1, n_inputs=0), "at least one parameter"),
])
def test_structure_errors(kw, match):
    with pytest.raises((ValueError, TypeError), match=match):
        family_structure(**kw)


def test_stability_test_and_reflection_against_numpy_roots(rng):
    for _ in range(300):
        n = int(rng.integers(1, 6))
        p = np.concatenate([[1.0], 1.5 * rng.standard_normal(n)])
        radius = np.max(np.abs(np.roots(p)))
        if abs(radius - 1.0) > 1e-9:
            assert is_stable(p) == (radius < 1.0)
        q = reflect(p)
        assert is_stable(q)
        # reflection keeps |p(e^jw)| up to a constant
        w = np.linspace(0, np.pi, 64)
        ratio = (np.abs(np.polyval(p[::-1], np.exp(-1j * w)))
                 / np.abs(np.polyval(q[::-1], np.exp(-1j * w))))
        if radius < 1 - 1e-6 or min(np.abs(np.abs(np.roots(p)) - 1)) > 1e-6:
            np.testing.assert_allclose(ratio, ratio[0], rtol=1e-6)


def test_levinson_equals_yule_walker_solve(rng):
    x = lfilter([1.0], [1, -0.6, 0.3], rng.standard_normal(5000))
    a, _ = levinson_ar(x, 2, criterion="aic")
    r = np.array([x[: len(x) - k] @ x[k:] for k in range(3)]) / len(x)
    R = np.array([[r[0], r[1]], [r[1], r[0]]])
    np.testing.assert_allclose(a[1:], -np.linalg.solve(R, r[1:]), rtol=1e-10)
