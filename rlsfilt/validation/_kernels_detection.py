"""Compiled (numba) step of `BankChangeDetector`: one detector per channel of a bank.

One call feeds one innovation per channel. The arithmetic of each channel is
that of `ChangeDetector`, operation by operation, so the alarms and the
statistics are the same bits (``tests/test_bank_detection.py``):

    e = y / sqrt(S)                        (a NaN y: the channel is skipped)
    CUSUM:         g+ = max(0, g+ + e - k),  g- = max(0, g- - e - k)
    Page-Hinkley:  n += 1, m += (e - m) / n, e <- e - m, then the CUSUM
    GLR:           s = 0; for the last L = 1 .. M samples, newest first:
                   s += e_(k-L+1), g = s * s * (1 / (2 L)) -> g+ (s > 0) or g- (s <= 0)

Layout: the channel index is last in ``fstate`` ``(4, C)`` (``g+, g-``,
running mean and count), ``bounds`` ``(2, K, C)`` (see below) and ``istate``
``(3, C)`` (samples seen, newest slot of the GLR ring, samples in the GLR
window), so the loops over the channels vectorize; the GLR ring ``recent`` is
``(M, C)``, slot-major: channels that advance together (no missing sample)
write one contiguous row per step, a few cache lines instead of one line per
channel (the window is read, cyclically, only by a scan).

**The GLR's exact pruning.** Scanning the ``M`` windows of every channel at
every step costs ``O(C M)``. The test only needs to know whether some window
crosses, :math:`|S_L| > b \\sqrt{L}` (:math:`b = \\sqrt{2h}`, :math:`L` the
window length). On each piece :math:`[L_1, L_2]` of the window lengths
(:math:`1, 4, 16, \\dots, M`) the concave :math:`b \\sqrt{L}` lies above its
chord :math:`\\alpha + \\beta L`, so a crossing in the piece makes
:math:`S_L - \\beta L > \\alpha`, hence the CUSUM with drift :math:`\\beta`,
:math:`W = \\max(0, W + e - \\beta)` (the largest :math:`S_L - \\beta L` over
all windows since the last alarm), exceed :math:`\\alpha`. The kernel runs one
such CUSUM per piece and sign (``bounds``; chords of a ``b``
smaller by 1e-7 relative, so rounding cannot hide a crossing) and scans only
the channels where one exceeds its :math:`\\alpha`; the decision is the same as
scanning all (tested). The statistics themselves (``g+``, ``g-``) are computed
from the ring when they are read (`glr_statistics`).
"""

import math

import numpy as np

from .._numba import njit

__all__ = []

CUSUM, PAGE_HINKLEY, GLR = 0, 1, 2
# NumPy's error model (a division by zero gives inf or NaN, no check): the loops vectorize
_JIT = {"cache": True, "error_model": "numpy"}
_RATIO = 4          # the pieces of the window lengths: [1, 4], [4, 16], ... (see above)


def glr_pieces(threshold, window):
    """``(2, K)``: the chords ``alpha`` (row 0) and ``beta`` (row 1) of ``b sqrt(L)``
    on the pieces ``[1, 4], [4, 16], ..., [4^j, window]`` of the window lengths."""
    b = math.sqrt(2.0 * threshold) * (1.0 - 1e-7)
    edges = [1]
    while edges[-1] * _RATIO < window:
        edges.append(edges[-1] * _RATIO)
    edges.append(window)
    out = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        beta = b * (math.sqrt(hi) - math.sqrt(lo)) / (hi - lo) if hi > lo else 0.0
        out.append((b * math.sqrt(lo) - beta * lo, beta))
    if not out:                                          # window == 1
        out.append((b, 0.0))
    return np.ascontiguousarray(np.array(out).T)


@njit(**_JIT)
def _scan(recent, c, top, n, half_inverse):
    """``(g+, g-)`` of channel ``c``'s GLR window: its ``n`` newest values, the
    newest in slot ``top`` of the ring (older ones in the slots before it, cyclically)."""
    M = recent.shape[0]
    gp = 0.0
    gm = 0.0
    s = 0.0
    slot = top
    for L in range(n):                                   # windows of L + 1 samples
        s += recent[slot, c]
        slot = slot - 1 if slot > 0 else M - 1
        g = s * s * half_inverse[L]
        if s > 0.0:
            if g > gp:
                gp = g
        elif g > gm:
            gm = g
    return gp, gm


@njit(**_JIT)
def glr_statistics(istate, recent, consts, out):
    """``out[0], out[1]`` (each ``(C,)``): the GLR's ``g+`` and ``g-`` of every channel."""
    half_inverse = consts[4 + 2 * int(consts[3]):]
    for c in range(istate.shape[1]):
        gp, gm = _scan(recent, c, istate[1, c], istate[2, c], half_inverse)
        out[0, c] = gp
        out[1, c] = gm


def constants(method, drift, threshold, window):
    """The constants of `bank_detect` in one array (one argument less to unbox per
    call): ``[method code, drift, threshold, K, alpha (K), beta (K), 1 / (2 L) for
    L = 1 .. window]``, with the GLR's ``K`` pieces (`glr_pieces`; none otherwise)."""
    pieces = glr_pieces(threshold, window) if method == GLR else np.zeros((2, 0))
    return np.concatenate([[method, drift, threshold, pieces.shape[1]], pieces[0], pieces[1],
                           0.5 / np.arange(1.0, window + 1.0)])


@njit(**_JIT)
def bank_detect(y, S, consts, fstate, istate, recent, bounds, alarm):
    """Feed ``y / sqrt(S)`` of every channel (``consts`` from `constants`); set
    ``alarm[c]`` and restart the alarmed channels' statistics. Returns the number
    of alarms, or ``-(c + 1)`` for the first channel ``c`` whose ``S`` is not a
    positive finite number where its ``y`` is not NaN
    (then nothing has changed)."""
    C = y.shape[0]
    method = int(consts[0])
    drift = consts[1]
    threshold = consts[2]
    # (loops without early exits or branches on the data: LLVM vectorizes them)
    n_bad = 0
    e = np.empty(C)
    for c in range(C):
        n_bad += (y[c] == y[c]) & ~((S[c] > 0.0) & (S[c] < math.inf))
        e[c] = y[c] / math.sqrt(S[c])                    # NaN where y is NaN
    if n_bad:                                            # (nothing changed yet)
        for c in range(C):
            if y[c] == y[c] and not (S[c] > 0.0 and S[c] < math.inf):
                return -(c + 1)
    n_alarms = 0
    if method == GLR:
        M = recent.shape[0]
        for c in range(C):                               # (branch-free: vectorizes)
            alarm[c] = False
            valid = e[c] == e[c]
            istate[0, c] += valid
            pos = istate[1, c] + valid                   # the newest slot of the ring
            istate[1, c] = 0 if pos == M else pos
            istate[2, c] += valid & (istate[2, c] < M)
        for c in range(C):                               # the ring: slot-major, so the
            if e[c] == e[c]:                             # channels in step write one row
                recent[istate[1, c], c] = e[c]
        K = int(consts[3])
        half_inverse = consts[4 + 2 * K:]
        flag = np.zeros(C, dtype=np.bool_)
        for i in range(K):                               # the CUSUM bound of each piece
            a = consts[4 + i]
            bt = consts[4 + K + i]
            for c in range(C):
                ec = e[c]
                valid = ec == ec
                wp = bounds[0, i, c] + ec - bt
                wm = bounds[1, i, c] - ec - bt
                wp = wp if wp > 0.0 else 0.0
                wm = wm if wm > 0.0 else 0.0
                wp = wp if valid else bounds[0, i, c]
                wm = wm if valid else bounds[1, i, c]
                bounds[0, i, c] = wp
                bounds[1, i, c] = wm
                flag[c] = flag[c] | (wp > a) | (wm > a)
        for c in range(C):
            if not flag[c] or e[c] != e[c]:
                continue
            gp, gm = _scan(recent, c, istate[1, c], istate[2, c], half_inverse)
            if gp > threshold or gm > threshold:
                alarm[c] = True
                n_alarms += 1
                istate[2, c] = 0
                for i in range(K):
                    bounds[0, i, c] = 0.0
                    bounds[1, i, c] = 0.0
        return n_alarms
    if method == PAGE_HINKLEY:
        for c in range(C):
            ec = e[c]
            valid = ec == ec
            count = fstate[3, c] + 1.0
            mean = fstate[2, c] + (ec - fstate[2, c]) / count
            fstate[2, c] = mean if valid else fstate[2, c]
            fstate[3, c] = count if valid else fstate[3, c]
            e[c] = ec - mean                             # (NaN stays NaN)
    for c in range(C):
        ec = e[c]
        valid = ec == ec
        gp = fstate[0, c] + ec - drift                   # g+ = max(0, g+ + e - k)
        gm = fstate[1, c] - ec - drift                   # g- = max(0, g- - e - k)
        gp = gp if gp > 0.0 else 0.0
        gm = gm if gm > 0.0 else 0.0
        hit = valid & ((gp > threshold) | (gm > threshold))
        n_alarms += hit
        alarm[c] = hit
        istate[0, c] += valid
        fstate[0, c] = 0.0 if hit else (gp if valid else fstate[0, c])
        fstate[1, c] = 0.0 if hit else (gm if valid else fstate[1, c])
        fstate[2, c] = 0.0 if hit else fstate[2, c]
        fstate[3, c] = 0.0 if hit else fstate[3, c]
    return n_alarms
