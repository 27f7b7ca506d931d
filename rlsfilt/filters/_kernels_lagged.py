"""Compiled (numba) regressor rows read from lagged signals, without a regressor matrix.

An ARX fit's row ``t`` is :math:`\\varphi(t) = [-y(t-1) \\dots -y(t-n_a),\\ u(t-n_k)
\\dots,\\ 1]`: a few entries of the record itself. Writing the rows out as a matrix costs
``8 n`` bytes per sample of fresh memory, more than the recursion that reads them
(``ARX.fit(method="rls")``). These functions read them from the signals instead:

``lags = (Y, U, cols, seg_rows, seg_t0)``

- ``Y`` (T, ny), ``U`` (T, nu): the signals, float64, C order (several experiments
  one after the other);
- ``cols`` (n, 3) int64: column ``j`` is ``kind, channel, lag``, with kind 0 for
  ``-Y[t - lag, channel]``, 1 for ``U[t - lag, channel]`` and 2 for the constant 1;
- ``seg_rows`` (n_seg + 1,) int64: the first row of each experiment, then the number
  of rows; ``seg_t0`` (n_seg,) int64: the time (index into ``Y`` and ``U``) of each
  experiment's first row. Row ``k`` of segment ``s`` is time
  ``seg_t0[s] + k - seg_rows[s]``.

The entries are the numbers a regressor matrix built from the same signals holds
(a negation is exact), so everything computed on them is what the matrix gives.
`exponential_batch` fills its blocks of scaled rows with `lag_block`.
"""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable

__all__ = ["lag_rows", "lag_rows_numpy", "lag_block", "lag_gram", "lag_residuals"]

_BLOCK = 1024   # rows `lag_gram` and `lag_residuals` build at a time


@njit(cache=True, error_model="numpy", inline="always")
def lag_rows(lags, k, scale, out):
    """``out[r, j] = phi_j(k + r) * scale[j]`` for the rows from row `k` that exist (at
    most ``len(out)``); returns how many were written.

    Column by column over each experiment's run of rows (a strided copy of one
    signal, times one factor: ``-y * f`` is ``y * (-f)``, bit for bit). `out`
    may be a transposed (F-order) view: the columns are then contiguous.
    """
    Y, U, cols, seg_rows, seg_t0 = lags
    rows = min(out.shape[0], seg_rows[-1] - k)
    n = cols.shape[0]
    s = _segment(seg_rows, k)
    r0 = 0
    while r0 < rows:
        kr = k + r0
        while kr >= seg_rows[s + 1]:
            s += 1
        run = min(rows - r0, seg_rows[s + 1] - kr)
        t = seg_t0[s] + kr - seg_rows[s]
        # unsigned indices: no wraparound test, so the copies vectorize
        o, m = np.uint64(r0), np.uint64(run)
        for j in range(n):
            kind, ch, jj = cols[j, 0], np.uint64(cols[j, 1]), np.uint64(j)
            base = np.uint64(t - cols[j, 2])
            if kind == 0:
                f = -scale[j]
                for r in range(m):
                    out[o + r, jj] = Y[base + r, ch] * f
            elif kind == 1:
                f = scale[j]
                for r in range(m):
                    out[o + r, jj] = U[base + r, ch] * f
            else:
                f = scale[j]
                for r in range(m):
                    out[o + r, jj] = f
        r0 += run
    return rows


def lag_rows_numpy(lags, k, scale, out):
    """`lag_rows` in NumPy, for the calls from Python (a few leading rows, the last row, a
    whole matrix): the same numbers, a strided copy times one factor per column and run
    of rows, with nothing to compile (the compiled kernels read rows a block at a time,
    `lag_block`)."""
    Y, U, cols, seg_rows, seg_t0 = lags
    rows = min(out.shape[0], int(seg_rows[-1]) - k)
    s = int(np.searchsorted(seg_rows, k, side="right")) - 1
    r0 = 0
    while r0 < rows:
        kr = k + r0
        while kr >= seg_rows[s + 1]:
            s += 1
        run = min(rows - r0, int(seg_rows[s + 1]) - kr)
        t = int(seg_t0[s]) + kr - int(seg_rows[s])
        for j, (kind, ch, lag) in enumerate(cols.tolist()):
            dst = out[r0:r0 + run, j]
            if kind == 0:                         # -y * f as y * (-f): the same bits
                np.multiply(Y[t - lag:t - lag + run, ch], -scale[j], out=dst)
            elif kind == 1:
                np.multiply(U[t - lag:t - lag + run, ch], scale[j], out=dst)
            else:
                dst[...] = scale[j]
        r0 += run
    return rows


@njit(cache=True, error_model="numpy", inline="always")
def _segment(seg_rows, k):
    """The experiment of row `k`: the last ``s`` with ``seg_rows[s] <= k`` (bisection;
    ``np.searchsorted(seg_rows, k, side="right") - 1``, whose string argument made
    numba compile its string operations into every caller, a second of CPU)."""
    lo, hi = 0, seg_rows.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        if seg_rows[mid] <= k:
            lo = mid + 1
        else:
            hi = mid
    return lo - 1


@njit(cache=True, error_model="numpy")
def lag_block(lags, k, scale, out):
    """`lag_rows` as a call into a transposed (F-order) block: `lag_gram`,
    `lag_residuals` and the fused loop of ``RecursiveLeastSquares`` (one block of rows per
    call) share this one compiled copy instead of an inlined copy each (a third of a
    second of a first run's compile work each)."""
    return lag_rows(lags, k, scale, out)


@njit(cache=True, error_model="numpy", fastmath={"reassoc", "contract"})
def _dot(a, b, rows):
    """``a[:rows] . b[:rows]`` in any order, with fused multiply-adds (vectorized: the
    Gram bound of ``ARX.fit`` holds for every summation order, and a fused
    multiply-add rounds once where a product and a sum round twice)."""
    acc = 0.0
    for r in range(rows):
        acc += a[r] * b[r]
    return acc


@njit(cache=True, error_model="numpy")
def lag_gram(lags, scale, G):
    r"""``G = Phi_s^T Phi_s`` of the rows scaled column by column by `scale` (all rows),
    built a block of columns at a time in cache; `G` (n, n) is overwritten."""
    n = G.shape[0]
    Bt = np.empty((n, _BLOCK))
    G[:, :] = 0.0
    total = lags[3][-1]
    for k in range(0, total, _BLOCK):
        rows = lag_block(lags, k, scale, Bt.T)
        for i in range(n):
            for j in range(i, n):
                G[i, j] += _dot(Bt[i], Bt[j], rows)
    for i in range(n):
        for j in range(i):
            G[i, j] = G[j, i]


@njit(cache=True, error_model="numpy")
def _max_abs(x, rows, top):
    """``max(top, max|x[:rows]|)`` (four running maxima; NaN entries are passed over)."""
    m0 = m1 = m2 = m3 = top
    r = 0
    while r + 4 <= rows:
        m0 = max(m0, abs(x[r]))
        m1 = max(m1, abs(x[r + 1]))
        m2 = max(m2, abs(x[r + 2]))
        m3 = max(m3, abs(x[r + 3]))
        r += 4
    while r < rows:
        m0 = max(m0, abs(x[r]))
        r += 1
    return max(max(m0, m1), max(m2, m3))


@njit(cache=True, error_model="numpy")
def lag_residuals(lags, theta, out, top):
    r"""``out[k, i] = Y[t, i] - phi(k) . theta[:, i]`` for every row (the residuals of
    the estimate `theta` (n, m), in the signals' units; ``Y``'s first ``m``
    channels are the outputs), the products summed in column order;
    ``top[i] = max_k |out[k, i]|`` (of the numbers among them: a NaN residual
    makes every sum over them NaN whatever the scale).

    The target is one more column for `lag_rows`, ``-Y[t - 0, i]`` times -1 (exactly
    ``y(t)``), beside the products ``phi_j(t) theta_j``."""
    Y, U, cols, seg_rows, seg_t0 = lags
    n, m = theta.shape
    with_target = np.empty((n + 1, 3), dtype=np.int64)
    for j in range(n):                            # loops, not slice assignments: less to compile
        for c in range(3):
            with_target[j, c] = cols[j, c]
    scale = np.empty(n + 1)
    scale[n] = -1.0
    Bt = np.empty((n + 1, _BLOCK))
    acc = np.empty(_BLOCK)
    total = seg_rows[-1]
    for i in range(m):
        with_target[n, 0], with_target[n, 1], with_target[n, 2] = 0, i, 0
        for j in range(n):
            scale[j] = theta[j, i]
        rows_lags = (Y, U, with_target, seg_rows, seg_t0)
        top[i] = 0.0
        for k in range(0, total, _BLOCK):
            rows = lag_block(rows_lags, k, scale, Bt.T)
            w, un, c, o = np.uint64(rows), np.uint64(n), np.uint64(i), np.uint64(k)
            for r in range(w):                    # y(t) - sum_j phi_j(t) theta_j, in order
                acc[r] = Bt[0, r]
            for j in range(1, n):
                jj = np.uint64(j)
                for r in range(w):
                    acc[r] += Bt[jj, r]
            for r in range(w):
                acc[r] = Bt[un, r] - acc[r]
                out[o + r, c] = acc[r]
            top[i] = _max_abs(acc, rows, top[i])
