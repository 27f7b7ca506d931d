r"""Compiled (numba) steps and batch loops of the gradient filters (`rlsfilt.filters.gradient`).

One step function per family, shared by the streaming kernel and the batch
loop, so that ``update`` and ``batch_filter`` agree bit for bit:

- `lms_step`: LMS, normalized LMS and the sign variants, with leakage
  (Haykin 2002, ch. 5-6):

  .. math::

      y = z - x^T h, \qquad K = \mu\, s(h) / n, \qquad
      x \leftarrow (1 - \mu a)\, x + K\, g(y)^T

  with ``s(h) = h`` or ``sign(h)``, ``g(y) = y`` or ``sign(y)``, the norm
  ``n = 1`` or ``eps + h^T h`` (normalized) and the leak ``a``;
- `apa_step`: affine projection of order ``k`` (Ozeki & Umeda 1984; Haykin
  2002, ch. 6), on the ``k`` newest regressor rows ``X`` (newest first):

  .. math::

      E = D - X x, \qquad K = \mu X^T (X X^T + \epsilon I)^{-1}, \qquad
      x \leftarrow x + K E.

A missing measurement (NaN) skips the step: nothing changes, ``K`` keeps its
last value. No kernel allocates inside its loop: work space comes from the
caller.
"""

import numpy as np

from .._numba import njit

__all__ = []

#: Method codes of `lms_step` (positions in `METHODS`; never reused).
METHODS = ("lms", "nlms", "sign_error", "sign_data", "sign_sign")
LMS, NLMS, SIGN_ERROR, SIGN_DATA, SIGN_SIGN = range(5)


@njit(cache=True, inline="always")
def _sign(v):
    if v > 0.0:
        return 1.0
    if v < 0.0:
        return -1.0
    return 0.0


@njit(cache=True, inline="always")
def lms_step(method, x, Hm, Z, k, mu, eps, leak, K, y):
    """One gradient step in place on sample `k`: `x` (n, m), regressor ``Hm[k]``
    (n,), measurement ``Z[k]`` (m,), gain `K` (n,) and residual `y` (m,) written
    (rows are indexed, not sliced: no array views in the loop). Returns False
    (and changes nothing) when the measurement is missing."""
    n, m = x.shape
    for j in range(m):
        if np.isnan(Z[k, j]):
            return False
    for j in range(m):                                   # y = z - x^T h
        acc = 0.0
        for i in range(n):
            acc += x[i, j] * Hm[k, i]
        y[j] = Z[k, j] - acc
    norm = 1.0
    if method == NLMS:                                   # n = eps + h^T h
        norm = eps
        for i in range(n):
            norm += Hm[k, i] * Hm[k, i]
    for i in range(n):                                   # K = mu s(h) / n
        hi = _sign(Hm[k, i]) if (method == SIGN_DATA or method == SIGN_SIGN) else Hm[k, i]
        K[i] = mu * hi / norm
    keep = 1.0 - mu * leak
    for j in range(m):                                   # x <- (1 - mu a) x + K g(y)^T
        e = _sign(y[j]) if (method == SIGN_ERROR or method == SIGN_SIGN) else y[j]
        for i in range(n):
            x[i, j] = keep * x[i, j] + K[i] * e
    return True


@njit(cache=True)
def lms_update(method, x, h, z, mu, eps, leak, K, y):
    """The streaming step: `lms_step` on arrays the caller allocated (`h` the row
    ``(1, n)``, `z` the measurement ``(1, m)``)."""
    return lms_step(method, x, h, z, 0, mu, eps, leak, K, y)


@njit(cache=True, inline="always")
def _store(out, k, x):
    """``out[k] = x`` element by element (cheaper than a slice assignment per sample)."""
    n, m = x.shape
    for i in range(n):
        for j in range(m):
            out[k, i, j] = x[i, j]


@njit(cache=True)
def lms_batch(method, x, Hm, Z, mu, eps, leak, update_first, K, y, means, means_p):
    """`lms_step` over a record; `x`, `K`, `y` hold the final state. Returns the
    index of the last sample that updated (-1: none)."""
    last = -1
    for k in range(Z.shape[0]):
        if not update_first:
            _store(means_p, k, x)
        if lms_step(method, x, Hm, Z, k, mu, eps, leak, K, y):
            last = k
        _store(means, k, x)
        if update_first:
            _store(means_p, k, x)
    return last


@njit(cache=True)
def apa_step(x, h, z, mu, eps, X, D, K, y, A, B, E):
    """One affine-projection step in place: the newest row `h` and measurement `z`
    enter the buffers `X` (k, n) and `D` (k, m) (newest first), then
    ``E = D - X x``, ``K = mu X^T (X X^T + eps I)^-1`` (n, k), ``x <- x + K E``.
    `A` (k, k), `B` (k, n) and `E` (k, m) are work space; `y` (m,) is the
    current residual ``E[0]``. Returns False (nothing changes) when `z` is missing."""
    k, n = X.shape
    m = x.shape[1]
    for j in range(m):
        if np.isnan(z[j]):
            return False
    for r in range(k - 1, 0, -1):                        # shift the buffers, newest first
        for i in range(n):
            X[r, i] = X[r - 1, i]
        for j in range(m):
            D[r, j] = D[r - 1, j]
    for i in range(n):
        X[0, i] = h[i]
    for j in range(m):
        D[0, j] = z[j]
    for r in range(k):                                   # E = D - X x
        for j in range(m):
            acc = 0.0
            for i in range(n):
                acc += X[r, i] * x[i, j]
            E[r, j] = D[r, j] - acc
    for r in range(k):                                   # A = X X^T + eps I
        for c in range(r + 1):
            acc = 0.0
            for i in range(n):
                acc += X[r, i] * X[c, i]
            A[r, c] = acc
            A[c, r] = acc
        A[r, r] += eps
    for c in range(k):                                   # A = L L^T (lower triangle of A)
        d = A[c, c]
        for t in range(c):
            d -= A[c, t] * A[c, t]
        d = np.sqrt(d)
        A[c, c] = d
        for r in range(c + 1, k):
            s = A[r, c]
            for t in range(c):
                s -= A[r, t] * A[c, t]
            A[r, c] = s / d
    for i in range(n):                                   # B = A^-1 X by L, then L^T
        for r in range(k):
            s = X[r, i]
            for t in range(r):
                s -= A[r, t] * B[t, i]
            B[r, i] = s / A[r, r]
        for r in range(k - 1, -1, -1):
            s = B[r, i]
            for t in range(r + 1, k):
                s -= A[t, r] * B[t, i]
            B[r, i] = s / A[r, r]
    for i in range(n):                                   # K = mu B^T
        for r in range(k):
            K[i, r] = mu * B[r, i]
    for j in range(m):                                   # x <- x + K E; y = E[0]
        y[j] = E[0, j]
        for i in range(n):
            acc = 0.0
            for r in range(k):
                acc += K[i, r] * E[r, j]
            x[i, j] += acc
    return True


@njit(cache=True)
def apa_update(x, h, z, mu, eps, X, D, K, y, A, B, E):
    """The streaming step: `apa_step` on arrays the caller allocated."""
    return apa_step(x, h, z, mu, eps, X, D, K, y, A, B, E)


@njit(cache=True)
def apa_batch(x, Hm, Z, mu, eps, update_first, X, D, K, y, A, B, E, means, means_p):
    """`apa_step` over a record; `x`, the buffers, `K`, `y` hold the final state.
    Returns the index of the last sample that updated (-1: none)."""
    last = -1
    for k in range(Z.shape[0]):
        if not update_first:
            _store(means_p, k, x)
        if apa_step(x, Hm[k], Z[k], mu, eps, X, D, K, y, A, B, E):
            last = k
        _store(means, k, x)
        if update_first:
            _store(means_p, k, x)
    return last


@njit(cache=True, inline="always")
def bank_step(method, x, H, Z, k, mu, eps, leak, K, y, S, R, r_row):
    """`lms_step` of every channel ``c`` of a `GradientBank` on sample `k`, with the
    same operations in the same order (so each channel has the bits of its own
    filter): `x` (C, n), regressors ``H[k]`` (C, n), measurements ``Z[k]`` (C,),
    step sizes `mu`, `eps`, `leak` (C,); writes the gains `K` (C, n), residuals `y`
    and variances `S` ``= R[r_row]`` (C,). A channel whose measurement or
    regressor holds NaN skips the step (``y`` NaN, ``K`` zero; ``S`` NaN when the
    regressor holds NaN). Returns the number of channels that updated."""
    C, n = x.shape
    count = 0
    for c in range(C):
        hok = True
        for i in range(n):
            hok = hok and H[k, c, i] == H[k, c, i]
        if not (hok and Z[k, c] == Z[k, c]):
            y[c] = np.nan
            S[c] = R[r_row, c] if hok else np.nan
            for i in range(n):
                K[c, i] = 0.0
            continue
        count += 1
        acc = 0.0                                        # y = z - x^T h
        for i in range(n):
            acc += x[c, i] * H[k, c, i]
        e = Z[k, c] - acc
        y[c] = e
        S[c] = R[r_row, c]
        norm = 1.0
        if method == NLMS:                               # n = eps + h^T h
            norm = eps[c]
            for i in range(n):
                norm += H[k, c, i] * H[k, c, i]
        m = mu[c]
        for i in range(n):                               # K = mu s(h) / n
            hi = _sign(H[k, c, i]) if (method == SIGN_DATA or method == SIGN_SIGN) \
                else H[k, c, i]
            K[c, i] = m * hi / norm
        keep = 1.0 - m * leak[c]
        if method == SIGN_ERROR or method == SIGN_SIGN:
            e = _sign(e)
        for i in range(n):                               # x <- (1 - mu a) x + K g(y)
            x[c, i] = keep * x[c, i] + K[c, i] * e
    return count


@njit(cache=True)
def bank_update(method, x, H, Z, mu, eps, leak, K, y, S, R):
    """The streaming step of a `GradientBank`: `bank_step` on ``H`` (1, C, n), ``Z``
    (1, C) and ``R`` (1, C)."""
    return bank_step(method, x, H, Z, 0, mu, eps, leak, K, y, S, R, 0)


@njit(cache=True)
def bank_batch(method, x, H, Z, mu, eps, leak, update_first, K, y, S, R, means, means_p,
               ys, ss, x_last):
    """`bank_step` over a record ``H`` (N, C, n), ``Z`` (N, C), ``R`` (N, C) or (1, C);
    `x`, `K`, `y`, `S` hold the final state, `x_last` (C, n) the estimates before
    the last step. ``means``, ``means_p`` (N, C, n) and ``ys``, ``ss`` (N, C)
    receive the histories when they have N rows (none with 0 rows). Returns the
    index of the last sample at which a channel updated (-1: none)."""
    N = Z.shape[0]
    C, n = x.shape
    keep_means, keep_res = means.shape[0] == N, ys.shape[0] == N
    per_row = R.shape[0] == N
    last = -1
    for k in range(N):
        if k == N - 1:
            for c in range(C):
                for i in range(n):
                    x_last[c, i] = x[c, i]
        if keep_means and not update_first:
            for c in range(C):
                for i in range(n):
                    means_p[k, c, i] = x[c, i]
        if bank_step(method, x, H, Z, k, mu, eps, leak, K, y, S, R, k if per_row else 0):
            last = k
        if keep_res:
            for c in range(C):
                ys[k, c] = y[c]
                ss[k, c] = S[c]
        if keep_means:
            for c in range(C):
                for i in range(n):
                    means[k, c, i] = x[c, i]
            if update_first:
                for c in range(C):
                    for i in range(n):
                        means_p[k, c, i] = x[c, i]
    return last
