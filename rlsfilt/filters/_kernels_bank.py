"""Compiled (numba) kernels of `RLSBank`: many independent RLS filters at once.

The readable NumPy version of the same recursion is
``tests/_reference_bank.py``; the tests hold the two equal to
1e-12, and every channel equal (bit for bit, in practice) to its own
`RecursiveLeastSquares`.

Layout. `RLSBank` stores its state in Fortran order, so that the kernels
read and write the transposes ``x^T`` (n, C) and ``P^T`` (n, n, C), the
channel index last and contiguous (see `_load`). The kernels process the
channels in blocks (`block_size`).
A block's state is copied into local arrays with the channel index last,
``x[i, b]`` and the upper triangle of ``P`` packed row by row,
``P[t, b]`` with ``t`` running over ``(i, j), i <= j`` (``P`` is exactly
symmetric, so the other triangle carries no information). The record
kernel runs the whole record on one block before the next block starts:
the block's state (``dim_x (dim_x + 3) / 2`` numbers per channel) stays in
cache for the whole record, and
every inner loop runs over the channels of the block with no dependency
between them, so LLVM vectorizes it without reordering any sum (no
``fastmath``). The arithmetic of each channel is therefore exactly that of
one `RecursiveLeastSquares`, operation by operation:

    P <- P * (1/lam) + Q                     time update (1/lam = 1 except "exponential")
    g = P h                                  g_i = sum_j P_ji h_j, j ascending
    s = h . g + r
    y = z - h . x
    "exponential":     c = 1 / s, K = g c, x <- x + K y, P <- P - (g g^T) c
    "directional":     rho = (s - r) / r, e = lam - (1 - lam) / rho (rho > eps, else 1),
                       d = r (1 + e rho), K = g / d, x <- x + K y, P <- P - (e / d)(g g^T)
    "constant_trace":  K = g / s, x <- x + K y, P <- P - (g g^T) / s, t = trace P,
                       P <- (c1 / t) P + c2 I

The exponential mode has the windup cap of `RecursiveLeastSquares`
(``_kernels.windup_cap``): ``s = w h . g + r`` and ``P <- P - (g g^T) cu`` with
the coefficients of ``_kernels.exponential_coefficient`` (`_exponential_coefficients`),
and after each update `_cap_step` decides per channel, from the diagonal of
the updated ``P``, whether the next time update divides by ``lam`` (``w = 1``
then; else the factor is 1 and ``w = 1 / lam``). Without the cap engaged
``w = 1`` and the numbers are those of the plain recursion, bit for bit.

(``_kernels.batch_filter_kernel`` for the exponential mode,
``_kernels.general_update`` for the two others). As in the exponential
kernel of `RecursiveLeastSquares`, the exponential mode applies the next
time update in the same sweep over ``P`` as the measurement update
(``P <- (P - (g g^T) c) / lam + Q``), whenever nothing needs ``P`` in
between (no covariance history, no health check at that step).

A channel whose measurement is missing (NaN ``z``) or whose regressor holds
a NaN is left unchanged by the measurement update. Each step of a block
first counts the non-finite inputs of the block in one vectorized pass
(`_read_step`). With none (the usual case) the step runs without masks or
selects; otherwise infinities are reported as errors and the masked path
decides per channel with selects (``c if ok else 0``): multiplying by a
selected ``1`` or adding a selected ``0`` is exact, so the channels that do
update are not perturbed, and both paths give the same bits.

The periodic health check of a block (`_check_block`) runs the cheap bound
of `unhealthy` (a Cholesky factor and ``trace(P) trace(P^-1)``) on all
lanes at once; only the channels it cannot prove healthy are decided by
`unhealthy` itself, so the decisions are the same.

The blocks are independent: ``bank_batch_parallel`` runs them on numba's
threads (``prange``); ``docs/performance.md`` says when that pays.

Every function is ``njit(cache=True)`` with ``error_model="numpy"``
(IEEE division: no zero test in the vectorized loops).
"""

import numpy as np
from numba import prange

from .._numba import njit  # numba.njit, uncached where no cache directory is writable
from ._kernels_shared import unhealthy as _unhealthy

__all__ = []

EXPONENTIAL, DIRECTIONAL, CONSTANT_TRACE = 0, 1, 2

_JIT = {"cache": True, "error_model": "numpy"}


def block_size(dim_x, n_channels):
    """Channels per block of the record kernels.

    Each step runs a few dozen short loops over the channels of a block, so
    wide blocks amortize the loop overhead over more channels (measured at
    ``dim_x = 4``, 10,000 channels x 1,000 samples, no histories: 32
    channels per block ran 1.43x the time of the hand-written loop of
    ``benchmarks/handwritten_bank.py``, 128 channels 1.04x, 256 channels
    0.89x, 512 and 1024 channels 0.85x). The block's working set (``x``, ``P``, ``Q``,
    ``g``, ``h``, ``K``: about ``(dim_x^2 + 9 dim_x) / 2 + 8`` numbers per
    channel) is kept near 128 KB, in the second-level cache. A multiple of
    8 between 16 and 1024, no wider than `n_channels` needs.
    """
    per_channel = 8 * ((dim_x * dim_x + 9 * dim_x) // 2 + 8)
    b = max(16, min(1024, (128 * 1024 // per_channel) // 8 * 8))
    return int(min(b, max(8, -(-n_channels // 8) * 8)))


# ----------------------------------------------------------------------
# packed upper triangle
# ----------------------------------------------------------------------
@njit(**_JIT)
def _triangle(n):
    """Row and column of each packed entry, and the packed index of ``(i, j)``."""
    nt = n * (n + 1) // 2
    iu = np.empty(nt, dtype=np.int64)
    ju = np.empty(nt, dtype=np.int64)
    tri = np.empty((n, n), dtype=np.int64)
    t = 0
    for i in range(n):
        for j in range(i, n):
            iu[t] = i
            ju[t] = j
            tri[i, j] = t
            tri[j, i] = t
            t += 1
    return iu, ju, tri


@njit(**_JIT)
def _load(xt, Pt, Qt, q_zero, c0, nb, xb, Pb, Qb, iu, ju):
    """Copy channels ``c0 .. c0 + nb - 1`` of the state into the block arrays.

    ``xt``, ``Pt``, ``Qt`` are the bank's state in its own layout, the
    transposes ``x^T`` (n, C) and ``P^T`` (n, n, C) (``Pt[j, i, c] = P[c,
    i, j]``): every loop below runs over contiguous channels. ``P`` is read
    as ``(P + P^T) / 2``, which is ``P`` itself, bit for bit, when ``P`` is
    exactly symmetric.
    """
    n = xt.shape[0]
    c1 = c0 + nb
    for i in range(n):
        src, dst = xt[i, c0:c1], xb[i]
        for b in range(nb):
            dst[b] = src[b]
    for t in range(iu.shape[0]):
        i, j = iu[t], ju[t]
        u, v, dst = Pt[j, i, c0:c1], Pt[i, j, c0:c1], Pb[t]
        for b in range(nb):
            dst[b] = 0.5 * (u[b] + v[b])
        if not q_zero:
            src, dst = Qt[j, i, c0:c1], Qb[t]
            for b in range(nb):
                dst[b] = src[b]


@njit(inline="always", **_JIT)
def _load_predicted(xt, Pt, il, Qt, q_zero, c0, nb, xb, Pb, iu, ju):
    """`_load` of the state after the time update ``P <- P * il + Q``, in one pass.

    The entries are those `bank_predict` then `_load` give, bit for bit:
    ``P[c, i, j] * il + Q[c, i, j]`` for each of the two triangles (``Q``
    as stored, ``il`` per channel), then their mean.
    """
    n = xt.shape[0]
    c1 = c0 + nb
    for i in range(n):
        src, dst = xt[i, c0:c1], xb[i]
        for b in range(nb):
            dst[b] = src[b]
    ilb = il[c0:c1]
    for t in range(iu.shape[0]):
        i, j = iu[t], ju[t]
        u, v, dst = Pt[j, i, c0:c1], Pt[i, j, c0:c1], Pb[t]
        if q_zero:
            for b in range(nb):
                dst[b] = 0.5 * (u[b] * ilb[b] + v[b] * ilb[b])
        else:
            qu, qv = Qt[j, i, c0:c1], Qt[i, j, c0:c1]
            for b in range(nb):
                dst[b] = 0.5 * ((u[b] * ilb[b] + qu[b]) + (v[b] * ilb[b] + qv[b]))


@njit(inline="always", **_JIT)
def _store(xb, Pb, xt, Pt, c0, nb, iu, ju):
    """``x[c], P[c]`` (both triangles) from the block, into the transposes
    ``xt`` (n, C) and ``Pt`` (n, n, C), as `_load` reads them."""
    n = xb.shape[0]
    c1 = c0 + nb
    for i in range(n):
        src, dst = xb[i], xt[i, c0:c1]
        for b in range(nb):
            dst[b] = src[b]
    for t in range(iu.shape[0]):
        i, j = iu[t], ju[t]
        src, u, v = Pb[t], Pt[j, i, c0:c1], Pt[i, j, c0:c1]
        for b in range(nb):
            u[b] = src[b]
            v[b] = src[b]


@njit(inline="always", **_JIT)
def _store_P(Pb, out, k, c0, nb, iu, ju):
    """``out[k, c] = P`` of each channel of the block."""
    n = out.shape[2]
    t = 0
    for i in range(n):
        for j in range(i, n):
            for b in range(nb):
                v = Pb[t, b]
                out[k, c0 + b, i, j] = v
                out[k, c0 + b, j, i] = v
            t += 1


# ----------------------------------------------------------------------
# the arithmetic of one step on a block
#
# Every inner loop runs over the channels of the block through 1-d views
# (``row = A[i]``; ``row[b]``): indexed so, numba's loops vectorize, where
# ``A[i, b]`` inside the loop kept LLVM from vectorizing some of them
# (measured: the state copy of `_load` ran 3.5x faster).
# ----------------------------------------------------------------------
@njit(inline="always", **_JIT)
def _predict(Pb, ilb, Qb, q_zero, nb):
    """Time update ``P <- P * il + Q``."""
    for t in range(Pb.shape[0]):
        p = Pb[t]
        if q_zero:
            for b in range(nb):
                p[b] = p[b] * ilb[b]
        else:
            q = Qb[t]
            for b in range(nb):
                p[b] = p[b] * ilb[b] + q[b]


@njit(inline="always", **_JIT)
def _read_step(Z, H, h_last, k, c0, nb, zb, h, fin):
    """Load step ``k`` of the block (``zb``, ``h``); return how many of its
    channels hold a value that is not finite (NaN: missing, or inf: an error).

    ``fin[b] = (z - z) + sum_j (h_j - h_j)`` is 0 for finite values and NaN
    otherwise: one pass over the loads, no branch in the channel loop, and
    an integer count (which vectorizes) decides the path of the whole block.
    """
    n = h.shape[0]
    c1 = c0 + nb
    src = Z[k, c0:c1]
    for b in range(nb):
        v = src[b]
        zb[b] = v
        fin[b] = v - v
    for j in range(n):
        dst = h[j]
        if h_last:                       # H is (N, n, C): contiguous loads
            src = H[k, j, c0:c1]
            for b in range(nb):
                v = src[b]
                dst[b] = v
                fin[b] += v - v
        else:                            # H is (N, C, n)
            src2 = H[k, c0:c1, j]
            for b in range(nb):
                v = src2[b]
                dst[b] = v
                fin[b] += v - v
    count = 0
    for b in range(nb):
        count += fin[b] != fin[b]
    return count


@njit(inline="always", **_JIT)
def _infinite(h, zb, flag, nb):
    """Whether a regressor or measurement of the block is infinite (``flag[b]``
    marks the channels); NaN (missing) is not."""
    n = h.shape[0]
    for b in range(nb):
        v = zb[b]
        flag[b] = v == v and v - v != 0.0
    for j in range(n):
        hj = h[j]
        for b in range(nb):
            v = hj[b]
            flag[b] = flag[b] or (v == v and v - v != 0.0)
    found = False
    for b in range(nb):
        found = found or flag[b]
    return found


@njit(inline="always", **_JIT)
def _gain_residual(xb, Pb, h, zb, rb, g, sb, yb, acc, nb, iu, ju, wq, qb):
    """``g = P h``, ``q = h . g`` (into ``qb``), ``s = w q + r`` and ``y = z - h . x`` of
    every lane (``w = wq``: ``1 / lam`` where the windup cap held the last time
    update's forgetting back, else 1, and ``1 * q`` is ``q``)."""
    n = xb.shape[0]
    for i in range(n):
        gi = g[i]
        for b in range(nb):
            gi[b] = 0.0
    # g = P h, g_i = sum_j P_ij h_j with j ascending: the packed rows in order,
    # row (i, j) (i <= j) adds P_ij h_j to g_i and P_ij h_i to g_j; each g_i
    # receives its terms in the order j = 0, 1, ..., n - 1, and each row of P
    # is read once
    for t in range(Pb.shape[0]):
        i, j = iu[t], ju[t]
        p, gi, hj = Pb[t], g[i], h[j]
        for b in range(nb):
            gi[b] += p[b] * hj[b]
        if i != j:
            gj, hi = g[j], h[i]
            for b in range(nb):
                gj[b] += p[b] * hi[b]
    for b in range(nb):
        acc[b] = 0.0
    for i in range(n):
        hi, gi = h[i], g[i]
        for b in range(nb):
            acc[b] += hi[b] * gi[b]
    for b in range(nb):
        qb[b] = acc[b]
        sb[b] = wq[b] * acc[b] + rb[b]                      # s = w h . g + r
        acc[b] = 0.0
    for i in range(n):
        hi, xi = h[i], xb[i]
        for b in range(nb):
            acc[b] += hi[b] * xi[b]
    for b in range(nb):
        yb[b] = zb[b] - acc[b]                              # y = z - h . x


@njit(inline="always", **_JIT)
def _measure(xb, Pb, h, zb, rb, hok, ok, g, sb, yb, acc, nb, iu, ju, wq, qb):
    """Validity, then `_gain_residual`.

    ``hok``: the regressor has no NaN (otherwise it is zeroed here, so that
    no NaN enters the arithmetic); ``ok``: ``hok`` and ``z`` is not NaN.
    """
    n = xb.shape[0]
    for b in range(nb):
        hok[b] = True
    for j in range(n):
        hj = h[j]
        for b in range(nb):
            hok[b] = hok[b] and hj[b] == hj[b]
    for b in range(nb):
        ok[b] = hok[b] and zb[b] == zb[b]
    for j in range(n):
        hj = h[j]
        for b in range(nb):
            hj[b] = hj[b] if hok[b] else 0.0
    _gain_residual(xb, Pb, h, zb, rb, g, sb, yb, acc, nb, iu, ju, wq, qb)


@njit(inline="always", **_JIT)
def _exponential_sweep(Pb, g, w, nb, iu, ju, fuse, ilb, Qb, q_zero):
    """``P = P - (g g^T) c`` over the packed triangle ``Pb`` (``c = w``, zero where a
    channel does not update); with `fuse` also the next time update ``P / lam (+ Q)``."""
    for t in range(Pb.shape[0]):
        p, gi, gj = Pb[t], g[iu[t]], g[ju[t]]
        if not fuse:
            for b in range(nb):                             # P = P - (g g^T) c
                p[b] = p[b] - (gi[b] * gj[b]) * w[b]
        elif q_zero:
            for b in range(nb):                             # ... then P = P / lam
                p[b] = (p[b] - (gi[b] * gj[b]) * w[b]) * ilb[b]
        else:
            q = Qb[t]
            for b in range(nb):                             # ... then P = P / lam + Q
                p[b] = (p[b] - (gi[b] * gj[b]) * w[b]) * ilb[b] + q[b]


@njit(inline="always", **_JIT)
def _exponential_coefficients(sb, qb, wq, ok, w, cub, nb):
    """The gain factor ``w[b] = wq c`` (0 where not `ok`) and the rank-one coefficient
    ``cub[b]`` of ``P <- P - (g g^T) cu`` of each lane, ``c = 1 / s``: those of
    ``_kernels.exponential_coefficient`` (``cu = c``, or 0 where not `ok`, unless the
    windup cap held the forgetting back, ``wq = 1 / lam``: then ``cu = wq^2 c - (wq - 1)
    / q``, or ``-(wq - 1) / q`` where not `ok`, the forgetting along the regressor)."""
    for b in range(nb):
        c = 1.0 / sb[b]                                     # c = 1 / s
        v = wq[b]
        if v == 1.0:
            cub[b] = c if ok[b] else 0.0
        else:
            q = qb[b]
            f = (v - 1.0) / q if q > 0.0 else 0.0
            cub[b] = v * v * c - f if ok[b] else -f
        w[b] = v * c if ok[b] else 0.0                      # K = g (w c)


@njit(inline="always", **_JIT)
def _cap_step(Pb, g, cub, h, qb, rb, w, wq, ok, ilb, p0, p1, capb, tfb, ncap, c0, nb, tri,
              tr, spread):
    """The windup cap of each lane after its exponential update (``_kernels.windup_cap``
    on the diagonal of the updated ``P``, ``P_ii - (g_i g_i) cu``, before the sweep
    writes it): ``capb``, the next time update's factor ``tfb`` (1 where held back,
    else ``1 / lam``) and the next update's ``wq`` (``1 / lam`` where held back, else
    1); ``ncap`` counts the updates that ran held back. ``p0``, ``p1`` are
    ``spread_max``, ``trace_max``; `w` the gain factors ``wq c``."""
    n = g.shape[0]
    for b in range(nb):                      # (tr, spread: work arrays of the block)
        tr[b] = 0.0
        spread[b] = 0.0
    for i in range(n):
        p, gi, hi = Pb[tri[i, i]], g[i], h[i]
        for b in range(nb):
            d = p[b] - (gi[b] * gi[b]) * cub[b]
            tr[b] += d
            spread[b] += (d * hi[b]) * hi[b]
    for b in range(nb):
        il = ilb[b]
        hph = qb[b] * rb[b] * w[b] if ok[b] else qb[b] * wq[b]   # h P h^T after the update
        if il == 1.0:
            cap = False
        elif tr[b] * il > p1[b]:
            cap = True
        else:
            cap = p0[b] < np.inf and spread[b] > p0[b] * hph
        ncap[c0 + b] += wq[b] != 1.0
        capb[b] = cap
        tfb[b] = 1.0 if cap else il
        wq[b] = il if cap else 1.0


@njit(inline="always", **_JIT)
def _update_exponential(xb, Pb, g, Kb, sb, yb, w, nb, iu, ju, fuse, ilb, Qb, q_zero, store_k):
    """The exponential measurement update of `_update` when every channel of the
    block updates: the same operations, no selects (``w`` holds the gain factors
    ``wq c`` of `_exponential_coefficients`; the sweep is the caller's). The gain
    is written to ``Kb`` only with `store_k` (the last step)."""
    n = xb.shape[0]
    for i in range(n):
        gi, xi = g[i], xb[i]
        if store_k:
            ki = Kb[i]
            for b in range(nb):
                k = gi[b] * w[b]                            # K = g c
                ki[b] = k
                xi[b] = xi[b] + k * yb[b]                   # x = x + K y
        else:
            for b in range(nb):
                xi[b] = xi[b] + (gi[b] * w[b]) * yb[b]


@njit(inline="always", **_JIT)
def _update(xb, Pb, g, Kb, sb, yb, rb, ok, lamb, p0, p1, mode, lt, w, d, nb, iu, ju,
            fuse, ilb, Qb, q_zero):
    """The measurement update of `mode`; channels not `ok` are unchanged.

    Writes ``x``, ``P``, the gain ``K`` (zero where not `ok`) and the
    forgetting factor ``lt`` the step applied (``lam`` in the exponential
    mode, whose forgetting is the time update; 1 where not `ok` in the
    others). With `fuse` (exponential mode only) the sweep over ``P`` also
    applies the next time update. ``w``, ``d`` are work arrays (one entry per channel).
    """
    n = xb.shape[0]
    nt = Pb.shape[0]
    if mode == EXPONENTIAL:             # (w: the gain factors of _exponential_coefficients)
        for b in range(nb):
            d[b] = yb[b] if ok[b] else 0.0
            lt[b] = lamb[b]
        for i in range(n):
            gi, ki, xi = g[i], Kb[i], xb[i]
            for b in range(nb):
                k = gi[b] * w[b]                            # K = g c
                ki[b] = k
                xi[b] = xi[b] + k * d[b]                    # x = x + K y
        return
    if mode == DIRECTIONAL:
        for b in range(nb):
            r = rb[b]
            rho = (sb[b] - r) / r                           # h P h^T / r
            lm = lamb[b]
            e = lm - (1.0 - lm) / rho if rho > p0[b] else 1.0
            dd = r * (1.0 + e * rho)
            lt[b] = e if ok[b] else 1.0
            w[b] = e / dd if ok[b] else 0.0                 # e / d
            d[b] = dd if ok[b] else np.inf                  # K = g / d (0 where not ok)
    else:                                                   # constant trace
        for b in range(nb):
            d[b] = sb[b] if ok[b] else np.inf               # K = g / s (0 where not ok)
    for i in range(n):
        gi, ki, xi = g[i], Kb[i], xb[i]
        for b in range(nb):
            k = gi[b] / d[b]
            ki[b] = k
            xi[b] = xi[b] + k * (yb[b] if ok[b] else 0.0)
    if mode == DIRECTIONAL:
        for t in range(nt):
            p, gi, gj = Pb[t], g[iu[t]], g[ju[t]]
            for b in range(nb):                             # P = P - (e / d) g g^T
                p[b] = p[b] - w[b] * (gi[b] * gj[b])
        return
    for t in range(nt):
        p, gi, gj = Pb[t], g[iu[t]], g[ju[t]]
        for b in range(nb):                                 # P_bar = P - g g^T / s
            p[b] = p[b] - (gi[b] * gj[b]) / d[b]
    for b in range(nb):
        w[b] = 0.0
    for i in range(n):
        p = Pb[(i * (2 * n - i + 1)) // 2]                  # packed index of (i, i)
        for b in range(nb):
            w[b] += p[b]                                    # t = trace(P_bar)
    for b in range(nb):
        trace, ratio = p0[b], p1[b]
        c2 = trace / (ratio + n)
        c1 = trace - n * c2
        lt[b] = w[b] / c1 if ok[b] else 1.0
        w[b] = c1 / w[b] if ok[b] else 1.0                  # c1 / t
        d[b] = c2 if ok[b] else 0.0
    for t in range(nt):
        p = Pb[t]
        for b in range(nb):                                 # P = (c1 / t) P_bar ...
            p[b] = w[b] * p[b]
    for i in range(n):
        p = Pb[(i * (2 * n - i + 1)) // 2]
        for b in range(nb):                                 # ... + c2 I
            p[b] = p[b] + d[b]


# ----------------------------------------------------------------------
# the health check of a block
# ----------------------------------------------------------------------
@njit(inline="always", **_JIT)
def _bound_healthy(W, X, tr, fin, acc, good, nb, cond_max):
    """``good[b]``: the cheap bound of ``_kernels_shared.unhealthy_sym`` proves
    channel ``b`` healthy.

    ``W[i, j, b]`` (``j >= i``) holds the upper triangle of ``A = (P +
    P^T) / 2`` and ``fin[b]`` the sum of ``0 * A_ij`` (0 when every entry
    is finite, else NaN). The operations are those of `unhealthy_sym`, one
    channel per lane: the Cholesky factor ``A = U^T U`` (in ``W``), then
    ``trace(A) ||U^-T||_F^2 < min(cond_max / 2, 1e12)`` (``X``: the rows
    of ``U^-T``). Where it holds `unhealthy_sym` returns False; elsewhere
    (no factor, a large bound, a non-finite entry) the caller asks
    `unhealthy` itself, so the decisions are the same, channel by channel.
    """
    n = W.shape[0]
    for b in range(nb):
        tr[b] = 0.0
        good[b] = fin[b] == 0.0
    for i in range(n):
        for b in range(nb):
            tr[b] += W[i, i, b]                             # trace(A)
    for k in range(n):                                      # W <- U, row by row
        for b in range(nb):
            d = W[k, k, b]
            good[b] = good[b] and d > 0.0
            u = np.sqrt(d)
            W[k, k, b] = u
            acc[b] = 1.0 / u
        for j in range(k + 1, n):
            for b in range(nb):
                W[k, j, b] = W[k, j, b] * acc[b]
        for i in range(k + 1, n):                           # trailing triangle -= u_k^T u_k
            for j in range(i, n):
                for b in range(nb):
                    W[i, j, b] = W[i, j, b] - W[k, i, b] * W[k, j, b]
    for b in range(nb):
        acc[b] = 0.0
    for i in range(n):                                      # ||U^-1||_F^2, rows of U^-T
        for j in range(i + 1):
            for b in range(nb):
                X[i, j, b] = 0.0
        for b in range(nb):
            X[i, i, b] = 1.0
        for k in range(i):                                  # X_i -= U_ki X_k
            for j in range(k + 1):
                for b in range(nb):
                    X[i, j, b] = X[i, j, b] - W[k, i, b] * X[k, j, b]
        for j in range(i + 1):
            for b in range(nb):
                v = X[i, j, b] * (1.0 / W[i, i, b])
                X[i, j, b] = v
                acc[b] += v * v
    limit = min(0.5 * cond_max, 1e12)
    for b in range(nb):
        good[b] = good[b] and tr[b] * acc[b] < limit


@njit(**_JIT)
def _check_block(Pb, nb, tri, cond_max, c0, k, k_fail, W, X, tr, fin, acc, good, T):
    """The periodic health check of a block's packed ``P`` (after step ``k``):
    ``k_fail[c0 + b] = k`` for each channel that fails it first.

    Most channels are proved healthy by `_bound_healthy`, all lanes at once;
    the others are decided by `unhealthy` on the channel's matrix."""
    n = W.shape[0]
    for b in range(nb):
        fin[b] = 0.0
    for i in range(n):
        for j in range(i, n):
            t = tri[i, j]
            for b in range(nb):
                v = Pb[t, b]
                a = 0.5 * (v + v)                           # A = (P + P^T) / 2
                W[i, j, b] = a
                fin[b] += 0.0 * a
    _bound_healthy(W, X, tr, fin, acc, good, nb, cond_max)
    for b in range(nb):
        if k_fail[c0 + b] < 0 and not good[b]:
            for i in range(n):
                for j in range(n):
                    T[i, j] = Pb[tri[i, j], b]
            if _unhealthy(T, cond_max):
                k_fail[c0 + b] = k


# ----------------------------------------------------------------------
# record kernels (batch_filter)
# ----------------------------------------------------------------------
@njit(**_JIT)
def _run_block(c0, nb, B, x, P, Z, H, h_last, Rv, il, lam, Q, q_zero, mode, params, update_first,
               means, covs, covs_p, ys, ss, x_prior, P_prior, x_post, P_post, K, lam_t,
               check_every, step0, cond_max, k_fail, k_inf, cap, wst, ncap):
    """Run the record on channels ``c0 .. c0 + nb - 1``, ``nb <= B`` (see `bank_batch`).

    Each step first loads the block's measurements and regressors and counts
    its non-finite values (`_read_step`). When there are none (the usual
    case) every channel updates, and the step runs without validity masks
    (`_gain_residual`, and `_update_exponential` in the exponential mode);
    otherwise infinities are reported and the masked path (`_measure`,
    `_update`) skips the channels with missing data. Both paths do the same
    operations on a channel that updates.
    """
    N = Z.shape[0]
    n = x.shape[0]
    iu, ju, tri = _triangle(n)
    nt = iu.shape[0]
    store_means = means.shape[0] == N
    store_covs = covs.shape[0] == N
    store_res = ys.shape[0] == N           # else only the last step's, in row 0
    r_each = Rv.shape[0] == N
    xb = np.empty((n, B))
    Pb = np.empty((nt, B))
    Qb = np.zeros((nt, B))
    _load(x, P, Q, q_zero, c0, nb, xb, Pb, Qb, iu, ju)
    ilb = np.ones(B)
    lamb = np.ones(B)
    p0 = np.zeros(B)
    p1 = np.zeros(B)
    rb = np.empty(B)
    expo = mode == EXPONENTIAL
    capb = np.zeros(B, dtype=np.bool_)     # the windup cap (exponential mode)
    tfb = np.ones(B)                       # the time update's factor: 1 / lam, or 1 (capped)
    wq = np.ones(B)                        # the next update's w: 1, or 1 / lam (capped)
    qb = np.zeros(B)
    cub = np.zeros(B)
    trw = np.empty(B)
    spw = np.empty(B)
    for b in range(nb):
        ilb[b] = il[c0 + b]
        lamb[b] = lam[c0 + b]
        p0[b] = params[c0 + b, 0]
        p1[b] = params[c0 + b, 1]
        rb[b] = Rv[0, c0 + b]
        capb[b] = cap[c0 + b] != 0.0
        tfb[b] = 1.0 if capb[b] else ilb[b]
        wq[b] = wst[c0 + b]
    lt = lamb.copy()
    g = np.empty((n, B))
    h = np.empty((n, B))
    Kb = np.zeros((n, B))
    zb = np.empty(B)
    ok = np.empty(B, dtype=np.bool_)
    hok = np.empty(B, dtype=np.bool_)
    every = np.ones(B, dtype=np.bool_)     # the validity of a step where all channels update
    sb = np.empty(B)
    yb = np.empty(B)
    w = np.empty(B)
    d = np.empty(B)
    fin = np.empty(B)
    nc = n if check_every > 0 else 0       # work space of the health check
    W = np.empty((nc, nc, B))
    X = np.empty((nc, nc, B))
    T = np.empty((n, n))
    predict = not q_zero                   # else the time update is the identity
    for b in range(nb):
        if ilb[b] != 1.0:
            predict = True
    # the time update before the first measurement update; later ones are
    # fused into the sweep of the measurement update when possible
    pending = predict and not update_first
    for k in range(N):
        last = k == N - 1
        if not update_first:
            if pending:
                _predict(Pb, tfb, Qb, q_zero, nb)
                if expo:
                    for b in range(nb):
                        wq[b] = ilb[b] if capb[b] else 1.0
            if store_covs:
                _store_P(Pb, covs_p, k, c0, nb, iu, ju)
            if last:
                _store(xb, Pb, x_prior, P_prior, c0, nb, iu, ju)
        if r_each:
            for b in range(nb):
                rb[b] = Rv[k, c0 + b]
        masked = _read_step(Z, H, h_last, k, c0, nb, zb, h, fin) > 0
        if masked and _infinite(h, zb, hok, nb):    # an error: stop the block, report where
            for b in range(nb):
                if hok[b]:
                    k_inf[c0 + b] = k
            return
        check = check_every > 0 and (step0 + k + 1) % check_every == 0
        # fuse the next time update into this sweep when nothing looks at P in between
        fuse = (mode == EXPONENTIAL and predict and not store_covs and not check
                and not last)
        if masked:                         # missing data: skip those channels
            _measure(xb, Pb, h, zb, rb, hok, ok, g, sb, yb, w, nb, iu, ju, wq, qb)
            if expo:
                _exponential_coefficients(sb, qb, wq, ok, w, cub, nb)
            _update(xb, Pb, g, Kb, sb, yb, rb, ok, lamb, p0, p1, mode, lt, w, d, nb, iu, ju,
                    fuse, ilb, Qb, q_zero)
        else:                              # every channel updates: no masks
            _gain_residual(xb, Pb, h, zb, rb, g, sb, yb, w, nb, iu, ju, wq, qb)
            if expo:
                _exponential_coefficients(sb, qb, wq, every, w, cub, nb)
                _update_exponential(xb, Pb, g, Kb, sb, yb, w, nb, iu, ju, fuse, ilb, Qb,
                                    q_zero, last)
            else:
                _update(xb, Pb, g, Kb, sb, yb, rb, every, lamb, p0, p1, mode, lt, w, d, nb,
                        iu, ju, fuse, ilb, Qb, q_zero)
        if expo:                           # the windup cap, then P - (g g^T) cu (/ lam + Q)
            _cap_step(Pb, g, cub, h, qb, rb, w, wq, ok if masked else every, ilb, p0, p1,
                      capb, tfb, ncap, c0, nb, tri, trw, spw)
            _exponential_sweep(Pb, g, cub, nb, iu, ju, fuse, tfb, Qb, q_zero)
        pending = predict and not fuse
        if store_res or last:
            row = k if store_res else 0
            if masked:
                for b in range(nb):
                    ys[row, c0 + b] = yb[b] if ok[b] else np.nan
                    ss[row, c0 + b] = sb[b] if hok[b] else np.nan
            else:
                for b in range(nb):
                    ys[row, c0 + b] = yb[b]
                    ss[row, c0 + b] = sb[b]
        if store_means:
            for b in range(nb):
                for i in range(n):
                    means[k, c0 + b, i] = xb[i, b]
        if store_covs:
            _store_P(Pb, covs, k, c0, nb, iu, ju)
        if last:
            _store(xb, Pb, x_post, P_post, c0, nb, iu, ju)
        if update_first:
            if pending:
                _predict(Pb, tfb, Qb, q_zero, nb)
            pending = False
            if store_covs:
                _store_P(Pb, covs_p, k, c0, nb, iu, ju)
            if last:
                _store(xb, Pb, x_prior, P_prior, c0, nb, iu, ju)
        if check:                          # the periodic health check of each channel's P
            _check_block(Pb, nb, tri, cond_max, c0, k, k_fail, W, X, w, fin, d, hok, T)
    _store(xb, Pb, x, P, c0, nb, iu, ju)
    for b in range(nb):
        lam_t[c0 + b] = lt[b]
        cap[c0 + b] = 1.0 if capb[b] else 0.0
        # the next update's w: after a time update (update_first) as the cap left it
        wst[c0 + b] = wq[b] if update_first else 1.0
    for i in range(n):
        for b in range(nb):
            K[i, c0 + b] = Kb[i, b]


@njit(**_JIT)
def bank_batch(x, P, Z, H, h_last, Rv, il, lam, Q, q_zero, mode, params, update_first,
               means, covs, covs_p, ys, ss, x_prior, P_prior, x_post, P_post, K, lam_t,
               check_every, step0, cond_max, k_fail, k_inf, cap, wst, ncap, block):
    """Run the recursion of every channel over a record, one block after another.

    Parameters
    ----------
    x : (n, C), P : (n, n, C)
        Working state, overwritten with the final state, stored as the
        transposes of the bank's ``x`` (C, n) and ``P`` (C, n, n) (see
        `_load`; so are ``Q``, ``x_prior``, ``P_prior``, ``x_post``,
        ``P_post`` and ``K``).
    Z : (N, C), H : (N, C, n), or (N, n, C) with `h_last`
        Measurements and regressors (NaN marks a missing sample of a
        channel). With `h_last` the channel index of ``H`` is last, so that
        the loads of a block's regressors are contiguous (`fit_many` builds
        its regressors that way).
    Rv : (N, C) or (1, C)
        Noise variances per step, or one per channel for every step.
    il, lam : (C,)
        ``1 / lam`` applied by the time update (1 except in the exponential
        mode) and the forgetting factors.
    Q : (n, n, C), q_zero : bool
        Random walks (ignored, and may be (n, n, 1), when `q_zero`).
    mode : int, params : (C, 2)
        Mode code and its constants (directional: ``eps``; constant trace:
        ``trace``, ``ratio``).
    update_first : bool
        Update before predict in each step.
    means : (N, C, n) or (0, C, n); covs, covs_p : (N, C, n, n) or (0, C, n, n)
        Estimates after each update and covariances after each update and
        each predict, written when their length is N.
    ys, ss : (N, C), or (1, C)
        A-priori residuals (NaN where skipped) and innovation variances
        (NaN where the regressor holds NaN) of every step, or (one row)
        of the last step only.
    x_prior, P_prior, x_post, P_post : like x and P
        The last step's prior and posterior (written when N > 0).
    K : (n, C), lam_t : (C,)
        The last step's gain (zero where skipped) and forgetting factor.
    check_every, step0, cond_max, k_fail : int, int, float, (C,) int64
        The health check of each channel's P after step ``k`` when
        ``(step0 + k + 1) % check_every == 0``; the first failing step of
        channel ``c`` is written to ``k_fail[c]`` if that is still -1.
    k_inf : (C,) int64
        Set to the step at which channel ``c`` has an infinite regressor or
        measurement (an error: the block of that channel stops there, and
        the caller discards the results).
    block : int
        Channels per block (`block_size`).
    """
    C = x.shape[1]
    for blk in range((C + block - 1) // block):
        c0 = blk * block
        _run_block(c0, min(block, C - c0), block, x, P, Z, H, h_last, Rv, il, lam, Q, q_zero,
                   mode, params, update_first, means, covs, covs_p, ys, ss, x_prior, P_prior,
                   x_post, P_post, K, lam_t, check_every, step0, cond_max, k_fail, k_inf,
                   cap, wst, ncap)


@njit(parallel=True, **_JIT)
def bank_batch_parallel(x, P, Z, H, h_last, Rv, il, lam, Q, q_zero, mode, params,
                        update_first, means, covs, covs_p, ys, ss, x_prior, P_prior, x_post,
                        P_post, K, lam_t, check_every, step0, cond_max, k_fail, k_inf, cap,
                        wst, ncap, block):
    """`bank_batch` with the blocks distributed over numba's threads (``prange``)."""
    C = x.shape[1]
    for blk in prange((C + block - 1) // block):
        c0 = blk * block
        _run_block(c0, min(block, C - c0), block, x, P, Z, H, h_last, Rv, il, lam, Q, q_zero,
                   mode, params, update_first, means, covs, covs_p, ys, ss, x_prior, P_prior,
                   x_post, P_post, K, lam_t, check_every, step0, cond_max, k_fail, k_inf,
                   cap, wst, ncap)


# ----------------------------------------------------------------------
# streaming kernels (predict, update) and the health check
# ----------------------------------------------------------------------
STREAM_BLOCK = 128    # channels per block of `bank_update` (its work arrays stay in L1)


@njit(**_JIT)
def bank_predict(Pt, il, Qt, q_zero, Pn, P_prior):
    """``Pn = P * il + Q`` for every channel (``Q`` ignored when `q_zero`), and
    the same values in `P_prior`. All in the bank's layout ``(n, n, C)``
    (`_load`): each loop runs over the channels, contiguous."""
    n, C = Pt.shape[0], Pt.shape[2]
    nn = n * n
    Pf, Nf, Af = Pt.reshape((nn, C)), Pn.reshape((nn, C)), P_prior.reshape((nn, C))
    for e in range(nn):
        p, pn, pa = Pf[e], Nf[e], Af[e]
        if q_zero:
            for c in range(C):
                v = p[c] * il[c]
                pn[c] = v
                pa[c] = v
        else:
            q = Qt.reshape((nn, C))[e]
            for c in range(C):
                v = p[c] * il[c] + q[c]
                pn[c] = v
                pa[c] = v


@njit(**_JIT)
def bank_update(xt, Pt, z, H, r, lam, mode, params, pending, il, Qt, q_zero, xn, Pn, y, S,
                SI, K, lam_t, wst, cap, ncap):
    """One measurement update of every channel: the arithmetic of `bank_batch`.

    Reads the state ``xt`` (n, C), ``Pt`` (n, n, C) (the bank's layout, see
    `_load`), ``z`` (C,), ``H`` (C, n), ``r`` (C,). With `pending` the time
    update ``P <- P * il + Q`` (``Qt`` (n, n, C), ignored when `q_zero`)
    of a deferred `bank_predict` is applied first, as the block is loaded
    (`_load_predicted`: the same bits as `bank_predict` then this kernel).
    Writes the new state ``xn``, ``Pn`` (same layout),
    the residuals ``y`` (NaN where skipped), ``S`` and ``SI = 1 / S`` (NaN
    where the regressor holds NaN), the gains ``K`` (n, C; zero where
    skipped) and ``lam_t``; `STREAM_BLOCK` channels at a time. The exponential
    mode's windup cap: ``wst`` (C,) the update's ``w`` (``1 / lam`` where the
    time update held the forgetting back, else 1), ``cap`` (C,) receives the
    cap's decision for the next time update (1.0 or 0.0), ``ncap`` counts the
    updates that ran held back.

    Returns
    -------
    int
        The number of channels whose new ``P`` has a diagonal entry that is
        not positive and finite (the cheap health check), or ``-1 - c`` when
        channel ``c`` (the first) has an infinite measurement or regressor
        (an error: the outputs are then incomplete).
    """
    n, C = xt.shape
    B = STREAM_BLOCK
    iu, ju, tri = _triangle(n)
    nt = iu.shape[0]
    xb = np.empty((n, B))
    Pb = np.empty((nt, B))
    Qb = np.empty((1, 1))
    h = np.empty((n, B))
    g = np.empty((n, B))
    Kb = np.zeros((n, B))
    zb = np.empty(B)
    rb = np.empty(B)
    ok = np.empty(B, dtype=np.bool_)
    hok = np.empty(B, dtype=np.bool_)
    every = np.ones(B, dtype=np.bool_)
    sb = np.empty(B)
    yb = np.empty(B)
    w = np.empty(B)
    d = np.empty(B)
    fin = np.empty(B)
    lamb = np.ones(B)
    lt = np.empty(B)
    p0 = np.zeros(B)
    p1 = np.zeros(B)
    expo = mode == EXPONENTIAL
    capb = np.zeros(B, dtype=np.bool_)
    tfb = np.ones(B)
    ilx = np.ones(B)
    wq = np.ones(B)
    qb = np.zeros(B)
    cub = np.zeros(B)
    trw = np.empty(B)
    spw = np.empty(B)
    bad = 0
    for c0 in range(0, C, B):
        nb = min(B, C - c0)
        c1 = c0 + nb
        if pending:
            _load_predicted(xt, Pt, il, Qt, q_zero, c0, nb, xb, Pb, iu, ju)
        else:
            _load(xt, Pt, Pt, True, c0, nb, xb, Pb, Qb, iu, ju)
        for j in range(n):                   # the regressors, one row per channel
            src, dst = H[c0:c1, j], h[j]
            for b in range(nb):
                dst[b] = src[b]
        zs, rs, ls = z[c0:c1], r[c0:c1], lam[c0:c1]
        for b in range(nb):
            zb[b] = zs[b]
            rb[b] = rs[b]
            lamb[b] = ls[b]
            ilx[b] = 1.0 / ls[b] if expo else 1.0     # (the bank's il, bit for bit)
            wq[b] = wst[c0 + b]
            p0[b] = params[c0 + b, 0]
            p1[b] = params[c0 + b, 1]
        for b in range(nb):                  # the finiteness of the block's inputs
            fin[b] = zb[b] - zb[b]
        for j in range(n):
            for b in range(nb):
                fin[b] += h[j, b] - h[j, b]
        count = 0
        for b in range(nb):
            count += fin[b] != fin[b]
        if count:
            if _infinite(h, zb, hok, nb):
                for b in range(nb):
                    if hok[b]:
                        return -1 - (c0 + b)
            _measure(xb, Pb, h, zb, rb, hok, ok, g, sb, yb, w, nb, iu, ju, wq, qb)
            if expo:
                _exponential_coefficients(sb, qb, wq, ok, w, cub, nb)
            _update(xb, Pb, g, Kb, sb, yb, rb, ok, lamb, p0, p1, mode, lt, w, d, nb, iu, ju,
                    False, lamb, Qb, True)
            if expo:
                _cap_step(Pb, g, cub, h, qb, rb, w, wq, ok, ilx, p0, p1, capb, tfb, ncap, c0,
                          nb, tri, trw, spw)
                _exponential_sweep(Pb, g, cub, nb, iu, ju, False, tfb, Qb, True)
            for b in range(nb):
                yb[b] = yb[b] if ok[b] else np.nan
                sb[b] = sb[b] if hok[b] else np.nan
        else:
            _gain_residual(xb, Pb, h, zb, rb, g, sb, yb, w, nb, iu, ju, wq, qb)
            if expo:
                _exponential_coefficients(sb, qb, wq, every, w, cub, nb)
                _update_exponential(xb, Pb, g, Kb, sb, yb, w, nb, iu, ju, False, lamb, Qb,
                                    True, True)
                _cap_step(Pb, g, cub, h, qb, rb, w, wq, every, ilx, p0, p1, capb, tfb, ncap,
                          c0, nb, tri, trw, spw)
                _exponential_sweep(Pb, g, cub, nb, iu, ju, False, tfb, Qb, True)
                for b in range(nb):
                    lt[b] = lamb[b]
            else:
                _update(xb, Pb, g, Kb, sb, yb, rb, every, lamb, p0, p1, mode, lt, w, d, nb,
                        iu, ju, False, lamb, Qb, True)
        for b in range(nb):
            cap[c0 + b] = 1.0 if expo and capb[b] else 0.0
        for b in range(nb):                  # the cheap health check: the diagonal
            fin[b] = 0.0
        for i in range(n):
            t = tri[i, i]
            for b in range(nb):
                v = Pb[t, b]
                fin[b] += 0.0 if v > 0.0 and v != np.inf else 1.0
        for b in range(nb):
            bad += fin[b] > 0.0
        _store(xb, Pb, xn, Pn, c0, nb, iu, ju)
        for i in range(n):
            src, dst = Kb[i], K[i, c0:c1]
            for b in range(nb):
                dst[b] = src[b]
        ys, ss, si, lts = y[c0:c1], S[c0:c1], SI[c0:c1], lam_t[c0:c1]
        for b in range(nb):
            ys[b] = yb[b]
            ss[b] = sb[b]
            si[b] = 1.0 / sb[b]
            lts[b] = lt[b]
    return bad


@njit(**_JIT)
def bank_unhealthy(Pt, cond_max, bad):
    """``bad[c]``: channel ``c``'s ``P`` fails the health check of
    `RecursiveLeastSquares` (``_kernels_shared.unhealthy``).

    ``Pt`` is in the bank's layout (n, n, C) (`_load`). Blocks of channels
    whose ``P`` is exactly symmetric are proved healthy by `_bound_healthy`
    all at once; `unhealthy` decides the others.
    """
    n, C = Pt.shape[0], Pt.shape[2]
    B = 64
    W = np.empty((n, n, B))
    X = np.empty((n, n, B))
    T = np.empty((n, n))
    tr = np.empty(B)
    fin = np.empty(B)
    acc = np.empty(B)
    good = np.empty(B, dtype=np.bool_)
    for c0 in range(0, C, B):
        nb = min(B, C - c0)
        for b in range(nb):
            fin[b] = 0.0
        for i in range(n):
            for j in range(i, n):
                for b in range(nb):
                    u = Pt[j, i, c0 + b]                    # P[c, i, j]
                    v = Pt[i, j, c0 + b]                    # P[c, j, i]
                    a = 0.5 * (u + v)                       # A = (P + P^T) / 2
                    W[i, j, b] = a
                    # 0 when finite; NaN (the exact test decides) when not, or when
                    # P is not exactly symmetric
                    fin[b] += 0.0 * a + (0.0 if u == v else np.nan)
        _bound_healthy(W, X, tr, fin, acc, good, nb, cond_max)
        for b in range(nb):
            if good[b]:
                bad[c0 + b] = False
            else:
                for i in range(n):
                    for j in range(n):
                        T[i, j] = Pt[j, i, c0 + b]
                bad[c0 + b] = _unhealthy(T, cond_max)


@njit(**_JIT)
def bank_residuals(xt, Pt, z, H, r, y, S, SI):
    """The diagnostics of a measurement update without the update (a frozen bank):
    ``y = z - h . x`` (NaN where ``z`` or the regressor holds NaN), ``S = h . (P h)
    + r`` (NaN where the regressor holds NaN) and ``SI = 1 / S`` of every channel,
    with the sums in the order of `_gain_residual` (``g_i = sum_j P_ij h_j``, ``j``
    ascending; ``h . g`` and ``h . x`` over ``i`` ascending). ``xt`` (n, C) and
    ``Pt`` (n, n, C) in the bank's layout are only read."""
    n, C = xt.shape
    g = np.empty(n)
    for c in range(C):
        hok = True
        for j in range(n):
            hok = hok and H[c, j] == H[c, j]
        if not hok:
            y[c] = np.nan
            S[c] = np.nan
            SI[c] = np.nan
            continue
        for i in range(n):                   # g = P h
            acc = 0.0
            for j in range(n):
                acc += Pt[j, i, c] * H[c, j]
            g[i] = acc
        acc = 0.0
        for i in range(n):                   # s = h . g + r
            acc += H[c, i] * g[i]
        S[c] = acc + r[c]
        SI[c] = 1.0 / S[c]
        acc = 0.0
        for i in range(n):                   # y = z - h . x
            acc += H[c, i] * xt[i, c]
        y[c] = z[c] - acc
