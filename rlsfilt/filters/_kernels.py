"""Compiled (numba) kernels of `RecursiveLeastSquares`: its one production path.

Every public method of the filter that runs the recursion calls these
(``predict``, ``update``, ``predict_update``, ``batch_filter``,
``get_prediction``, the projection of ``constrain``). The same recursion in
readable NumPy is ``tests/_reference.py`` (``rls_predict``,
``rls_update``, ``update_<mode>``, ``windup_cap``); ``tests/test_kernels.py``
holds the two equal step by step to 1e-12 for every mode and option. Every
function is ``njit(cache=True)``: compiled on first use, then loaded from the
disk cache.

One step, for every forgetting mode (the codes of
:mod:`rlsfilt.filters.forgetting`), the gate and the constraints::

    P <- P il + Q;  P <- Pi P Pi            time_update (il = 1/lam in the exponential
                                            mode, 1 when the windup cap holds the
                                            forgetting back; the other modes forget
                                            in the update)
    P_ij <- P_ij (w_i w_j) + Q_ij           diagonal_time_update (the diagonal mode:
                                            P^- = L^-1/2 P L^-1/2 + Q, w_i = lam_i^-1/2
                                            from the configuration, diagonal_factors)
    g = P phi;  q = phi . g                 measurement_update
    s = w q + r                             w = il if the forgetting was held back, else 1
    y = z - phi x                           per output
    y . y > gate^2 s: gated, no measurement update
    exponential: c = 1/s;  K = g (w c);  x <- x + K y^T;  P <- P - (g g^T) cu
                 cu = c, or cu = w^2 c - (w - 1)/q when held back (the held-back
                 forgetting P <- P + (w - 1) g g^T / q along the regressor, and
                 the update, in one rank-one term)
    diagonal: as exponential; held back, w = phi L^-1/2 P L^-1/2 phi^T / q
              (held_back_factor: the growth of phi P phi^T the time update would give)
    directional, constant_trace, efra, variable: the formulas of _reference.update_<mode>
    P <- Pi P Pi

``P`` is kept exactly symmetric: every entry is computed from the symmetric
formula ``P_ij - (g_i g_j) cu`` (the product ``g_i g_j`` is the same number as
``g_j g_i``), never mirrored.

**The windup cap** (exponential mode, ``lam < 1``). After each update the
kernels decide, in O(n), whether the next time update may divide ``P`` by
``lam``: not when that would make ``trace(P)`` exceed ``trace_max``, or when
``sum_i P_ii phi_i^2 > spread_max * phi P phi^T`` (``P`` is far larger off the
regressor's direction than along it: the directions the data no longer excite
are winding up). Then the time update leaves ``P`` (and adds ``Q``) and the
next update forgets along its regressor only (``_reference.windup_cap``).

``batch_filter`` runs ``time_update`` and ``measurement_update`` once per
sample (`step_batch`), and the streaming ``predict_kernel`` and
``update_kernel`` run the same two, one each: streaming and batch agree bit
for bit.
The default configuration with one output (ARX fits, long records) runs
`exponential_batch` instead: one sweep over ``P``
per sample applies the update, the next time update and the next gain
together (reading and writing ``P`` once, four rows at a time). Its
arithmetic is, element by element, that of the two steps (the same products
summed in the same order; no ``fastmath``), so it gives the same bits, faster.
Its usual steps run in `_usual_steps`, a loop that makes no call (the rare
steps return to `exponential_batch`, whose sweeps are one shared call,
`_sweep_call`), compiled once for every size (with the dimension as a
constant only where it measurably pays: `_SPECIALISED`, `_dimension_witness`).
What the first run compiles is kept small: no literal arguments (a literal
``0`` compiles a callee a second time), no slice assignment of arrays (numba
compiles its error message, string formatting included), the health
checks in one layout and without the constrained variant in the fused loop,
the random walk ``Q`` None when absent (the fused loop compiles its ``Q``
loops only for a ``Q``: numba prunes a branch on an argument before inlining
what it calls), and the rare steps sweeping row by row and copying through one
compiled `_copy_leading` (inlined copies were two fifths of the loop's code).

**The health check** runs in two tiers: every update tests the diagonal of
``P`` (positive and finite, O(n)); every ``check_every`` updates (and at once
when the diagonal test fails) `unhealthy_sym` decides as ``eigvalsh`` would
(a vectorized Cholesky settles the healthy case). A failure starts an
*episode* (one warning); a later periodic check that passes ends it, so the
next failure warns again.
"""

import numba
import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable
from ._kernels_lagged import lag_block, lag_rows_numpy
from ._kernels_shared import (
    aligned_zeros,
    any_nan,
    copy2,
    diagonal_bad,
    padded_width,
    unhealthy,
    unhealthy_on,
    unhealthy_sym,
)
from .forgetting import (
    CFG_GATE,
    CFG_LAM,
    CFG_MODE,
    CFG_PARAMS,
    CFG_PI,
    CONSTANT_TRACE,
    DIAGONAL,
    DIRECTIONAL,
    EFRA,
    EXPONENTIAL,
    VARIABLE,
)

__all__ = []


# ----------------------------------------------------------------------
# one step
# ----------------------------------------------------------------------
@njit(cache=True, error_model="numpy", inline="always")
def _pi_start(cfg, n):
    """Where the projector starts in `cfg`: after the diagonal mode's ``n`` factors."""
    return CFG_PI + n if int(cfg[CFG_MODE]) == DIAGONAL else CFG_PI


@njit(cache=True, error_model="numpy", inline="always")
def projector(cfg, n):
    """The projector ``Pi`` of the constraints in `cfg` ((0, 0) without them)."""
    start = _pi_start(cfg, n)
    k = n if cfg.shape[0] > start else 0
    return cfg[start:start + k * k].reshape((k, k))


@njit(cache=True, error_model="numpy", inline="always")
def diagonal_factors(cfg, n):
    """The diagonal mode's time-update factors ``w_i = 1 / sqrt(lam_i)`` in `cfg`
    (length ``n``; empty in every other mode)."""
    k = n if int(cfg[CFG_MODE]) == DIAGONAL else 0
    return cfg[CFG_PI:CFG_PI + k]


@njit(cache=True, error_model="numpy", inline="always")
def unconstrained(cfg, n):
    """Whether `cfg` holds no constraints (no projector)."""
    return cfg.shape[0] == _pi_start(cfg, n)


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy", inline="always")
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


@njit(cache=True, error_model="numpy")
def diagonal_time_update(P, wd, Q, Pi, T, Pn):
    """The diagonal mode's ``Pn = L^-1/2 P L^-1/2 + Q`` (``L = diag(lam)``), entry by
    entry ``Pn_ij = P_ij (w_i w_j) + Q_ij`` with ``w_i = 1 / sqrt(lam_i)`` (`wd`;
    the products as `tuning`'s likelihood forms them), then ``Pn <- Pi Pn Pi``
    (`Q`, `Pi` empty when absent; `Pn` may be `P`)."""
    n = P.shape[0]
    if Q.shape[0]:
        for i in range(n):
            wi = wd[i]
            for j in range(n):
                Pn[i, j] = (wi * wd[j]) * P[i, j] + Q[i, j]
    else:
        for i in range(n):
            wi = wd[i]
            for j in range(n):
                Pn[i, j] = (wi * wd[j]) * P[i, j]
    if Pi.shape[0]:
        project(Pn, Pi, T)


@njit(cache=True, error_model="numpy")
def held_back_factor(P, phi, wd):
    """The diagonal mode's forgetting along the regressor when the windup cap held its
    time update back: ``w = (phi L^-1/2 P L^-1/2 phi^T) / (phi P phi^T)``, the growth of
    ``phi P phi^T`` the held-back time update would have given (``1 / lam`` for equal
    factors); 1 when ``phi P phi^T`` is not positive. (Called by the step's callers,
    before `measurement_update`, which takes it as its `w`.)"""
    n = P.shape[0]
    q = 0.0
    qa = 0.0
    for i in range(n):
        acc = 0.0
        acc_w = 0.0
        for j in range(n):
            acc += P[i, j] * phi[j]
            acc_w += P[i, j] * (phi[j] * wd[j])
        q += phi[i] * acc
        qa += (phi[i] * wd[i]) * acc_w
    return qa / q if q > 0.0 else 1.0


@njit(cache=True, error_model="numpy", inline="always")
def gain(P, phi, g):
    """``g = P phi``, summed row by row (``g_j += P_ij phi_i``, ``i`` ascending: the
    order in which `_sweep_call` accumulates the next gain)."""
    n = P.shape[0]
    for j in range(n):
        g[j] = 0.0
    for i in range(n):
        hi = phi[i]
        row = P[i]                           # a 1-d row view: the loop vectorizes
        for j in range(n):
            g[j] += row[j] * hi


@njit(cache=True, error_model="numpy", inline="always")
def exponential_coefficient(q, c, w, updated):
    """The rank-one coefficient ``cu`` of ``P <- P - (g g^T) cu`` in the exponential mode.

    ``c = 1 / s``; `w` is ``1 / lam`` when the time update held the forgetting
    back (the windup cap) and 1 otherwise; `updated` is False for a missing or
    gated sample. Held back, the forgetting happens here, along the regressor
    only: ``P <- P + (w - 1) g g^T / q`` (``q = phi g``), whose gain is ``w g``.
    """
    if w == 1.0:
        return c if updated else 0.0
    f = (w - 1.0) / q if q > 0.0 else 0.0
    return w * w * c - f if updated else -f


@njit(cache=True, error_model="numpy", inline="always")
def _diagonal_stats(P, g, cu, h, n):
    """``trace``, ``sum_i d_i h_i^2`` and ``min_i d_i`` of ``d_i = P_ii - (g_i g_i) cu``,
    the diagonal of ``P - (g g^T) cu`` (the updated ``P``), without forming it
    (``i`` below ``n``, the length of ``h``: ``P`` may be a padded work array).

    (``min`` skips NaN; NaN or inf then shows in the trace.)
    """
    tr = 0.0
    spread = 0.0
    dmin = np.inf
    for i in range(n):
        d = P[i, i] - (g[i] * g[i]) * cu
        tr += d
        spread += (d * h[i]) * h[i]
        dmin = d if d < dmin else dmin
    return tr, spread, dmin


@njit(cache=True, error_model="numpy", inline="always")
def windup_cap(d_trace, d_spread, hph, il, cfg):
    """Whether the next time update must hold the forgetting back (see the module).

    `d_trace` is ``trace(P)`` after the update, `d_spread` ``sum_i P_ii
    phi_i^2``, `hph` ``phi P phi^T`` (all of the updated ``P``), `il` ``1 /
    lam``; the limits ``spread_max``, ``trace_max`` are the exponential
    mode's parameters in `cfg`.
    """
    if il == 1.0:
        return False
    if d_trace * il > cfg[CFG_PARAMS + 1]:
        return True
    # under constraints P is singular by design: the spread test does not apply
    spread_max = cfg[CFG_PARAMS]
    return cfg.shape[0] == CFG_PI and spread_max < np.inf and d_spread > spread_max * hph


@njit(cache=True, error_model="numpy", inline="always")
def _innovation(x, phi, z, missing, r, w, gate, g, y):
    """``q = phi g`` (``g = P phi``), ``s = w q + r`` and the residual ``y`` (NaN when
    `missing`) with the outlier gate: ``(q, s, yy, updated, gated)``, ``yy = y^T y``."""
    n, m = x.shape
    q = 0.0
    for i in range(n):
        q += phi[i] * g[i]
    s = w * q + r                            # S = H P H^T + R
    if missing:
        for j in range(m):
            y[j] = np.nan
        return q, s, 0.0, False, False
    yy = 0.0
    for j in range(m):                       # y = z - H x
        acc = 0.0
        for i in range(n):
            acc += phi[i] * x[i, j]
        y[j] = z[j] - acc
        yy += y[j] * y[j]
    # sqrt(y'y / S) > gate; without a gate (inf) never: `inf * S` is -inf where round-off
    # has made S negative (P indefinite), and every later sample was then rejected
    gated = gate < np.inf and yy > gate * gate * s
    return q, s, yy, not gated, gated


@njit(cache=True, error_model="numpy", inline="always")
def measurement_update(x, P, phi, z, missing, r, cfg, Pi, g, y, K, T, w, xn, Pn):
    """One measurement update of any mode with the gate and the constraints.

    Reads ``x`` (n, m) and ``P`` (n, n) and writes the new ones into ``xn``,
    ``Pn`` (which may be ``x`` and ``P`` themselves: the batch loops update
    in place); a missing or gated sample leaves them (but for forgetting the
    time update held back). Writes ``g = P phi`` (n,), the residual ``y``
    (m,; NaN when missing) and the gain ``K`` (n,; zero when missing or
    gated). `cfg` is ``forgetting.kernel_config``, `Pi` its projector; `T`
    is (n, n) work; `w` is ``1 / lam`` when the last time update held the
    forgetting back (the windup cap, exponential mode), `held_back_factor` in the
    diagonal mode, and 1 otherwise.

    Returns
    -------
    s : float
        Innovation variance ``w phi P phi^T + r``.
    lam_t : float
        Forgetting factor the step applied.
    gated : bool
        Whether the gate rejected the sample.
    cap : bool
        Whether the next time update must hold the forgetting back.
    """
    n, m = x.shape
    mode = int(cfg[CFG_MODE])
    lam = cfg[CFG_LAM]
    timed = mode == EXPONENTIAL or mode == DIAGONAL       # forgets in the time update
    gain(P, phi, g)                          # g = P H^T
    q, s, yy, updated, gated = _innovation(x, phi, z, missing, r, w, cfg[CFG_GATE], g, y)
    lam_skip = lam if timed else 1.0
    if not updated:
        for i in range(n):
            K[i] = 0.0
        if not timed:
            copy2(x, xn)
            copy2(P, Pn)
            return s, lam_skip, gated, False
    lam_t = lam
    if timed:                                # exponential, diagonal: the standard update
        c = 1.0 / s
        cu = exponential_coefficient(q, c, w, updated)
        if updated:
            kc = w * c
            for i in range(n):
                K[i] = g[i] * kc             # K = P H^T / S
        for i in range(n):
            gi = g[i]
            for j in range(n):
                Pn[i, j] = P[i, j] - (gi * g[j]) * cu   # P = P - g g^T / S
        if not updated:
            lam_t = lam_skip
    elif mode == DIRECTIONAL:
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
    else:                                    # constant trace, variable
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
    if updated:
        for i in range(n):                   # x = x + K y^T
            ki = K[i]
            for j in range(m):
                xn[i, j] = x[i, j] + ki * y[j]
    else:                                    # exponential, held back: x unchanged
        copy2(x, xn)
    if Pi.shape[0] and (updated or w != 1.0):   # keep A P = 0 (a sample skipped with no
        project(Pn, Pi, T)                      # forgetting held back leaves P, as every mode)
    cap = False                              # (the diagonal mode's: `diagonal_windup_cap`,
    if mode == EXPONENTIAL:                  # which the callers decide)
        hph = q * r * (w * (1.0 / s)) if updated else q * w    # phi P phi^T after the update
        tr, spread, _ = _diagonal_stats(Pn, g, 0.0, phi, phi.shape[0])   # of the updated P
        cap = windup_cap(tr, spread, hph, 1.0 / lam, cfg)
    return s, lam_t, gated, cap


@njit(cache=True, error_model="numpy")
def diagonal_windup_cap(P, phi, g, s, r, w, updated, wd, cfg, plain):
    """`windup_cap` of the diagonal mode, after `measurement_update` (``P`` the updated
    covariance, `g`, `s`, `w` those of the step, `updated` False for a missing or gated
    sample): hold the next time update back when the trace after it,
    ``sum_i P_ii / lam_i``, would exceed ``trace_max``, or when
    ``sum_i P_ii phi_i^2 > spread_max phi P phi^T`` (without constraints: `plain`).
    Never when every factor is 1. (Called by `step_batch` and `update_kernel` outside
    the step every other mode shares, so their loops carry no trace of it.)"""
    if cfg[CFG_LAM] == 1.0:
        return False
    q = 0.0
    for i in range(phi.shape[0]):
        q += phi[i] * g[i]
    hph = q * r * (w * (1.0 / s)) if updated else q * w    # phi P phi^T after the update
    tr = 0.0
    spread = 0.0
    for i in range(P.shape[0]):
        d = P[i, i]
        tr += d * (wd[i] * wd[i])
        spread += (d * phi[i]) * phi[i]
    if tr > cfg[CFG_PARAMS + 1]:
        return True
    spread_max = cfg[CFG_PARAMS]
    return plain and spread_max < np.inf and spread > spread_max * hph


# ----------------------------------------------------------------------
# the streaming steps: RecursiveLeastSquares.predict and .update
# ----------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def predict_kernel(P, il, Q, cfg, Pn):
    """Streaming ``predict``: ``Pn = P il + Q`` then ``Pn <- Pi Pn Pi`` (`time_update`,
    `Q` (0, 0) when absent, ``Pi`` the projector of the configuration `cfg`)."""
    n = P.shape[0]
    Pi = projector(cfg, n)
    k = Pi.shape[0]
    wd = diagonal_factors(cfg, n)
    if wd.shape[0] and il != 1.0:            # diagonal: P^- = L^-1/2 P L^-1/2 + Q
        diagonal_time_update(P, wd, Q, Pi, np.empty((k, k)), Pn)
    else:
        time_update(P, il, Q, Pi, np.empty((k, k)), Pn)


#: The flags `update_kernel` returns, added: a regressor with NaN or inf (nothing
#: written), a diagonal of the new ``P`` that is not positive and finite (the cheap
#: health check; without constraints only), a gated sample, and the windup cap's
#: decision for the next time update.
BAD_ROW, BAD_DIAGONAL, GATED, CAP = 1, 2, 4, 8


@njit(cache=True, error_model="numpy")
def update_kernel(x, P, H, z, r, cfg, w, xn, Pn, y, K, S, SI):
    """Streaming ``update``: `measurement_update` of ``x`` (n, m), ``P`` (n, n) with
    the regressor row ``H`` (1, n) and the measurement column ``z`` (m, 1; any NaN:
    missing), written into new arrays.

    Writes the new estimate ``xn`` (n, m) and covariance ``Pn`` (n, n), the
    residual ``y`` (m, 1), the gain ``K`` (n, 1), ``S = s I`` and ``SI = I / s``
    (m, m). `w` as in `measurement_update` (in the diagonal mode any value but 1
    says held back: its `held_back_factor` is computed here, and the windup cap by
    `diagonal_windup_cap`). The same operations as one step of `step_batch`, so
    streaming and ``batch_filter`` agree bit for bit.

    Returns
    -------
    flags : int
        The sum of `BAD_ROW` (``H`` holds NaN or inf: nothing is written; tested
        here because it is cheaper than ``np.isfinite`` on a small row),
        `BAD_DIAGONAL` (the cheap check of the new ``P``; without constraints
        only: under them ``P`` is singular by design), `GATED` and `CAP` (the
        next time update must hold the forgetting back); 0 for an ordinary step.
    lam_t : float
        The forgetting factor the step applied.
    """
    n, m = x.shape
    phi = H[0]
    for i in range(n):
        v = phi[i]
        if v - v != 0.0:                     # NaN or inf
            return BAD_ROW, np.nan
    plain = unconstrained(cfg, n)            # no constraints
    k = 0 if plain and int(cfg[CFG_MODE]) != EFRA else n     # (n, n) work: Pi P Pi, EFRA
    wd = diagonal_factors(cfg, n)
    if wd.shape[0] and w != 1.0:             # diagonal, held back: its factor along H
        w = held_back_factor(P, phi, wd)
    g = np.empty(n)
    missing = any_nan(z[:, 0])
    s, lam_t, gated, cap = measurement_update(x, P, phi, z[:, 0], missing, r, cfg,
                                              projector(cfg, n), g, y[:, 0],
                                              K[:, 0], np.empty((k, k)), w, xn, Pn)
    if wd.shape[0]:
        cap = diagonal_windup_cap(Pn, phi, g, s, r, w, not (missing or gated), wd, cfg, plain)
    for i in range(m):
        for j in range(m):
            S[i, j] = s if i == j else 0.0
            SI[i, j] = 1.0 / s if i == j else 0.0
    flags = (GATED if gated else 0) + (CAP if cap else 0)
    if plain and diagonal_bad(Pn):
        flags += BAD_DIAGONAL
    return flags, lam_t


# ----------------------------------------------------------------------
# batch_filter
# ----------------------------------------------------------------------
#: Health episodes a batch run records with their step and ``P`` (more are counted).
MAX_EPISODES = 16


@njit(cache=True, error_model="numpy")
def _copy_leading(a, b):
    """``b[:] = a[:m, :n]`` for ``b`` of shape ``(m, n)``: the leading block of `a` (the
    padded work array of `exponential_batch` holds ``P`` in its first rows and columns).

    A call, not inlined: the rare steps of `exponential_batch` and the health check
    keep a dozen copies of ``x`` and ``P``, one compiled loop instead of an inlined
    copy at each (two fifths of the fused loop's code), and none from a strided view
    (whose compiled loop was five times the size).
    """
    for i in range(b.shape[0]):
        for j in range(b.shape[1]):
            b[i, j] = a[i, j]


@njit(cache=True, error_model="numpy")
def _health(P, basis, symmetric, cond_max, k, due, cheap_bad, state, episodes, P_fail, W, X):
    """The health check at the end of step `k` of a batch run.

    ``P`` is the ``(n, n)`` covariance, or the padded work array of the fused
    loop, which holds it in its leading block (``n`` is the size of the work
    arrays `W`, `X`). `state` is ``[armed, n_episodes, ...]``; a full check
    runs when it is `due` (every ``check_every`` updates) or when the cheap diagonal test
    failed while armed: on the null space `basis` of the constraints (when it
    has columns), else with `unhealthy_sym` when ``P`` is exactly `symmetric`
    (it stays so when it starts so). A failure while armed starts an episode
    (its step in `episodes`, its ``P`` in `P_fail`, up to `MAX_EPISODES`) and
    disarms; a due check whose Cholesky bound certifies ``P`` re-arms (while
    disarmed, only that bound is computed). The caller calls it only then (not
    inlined: the loops stay lean).
    """
    armed = state[0] == 1
    n = W.shape[0]
    Pc = np.empty((n, n))                    # P's n x n block (the fused loop passes its
    _copy_leading(P, Pc)                     # padded work array)
    P = Pc
    constrained = False
    bad = False
    if basis is not None:                    # None (the fused loop): not compiled in
        if basis.shape[1]:
            constrained = True
            bad = unhealthy_on(P, basis, cond_max, armed)
    if constrained:
        pass
    elif symmetric:
        bad = unhealthy_sym(P, cond_max, W, X, armed)
    elif basis is None:
        # the fused loop keeps P exactly as symmetric as it starts, which it does unless
        # the caller's P was not: `unhealthy` through Python, compiled on its first call
        # (not into the loop, for a case most runs never meet)
        with numba.objmode(bad="boolean"):
            bad = _unhealthy_call(P, cond_max, armed)
    else:
        bad = unhealthy(P, cond_max, armed)
    if bad and armed:
        e = int(state[1])
        if e < episodes.shape[0]:
            episodes[e] = k
            _copy_leading(P, P_fail[e])
        state[1] = e + 1
        state[0] = 0
    elif not bad and due:
        state[0] = 1


def _unhealthy_call(P, cond_max, exact):
    """`unhealthy` called from `_health`'s object-mode block."""
    return bool(unhealthy(P, cond_max, exact))


@njit(cache=True, error_model="numpy")
def step_batch(x, P, Z, Hm, Rv, il, Q, update_first, cfg, basis,
               means, means_p, covs, covs_p, ys, ss, gated,
               x_prior, P_prior, x_post, P_post, K, check_every, step0, cond_max,
               state, episodes, P_fail, symmetric, wd):
    """`time_update` and `measurement_update` over a record, in place on ``x``, ``P``.

    ``Z`` (N, m; NaN rows missing), ``Hm`` (N, n), ``Rv`` (N,) or (1,) (one
    variance for every step); ``il`` is ``1 / lam`` in the exponential mode
    and 1 otherwise. Writes the estimates after each update and predict
    (``means``, ``means_p``), the covariances (``covs``, ``covs_p``, when
    their length is N), the residuals ``ys`` (N, m), the innovation
    variances ``ss`` (N,), the gate decisions ``gated`` (N,), the last
    step's prior and posterior, and ``K`` (n,), the last gain. The health
    check of ``P`` (on the null space `basis` of the constraints; `basis`
    has no columns without them) runs as `_health` says at the end of each
    step; ``step0`` is the filter's update count before the run. `state` is
    ``[armed, n_episodes, n_capped, cap, w]`` on entry and exit: the
    health-check state, the count of updates whose forgetting the windup
    cap held back, whether the next time update must hold it back, and
    ``1 / lam`` when the last one did (else 1). `wd` is None but in the diagonal
    mode, where it holds its factors ``1 / sqrt(lam_i)`` (`diagonal_factors`): its
    branches are then compiled in, and only then (numba prunes ``wd is None``).

    Returns
    -------
    s, lam_t : float
        The last step's innovation variance and forgetting factor.
    """
    N = Z.shape[0]
    n, m = x.shape
    Pi = projector(cfg, n)
    plain = unconstrained(cfg, n)
    r_each = Rv.shape[0] == N
    g = np.empty(n)
    y = np.empty(m)
    T = np.empty((n, n))
    W = np.empty((n, n))
    X = np.empty((n, n))
    s = np.nan
    lam_t = cfg[CFG_LAM]
    cap = state[3] == 1
    w = state[4]
    armed = state[0] == 1                     # local copies: no store to `state` in the loop
    n_capped = 0
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    for k in range(N):
        if not update_first:
            w = il if cap else 1.0
            _mode_time_step(x, P, il, cap, wd, Q, Pi, T, k, N, means_p, covs_p, x_prior,
                            P_prior)
        z = Z[k]
        n_capped += w != 1.0
        if wd is not None:
            if w != 1.0:                     # diagonal, held back: its factor along H
                w = held_back_factor(P, Hm[k], wd)
        r = Rv[k if r_each else 0]
        s, lam_t, gk, cap = measurement_update(x, P, Hm[k], z, any_nan(z), r, cfg, Pi, g, y,
                                               K, T, w, x, P)
        if wd is not None:
            cap = diagonal_windup_cap(P, Hm[k], g, s, r, w, not (gk or any_nan(z)), wd, cfg,
                                      plain)
        w = 1.0
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
        cheap_bad = plain and diagonal_bad(P)
        if update_first:
            w = il if cap else 1.0
            _mode_time_step(x, P, il, cap, wd, Q, Pi, T, k, N, means_p, covs_p, x_prior,
                            P_prior)
        countdown -= 1                 # zero when (step0 + k + 1) % check_every == 0
        due = countdown == 0
        if due:
            countdown = check_every
        if check_every > 0 and (due or (cheap_bad and armed)):
            _health(P, basis, symmetric, cond_max, k, due, cheap_bad, state, episodes, P_fail,
                    W, X)
            armed = state[0] == 1
    state[2] += n_capped
    state[3] = 1 if cap else 0
    state[4] = w
    return s, lam_t


@njit(cache=True, error_model="numpy", inline="always")
def _time_step(x, P, il, Q, Pi, T, k, N, means_p, covs_p, x_prior, P_prior):
    """`time_update` in `step_batch`, with its histories (and the last prior)."""
    if il != 1.0 or Q.shape[0] or Pi.shape[0]:
        time_update(P, il, Q, Pi, T, P)
    _record_prior(x, P, k, N, means_p, covs_p, x_prior, P_prior)


@njit(cache=True, error_model="numpy", inline="always")
def _diagonal_time_step(x, P, forget, wd, Q, Pi, T, k, N, means_p, covs_p, x_prior,
                        P_prior):
    """`_time_step` of the diagonal mode: `diagonal_time_update` when it `forget`s (not
    held back by the windup cap), else ``P + Q`` (`time_update` with ``il = 1``)."""
    if forget:
        diagonal_time_update(P, wd, Q, Pi, T, P)
    elif Q.shape[0] or Pi.shape[0]:
        time_update(P, 1.0, Q, Pi, T, P)
    _record_prior(x, P, k, N, means_p, covs_p, x_prior, P_prior)


@njit(cache=True, error_model="numpy", inline="always")
def _mode_time_step(x, P, il, cap, wd, Q, Pi, T, k, N, means_p, covs_p, x_prior, P_prior):
    """`step_batch`'s time update of either kind: `_time_step` (``il``, or 1 when the
    windup `cap` holds it back), or `_diagonal_time_step` when the mode has per-parameter
    factors `wd` (None otherwise)."""
    if wd is None:
        _time_step(x, P, 1.0 if cap else il, Q, Pi, T, k, N, means_p, covs_p, x_prior, P_prior)
    else:
        _diagonal_time_step(x, P, il != 1.0 and not cap, wd, Q, Pi, T, k, N, means_p, covs_p,
                            x_prior, P_prior)


@njit(cache=True, error_model="numpy", inline="always")
def _record_prior(x, P, k, N, means_p, covs_p, x_prior, P_prior):
    """The histories of a time update in `step_batch` (and the last prior)."""
    if means_p.shape[0]:
        copy2(x, means_p[k])
    if covs_p.shape[0]:
        copy2(P, covs_p[k])
    if k == N - 1:
        copy2(x, x_prior)
        copy2(P, P_prior)


@njit(cache=True, error_model="numpy")
def _sweep_call(P, g, cu, il, Q, h, gn):
    """One sweep over ``P``: ``P <- (P - (g g^T) cu) il + Q``, accumulating the next
    gain ``gn = P h`` on the way (row by row, as `gain` does; ``Q`` None when absent).

    ``cu = 0`` is a time update alone (``P - 0 = P`` exactly), ``il = 1``
    (without ``Q``) an update alone. The rare steps of `exponential_batch` share
    this one compiled sweep, `_sweep_each_row` (a few steps in a hundred: the
    four-row loop would not pay its compile work here); the usual steps inline
    `_sweep_rows`, or `_sweep_each_row` with ``Q`` (`_usual_steps`). Both add the
    same products in the same order: the same numbers.
    """
    _sweep_each_row(P, g, cu, il, Q, h, gn)


@njit(cache=True, error_model="numpy", inline="always")
def _sweep_rows(P, g, cu, il, h, gn, n, L):
    """`_sweep_call`'s sweep without ``Q``, four rows at a time.

    ``n`` is the length of ``h`` (an argument: a compile-time constant where
    the caller has one, see `exponential_batch`); ``P`` has at least ``n``
    rows of ``L >= n`` entries (the padded work array of `exponential_batch`,
    zero past column ``n``; only its first ``n`` rows are swept), ``g`` and
    ``gn`` have length ``L`` (``g`` zero past ``n``: the padding stays zero).
    Each ``g_j``, ``gn_j`` is loaded once for four rows and the four contributions
    are added to ``gn_j`` in row order, so the numbers are those of the
    row-by-row loop. The indices are unsigned (``np.uint64``: no
    negative-index fix-up) and ``P`` is indexed directly (no row views): with
    ``L`` a multiple of 8 the compiler vectorizes the inner loop with no
    scalar remainder.
    """
    if n == 2:                       # the same operations, written out (no loop overhead)
        g0, g1 = g[0], g[1]
        h0, h1 = h[0], h[1]
        v00 = (P[0, 0] - (g0 * g0) * cu) * il
        v01 = (P[0, 1] - (g0 * g1) * cu) * il
        v10 = (P[1, 0] - (g1 * g0) * cu) * il
        v11 = (P[1, 1] - (g1 * g1) * cu) * il
        P[0, 0] = v00
        P[0, 1] = v01
        P[1, 0] = v10
        P[1, 1] = v11
        gn[0] = (0.0 + v00 * h0) + v10 * h1
        gn[1] = (0.0 + v01 * h0) + v11 * h1
        return
    L, un = np.uint64(L), np.uint64(n)
    one = np.uint64(1)
    for j in range(L):
        gn[j] = 0.0
    i = np.uint64(0)
    while i + np.uint64(3) < un:               # rows i, ..., i + 3
        i1, i2, i3 = i + one, i + np.uint64(2), i + np.uint64(3)
        a0, a1, a2, a3 = g[i], g[i1], g[i2], g[i3]
        h0, h1, h2, h3 = h[i], h[i1], h[i2], h[i3]
        for j in range(L):
            gj = g[j]
            v0 = (P[i, j] - (a0 * gj) * cu) * il
            v1 = (P[i1, j] - (a1 * gj) * cu) * il
            v2 = (P[i2, j] - (a2 * gj) * cu) * il
            v3 = (P[i3, j] - (a3 * gj) * cu) * il
            P[i, j] = v0
            P[i1, j] = v1
            P[i2, j] = v2
            P[i3, j] = v3
            gn[j] = (((gn[j] + v0 * h0) + v1 * h1) + v2 * h2) + v3 * h3
        i += np.uint64(4)
    while i < un:                              # the last rows, one at a time
        ai = g[i]
        hi = h[i]
        for j in range(L):
            v = (P[i, j] - (ai * g[j]) * cu) * il
            P[i, j] = v
            gn[j] += v * hi
        i += one


@njit(cache=True, error_model="numpy", inline="always")
def _sweep_each_row(P, g, cu, il, Q, h, gn):
    """`_sweep_call`'s sweep row by row, with ``Q`` or without (None: numba compiles
    the loop without the branch) (``n`` the length of ``h``: over the first ``n``
    rows and columns of a padded ``P``; ``gn`` is zeroed over its whole length: its
    padding stays zero)."""
    n = h.shape[0]
    for j in range(gn.shape[0]):
        gn[j] = 0.0
    for i in range(n):
        ai = g[i]
        hi = h[i]
        for j in range(n):
            v = (P[i, j] - (ai * g[j]) * cu) * il
            if Q is not None:
                v += Q[i, j]
            P[i, j] = v
            gn[j] += v * hi


@njit(cache=True, error_model="numpy")
def exponential_batch(x, P, Z, Hm, Rv, il, Q, cfg, update_first, means, covs, covs_p, ys,
                      ss, x_prior, P_prior, x_post, P_post, K, check_every, step0, cond_max,
                      state, episodes, P_fail, symmetric, Pw, scales, lags, dims):
    """`step_batch` of the default configuration with one output, fused (see the module).

    Exponential forgetting, no gate, no constraints, ``m = 1``: ``ss`` has
    length 1 (the last step), ``ys`` length N (every residual) or 1 (the
    last). With covariance histories (``covs``, ``covs_p`` of length N) each
    step's sweep runs in its two halves, ``P`` written after each. Arguments
    and returns otherwise as `step_batch` (``means_p`` is ``means`` shifted
    by one step; the caller builds it), but for ``lam_t``.

    ``Pw`` is (n + 2, L) work space of zeros, ``L = padded_width(n, 0)``,
    from `aligned_zeros`: the loop keeps ``P`` in the first ``n`` columns of
    its first ``n`` rows (see `_sweep_rows`) and the gains ``g``, ``gn`` in
    its last two rows, every row on a cache line, and writes ``P`` back at the
    end.

    ``scales``: None, or scaled units (``ARX.fit``,
    :mod:`rlsfilt.models._units`), ``(hsc, zsc, msc, ysc, Hb)``: the recursion
    then runs on the rows ``Hm[k] * hsc`` and targets ``Z[k] * zsc`` and
    writes ``means[k] = x * msc`` and ``ys[k] = y * ysc``. The factors are
    powers of two, so the products are exact (in range) and the numbers those
    of a run on scaled copies of the record mapped back, without the copies.
    The scaled rows go through ``Hb`` (``(_SCALED_BLOCK + 1, n)``, in F order as
    the blocks of `lag_gram`: the two share one compiled `lag_block`) a block at a
    time, written well before they are read (a row stored just before its
    loads stalls them). numba compiles the two cases apart (``scales is
    None`` is decided at compile time, the branches pruned), so the plain loop
    carries none of this; each step takes its rows afresh (a row view carried
    from one step to the next cost the scaled loop 10 %).

    ``lags``: None, or (with `scales`) the rows' lagged signals
    (:mod:`rlsfilt.filters._kernels_lagged`): the blocks are then filled from
    the signals (``Hm`` is not read), so no regressor matrix need exist.

    ``dims``: `_dimension_witness` of ``n``. A tuple of ``n`` zeros makes ``n``
    a compile-time constant (``len`` of a tuple is part of its type): numba
    compiles the function once per such ``n`` and the compiler unrolls the
    loops over ``n``; an array makes it one loop for every ``n`` (see
    `_SPECIALISED` for where the constant pays).

    The usual steps run in `_usual_steps`, a loop without calls; this
    function takes the others (the windup cap, health checks, stored
    covariances, the last two steps, the end of a block of rows), then hands
    back.
    """
    N = Z.shape[0]
    n = len(dims)                                    # a constant when dims is a tuple
    hasq = Q is not None
    store = covs.shape[0] > 0
    th = x[:, 0].copy()                              # local: no aliasing in the loop
    for i in range(n):
        for j in range(Pw.shape[1]):
            Pw[i, j] = P[i, j] if j < n else 0.0
    g = Pw[n]                                        # the gains: rows n, n + 1
    gn = Pw[n + 1]
    W = np.empty((n, n))
    X = np.empty((n, n))
    cap = state[3] == 1
    n_capped = np.int64(0)                           # a literal 0: two compiles
    w = state[4]
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    if scales is not None:
        hsc, zsc, msc, ysc, Hb = scales
        _fill_block(Hm, lags, np.int64(0), hsc, Hb)    # not a literal 0: one compile
        h = Hb[0]
    else:
        h = Hm[0]
    if update_first:                                 # the gain of P
        _sweep_call(Pw, g, 0.0, 1.0, None, h, gn)
    else:                                            # P^- and its gain
        w = il if cap else 1.0
        _sweep_call(Pw, g, 0.0, 1.0 if cap else il, Q, h, gn)
        if store:
            _copy_leading(Pw, covs_p[0])
    g, gn = gn, g
    if not update_first and N == 1:
        _copy_leading(x, x_prior)
        _copy_leading(Pw, P_prior)
    s = np.nan
    yk = np.nan
    H = Hm if scales is None else Hb
    k = np.int64(0)                                  # not a literal: one compile
    while True:
        off = 0 if scales is None else k - k % _SCALED_BLOCK    # the row of step k in H: k - off
        (k, cu, kc, updated, cap, check, due, cheap_bad, s, yk, w, countdown, n_capped,
         odd) = _usual_steps(k, N, Z, H, off, Rv, il, Q, cfg, means, ys, th, Pw, g, gn, w,
                             countdown, n_capped, check_every, state, store, scales, dims)
        if odd:
            g, gn = gn, g
        # step k is not a usual one (or the last of a block of rows): its sweep
        last = k == N - 1
        hn = H[min(k + 1, N - 1) - off]              # the next row
        if last:
            _store_column(th, x)
            if updated:
                for i in range(n):
                    K[i] = g[i] * kc
        # a due health check looks at P after the fused sweep: that is the P it
        # tests with update_first, and otherwise P / lam, whose definiteness and
        # condition number are those of P (with Q the two halves run apart)
        if last or cap or store or (check and hasq and not update_first):
            _unfused_step(x, Pw, g, gn, cu, 1.0 if cap else il, Q, hn, k,
                          last, check, update_first, due, cheap_bad, cond_max, state,
                          episodes, P_fail, W, X, symmetric, x_prior, P_prior, x_post,
                          P_post, covs, covs_p)
        else:
            _sweep_call(Pw, g, cu, il, Q, hn, gn)
            if check:
                _health(Pw, None, symmetric, cond_max, k, due, cheap_bad, state, episodes,
                        P_fail, W, X)
        g, gn = gn, g
        if k == N - 2 and not update_first:
            _store_column(th, x)
            _copy_leading(x, x_prior)
            _copy_leading(Pw, P_prior)
        if last:
            break
        k += 1
        if scales is not None and k % _SCALED_BLOCK == 0:
            _fill_block(Hm, lags, k, hsc, Hb)        # the next block (row k: the same bits)
    _copy_leading(Pw, P)
    if not update_first:
        w = 1.0                                      # no time update after the last update
    state[2] += n_capped
    ss[0] = s
    if scales is not None:
        yk *= ysc
    ys[ys.shape[0] - 1, 0] = yk
    state[3] = 1 if cap else 0
    state[4] = w
    return s


@njit(cache=True, error_model="numpy", _nrt=False)
def _usual_steps(k, N, Z, H, off, Rv, il, Q, cfg, means, ys, th, Pw, g, gn, w, countdown,
                 n_capped, check_every, state, store, scales, dims):
    """The steps of `exponential_batch` from step `k` on, up to the first that is not
    a usual one, whose sweep it leaves to the caller.

    A usual step is followed by the fused sweep alone: it is not the last
    step or the one before, nor the last of a block of rows ``H`` (row ``k -
    off``; ``H`` has a row past the block, the next step's), the windup cap
    does not hold its forgetting back, no health check is due or called for,
    no covariance is stored. This loop makes no call, so its values stay in
    registers (a call in the loop, even on a branch not taken, made the
    compiler keep them on the stack: 13 % of the time at 4 parameters).

    Returns the step it stopped at, its values the caller needs (``cu``,
    ``kc``, ``updated``, ``cap``, ``check``, ``due``, ``cheap_bad``, ``s``,
    ``y``), the running ``w``, ``countdown``, ``n_capped`` and whether the
    gains ``g``, ``gn`` changed places an odd number of times.
    """
    n = len(dims)
    L = Pw.shape[1]
    r_each = Rv.shape[0] == N
    every_y = ys.shape[0] == N
    rows = H.shape[0]
    odd = False
    while True:
        zk = Z[k, 0]
        if scales is not None:
            zk *= scales[1]
        kr = k - off
        q = 0.0
        acc = 0.0
        for i in range(n):
            hi = H[kr, i]
            q += hi * g[i]
            acc += hi * th[i]
        r = Rv[k if r_each else 0]
        s = w * q + r                                # S = H P H^T + R
        c = 1.0 / s
        updated = zk == zk                           # not missing
        n_capped += w != 1.0
        cu = exponential_coefficient(q, c, w, updated)
        kc = w * c
        if updated:
            yk = zk - acc                            # y = z - H x
            for i in range(n):
                th[i] = th[i] + (g[i] * kc) * yk     # x = x + K y,  K = P H^T / S
            hph = q * r * kc                         # H P H^T after the update
        else:
            yk = np.nan
            hph = q * w
        if scales is not None:
            msc = scales[2]
            for i in range(n):
                means[k, i, 0] = th[i] * msc[i]
            if every_y:
                ys[k, 0] = yk * scales[3]
        else:
            for i in range(n):
                means[k, i, 0] = th[i]
            if every_y:
                ys[k, 0] = yk
        # the diagonal of the updated P: the cheap check and the windup cap
        tr, spread, dmin = _diagonal_stats(Pw, g, cu, H[kr], n)
        cheap_bad = not (dmin > 0.0 and tr < np.inf)
        cap = windup_cap(tr, spread, hph, il, cfg)
        w = il if cap else 1.0                       # the next update's w
        countdown -= 1                 # zero when (step0 + k + 1) % check_every == 0
        due = countdown == 0
        if due:
            countdown = check_every
        check = check_every > 0 and (due or (cheap_bad and state[0] == 1))
        if cap or check or store or k + 2 >= N or kr + 2 >= rows:
            return (k, cu, kc, updated, cap, check, due, cheap_bad, s, yk, w, countdown,
                    n_capped, odd)
        # the fused sweep, P <- (P - (g g^T) cu) il + Q with the next gain: the branch is
        # on an argument, so numba drops the other loop before inlining (Q is None without)
        if Q is None:
            _sweep_rows(Pw, g, cu, il, H[kr + 1], gn, n, L)
        else:
            _sweep_each_row(Pw, g, cu, il, Q, H[kr + 1], gn)
        g, gn = gn, g
        odd = not odd
        k += 1


_SCALED_BLOCK = 256   # rows `exponential_batch` scales at a time
#: The sizes `exponential_batch` is compiled for with ``n`` a constant. Each is a
#: compile of its own (about 3 s of CPU the first time it runs); measured against the one
#: loop for every ``n`` (batch_filter, lam = 0.99, 10^4 to 10^5 samples, median of 7
#: interleaved rounds in one process, thread CPU time): 1.00x at 2 parameters, 0.84x (slower)
#: at 3, 1.02x at 4, 1.12x at 5, 1.00x at 6, 0.97x at 8. Only 5 is kept: the batch_filter
#: target at 5 parameters (at most the hand-written loop's time, benchmarks/bench_targets.py)
#: is met with it and missed without.
_SPECIALISED = (5,)


def _dimension_witness(n):
    """The ``dims`` argument of `exponential_batch` for `n` parameters: a tuple of
    `n` zeros for the sizes of `_SPECIALISED` (``n`` is then a constant of the
    compiled loop), else an array of length `n` (one compiled loop for every
    other ``n``)."""
    return (0,) * n if n in _SPECIALISED else np.zeros(n, dtype=np.int8)


@njit(cache=True, error_model="numpy", inline="always")
def _fill_block(Hm, lags, k, hsc, Hb):
    """The block of scaled rows from row `k`: from `Hm` (`_scale_block`), or read from the
    lagged signals `lags` (`_kernels_lagged.lag_block`; ``Hm`` is then not read)."""
    if lags is None:
        _scale_block(Hm, k, hsc, Hb)
    else:
        lag_block(lags, k, hsc, Hb)


@njit(cache=True, error_model="numpy", inline="always")
def _scale_block(Hm, k, hsc, Hb):
    """``Hb[r] = Hm[k + r] * hsc`` for the rows of the block from row `k` (and the next
    block's first row) that exist."""
    rows = min(Hb.shape[0], Hm.shape[0] - k)
    n = hsc.shape[0]
    for i in range(n):                       # column by column: `Hb` is in F order
        for r in range(rows):
            Hb[r, i] = Hm[k + r, i] * hsc[i]


@njit(cache=True, error_model="numpy", inline="always")
def _store_column(th, x):
    """``x[:, 0] = th`` as a loop (a slice assignment compiles numba's shape-error
    message, string formatting included: a second of CPU on the first run)."""
    for i in range(th.shape[0]):
        x[i, 0] = th[i]


@njit(cache=True, error_model="numpy", inline="always")
def _unfused_step(x, Pw, g, gn, cu, il, Q, h, k, last, check, update_first, due, cheap_bad,
                  cond_max, state, episodes, P_fail, W, X, symmetric, x_prior, P_prior,
                  x_post, P_post, covs, covs_p):
    """The rare steps of `exponential_batch` (inlined there: the usual steps run in
    `_usual_steps`, so this stays out of the hot loop; a separate function was compiled
    again with its callees linked in, a fifth of the first run's compile work): a step
    whose time update the windup cap holds back (`il` is then 1), and a step whose
    updated ``P`` is checked, kept (the last) or stored (``covs``, ``covs_p`` of
    length N), whose sweep runs in two halves:
    the update, then the time update with the next gain (after the last
    update only with `update_first`). The sweeps run on the padded ``Pw``, the
    copies and the checks read its leading ``n x n`` block, ``P``."""
    store = covs.shape[0] > 0
    if not (check or last or store):
        _sweep_call(Pw, g, cu, il, Q, h, gn)
        return
    _sweep_call(Pw, g, cu, 1.0, None, h, gn)         # the update half, no Q
    if store:
        _copy_leading(Pw, covs[k])
    if last:
        _copy_leading(x, x_post)
        _copy_leading(Pw, P_post)
    if check and not update_first:
        _health(Pw, None, symmetric, cond_max, k, due, cheap_bad, state, episodes, P_fail, W,
                X)
    if not last or update_first:
        _sweep_call(Pw, g, 0.0, il, Q, h, gn)
        if store:
            _copy_leading(Pw, covs_p[k if update_first else k + 1])
    if check and update_first:
        _health(Pw, None, symmetric, cond_max, k, due, cheap_bad, state, episodes, P_fail, W,
                X)
    if last and update_first:
        _copy_leading(x, x_prior)
        _copy_leading(Pw, P_prior)


class BatchResult:
    """What `run_batch` returns: the histories and the last step's state."""

    __slots__ = ("buffer", "means", "covariances", "means_p", "covariances_p", "ys", "ss",
                 "gated", "x", "P", "x_prior", "P_prior", "x_post", "P_post", "K_last", "s_last",
                 "lam_t_last", "state", "episodes", "P_fail", "H_last", "z_last", "y_last")


def run_batch(x, P, Z, Hm, Rv, cfg, Q, basis, update_first, store_covariances,
              check_every, step0, cond_max, state, lead=0, residuals=False, scales=None,
              lags=None):
    """Run `RecursiveLeastSquares` over a validated record; `x`, `P` are not modified.

    `cfg` is ``forgetting.kernel_config``; `Q` None when absent; `basis`
    the null-space basis of the constraints (None without); `state` the
    ``[armed, n_episodes, n_capped, cap, w]`` of `step_batch` (a new array is
    returned in the result). Chooses `exponential_batch` for the default
    configuration with one output, `step_batch` otherwise. Returns a
    `BatchResult` (``ss``, ``gated`` hold the last step only after
    `exponential_batch`, and ``ys`` too unless `residuals`; ``H_last``,
    ``z_last``, ``y_last``: the last row, target and residual as the filter
    saw them). The
    estimate histories share one buffer, ``buffer``: `lead` rows of NaN (room
    for what a caller puts before the run), the estimate before the first
    update, then the estimate after each update (``means``); ``means_p`` is a
    read-only view of it (the estimate before each update is the one after
    the update before), so memory stays one ``N x dim_x x dim_z`` array.

    `residuals` may be an array ``(N, m)``: every residual is written there
    (``ys`` is that array). `scales` (``ARX.fit``): powers of two ``(hsc,
    zsc, msc, ysc)``, arrays of shape ``(n,)``, ``(m,)``, ``(n, m)``,
    ``(m,)``; the recursion then runs on ``Hm * hsc`` and ``Z * zsc`` (`x`
    and `P` are in those units) and the histories are written mapped back,
    ``means = x * msc`` (``buffer`` too) and ``ys = y * ysc``: the numbers of
    a run on scaled copies of the record, mapped back after, bit for bit
    (see `exponential_batch`, which applies them on the fly).

    `lags` (``ARX.fit``): the rows as lagged signals
    (:mod:`rlsfilt.filters._kernels_lagged`) instead of `Hm` (None then): the
    fused loop reads them from the signals, the other loop from a matrix built
    here.
    """
    N = len(Z)
    n, m = x.shape
    if lags is not None:
        if scales is None:                            # unit factors: the same numbers
            scales = (np.ones(n), np.ones(m), np.ones((n, m)), np.ones(m))
        Hm = np.empty((0, n))
    if scales is not None:
        hsc, zsc, msc, ysc = (np.ascontiguousarray(a, dtype=np.float64) for a in scales)
    mode, lam, gate = int(cfg[CFG_MODE]), cfg[CFG_LAM], cfg[CFG_GATE]
    # 1 / lam in the exponential mode; in the diagonal mode 1 / min(lam) (not 1 when it
    # forgets: the time update then reads its factors from cfg)
    il = 1.0 / lam if mode == EXPONENTIAL or mode == DIAGONAL else 1.0
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
    # one buffer for both estimate histories: row k + 1 is the estimate after
    # update k, row 0 the estimate before the first (x does not change in a predict)
    buf = np.empty((lead + N + 1, n, m))
    buf[:lead] = np.nan
    buf[lead] = x if scales is None else x * msc
    out.buffer = buf
    out.means = buf[lead + 1:]
    means_p = buf[lead + 1:] if update_first else buf[lead:-1]
    out.means_p = means_p.view()
    out.means_p.flags.writeable = False
    K = np.zeros(n)
    symmetric = bool(np.array_equal(out.P, out.P.T))    # then it stays exactly symmetric
    out.state = np.array(state, dtype=np.float64)
    out.episodes = np.zeros(MAX_EPISODES, dtype=np.int64)
    out.P_fail = np.empty((MAX_EPISODES, n, n))
    fused = mode == EXPONENTIAL and gate == np.inf and len(cfg) == CFG_PI and m == 1 and N > 0
    if lags is not None and not fused:                # the step loop reads a matrix
        Hm = np.empty((N, n))
        lag_rows_numpy(lags, 0, np.ones(n), Hm)
        Hc, lags = Hm, None
    covs = np.empty((N if store_covariances else 0, n, n))
    covs_p = np.empty((N if store_covariances else 0, n, n))
    out.covariances = covs if store_covariances else None
    out.covariances_p = covs_p if store_covariances else None
    given = isinstance(residuals, np.ndarray)
    if fused:
        out.ys = residuals if given else np.empty((N if residuals else 1, 1))
        out.ss = np.empty(1)
        out.s_last = exponential_batch(
            out.x, out.P, Zc, Hc, Rv, il, None if Q is None else Qa, cfg, bool(update_first),
            out.means, covs, covs_p, out.ys, out.ss, out.x_prior, out.P_prior, out.x_post,
            out.P_post, K, int(check_every), int(step0), float(cond_max), out.state,
            out.episodes, out.P_fail, symmetric, aligned_zeros((n + 2, padded_width(n, 0))),
            None if scales is None else (hsc, zsc[0], msc[:, 0].copy(), ysc[0],
                                         aligned_zeros((n, _SCALED_BLOCK + 1)).T), lags,
            _dimension_witness(n))
        out.gated = np.zeros(1, dtype=np.bool_)
        out.lam_t_last = lam
    else:
        if scales is not None:                        # scaled copies, the histories mapped after
            Hc, Zc = Hm * hsc, Z * zsc
        out.ys, out.ss = np.empty((N, m)), np.empty(N)
        out.gated = np.zeros(N, dtype=np.bool_)
        out.s_last, out.lam_t_last = step_batch(
            out.x, out.P, Zc, Hc, Rv, il, Qa, bool(update_first), cfg, Ba,
            out.means, np.empty((0, n, m)), covs, covs_p, out.ys, out.ss, out.gated,
            out.x_prior, out.P_prior, out.x_post, out.P_post, K,
            int(check_every), int(step0), float(cond_max), out.state, out.episodes,
            out.P_fail, symmetric, cfg[CFG_PI:CFG_PI + n].copy() if mode == DIAGONAL else None)
        if scales is not None:                        # inf where beyond the double range
            with np.errstate(over="ignore", under="ignore"):
                np.multiply(out.means, msc, out=out.means)
                np.multiply(out.ys, ysc, out=out.ys)
        if given:
            residuals[...] = out.ys
            out.ys = residuals
    if N:                                             # the last step as the filter saw it
        if lags is not None:                          # the last row, read as the loop read it
            out.H_last = np.empty((1, n))
            lag_rows_numpy(lags, N - 1, hsc, out.H_last)
            out.H_last, out.z_last, out.y_last = out.H_last[0], Z[-1] * zsc, out.ys[-1] / ysc
        elif scales is not None:
            out.H_last, out.z_last, out.y_last = Hm[-1] * hsc, Z[-1] * zsc, out.ys[-1] / ysc
        else:
            out.H_last, out.z_last, out.y_last = Hc[-1], Zc[-1], out.ys[-1]
    if N and np.isnan(Z[-1]).any():                   # the last sample was missing: no gain
        K[:] = 0.0
    out.K_last = K.reshape(n, 1)
    return out
