r"""Long autoregressions: the nonparametric noise models behind the start and the IV covariance.

Two estimators that approximate a coloured disturbance by a long AR model:

* `levinson_ar`: Yule-Walker AR fits of every order ``0 .. p_max`` by the
  Levinson-Durbin recursion (stable by construction), the order chosen by
  Akaike's criterion. It supplies the noise model of the instrumental-variable
  covariance.
* `long_arx_residuals`: the first stage of the Hannan-Rissanen procedure, a
  long ARX fitted by least squares whose residuals estimate the innovations
  :math:`e(t)`; regressing on them makes ARMAX/ARMA starts consistent.

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
   Prentice Hall, 1999, ch. 10 (multistep methods).
.. [2] E. J. Hannan and J. Rissanen, "Recursive estimation of mixed
   autoregressive-moving average order", *Biometrika* 69(1), 81-94, 1982.
.. [3] P. J. Brockwell and R. A. Davis, *Introduction to Time Series and
   Forecasting*, 2nd ed., Springer, 2002, sec. 5.1 (Durbin-Levinson).
"""

import numpy as np

__all__ = []


def autocovariance(x, max_lag):
    r"""Biased sample autocovariances :math:`r_k = \frac1N \sum_t x_t x_{t+k}`, ``k = 0..max_lag``.

    The biased estimate makes the Toeplitz matrix positive semidefinite, so
    the Yule-Walker AR model is stable. Computed through the FFT.
    """
    x = np.asarray(x, dtype=float)
    N = len(x)
    n_fft = 1 << int(np.ceil(np.log2(2 * N - 1))) if N > 1 else 2
    X = np.fft.rfft(x, n_fft)
    r = np.fft.irfft(X * np.conj(X), n_fft)[:max_lag + 1] / N
    out = np.zeros(max_lag + 1)
    out[:len(r)] = r
    return out


def levinson_ar(x, p_max, criterion="aic"):
    r"""Yule-Walker AR model of `x` of the order (``<= p_max``) that minimizes AIC.

    The Durbin-Levinson recursion gives every order at once: with
    :math:`\sigma^2_0 = r_0`,

    .. math::

        k_p = \frac{r_p + \sum_{j=1}^{p-1} a_{p-1,j}\, r_{p-j}}{\sigma^2_{p-1}},\quad
        a_{p,p} = -k_p,\quad a_{p,j} = a_{p-1,j} - k_p\, a_{p-1,p-j},\quad
        \sigma^2_p = \sigma^2_{p-1}(1 - k_p^2),

    for the model :math:`x(t) + a_1 x(t-1) + \dots + a_p x(t-p) = e(t)`,
    and :math:`\mathrm{AIC}(p) = N \log\sigma^2_p + 2p`.

    Returns
    -------
    a : ndarray
        ``[1, a_1, .., a_p]``.
    sigma2 : float
        Innovation variance of the chosen order.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.models._long_ar import levinson_ar
    >>> x = lfilter([1.0], [1.0, -0.8], np.random.default_rng(0).standard_normal(20000))
    >>> a, s2 = levinson_ar(x, 10)
    >>> np.round(a[:2], 2), round(s2, 1)
    (array([ 1.  , -0.8]), 1.0)
    """
    x = np.asarray(x, dtype=float)
    N = len(x)
    p_max = int(max(0, min(p_max, N - 1)))
    r = autocovariance(x, p_max)
    a = np.ones(1)
    s2 = r[0]
    best = (N * np.log(s2) if s2 > 0 else -np.inf, a, s2)
    for p in range(1, p_max + 1):
        if not s2 > 0:
            break
        k = (r[p] + np.dot(a[1:], r[p - 1:0:-1])) / s2
        a_new = np.concatenate([a, [0.0]])
        a_new[1:] -= k * a[::-1]
        a, s2 = a_new, s2 * (1.0 - k * k)
        score = N * np.log(s2) + (2 * p if criterion == "aic" else p * np.log(N)) \
            if s2 > 0 else -np.inf
        if score < best[0]:
            best = (score, a, s2)
    return best[1], float(best[2])


def long_arx_residuals(U, y, order, nk=None):
    r"""Residuals of a long ARX model: estimates of the innovations ``e(t)``.

    Fits :math:`y(t) + \sum_{k=1}^{L} \alpha_k y(t-k) = \sum_i \sum_{k=0}^{L-1}
    \beta_{i,k} u_i(t - n_{k,i} - k) + e(t)` by least squares on the rows
    ``t >= L + max(nk)`` and returns its residuals, zero on the earlier rows.
    For a time series (``U`` with no columns) it is a long AR.

    Parameters
    ----------
    U : ndarray, shape (N, nu)
    y : ndarray, shape (N,)
    order : int
        ``L``.
    nk : sequence of int, optional
        Input delays (default 0 for every input).
    """
    N, nu = U.shape
    nk = (0,) * nu if nk is None else tuple(nk)
    t0 = order + (max(nk) if nu else 0)
    cols = [-y[t0 - k:N - k] for k in range(1, order + 1)]
    for i in range(nu):
        cols += [U[t0 - nk[i] - k:N - nk[i] - k, i] for k in range(order)]
    if not cols:                      # order 0 and no inputs: y itself is the residual
        return np.array(y, dtype=float)
    e = np.zeros(N)
    if N - t0 <= len(cols):           # too short to fit: no estimate of e
        return e
    Phi = np.column_stack(cols)
    theta = np.linalg.lstsq(Phi, y[t0:], rcond=None)[0]
    e[t0:] = y[t0:] - Phi @ theta
    return e
