"""`RecursiveLeastSquares`'s plain step on its state vector, compiled (numba).

python-control simulates a system from its state vector alone
(`rlsfilt._iosystem`); the self-tuning regulator's system runs a whole sample
as one compiled call on that vector (`rlsfilt.adaptive._kernels_design.sample`).
Its estimator part is here, beside the filter's own kernels: `vector_step`
reads the filter's state where :meth:`RecursiveLeastSquares.get_state` lays
it out (`_filter_state.get_state`: ``x``, ``P``, then the scalars of `SCALARS`)
and writes the state that ``predict(); update(z, phi)`` would leave, by the
filter's own compiled steps (`_kernels.predict_kernel`, `_kernels.update_kernel`)
on the same numbers, so the result is that of the filter's methods bit for bit.

Only the plain step is taken here: a step with anything to decide in Python
(a health check due, a flag of the update such as a gated sample or the
windup cap, EFRA's first step, a state assigned since the last step) returns
a nonzero status and the caller runs the filter's methods instead, which
decide and word it. The constants of the filter's configuration come from the
filter contract (`contract.vector_step_constants`).
"""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable
from ._kernels import predict_kernel, update_kernel

__all__ = []

#: The scalars of ``RecursiveLeastSquares.get_state()`` after ``x`` and ``P``, in order.
SCALARS = ("n_updates", "efra_pending", "n_capped", "cap", "w", "n_gated", "gated", "lam_t",
           "warned_health", "updates_since_predict", "recheck")
_N_UPDATES, _EFRA, _CAP, _W, _GATED, _LAM_T, _SINCE, _RECHECK = 0, 1, 3, 4, 6, 7, 9, 10

#: Statuses of `vector_step`: 0 the plain step, written; anything else: run the methods.
PLAIN, NOT_PLAIN, HEALTH_DUE, FLAGGED = 0, 1, 2, 3


@njit(cache=True, error_model="numpy")
def vector_step(v, z, phi, il, Q, cfg, r, check_every, out):
    r"""``predict(); update(z, phi)`` of the filter whose state vector is `v`.

    Parameters: `v` the state vector (``x`` (n, m) flattened, ``P`` (n, n)
    flattened, the `SCALARS`), `z` the measurement (m,), `phi` the regressor
    (n,), and the constants of the filter (`contract.vector_step_constants`):
    `il` (``1 / lam`` of the time update), `Q` ((0, 0) when zero), the
    configuration `cfg`, the variance `r` and `check_every`. Writes into `out`
    (same length as `v`) the state the two methods leave:

    .. math::

        P^- = P / \lambda + Q, \quad y = z - \varphi^T x, \quad
        K = P^- \varphi / (\varphi^T P^- \varphi + r), \quad
        x \leftarrow x + K y^T, \quad P \leftarrow P^- - K S K^T

    (the filter's forgetting mode, constraints and gate as configured), with
    ``n_updates`` + 1, ``lam_t`` of the step, ``updates_since_predict`` 1 and
    the flags cleared, as `RecursiveLeastSquares._commit_update` sets them.

    Returns `PLAIN` (0) when written; `NOT_PLAIN` (EFRA's first step, the
    forgetting held back, a state to recheck), `HEALTH_DUE` (the periodic
    health check falls on this update) or `FLAGGED` (the update flags a bad
    row or diagonal, a gated sample or the windup cap) when the filter's
    methods must take the step: `out` is then unspecified.
    """
    n, m = phi.shape[0], z.shape[0]
    nx = n * m
    o = nx + n * n                              # the scalars
    if v[o + _EFRA] != 0.0 or v[o + _CAP] != 0.0 or v[o + _RECHECK] != 0.0:
        return NOT_PLAIN
    n_updates = v[o + _N_UPDATES] + 1.0
    if check_every != 0 and n_updates % check_every == 0.0:
        return HEALTH_DUE
    x = v[:nx].reshape((n, m)).copy()
    P = v[nx:o].reshape((n, n)).copy()
    # predict: P^- = P / lam + Q (the cap is not set: 1 / lam is not held back)
    P_prior = np.empty((n, n))
    predict_kernel(P, il, Q, cfg, P_prior)
    # update, right after that predict (w = 1: nothing held back)
    xn, Pn = np.empty((n, m)), np.empty((n, n))
    y, K, S, SI = np.empty((m, 1)), np.empty((n, 1)), np.empty((m, m)), np.empty((m, m))
    flags, lam_t = update_kernel(x, P_prior, phi.reshape((1, n)), z.reshape((m, 1)), r, cfg,
                                 1.0, xn, Pn, y, K, S, SI)
    if flags != 0:
        return FLAGGED
    out[:] = v                                  # n_capped, n_gated, warned_health: kept
    out[:nx] = xn.ravel()
    out[nx:o] = Pn.ravel()
    out[o + _N_UPDATES] = n_updates
    out[o + _EFRA] = 0.0
    out[o + _CAP] = 0.0
    out[o + _W] = 1.0
    out[o + _GATED] = 0.0
    out[o + _LAM_T] = lam_t
    out[o + _SINCE] = 1.0
    out[o + _RECHECK] = 0.0
    return PLAIN


@njit(cache=True, error_model="numpy")
def vector_assign_x(out, x):
    """``f.x = x`` on the state vector `out` of a filter with one output: the
    estimate written, the state marked to be checked before the next step (the
    setter's ``recheck``)."""
    n = x.shape[0]
    out[:n] = x
    out[n + n * n + _RECHECK] = 1.0


@njit(cache=True, error_model="numpy")
def vector_x_P(v, n):
    """Views of the estimate ``x`` (n,) and the covariance ``P`` (n, n) in the state
    vector `v` of a filter with `n` parameters and one output."""
    return v[:n], v[n:n + n * n].reshape((n, n))


@njit(cache=True, error_model="numpy")
def prediction_errors(z, phi, x, out):
    r"""``out[j] = z[j] - sum_i phi[i] x[i, j]``, the a-priori errors :math:`z - \varphi^T x`,
    summed in order (the estimator system's outputs, the same numbers on both paths)."""
    for j in range(x.shape[1]):
        s = 0.0
        for i in range(x.shape[0]):
            s += phi[i] * x[i, j]
        out[j] = z[j] - s


@njit(cache=True, error_model="numpy")
def estimator_sample(v, w, out, outputs, orders, il, Q, cfg, r, check_every):
    r"""One sample of `estimator_iosystem` on its state vector: ``out``, the state after it.

    `v` is the system's state (the filter's, then with an ARX regressor the
    memories ``y(t-1) .. y(t-n_a)``, ``u(t-1) ..``), `w` its inputs (``[u, y]``
    with an ARX regressor; ``[z.., phi..]`` directly), `orders`
    ``[n, m, arx, na, nb, nk]``, then the filter's constants as in `vector_step`.
    The sample, as ``filter.predict(); filter.update(z, phi)``:

    .. math::

        \varphi(t) = [-y(t-1) .. -y(t-n_a), u(t-n_k) .. u(t-n_k-n_b+1)]
        \ (\text{ARX}), \quad e = z - \varphi^T \hat\theta(t-1),

    the filter's plain step (`vector_step`), the memories pushed. Writes
    ``[theta.., e..]`` into `outputs`. Returns `vector_step`'s status: nonzero,
    the filter's methods take the sample (`out`, `outputs` unspecified).
    """
    n, m, arx, na, nb, nk = orders[0], orders[1], orders[2], orders[3], orders[4], orders[5]
    nu = nk + nb - 1 if arx else 0
    nf = len(v) - (na + nu if arx else 0)
    phi = np.empty(n)
    if arx:
        ypast, upast = v[nf:nf + na], v[nf + na:]
        for i in range(na):
            phi[i] = -ypast[i]
        for i in range(nb):         # u(t-nk-i); with nk = 0 the first is this sample's u
            phi[na + i] = upast[nk - 1 + i] if nk + i > 0 else w[0]
        z = w[1:2]
    else:
        z = w[:m]
        phi[:] = w[m:m + n]
    status = vector_step(v[:nf], z, phi, il, Q, cfg, r, check_every, out[:nf])
    if status != PLAIN:
        return status
    outputs[:n * m] = out[:n * m]
    prediction_errors(z, phi, v[:n * m].reshape((n, m)), outputs[n * m:])
    if arx:                         # the memories, newest first
        for i in range(na - 1, 0, -1):
            out[nf + i] = v[nf + i - 1]
        if na:
            out[nf] = w[1]
        for i in range(nu - 1, 0, -1):
            out[nf + na + i] = v[nf + na + i - 1]
        if nu:
            out[nf + na] = w[0]
    return PLAIN
