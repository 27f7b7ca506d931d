"""Closed-form and external oracles for the models beyond ARX (issue 14).

* The ARX least-squares estimate of an ARMAX plant converges to its biased
  limit ``theta* = R^-1 E[phi y]``, computed here from the exact covariances of
  the plant's state-space realization (a discrete Lyapunov equation), while the
  prediction-error ARMAX estimate and the IV estimate converge to the truth.
* ARMA by prediction error agrees with statsmodels' exact maximum likelihood.
"""

import numpy as np
import pytest
from scipy.linalg import solve_discrete_lyapunov
from scipy.signal import lfilter

from rlsfilt.models import arx_regressors, arx_structure
from rlsfilt.models._family import family_structure
from rlsfilt.models._iv import fit_iv
from rlsfilt.models._pem import pem

A_TRUE, B_TRUE, C_TRUE = [1.0, -1.5, 0.7], [0.0, 1.0, 0.5], [1.0, -1.0, 0.2]


def observable_form(num, den):
    """``(F, G, H, J)`` of ``num/den`` (polynomials in q^-1, monic ``den``) in
    observer canonical form: x(t+1) = F x + G w, y = H x + J w."""
    n = max(len(num), len(den)) - 1
    num = np.concatenate([num, np.zeros(n + 1 - len(num))])
    den = np.concatenate([den, np.zeros(n + 1 - len(den))])
    F = np.zeros((n, n))
    F[:, 0] = -den[1:]
    F[:-1, 1:] = np.eye(n - 1)
    G = (num[1:] - den[1:] * num[0])[:, None]
    H = np.zeros((1, n))
    H[0, 0] = 1.0
    return F, G, H, np.array([[num[0]]])


def arx_limit(su2=1.0, se2=1.0):
    """theta* of ARX(2, 2, 1) least squares on y = B/A u + C/A e (white u, e)."""
    F1, G1, H1, J1 = observable_form(B_TRUE, A_TRUE)
    F2, G2, H2, J2 = observable_form(C_TRUE, A_TRUE)
    F = np.block([[F1, np.zeros_like(F1)], [np.zeros_like(F2), F2]])
    G = np.block([[G1, np.zeros_like(G1)], [np.zeros_like(G2), G2]])
    H = np.hstack([H1, H2])
    J = np.hstack([J1, J2])
    W = np.diag([su2, se2])
    S = solve_discrete_lyapunov(F, G @ W @ G.T)              # state covariance

    def r_yy(k):                                            # E y(t) y(t-k)
        k = abs(k)
        if k == 0:
            return (H @ S @ H.T + J @ W @ J.T).item()
        Fk1 = np.linalg.matrix_power(F, k - 1)
        return (H @ F @ Fk1 @ S @ H.T + H @ Fk1 @ G @ W @ J.T).item()

    def g(k):                                               # impulse response of B/A
        if k < 0:
            return 0.0
        if k == 0:
            return J1.item()
        return (H1 @ np.linalg.matrix_power(F1, k - 1) @ G1).item()

    def r_yu(i, j):                                         # E y(t-i) u(t-j)
        return su2 * g(j - i)

    # phi = [-y(t-1), -y(t-2), u(t-1), u(t-2)]
    R = np.array([[r_yy(0), r_yy(1), -r_yu(1, 1), -r_yu(1, 2)],
                  [r_yy(1), r_yy(0), -r_yu(2, 1), -r_yu(2, 2)],
                  [-r_yu(1, 1), -r_yu(2, 1), su2, 0.0],
                  [-r_yu(1, 2), -r_yu(2, 2), 0.0, su2]])
    rhs = np.array([-r_yy(1), -r_yy(2), r_yu(0, 1), r_yu(0, 2)])
    return np.linalg.solve(R, rhs), r_yy(0)


def test_lyapunov_covariances_match_a_simulation(rng):
    """The oracle itself: the Lyapunov variance of y matches a long simulation."""
    _, var_y = arx_limit()
    u, e = rng.standard_normal(400_000), rng.standard_normal(400_000)
    y = lfilter(B_TRUE, A_TRUE, u) + lfilter(C_TRUE, A_TRUE, e)
    assert np.var(y[1000:]) == pytest.approx(var_y, rel=0.03)


@pytest.mark.slow
def test_arx_is_biased_to_its_limit_while_armax_and_iv_reach_the_truth(rng):
    N = 200_000
    u, e = rng.standard_normal(N), rng.standard_normal(N)
    y = lfilter(B_TRUE, A_TRUE, u) + lfilter(C_TRUE, A_TRUE, e)
    truth = np.array([-1.5, 0.7, 1.0, 0.5])
    limit, _ = arx_limit()
    assert np.max(np.abs(limit - truth)) > 0.25               # the bias is large

    Phi, target = arx_regressors(u, y, 2, 2, 1)
    theta_ls = np.linalg.lstsq(Phi, target, rcond=None)[0]
    # sampling spread of the ARX estimate at N = 2e5 is about 3e-3 (measured)
    np.testing.assert_allclose(theta_ls, limit, atol=0.01)

    armax = pem(u[:, None], y, family_structure(na=2, nb=2, nc=2, nk=1))
    se = np.sqrt(np.diag(armax.cov))
    z = (armax.theta - np.concatenate([truth, C_TRUE[1:]])) / se
    assert np.all(np.abs(z) < 3), z

    for instruments in ("model", "delayed"):
        iv = fit_iv(u[:, None], y[:, None], arx_structure(2, 2, 1), instruments)
        z = (iv.theta[:, 0] - truth) / np.sqrt(np.diag(iv.cov))
        assert np.all(np.abs(z) < 3), (instruments, z)


@pytest.mark.slow
@pytest.mark.parametrize("p, q, a, c", [(2, 1, [-1.2, 0.5], [0.6]), (1, 2, [-0.7], [0.4, -0.3])])
def test_arma_agrees_with_statsmodels_maximum_likelihood(p, q, a, c, rng):
    pytest.importorskip("statsmodels")
    from statsmodels.tsa.arima.model import ARIMA

    N = 20_000
    y = lfilter(np.concatenate([[1.0], c]), np.concatenate([[1.0], a]),
                rng.standard_normal(N))
    fit = pem(np.zeros((N, 0)), y, family_structure(na=p, nc=q, n_inputs=0))
    sm = ARIMA(y, order=(p, 0, q), trend="n").fit()
    # statsmodels: y_t = phi_1 y_{t-1} + ... + e_t + theta_1 e_{t-1}; ours: a_k = -phi_k
    theta_sm = np.concatenate([-sm.params[:p], sm.params[p:p + q]])
    se_sm = sm.bse[:p + q]
    assert np.all(np.abs(fit.theta - theta_sm) < 0.2 * se_sm), (fit.theta - theta_sm) / se_sm
    np.testing.assert_allclose(np.sqrt(np.diag(fit.cov)), se_sm, rtol=0.1)
    assert fit.noise_variance == pytest.approx(sm.params[-1], rel=0.01)
