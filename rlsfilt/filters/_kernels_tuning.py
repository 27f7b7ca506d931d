"""Compiled profile-likelihood terms of the Kalman recursion of the parameters, with their
first and second derivatives (for `tuning`).

One pass of `RecursiveLeastSquares`' exponential-forgetting recursion with
``R = 1`` that keeps no history, only the two sums of the prediction-error
decomposition and, by the sensitivity recursions of the filter (the
derivatives of ``x``, ``P``, ``y`` and ``s`` with respect to the
hyperparameters, carried along the pass), their gradients and Hessians: the
Newton search of :mod:`rlsfilt.filters.tuning` calls it a handful of times per
record. ``tests/test_tuning.py`` holds the sums equal to those of
``batch_filter``'s innovations and the derivatives equal to finite
differences.

`profile_derivs` is the general pass (any number of hyperparameters, any
time update ``P^- = A * P + Q``); the searches run leaner passes of their own,
held equal to it: `scalar_pass` for one variable (``q`` or ``lam``, the whole
search `scalar_search` one compiled call) and `diag_pass` for a diagonal
random walk (``q_diag``, `diag_search`), both on the upper triangle of ``P``
with the order of the derivatives and the size as compile-time constants.
"""

import math

import numpy as np

from .._numba import njit

__all__ = []


@njit(cache=True)
def profile_derivs(x0, P0, Z, H, A, Q, dA, dQ, d2A, d2Q, burn, order):
    """``(slog, sq, count, dslog, dsq, d2slog, d2sq)`` over the record.

    ``slog = sum log s_t`` and ``sq = sum y_t^T y_t / s_t`` over the counted
    steps, `count` the outputs counted; ``dslog``, ``dsq`` (k,) their first
    derivatives and ``d2slog``, ``d2sq`` (k, k) their second derivatives with
    respect to the k hyperparameters (computed when ``order >= 1`` and
    ``order >= 2``; zeros otherwise).

    `x0` (n, m) and `P0` (n, n) start the run (not modified); `Z` (N, m) with
    NaN for missing samples; `H` (N, n); the time update is the elementwise
    ``P^- = A * P + Q`` (``A = 1 / lam`` everywhere for exponential
    forgetting; ``A_ij = 1 / sqrt(lam_i lam_j)`` for a diagonal one), with `dA`,
    `dQ` (k, n, n) and `d2A`, `d2Q` (k, k, n, n) the derivatives of `A` and
    `Q` (upper triangle ``a <= b`` read). Steps before `burn` update the state
    but are not counted. Each step, and its derivative by the product rule
    (``d`` one hyperparameter, ``d2`` two):

        P^- = A * P + Q                        time update
        g = P^- h,  s = h^T g + 1,  y = z - x^T h
        e = y / s
        x = x + g e^T
        P = P^- - g g^T / s                    (kept exactly symmetric)
    """
    n, m = x0.shape
    k = dA.shape[0]
    x = x0.copy()
    P = P0.copy()
    dx = np.zeros((k, n, m))
    dP = np.zeros((k, n, n))
    d2x = np.zeros((k, k, n, m))
    d2P = np.zeros((k, k, n, n))
    g = np.empty(n)
    y = np.empty(m)
    e = np.empty(m)
    dg = np.zeros((k, n))
    ds = np.zeros(k)
    dy = np.zeros((k, m))
    de = np.zeros((k, m))
    dr = np.zeros(k)
    d2g = np.zeros((k, k, n))
    d2s = np.zeros((k, k))
    d2y = np.zeros((k, k, m))
    d2e = np.zeros((k, k, m))
    slog = 0.0
    sq = 0.0
    dslog = np.zeros(k)
    dsq = np.zeros(k)
    d2slog = np.zeros((k, k))
    d2sq = np.zeros((k, k))
    count = 0
    for t in range(Z.shape[0]):
        # time update, second derivatives first (they read the old P and dP):
        # d2P^- = d2A P + dA_a dP_b + dA_b dP_a + A d2P + d2Q;  dP^- = dA P + A dP + dQ
        if order >= 2:
            for a in range(k):
                for b in range(a, k):
                    for i in range(n):
                        for j in range(i, n):
                            v = (d2A[a, b, i, j] * P[i, j] + dA[a, i, j] * dP[b, i, j]
                                 + dA[b, i, j] * dP[a, i, j] + A[i, j] * d2P[a, b, i, j]
                                 + d2Q[a, b, i, j])
                            d2P[a, b, i, j] = v
                            d2P[a, b, j, i] = v
        if order >= 1:
            for a in range(k):
                for i in range(n):
                    for j in range(i, n):
                        v = dA[a, i, j] * P[i, j] + A[i, j] * dP[a, i, j] + dQ[a, i, j]
                        dP[a, i, j] = v
                        dP[a, j, i] = v
        for i in range(n):
            for j in range(i, n):
                v = A[i, j] * P[i, j] + Q[i, j]
                P[i, j] = v
                P[j, i] = v
        # g = P^- h, s = h^T g + 1 (and their derivatives)
        s = 1.0
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += P[i, j] * H[t, j]
            g[i] = acc
            s += H[t, i] * acc
        missing = False
        for c in range(m):
            acc = Z[t, c]
            for i in range(n):
                acc -= H[t, i] * x[i, c]
            y[c] = acc
            e[c] = acc / s
            if acc != acc:
                missing = True
        if missing:                       # posterior = prior (derivatives too)
            continue
        r = 1.0 / s
        if order >= 1:
            for a in range(k):
                acc_s = 0.0
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += dP[a, i, j] * H[t, j]
                    dg[a, i] = acc
                    acc_s += H[t, i] * acc
                ds[a] = acc_s
                dr[a] = -acc_s * r * r                      # d(1/s)
                for c in range(m):
                    acc = 0.0
                    for i in range(n):
                        acc -= H[t, i] * dx[a, i, c]
                    dy[a, c] = acc
                    de[a, c] = acc * r - y[c] * acc_s * r * r
        if order >= 2:
            for a in range(k):
                for b in range(a, k):
                    acc_s = 0.0
                    for i in range(n):
                        acc = 0.0
                        for j in range(n):
                            acc += d2P[a, b, i, j] * H[t, j]
                        d2g[a, b, i] = acc
                        acc_s += H[t, i] * acc
                    d2s[a, b] = acc_s
                    for c in range(m):
                        acc = 0.0
                        for i in range(n):
                            acc -= H[t, i] * d2x[a, b, i, c]
                        d2y[a, b, c] = acc
                        # d2(y/s) = d2y/s - (dy_a ds_b + dy_b ds_a)/s^2 - y d2s/s^2
                        #           + 2 y ds_a ds_b / s^3
                        d2e[a, b, c] = (acc * r - (dy[a, c] * ds[b] + dy[b, c] * ds[a]) * r * r
                                        - y[c] * acc_s * r * r
                                        + 2.0 * y[c] * ds[a] * ds[b] * r * r * r)
        if t >= burn:
            # the sums and their derivatives
            slog += math.log(s)
            for c in range(m):
                sq += y[c] * y[c] * r
            count += m
            if order >= 1:
                for a in range(k):
                    dslog[a] += ds[a] * r
                    for c in range(m):
                        dsq[a] += 2.0 * y[c] * dy[a, c] * r - y[c] * y[c] * ds[a] * r * r
            if order >= 2:
                for a in range(k):
                    for b in range(a, k):
                        d2slog[a, b] += d2s[a, b] * r - ds[a] * ds[b] * r * r
                        for c in range(m):
                            yc = y[c]
                            d2sq[a, b] += (2.0 * dy[a, c] * dy[b, c] * r
                                           + 2.0 * yc * d2y[a, b, c] * r
                                           - 2.0 * yc * (dy[a, c] * ds[b] + dy[b, c] * ds[a])
                                           * r * r
                                           - yc * yc * d2s[a, b] * r * r
                                           + 2.0 * yc * yc * ds[a] * ds[b] * r * r * r)
        # measurement update of the derivatives (they read g, dg, e, de of the prior)
        if order >= 2:
            for a in range(k):
                for b in range(a, k):
                    # d2r = -d2s / s^2 + 2 ds_a ds_b / s^3
                    d2r = -d2s[a, b] * r * r + 2.0 * ds[a] * ds[b] * r * r * r
                    for i in range(n):
                        for c in range(m):
                            d2x[a, b, i, c] += (d2g[a, b, i] * e[c] + dg[a, i] * de[b, c]
                                                + dg[b, i] * de[a, c] + g[i] * d2e[a, b, c])
                    for i in range(n):
                        for j in range(i, n):
                            v = d2P[a, b, i, j] - (
                                (d2g[a, b, i] * g[j] + dg[a, i] * dg[b, j] + dg[b, i] * dg[a, j]
                                 + g[i] * d2g[a, b, j]) * r
                                + (dg[a, i] * g[j] + g[i] * dg[a, j]) * dr[b]
                                + (dg[b, i] * g[j] + g[i] * dg[b, j]) * dr[a]
                                + g[i] * g[j] * d2r)
                            d2P[a, b, i, j] = v
                            d2P[a, b, j, i] = v
        if order >= 1:
            for a in range(k):
                for i in range(n):
                    for c in range(m):
                        dx[a, i, c] += dg[a, i] * e[c] + g[i] * de[a, c]
                for i in range(n):
                    for j in range(i, n):
                        v = dP[a, i, j] - ((dg[a, i] * g[j] + g[i] * dg[a, j]) * r
                                           + g[i] * g[j] * dr[a])
                        dP[a, i, j] = v
                        dP[a, j, i] = v
        for i in range(n):
            for c in range(m):
                x[i, c] += g[i] * e[c]
        for i in range(n):
            for j in range(i, n):
                v = P[i, j] - g[i] * g[j] * r
                P[i, j] = v
                P[j, i] = v
    for a in range(k):
        for b in range(a + 1, k):
            d2slog[b, a] = d2slog[a, b]
            d2sq[b, a] = d2sq[a, b]
    return slog, sq, count, dslog, dsq, d2slog, d2sq


# ----------------------------------------------------------------------
# one hyperparameter ("q" or "lam"): a leaner pass and the whole search compiled
# ----------------------------------------------------------------------
_LOG_2PI = math.log(2.0 * math.pi)


@njit(cache=True)
def _add_log(slog, prod, s):
    """``(slog, prod)`` after adding ``log s`` to ``slog + log prod``: ``sum log s`` kept as
    the log of running products (one ``log`` per hundred steps or so)."""
    if s < 1e100:
        prod *= s
        if prod > 1e150:
            slog += math.log(prod)
            prod = 1.0
    else:
        slog += math.log(s)
    return slog, prod


@njit(cache=True)
def scalar_model(kind, v, lam0):
    """``(a, da, d2a, c, dc, d2c)`` of the time update ``P^- = a P + c Qb`` at the search
    variable `v` and their derivatives in `v`: ``kind`` 0 is ``q`` (``Q = exp(v) I``:
    ``c = dc = d2c = exp(v)``, ``a = 1 / lam0``), 1 is ``lam`` (``lam = 1 - exp(v)``,
    ``a = 1 / lam``: ``da = (1 - lam) / lam^2``, ``d2a = (1 - lam)(2 - lam) / lam^3``;
    ``c = 1``)."""
    if kind == 0:
        c = math.exp(v)
        return 1.0 / lam0, 0.0, 0.0, c, c, c
    d = math.exp(v)                      # 1 - lam
    lam = 1.0 - d
    return 1.0 / lam, d / (lam * lam), d * (2.0 - lam) / lam ** 3, 1.0, 0.0, 0.0


@njit(cache=True)
def scalar_work(n, m):
    """The state of a scalar pass: ``(x, dx, d2x, P, dP, d2P, g, dg, d2g, y, dy, d2y)``."""
    return (np.empty((n, m)), np.empty((n, m)), np.empty((n, m)),
            np.empty((n, n)), np.empty((n, n)), np.empty((n, n)),
            np.empty(n), np.empty(n), np.empty(n), np.empty(m), np.empty(m), np.empty(m))


@njit(cache=True)
def scalar_pass(x0, P0, Z, H, Qb, a, da, d2a, c, dc, d2c, burn, orders, dims, work):
    """``(slog, sq, count, dslog, dsq, d2slog, d2sq)`` of `profile_derivs` for one
    hyperparameter (scalars), the time update ``P^- = a P + c Qb`` (`scalar_model`).

    The same recursion with ``k = 1``, its loops fused: each step's measurement
    update and the next time update are one sweep of ``P`` and its derivatives
    (``P^-_{t+1} = a (P^-_t - g g^T / s) + c Qb``; `Qb` symmetric), over the upper
    triangle only (``P``, ``dP``, ``d2P`` are read as symmetric: entry ``(i, j)`` from
    ``(min, max)``; the lower triangle of the work arrays is not kept); `work`
    (`scalar_work`) holds the state, so a pass allocates nothing; ``sum log s`` is the
    log of running products of ``s`` (one ``log`` per hundred steps or so instead of
    one per step: about 10 % of a pass), flushed before they can overflow.
    ``tests/test_tuning.py`` holds it equal to `profile_derivs`.

    `orders` is a tuple of ``order`` zeros (the derivatives wanted: 0, 1 or 2) and
    `dims` a tuple of ``n`` zeros or an array of length ``n`` (`tuning._dims`): the
    length of a tuple is part of its type, so numba compiles one pass per order (the
    branches of the others pruned) and, for a tuple `dims`, per ``n`` (its loops
    unrolled: at ``n = 3`` the order-1 pass runs in 0.65x the time of one loop for
    every ``n`` and every order). ``Qb = None`` is the identity with a constant ``a``
    (``da = d2a = 0``: the random walk ``Q = c I`` of ``q``), a pass of its own without
    the products by 0 and 1 (the same numbers: about 0.87x the time at order 1).
    """
    x, dx, d2x, P, dP, d2P, g, dg, d2g, y, dy, d2y = work
    m = x0.shape[1]
    n = len(dims)                         # a constant when dims is a tuple
    d1 = len(orders) >= 1                 # constants: the branches are pruned
    d2 = len(orders) >= 2
    for i in range(n):
        for c_ in range(m):
            x[i, c_] = x0[i, c_]
            dx[i, c_] = 0.0
            d2x[i, c_] = 0.0
        for j in range(i, n):             # the first prior (P0 has no derivative; its
            p0 = P0[i, j]                 # upper triangle read, as Qb's)
            qb = (1.0 if i == j else 0.0) if Qb is None else Qb[i, j]
            P[i, j] = a * p0 + c * qb
            dP[i, j] = da * p0 + dc * qb
            d2P[i, j] = d2a * p0 + d2c * qb
    slog = sq = dslog = dsq = d2slog = d2sq = 0.0
    prod = 1.0                            # running product of s >= 1
    count = 0
    for t in range(Z.shape[0]):
        # g = P^- h, s = h^T g + 1, y = z - x^T h (and their derivatives)
        s = 1.0
        ds = 0.0
        d2s = 0.0
        for i in range(n):
            acc = 0.0
            acc1 = 0.0
            acc2 = 0.0
            for j in range(n):
                hj = H[t, j]
                lo, hi = min(i, j), max(i, j)
                acc += P[lo, hi] * hj
                if d1:
                    acc1 += dP[lo, hi] * hj
                if d2:
                    acc2 += d2P[lo, hi] * hj
            hi = H[t, i]
            g[i] = acc
            s += hi * acc
            dg[i] = acc1
            ds += hi * acc1
            d2g[i] = acc2
            d2s += hi * acc2
        missing = False
        for c_ in range(m):
            acc = Z[t, c_]
            acc1 = 0.0
            acc2 = 0.0
            for i in range(n):
                hi = H[t, i]
                acc -= hi * x[i, c_]
                if d1:
                    acc1 -= hi * dx[i, c_]
                if d2:
                    acc2 -= hi * d2x[i, c_]
            y[c_] = acc
            dy[c_] = acc1
            d2y[c_] = acc2
            if acc != acc:
                missing = True
        if missing:                       # posterior = prior: P^-_{t+1} = a P^-_t + c Qb
            for i in range(n):
                for j in range(i, n):
                    pp, dpp = P[i, j], dP[i, j]
                    qb = (1.0 if i == j else 0.0) if Qb is None else Qb[i, j]
                    if d2:
                        d2P[i, j] = d2a * pp + 2.0 * da * dpp + a * d2P[i, j] + d2c * qb
                    if d1:
                        dP[i, j] = da * pp + a * dpp + dc * qb
                    P[i, j] = a * pp + c * qb
            continue
        r = 1.0 / s
        r2 = r * r
        dr = -ds * r2                                   # d(1/s)
        d2r = -d2s * r2 + 2.0 * ds * ds * r2 * r
        if t >= burn:
            slog, prod = _add_log(slog, prod, s)
            count += m
            dslog += ds * r
            d2slog += d2s * r - ds * ds * r2
            for c_ in range(m):
                yc, dyc, d2yc = y[c_], dy[c_], d2y[c_]
                sq += yc * yc * r
                dsq += 2.0 * yc * dyc * r - yc * yc * ds * r2
                d2sq += (2.0 * dyc * dyc * r + 2.0 * yc * d2yc * r
                         - 4.0 * yc * dyc * ds * r2 - yc * yc * d2s * r2
                         + 2.0 * yc * yc * ds * ds * r2 * r)
        # x = x + g e^T, e = y / s (and derivatives)
        for c_ in range(m):
            yc, dyc, d2yc = y[c_], dy[c_], d2y[c_]
            e = yc * r
            de = dyc * r - yc * ds * r2
            d2e = (d2yc * r - 2.0 * dyc * ds * r2 - yc * d2s * r2
                   + 2.0 * yc * ds * ds * r2 * r)
            for i in range(n):
                gi = g[i]
                x[i, c_] += gi * e
                if d1:
                    dx[i, c_] += dg[i] * e + gi * de
                if d2:
                    d2x[i, c_] += d2g[i] * e + 2.0 * dg[i] * de + gi * d2e
        # P = P^- - g g^T / s, then the next prior a P + c Qb (and derivatives), on the
        # upper triangle
        for i in range(n):
            gi, dgi, d2gi = g[i], dg[i], d2g[i]
            for j in range(i, n):
                gj, dgj = g[j], dg[j]
                gg = gi * gj
                pp = P[i, j] - gg * r
                if Qb is None:            # Q = c I, a constant a (da = d2a = 0): the same
                    dq = i == j           # numbers without the products by 0 and 1
                    P[i, j] = a * pp + c if dq else a * pp
                    if d1:
                        dgg = dgi * gj + gi * dgj
                        dpp = dP[i, j] - (dgg * r + gg * dr)
                        dP[i, j] = a * dpp + dc if dq else a * dpp
                        if d2:
                            d2pp = d2P[i, j] - (((d2gi * gj + gi * d2g[j]) + 2.0 * dgi * dgj)
                                                * r + 2.0 * dgg * dr + gg * d2r)
                            d2P[i, j] = a * d2pp + d2c if dq else a * d2pp
                    continue
                P[i, j] = a * pp + c * Qb[i, j]
                if d1:
                    dgg = dgi * gj + gi * dgj
                    dpp = dP[i, j] - (dgg * r + gg * dr)
                    dP[i, j] = da * pp + a * dpp + dc * Qb[i, j]
                    if d2:
                        d2pp = d2P[i, j] - (((d2gi * gj + gi * d2g[j]) + 2.0 * dgi * dgj) * r
                                            + 2.0 * dgg * dr + gg * d2r)
                        d2P[i, j] = d2a * pp + 2.0 * da * dpp + a * d2pp + d2c * Qb[i, j]
    slog += math.log(prod)
    return slog, sq, count, dslog, dsq, d2slog, d2sq


@njit(cache=True, error_model="numpy")
def scalar_point(x0, P0, Z, H, Qb, kind, v, lam0, burn, orders, dims, work):
    r"""``(loglik, sigma2, n_obs, gradient, second derivative, dsigma2)`` of the profile
    log-likelihood in the search variable `v` (one `scalar_pass` of the order that
    `orders` witnesses; ``n_obs = 0`` when no innovation is counted):
    :math:`\ell_p = -\tfrac12 (N (\log 2\pi + \log(sq/N) + 1) + m\,slog)`,
    :math:`\ell_p' = -\tfrac12 (N\,sq' / sq + m\,slog')`,
    :math:`\ell_p'' = -\tfrac12 (N (sq''/sq - sq'^2 / sq^2) + m\,slog'')`,
    ``dsigma2 = sq' / N`` (the derivative of :math:`\sigma^2 = sq / N`)."""
    a, da, d2a, c, dc, d2c = scalar_model(kind, v, lam0)
    slog, sq, count, dslog, dsq, d2slog, d2sq = scalar_pass(
        x0, P0, Z, H, Qb, a, da, d2a, c, dc, d2c, burn, orders, dims, work)
    if count == 0:
        return math.nan, math.nan, 0, math.nan, math.nan, math.nan
    m = x0.shape[1]
    sigma2 = sq / count
    ll = -0.5 * (count * (_LOG_2PI + math.log(sigma2) + 1.0) + m * slog)
    grad = -0.5 * (count * dsq / sq + m * dslog)
    hess = -0.5 * (count * (d2sq / sq - dsq * dsq / (sq * sq)) + m * d2slog)
    return ll, sigma2, count, grad, hess, dsq / count


@njit(cache=True, error_model="numpy")
def scalar_profile(x0, P0, Z, H, Qb, kind, v, lam0, burn, order, work, dims):
    """`scalar_point` with the order as a number (0, 1 or 2)."""
    if order <= 0:
        return scalar_point(x0, P0, Z, H, Qb, kind, v, lam0, burn, (), dims, work)
    if order == 1:
        return scalar_point(x0, P0, Z, H, Qb, kind, v, lam0, burn, (0,), dims, work)
    return scalar_point(x0, P0, Z, H, Qb, kind, v, lam0, burn, (0, 0), dims, work)


#: The last step of the one-variable search is taken on the quadratic model, without a
#: pass, when it is at most `_LAST_STEP` long and its product with the step before at
#: most `_LAST_PRODUCT`: the secant iteration's error after a step is about
#: ``|f''' / 2 f''|`` times that product (about 0.02 x 1e-7 for the records of
#: benchmarks/bench_tune.py), and the log-likelihood, sigma^2 and the gradient there
#: are their Taylor expansions (errors of order ``step^2 |h - h_secant|``, below 1e-11).
_LAST_STEP = 3e-5
_LAST_PRODUCT = 1e-7


@njit(cache=True, error_model="numpy")
def scalar_search(x0, P0, Z, H, Qb, kind, lam0, burn, v0, lo, hi, max_step, maxiter, xtol,
                  screen, dims):
    """Maximize the profile log-likelihood of one variable `v` in ``[lo, hi]`` by a
    safeguarded Newton search: the exact second derivative at the start, then the slope
    of the quadratic interpolation of the exact first derivatives at the last three
    points (a secant with a curvature correction: about 13 % fewer passes than the
    secant alone over q and lam of slow to fast drifts; the secant where that slope is
    not negative, the exact second derivative where neither is);
    steps at most `max_step`, halved until the likelihood does not fall; an uphill
    step of that length where the curvature is not negative; stop when a step would
    be shorter than `xtol`, or take the last step on the quadratic model without a
    pass when it is short enough (`_LAST_STEP`, `_LAST_PRODUCT`), or when the start
    sits on a bound with the gradient pointing out. One compiled call: no Python
    between passes. `dims`: as for `scalar_pass`.

    With `screen`, the record is first screened as ``batch_filter`` validates it (every
    entry of `H` finite, no infinity in `Z`; NaN there marks a missing sample): a
    record that fails returns at once with ``n_obs = -1`` and no pass (the caller
    validates it again to name the bad entry), so that a record the caller has not
    validated costs no Python pass over it.

    Returns ``(v, loglik, sigma2, n_obs, gradient, second derivative, converged, held,
    n_passes)``; ``n_obs = 0`` when the record has no innovation to count.
    """
    n, m = x0.shape
    if screen:
        bad = 0.0                         # 0 * h is 0 for a finite h, NaN for inf or NaN
        for t in range(H.shape[0]):
            for j in range(H.shape[1]):
                bad += 0.0 * H[t, j]
        for t in range(Z.shape[0]):
            for c_ in range(Z.shape[1]):
                if abs(Z[t, c_]) == math.inf:
                    bad = math.nan
        if bad != 0.0:
            return v0, math.nan, math.nan, -1, math.nan, math.nan, False, False, 0
    work = scalar_work(n, m)
    v = min(max(v0, lo), hi)
    ll, sigma2, n_obs, g, h, ds2 = scalar_point(x0, P0, Z, H, Qb, kind, v, lam0, burn,
                                                (0, 0), dims, work)
    passes = 1
    converged = False
    held = False
    if n_obs == 0:
        return v, ll, sigma2, n_obs, g, h, converged, held, passes
    last = math.inf                       # the length of the last step taken
    v_prev, dd_prev = v, h                # the point before v, the divided difference
    for _ in range(maxiter):
        held = (v <= lo and g < 0.0) or (v >= hi and g > 0.0)
        if held:
            converged = True
            break
        step = -g / h if h < 0.0 else math.copysign(max_step, g)
        step = max(-max_step, min(max_step, step))
        v_new = min(max(v + step, lo), hi)
        if abs(v_new - v) <= xtol:
            converged = True
            break
        if (h < 0.0 and v_new == v + step and abs(step) <= _LAST_STEP
                and abs(step) * last <= _LAST_PRODUCT):
            # the last step on the quadratic model l + g d + h d^2 / 2 (d = -g / h)
            ll += 0.5 * g * step
            sigma2 += ds2 * step
            g += h * step
            v = v_new
            converged = True
            break
        tol = 1e-12 * (1.0 + abs(ll))                  # round-off of the sums
        ll_n, s2_n, nobs_n, g_n, h_n, ds2_n = scalar_point(x0, P0, Z, H, Qb, kind, v_new,
                                                           lam0, burn, (0,), dims, work)
        passes += 1
        halvings = 0
        while ll_n < ll - tol and halvings < 60:
            step *= 0.5
            halvings += 1
            v_new = min(max(v + step, lo), hi)
            ll_n, s2_n, nobs_n, g_n, h_n, ds2_n = scalar_point(x0, P0, Z, H, Qb, kind, v_new,
                                                               lam0, burn, (0,), dims, work)
            passes += 1
        if ll_n < ll - tol:                             # no ascent left: stay
            break
        dv = v_new - v
        if abs(dv) > 1e-6 * (1.0 + abs(v)):             # else: round-off dominates
            # the slope of the gradient at v_new from its quadratic interpolation
            # through the last three points (Newton's divided differences; the start
            # counts twice, with its exact h): the secant's plus c (v_new - v)
            h_sec = (g_n - g) / dv
            h_quad = h_sec
            if v_new != v_prev:
                h_quad += (h_sec - dd_prev) / (v_new - v_prev) * dv
            v_prev, dd_prev = v, h_sec
            if h_quad < 0.0:
                h = h_quad
            elif h_sec < 0.0:
                h = h_sec
            else:                                       # not concave here: exact
                ll_n, s2_n, nobs_n, g_n, h_n, ds2_n = scalar_point(
                    x0, P0, Z, H, Qb, kind, v_new, lam0, burn, (0, 0), dims, work)
                passes += 1
                h = h_n
                v_prev, dd_prev = v_new, h_n
        last = abs(dv)
        v, ll, sigma2, n_obs, g, ds2 = v_new, ll_n, s2_n, nobs_n, g_n, ds2_n
    return v, ll, sigma2, n_obs, g, h, converged, held, passes


# ----------------------------------------------------------------------
# a diagonal random walk ("q_diag"): a pass specialized to Q = diag(exp(v)), and the
# whole Newton search compiled
# ----------------------------------------------------------------------
@njit(cache=True)
def diag_work(n, m):
    """The state of a `diag_pass`: ``(x, dx, d2x, P, dP, d2P, g, dg, d2g, y, dy, d2y, ds,
    d2s, de, dslog, dsq, d2slog, d2sq, dgg)`` (``k = n`` variables)."""
    return (np.empty((n, m)), np.empty((n, n, m)), np.empty((n, n, n, m)),
            np.empty((n, n)), np.empty((n, n, n)), np.empty((n, n, n, n)),
            np.empty(n), np.empty((n, n)), np.empty((n, n, n)),
            np.empty(m), np.empty((n, m)), np.empty((n, n, m)),
            np.empty(n), np.empty((n, n)), np.empty((n, m)),
            np.empty(n), np.empty(n), np.empty((n, n)), np.empty((n, n)), np.empty((n, n, n)))


@njit(cache=True)
def diag_pass(x0, P0, Z, H, a, q, burn, orders, dims, work):
    """``(slog, sq, count)`` of `profile_derivs` for the time update
    ``P^- = a P + diag(q)``, ``q = exp(v)`` (``v`` the ``n`` search variables), with the
    gradients ``dslog``, ``dsq`` and the Hessians ``d2slog``, ``d2sq`` in ``v`` left in
    `work` (`diag_work`; up to the order that `orders` witnesses).

    `profile_derivs` with ``A = a``, ``dA = d2A = 0``, ``dQ_k = d2Q_kk = q_k E_kk``: the
    time update of a derivative is ``a dP + q_k E_kk``; each step's measurement update
    and the next time update are one sweep of ``P`` and its derivatives, on the upper
    triangle (read as symmetric) and the pairs ``k <= l``, with `orders` and `dims` as
    for `scalar_pass` (the loops unrolled for a tuple `dims`). ``tests/test_tuning.py``
    holds it equal to `profile_derivs`.
    """
    (x, dx, d2x, P, dP, d2P, g, dg, d2g, y, dy, d2y, ds, d2s, de, dslog, dsq, d2slog,
     d2sq, dgg) = work
    m = x0.shape[1]
    n = len(dims)                         # a constant when dims is a tuple
    d1 = len(orders) >= 1
    d2 = len(orders) >= 2
    for i in range(n):
        for c_ in range(m):
            x[i, c_] = x0[i, c_]
        for j in range(i, n):             # the first prior a P0 + diag(q)
            P[i, j] = a * P0[i, j] + (q[i] if i == j else 0.0)
    for k in range(n):
        dslog[k] = dsq[k] = 0.0
        for i in range(n):
            for c_ in range(m):
                dx[k, i, c_] = 0.0
            for j in range(i, n):
                dP[k, i, j] = q[k] if (i == k and j == k) else 0.0
        for l_ in range(n):
            d2slog[k, l_] = d2sq[k, l_] = 0.0
            for i in range(n):
                for c_ in range(m):
                    d2x[k, l_, i, c_] = 0.0
                for j in range(i, n):
                    d2P[k, l_, i, j] = q[k] if (k == l_ and i == k and j == k) else 0.0
    slog = sq = 0.0
    prod = 1.0                            # running product of s >= 1
    count = 0
    for t in range(Z.shape[0]):
        # g = P^- h, s = h^T g + 1, y = z - x^T h (and their derivatives)
        s = 1.0
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += P[min(i, j), max(i, j)] * H[t, j]
            g[i] = acc
            s += H[t, i] * acc
        if d1:
            for k in range(n):
                acc_s = 0.0
                for i in range(n):
                    acc = 0.0
                    for j in range(n):
                        acc += dP[k, min(i, j), max(i, j)] * H[t, j]
                    dg[k, i] = acc
                    acc_s += H[t, i] * acc
                ds[k] = acc_s
        if d2:
            for k in range(n):
                for l_ in range(k, n):
                    acc_s = 0.0
                    for i in range(n):
                        acc = 0.0
                        for j in range(n):
                            acc += d2P[k, l_, min(i, j), max(i, j)] * H[t, j]
                        d2g[k, l_, i] = acc
                        acc_s += H[t, i] * acc
                    d2s[k, l_] = acc_s
        missing = False
        for c_ in range(m):
            acc = Z[t, c_]
            for i in range(n):
                acc -= H[t, i] * x[i, c_]
            y[c_] = acc
            if acc != acc:
                missing = True
            if d1:
                for k in range(n):
                    acc = 0.0
                    for i in range(n):
                        acc -= H[t, i] * dx[k, i, c_]
                    dy[k, c_] = acc
            if d2:
                for k in range(n):
                    for l_ in range(k, n):
                        acc = 0.0
                        for i in range(n):
                            acc -= H[t, i] * d2x[k, l_, i, c_]
                        d2y[k, l_, c_] = acc
        if missing:                       # posterior = prior: P^-_{t+1} = a P^-_t + diag(q)
            for i in range(n):
                for j in range(i, n):
                    P[i, j] = a * P[i, j] + (q[i] if i == j else 0.0)
            if d1:
                for k in range(n):
                    for i in range(n):
                        for j in range(i, n):
                            dP[k, i, j] = a * dP[k, i, j] + (q[k] if (i == k and j == k)
                                                             else 0.0)
            if d2:
                for k in range(n):
                    for l_ in range(k, n):
                        for i in range(n):
                            for j in range(i, n):
                                d2P[k, l_, i, j] = a * d2P[k, l_, i, j] + (
                                    q[k] if (k == l_ and i == k and j == k) else 0.0)
            continue
        r = 1.0 / s
        r2 = r * r
        r3 = r2 * r
        if t >= burn:
            slog, prod = _add_log(slog, prod, s)
            count += m
            for c_ in range(m):
                sq += y[c_] * y[c_] * r
            if d1:
                for k in range(n):
                    dslog[k] += ds[k] * r
                    for c_ in range(m):
                        yc = y[c_]
                        dsq[k] += 2.0 * yc * dy[k, c_] * r - yc * yc * ds[k] * r2
            if d2:
                for k in range(n):
                    for l_ in range(k, n):
                        d2slog[k, l_] += d2s[k, l_] * r - ds[k] * ds[l_] * r2
                        for c_ in range(m):
                            yc = y[c_]
                            d2sq[k, l_] += (2.0 * dy[k, c_] * dy[l_, c_] * r
                                            + 2.0 * yc * d2y[k, l_, c_] * r
                                            - 2.0 * yc * (dy[k, c_] * ds[l_]
                                                          + dy[l_, c_] * ds[k]) * r2
                                            - yc * yc * d2s[k, l_] * r2
                                            + 2.0 * yc * yc * ds[k] * ds[l_] * r3)
        # x = x + g e^T, e = y / s (and derivatives; they read dg, de of this step)
        for c_ in range(m):
            e = y[c_] * r
            if d1:
                for k in range(n):
                    de[k, c_] = dy[k, c_] * r - y[c_] * ds[k] * r2
            if d2:
                for k in range(n):
                    for l_ in range(k, n):
                        d2e = (d2y[k, l_, c_] * r - (dy[k, c_] * ds[l_] + dy[l_, c_] * ds[k]) * r2
                               - y[c_] * d2s[k, l_] * r2 + 2.0 * y[c_] * ds[k] * ds[l_] * r3)
                        for i in range(n):
                            d2x[k, l_, i, c_] += (d2g[k, l_, i] * e + dg[k, i] * de[l_, c_]
                                                  + dg[l_, i] * de[k, c_] + g[i] * d2e)
            if d1:
                for k in range(n):
                    for i in range(n):
                        dx[k, i, c_] += dg[k, i] * e + g[i] * de[k, c_]
            for i in range(n):
                x[i, c_] += g[i] * e
        # P = P^- - g g^T / s and the next prior a P + diag(q) (and derivatives);
        # dgg_k = d(g g^T) / dv_k, once per step
        if d1:
            for k in range(n):
                for i in range(n):
                    for j in range(i, n):
                        dgg[k, i, j] = dg[k, i] * g[j] + g[i] * dg[k, j]
        if d2:
            for k in range(n):
                for l_ in range(k, n):
                    d2r = -d2s[k, l_] * r2 + 2.0 * ds[k] * ds[l_] * r3
                    drk = -ds[k] * r2
                    drl = -ds[l_] * r2
                    for i in range(n):
                        for j in range(i, n):
                            v = d2P[k, l_, i, j] - (
                                (d2g[k, l_, i] * g[j] + dg[k, i] * dg[l_, j]
                                 + dg[l_, i] * dg[k, j] + g[i] * d2g[k, l_, j]) * r
                                + dgg[k, i, j] * drl + dgg[l_, i, j] * drk
                                + g[i] * g[j] * d2r)
                            d2P[k, l_, i, j] = a * v + (q[k] if (k == l_ and i == k and j == k)
                                                        else 0.0)
        if d1:
            for k in range(n):
                drk = -ds[k] * r2
                for i in range(n):
                    for j in range(i, n):
                        v = dP[k, i, j] - (dgg[k, i, j] * r + g[i] * g[j] * drk)
                        dP[k, i, j] = a * v + (q[k] if (i == k and j == k) else 0.0)
        for i in range(n):
            for j in range(i, n):
                P[i, j] = a * (P[i, j] - g[i] * g[j] * r) + (q[i] if i == j else 0.0)
    slog += math.log(prod)
    for k in range(n):
        for l_ in range(k + 1, n):
            d2slog[l_, k] = d2slog[k, l_]
            d2sq[l_, k] = d2sq[k, l_]
    return slog, sq, count


@njit(cache=True, error_model="numpy")
def diag_point(x0, P0, Z, H, a, v, burn, orders, dims, work, grad, hess):
    r"""``(loglik, sigma2, n_obs)`` of the profile log-likelihood at ``q = exp(v)`` (one
    `diag_pass`), its gradient written into `grad` (n,) and its Hessian into `hess`
    (n, n) in `v` (as `scalar_point`, entry by entry):
    :math:`\partial_k \ell_p = -\tfrac12 (N\,sq_k / sq + m\,slog_k)`,
    :math:`\partial_{kl} \ell_p = -\tfrac12 (N (sq_{kl}/sq - sq_k sq_l / sq^2)
    + m\,slog_{kl})`. ``n_obs = 0`` when no innovation is counted."""
    n = len(v)
    q = np.exp(v)
    slog, sq, count = diag_pass(x0, P0, Z, H, a, q, burn, orders, dims, work)
    if count == 0:
        return math.nan, math.nan, 0
    dslog, dsq, d2slog, d2sq = work[15], work[16], work[17], work[18]
    m = x0.shape[1]
    sigma2 = sq / count
    ll = -0.5 * (count * (_LOG_2PI + math.log(sigma2) + 1.0) + m * slog)
    if len(orders) >= 1:
        for k in range(n):
            grad[k] = -0.5 * (count * dsq[k] / sq + m * dslog[k])
    if len(orders) >= 2:
        for k in range(n):
            for l_ in range(n):
                hess[k, l_] = -0.5 * (count * (d2sq[k, l_] / sq - dsq[k] * dsq[l_] / (sq * sq))
                                      + m * d2slog[k, l_])
    return ll, sigma2, count


@njit(cache=True, error_model="numpy")
def diag_profile(x0, P0, Z, H, a, v, burn, order, dims):
    """`diag_point` with the order as a number: ``(loglik, sigma2, n_obs, gradient,
    Hessian)``."""
    n = len(v)
    work = diag_work(n, x0.shape[1])
    grad = np.zeros(n)
    hess = np.zeros((n, n))
    if order <= 0:
        ll, sigma2, count = diag_point(x0, P0, Z, H, a, v, burn, (), dims, work, grad, hess)
    elif order == 1:
        ll, sigma2, count = diag_point(x0, P0, Z, H, a, v, burn, (0,), dims, work, grad,
                                       hess)
    else:
        ll, sigma2, count = diag_point(x0, P0, Z, H, a, v, burn, (0, 0), dims, work, grad,
                                       hess)
    return ll, sigma2, count, grad, hess


@njit(cache=True, error_model="numpy")
def _newton_direction(grad, hess, free, max_step, step):
    """The Newton step ``-hess^-1 grad`` of the free variables into `step` (zeros for the
    others), by a Cholesky factorization of ``-hess`` on the free set; where it is not
    positive definite, a steepest ascent step of length `max_step` instead. Steps are
    cut to `max_step` in the largest entry."""
    n = len(grad)
    idx = np.empty(n, dtype=np.int64)
    f = 0
    for i in range(n):
        step[i] = 0.0
        if free[i]:
            idx[f] = i
            f += 1
    L = np.zeros((f, f))
    ok = True
    for i in range(f):                    # -hess = L L^T on the free set
        for j in range(i + 1):
            acc = -hess[idx[i], idx[j]]
            for p in range(j):
                acc -= L[i, p] * L[j, p]
            if i == j:
                if not acc > 0.0:
                    ok = False
                    break
                L[i, i] = math.sqrt(acc)
            else:
                L[i, j] = acc / L[j, j]
        if not ok:
            break
    if ok:
        w = np.empty(f)
        for i in range(f):                # L w = grad, L^T d = w
            acc = grad[idx[i]]
            for p in range(i):
                acc -= L[i, p] * w[p]
            w[i] = acc / L[i, i]
        for i in range(f - 1, -1, -1):
            acc = w[i]
            for p in range(i + 1, f):
                acc -= L[p, i] * step[idx[p]]
            step[idx[i]] = acc / L[i, i]
    else:
        big = 0.0
        for i in range(f):
            big = max(big, abs(grad[idx[i]]))
        for i in range(f):
            step[idx[i]] = max_step * grad[idx[i]] / big if big > 0.0 else 0.0
    big = 0.0
    for i in range(n):
        big = max(big, abs(step[i]))
    if big > max_step:
        for i in range(n):
            step[i] *= max_step / big


#: The Newton search of ``q_diag`` takes its last step on the quadratic model, without a
#: pass, also when it is at most `_NEWTON_LAST` long and the error it leaves, about
#: ``M step^2`` with ``M = |step| / |last step|^2`` read off the quadratic convergence,
#: is at most `_NEWTON_ERROR` (the Hessian of the standard errors is then the one a
#: step away: a relative change of about 1e-3 times the third derivative over the
#: second, about 4e-5 here).
_NEWTON_LAST = 1e-3
_NEWTON_ERROR = 1e-7


@njit(cache=True, error_model="numpy")
def diag_search(x0, P0, Z, H, a, burn, v0, lo, hi, max_step, maxiter, xtol, dims):
    """Maximize the profile log-likelihood of ``v = log q`` (``Q = diag(exp(v))``) in the
    box ``[lo, hi]`` by a projected Newton search on the exact gradient and Hessian
    (every pass of order 2): a variable on a bound whose gradient points out is held
    there; the others take the Newton step (`_newton_direction`), cut to the box and
    halved until the likelihood does not fall. It stops when the step is shorter than
    `xtol` in every entry, or takes a last step on the quadratic model without a pass
    when it is shorter than `_LAST_STEP`, or than `_NEWTON_LAST` with the error it
    leaves below `_NEWTON_ERROR` (the error after a Newton step is of the order of its
    square). One compiled call.

    Returns ``(v, loglik, sigma2, n_obs, gradient, Hessian, converged, held, n_passes)``
    (`held`: bool per variable; ``n_obs = 0`` when no innovation is counted).
    """
    n, m = x0.shape
    work = diag_work(n, m)
    grad = np.zeros(n)
    hess = np.zeros((n, n))
    g_n = np.zeros(n)
    h_n = np.zeros((n, n))
    v = np.empty(n)
    v_new = np.empty(n)
    for i in range(n):
        v[i] = min(max(v0[i], lo[i]), hi[i])
    held = np.zeros(n, dtype=np.bool_)
    free = np.ones(n, dtype=np.bool_)
    step = np.zeros(n)
    ll, sigma2, n_obs = diag_point(x0, P0, Z, H, a, v, burn, (0, 0), dims, work, grad, hess)
    passes = 1
    converged = False
    if n_obs == 0:
        return v, ll, sigma2, n_obs, grad, hess, converged, held, passes
    last = 0.0                            # the length of the last step taken (none yet)
    for _ in range(maxiter):
        any_free = False
        for i in range(n):
            held[i] = (v[i] <= lo[i] and grad[i] < 0.0) or (v[i] >= hi[i] and grad[i] > 0.0)
            free[i] = not held[i]
            any_free = any_free or free[i]
        if not any_free:
            converged = True
            break
        _newton_direction(grad, hess, free, max_step, step)
        longest = 0.0
        cut = False
        for i in range(n):
            v_new[i] = min(max(v[i] + step[i], lo[i]), hi[i])
            longest = max(longest, abs(v_new[i] - v[i]))
            cut = cut or v_new[i] != v[i] + step[i]
        if longest <= xtol:
            converged = True
            break
        if not cut and (longest <= _LAST_STEP or (
                longest <= _NEWTON_LAST and longest ** 3 <= _NEWTON_ERROR * last * last)):
            # the last step on the quadratic model: l + g.d + d.H d / 2 = l + g.d / 2
            # (d the Newton step, H d = -g on the free set)
            gd = 0.0
            ds2 = 0.0
            dsq = work[16]
            count = n_obs
            for i in range(n):
                gd += grad[i] * step[i]
                ds2 += dsq[i] / count * step[i]
            for i in range(n):
                acc = grad[i]
                for j in range(n):
                    acc += hess[i, j] * step[j]
                grad[i] = acc
                v[i] = v_new[i]
            ll += 0.5 * gd
            sigma2 += ds2
            converged = True
            break
        tol = 1e-12 * (1.0 + abs(ll))                  # round-off of the sums
        ll_n, s2_n, nobs_n = diag_point(x0, P0, Z, H, a, v_new, burn, (0, 0), dims, work,
                                        g_n, h_n)
        passes += 1
        halvings = 0
        while ll_n < ll - tol and halvings < 60:
            halvings += 1
            for i in range(n):
                step[i] *= 0.5
                v_new[i] = min(max(v[i] + step[i], lo[i]), hi[i])
            ll_n, s2_n, nobs_n = diag_point(x0, P0, Z, H, a, v_new, burn, (0, 0), dims,
                                            work, g_n, h_n)
            passes += 1
        if ll_n < ll - tol:                             # no ascent left: stay
            # (the work arrays now hold the last trial: `grad`, `hess` stay those of v)
            break
        last = 0.0
        for i in range(n):
            last = max(last, abs(v_new[i] - v[i]))
            v[i] = v_new[i]
            grad[i] = g_n[i]
            for j in range(n):
                hess[i, j] = h_n[i, j]
        ll, sigma2, n_obs = ll_n, s2_n, nobs_n
    for i in range(n):
        held[i] = (v[i] <= lo[i] and grad[i] < 0.0) or (v[i] >= hi[i] and grad[i] > 0.0)
    return v, ll, sigma2, n_obs, grad, hess, converged, held, passes
