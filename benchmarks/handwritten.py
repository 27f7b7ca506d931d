"""The yardstick: a careful hand-written compiled RLS loop (not part of rlsfilt).

This is what an engineer writes when RLS must be fast: one numba function,
forgetting folded into the gain (``s = lam + h' P h``), one division per
step (``c = 1 / s``), the covariance update on one triangle mirrored to the
other so that ``P`` stays exactly symmetric, and no histories beyond the
estimate. ``benchmarks/bench_rls.py`` reports rlsfilt's times as ratios to
this loop.
"""

import numpy as np
from numba import njit

__all__ = ["rls_handwritten"]


@njit(cache=True)
def rls_handwritten(Hs, zs, lam, P0, theta0):
    """Exponentially forgetting RLS; returns the estimate history and the final ``P``.

    ``Hs`` (N, n), ``zs`` (N,), ``P0`` (n, n), ``theta0`` (n,).
    """
    N, n = Hs.shape
    P = P0.copy()
    th = theta0.copy()
    thetas = np.empty((N, n))
    g = np.empty(n)
    il = 1.0 / lam
    for k in range(N):
        h = Hs[k]
        for i in range(n):                       # g = P h
            acc = 0.0
            for j in range(n):
                acc += P[i, j] * h[j]
            g[i] = acc
        s = lam
        e = zs[k]
        for i in range(n):
            s += h[i] * g[i]                     # s = lam + h' P h
            e -= h[i] * th[i]                    # e = z - h' theta
        c = 1.0 / s
        for i in range(n):
            th[i] += g[i] * (c * e)              # theta += P h e / s
        for i in range(n):                       # P = (P - g g' / s) / lam, one triangle
            gi = g[i] * c
            for j in range(i, n):
                v = (P[i, j] - gi * g[j]) * il
                P[i, j] = v
                P[j, i] = v
        thetas[k] = th
    return thetas, P
