"""Instrumental variables, batch and recursive (rlsfilt.models._iv).

Oracles: ``numpy.linalg.solve`` of the IV normal equations ``(Z^T Phi) theta =
Z^T y`` built here from shifted columns, at every step of the recursion; the
readable NumPy reference of the kernels; z-scores over repeated experiments
for the covariance under coloured noise.
"""

import _reference_riv
import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import NumericalWarning
from rlsfilt.models import arx_regressors, arx_structure
from rlsfilt.models._iv import (
    delayed_input_instruments,
    fit_iv,
    iv_solve,
    recursive_iv,
)

A_TRUE, B_TRUE, C_TRUE = [1, -1.5, 0.7], [0, 1.0, 0.5], [1, -1.0, 0.2]
THETA = np.array([-1.5, 0.7, 1.0, 0.5])


def armax_record(rng, N, noise_std=1.0):
    u = rng.standard_normal(N)
    e = noise_std * rng.standard_normal(N)
    y = lfilter(B_TRUE, A_TRUE, u) + lfilter(C_TRUE, A_TRUE, e)
    return u, y


def shifted(x, k):
    out = np.zeros_like(x)
    out[k:] = x[:len(x) - k]
    return out


def test_delayed_instruments_are_the_shifted_inputs(rng):
    U = rng.standard_normal((50, 2))
    s = arx_structure(2, (2, 1), (1, 0), n_inputs=2)
    Z = delayed_input_instruments(U, s)
    expect = np.column_stack([shifted(U[:, 0], 3), shifted(U[:, 0], 4),
                              shifted(U[:, 0], 1), shifted(U[:, 0], 2), U[:, 1]])[s.max_lag:]
    np.testing.assert_array_equal(Z, expect)


@pytest.mark.parametrize("instruments", ["delayed", "user"])
def test_batch_iv_solves_the_iv_normal_equations(instruments, rng):
    u, y = armax_record(rng, 3000)
    s = arx_structure(2, 2, 1)
    Phi, target = arx_regressors(u, y, 2, 2, 1)
    if instruments == "user":
        r = rng.standard_normal(3000)            # e.g. a reference signal, lags 1..4
        Zfull = np.column_stack([shifted(u + 0.1 * r, k) for k in range(1, 5)])
        arg, Z = Zfull, Zfull[s.max_lag:]
    else:
        arg = "delayed"
        Z = np.column_stack([shifted(u, k) for k in (3, 4, 1, 2)])[s.max_lag:]
    fit = fit_iv(u[:, None], y[:, None], s, arg)
    np.testing.assert_allclose(fit.theta[:, 0], np.linalg.solve(Z.T @ Phi, Z.T @ target),
                               rtol=1e-10)


def test_refined_iv_is_a_fixed_point_of_its_iteration(rng):
    """At convergence the estimate reproduces itself when its own auxiliary
    model and prefilter 1/A generate the instruments."""
    u, y = armax_record(rng, 5000)
    s = arx_structure(2, 2, 1)
    fit = fit_iv(u[:, None], y[:, None], s, "model", n_iter=50, tol=1e-13)
    a = np.concatenate([[1.0], fit.theta[:2, 0]])
    x = lfilter(np.concatenate([[0.0], fit.theta[2:, 0]]), a, u)
    uf, yf, xf = (lfilter([1.0], a, v) for v in (u, y, x))
    Phi, target = arx_regressors(uf, yf, 2, 2, 1)
    Z, _ = arx_regressors(uf, xf, 2, 2, 1)
    np.testing.assert_allclose(fit.theta[:, 0], np.linalg.solve(Z.T @ Phi, Z.T @ target),
                               rtol=1e-9)


@pytest.mark.parametrize("instruments", ["delayed", "user", "model", "model-prefilter"])
def test_recursive_iv_equals_batch_iv_at_every_step(instruments, rng):
    """lam = 1 and the exact start on the first n_params rows: theta(t) is
    (Z_t^T Phi_t)^-1 Z_t^T y_t for every t, with the rows the recursion used."""
    u, y = armax_record(rng, 1500)
    s = arx_structure(2, 2, 1)
    kw = {}
    if instruments == "user":
        arg = np.column_stack([shifted(u, k) for k in (1, 2, 3, 5)])
    elif instruments.startswith("model"):
        arg = "model"
        kw = dict(refresh=97, prefilter=instruments.endswith("prefilter"))
    else:
        arg = "delayed"
    fit = recursive_iv(u[:, None], y[:, None], s, arg, **kw)
    Phi, Z, target = fit.Phi, fit.Z, fit.target[:, 0]
    n = s.n_params
    assert np.isnan(fit.theta_history[:n - 1]).all()
    for t in range(n, len(Phi) + 1, 7):
        batch = np.linalg.solve(Z[:t].T @ Phi[:t], Z[:t].T @ target[:t])
        np.testing.assert_allclose(fit.theta_history[t - 1, :, 0], batch, rtol=1e-10,
                                   atol=1e-10 * np.max(np.abs(batch)), err_msg=f"step {t}")
    if instruments == "delayed":
        np.testing.assert_array_equal(Z, delayed_input_instruments(u[:, None], s))


@pytest.mark.parametrize("case", ["rows", "model", "model-prefilter-lam-Q"])
def test_compiled_recursive_iv_equals_the_numpy_reference(case, rng):
    u, y = armax_record(rng, 600)
    s = arx_structure(2, 2, 1)
    kw = dict(lam=0.99, Q=1e-4 * np.eye(4)) if case.endswith("Q") else {}
    if case.startswith("model"):
        kw.update(refresh=40, prefilter="prefilter" in case)
    arg = "delayed" if case == "rows" else "model"
    a = recursive_iv(u[:, None], y[:, None], s, arg, **kw)
    b = recursive_iv(u[:, None], y[:, None], s, arg, kernels=_reference_riv, **kw)
    np.testing.assert_allclose(a.theta_history, b.theta_history, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(a.P, b.P, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a.Z, b.Z, rtol=1e-10, atol=1e-12)


def test_p_is_not_symmetric_and_is_the_inverse_of_z_phi(rng):
    u, y = armax_record(rng, 800)
    s = arx_structure(2, 2, 1)
    fit = recursive_iv(u[:, None], y[:, None], s, "delayed")
    M = fit.Z.T @ fit.Phi
    np.testing.assert_allclose(fit.P @ M, np.eye(4), atol=1e-9)
    assert np.max(np.abs(fit.P - fit.P.T)) > 1e-6


def test_uncorrelated_instruments_are_reported(rng):
    u, y = armax_record(rng, 500)
    s = arx_structure(2, 2, 1)
    Z = np.column_stack([shifted(u, 1), shifted(u, 2), rng.standard_normal(500) * 0,
                         shifted(u, 3)])
    with pytest.raises(ValueError, match="not correlated with every regressor"):
        fit_iv(u[:, None], y[:, None], s, Z)
    with pytest.raises(ValueError, match="exact start on the first k0 = 4 rows is singular"):
        recursive_iv(u[:, None], y[:, None], s, Z)
    # a prior start runs; an instrument that makes R + phi^T P z vanish is reported:
    # zero instruments leave P = P0 = I for three rows, then z = -phi / |phi|^2
    Phi, _ = arx_regressors(u, y, 2, 2, 1, start=0)
    Zbad = rng.standard_normal((500, 4))
    t3 = s.max_lag + 3
    Zbad[s.max_lag:t3] = 0.0
    Zbad[t3] = -Phi[t3] / (Phi[t3] @ Phi[t3])
    with pytest.warns(NumericalWarning, match="nearly vanished at row 3"):
        fit = recursive_iv(u[:, None], y[:, None], s, Zbad, k0=0, P0=1.0)
    assert fit.bad_step == 3


def test_iv_solve_extended_instruments(rng):
    Phi = rng.standard_normal((200, 3))
    Z = np.hstack([Phi + 0.1 * rng.standard_normal((200, 3)), rng.standard_normal((200, 2))])
    y = Phi @ [1.0, -2.0, 0.5] + rng.standard_normal(200)
    theta, G, M = iv_solve(Z, Phi, y)
    np.testing.assert_allclose(theta, np.linalg.lstsq(Z.T @ Phi, Z.T @ y, rcond=None)[0],
                               rtol=1e-10)


def test_iv_covariance_is_calibrated_under_coloured_noise(rng):
    """z-scores of the refined IV estimate over repeated ARMAX experiments
    (MA(2) equation error) have unit spread."""
    s = arx_structure(2, 2, 1)
    z = []
    for _ in range(200):
        u, y = armax_record(rng, 2000)
        fit = fit_iv(u[:, None], y[:, None], s, "model")
        z.append((fit.theta[:, 0] - THETA) / np.sqrt(np.diag(fit.cov)))
    z = np.array(z)
    assert 0.85 < np.std(z) < 1.15, np.std(z, axis=0)
    assert np.all(np.abs(np.mean(z, axis=0)) < 0.3), np.mean(z, axis=0)


# ----------------------------------------------------------------------
# ARX.fit(method="iv" | "riv")
# ----------------------------------------------------------------------
def test_arx_iv_is_the_iv_solution_on_its_instruments(rng):
    from rlsfilt import ARX

    u, y = armax_record(rng, 4000)
    Phi, target = arx_regressors(u, y, 2, 2, 1)
    for kw in ({}, {"instruments": "delayed"}, {"prefilter": False}):
        model = ARX(2, 2, 1).fit(u, y, method="iv", **kw)
        if kw.get("prefilter", True) and "instruments" not in kw:
            continue          # the refined IV works on prefiltered rows (fixed point test above)
        Z = model.instruments_
        np.testing.assert_allclose(model.theta_, np.linalg.solve(Z.T @ Phi, Z.T @ target),
                                   rtol=1e-10)
        np.testing.assert_allclose(model.residuals_, target - Phi @ model.theta_, rtol=1e-12)
    ls = ARX(2, 2, 1).fit(u, y)
    iv = ARX(2, 2, 1).fit(u, y, method="iv")
    # least squares is biased by the MA(2) equation error, IV is not
    assert np.any(np.abs(ls.theta_ - THETA) > 5 * ls.std_errors_)
    assert np.all(np.abs(iv.theta_ - THETA) < 3 * iv.std_errors_)


def test_arx_riv_history_is_batch_iv_at_every_step(rng):
    from rlsfilt import ARX

    u, y = armax_record(rng, 600)
    model = ARX(2, 2, 1).fit(u, y, method="riv", instruments="delayed")
    Phi, target = arx_regressors(u, y, 2, 2, 1)
    Z = model.instruments_
    assert model.k0_ == 4 and model.method_ == "riv"
    for t in range(4, len(Phi) + 1, 11):
        np.testing.assert_allclose(model.theta_history_[t - 1],
                                   np.linalg.solve(Z[:t].T @ Phi[:t], Z[:t].T @ target[:t]),
                                   rtol=1e-10, atol=1e-12)
    assert "recursive instrumental variables" in str(model.summary())


def test_arx_iv_options_are_checked(rng):
    from rlsfilt import ARX

    u, y = armax_record(rng, 300)
    with pytest.raises(TypeError, match="`refresh` is not an option of ARX.fit\\(method='iv'\\)"):
        ARX(2, 2).fit(u, y, method="iv", refresh=10)
    with pytest.raises(TypeError, match="`forgetting` is not an option of ARX.fit\\(method='riv'"):
        ARX(2, 2).fit(u, y, method="riv", forgetting="directional")
    with pytest.raises(ValueError, match="`instruments` must be 'model', 'delayed' or an array"):
        ARX(2, 2).fit(u, y, method="iv", instruments="lagged")
    with pytest.raises(ValueError, match="`instruments='model'` needs a single output"):
        ARX(1, 1).fit(u, np.column_stack([y, y]), method="iv", instruments="model")
    with pytest.raises(ValueError, match="`lam` must be in \\(0, 1\\]; got 0.0"):
        ARX(2, 2).fit(u, y, method="riv", lam=0.0)


# ----------------------------------------------------------------------
# the streaming form
# ----------------------------------------------------------------------
@pytest.mark.parametrize("kw", [dict(k0=0), dict(k0=4, prefilter=True, refresh=37)])
def test_streaming_riv_equals_the_batch_recursion_bit_for_bit(kw, rng):
    from rlsfilt import RecursiveIV

    u, y = armax_record(rng, 1500)
    aux = np.array([-1.0, 0.3, 1.0, 0.0])
    est = RecursiveIV(2, 2, 1, theta_aux=aux, **kw)
    thetas = np.array([est.step(y[t], u[t])[1] for t in range(len(y))])
    kw_batch = dict(kw, refresh=est.refresh)
    fit = recursive_iv(u[:, None], y[:, None], arx_structure(2, 2, 1), "model", theta_aux=aux,
                       P0=1e4, **kw_batch)
    hist = fit.theta_history[:, :, 0]
    start = max(kw["k0"] - 1, 0)
    np.testing.assert_array_equal(thetas[2 + start:], hist[start:])


def test_streaming_riv_with_given_instruments_is_batch_iv(rng):
    """Instruments supplied per sample (a reference signal's lags), exact start on 4 rows:
    every estimate is the batch IV solution of the rows so far."""
    from rlsfilt import RecursiveIV

    u, y = armax_record(rng, 400)
    r = u + 0.2 * rng.standard_normal(400)
    Zfull = np.column_stack([shifted(r, k) for k in (1, 2, 3, 4)])
    est = RecursiveIV(2, 2, 1, instruments="given", k0=4)
    preds, thetas = [], []
    for t in range(400):
        yhat, theta = est.step(y[t], u[t], z=Zfull[t])
        preds.append(yhat)
        thetas.append(theta)
    Phi, target = arx_regressors(u, y, 2, 2, 1)
    Z = Zfull[2:]
    for t in range(4, len(Phi) + 1, 9):
        np.testing.assert_allclose(thetas[t + 1], np.linalg.solve(Z[:t].T @ Phi[:t],
                                                                  Z[:t].T @ target[:t]),
                                   rtol=1e-10)
    assert np.isnan(preds[2:5]).all() and np.isfinite(preds[6])
    np.testing.assert_allclose(preds[10], Phi[8] @ thetas[9], rtol=1e-13)


def test_streaming_riv_errors(rng):
    from rlsfilt import RecursiveIV

    est = RecursiveIV(1, 1, 1, instruments="given")
    with pytest.raises(ValueError, match="`z` must be given: instruments='given'"):
        est.step(1.0, 0.0)
    with pytest.raises(ValueError, match="`z` must have n_params = 2 entries; got 3"):
        est.step(1.0, 0.0, z=[1, 2, 3])
    with pytest.raises(ValueError, match="`z` only applies to instruments='given'"):
        RecursiveIV(1, 1).step(1.0, 0.0, z=[1, 2])
    with pytest.raises(ValueError, match="`instruments` must be 'model', 'delayed' or 'given'; "
                                         "got 'lagged'"):
        RecursiveIV(1, 1, instruments="lagged")
    with pytest.raises(ValueError, match="`u` must have 1 entries"):
        RecursiveIV(1, 1).step(1.0, [0.0, 1.0])
    assert est.n_steps == 0
    zero = RecursiveIV(1, 1, 1, instruments="given", k0=2)
    zero.step(1.0, 1.0, z=[0.0, 0.0])
    zero.step(1.0, 1.0, z=[0.0, 0.0])
    with pytest.raises(ValueError, match="exact start on the first k0 = 2 rows is singular"):
        zero.step(1.0, 1.0, z=[0.0, 0.0])
