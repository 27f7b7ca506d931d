"""Compiled (numba) kernels of the RLS recursion.

The pure-NumPy reference of the same recursion is ``_batch_reference`` in
:mod:`rlsfilt.filters.rls`; the tests hold the two equal to 1e-12. Every
function here is ``njit(cache=True)``: the machine code is written to the
``__pycache__`` next to this file (or to ``NUMBA_CACHE_DIR``) on the first
call and loaded from there by later processes, so only the very first run
after an install pays the compilation.

Arithmetic of one step (the same helpers serve the batch kernel and the
streaming :meth:`RecursiveLeastSquares.update`, so the two agree bit for
bit)::

    P <- P * (1/lam) + Q                     predict, elementwise
    g = P phi                                column sweep; P is symmetric
    s = phi . g + r                          innovation variance
    c = 1 / s                                the only division of the step
    K = g c                                  gain
    y = z - phi . x                          a-priori residual, per output
    x <- x + K y^T
    P <- P - (g g^T) c                       g_i g_j = g_j g_i exactly, so
                                             P stays exactly symmetric

The cost per step is about ``3 dim_x^2`` multiply-adds (one sweep over ``P``
for the predict and gain, one for the rank-one update) plus
``2 dim_x dim_z`` for the residual and estimate. Both sweeps run along rows
of the C-contiguous ``P`` with no reduction in the inner loop, so LLVM
vectorizes them without any reassociation (no ``fastmath``): the results do
not depend on the vector width.

``mode`` selects the covariance update (only ``MODE_EXPONENTIAL`` so far:
exponential forgetting plus an optional random walk ``Q``); ``params`` is a
small float array reserved for the parameters of further modes.
"""

import numpy as np
from numba import njit

__all__ = []

MODE_EXPONENTIAL = 0


@njit(cache=True)
def _predict_inplace(P, il, Q, q_zero):
    """``P <- P * il + Q`` in place (``Q`` ignored when `q_zero`)."""
    n = P.shape[0]
    if q_zero:
        for j in range(n):
            for i in range(n):
                P[j, i] = P[j, i] * il
    else:
        for j in range(n):
            for i in range(n):
                P[j, i] = P[j, i] * il + Q[j, i]


@njit(cache=True)
def _predict_gain_inplace(P, il, Q, q_zero, predict, phi, g):
    """Optional predict fused with ``g = P phi``; returns nothing.

    ``g`` is accumulated row by row (``g += P[j, :] phi_j``), which for a
    symmetric ``P`` is ``P phi`` summed in the natural order, with a
    contiguous, reduction-free inner loop.
    """
    n = P.shape[0]
    for i in range(n):
        g[i] = 0.0
    if not predict:
        for j in range(n):
            pj = phi[j]
            for i in range(n):
                g[i] += P[j, i] * pj
    elif q_zero:
        for j in range(n):
            pj = phi[j]
            for i in range(n):
                v = P[j, i] * il
                P[j, i] = v
                g[i] += v * pj
    else:
        for j in range(n):
            pj = phi[j]
            for i in range(n):
                v = P[j, i] * il + Q[j, i]
                P[j, i] = v
                g[i] += v * pj


@njit(cache=True)
def _innovation_variance(phi, g, r):
    """``s = phi . g + r``."""
    s = 0.0
    for i in range(phi.shape[0]):
        s += phi[i] * g[i]
    return s + r


@njit(cache=True)
def _residual(x, phi, z, y):
    """``y = z - phi . x`` for each output column; ``y`` has ``dim_z`` entries."""
    n, m = x.shape
    for c in range(m):
        acc = 0.0
        for i in range(n):
            acc += phi[i] * x[i, c]
        y[c] = z[c] - acc


@njit(cache=True)
def _measurement_update(x, P, g, c, y, K, xn, Pn):
    """``K = g c``, ``xn = x + K y^T``, ``Pn = P - (g g^T) c``.

    ``xn``/``Pn`` may be ``x``/``P`` themselves (in-place update).
    """
    n, m = x.shape
    for i in range(n):
        K[i] = g[i] * c
    for i in range(n):
        ki = K[i]
        for j in range(m):
            xn[i, j] = x[i, j] + ki * y[j]
    for i in range(n):
        gi = g[i]
        for j in range(n):
            Pn[i, j] = P[i, j] - (gi * g[j]) * c


@njit(cache=True)
def _any_nan(z):
    for v in z:
        if v != v:
            return True
    return False


@njit(cache=True)
def batch_filter_kernel(x, P, Z, Hm, Rv, il, Q, q_zero, update_first, mode, params,
                        means, means_p, covs, covs_p, ys, ss,
                        x_prior, P_prior, x_post, P_post, K):
    """Run the recursion over a record, in place on the working ``x``, ``P``.

    Parameters
    ----------
    x : (n, m) float64, P : (n, n) float64
        Working state (overwritten with the final state).
    Z : (N, m), Hm : (N, n), Rv : (N,)
        Measurements (NaN rows missing), regressors, noise variances.
    il : float
        ``1 / lam``.
    Q : (n, n), q_zero : bool
        Random walk and whether it is identically zero.
    update_first : bool
        Update before predict in each step.
    mode : int, params : (p,) float64
        Covariance-update mode (``MODE_EXPONENTIAL``) and its parameters.
    means, means_p : (N, n, m)
        Estimate histories (written).
    covs, covs_p : (N, n, n) or (0, n, n)
        Covariance histories; not written when their length is 0.
    ys : (N, m), ss : (N,)
        Residuals (NaN when missing) and innovation variances (written).
    x_prior, P_prior, x_post, P_post : arrays shaped as x and P
        The last step's prior and posterior (written when ``N > 0``).
    K : (n,)
        Gain of the last non-missing update (kept when none).

    Returns
    -------
    s : float
        Innovation variance of the last step (NaN when ``N == 0``).
    """
    N = Z.shape[0]
    n, m = x.shape
    store = covs.shape[0] == N and N > 0
    plain = il == 1.0 and q_zero       # predict is the identity
    g = np.empty(n)
    y = np.empty(m)
    s = np.nan
    for k in range(N):
        phi = Hm[k]
        if not update_first:
            _predict_gain_inplace(P, il, Q, q_zero, not plain, phi, g)
            means_p[k] = x
            if store:
                covs_p[k] = P
            if k == N - 1:
                x_prior[:] = x
                P_prior[:] = P
        else:
            _predict_gain_inplace(P, il, Q, q_zero, False, phi, g)
        s = _innovation_variance(phi, g, Rv[k])
        ss[k] = s
        z = Z[k]
        if _any_nan(z):
            for j in range(m):
                ys[k, j] = np.nan
        else:
            _residual(x, phi, z, y)
            _measurement_update(x, P, g, 1.0 / s, y, K, x, P)
            ys[k] = y
        means[k] = x
        if store:
            covs[k] = P
        if k == N - 1:
            x_post[:] = x
            P_post[:] = P
        if update_first:
            if not plain:
                _predict_inplace(P, il, Q, q_zero)
            means_p[k] = x
            if store:
                covs_p[k] = P
            if k == N - 1:
                x_prior[:] = x
                P_prior[:] = P
    return s


@njit(cache=True)
def update_kernel(x, P, phi, z, r, missing, xn, Pn, y, K, S, SI, Hc, x_post, P_post):
    """One measurement update for the streaming :meth:`update`.

    Reads ``x`` (n, m), ``P`` (n, n), the regressor ``phi`` (n,) and the
    measurement ``z`` (m, 1) and writes the new estimate ``xn`` and
    covariance ``Pn`` with their copies ``x_post``, ``P_post``, the residual
    ``y`` (m, 1), the gain ``K`` (n, 1), ``S = s I`` and ``SI = I / s``
    (m, m), and a copy ``Hc`` (1, n) of ``phi``. When `missing` is true
    ``y``, ``K`` are not written and ``xn``, ``Pn`` are copies of ``x``,
    ``P``. ``phi`` is first tested for finiteness.

    Returns
    -------
    s : float
        Innovation variance, or NaN when ``phi`` holds NaN or inf (nothing
        is written then).
    """
    n, m = x.shape
    for i in range(n):
        v = phi[i]
        if v - v != 0.0:          # NaN or inf
            return np.nan
    for i in range(n):
        Hc[0, i] = phi[i]
    g = np.empty(n)
    _predict_gain_inplace(P, 1.0, P, True, False, phi, g)
    s = _innovation_variance(phi, g, r)
    c = 1.0 / s
    for i in range(m):
        for j in range(m):
            S[i, j] = 0.0
            SI[i, j] = 0.0
        S[i, i] = s
        SI[i, i] = c
    if missing:
        xn[:] = x
        Pn[:] = P
    else:
        yv = np.empty(m)
        Kv = np.empty(n)
        _residual(x, phi, z[:, 0], yv)
        _measurement_update(x, P, g, c, yv, Kv, xn, Pn)
        for j in range(m):
            y[j, 0] = yv[j]
        for i in range(n):
            K[i, 0] = Kv[i]
    x_post[:] = xn
    P_post[:] = Pn
    return s


def batch_compiled(x, P, Z, Hm, Rv, lam, Q, update_first, store_covariances,
                   mode=MODE_EXPONENTIAL, params=None):
    """Compiled counterpart of ``rls._batch_reference`` (same arguments, same result).

    `x`, `P` are not modified. Returns a ``rls._BatchResult``.
    """
    from .rls import _BatchResult

    N = len(Z)
    n, m = x.shape
    out = _BatchResult()
    out.means = np.empty((N, n, m))
    out.means_p = np.empty((N, n, m))
    if store_covariances:
        covs, covs_p = np.empty((N, n, n)), np.empty((N, n, n))
        out.covariances, out.covariances_p = covs, covs_p
    else:
        covs = covs_p = np.empty((0, n, n))
        out.covariances = out.covariances_p = None
    out.ys = np.empty((N, m))
    out.ss = np.empty(N)
    xw = np.array(x, dtype=np.float64, order="C")
    Pw = np.array(P, dtype=np.float64, order="C")
    q_zero = Q is None
    Qa = np.zeros((0, 0)) if q_zero else np.ascontiguousarray(Q, dtype=np.float64)
    params = np.zeros(0) if params is None else np.ascontiguousarray(params, dtype=np.float64)
    x_prior, P_prior = np.empty((n, m)), np.empty((n, n))
    x_post, P_post = np.empty((n, m)), np.empty((n, n))
    K = np.zeros(n)
    s = batch_filter_kernel(
        xw, Pw, np.ascontiguousarray(Z, dtype=np.float64),
        np.ascontiguousarray(Hm, dtype=np.float64), np.ascontiguousarray(Rv, dtype=np.float64),
        1.0 / lam, Qa, q_zero, bool(update_first), int(mode), params,
        out.means, out.means_p, covs, covs_p, out.ys, out.ss,
        x_prior, P_prior, x_post, P_post, K)
    out.x, out.P = xw, Pw
    if N:
        out.x_prior, out.P_prior = x_prior, P_prior
        out.x_post, out.P_post = x_post, P_post
        out.y_last, out.K_last, out.s_last = out.ys[-1].copy(), K.reshape(n, 1), s
    return out
