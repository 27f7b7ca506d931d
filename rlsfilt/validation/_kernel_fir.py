r"""Kernel-regularized FIR least squares, hyperparameters by marginal likelihood.

The estimate of :func:`rlsfilt.validation.impulseest` with ``regularization="tc"`` or
``"dc"`` (MATLAB's default ``impulseest``): the FIR regression

.. math::

    Y = \Phi g + e, \qquad e \sim N(0, \sigma^2 I_N),

with a Gaussian prior :math:`g \sim N(0, P(\eta))` whose covariance (the kernel) encodes
an exponentially decaying, smooth impulse response, one block per input. The
hyperparameters :math:`\eta` maximize the marginal likelihood of the data (empirical Bayes),
and the estimate is the posterior mean with the posterior covariance as its uncertainty
(T. Chen, H. Ohlsson and L. Ljung, "On the estimation of transfer functions,
regularizations and Gaussian processes - Revisited", Automatica 48(8), 2012).
"""

import numpy as np

__all__ = []

#: The kernels and their hyperparameters, in the order of the optimizer's vector.
KERNEL_PARAMS = {"tc": ("c", "lam"), "dc": ("c", "lam", "rho")}

#: The starts of the decay rate lambda (the search runs from each and keeps the best).
_LAMBDA_STARTS = (0.6, 0.8, 0.9, 0.95)


def kernel_matrix(kind, n, c, lam, rho=None):
    r"""The prior covariance of ``n`` coefficients, lags ``0 .. n - 1`` (``k = lag + 1``).

    TC (tuned/correlated), :math:`P_{kj} = c\,\lambda^{\max(k, j)}`; DC (diagonal/
    correlated), :math:`P_{kj} = c\,\lambda^{(k + j)/2} \rho^{|k - j|}`, for
    :math:`k, j = 1 .. n` (Chen, Ohlsson and Ljung 2012, eqs. (14) and (15)).
    """
    k = np.arange(1, n + 1)
    if kind == "tc":
        # P[k, j] = c * lam^max(k, j)
        return c * lam ** np.maximum.outer(k, k).astype(float)
    # P[k, j] = c * lam^((k + j) / 2) * rho^|k - j|
    return (c * lam ** (np.add.outer(k, k) / 2.0)
            * float(rho) ** np.abs(np.subtract.outer(k, k)).astype(float))


def prior_covariance(kind, n, hyper):
    """Block-diagonal prior of all inputs (columns input by input, `n` lags each);
    `hyper` maps each hyperparameter name to an array with one value per input."""
    nu = len(hyper["c"])
    P = np.zeros((n * nu, n * nu))
    for j in range(nu):
        args = [hyper[name][j] for name in KERNEL_PARAMS[kind]]
        P[j * n:(j + 1) * n, j * n:(j + 1) * n] = kernel_matrix(kind, n, *args)
    return P


class Evidence:
    r"""The regression reduced once by a QR factorization, for fast marginal likelihoods.

    With :math:`\Phi = Q_1 R` (:math:`Q_1` of shape ``(N, m)``, orthonormal columns),
    :math:`z = Q_1^\top Y` and :math:`r = \lVert Y - Q_1 z\rVert^2`, the covariance of the
    data :math:`\Sigma = \Phi P \Phi^\top + \sigma^2 I_N` is block diagonal in the basis
    :math:`[Q_1\ Q_2]`: :math:`S = R P R^\top + \sigma^2 I_m` on the range of
    :math:`\Phi`, :math:`\sigma^2 I_{N-m}` on its complement. Every quantity then costs
    :math:`O(m^3)` instead of :math:`O(N^3)`:

    .. math::

        \log p(Y \mid \eta) = -\tfrac12 \left( z^\top S^{-1} z + r / \sigma^2
            + \log\det S + (N - m) \log\sigma^2 + N \log 2\pi \right),

        \hat g = P R^\top S^{-1} z, \qquad
        \operatorname{cov}(g \mid Y) = P - P R^\top S^{-1} R P .
    """

    def __init__(self, Phi, Y, sigma2):
        Q, self.R = np.linalg.qr(Phi)
        self.z = Q.T @ Y
        self.r = float(np.sum((Y - Q @ self.z) ** 2))
        self.N, self.m = Phi.shape
        self.sigma2 = float(sigma2)

    def _chol(self, P):
        from scipy.linalg import cho_factor

        RP = self.R @ P
        S = RP @ self.R.T + self.sigma2 * np.eye(self.m)
        return cho_factor(0.5 * (S + S.T), lower=True), RP

    def log_likelihood(self, P):
        """:math:`\\log p(Y \\mid P, \\sigma^2)`, the Gaussian log-density of the data."""
        from scipy.linalg import solve_triangular

        (L, _), _ = self._chol(P)
        w = solve_triangular(L, self.z, lower=True)           # z' S^-1 z = |L^-1 z|^2
        quad = float(w @ w) + self.r / self.sigma2
        logdet = 2.0 * np.sum(np.log(np.diag(L))) + (self.N - self.m) * np.log(self.sigma2)
        return -0.5 * (quad + logdet + self.N * np.log(2.0 * np.pi))

    def posterior(self, P):
        """``(mean, covariance)`` of the coefficients given the data."""
        from scipy.linalg import cho_solve, solve_triangular

        cf, RP = self._chol(P)
        mean = RP.T @ cho_solve(cf, self.z)                    # P R' S^-1 z
        B = solve_triangular(cf[0], RP, lower=True)            # L^-1 R P
        cov = P - B.T @ B                                      # P - P R' S^-1 R P
        return mean, 0.5 * (cov + cov.T)


def fit_kernel(Phi, Y, kind, nu, n, sigma2, hyper=None):
    """The regularized FIR estimate: ``(mean, cov, hyper, log_likelihood)``.

    `hyper` None: the hyperparameters maximize the marginal likelihood (scipy's L-BFGS-B
    on ``log c``, ``logit lam`` and ``artanh rho`` per input, from several decay rates,
    the best kept); else the given values (each an array, one per input) are used as
    they are.
    """
    ev = Evidence(Phi, Y, sigma2)
    if hyper is None:
        hyper = _maximize(ev, Phi, Y, kind, nu, n)
    P = prior_covariance(kind, n, hyper)
    mean, cov = ev.posterior(P)
    return mean, cov, hyper, float(ev.log_likelihood(P))


def _maximize(ev, Phi, Y, kind, nu, n):
    """The hyperparameters that maximize ``ev.log_likelihood`` (see `fit_kernel`)."""
    from scipy.optimize import minimize

    names = KERNEL_PARAMS[kind]
    k = len(names)
    # the scale of c (units of g^2): the prior variance whose predicted output power
    # trace(Phi P Phi') = c * |Phi|_F^2 / n (lam near 1) matches the data's |Y|^2; the
    # least-squares coefficients are no guide (on a poorly exciting input they blow up)
    Y2 = max(float(Y @ Y), np.finfo(float).tiny)
    col2 = np.sum(Phi ** 2, axis=0).reshape(nu, n).sum(axis=1)
    c_scale = n * Y2 / np.maximum(col2, np.finfo(float).tiny)

    def unpack(x):
        x = x.reshape(nu, k)
        hyper = {"c": c_scale * np.exp(np.clip(x[:, 0], -40.0, 20.0)),    # c = scale e^x
                 "lam": 1.0 / (1.0 + np.exp(-np.clip(x[:, 1], -40.0, 40.0)))}  # logistic
        if kind == "dc":
            hyper["rho"] = np.tanh(np.clip(x[:, 2], -20.0, 20.0))          # |rho| < 1
        return hyper

    def cost(x):
        try:
            return -ev.log_likelihood(prior_covariance(kind, n, unpack(x)))
        except (np.linalg.LinAlgError, ValueError):    # not positive definite, or overflow
            return np.inf

    best = None
    for lam in _LAMBDA_STARTS:
        x0 = np.tile([np.log(1.0 / lam), np.log(lam / (1.0 - lam))] + [0.5] * (k - 2), nu)
        res = minimize(cost, x0, method="L-BFGS-B")
        if np.isfinite(res.fun) and (best is None or res.fun < best.fun):
            best = res
    if best is None:
        raise np.linalg.LinAlgError("the marginal likelihood of the regularized FIR "
                                    "estimate could not be evaluated at any start")
    return unpack(best.x)
