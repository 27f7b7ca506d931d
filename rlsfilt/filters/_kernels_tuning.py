"""Compiled profile-likelihood terms of the Kalman recursion of the parameters (for `tuning`).

One pass of `RecursiveLeastSquares`' exponential-forgetting recursion with
``R = 1`` that keeps no history, only the two sums of the prediction-error
decomposition: the likelihood search of :mod:`rlsfilt.filters.tuning` calls it
a few dozen times per record. ``tests/test_tuning.py`` holds its innovations
equal to those of ``batch_filter``.
"""

import math

import numpy as np

from .._numba import njit

__all__ = []


@njit(cache=True)
def profile_terms(x0, P0, Z, H, il, Q, burn):
    """``(sum log s_t, sum y_t^T y_t / s_t, number of outputs counted)`` over the record.

    `x0` (n, m) and `P0` (n, n) start the run (not modified), `Z` (N, m) with
    NaN for missing samples, `H` (N, n), `il` = 1 / lam, `Q` (n, n) relative to
    ``R = 1``; samples before index `burn` update the state but are not counted.
    Each step:

        P^- = P il + Q                 time update (P / lam + Q)
        y = z - H x^-,  s = H P^- H^T + 1
        x = x^- + g y^T / s,  g = P^- H^T
        P = P^- - g g^T / s            (kept exactly symmetric)
    """
    n, m = x0.shape
    x = x0.copy()
    P = P0.copy()
    g = np.empty(n)
    y = np.empty(m)
    slog = 0.0
    sq = 0.0
    count = 0
    for k in range(Z.shape[0]):
        for i in range(n):
            for j in range(n):
                P[i, j] = P[i, j] * il + Q[i, j]
        s = 1.0
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += P[i, j] * H[k, j]
            g[i] = acc
            s += H[k, i] * acc
        missing = False
        for c in range(m):
            acc = Z[k, c]
            for i in range(n):
                acc -= H[k, i] * x[i, c]
            y[c] = acc
            if acc != acc:
                missing = True
        if missing:                       # posterior = prior
            continue
        if k >= burn:
            slog += math.log(s)
            for c in range(m):
                sq += y[c] * y[c] / s
            count += m
        for i in range(n):
            gi = g[i] / s
            for c in range(m):
                x[i, c] += gi * y[c]
        for i in range(n):
            for j in range(i, n):
                v = P[i, j] - g[i] * g[j] / s
                P[i, j] = v
                P[j, i] = v
    return slog, sq, count
