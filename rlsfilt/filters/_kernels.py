"""Compiled (numba) kernels of the RLS recursion.

The pure-NumPy reference of the same recursion is ``_batch_reference`` in
:mod:`rlsfilt.filters.rls`; the tests hold the two equal to 1e-12. Every
function here is ``njit(cache=True)``: the machine code is written to the
``__pycache__`` next to this file (or to ``NUMBA_CACHE_DIR``) on the first
call and loaded from there by later processes, so only the very first run
after an install pays the compilation.

Arithmetic of one step (the same helpers serve the batch kernel and the
streaming :meth:`RecursiveLeastSquares.update`, so the two agree bit for
bit)::

    P <- P * (1/lam) + Q                     predict, elementwise
    g = P phi                                column sweep; P is symmetric
    s = phi . g + r                          innovation variance
    c = 1 / s                                the only division of the step
    K = g c                                  gain
    y = z - phi . x                          a-priori residual, per output
    x <- x + K y^T
    P <- P - (g g^T) c                       g_i g_j = g_j g_i exactly, so
                                             P stays exactly symmetric

The batch kernel makes one sweep over ``P`` per step that applies the
measurement update, the next time update and the next gain together
(``v = (P_ij - g_i g_j c) * il; P_ij = v; g'_j += v phi'_i``): about
``6 dim_x^2`` floating-point operations and one read and one write of ``P``
per step, plus ``4 dim_x dim_z`` for the residual and the estimate. The
sweep runs along rows of the C-contiguous ``P`` with no reduction in the
inner loop, so LLVM vectorizes it without any reassociation (no
``fastmath``): the results do not depend on the vector width, and the
streaming methods, which run the same arithmetic in separate calls, agree
with the batch kernel bit for bit.

``batch_filter_kernel``, ``predict_kernel`` and ``update_kernel`` run this
fused arithmetic for the default mode (exponential forgetting plus an
optional random walk ``Q``, no gate, no constraints). Every other option
(the anti-windup modes of :mod:`rlsfilt.filters.forgetting`, the outlier
gate, the equality constraints) runs ``general_batch_kernel``, or
``general_predict`` and ``general_update_kernel`` when streaming: one
unfused step per sample that follows the NumPy reference operation by
operation (``rls._measurement_step``, ``forgetting.update_<mode>``,
``rls._project``), so that it agrees with it to round-off and the batch and
streaming runs agree bit for bit.
"""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable

__all__ = []

MODE_EXPONENTIAL = 0


@njit(cache=True)
def _predict_inplace(P, il, Q, q_zero):
    """``P <- P * il + Q`` in place (``Q`` ignored when `q_zero`)."""
    n = P.shape[0]
    if q_zero:
        for j in range(n):
            for i in range(n):
                P[j, i] = P[j, i] * il
    else:
        for j in range(n):
            for i in range(n):
                P[j, i] = P[j, i] * il + Q[j, i]


@njit(cache=True)
def _predict_gain_inplace(P, il, Q, q_zero, predict, phi, g):
    """Optional predict fused with ``g = P phi``; returns nothing.

    ``g`` is accumulated row by row (``g += P[j, :] phi_j``), which for a
    symmetric ``P`` is ``P phi`` summed in the natural order, with a
    contiguous, reduction-free inner loop.
    """
    n = P.shape[0]
    for i in range(n):
        g[i] = 0.0
    if not predict:
        for j in range(n):
            pj = phi[j]
            for i in range(n):
                g[i] += P[j, i] * pj
    elif q_zero:
        for j in range(n):
            pj = phi[j]
            for i in range(n):
                v = P[j, i] * il
                P[j, i] = v
                g[i] += v * pj
    else:
        for j in range(n):
            pj = phi[j]
            for i in range(n):
                v = P[j, i] * il + Q[j, i]
                P[j, i] = v
                g[i] += v * pj


@njit(cache=True, inline="always")
def _innovation_variance(phi, g, r):
    """``s = phi . g + r``."""
    s = 0.0
    for i in range(phi.shape[0]):
        s += phi[i] * g[i]
    return s + r


@njit(cache=True, inline="always")
def _residual(x, phi, z, y):
    """``y = z - phi . x`` for each output column; ``y`` has ``dim_z`` entries."""
    n, m = x.shape
    for c in range(m):
        acc = 0.0
        for i in range(n):
            acc += phi[i] * x[i, c]
        y[c] = z[c] - acc


@njit(cache=True, inline="always")
def _measurement_update(x, P, g, c, y, K, xn, Pn):
    """``K = g c``, ``xn = x + K y^T``, ``Pn = P - (g g^T) c``.

    ``xn``/``Pn`` may be ``x``/``P`` themselves (in-place update).
    """
    n, m = x.shape
    for i in range(n):
        K[i] = g[i] * c
    for i in range(n):
        ki = K[i]
        for j in range(m):
            xn[i, j] = x[i, j] + ki * y[j]
    for i in range(n):
        gi = g[i]
        for j in range(n):
            Pn[i, j] = P[i, j] - (gi * g[j]) * c


@njit(cache=True)
def _copy2(a, b):
    """``b[:] = a`` for 2-D arrays, as a plain loop."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            b[i, j] = a[i, j]


@njit(cache=True, inline="always")
def _any_nan(z):
    for v in z:
        if v != v:
            return True
    return False


@njit(cache=True, inline="always")
def _estimate_update(x, g, c, y, K):
    """``K = g c`` and ``x <- x + K y^T`` in place."""
    n, m = x.shape
    for i in range(n):
        ki = g[i] * c
        K[i] = ki
        for j in range(m):
            x[i, j] = x[i, j] + ki * y[j]


@njit(cache=True, inline="always")
def _covariance_pass(P, g, c, update, predict, il, Q, q_zero, phin, gn):
    """One sweep over ``P``: update, predict and the next gain, fused.

    ``P <- P - (g g^T) c`` (when `update`), then ``P <- P * il + Q`` (when
    `predict`), while accumulating ``gn = P phin`` for the next step. The
    elementwise arithmetic is exactly that of the separate steps.
    """
    n = P.shape[0]
    for i in range(n):
        gn[i] = 0.0
    if update and predict and q_zero:            # the common case, branch-free
        for i in range(n):
            gi = g[i]
            hi = phin[i]
            for j in range(n):
                v = (P[i, j] - (gi * g[j]) * c) * il
                P[i, j] = v
                gn[j] += v * hi
    elif update and predict:
        for i in range(n):
            gi = g[i]
            hi = phin[i]
            for j in range(n):
                v = (P[i, j] - (gi * g[j]) * c) * il + Q[i, j]
                P[i, j] = v
                gn[j] += v * hi
    elif update:
        for i in range(n):
            gi = g[i]
            hi = phin[i]
            for j in range(n):
                v = P[i, j] - (gi * g[j]) * c
                P[i, j] = v
                gn[j] += v * hi
    else:
        _predict_gain_inplace(P, il, Q, q_zero, predict, phin, gn)


@njit(cache=True, inline="always")
def _covariance_pass_store(P, g, c, update, predict, il, Q, q_zero, phin, gn, C_post, C_prior):
    """`_covariance_pass` that also writes ``P`` after the update into
    ``C_post`` and after the predict into ``C_prior`` (same arithmetic)."""
    n = P.shape[0]
    for i in range(n):
        gn[i] = 0.0
    if update and predict and q_zero:            # the common case, branch-free
        for i in range(n):
            gi = g[i]
            hi = phin[i]
            for j in range(n):
                v = P[i, j] - (gi * g[j]) * c
                C_post[i, j] = v
                v = v * il
                C_prior[i, j] = v
                P[i, j] = v
                gn[j] += v * hi
    else:
        for i in range(n):
            gi = g[i]
            hi = phin[i]
            for j in range(n):
                v = P[i, j]
                if update:
                    v = v - (gi * g[j]) * c
                C_post[i, j] = v
                if predict:
                    if q_zero:
                        v = v * il
                    else:
                        v = v * il + Q[i, j]
                C_prior[i, j] = v
                P[i, j] = v
                gn[j] += v * hi


@njit(cache=True)
def batch_filter_kernel(x, P, Z, Hm, Rv, il, Q, q_zero, update_first, mode, params,
                        means, covs, covs_p, ys, ss,
                        x_prior, P_prior, x_post, P_post, K,
                        check_every, step0, cond_max, P_fail):
    """Run the recursion over a record, in place on the working ``x``, ``P``.

    Each step makes one sweep over ``P`` that applies the measurement
    update, the next time update and the next gain ``P phi`` together.

    Parameters
    ----------
    x : (n, m) float64, P : (n, n) float64
        Working state (overwritten with the final state).
    Z : (N, m), Hm : (N, n), Rv : (N,) or (1,)
        Measurements (NaN rows missing), regressors, noise variances (one
        for all steps when ``Rv`` has length 1).
    il : float
        ``1 / lam``.
    Q : (n, n), q_zero : bool
        Random walk and whether it is identically zero (then ``Q`` may be
        empty).
    update_first : bool
        Update before predict in each step.
    mode : int, params : (p,) float64
        Covariance-update mode (``MODE_EXPONENTIAL``) and its parameters.
    means : (N, n, m)
        Estimate after each update (written). The estimates after each
        predict are the same numbers shifted by one step (or not shifted
        with `update_first`); the caller builds them.
    covs, covs_p : (N, n, n) or (0, n, n)
        Covariances after each update and each predict; not written when
        their length is 0.
    ys : (N, m) or (1, m), ss : (N,) or (1,)
        Residuals (NaN when missing) and innovation variances, for every
        step or (length 1) for the last step only.
    x_prior, P_prior, x_post, P_post : arrays shaped as x and P
        The last step's prior and posterior (written when ``N > 0``).
    K : (n,)
        Gain of the last non-missing update (kept when none).
    check_every, step0, cond_max, P_fail
        Health check of ``P`` at the end of every step ``k`` with
        ``(step0 + k + 1) % check_every == 0`` (none when `check_every` is
        0), as ``rls._health_problem`` does it; the first failing ``P`` is
        copied to ``P_fail`` (n, n).

    Returns
    -------
    s : float
        Innovation variance of the last step (NaN when ``N == 0``).
    k_fail : int
        Step of the first failed health check, or -1.
    """
    if mode != MODE_EXPONENTIAL:
        raise ValueError("batch_filter_kernel: unknown covariance-update mode")
    N = Z.shape[0]
    n, m = x.shape
    if N == 0:
        return np.nan, -1
    store = covs.shape[0] == N
    if m == 1 and not store:
        return _run_single(x, P, Z, Hm, Rv, il, Q, q_zero, update_first, means, ys, ss,
                           x_prior, P_prior, x_post, P_post, K,
                           check_every, step0, cond_max, P_fail)
    r_each = Rv.shape[0] == N                  # else one variance for all steps
    hist = ys.shape[0] == N                    # else ys, ss hold the last step only
    predict = not (il == 1.0 and q_zero)       # otherwise the time update is the identity
    g = np.empty(n)
    gn = np.empty(n)
    y = np.empty(m)
    k_fail = -1
    # steps to the next health check (a countdown: no division per step)
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    # the time update before the first measurement update, and its gain
    _predict_gain_inplace(P, il, Q, q_zero, predict and not update_first, Hm[0], g)
    if not update_first:
        if store:
            _copy2(P, covs_p[0])
        if N == 1:
            _copy2(x, x_prior)
            _copy2(P, P_prior)
    s = np.nan
    for k in range(N):
        phi = Hm[k]
        s = _innovation_variance(phi, g, Rv[k if r_each else 0])
        hk = k if hist else 0          # histories, or just the last step
        ss[hk] = s
        c = 1.0 / s
        z = Z[k]
        update = not _any_nan(z)
        if update:
            _residual(x, phi, z, y)
            _estimate_update(x, g, c, y, K)
            for j in range(m):
                ys[hk, j] = y[j]
        else:
            for j in range(m):
                ys[hk, j] = np.nan
        _copy2(x, means[k])
        countdown -= 1                 # zero when (step0 + k + 1) % check_every == 0
        check = countdown == 0 and k_fail < 0
        if countdown == 0:
            countdown = check_every
        if k < N - 1 and check:                       # unfused, to look at P in between
            kp = k if update_first else k + 1
            _covariance_pass(P, g, c, update, False, il, Q, q_zero, phi, gn)
            if store:
                _copy2(P, covs[k])
            if not update_first and _unhealthy(P, cond_max):
                k_fail = k
                _copy2(P, P_fail)
            _predict_gain_inplace(P, il, Q, q_zero, predict, Hm[k + 1], gn)
            if store:
                _copy2(P, covs_p[kp])
            if update_first and _unhealthy(P, cond_max):
                k_fail = k
                _copy2(P, P_fail)
            g, gn = gn, g
            if k == N - 2 and not update_first:
                _copy2(x, x_prior)
                _copy2(P, P_prior)
        elif k < N - 1:
            kp = k if update_first else k + 1        # index of the predict that follows
            if store:
                _covariance_pass_store(P, g, c, update, predict, il, Q, q_zero, Hm[k + 1], gn,
                                       covs[k], covs_p[kp])
            else:
                _covariance_pass(P, g, c, update, predict, il, Q, q_zero, Hm[k + 1], gn)
            g, gn = gn, g
            if k == N - 2 and not update_first:
                _copy2(x, x_prior)
                _copy2(P, P_prior)
        else:                                         # the last step
            _covariance_pass(P, g, c, update, False, il, Q, q_zero, phi, gn)
            if store:
                _copy2(P, covs[k])
            _copy2(x, x_post)
            _copy2(P, P_post)
            if update_first:
                if predict:
                    _predict_inplace(P, il, Q, q_zero)
                if store:
                    _copy2(P, covs_p[k])
                _copy2(x, x_prior)
                _copy2(P, P_prior)
            if check and _unhealthy(P_post if not update_first else P, cond_max):
                k_fail = k
                _copy2(P_post if not update_first else P, P_fail)
    return s, k_fail


@njit(cache=True)
def _unhealthy(P, cond_max):
    """True when ``P`` fails ``rls._health_problem`` (no constraints): non-finite,
    not symmetric to 1e-8, not positive definite, or condition number above
    `cond_max`.

    The decision is the one ``eigvalsh`` gives, but a Cholesky factor
    ``A = L L^T`` settles the usual healthy case in about ``n^3 / 3``
    operations: ``cond(A) <= trace(A) trace(A^-1) = trace(A) ||L^-1||_F^2``,
    and a bound well inside `cond_max` (and below 1e12, where the computed
    eigenvalues are safely positive) means healthy. Otherwise the
    eigenvalues decide.
    """
    n = P.shape[0]
    A = np.empty((n, n))
    asym = 0.0
    scale = 0.0
    for i in range(n):
        for j in range(n):
            v = P[i, j]
            if v - v != 0.0:
                return True
            A[i, j] = 0.5 * (v + P[j, i])
            asym = max(asym, abs(v - P[j, i]))
            scale = max(scale, abs(v))
    if asym > 1e-8 * scale:
        return True
    L = np.zeros((n, n))
    chol = True
    for j in range(n):
        d = A[j, j]
        for k in range(j):
            d -= L[j, k] * L[j, k]
        if not d > 0.0:
            chol = False
            break
        ljj = np.sqrt(d)
        L[j, j] = ljj
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / ljj
    if chol:
        trace = 0.0
        for i in range(n):
            trace += A[i, i]
        inv_norm2 = 0.0                      # ||L^-1||_F^2, column by column
        col = np.empty(n)
        for j in range(n):
            for i in range(n):
                t = 1.0 if i == j else 0.0
                for k in range(j, i):
                    t -= L[i, k] * col[k]
                col[i] = t / L[i, i] if i >= j else 0.0
                if i >= j:
                    inv_norm2 += col[i] * col[i]
        if trace * inv_norm2 < min(0.5 * cond_max, 1e12):
            return False
    w = np.linalg.eigvalsh(A)
    return w[0] <= 0.0 or w[n - 1] > cond_max * w[0]


@njit(cache=True)
def _run_single(x, P, Z, Hm, Rv, il, Q, q_zero, update_first, means, ys, ss,
                x_prior, P_prior, x_post, P_post, K, check_every, step0, cond_max, P_fail):
    """`batch_filter_kernel` for one output without covariance histories.

    The hot path of ARX fits and long records: the same arithmetic in the
    same order as the general loop (so the results are identical), written
    with scalars for the single output.
    """
    N = Z.shape[0]
    n = x.shape[0]
    r_each = Rv.shape[0] == N
    hist = ys.shape[0] == N
    predict = not (il == 1.0 and q_zero)
    th = x[:, 0]
    g = np.empty(n)
    gn = np.empty(n)
    k_fail = -1
    # steps to the next health check (a countdown: no division per step)
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    _predict_gain_inplace(P, il, Q, q_zero, predict and not update_first, Hm[0], g)
    if not update_first and N == 1:
        _copy2(x, x_prior)
        _copy2(P, P_prior)
    s = np.nan
    for k in range(N):
        h = Hm[k]
        acc = 0.0
        for i in range(n):
            acc += h[i] * g[i]
        s = acc + Rv[k if r_each else 0]          # s = h . g + r
        hk = k if hist else 0          # histories, or just the last step
        ss[hk] = s
        c = 1.0 / s
        zk = Z[k, 0]
        update = zk == zk                          # not missing
        if update:
            acc = 0.0
            for i in range(n):
                acc += h[i] * th[i]
            y = zk - acc                           # y = z - h . x
            ys[hk, 0] = y
            for i in range(n):
                ki = g[i] * c                      # K = g / s
                K[i] = ki
                th[i] = th[i] + ki * y             # x = x + K y
        else:
            ys[hk, 0] = np.nan
        mk = means[k]
        for i in range(n):
            mk[i, 0] = th[i]
        countdown -= 1                 # zero when (step0 + k + 1) % check_every == 0
        check = countdown == 0 and k_fail < 0
        if countdown == 0:
            countdown = check_every
        if k < N - 1 and check:                       # unfused, to look at P in between
            _covariance_pass(P, g, c, update, False, il, Q, q_zero, h, gn)
            if not update_first and _unhealthy(P, cond_max):
                k_fail = k
                _copy2(P, P_fail)
            _predict_gain_inplace(P, il, Q, q_zero, predict, Hm[k + 1], gn)
            if update_first and _unhealthy(P, cond_max):
                k_fail = k
                _copy2(P, P_fail)
            g, gn = gn, g
            if k == N - 2 and not update_first:
                _copy2(x, x_prior)
                _copy2(P, P_prior)
        elif k < N - 1:
            _covariance_pass(P, g, c, update, predict, il, Q, q_zero, Hm[k + 1], gn)
            g, gn = gn, g
            if k == N - 2 and not update_first:
                _copy2(x, x_prior)
                _copy2(P, P_prior)
        else:
            _covariance_pass(P, g, c, update, False, il, Q, q_zero, h, gn)
            _copy2(x, x_post)
            _copy2(P, P_post)
            if update_first:
                if predict:
                    _predict_inplace(P, il, Q, q_zero)
                _copy2(x, x_prior)
                _copy2(P, P_prior)
            if check and _unhealthy(P_post if not update_first else P, cond_max):
                k_fail = k
                _copy2(P_post if not update_first else P, P_fail)
    return s, k_fail


@njit(cache=True)
def predict_kernel(x, P, il, Q, q_zero, Pn, x_prior, P_prior):
    """Streaming time update: ``Pn = P * il + Q`` (``Pn`` may be ``P``) and the prior copies."""
    n, m = x.shape
    if q_zero:
        for i in range(n):
            for j in range(n):
                v = P[i, j] * il
                Pn[i, j] = v
                P_prior[i, j] = v
    else:
        for i in range(n):
            for j in range(n):
                v = P[i, j] * il + Q[i, j]
                Pn[i, j] = v
                P_prior[i, j] = v
    for i in range(n):
        for j in range(m):
            x_prior[i, j] = x[i, j]


@njit(cache=True)
def update_kernel(x, P, phi, z, z0, zmode, r, xn, Pn, y, K, S, SI, Hc, x_post, P_post):
    """One measurement update for the streaming :meth:`update`.

    Reads ``x`` (n, m), ``P`` (n, n), the regressor ``phi`` (n,) and the
    measurement ``z`` (m, 1); with ``zmode`` 1 the kernel first writes the
    scalar ``z0`` into ``z``, with 2 the measurement is missing and ``z`` is
    filled with NaN. Writes the new estimate ``xn`` and covariance ``Pn``
    (which may be ``x`` and ``P`` themselves) with their copies ``x_post``,
    ``P_post``, the residual ``y`` (m, 1), the gain ``K`` (n, 1),
    ``S = s I`` and ``SI = I / s`` (m, m), and a copy ``Hc`` (1, n) of
    ``phi``. A missing measurement leaves the state unchanged, ``y`` NaN and
    ``K`` zero. ``phi`` is first tested for finiteness.

    Returns
    -------
    code : int
        0; 1 when ``phi`` holds NaN or inf (nothing is written then); 2 when
        the diagonal of the new ``P`` is not finite and positive (the cheap
        health check).
    """
    n, m = x.shape
    for i in range(n):
        v = phi[i]
        if v - v != 0.0:          # NaN or inf
            return 1
    missing = zmode == 2
    if zmode == 1:
        z[0, 0] = z0
    elif missing:
        for j in range(m):
            z[j, 0] = np.nan
    for i in range(n):
        Hc[0, i] = phi[i]
    g = K[:, 0]                   # K's storage holds g = P phi until the end
    _predict_gain_inplace(P, 1.0, P, True, False, phi, g)
    s = _innovation_variance(phi, g, r)
    c = 1.0 / s
    for i in range(m):
        for j in range(m):
            S[i, j] = 0.0
            SI[i, j] = 0.0
        S[i, i] = s
        SI[i, i] = c
    if missing:
        for j in range(m):
            y[j, 0] = np.nan
        for i in range(n):
            K[i, 0] = 0.0
        _copy2(x, xn)
        _copy2(P, Pn)
    else:
        yv = y[:, 0]
        _residual(x, phi, z[:, 0], yv)
        for i in range(n):                    # x = x + K y^T, K = g / s
            ki = g[i] * c
            for j in range(m):
                xn[i, j] = x[i, j] + ki * yv[j]
        for i in range(n):                    # P = P - (g g^T) / s
            gi = g[i]
            for j in range(n):
                Pn[i, j] = P[i, j] - (gi * g[j]) * c
        for i in range(n):
            K[i, 0] = g[i] * c
    _copy2(xn, x_post)
    _copy2(Pn, P_post)
    for i in range(n):
        if not Pn[i, i] > 0.0 or Pn[i, i] == np.inf:
            return 2
    return 0


def batch_compiled(x, P, Z, Hm, Rv, lam, Q, update_first, store_covariances, *,
                   mode=MODE_EXPONENTIAL, params=(), gate=None, Pi=None, check_every=0,
                   basis=None, cond_max=np.inf, step0=0, histories=True):
    """Compiled counterpart of ``rls._batch_reference`` (same arguments, same result).

    Exponential forgetting without gate or constraints only (a ValueError
    otherwise; `batch_general` runs every option). `x`, `P` are not
    modified. Returns a ``rls._BatchResult``; with ``histories=False`` its
    ``ys`` and ``ss`` hold the last step only (``batch_filter`` needs no
    more), which saves ``N (dim_z + 1)`` numbers.
    """
    from .rls import _BatchResult, _health_problem

    if mode != MODE_EXPONENTIAL or gate is not None or Pi is not None:
        raise ValueError("the compiled batch kernel runs exponential forgetting without gate "
                         "or constraints only")

    N = len(Z)
    n, m = x.shape
    out = _BatchResult()
    out.means = np.empty((N, n, m))
    if store_covariances:
        covs, covs_p = np.empty((N, n, n)), np.empty((N, n, n))
        out.covariances, out.covariances_p = covs, covs_p
    else:
        covs = covs_p = np.empty((0, n, n))
        out.covariances = out.covariances_p = None
    n_hist = N if histories else min(N, 1)
    out.ys = np.empty((n_hist, m))
    out.ss = np.empty(n_hist)
    Rv = np.asarray(Rv, dtype=np.float64)
    if Rv.ndim == 1 and N > 1 and Rv.strides[0] == 0:      # a broadcast scalar
        Rv = np.ascontiguousarray(Rv[:1])
    else:
        Rv = np.ascontiguousarray(Rv)
    xw = np.array(x, dtype=np.float64, order="C")
    Pw = np.array(P, dtype=np.float64, order="C")
    q_zero = Q is None
    Qa = np.zeros((0, 0)) if q_zero else np.ascontiguousarray(Q, dtype=np.float64)
    params = np.ascontiguousarray(np.asarray(params, dtype=np.float64).reshape(-1))
    x_prior, P_prior = np.empty((n, m)), np.empty((n, n))
    x_post, P_post = np.empty((n, m)), np.empty((n, n))
    K = np.zeros(n)
    P_fail = np.empty((n, n))
    s, k_fail = batch_filter_kernel(
        xw, Pw, np.ascontiguousarray(Z, dtype=np.float64),
        np.ascontiguousarray(Hm, dtype=np.float64), Rv,
        1.0 / lam, Qa, q_zero, bool(update_first), int(mode), params,
        out.means, covs, covs_p, out.ys, out.ss,
        x_prior, P_prior, x_post, P_post, K,
        int(check_every), int(step0), float(cond_max), P_fail)
    out.gated = np.zeros(N, dtype=bool)
    out.lam_t_last = lam
    out.problem = None
    if k_fail >= 0:
        problem = _health_problem(P_fail, None, cond_max) or "`P` failed the health check"
        out.problem = (f"{problem} at step {k_fail} of batch_filter (update "
                       f"{step0 + k_fail + 1} since reset)")
    # the estimate is unchanged by a time update
    if update_first:
        out.means_p = out.means.copy()
    else:
        out.means_p = np.empty((N, n, m))
        if N:
            out.means_p[0] = x
            out.means_p[1:] = out.means[:-1]
    out.x, out.P = xw, Pw
    if N:
        out.x_prior, out.P_prior = x_prior, P_prior
        out.x_post, out.P_post = x_post, P_post
        if np.isnan(out.ys[-1]).any():     # the last sample was missing: no gain
            K[:] = 0.0
        out.y_last, out.K_last, out.s_last = out.ys[-1].copy(), K.reshape(n, 1), s
    return out


# ----------------------------------------------------------------------
# Every other option: the anti-windup modes, the gate, the constraints.
#
# One step is `general_predict` then `general_update` (or the reverse with
# `update_first`); the batch kernel `general_batch_kernel` and the streaming
# `predict`/`update` call the same two functions, so they agree bit for bit.
# The arithmetic follows `forgetting.update_<mode>` and `rls._project`
# operation by operation (products summed in the natural order).
# ----------------------------------------------------------------------
MODE_DIRECTIONAL, MODE_CONSTANT_TRACE, MODE_EFRA, MODE_VARIABLE = 1, 2, 3, 4


@njit(cache=True)
def _project_inplace(P, Pi, T):
    """``P <- Pi P Pi`` made exactly symmetric (``rls._project``); `T` is (n, n) work."""
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


@njit(cache=True)
def general_predict(P, il, Q, q_zero, constrained, Pi, T):
    """Time update of the general path, in place: ``P <- P il + Q``, then ``Pi P Pi``.

    ``il`` is ``1 / lam`` in the exponential mode and 1 otherwise (the other
    modes forget in the update).
    """
    n = P.shape[0]
    if il != 1.0:
        for i in range(n):
            for j in range(n):
                P[i, j] = P[i, j] * il
    if not q_zero:
        for i in range(n):
            for j in range(n):
                P[i, j] = P[i, j] + Q[i, j]
    if constrained:
        _project_inplace(P, Pi, T)


@njit(cache=True)
def general_update(x, P, phi, z, missing, r, mode, params, lam, has_gate, gate,
                   constrained, Pi, g, y, K, T):
    """One measurement update of any mode with the gate and the constraints, in place.

    The compiled ``rls._measurement_step``: ``x`` (n, m) and ``P`` (n, n)
    are updated in place (unchanged for a missing or gated sample); writes
    ``g = P phi`` (n,), the residual ``y`` (m,; NaN when missing), the gain
    ``K`` (n,; zero when missing or gated). ``T`` is (n, n) work.

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
    for i in range(n):                       # g = P phi, as P @ phi.T
        acc = 0.0
        for j in range(n):
            acc += P[i, j] * phi[j]
        g[i] = acc
    acc = 0.0
    for i in range(n):
        acc += phi[i] * g[i]
    s = acc + r
    lam_skip = lam if mode == MODE_EXPONENTIAL else 1.0
    if missing:
        for j in range(m):
            y[j] = np.nan
        for i in range(n):
            K[i] = 0.0
        return s, lam_skip, False
    _residual(x, phi, z, y)
    if has_gate:
        yy = 0.0
        for j in range(m):
            yy += y[j] * y[j]
        if yy > gate * gate * s:             # sqrt(y'y / S) > gate
            for i in range(n):
                K[i] = 0.0
            return s, lam_skip, True
    lam_t = lam
    if mode == MODE_DIRECTIONAL:
        eps = params[0]
        rho = (s - r) / r                    # phi P phi^T / r
        e = lam - (1.0 - lam) / rho if rho > eps else 1.0
        d = r * (1.0 + e * rho)
        for i in range(n):
            K[i] = g[i] / d
        ed = e / d
        for i in range(n):
            gi = g[i]
            for j in range(n):
                P[i, j] = P[i, j] - ed * (gi * g[j])
        lam_t = e
    elif mode == MODE_EFRA:
        alpha, beta, delta = params[0], params[1], params[2]
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
                P[i, j] = 0.5 * (T[i, j] + T[j, i])
            P[i, i] = P[i, i] + br
    else:                                    # exponential, constant trace, variable
        for i in range(n):
            K[i] = g[i] / s
        for i in range(n):
            gi = g[i]
            for j in range(n):
                P[i, j] = P[i, j] - (gi * g[j]) / s
        if mode == MODE_CONSTANT_TRACE:
            trace, ratio = params[0], params[1]
            c2 = trace / (ratio + n)
            c1 = trace - n * c2
            tb = 0.0
            for i in range(n):
                tb += P[i, i]
            f = c1 / tb
            for i in range(n):
                for j in range(n):
                    P[i, j] = f * P[i, j]
                P[i, i] = P[i, i] + c2
            lam_t = tb / c1
        elif mode == MODE_VARIABLE:
            lam_min, trace_max = params[0], params[1]
            yy = 0.0
            for j in range(m):
                yy += y[j] * y[j]
            lt = 1.0 - (1.0 - lam) * yy / (m * s)
            lt = min(1.0, max(lam_min, lt))
            tb = 0.0
            for i in range(n):
                tb += P[i, i]
            lt = max(lt, min(1.0, tb / trace_max))
            if lt != 1.0:
                for i in range(n):
                    for j in range(n):
                        P[i, j] = P[i, j] / lt
            lam_t = lt
    for i in range(n):                       # x = x + K y^T
        ki = K[i]
        for j in range(m):
            x[i, j] = x[i, j] + ki * y[j]
    if constrained:                          # keep A P = 0
        _project_inplace(P, Pi, T)
    return s, lam_t, False


@njit(cache=True)
def general_update_kernel(x, P, phi, z, z0, zmode, r, mode, params, lam, has_gate, gate,
                          constrained, Pi, y, K, S, SI, Hc, x_post, P_post):
    """`general_update` for the streaming :meth:`update`, in place on ``x``, ``P``.

    As `update_kernel`: ``zmode`` 1 writes the scalar ``z0`` into ``z``
    (m,), 2 marks the measurement missing and fills ``z`` with NaN. Writes
    ``y`` (m,), ``K`` (n,), ``S = s I``, ``SI = I / s`` (m, m), the copy
    ``Hc`` (1, n) of ``phi`` and the copies ``x_post``, ``P_post``.

    Returns
    -------
    code : int
        0; 1 when ``phi`` holds NaN or inf (nothing is written then); 2 when
        the diagonal of the new ``P`` is not finite and positive.
    s, lam_t : float
    gated : bool
    """
    n, m = x.shape
    for i in range(n):
        v = phi[i]
        if v - v != 0.0:          # NaN or inf
            return 1, np.nan, lam, False
    missing = zmode == 2
    if zmode == 1:
        z[0] = z0
    elif missing:
        for j in range(m):
            z[j] = np.nan
    for i in range(n):
        Hc[0, i] = phi[i]
    g = np.empty(n)
    T = np.empty((n, n))
    s, lam_t, gated = general_update(x, P, phi, z, missing, r, mode, params, lam, has_gate,
                                     gate, constrained, Pi, g, y, K, T)
    c = 1.0 / s
    for i in range(m):
        for j in range(m):
            S[i, j] = 0.0
            SI[i, j] = 0.0
        S[i, i] = s
        SI[i, i] = c
    _copy2(x, x_post)
    _copy2(P, P_post)
    for i in range(n):
        if not P[i, i] > 0.0 or P[i, i] == np.inf:
            return 2, s, lam_t, gated
    return 0, s, lam_t, gated


@njit(cache=True)
def _unhealthy_on(P, constrained, basis, cond_max):
    """`_unhealthy` of ``basis^T P basis`` when `constrained` (else of ``P``)."""
    if not constrained:
        return _unhealthy(P, cond_max)
    n, p = basis.shape
    for i in range(n):
        for j in range(n):
            v = P[i, j]
            if v - v != 0.0:
                return True
    B = np.zeros((n, p))                     # P basis
    for i in range(n):
        for k in range(n):
            a = P[i, k]
            for j in range(p):
                B[i, j] += a * basis[k, j]
    R = np.zeros((p, p))                     # basis^T (P basis)
    for k in range(n):
        for i in range(p):
            a = basis[k, i]
            for j in range(p):
                R[i, j] += a * B[k, j]
    if p == 0:
        return False
    return _unhealthy(R, cond_max)


@njit(cache=True)
def general_batch_kernel(x, P, Z, Hm, Rv, il, Q, q_zero, update_first, mode, params, lam,
                         has_gate, gate, constrained, Pi, basis,
                         means, means_p, covs, covs_p, ys, ss, gated,
                         x_prior, P_prior, x_post, P_post, K,
                         check_every, step0, cond_max, P_fail):
    """The recursion of every mode, gate and constraint over a record, in place.

    Arguments as `batch_filter_kernel`, plus: `mode`, `params`, `lam` of
    ``forgetting``; `has_gate`, `gate`; `constrained`, the projector `Pi`
    and the null-space `basis` (for the health check); `means_p` (written
    here); `gated` (N,) bool (written). ``ys`` and ``ss`` are written for
    every step (``ys`` NaN when missing, the rejected residual when gated).

    Returns
    -------
    s : float, k_fail : int, lam_t : float
        Innovation variance and forgetting factor of the last step, and the
        step of the first failed health check (or -1).
    """
    N = Z.shape[0]
    n, m = x.shape
    store = covs.shape[0] == N
    r_each = Rv.shape[0] == N
    g = np.empty(n)
    y = np.empty(m)
    T = np.empty((n, n))
    s = np.nan
    lam_t = lam
    k_fail = -1
    for k in range(N):
        if not update_first:
            general_predict(P, il, Q, q_zero, constrained, Pi, T)
            _copy2(x, means_p[k])
            if store:
                _copy2(P, covs_p[k])
            if k == N - 1:
                _copy2(x, x_prior)
                _copy2(P, P_prior)
        z = Z[k]
        s, lam_t, gk = general_update(x, P, Hm[k], z, _any_nan(z), Rv[k if r_each else 0],
                                      mode, params, lam, has_gate, gate, constrained, Pi,
                                      g, y, K, T)
        ss[k] = s
        gated[k] = gk
        for j in range(m):
            ys[k, j] = y[j]
        _copy2(x, means[k])
        if store:
            _copy2(P, covs[k])
        if k == N - 1:
            _copy2(x, x_post)
            _copy2(P, P_post)
        if update_first:
            general_predict(P, il, Q, q_zero, constrained, Pi, T)
            _copy2(x, means_p[k])
            if store:
                _copy2(P, covs_p[k])
            if k == N - 1:
                _copy2(x, x_prior)
                _copy2(P, P_prior)
        if (check_every > 0 and k_fail < 0 and (step0 + k + 1) % check_every == 0
                and _unhealthy_on(P, constrained, basis, cond_max)):
            k_fail = k
            _copy2(P, P_fail)
    return s, k_fail, lam_t


def batch_general(x, P, Z, Hm, Rv, lam, Q, update_first, store_covariances, *,
                  mode=MODE_EXPONENTIAL, params=(), gate=None, Pi=None, check_every=0,
                  basis=None, cond_max=np.inf, step0=0):
    """Compiled counterpart of ``rls._batch_reference`` for every mode and option."""
    from .rls import _BatchResult, _health_problem

    N = len(Z)
    n, m = x.shape
    out = _BatchResult()
    out.means = np.empty((N, n, m))
    out.means_p = np.empty((N, n, m))
    if store_covariances:
        covs, covs_p = np.empty((N, n, n)), np.empty((N, n, n))
        out.covariances, out.covariances_p = covs, covs_p
    else:
        covs = covs_p = np.empty((0, n, n))
        out.covariances = out.covariances_p = None
    out.ys = np.empty((N, m))
    out.ss = np.empty(N)
    out.gated = np.zeros(N, dtype=np.bool_)
    Rv = np.asarray(Rv, dtype=np.float64)
    if Rv.ndim == 1 and N > 1 and Rv.strides[0] == 0:      # a broadcast scalar
        Rv = np.ascontiguousarray(Rv[:1])
    else:
        Rv = np.ascontiguousarray(Rv)
    xw = np.array(x, dtype=np.float64, order="C")
    Pw = np.array(P, dtype=np.float64, order="C")
    q_zero = Q is None
    Qa = np.zeros((0, 0)) if q_zero else np.ascontiguousarray(Q, dtype=np.float64)
    constrained = Pi is not None
    Pia = np.ascontiguousarray(Pi, dtype=np.float64) if constrained else np.zeros((0, 0))
    Ba = (np.ascontiguousarray(basis, dtype=np.float64) if constrained and basis is not None
          else np.zeros((n, 0)))
    params = np.ascontiguousarray(np.asarray(params, dtype=np.float64).reshape(-1))
    tlam = lam if mode == MODE_EXPONENTIAL else 1.0
    x_prior, P_prior = np.empty((n, m)), np.empty((n, n))
    x_post, P_post = np.empty((n, m)), np.empty((n, n))
    K = np.zeros(n)
    P_fail = np.empty((n, n))
    s, k_fail, lam_t = general_batch_kernel(
        xw, Pw, np.ascontiguousarray(Z, dtype=np.float64),
        np.ascontiguousarray(Hm, dtype=np.float64), Rv,
        1.0 / tlam, Qa, q_zero, bool(update_first), int(mode), params, float(lam),
        gate is not None, 0.0 if gate is None else float(gate), constrained, Pia, Ba,
        out.means, out.means_p, covs, covs_p, out.ys, out.ss, out.gated,
        x_prior, P_prior, x_post, P_post, K,
        int(check_every), int(step0), float(cond_max), P_fail)
    out.problem = None
    if k_fail >= 0:
        problem = (_health_problem(P_fail, basis if constrained else None, cond_max)
                   or "`P` failed the health check")
        out.problem = (f"{problem} at step {k_fail} of batch_filter (update "
                       f"{step0 + k_fail + 1} since reset)")
    out.x, out.P = xw, Pw
    if N:
        out.x_prior, out.P_prior = x_prior, P_prior
        out.x_post, out.P_post = x_post, P_post
        out.y_last, out.K_last, out.s_last = out.ys[-1].copy(), K.reshape(n, 1), s
        out.lam_t_last = lam_t
    return out
