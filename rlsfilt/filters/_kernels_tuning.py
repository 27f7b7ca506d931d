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
