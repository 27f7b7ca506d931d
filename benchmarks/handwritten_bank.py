"""The yardstick of the bank benchmark: a hand-written compiled loop over many channels.

What an engineer writes to run one small RLS per channel fast: one numba
function, the state stored with the channel index last (``P[i, j, c]``) so
that the innermost loop runs over the channels and vectorizes, forgetting
folded into the gain (``s = lam + h' P h``), one division per step and
channel, and no histories. Not part of rlsfilt; ``benchmarks/bench_bank.py``
reports `RLSBank.batch_filter` as a ratio to it.
"""

import numpy as np
from numba import njit

__all__ = ["rls_bank_handwritten"]


@njit(cache=True, error_model="numpy")
def rls_bank_handwritten(Hs, zs, lam, p0):
    """Exponentially forgetting RLS on every channel.

    ``Hs`` (N, C, n), ``zs`` (N, C), ``lam`` (C,), ``p0`` the initial
    ``P = p0 I``. Returns the final estimates (C, n) and covariances (C, n, n).
    """
    N, C, n = Hs.shape
    P = np.zeros((n, n, C))
    for i in range(n):
        P[i, i, :] = p0
    th = np.zeros((n, C))
    g = np.empty((n, C))
    h = np.empty((n, C))
    s = np.empty(C)
    e = np.empty(C)
    il = 1.0 / lam
    for k in range(N):
        for c in range(C):
            for i in range(n):
                h[i, c] = Hs[k, c, i]
        for i in range(n):                          # g = P h
            for c in range(C):
                g[i, c] = 0.0
            for j in range(n):
                for c in range(C):
                    g[i, c] += P[i, j, c] * h[j, c]
        for c in range(C):
            s[c] = lam[c]
            e[c] = zs[k, c]
        for i in range(n):
            for c in range(C):
                s[c] += h[i, c] * g[i, c]           # s = lam + h' P h
                e[c] -= h[i, c] * th[i, c]          # e = z - h' theta
        for c in range(C):
            s[c] = 1.0 / s[c]
        for i in range(n):
            for c in range(C):
                th[i, c] += g[i, c] * (s[c] * e[c])
        for i in range(n):                          # P = (P - g g' / s) / lam, one triangle
            for j in range(i, n):
                for c in range(C):
                    v = (P[i, j, c] - g[i, c] * s[c] * g[j, c]) * il[c]
                    P[i, j, c] = v
                    P[j, i, c] = v
    return th.T.copy(), P.transpose(2, 0, 1).copy()
