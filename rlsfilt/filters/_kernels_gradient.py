r"""Compiled (numba) steps and batch loops of the gradient filters (`rlsfilt.filters.gradient`).

One step per family; the batch loops run the same operations in the same
order (for one output written out in the loop, `_lms_one` and `_apa_one`), so
that ``update`` and ``batch_filter`` agree bit for bit
(``tests/test_gradient.py``, the contract suite):

- `lms_step`: LMS, normalized LMS and the sign variants, with leakage
  (Haykin 2002, ch. 5-6):

  .. math::

      y = z - x^T h, \qquad K = \mu\, s(h) / n, \qquad
      x \leftarrow (1 - \mu a)\, x + K\, g(y)^T

  with ``s(h) = h`` or ``sign(h)``, ``g(y) = y`` or ``sign(y)``, the norm
  ``n = 1`` or ``eps + h^T h`` (normalized) and the leak ``a``;
- `apa_update`/`apa_batch`: affine projection of order ``k`` (Ozeki & Umeda
  1984; Haykin 2002, ch. 6), on the ``k`` newest regressor rows ``X`` (newest
  first):

  .. math::

      E = D - X x, \qquad K = \mu X^T (X X^T + \epsilon I)^{-1}, \qquad
      x \leftarrow x + K E,

  computed as ``x + mu X^T w`` with ``w`` solved from the ``L D L^T``
  factors of ``X X^T + eps I`` (the gain itself is only a diagnostic: formed once per
  streaming step, once per record in the batch loop).

A missing measurement (NaN) skips the step: nothing changes, ``K`` keeps its
last value. No kernel allocates inside its loop: work space comes from the
caller.

Speed (``benchmarks/bench_gradient.py``, ``docs/performance.md``): the batch
loops for one output are written out per method (`_lms_one`, `_apa_one`: no
call, no method test and no stored gain per sample), which took
``batch_filter`` from 89 to 11 ns per sample for LMS at ``dim_x = 4`` (24x to
190x padasip; 192 to 19 ns at ``dim_x = 16``) and affine projection of order
4 from 375 to 84 ns (22x to 102x padasip). numba compiled the former loop,
an ``inline="always"`` step with an early return per sample, about 8 times
slower than the same arithmetic written out in the loop.

The affine projection loop for one output takes its order ``q`` as a compile-time
constant (`_apa_one`, for the orders of `_APA_ORDERS`; a tuple of ``q`` zeros is the
witness, as `_dimension_witness` does for the dimension in ``_kernels.py``; numba
compiles one loop per order used, lazily): the shift of the rows, the new Gram row
and ``X x`` are one pass over the entries with their ``q`` sums in registers, every
sum in the order of the entries (bit for bit the former loop and `apa_update`). At
order 4 it took 125 to 74 ns per sample at ``dim_x = 16`` (1.68x) and 77 to 43 ns at
``dim_x = 4`` (1.81x); order 5 1.60x and 1.72x, order 6 1.47x and 1.64x, order 1
1.93x and 1.31x (one run, interleaved, best of 7). From order 7 the sums no longer
stay in registers (0.43x at order 8), so those orders keep the loop with the order
as a variable (`_apa_one_any`). Tried before and not kept (below the 1.5x a change
must pay): the rows in a ring instead of shifted (0.89x alone), a transposed buffer
with the row sums interleaved per entry (0.65x), the new Gram row and ``X x`` fused
two or four rows per pass for any order (1.03x, 1.32x), a reciprocal of ``D``
instead of the divisions (no gain).
"""

import numpy as np
from numba.cpython.unsafe.tuple import tuple_setitem

from .._numba import njit

__all__ = []

#: Method codes of `lms_step` (positions in `METHODS`; never reused).
METHODS = ("lms", "nlms", "sign_error", "sign_data", "sign_sign")
LMS, NLMS, SIGN_ERROR, SIGN_DATA, SIGN_SIGN = range(5)


@njit(cache=True, inline="always")
def _sign(v):
    """1, -1 or 0 (also for NaN), without a branch: the sign of random data is a
    coin toss, which a branch predictor cannot learn."""
    return 1.0 * (v > 0.0) - 1.0 * (v < 0.0)


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
def lms_batch(method, x, Hm, Z, mu, eps, leak, K, y, means):
    """`lms_step` over a record: ``means[k + 1]`` is the estimate after sample `k`
    (``means[0]`` is written with the estimate at entry), and `x`, `K`, `y` hold the
    final state. Returns the index of the last sample that updated (-1: none).

    With one output the loop is `_lms_one`, specialised per method (the same
    operations in the same order as `lms_step`, so bit for bit the streaming steps);
    several outputs run `lms_step` itself."""
    _store(means, 0, x)
    if x.shape[1] != 1:
        last = -1
        for k in range(Z.shape[0]):
            if lms_step(method, x, Hm, Z, k, mu, eps, leak, K, y):
                last = k
            _store(means, k + 1, x)
        return last
    normalized = method == NLMS
    sign_data = method == SIGN_DATA or method == SIGN_SIGN
    sign_error = method == SIGN_ERROR or method == SIGN_SIGN
    # one loop per combination, chosen once: no method test inside the sample loop
    if normalized:
        last = _lms_one(x, Hm, Z, mu, eps, 1.0 - mu * leak, y, means, True, False, False)
    elif sign_data and sign_error:
        last = _lms_one(x, Hm, Z, mu, eps, 1.0 - mu * leak, y, means, False, True, True)
    elif sign_data:
        last = _lms_one(x, Hm, Z, mu, eps, 1.0 - mu * leak, y, means, False, True, False)
    elif sign_error:
        last = _lms_one(x, Hm, Z, mu, eps, 1.0 - mu * leak, y, means, False, False, True)
    else:
        last = _lms_one(x, Hm, Z, mu, eps, 1.0 - mu * leak, y, means, False, False, False)
    if last >= 0:                                        # the gain of the last step
        n = x.shape[0]
        norm = 1.0
        if normalized:
            norm = eps
            for i in range(n):
                norm += Hm[last, i] * Hm[last, i]
        for i in range(n):
            hi = _sign(Hm[last, i]) if sign_data else Hm[last, i]
            K[i] = mu * hi / norm
    return last


@njit(cache=True, inline="always")
def _lms_one(x, Hm, Z, mu, eps, keep, y, means, normalized, sign_data, sign_error):
    """The sample loop of `lms_batch` for one output; the three flags are constants
    at each (inlined) call, so each call compiles to its own branch-free loop. The
    arithmetic is `lms_step`'s, operation for operation; the gain is not stored
    (`lms_batch` recomputes the last one). Returns the last sample that updated."""
    n = x.shape[0]
    last = -1
    for k in range(Z.shape[0]):
        z = Z[k, 0]
        if z == z:                                       # not missing (NaN)
            acc = 0.0                                    # y = z - x^T h
            for i in range(n):
                acc += x[i, 0] * Hm[k, i]
            e = z - acc
            y[0] = e
            norm = 1.0
            if normalized:                               # n = eps + h^T h
                norm = eps
                for i in range(n):
                    norm += Hm[k, i] * Hm[k, i]
            g = _sign(e) if sign_error else e
            for i in range(n):                           # x <- (1 - mu a) x + K g(y)
                hi = _sign(Hm[k, i]) if sign_data else Hm[k, i]
                x[i, 0] = keep * x[i, 0] + (mu * hi / norm) * g
            last = k
        for i in range(n):
            means[k + 1, i, 0] = x[i, 0]
    return last


@njit(cache=True, inline="always")
def _apa_shift(X, D, Hm, Z, k):
    """The newest row ``Hm[k]`` and measurement ``Z[k]`` enter the buffers `X` (q, n)
    and `D` (q, m), newest first."""
    q, n = X.shape
    m = D.shape[1]
    for r in range(q - 1, 0, -1):
        for i in range(n):
            X[r, i] = X[r - 1, i]
        for j in range(m):
            D[r, j] = D[r - 1, j]
    for i in range(n):
        X[0, i] = Hm[k, i]
    for j in range(m):
        D[0, j] = Z[k, j]


@njit(cache=True, inline="always")
def _apa_gram(X, G, first_row_only):
    """``G = X X^T`` (q, q). With `first_row_only`, after `_apa_shift`: the old
    products move one place down the diagonal and only the new row's are computed.
    Either way each entry is the dot product of the same two stored rows in the same
    order, so the two ways give the same bits."""
    q, n = X.shape
    if first_row_only:
        for r in range(q - 1, 0, -1):
            for c in range(r, 0, -1):
                G[r, c] = G[r - 1, c - 1]
                G[c, r] = G[r, c]
        rows = 1
    else:
        rows = q
    for r in range(q):
        for c in range(min(r + 1, rows)):
            acc = 0.0
            for i in range(n):
                acc += X[r, i] * X[c, i]
            G[r, c] = acc
            G[c, r] = acc


@njit(cache=True, inline="always")
def _apa_correct(x, X, D, G, mu, eps, A, E, y):
    """``E = D - X x``; `A` the factors of ``G + eps I = L D L^T`` (``L`` below the
    diagonal, ``D`` on it); ``E <- (G + eps I)^-1 E``; ``x <- x + mu X^T E`` (the
    step ``x + K E``); `y` the current residual."""
    q, n = X.shape
    m = x.shape[1]
    for r in range(q):                                   # E = D - X x
        for j in range(m):
            acc = 0.0
            for i in range(n):
                acc += X[r, i] * x[i, j]
            E[r, j] = D[r, j] - acc
    for j in range(m):
        y[j] = E[0, j]
    for c in range(q):                                   # G + eps I = L D L^T: L unit lower
        d = G[c, c] + eps                                # triangular below A's diagonal, D
        for t in range(c):                               # on it (no square root; one
            d -= A[c, t] * A[c, t] * A[t, t]             # division per column)
        A[c, c] = d
        inv = 1.0 / d
        for r in range(c + 1, q):
            s = G[r, c]
            for t in range(c):
                s -= A[r, t] * A[c, t] * A[t, t]
            A[r, c] = s * inv
    for j in range(m):                                   # E <- (L D L^T)^-1 E
        _ldl_solve(A, E, j)
    for j in range(m):                                   # x <- x + mu X^T E
        for i in range(n):
            acc = 0.0
            for r in range(q):
                acc += X[r, i] * E[r, j]
            x[i, j] += mu * acc


@njit(cache=True, inline="always")
def _ldl_solve(A, V, j):
    """Column `j` of `V` (q, .) <- ``(L D L^T)^-1`` times it, in place, with the
    factors in `A` as `_apa_correct` leaves them."""
    q = A.shape[0]
    for r in range(q):                                   # L u = v
        s = V[r, j]
        for t in range(r):
            s -= A[r, t] * V[t, j]
        V[r, j] = s
    for r in range(q):                                   # D z = u
        V[r, j] = V[r, j] / A[r, r]
    for r in range(q - 1, -1, -1):                       # L^T w = z
        s = V[r, j]
        for t in range(r + 1, q):
            s -= A[t, r] * V[t, j]
        V[r, j] = s


@njit(cache=True, inline="always")
def _apa_gain(X, mu, A, B, K):
    """The gain ``K = mu X^T (X X^T + eps I)^-1`` (n, q) from the factors in `A`
    (``L``, ``D``) of the last step (`B` (q, n) is work space)."""
    q, n = X.shape
    for r in range(q):                                   # B = (L D L^T)^-1 X
        for i in range(n):
            B[r, i] = X[r, i]
    for i in range(n):
        _ldl_solve(A, B, i)
    for i in range(n):                                   # K = mu B^T
        for r in range(q):
            K[i, r] = mu * B[r, i]


@njit(cache=True)
def apa_update(x, h, z, mu, eps, X, D, K, y, A, B, E, G):
    """The streaming step of affine projection, in place: the newest row `h` (1, n)
    and measurement `z` (1, m) enter the buffers, then ``E = D - X x``,
    ``x <- x + mu X^T (X X^T + eps I)^-1 E`` and the gain `K` (n, q). `A`, `B`, `E`,
    `G` are work space. Returns False (nothing changes) when `z` is missing."""
    for j in range(z.shape[1]):
        if np.isnan(z[0, j]):
            return False
    _apa_shift(X, D, h, z, 0)
    _apa_gram(X, G, False)
    _apa_correct(x, X, D, G, mu, eps, A, E, y)
    _apa_gain(X, mu, A, B, K)
    return True


#: The orders whose batch loop for one output is compiled with the order as a constant
#: (`_apa_one`); above them the sums no longer stay in registers and the fused loop
#: is slower than `_apa_one_any` (0.43x at order 8, ``dim_x = 16``).
_APA_ORDERS = range(1, 7)


def apa_batch(x, Hm, Z, mu, eps, X, D, K, y, A, B, E, G, means):
    """`apa_update` over a record: ``means[k + 1]`` is the estimate after sample `k`
    (``means[0]`` the estimate at entry); `x`, the buffers, `K`, `y` hold the final
    state. The Gram matrix ``X X^T`` is carried from step to step (one new row per
    sample, the same bits as recomputing it) and the gain is formed once, for the
    last step. Returns the index of the last sample that updated (-1: none).

    The order ``q`` enters the compiled loop as a tuple of ``q`` zeros (``len`` of
    a tuple is part of its type, so ``q`` is a compile-time constant: numba
    compiles one loop per order used, lazily)."""
    q = X.shape[0]
    return _apa_batch(x, Hm, Z, mu, eps, X, D, K, y, A, B, E, G, means,
                      (0.0,) * q if q in _APA_ORDERS else None)


@njit(cache=True)
def _apa_batch(x, Hm, Z, mu, eps, X, D, K, y, A, B, E, G, means, zeros):
    """`apa_batch` with the order witness `zeros` (a tuple of ``q`` zeros; None for
    an order above `_APA_ORDERS`)."""
    _store(means, 0, x)
    _apa_gram(X, G, False)
    m = x.shape[1]
    if m == 1:
        if zeros is None:                                # numba prunes the other branch
            last = _apa_one_any(x, Hm, Z, mu, eps, X, D, y, A, E, G, means)
        else:
            last = _apa_one(x, Hm, Z, mu, eps, X, D, y, A, E, G, means, zeros)
        if last >= 0:
            _apa_gain(X, mu, A, B, K)
        return last
    last = -1
    for k in range(Z.shape[0]):
        missing = False
        for j in range(m):
            missing = missing or np.isnan(Z[k, j])
        if not missing:
            _apa_shift(X, D, Hm, Z, k)
            _apa_gram(X, G, True)
            _apa_correct(x, X, D, G, mu, eps, A, E, y)
            last = k
        _store(means, k + 1, x)
    if last >= 0:
        _apa_gain(X, mu, A, B, K)
    return last


@njit(cache=True)
def _apa_one(x, Hm, Z, mu, eps, X, D, y, A, E, G, means, zeros):
    """The sample loop of `apa_batch` for one output: `_apa_shift`, `_apa_gram` and
    `_apa_correct` written out for ``m = 1``, operation for operation (so bit for bit
    the streaming step) and with no call inside the loop. The order ``q =
    len(zeros)`` is a compile-time constant: the shift of the rows, the new Gram
    row ``X[0] X^T`` and ``X x`` are one pass over the entries, their ``q`` sums
    each in a tuple (registers), every sum still in the order of the entries.
    Returns the last sample that updated (-1: none)."""
    q = len(zeros)                                       # a constant: one loop per order
    n = X.shape[1]
    last = -1
    for k in range(Z.shape[0]):
        z = Z[k, 0]
        if z == z:                                       # not missing (NaN)
            for r in range(q - 1, 0, -1):                # the rows move one place down
                D[r, 0] = D[r - 1, 0]
                for c in range(r, 0, -1):                # and so do their products
                    G[r, c] = G[r - 1, c - 1]
                    G[c, r] = G[r, c]
            D[0, 0] = z
            g = zeros                                    # g = X[0] X^T (the new Gram row)
            e = zeros                                    # e = X x
            for i in range(n):
                xi = x[i, 0]
                h = Hm[k, i]
                for r in range(q - 1, 0, -1):
                    X[r, i] = X[r - 1, i]
                X[0, i] = h
                for r in range(q):
                    v = X[r, i]
                    g = tuple_setitem(g, r, g[r] + v * h)
                    e = tuple_setitem(e, r, e[r] + v * xi)
            for r in range(q):
                G[r, 0] = g[r]
                G[0, r] = g[r]
                E[r, 0] = D[r, 0] - e[r]                 # E = D - X x
            y[0] = E[0, 0]
            for c in range(q):                           # G + eps I = L D L^T
                d = G[c, c] + eps
                for t in range(c):
                    d -= A[c, t] * A[c, t] * A[t, t]
                A[c, c] = d
                inv = 1.0 / d
                for r in range(c + 1, q):
                    s = G[r, c]
                    for t in range(c):
                        s -= A[r, t] * A[c, t] * A[t, t]
                    A[r, c] = s * inv
            for r in range(q):                           # E <- (L D L^T)^-1 E
                s = E[r, 0]
                for t in range(r):
                    s -= A[r, t] * E[t, 0]
                E[r, 0] = s
            for r in range(q):
                E[r, 0] = E[r, 0] / A[r, r]
            for r in range(q - 1, -1, -1):
                s = E[r, 0]
                for t in range(r + 1, q):
                    s -= A[t, r] * E[t, 0]
                E[r, 0] = s
            for i in range(n):                           # x <- x + mu X^T E
                acc = 0.0
                for r in range(q):
                    acc += X[r, i] * E[r, 0]
                x[i, 0] += mu * acc
                means[k + 1, i, 0] = x[i, 0]
            last = k
        else:
            for i in range(n):
                means[k + 1, i, 0] = x[i, 0]
    return last


@njit(cache=True)
def _apa_one_any(x, Hm, Z, mu, eps, X, D, y, A, E, G, means):
    """The sample loop of `apa_batch` for one output and an order above
    `_APA_ORDERS`: `_apa_shift`, `_apa_gram` and `_apa_correct` written out for
    ``m = 1``, operation for operation (so bit for bit the streaming step) and with
    no call inside the loop. Returns the last sample that updated (-1: none)."""
    q, n = X.shape
    last = -1
    for k in range(Z.shape[0]):
        z = Z[k, 0]
        if z == z:                                       # not missing (NaN)
            _apa_shift(X, D, Hm, Z, k)
            _apa_gram(X, G, True)
            for r in range(q):                           # E = D - X x
                acc = 0.0
                for i in range(n):
                    acc += X[r, i] * x[i, 0]
                E[r, 0] = D[r, 0] - acc
            y[0] = E[0, 0]
            for c in range(q):                           # G + eps I = L D L^T
                d = G[c, c] + eps
                for t in range(c):
                    d -= A[c, t] * A[c, t] * A[t, t]
                A[c, c] = d
                inv = 1.0 / d
                for r in range(c + 1, q):
                    s = G[r, c]
                    for t in range(c):
                        s -= A[r, t] * A[c, t] * A[t, t]
                    A[r, c] = s * inv
            for r in range(q):                           # E <- (L D L^T)^-1 E
                s = E[r, 0]
                for t in range(r):
                    s -= A[r, t] * E[t, 0]
                E[r, 0] = s
            for r in range(q):
                E[r, 0] = E[r, 0] / A[r, r]
            for r in range(q - 1, -1, -1):
                s = E[r, 0]
                for t in range(r + 1, q):
                    s -= A[t, r] * E[t, 0]
                E[r, 0] = s
            for i in range(n):                           # x <- x + mu X^T E
                acc = 0.0
                for r in range(q):
                    acc += X[r, i] * E[r, 0]
                x[i, 0] += mu * acc
            last = k
        for i in range(n):
            means[k + 1, i, 0] = x[i, 0]
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
