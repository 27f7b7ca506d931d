"""Recursive prediction-error (RPEM) and pseudo-linear regression (RPLR) core.

Oracles: the readable NumPy reference (whose covariance update is the filters'
own ``forgetting.UPDATES``); `RecursiveLeastSquares` itself (RPLR on an ARX
structure *is* RLS, for every forgetting mode); the batch prediction-error
estimate; Ljung's positive-real condition.
"""

import warnings

import numpy as np
import pytest
from _reference_rpem import rpem_reference
from scipy.signal import lfilter

from rlsfilt import NumericalWarning, RecursiveLeastSquares
from rlsfilt.models import _recursive_kernels as K
from rlsfilt.models import arx_regressors
from rlsfilt.models._family import family_structure, split_theta
from rlsfilt.models._pem import pem
from rlsfilt.models._recursive_pem import (
    RecursionState,
    positive_real_margins,
    recursive_pem,
)
from rlsfilt.models._stability import is_stable, reflect

STRUCTURES = {
    "armax": (dict(na=2, nb=2, nc=2, nk=1), [-1.5, 0.7, 1.0, 0.5, -1.0, 0.2]),
    "oe": (dict(nb=2, nf=2, nk=1), [1.0, 0.5, -1.5, 0.7]),
    "bj": (dict(nb=2, nc=1, nd=1, nf=2, nk=1), [1.0, 0.5, 0.5, -0.9, -1.5, 0.7]),
    "miso_nk0": (dict(na=1, nb=(1, 2), nc=1, nf=(1, 0), nk=(0, 2), n_inputs=2),
                 [-0.6, 0.8, 1.0, 0.5, 0.4, -0.5]),
    "arma": (dict(na=2, nc=1, n_inputs=0), [-1.2, 0.5, 0.6]),
}

FORGETTING = [
    dict(),
    dict(lam=0.98),
    dict(lam=0.99, Q=1e-4),
    dict(lam=0.97, forgetting="directional"),
    dict(lam=0.98, forgetting="constant_trace"),
    dict(lam=0.98, forgetting="efra"),
    dict(lam=0.98, forgetting="variable"),
    dict(gate=2.5, R=0.25),
]


def simulate(s, theta, N, rng, noise_std=0.5):
    A, B, C, D, F = split_theta(np.asarray(theta, float), s)
    U = rng.standard_normal((N, s.n_inputs))
    e = noise_std * rng.standard_normal(N)
    x = sum((lfilter(B[i], F[i], U[:, i]) for i in range(s.n_inputs)), np.zeros(N))
    return U, lfilter([1.0], A, x + lfilter(C, D, e))


def _reference(state, y, U):
    """Run the NumPy reference from a fresh state's start."""
    Q = None if state.q_zero else state.Q
    return rpem_reference(state.theta, state.P, y, U, state.s, state.method, state.mode,
                          tuple(state.params), state.lam, Q, state.R, state.gate, state.project,
                          lam_now=state.lam_now, lam_rate=state.lam_rate)


@pytest.mark.parametrize("name", list(STRUCTURES))
@pytest.mark.parametrize("method", ["rpem", "rplr"])
@pytest.mark.parametrize("opts", FORGETTING, ids=lambda o: "-".join(map(str, o.values()))
                         or "plain")
def test_compiled_recursion_equals_the_numpy_reference(name, method, opts, rng):
    kw, theta = STRUCTURES[name]
    s = family_structure(**kw)
    U, y = simulate(s, theta, 250, rng)
    state = RecursionState(s, method, P0=100.0, **opts)
    theta_r, P_r, hist_r, yhat_r, eps_r = _reference(state, y, U)
    out = state.run(y, U)
    np.testing.assert_allclose(out["theta_history"], hist_r, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(out["yhat"], yhat_r, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(state.P, P_r, rtol=1e-8, atol=1e-9)


@pytest.mark.parametrize("opts", FORGETTING, ids=lambda o: "-".join(map(str, o.values()))
                         or "plain")
def test_rplr_of_an_arx_structure_is_recursive_least_squares(opts, rng):
    """With no C, D, F the pseudo-linear regressor is the ARX regressor and the
    recursion is RecursiveLeastSquares with the same options."""
    s = family_structure(na=2, nb=(2, 1), nk=(1, 0), n_inputs=2)
    U = rng.standard_normal((400, 2))
    y = lfilter([1.0], [1, -1.2, 0.5], U[:, 0] + 0.5 * U[:, 1] + 0.3 * rng.standard_normal(400))
    fit = recursive_pem(U, y, s, method="rplr", P0=50.0, lam_start=1.0, **opts)
    # the same rows from t = 0 with zero past: the recursion sees phi(t) from the first sample
    Phi, target = arx_regressors(U, y, 2, (2, 1), (1, 0), start=0)
    rls = RecursiveLeastSquares(s.n_params, P0=50.0, **opts)
    means = rls.batch_filter(target, Phi)[0][:, :, 0]
    np.testing.assert_allclose(fit.theta_history, means, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(fit.state.P, rls.P, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(fit.yhat, np.einsum("ij,ij->i", Phi,
                                                   np.vstack([np.zeros(s.n_params),
                                                              means[:-1]])), atol=1e-10)


@pytest.mark.parametrize("method", ["rpem", "rplr"])
def test_streaming_steps_equal_the_batch_run_bit_for_bit(method, rng):
    kw, theta = STRUCTURES["bj"]
    s = family_structure(**kw)
    U, y = simulate(s, theta, 300, rng)
    a = RecursionState(s, method, lam=0.99, Q=1e-5)
    b = a.copy()
    out = a.run(y, U)
    for t in range(len(y)):
        yhat, eps, _ = b.step(y[t], U[t])
        assert yhat == out["yhat"][t] and eps == out["eps"][t]
        np.testing.assert_array_equal(b.theta, out["theta_history"][t])
    np.testing.assert_array_equal(a.P, b.P)
    np.testing.assert_array_equal(a.buf, b.buf)


def test_split_record_continues_exactly(rng):
    """run(first half) then run(second half) is run(whole record)."""
    kw, theta = STRUCTURES["armax"]
    s = family_structure(**kw)
    U, y = simulate(s, theta, 400, rng)
    a = RecursionState(s, "rpem")
    b = a.copy()
    whole = a.run(y, U)["theta_history"]
    b.run(y[:150], U[:150])
    second = b.run(y[150:], U[150:])["theta_history"]
    np.testing.assert_array_equal(second, whole[150:])


def test_projection_keeps_the_predictor_stable(rng):
    kw, theta = STRUCTURES["bj"]
    s = family_structure(**kw)
    U, y = simulate(s, theta, 2000, rng)
    fit = recursive_pem(U, y, s, method="rpem", P0=1e4)
    for th in fit.theta_history[::7]:
        _, _, C, D, F = split_theta(th, s)
        assert is_stable(C) and is_stable(D) and is_stable(F[0])


# ----------------------------------------------------------------------
# the closed-form / oracle requirements
# ----------------------------------------------------------------------
def test_rplr_fails_where_1_over_C_is_not_positive_real_and_rpem_does_not(rng):
    """y = (1 + 1.6 q^-1 + 0.8 q^-2) e: Re{1/C} > 1/2 fails, so extended least
    squares does not reach the truth; RPEM does (Ljung 1977)."""
    s = family_structure(nc=2, n_inputs=0)
    N = 200_000
    y = lfilter([1.0, 1.6, 0.8], [1.0], rng.standard_normal(N))
    U = np.zeros((N, 0))
    rpem_fit = recursive_pem(U, y, s, method="rpem")
    assert np.max(np.abs(rpem_fit.theta - [1.6, 0.8])) < 0.01
    with pytest.warns(NumericalWarning, match="Re\\{1/C\\} > 1/2 fails.*method='rpem'"):
        rplr_fit = recursive_pem(U, y, s, method="rplr")
    assert np.max(np.abs(rplr_fit.theta - [1.6, 0.8])) > 0.01


def test_rplr_and_rpem_agree_where_1_over_C_is_positive_real(rng):
    s = family_structure(nc=2, n_inputs=0)
    N = 200_000
    y = lfilter([1.0, 0.5, 0.2], [1.0], rng.standard_normal(N))
    U = np.zeros((N, 0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")               # no positive-realness warning
        for method in ("rpem", "rplr"):
            fit = recursive_pem(U, y, s, method=method)
            assert np.max(np.abs(fit.theta - [0.5, 0.2])) < 0.02, method


@pytest.mark.parametrize("name", ["armax", "oe", "bj"])
def test_rpem_with_lam_1_ends_near_batch_pem(name, rng):
    """Within 2 standard errors of the batch estimate (both are asymptotically efficient)."""
    kw, theta = STRUCTURES[name]
    s = family_structure(**kw)
    U, y = simulate(s, theta, 20000, rng)
    batch = pem(U, y, s)
    fit = recursive_pem(U, y, s, method="rpem")
    se = np.sqrt(np.diag(batch.cov))
    assert np.all(np.abs(fit.theta - batch.theta) < 2 * se), (fit.theta - batch.theta) / se


def test_positive_real_margins_match_the_disc_condition():
    """Re{1/C} > 1/2 at a frequency if and only if |C - 1| < 1 there."""
    s = family_structure(nc=2, n_inputs=0)
    w = np.linspace(0, np.pi, 1024)
    for c in ([1.6, 0.8], [0.5, 0.2], [-1.0, 0.2], [0.9, 0.0], [0.0, -0.9]):
        Cw = 1 + c[0] * np.exp(-1j * w) + c[1] * np.exp(-2j * w)
        margin, omega = positive_real_margins(np.array(c), s)["1/C"]
        assert (margin > 0) == bool(np.all(np.abs(Cw - 1) < 1))
        np.testing.assert_allclose(margin, np.min(np.real(1 / Cw)) - 0.5, rtol=1e-12)


def test_positive_real_filters_per_structure():
    def names(**kw):
        s = family_structure(**kw)
        return sorted(positive_real_margins(np.zeros(s.n_params), s))

    assert names(na=1, nb=1, nc=1) == ["1/C"]
    assert names(nb=1, nf=1) == ["1/F"]
    assert names(nb=1, nc=1, nd=1, nf=1) == ["1/C", "D/(C F)"]
    assert names(na=1, nb=(1, 1), nd=1, nf=(1, 0), n_inputs=2) == ["D", "D/F_1"]
    assert names(na=1, nb=1) == []


def test_compiled_stability_helpers_equal_numpy(rng):
    for _ in range(200):
        n = int(rng.integers(1, 6))
        p = np.concatenate([[1.0], 1.5 * rng.standard_normal(n)])
        assert K.is_stable(p) == is_stable(p)
        np.testing.assert_allclose(K.reflect(p), reflect(p), rtol=1e-9, atol=1e-12)


def test_options_are_validated():
    s = family_structure(na=1, nb=1, nc=1)
    with pytest.raises(ValueError, match="`lam` must be in \\(0, 1\\]; got 1.5"):
        RecursionState(s, lam=1.5)
    with pytest.raises(ValueError, match="`method` must be 'rpem' or 'rplr'; got 'els'"):
        RecursionState(s, "els")
    with pytest.raises(ValueError, match="`forgetting` must be one of"):
        RecursionState(s, forgetting="sliding")
    with pytest.raises(TypeError, match="unknown keys \\['eps'\\]"):
        RecursionState(s, lam=0.9, forgetting="efra", forgetting_params={"eps": 1})
    with pytest.raises(ValueError, match="`P0` must be positive definite"):
        RecursionState(s, P0=0.0)
    with pytest.raises(ValueError, match="`x0` must have n_params = 3 entries; got 2"):
        RecursionState(s, x0=[0.0, 1.0])
    with pytest.raises(ValueError, match="`gate` must be a positive finite number; got -1.0"):
        RecursionState(s, gate=-1)
