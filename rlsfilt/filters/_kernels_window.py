"""Compiled (numba) kernels of `SlidingWindowRLS` and `SquareRootRLS`.

The pure-NumPy reference of each recursion is the class's own step
(``update`` with the module flag ``_COMPILED = False`` in
:mod:`rlsfilt.filters.sliding_window` and :mod:`rlsfilt.filters.square_root`);
the tests hold the two paths equal to 1e-12 on well-conditioned data. As in
:mod:`rlsfilt.filters._kernels`, every function is ``njit(cache=True)``, so
the machine code is compiled once and loaded from the disk cache by later
processes, and one step function serves both the batch kernel and the
streaming ``update``: the two agree bit for bit.

Sliding window, one step (Haykin 2002, sec. 9)::

    g = P phi, s = phi . g + r               update with the new sample
    x <- x + (g / s) (z - phi x)^T,  P <- P - g g^T / s
    ring buffer: the new sample replaces the oldest one
    g = P h, d = r_old - h . g               downdate with the leaving sample
    x <- x - (g / d) (z_old - h x)^T,  P <- P + g g^T / d
    refit by Householder QR of the stored window when d is not clearly
    positive, when the window first fills, and every `refresh` steps

Square root (QR, information form), one step::

    U <- sqrt(lam) U, d <- sqrt(lam) d      predict
    w = U^-T phi, s = w . w + r,  K = U^-1 w / s
    [U d; phi/sqrt(r) z^T/sqrt(r)] -> [U' d'; 0 e]   by n Givens rotations
    x = U'^-1 d'

The Givens rotations keep the diagonal of ``U`` positive by construction
(``U_ii <- hypot(U_ii, a_i)``), which is the unique factor the NumPy path
reaches with a Householder QR and a sign flip.
"""

import math

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable

__all__ = []


def c_array(a):
    """`a` as a writable C-contiguous float64 array (copied only when needed).

    The kernels are compiled for exactly this layout; a read-only or
    strided input would otherwise compile (and cache) another version.
    """
    if (type(a) is np.ndarray and a.dtype == np.float64 and a.flags.c_contiguous
            and a.flags.writeable):
        return a
    return np.array(a, dtype=np.float64, order="C")


# ----------------------------------------------------------------------
# shared small helpers
# ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def _any_nan(z):
    for v in z:
        if v != v:
            return True
    return False


@njit(cache=True, inline="always")
def _copy2(a, b):
    """``b[:] = a`` for 2-D arrays."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            b[i, j] = a[i, j]


@njit(cache=True)
def _upper_inverse_gram(U, P):
    """``P = U^-1 U^-T`` for an upper-triangular `U` with a nonzero diagonal.

    ``V = U^-1`` (upper triangular) by back substitution, column by column;
    then ``P_ij = sum_{k >= max(i, j)} V_ik V_jk`` for ``i <= j``, mirrored,
    so ``P`` is exactly symmetric.
    """
    n = U.shape[0]
    V = np.zeros((n, n))
    for j in range(n):
        V[j, j] = 1.0 / U[j, j]
        for i in range(j - 1, -1, -1):
            acc = 0.0
            for k in range(i + 1, j + 1):
                acc += U[i, k] * V[k, j]
            V[i, j] = -acc / U[i, i]
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(j, n):
                acc += V[i, k] * V[j, k]
            P[i, j] = acc
            P[j, i] = acc


@njit(cache=True)
def _back_substitute(U, B, X):
    """Solve ``U X = B`` (``U`` upper triangular); `X` may be `B`."""
    n, m = B.shape
    for c in range(m):
        for i in range(n - 1, -1, -1):
            acc = B[i, c]
            for k in range(i + 1, n):
                acc -= U[i, k] * X[k, c]
            X[i, c] = acc / U[i, i]


# ----------------------------------------------------------------------
# SquareRootRLS
# ----------------------------------------------------------------------
@njit(cache=True)
def sr_covariance(U, P):
    """``P = U^-1 U^-T`` (the ``P`` property and the covariance histories)."""
    _upper_inverse_gram(U, P)


@njit(cache=True)
def _sr_predict(U, d, c):
    """``U <- c U``, ``d <- c d`` in place (``c = sqrt(lam)``)."""
    n, m = d.shape
    for i in range(n):
        for j in range(n):
            U[i, j] = U[i, j] * c
        for j in range(m):
            d[i, j] = d[i, j] * c


@njit(cache=True)
def _sr_step(U, d, x, phi, z, r, w, y, K, gain):
    """One measurement update of the information square root, in place.

    Writes ``y`` (m,) and, when `gain`, ``K`` (n,) (NaN and zero when `z`
    holds a NaN) and returns ``s = H P H^T + R``. ``w`` (n,) is workspace.
    The gain is not needed to update ``U`` and ``d``: the batch kernel forms
    it for the last step only.
    """
    n, m = d.shape
    for i in range(n):                         # U^T w = phi (forward substitution)
        acc = phi[i]
        for k in range(i):
            acc -= U[k, i] * w[k]
        w[i] = acc / U[i, i]
    s = r
    for i in range(n):
        s += w[i] * w[i]                       # s = |U^-T phi|^2 + r
    if _any_nan(z):
        for j in range(m):
            y[j] = np.nan
        for i in range(n):
            K[i] = 0.0
        return s
    if gain:
        for i in range(n - 1, -1, -1):         # U v = w (back substitution); K = v / s
            acc = w[i]
            for k in range(i + 1, n):
                acc -= U[i, k] * K[k]
            K[i] = acc / U[i, i]
        for i in range(n):
            K[i] = K[i] / s
    for j in range(m):                         # y = z - phi x
        acc = 0.0
        for i in range(n):
            acc += phi[i] * x[i, j]
        y[j] = z[j] - acc
    # fold the row [phi, z^T] / sqrt(r) into [U, d] with Givens rotations
    c0 = 1.0 / math.sqrt(r)
    a = np.empty(n)
    b = np.empty(m)
    for i in range(n):
        a[i] = phi[i] * c0
    for j in range(m):
        b[j] = z[j] * c0
    for i in range(n):
        ai = a[i]
        if ai == 0.0:
            continue
        uii = U[i, i]
        rho = math.hypot(uii, ai)
        cs = uii / rho
        sn = ai / rho
        U[i, i] = rho
        for j in range(i + 1, n):
            t = U[i, j]
            aj = a[j]
            U[i, j] = cs * t + sn * aj
            a[j] = cs * aj - sn * t
        for j in range(m):
            t = d[i, j]
            bj = b[j]
            d[i, j] = cs * t + sn * bj
            b[j] = cs * bj - sn * t
    _back_substitute(U, d, x)                  # x = U^-1 d
    return s


@njit(cache=True)
def sr_update_kernel(U, d, x, phi, z, r, y, K):
    """Streaming :meth:`SquareRootRLS.update`: `_sr_step` on the given arrays.

    Returns ``s`` and whether the diagonal of the new ``U`` fails the cheap
    health check (`_sr_diagonal_bad`).
    """
    w = np.empty(U.shape[0])
    s = _sr_step(U, d, x, phi, z, r, w, y, K, U.shape[0] > 0)
    return s, _sr_diagonal_bad(U)


@njit(cache=True, inline="always")
def _sr_diagonal_bad(U):
    """True when a diagonal entry of ``U`` is not positive and finite, i.e.
    ``P = U^-1 U^-T`` is not (finitely) positive definite (the cheap check)."""
    for i in range(U.shape[0]):
        v = U[i, i]
        if not (v > 0.0 and v < np.inf):
            return True
    return False


@njit(cache=True)
def sr_unhealthy(U, cond_max):
    """True when ``P = U^-1 U^-T`` fails ``square_root._health_problem``:
    non-finite ``U``, a diagonal entry that is not positive, or
    ``cond(P) = cond(U)^2`` above `cond_max`.

    The singular values of the triangular factor come from `_singular_range`
    (one-sided Jacobi, high relative accuracy), so the condition number of
    ``P`` is read off without forming ``P``: ``O(n^3)`` per check.
    """
    n = U.shape[0]
    for i in range(n):
        for j in range(n):
            v = U[i, j]
            if v - v != 0.0:                   # NaN or infinite
                return True
    if _sr_diagonal_bad(U):
        return True
    smin, smax = _singular_range(U)
    if not smin > 0.0:
        return True
    ratio = smax / smin
    return ratio * ratio > cond_max


@njit(cache=True)
def sr_batch_kernel(U, d, x, Z, Hm, Rv, c, update_first, means, covs, covs_p,
                    x_prior, P_prior, P_post, y, K, check_every, step0, cond_max, U_fail):
    """Run `SquareRootRLS` over a record, in place on ``U``, ``d``, ``x``.

    ``c = sqrt(lam)`` (1.0: no time update). ``Rv`` has length N or 1 (one
    variance for all steps). ``covs``, ``covs_p`` (N, n, n) are written when
    their length is N. Leaves the last predict's ``x_prior``, ``P_prior``
    and the last update's ``P_post``, ``y`` and ``K`` (the last
    non-missing gain is not kept: a missing last sample leaves ``K`` zero,
    as the streaming step does).

    The health check of ``P`` runs after every update as
    :meth:`SquareRootRLS.update` runs it: the cheap diagonal test of ``U``
    each step and `sr_unhealthy` when the update count ``step0 + k + 1`` is
    a multiple of ``check_every`` (0 disables both). The first failing ``U``
    is copied to ``U_fail`` and no further checks run.

    Returns
    -------
    s : float
        The last step's ``S``.
    k_fail : int
        Step of the first failed health check, or -1.
    """
    N = Z.shape[0]
    n, m = x.shape
    store = covs.shape[0] == N and N > 0
    r_each = Rv.shape[0] == N
    w = np.empty(n)
    s = np.nan
    k_fail = -1
    # steps to the next full health check (a countdown: no division per step)
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    for k in range(N):
        if not update_first:
            if c != 1.0:
                _sr_predict(U, d, c)
            if store:
                _upper_inverse_gram(U, covs_p[k])
            if k == N - 1:
                _copy2(x, x_prior)
                if store:
                    _copy2(covs_p[k], P_prior)
                else:
                    _upper_inverse_gram(U, P_prior)
        s = _sr_step(U, d, x, Hm[k], Z[k], Rv[k if r_each else 0], w, y, K, k == N - 1)
        if countdown > 0:
            countdown -= 1
            full = countdown == 0
            if full:
                countdown = check_every
            if _sr_diagonal_bad(U) or (full and sr_unhealthy(U, cond_max)):
                k_fail = k
                countdown = -1
                _copy2(U, U_fail)
        _copy2(x, means[k])
        if store:
            _upper_inverse_gram(U, covs[k])
        if k == N - 1:
            if store:
                _copy2(covs[k], P_post)
            else:
                _upper_inverse_gram(U, P_post)
        if update_first:
            if c != 1.0:
                _sr_predict(U, d, c)
            if store:
                _upper_inverse_gram(U, covs_p[k])
            if k == N - 1:
                _copy2(x, x_prior)
                if store:
                    _copy2(covs_p[k], P_prior)
                else:
                    _upper_inverse_gram(U, P_prior)
    return s, k_fail


# ----------------------------------------------------------------------
# SlidingWindowRLS
# ----------------------------------------------------------------------
# the integer state ``ist`` of the sliding window
HEAD, NW, COUNT, NEXT_EXACT, EXACT = 0, 1, 2, 3, 4


_EPS = float(np.finfo(np.float64).eps)


@njit(cache=True)
def _singular_range(R):
    """Smallest and largest singular value of the square `R` (one-sided Jacobi).

    Hestenes' method: plane rotations orthogonalize the columns of a copy
    of `R`; the column norms are then the singular values, to high relative
    accuracy (Demmel & Veselic 1992). Cheap for the ``dim_x x dim_x``
    factor, and compiled without LAPACK.
    """
    n = R.shape[0]
    G = R.copy()
    for _ in range(60):
        rotated = False
        for p in range(n - 1):
            for q in range(p + 1, n):
                alpha = 0.0
                beta = 0.0
                gamma = 0.0
                for i in range(n):
                    alpha += G[i, p] * G[i, p]
                    beta += G[i, q] * G[i, q]
                    gamma += G[i, p] * G[i, q]
                if gamma == 0.0 or abs(gamma) <= _EPS * math.sqrt(alpha * beta):
                    continue
                rotated = True
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (abs(zeta) + math.sqrt(1.0 + zeta * zeta))
                c = 1.0 / math.sqrt(1.0 + t * t)
                s = c * t
                for i in range(n):
                    gp = G[i, p]
                    gq = G[i, q]
                    G[i, p] = c * gp - s * gq
                    G[i, q] = s * gp + c * gq
        if not rotated:
            break
    smin = np.inf
    smax = 0.0
    for j in range(n):
        acc = 0.0
        for i in range(n):
            acc += G[i, j] * G[i, j]
        v = math.sqrt(acc)
        smin = min(smin, v)
        smax = max(smax, v)
    return smin, smax


@njit(cache=True)
def _window_lstsq(wH, wZ, wR, nw, Lt, Ltx0, n_prior, x, P):
    """Weighted least squares on the first `nw` stored rows, by Householder QR.

    With ``n_prior = dim_x`` the rows ``[Lt, Lt x0]`` (``Lt^T Lt = P0^-1``)
    come first (ridge regression towards ``x0``); with 0 the solution exists
    only when the rows have full column rank, decided as
    ``numpy.linalg.matrix_rank`` decides it (singular values against
    ``s_max max(rows, n) eps``, here those of the triangular factor).
    Writes ``x`` and ``P`` and returns True, or returns False (nothing
    written) when there is no solution.
    """
    n = wH.shape[1]
    m = wZ.shape[1]
    rows = n_prior
    for k in range(nw):
        if not _any_nan(wZ[k]):
            rows += 1
    if rows < n:
        return False
    A = np.empty((rows, n + m))                    # [A | B], weighted
    for i in range(n_prior):
        for j in range(n):
            A[i, j] = Lt[i, j]
        for j in range(m):
            A[i, n + j] = Ltx0[i, j]
    i = n_prior
    for k in range(nw):
        if _any_nan(wZ[k]):
            continue
        wk = 1.0 / math.sqrt(wR[k])
        for j in range(n):
            A[i, j] = wH[k, j] * wk
        for j in range(m):
            A[i, n + j] = wZ[k, j] * wk
        i += 1
    # Householder QR of the first n columns, applied to all n + m columns
    v = np.empty(rows)
    for j in range(n):
        norm2 = 0.0
        for i in range(j, rows):
            norm2 += A[i, j] * A[i, j]
        norm = math.sqrt(norm2)
        if norm == 0.0:
            continue
        alpha = -norm if A[j, j] >= 0.0 else norm
        for i in range(j, rows):
            v[i] = A[i, j]
        v[j] -= alpha
        vnorm2 = norm2 - A[j, j] * A[j, j] + v[j] * v[j]
        A[j, j] = alpha
        for i in range(j + 1, rows):
            A[i, j] = 0.0
        if vnorm2 == 0.0:
            continue
        for col in range(j + 1, n + m):
            acc = 0.0
            for i in range(j, rows):
                acc += v[i] * A[i, col]
            f = 2.0 * acc / vnorm2
            for i in range(j, rows):
                A[i, col] -= f * v[i]
    Rf = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            Rf[i, j] = A[i, j] if j >= i else 0.0
    if n_prior == 0:
        smin, smax = _singular_range(Rf)
        if not smin > smax * max(rows, n) * _EPS:
            return False
    QtB = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            QtB[i, j] = A[i, n + j]
    _back_substitute(Rf, QtB, x)
    _upper_inverse_gram(Rf, P)
    return True


@njit(cache=True)
def _sw_step(x, P, phi, z, r, wH, wZ, wR, ist, refresh, Lt, Ltx0, g, y, K):
    """One `SlidingWindowRLS` update (add, slide the ring buffer, downdate,
    refit when due), in place on ``x``, ``P``, the buffer and ``ist``.

    Writes ``y`` (m,) and ``K`` (n,) (NaN and zero for a missing `z`) and
    returns ``s``. ``g`` (n,) is workspace.
    """
    n, m = x.shape
    window = wH.shape[0]
    for i in range(n):                         # g = P phi^T
        acc = 0.0
        for j in range(n):
            acc += P[i, j] * phi[j]
        g[i] = acc
    s = r
    for i in range(n):
        s += phi[i] * g[i]                     # s = phi P phi^T + r
    missing = _any_nan(z)
    if missing:
        for j in range(m):
            y[j] = np.nan
        for i in range(n):
            K[i] = 0.0
    else:
        for j in range(m):                     # y = z - phi x
            acc = 0.0
            for i in range(n):
                acc += phi[i] * x[i, j]
            y[j] = z[j] - acc
        for i in range(n):
            ki = g[i] / s                      # K = P phi^T / s
            K[i] = ki
            for j in range(m):
                x[i, j] = x[i, j] + ki * y[j]
        for i in range(n):                     # P = P - g g^T / s
            gi = g[i]
            for j in range(n):
                P[i, j] = P[i, j] - (gi * g[j]) / s
    # ring buffer: slot `head` holds the oldest sample once the window is full
    h = ist[HEAD]
    leaving = ist[NW] == window and not _any_nan(wZ[h])
    refit = False
    if leaving:                                # downdate with the leaving sample
        hl = wH[h]
        rl = wR[h]
        for i in range(n):
            acc = 0.0
            for j in range(n):
                acc += P[i, j] * hl[j]
            g[i] = acc
        dd = rl
        for i in range(n):
            dd -= hl[i] * g[i]                 # d = R - h P h^T
        if dd > 1e-8 * rl:
            for j in range(m):
                acc = 0.0
                for i in range(n):
                    acc += hl[i] * x[i, j]
                e = wZ[h, j] - acc             # residual of the leaving sample
                for i in range(n):
                    x[i, j] = x[i, j] - (g[i] / dd) * e
            for i in range(n):                 # P = P + g g^T / d
                gi = g[i]
                for j in range(n):
                    P[i, j] = P[i, j] + (gi * g[j]) / dd
        else:
            refit = True
    for j in range(n):
        wH[h, j] = phi[j]
    for j in range(m):
        wZ[h, j] = np.nan if missing else z[j]
    wR[h] = r
    ist[HEAD] = (h + 1) % window
    ist[NW] = min(ist[NW] + 1, window)
    ist[COUNT] += 1
    if ist[NW] == window and not ist[EXACT]:
        refit = refit or ist[COUNT] >= ist[NEXT_EXACT]
    if refresh and ist[COUNT] % refresh == 0:
        refit = True
    if refit:
        nw = ist[NW]
        if _window_lstsq(wH, wZ, wR, nw, Lt, Ltx0, n - n, x, P):   # (n - n: one typing)
            ist[EXACT] = 1
        else:
            ist[EXACT] = 0
            ist[NEXT_EXACT] = ist[COUNT] + window
            _window_lstsq(wH, wZ, wR, nw, Lt, Ltx0, n, x, P)
    return s


@njit(cache=True, inline="always")
def _sw_diagonal_bad(P):
    """True when a diagonal entry of ``P`` is not positive and finite (the
    cheap health check: a positive definite ``P`` has a positive diagonal)."""
    for i in range(P.shape[0]):
        v = P[i, i]
        if not (v > 0.0 and v < np.inf):
            return True
    return False


@njit(cache=True)
def sw_unhealthy(P, cond_max):
    """True when the symmetric ``P`` fails ``rls._health_problem`` (no
    constraints): non-finite, not symmetric to 1e-8, not positive definite
    (a Cholesky pivot not positive) or ``cond(P) = cond(L)^2`` above
    `cond_max`, with the singular values of the Cholesky factor ``L`` from
    `_singular_range` (``O(n^3)``, compiled without LAPACK).
    """
    n = P.shape[0]
    scale = 0.0
    for i in range(n):
        for j in range(n):
            v = P[i, j]
            if v - v != 0.0:                   # NaN or infinite
                return True
            scale = max(scale, abs(v))
    for i in range(n):
        for j in range(i + 1, n):
            if abs(P[i, j] - P[j, i]) > 1e-8 * scale:
                return True
    L = np.zeros((n, n))
    for j in range(n):                         # P = L L^T
        acc = P[j, j]
        for k in range(j):
            acc -= L[j, k] * L[j, k]
        if not acc > 0.0:
            return True
        ljj = math.sqrt(acc)
        L[j, j] = ljj
        for i in range(j + 1, n):
            acc = P[i, j]
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / ljj
    smin, smax = _singular_range(L)
    if not smin > 0.0:
        return True
    ratio = smax / smin
    return ratio * ratio > cond_max


@njit(cache=True)
def sw_update_kernel(x, P, phi, z, r, wH, wZ, wR, ist, refresh, Lt, Ltx0, y, K):
    """Streaming :meth:`SlidingWindowRLS.update`: `_sw_step` on the given arrays.

    Returns ``s`` and whether the diagonal of the new ``P`` fails the cheap
    health check (`_sw_diagonal_bad`).
    """
    g = np.empty(x.shape[0])
    s = _sw_step(x, P, phi, z, r, wH, wZ, wR, ist, refresh, Lt, Ltx0, g, y, K)
    return s, _sw_diagonal_bad(P)


@njit(cache=True)
def sw_batch_kernel(x, P, Z, Hm, Rv, wH, wZ, wR, ist, refresh, Lt, Ltx0, means, covs, y, K,
                    P_last, check_every, step0, cond_max, P_fail):
    """Run `SlidingWindowRLS` over a record, in place on the state.

    ``Rv`` has length N or 1; ``covs`` (N, n, n) is written when its length
    is N. ``y`` and ``K`` are the last step's, ``P_last`` is ``P`` before
    the last step. (The window has no time update: the caller builds the
    predicted histories from these.)

    The health check runs after every update as
    :meth:`SlidingWindowRLS.update` runs it: the cheap diagonal test each
    step and `sw_unhealthy` when the update count ``step0 + k + 1`` is a
    multiple of ``check_every`` (0 disables both). The first failing ``P``
    is copied to ``P_fail`` and no further checks run.

    Returns
    -------
    s : float
        The last step's ``S``.
    k_fail : int
        Step of the first failed health check, or -1.
    """
    N = Z.shape[0]
    store = covs.shape[0] == N and N > 0
    r_each = Rv.shape[0] == N
    g = np.empty(x.shape[0])
    s = np.nan
    k_fail = -1
    # steps to the next full health check (a countdown: no division per step)
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    for k in range(N):
        if k == N - 1:
            _copy2(P, P_last)
        s = _sw_step(x, P, Hm[k], Z[k], Rv[k if r_each else 0], wH, wZ, wR, ist, refresh,
                     Lt, Ltx0, g, y, K)
        if countdown > 0:
            countdown -= 1
            full = countdown == 0
            if full:
                countdown = check_every
            if _sw_diagonal_bad(P) or (full and sw_unhealthy(P, cond_max)):
                k_fail = k
                countdown = -1
                _copy2(P, P_fail)
        _copy2(x, means[k])
        if store:
            _copy2(P, covs[k])
    return s, k_fail
