"""Compiled (numba) helpers of `fit_many`: statistics of many fitted ARX models."""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable

__all__ = []


@njit(cache=True)
def fleet_statistics(Phi, target, theta, na, Y, resid, sigma2, pred_fit, sim_fit):
    r"""Residuals, noise variances and fit percentages of many fitted ARX models.

    For each channel ``c`` (one output), with the regressors ``Phi`` (rows,
    n, C: the channel index last) of the rows ``t = start .. N - 1``
    (``start = N - rows``), the
    targets ``target`` (rows, C), the parameters ``theta`` (C, n) (the first
    `na` the coefficients of :math:`A(q)` after its leading 1) and the
    record ``Y`` (N, C):

    * ``resid[t, c] = target - Phi theta`` (rows, C) and ``sigma2[c] =
      sum resid^2 / (rows - n)`` (NaN without spare rows);
    * ``pred_fit[c]``: `fit_percent` of the one-step prediction ``Phi theta``;
    * ``sim_fit[c]``: `fit_percent` of the free-run simulation started from
      the measured ``Y[:start]`` (the simulation of ``validate``):
      :math:`y_s(t) = B(q) u(t) - \sum_k a_k y_s(t - k)`, where the input
      part :math:`B(q) u(t)` is the ``u`` block of ``Phi`` times its
      parameters;

    (NaN fits for a constant target). Every sum runs over time in order,
    channel by channel, with the channels in the inner loop: a channel's
    numbers do not depend on the other channels.
    """
    rows, n, C = Phi.shape
    N = Y.shape[0]
    start = N - rows
    ysim = np.empty((N, C))
    mean = np.zeros(C)
    ss_pred = np.zeros(C)
    ss_sim = np.zeros(C)
    ss_dev = np.zeros(C)
    ar = np.empty(C)
    bu = np.empty(C)
    for t in range(start):
        for c in range(C):
            ysim[t, c] = Y[t, c]
    # every loop over the channels is innermost (contiguous, vectorized); each
    # channel's sums still run over p and t in the same order as before
    for k in range(rows):
        t = start + k
        for c in range(C):
            ar[c] = 0.0
            bu[c] = 0.0
        for p in range(na):
            for c in range(C):
                ar[c] += Phi[k, p, c] * theta[c, p]
        for p in range(na, n):
            for c in range(C):
                bu[c] += Phi[k, p, c] * theta[c, p]
        for c in range(C):
            yk = target[k, c]
            r = yk - (ar[c] + bu[c])                  # y - Phi theta
            resid[k, c] = r
            ss_pred[c] += r * r
            mean[c] += yk
        for c in range(C):
            ysim[t, c] = bu[c]
        for p in range(1, na + 1):
            for c in range(C):
                ysim[t, c] -= theta[c, p - 1] * ysim[t - p, c]
        for c in range(C):
            e = target[k, c] - ysim[t, c]
            ss_sim[c] += e * e
    for c in range(C):
        mean[c] /= rows
    for k in range(rows):
        for c in range(C):
            d = target[k, c] - mean[c]
            ss_dev[c] += d * d
    dof = rows - n
    for c in range(C):
        sigma2[c] = ss_pred[c] / dof if dof > 0 else np.nan
        den = np.sqrt(ss_dev[c])
        if den > 0.0:
            pred_fit[c] = 100.0 * (1.0 - np.sqrt(ss_pred[c]) / den)
            sim_fit[c] = 100.0 * (1.0 - np.sqrt(ss_sim[c]) / den)
        else:
            pred_fit[c] = np.nan
            sim_fit[c] = np.nan


@njit(cache=True)
def record_sums(Y, U, out):
    """``out[0, c] = sum_t Y[t, c]``, ``out[1, c] = sum_t sum_j U[t, c, j]``, summed in
    time order (so a channel's sums do not depend on the other channels)."""
    N, C = Y.shape
    for c in range(C):
        out[0, c] = 0.0
        out[1, c] = 0.0
    for t in range(N):
        for c in range(C):
            out[0, c] += Y[t, c]
            acc = 0.0
            for j in range(U.shape[2]):
                acc += U[t, c, j]
            out[1, c] += acc


@njit(cache=True)
def column_norms(Phi, out):
    """``out[c, p] = sqrt(sum_t Phi[t, p, c]^2)`` (``Phi`` is (rows, n, C)), summed in
    time order."""
    rows, n, C = Phi.shape
    for c in range(C):
        for p in range(n):
            out[c, p] = 0.0
    for t in range(rows):
        for p in range(n):
            for c in range(C):
                v = Phi[t, p, c]
                out[c, p] += v * v
    for c in range(C):
        for p in range(n):
            out[c, p] = np.sqrt(out[c, p])
