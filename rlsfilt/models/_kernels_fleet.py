"""Compiled (numba) helpers of `fit_many`: statistics of many fitted ARX models."""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable

__all__ = []


@njit(cache=True)
def fleet_statistics(Y, c0, U, cu0, na, u_lag, u_input, theta, resid, sigma2, pred_fit,
                     sim_fit):
    r"""Residuals, noise variances and fit percentages of many fitted ARX models.

    Reads the record itself, not a copy of its regressors: channel ``c`` of
    the chunk is column ``c0 + c`` of the outputs ``Y`` (N, C_all) and of the
    residuals ``resid`` (rows, C_all), and column ``cu0 + c`` of the inputs
    ``U`` (n_inputs, N, C_u: one (N, C_u) record per input); its ARX
    regressor row at time ``t`` is

    .. math::

        \varphi_t = [-y_{t-1}, \dots, -y_{t-n_a},\;
                     u_{j_1}(t - l_1), \dots, u_{j_m}(t - l_m)]

    (`u_lag` holds the lags :math:`l_i` and `u_input` the inputs :math:`j_i` of
    the input columns, in regressor order), for the rows ``t = start .. N - 1``
    with ``start = N - rows`` (``rows = resid.shape[0]``). With the
    parameters ``theta`` (c, n) (the first `na` the coefficients of
    :math:`A(q)` after its leading 1) it writes, for every channel:

    * ``resid[t - start, c0 + c] = y_t - phi_t theta`` and ``sigma2[c] =
      sum resid^2 / (rows - n)`` (NaN without spare rows);
    * ``pred_fit[c]``: `fit_percent` of the one-step prediction ``phi_t theta``;
    * ``sim_fit[c]``: `fit_percent` of the free-run simulation started from
      the measured ``y`` before `start` (the simulation of ``validate``):
      :math:`y_s(t) = B(q) u(t) - \sum_k a_k y_s(t - k)`, where the input part
      :math:`B(q) u(t)` is the ``u`` block of :math:`\varphi_t` times its
      parameters; only the last `na` simulated values are kept (a ring);

    (NaN fits for a constant target). Every product and sum is the one a
    regressor matrix ``Phi`` would give (:math:`(-y)\,a` is exactly
    :math:`-(y\,a)`), in the same order: over the parameters, then over
    time, channel by channel, with the channels in the inner loop (which
    vectorizes; a channel's numbers do not depend on the other channels).
    """
    C = theta.shape[0]
    n = theta.shape[1]
    N = Y.shape[0]
    rows = resid.shape[0]
    start = N - rows
    # every inner loop runs over the channels, on rows of contiguous 1-d views
    th = np.empty((n, C))                     # theta transposed: th[p] is parameter p
    for c in range(C):
        for p in range(n):
            th[p, c] = theta[c, p]
    nr = na + 1                               # ring of the simulated outputs
    ring = np.empty((nr, C))
    mean = np.zeros(C)
    ss_pred = np.zeros(C)
    ss_sim = np.zeros(C)
    ss_dev = np.zeros(C)
    ar = np.empty(C)
    bu = np.empty(C)
    for t in range(max(0, start - na), start):
        yt = Y[t, c0:c0 + C]
        ys = ring[t % nr]
        for c in range(C):
            ys[c] = yt[c]
    for k in range(rows):
        t = start + k
        for c in range(C):
            ar[c] = 0.0
            bu[c] = 0.0
        for p in range(na):                   # -y(t-1-p) a_(p+1)
            yp, tp = Y[t - 1 - p, c0:c0 + C], th[p]
            for c in range(C):
                ar[c] += -yp[c] * tp[c]
        for p in range(na, n):                # u_j(t-l) b
            up, tp = U[u_input[p - na], t - u_lag[p - na], cu0:cu0 + C], th[p]
            for c in range(C):
                bu[c] += up[c] * tp[c]
        yt, rt = Y[t, c0:c0 + C], resid[k, c0:c0 + C]
        for c in range(C):
            yk = yt[c]
            r = yk - (ar[c] + bu[c])              # y - phi theta
            rt[c] = r
            ss_pred[c] += r * r
            mean[c] += yk
        ys = ring[t % nr]                     # y_s(t) = B u(t) - sum_p a_p y_s(t - p)
        for c in range(C):
            ys[c] = bu[c]
        for p in range(1, na + 1):
            yb, tp = ring[(t - p) % nr], th[p - 1]
            for c in range(C):
                ys[c] -= tp[c] * yb[c]
        for c in range(C):
            e = yt[c] - ys[c]
            ss_sim[c] += e * e
    for c in range(C):
        mean[c] /= rows
    for k in range(rows):
        yt = Y[start + k, c0:c0 + C]
        for c in range(C):
            d = yt[c] - mean[c]
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
def build_regressors(Y, c0, U, cu0, na, u_lag, u_input, Phi, norms):
    r"""ARX regressors of many channels, and the norms of their columns.

    Channel ``c`` is column ``c0 + c`` of the outputs ``Y`` (N, C_all) and
    column ``cu0 + c`` of the inputs ``U`` (n_inputs, N, C_u); for the rows
    ``t = start .. N - 1`` (``start = N - rows``) it writes

    .. math::

        \Phi[t - start, :, c] = [-y_{t-1}, \dots, -y_{t-n_a},\;
                                 u_{j_1}(t - l_1), \dots, u_{j_m}(t - l_m)]

    into ``Phi`` (rows, n, c) (the channel index last; `u_lag`, `u_input`: the
    lags and inputs of the input columns) and ``norms[c, p] = sqrt(sum_t
    Phi[t, p, c]^2)``, summed in time order in the same pass (the unit columns
    of the rank decisions).
    """
    rows, n, C = Phi.shape
    start = Y.shape[0] - rows
    ss = np.zeros((n, C))
    for k in range(rows):
        t = start + k
        for p in range(na):
            src, dst, acc = Y[t - 1 - p, c0:c0 + C], Phi[k, p], ss[p]
            for c in range(C):
                v = -src[c]
                dst[c] = v
                acc[c] += v * v
        for p in range(na, n):
            src = U[u_input[p - na], t - u_lag[p - na], cu0:cu0 + C]
            dst, acc = Phi[k, p], ss[p]
            for c in range(C):
                v = src[c]
                dst[c] = v
                acc[c] += v * v
    for c in range(C):
        for p in range(n):
            norms[c, p] = np.sqrt(ss[p, c])
