"""Compiled (numba) kernels of `RecursiveLeastSquares`: its one production path.

Every public method of the filter that runs the recursion calls these
(``predict``, ``update``, ``predict_update``, ``batch_filter``,
``get_prediction``, the projection of ``constrain``). The same recursion in
readable NumPy is :mod:`rlsfilt.filters._reference` (``rls_predict``,
``rls_update``, ``update_<mode>``); ``tests/test_kernels.py`` holds the two
equal step by step to 1e-12 for every mode and option. Every function is
``njit(cache=True)``: compiled on first use, then loaded from the disk cache.

One step, for every forgetting mode (the codes of
:mod:`rlsfilt.filters.forgetting`), the gate and the constraints::

    P <- P il + Q;  P <- Pi P Pi            time_update (il = 1/lam in the exponential
                                            mode; the other modes forget in the update)
    g = P phi;  s = phi . g + r             measurement_update
    y = z - phi x                           per output
    y . y > gate^2 s: gated, no change
    exponential: c = 1/s;  K = g c;  x <- x + K y^T;  P <- P - (g g^T) c
    directional, constant_trace, efra, variable: the formulas of _reference.update_<mode>
    P <- Pi P Pi

``batch_filter`` runs ``time_update`` and ``measurement_update`` once per
sample (`step_batch`), and the streaming ``predict_kernel`` and
``update_kernel`` run the same two: streaming and batch agree bit for bit.
The default configuration with one output (ARX fits, long records) runs
`exponential_batch` instead: one sweep over ``P``
per sample applies the update, the next time update and the next gain
together (reading and writing ``P`` once). Its arithmetic is, element by
element, that of the two steps (the same products summed in the same
order, ``P_ij - (g_i g_j) c`` keeping ``P`` exactly symmetric; no
``fastmath``), so it gives the same bits, faster.
"""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable
from ._kernels_shared import any_nan, copy2, diagonal_bad, unhealthy, unhealthy_on
from .forgetting import (
    CFG_GATE,
    CFG_LAM,
    CFG_MODE,
    CFG_PARAMS,
    CFG_PI,
    CONSTANT_TRACE,
    DIRECTIONAL,
    EFRA,
    EXPONENTIAL,
    VARIABLE,
)

__all__ = []


# ----------------------------------------------------------------------
# one step
# ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def projector(cfg, n):
    """The projector ``Pi`` of the constraints in `cfg` ((0, 0) without them)."""
    k = n if cfg.shape[0] > CFG_PI else 0
    return cfg[CFG_PI:CFG_PI + k * k].reshape((k, k))


@njit(cache=True)
def project(P, Pi, T):
    """``P <- Pi P Pi`` made exactly symmetric; `T` is (n, n) work."""
    n = P.shape[0]
    for i in range(n):                       # T = Pi P
        for j in range(n):
            T[i, j] = 0.0
        for k in range(n):
            a = Pi[i, k]
            for j in range(n):
                T[i, j] += a * P[k, j]
    for i in range(n):                       # P = T Pi
        for j in range(n):
            P[i, j] = 0.0
        for k in range(n):
            a = T[i, k]
            for j in range(n):
                P[i, j] += a * Pi[k, j]
    for i in range(n):                       # P = (P + P^T) / 2
        for j in range(i + 1, n):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v


@njit(cache=True, inline="always")
def time_update(P, il, Q, Pi, T, Pn):
    """``Pn = P il + Q`` then ``Pn <- Pi Pn Pi`` (`Q`, `Pi` empty when absent; `Pn`
    may be `P`: the batch loops update in place)."""
    n = P.shape[0]
    if Q.shape[0]:
        for i in range(n):
            for j in range(n):
                Pn[i, j] = P[i, j] * il + Q[i, j]
    else:
        for i in range(n):
            for j in range(n):
                Pn[i, j] = P[i, j] * il
    if Pi.shape[0]:
        project(Pn, Pi, T)


@njit(cache=True, inline="always")
def measurement_update(x, P, phi, z, missing, r, cfg, Pi, g, y, K, T, xn, Pn):
    """One measurement update of any mode with the gate and the constraints.

    Reads ``x`` (n, m) and ``P`` (n, n) and writes the new ones into ``xn``,
    ``Pn`` (which may be ``x`` and ``P`` themselves: the batch loops update
    in place); a missing or gated sample leaves them. Writes ``g = P phi``
    (n,), the residual ``y`` (m,; NaN when missing) and the gain ``K`` (n,;
    zero when missing or gated). `cfg` is ``forgetting.kernel_config``,
    `Pi` its projector; `T` is (n, n) work.

    Returns
    -------
    s : float
        Innovation variance ``phi P phi^T + r``.
    lam_t : float
        Forgetting factor the step applied.
    gated : bool
        Whether the gate rejected the sample.
    """
    n, m = x.shape
    mode = int(cfg[CFG_MODE])
    lam = cfg[CFG_LAM]
    for j in range(n):
        g[j] = 0.0
    for i in range(n):                       # g = P phi (row i of the symmetric P times phi_i)
        hi = phi[i]
        for j in range(n):
            g[j] += P[i, j] * hi
    s = 0.0
    for i in range(n):
        s += phi[i] * g[i]
    s = s + r                                # S = H P H^T + R
    lam_skip = lam if mode == EXPONENTIAL else 1.0
    yy = 0.0
    if not missing:
        for j in range(m):                   # y = z - H x
            acc = 0.0
            for i in range(n):
                acc += phi[i] * x[i, j]
            y[j] = z[j] - acc
            yy += y[j] * y[j]
    gate = cfg[CFG_GATE]
    if missing or yy > gate * gate * s:      # missing, or sqrt(y'y / S) > gate: no update
        for j in range(m):
            if missing:
                y[j] = np.nan
        for i in range(n):
            K[i] = 0.0
        copy2(x, xn)
        copy2(P, Pn)
        return s, lam_skip, not missing
    lam_t = lam
    if mode == DIRECTIONAL:
        eps = cfg[CFG_PARAMS]
        rho = (s - r) / r                    # phi P phi^T / r
        e = lam - (1.0 - lam) / rho if rho > eps else 1.0
        d = r * (1.0 + e * rho)
        for i in range(n):
            K[i] = g[i] / d
        ed = e / d
        for i in range(n):
            gi = g[i]
            for j in range(n):
                Pn[i, j] = P[i, j] - ed * (gi * g[j])
        lam_t = e
    elif mode == EFRA:
        alpha, beta, delta = cfg[CFG_PARAMS], cfg[CFG_PARAMS + 1], cfg[CFG_PARAMS + 2]
        a_s = alpha / s
        d_r = delta / r
        for i in range(n):
            K[i] = a_s * g[i]
        for i in range(n):                   # T = P @ P
            for j in range(n):
                T[i, j] = 0.0
            for k in range(n):
                a = P[i, k]
                for j in range(n):
                    T[i, j] += a * P[k, j]
        for i in range(n):
            gi = g[i]
            for j in range(n):
                T[i, j] = P[i, j] / lam - a_s * (gi * g[j]) - d_r * T[i, j]
        br = beta * r
        for i in range(n):
            for j in range(n):
                Pn[i, j] = 0.5 * (T[i, j] + T[j, i])
            Pn[i, i] = Pn[i, i] + br
    else:                                    # exponential, constant trace, variable
        c = 1.0 / s
        for i in range(n):
            K[i] = g[i] * c                  # K = P H^T / S
        for i in range(n):
            gi = g[i]
            for j in range(n):
                Pn[i, j] = P[i, j] - (gi * g[j]) * c   # P = P - g g^T / S
        if mode == CONSTANT_TRACE:
            trace, ratio = cfg[CFG_PARAMS], cfg[CFG_PARAMS + 1]
            c2 = trace / (ratio + n)
            c1 = trace - n * c2
            tb = 0.0
            for i in range(n):
                tb += Pn[i, i]
            f = c1 / tb
            for i in range(n):
                for j in range(n):
                    Pn[i, j] = f * Pn[i, j]
                Pn[i, i] = Pn[i, i] + c2
            lam_t = tb / c1
        elif mode == VARIABLE:
            lam_min, trace_max = cfg[CFG_PARAMS], cfg[CFG_PARAMS + 1]
            lt = 1.0 - (1.0 - lam) * yy / (m * s)
            lt = min(1.0, max(lam_min, lt))
            tb = 0.0
            for i in range(n):
                tb += Pn[i, i]
            lt = max(lt, min(1.0, tb / trace_max))
            if lt != 1.0:
                for i in range(n):
                    for j in range(n):
                        Pn[i, j] = Pn[i, j] / lt
            lam_t = lt
    for i in range(n):                       # x = x + K y^T
        ki = K[i]
        for j in range(m):
            xn[i, j] = x[i, j] + ki * y[j]
    if Pi.shape[0]:                          # keep A P = 0
        project(Pn, Pi, T)
    return s, lam_t, False


# ----------------------------------------------------------------------
# the streaming steps (arguments packed by _streaming)
# ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def Pi_or_efra(cfg):
    """Whether a step needs the (n, n) work space: constraints or EFRA."""
    return cfg.shape[0] > CFG_PI or int(cfg[CFG_MODE]) == EFRA


@njit(cache=True)
def predict_kernel(x, P, il, Q, cfg, out):
    """Streaming ``predict`` into the block `out` (``_streaming.predict_shapes``, then
    ``n^2`` of work space): ``P^-`` = `time_update` of ``P``, and the copies
    ``x_prior = x``, ``P_prior = P^-``."""
    n, m = x.shape
    nP, nx = n * n, n * m                    # the block: P^- x_prior P_prior | T
    k = n if cfg.shape[0] > CFG_PI else 0    # T: work space of the projection
    o = nP + nx + nP
    time_update(P, il, Q, projector(cfg, n), out[o:o + k * k].reshape((k, k)),
                out[:nP].reshape((n, n)))
    for i in range(n):
        for j in range(m):
            out[nP + i * m + j] = x[i, j]    # x_prior
    for i in range(nP):
        out[nP + nx + i] = out[i]            # P_prior


@njit(cache=True)
def update_kernel(x, P, phi, z0, zmode, r, cfg, xn, Pn, out):
    """Streaming ``update``: `measurement_update` of ``x``, ``P`` into new arrays.

    Writes the new estimate ``xn`` (n, m) and covariance ``Pn`` (n, n), and
    into the block `out` (``_streaming.update_shapes``, then ``n + n^2`` of
    work space) ``y`` (m, 1), ``K`` (n, 1), ``S = s I`` and ``SI = I / s``
    (m, m), the copy ``H`` (1, n) of the regressor ``phi`` (n,), the
    measurement ``z`` (m, 1; NaN when missing) and the copies ``x_post``,
    ``P_post``. With ``zmode`` 0 the caller has written the measurement into
    the block's ``z``; with 1 it is the scalar ``z0``; with 2 it is missing.

    Returns
    -------
    code : int
        0; 1 when ``phi`` holds NaN or inf (nothing is written then); 2 when
        the diagonal of the new ``P`` is not positive and finite (checked
        without constraints only: under them ``P`` is singular by design).
    s, lam_t : float
    gated : bool
    """
    n, m = x.shape
    for i in range(n):
        v = phi[i]
        if v - v != 0.0:                     # NaN or inf
            return 1, np.nan, np.nan, False
    y, K = out[:m], out[m:m + n]             # the block: y K S SI H z x_post P_post | g T
    o = m + n
    S, SI, Hz = out[o:o + m * m], out[o + m * m:o + 2 * m * m], out[o + 2 * m * m:]
    for i in range(n):
        Hz[i] = phi[i]                       # H
    for j in range(m):
        if zmode != 0:
            Hz[n + j] = z0 if zmode == 1 else np.nan     # z
    o += 2 * m * m + n + m                   # x_post, P_post, then the work space
    nx, nP = n * m, n * n
    g = out[o + nx + nP:o + nx + nP + n]
    k = n if Pi_or_efra(cfg) else 0
    T = out[o + nx + nP + n:o + nx + nP + n + k * k].reshape((k, k))
    s, lam_t, gated = measurement_update(x, P, phi, Hz[n:n + m], zmode == 2, r, cfg,
                                         projector(cfg, n), g, y, K, T, xn, Pn)
    for i in range(m * m):
        S[i] = 0.0
        SI[i] = 0.0
    for i in range(m):
        S[i * m + i] = s
        SI[i * m + i] = 1.0 / s
    xf, Pf = xn.reshape(nx), Pn.reshape(nP)
    for i in range(nx):
        out[o + i] = xf[i]                   # x_post
    for i in range(nP):
        out[o + nx + i] = Pf[i]              # P_post
    # the cheap check (without constraints: under them P is singular by design)
    return (2 if cfg.shape[0] == CFG_PI and diagonal_bad(Pn) else 0), s, lam_t, gated


# ----------------------------------------------------------------------
# batch_filter
# ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def _predict_step(x, P, il, Q, Pi, T, k, means_p, covs_p, x_prior, P_prior):
    """`time_update` in `step_batch`, with its histories (and the last prior)."""
    if il != 1.0 or Q.shape[0] or Pi.shape[0]:
        time_update(P, il, Q, Pi, T, P)
    copy2(x, means_p[k])
    if covs_p.shape[0]:
        copy2(P, covs_p[k])
    if k == means_p.shape[0] - 1:
        copy2(x, x_prior)
        copy2(P, P_prior)


@njit(cache=True)
def step_batch(x, P, Z, Hm, Rv, il, Q, update_first, cfg, basis,
               means, means_p, covs, covs_p, ys, ss, gated,
               x_prior, P_prior, x_post, P_post, K, check_every, step0, cond_max, P_fail):
    """`time_update` and `measurement_update` over a record, in place on ``x``, ``P``.

    ``Z`` (N, m; NaN rows missing), ``Hm`` (N, n), ``Rv`` (N,) or (1,) (one
    variance for every step); ``il`` is ``1 / lam`` in the exponential mode
    and 1 otherwise. Writes the estimates after each update and predict
    (``means``, ``means_p``), the covariances (``covs``, ``covs_p``, when
    their length is N), the residuals ``ys`` (N, m), the innovation
    variances ``ss`` (N,), the gate decisions ``gated`` (N,), the last
    step's prior and posterior, and ``K`` (n,), the last gain. The health
    check of ``P`` (on the null space `basis` of the constraints; `basis`
    has no columns without them) runs at the end of each step whose update
    count ``step0 + k + 1`` is a multiple of `check_every`; the first
    failing ``P`` is copied to ``P_fail``.

    Returns
    -------
    s, lam_t : float
        The last step's innovation variance and forgetting factor.
    k_fail : int
        Step of the first failed health check, or -1.
    """
    N = Z.shape[0]
    n, m = x.shape
    Pi = projector(cfg, n)
    r_each = Rv.shape[0] == N
    g = np.empty(n)
    y = np.empty(m)
    T = np.empty((n, n))
    s = np.nan
    lam_t = cfg[CFG_LAM]
    k_fail = -1
    for k in range(N):
        if not update_first:
            _predict_step(x, P, il, Q, Pi, T, k, means_p, covs_p, x_prior, P_prior)
        z = Z[k]
        s, lam_t, gk = measurement_update(x, P, Hm[k], z, any_nan(z), Rv[k if r_each else 0],
                                          cfg, Pi, g, y, K, T, x, P)
        ss[k] = s
        gated[k] = gk
        for j in range(m):
            ys[k, j] = y[j]
        copy2(x, means[k])
        if covs.shape[0]:
            copy2(P, covs[k])
        if k == N - 1:
            copy2(x, x_post)
            copy2(P, P_post)
        if update_first:
            _predict_step(x, P, il, Q, Pi, T, k, means_p, covs_p, x_prior, P_prior)
        if (check_every > 0 and k_fail < 0 and (step0 + k + 1) % check_every == 0
                and unhealthy_on(P, basis, cond_max)):
            k_fail = k
            copy2(P, P_fail)
    return s, lam_t, k_fail


@njit(cache=True, inline="always")
def _sweep(P, g, c, update, il, Q, predict, phin, gn):
    """One sweep over ``P``: ``P <- P - (g g^T) c`` (`update`), then ``P <- P il + Q``
    (`predict`), accumulating the next gain ``gn = P phin`` on the way."""
    n = P.shape[0]
    for j in range(n):
        gn[j] = 0.0
    if update and predict and Q.shape[0] == 0:       # the common case, branch-free
        for i in range(n):
            gi = g[i]
            hi = phin[i]
            for j in range(n):
                v = (P[i, j] - (gi * g[j]) * c) * il
                P[i, j] = v
                gn[j] += v * hi
    else:
        none = P.reshape((1, n, n))                  # no histories to write
        _sweep_store(P, g, c, update, il, Q, predict, phin, gn, none, -1, none, -1)


@njit(cache=True, inline="always")
def _sweep_store(P, g, c, update, il, Q, predict, phin, gn, covs, k_post, covs_p, k_prior):
    """`_sweep` that also writes ``P`` after the update half to ``covs[k_post]`` and
    after the predict half to ``covs_p[k_prior]`` (not for an index of -1)."""
    n = P.shape[0]
    for j in range(n):
        gn[j] = 0.0
    for i in range(n):
        gi = g[i]
        hi = phin[i]
        for j in range(n):
            v = P[i, j]
            if update:
                v = v - (gi * g[j]) * c
            if k_post >= 0:
                covs[k_post, i, j] = v
            if predict:
                v = v * il
                if Q.shape[0]:
                    v = v + Q[i, j]
            if k_prior >= 0:
                covs_p[k_prior, i, j] = v
            P[i, j] = v
            gn[j] += v * hi


@njit(cache=True)
def exponential_batch(x, P, Z, Hm, Rv, il, Q, update_first, means, covs, covs_p, ys, ss,
                      x_prior, P_prior, x_post, P_post, K, check_every, step0, cond_max, P_fail):
    """`step_batch` of the default configuration with one output, fused (see the module).

    Exponential forgetting, no gate, no constraints, ``m = 1``; ``ys`` and
    ``ss`` have length 1 (the last step). Arguments and returns otherwise as
    `step_batch` (``means_p`` is ``means`` shifted by one step; the caller
    builds it).
    """
    N = Z.shape[0]
    n = x.shape[0]
    r_each = Rv.shape[0] == N
    store = covs.shape[0] > 0
    predict = not (il == 1.0 and Q.shape[0] == 0)    # otherwise the time update is the identity
    th = x[:, 0]
    g = np.empty(n)
    gn = np.empty(n)
    k_fail = -1
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    _sweep_store(P, g, 0.0, False, il, Q, predict and not update_first, Hm[0], gn,  # P^-, g
                 covs, -1, covs_p, 0 if store and not update_first else -1)
    g, gn = gn, g
    if not update_first and N == 1:
        copy2(x, x_prior)
        copy2(P, P_prior)
    s = np.nan
    for k in range(N):
        h = Hm[k]
        acc = 0.0
        for i in range(n):
            acc += h[i] * g[i]
        s = acc + Rv[k if r_each else 0]            # S = H P H^T + R
        ss[0] = s
        c = 1.0 / s
        zk = Z[k, 0]
        update = zk == zk                            # not missing
        if update:
            acc = 0.0
            for i in range(n):
                acc += h[i] * th[i]
            yk = zk - acc                            # y = z - H x
            ys[0, 0] = yk
            for i in range(n):
                ki = g[i] * c                        # K = P H^T / S
                K[i] = ki
                th[i] = th[i] + ki * yk              # x = x + K y
        else:
            ys[0, 0] = np.nan
        for i in range(n):
            means[k, i, 0] = th[i]
        countdown -= 1                 # zero when (step0 + k + 1) % check_every == 0
        check = countdown == 0 and k_fail < 0
        if countdown == 0:
            countdown = check_every
        last = k == N - 1
        if check or last:              # unfused, to look at P between the two halves
            _sweep_store(P, g, c, update, il, Q, False, h, gn, covs, k if store else -1, covs_p,
                         -1)
            if last:
                copy2(x, x_post)
                copy2(P, P_post)
            if check and not update_first and unhealthy(P, cond_max):
                k_fail = k
                copy2(P, P_fail)
            if not last or update_first:
                kp = (k if update_first else k + 1) if store else -1
                _sweep_store(P, g, c, False, il, Q, predict, Hm[min(k + 1, N - 1)], gn,
                             covs, -1, covs_p, kp)
            if check and update_first and unhealthy(P, cond_max):
                k_fail = k
                copy2(P, P_fail)
        elif store:                    # with the histories of P after each half
            _sweep_store(P, g, c, update, il, Q, predict, Hm[k + 1], gn, covs, k, covs_p,
                         k if update_first else k + 1)
        else:
            _sweep(P, g, c, update, il, Q, predict, Hm[k + 1], gn)
        g, gn = gn, g
        if (k == N - 2 and not update_first) or (last and update_first):
            copy2(x, x_prior)
            copy2(P, P_prior)
    return s, k_fail


class BatchResult:
    """What `run_batch` returns: the histories and the last step's state."""

    __slots__ = ("means", "covariances", "means_p", "covariances_p", "ys", "ss", "gated",
                 "x", "P", "x_prior", "P_prior", "x_post", "P_post", "K_last", "s_last",
                 "lam_t_last", "k_fail", "P_fail")


def run_batch(x, P, Z, Hm, Rv, cfg, Q, basis, update_first, store_covariances,
              check_every, step0, cond_max):
    """Run `RecursiveLeastSquares` over a validated record; `x`, `P` are not modified.

    `cfg` is ``forgetting.kernel_config``; `Q` None when absent; `basis`
    the null-space basis of the constraints (None without). Chooses
    `exponential_batch` for the default configuration with one output,
    `step_batch` otherwise. Returns a
    `BatchResult` (``ys``, ``ss``, ``gated`` hold the last step only after
    `exponential_batch`).
    """
    N = len(Z)
    n, m = x.shape
    mode, lam, gate = int(cfg[CFG_MODE]), cfg[CFG_LAM], cfg[CFG_GATE]
    il = 1.0 / lam if mode == EXPONENTIAL else 1.0
    empty = np.zeros((0, 0))
    Qa = empty if Q is None else np.ascontiguousarray(Q, dtype=np.float64)
    Ba = np.zeros((n, 0)) if basis is None else np.ascontiguousarray(basis, dtype=np.float64)
    Rv = np.ascontiguousarray(Rv[:1] if N > 1 and Rv.strides[0] == 0 else Rv, dtype=np.float64)
    Zc = np.ascontiguousarray(Z, dtype=np.float64)
    Hc = np.ascontiguousarray(Hm, dtype=np.float64)
    out = BatchResult()
    out.x = np.array(x, dtype=np.float64, order="C")
    out.P = np.array(P, dtype=np.float64, order="C")
    out.x_prior, out.P_prior = np.empty((n, m)), np.empty((n, n))
    out.x_post, out.P_post = np.empty((n, m)), np.empty((n, n))
    out.means = np.empty((N, n, m))
    K = np.zeros(n)
    out.P_fail = np.empty((n, n))
    fused = mode == EXPONENTIAL and gate == np.inf and len(cfg) == CFG_PI and m == 1 and N > 0
    covs = np.empty((N if store_covariances else 0, n, n))
    covs_p = np.empty((N if store_covariances else 0, n, n))
    out.covariances = covs if store_covariances else None
    out.covariances_p = covs_p if store_covariances else None
    if fused:
        out.ys, out.ss = np.empty((1, 1)), np.empty(1)
        out.s_last, out.k_fail = exponential_batch(
            out.x, out.P, Zc, Hc, Rv, il, Qa, bool(update_first), out.means, covs, covs_p,
            out.ys, out.ss, out.x_prior, out.P_prior, out.x_post, out.P_post, K,
            int(check_every), int(step0), float(cond_max), out.P_fail)
        out.gated = np.zeros(1, dtype=np.bool_)
        out.lam_t_last = lam
        out.means_p = out.means.copy() if update_first else np.empty((N, n, m))
        if not update_first:                         # the estimate is unchanged by a predict
            out.means_p[0] = x
            out.means_p[1:] = out.means[:-1]
    else:
        out.means_p = np.empty((N, n, m))
        out.ys, out.ss = np.empty((N, m)), np.empty(N)
        out.gated = np.zeros(N, dtype=np.bool_)
        out.s_last, out.lam_t_last, out.k_fail = step_batch(
            out.x, out.P, Zc, Hc, Rv, il, Qa, bool(update_first), cfg, Ba,
            out.means, out.means_p, covs, covs_p, out.ys, out.ss, out.gated,
            out.x_prior, out.P_prior, out.x_post, out.P_post, K,
            int(check_every), int(step0), float(cond_max), out.P_fail)
    if N and np.isnan(Z[-1]).any():                   # the last sample was missing: no gain
        K[:] = 0.0
    out.K_last = K.reshape(n, 1)
    return out
