"""Compiled (numba) step of `BankChangeDetector`: one detector per channel of a bank.

One call feeds one innovation per channel. The arithmetic of each channel is
that of `ChangeDetector`, operation by operation, so the alarms and the
statistics are the same bits (``tests/test_bank_detection.py``):

    e = y / sqrt(S)                        (a NaN y: the channel is skipped)
    CUSUM:         g+ = max(0, g+ + e - k),  g- = max(0, g- - e - k)
    Page-Hinkley:  n += 1, m += (e - m) / n, e <- e - m, then the CUSUM
    GLR:           s = 0; for the last L = 1 .. M samples, newest first:
                   s += e_(k-L+1), g = s * s * (1 / (2 L)) -> g+ (s > 0) or g- (s <= 0)

The state is packed in two arrays (one numba call with few arguments is
the whole cost of a step at a thousand channels): ``fstate[c]`` holds
``(g+, g-, running mean, running count)``, ``istate[c]`` ``(samples seen,
newest slot of the GLR ring, samples in the GLR window)``; ``recent[c]`` is
the GLR's ring of the last ``M`` normalized innovations.
"""

import math

from .._numba import njit

__all__ = []

CUSUM, PAGE_HINKLEY, GLR = 0, 1, 2


@njit(cache=True)
def bank_detect(y, S, method, drift, threshold, fstate, istate, recent, half_inverse,
                alarm):
    """Feed ``y / sqrt(S)`` of every channel; set ``alarm[c]`` and restart the alarmed
    channels' statistics. Returns the number of alarms, or ``-(c + 1)`` for the first
    channel ``c`` whose ``S`` is not a positive finite number where its ``y`` is not
    NaN (then nothing has changed)."""
    C = y.shape[0]
    M = recent.shape[1]
    for c in range(C):
        if y[c] == y[c] and not (S[c] > 0.0 and S[c] < math.inf):
            return -(c + 1)
    n_alarms = 0
    for c in range(C):
        alarm[c] = False
        if y[c] != y[c]:
            continue
        e = y[c] / math.sqrt(S[c])
        istate[c, 0] += 1
        if method == GLR:
            pos = istate[c, 1] + 1                       # the newest slot of the ring
            if pos == M:
                pos = 0
            istate[c, 1] = pos
            recent[c, pos] = e
            n = istate[c, 2] + 1
            if n > M:
                n = M
            istate[c, 2] = n
            gp = 0.0
            gm = 0.0
            s = 0.0
            i = pos
            for L in range(n):                           # windows of L + 1 samples
                s += recent[c, i]
                g = s * s * half_inverse[L]
                if s > 0.0:
                    if g > gp:
                        gp = g
                elif g > gm:
                    gm = g
                i -= 1
                if i < 0:
                    i = M - 1
        else:
            if method == PAGE_HINKLEY:
                count = fstate[c, 3] + 1.0
                mean = fstate[c, 2] + (e - fstate[c, 2]) / count
                fstate[c, 2] = mean
                fstate[c, 3] = count
                e = e - mean
            gp = max(0.0, fstate[c, 0] + e - drift)
            gm = max(0.0, fstate[c, 1] - e - drift)
        if gp > threshold or gm > threshold:
            alarm[c] = True
            n_alarms += 1
            fstate[c, 0] = 0.0
            fstate[c, 1] = 0.0
            fstate[c, 2] = 0.0
            fstate[c, 3] = 0.0
            istate[c, 2] = 0
        else:
            fstate[c, 0] = gp
            fstate[c, 1] = gm
    return n_alarms
