"""Compiled (numba) kernels of `SlidingWindowRLS` and `SquareRootRLS`: their one
production path.

Every public method of the two filters that runs the recursion calls these.
The same recursions in readable NumPy are in ``tests/_reference.py``
(``SlidingWindow``; ``square_root_update``, the Givens rotations whose numbers
the square root's kernel computes without square roots);
``tests/test_kernels_window.py`` holds the two equal step by step to 1e-12.
As in :mod:`rlsfilt.filters._kernels`, every function is ``njit(cache=True)``
and one implementation of a step serves both the batch kernel and the
streaming ``update`` (the square root's step function; the sliding window's
batch loop, which the streaming update runs on one sample), so the two agree
bit for bit.

Sliding window, one step (Haykin 2002, sec. 9)::

    g = P phi, s = phi . g + r               update with the new sample
    x <- x + (g / s) (z - phi x)^T,  P <- P - g g^T / s
    ring buffer: the new sample replaces the oldest one
    g = P h, d = r_old - h . g               downdate with the leaving sample
    x <- x - (g / d) (z_old - h x)^T,  P <- P + g g^T / d
    refit by Householder QR of the stored window when d is not clearly
    positive, when the window first fills, and every `refresh` steps

The batch loop makes one pass over ``P`` per sample (`_sw_pass`): a step
starts with both gains ``g = P phi`` and ``gl = P h`` (of the leaving row
``h``), which the previous pass summed; the downdate's gain on the updated
``P`` is ``P' h = gl - g (phi gl) / s`` (O(n)), and the pass applies the
update and the downdate together, ``P <- P - g g^T / s + g' g'^T / d``,
while it sums the next step's two gains and reads the new diagonal (the
cheap health check). That is ``10 n^2 + O(n)`` flops per step (the
rank-two update ``6 n^2``: each entry's products ``(g_i g_j) / s`` are
formed as the reference forms them, which keeps ``P`` exactly symmetric and
its round-off that of the reference; the two gains ``4 n^2``), as many as
the two passes of update then downdate, with half their loads and stores of
``P``. A full-rank refit is certified by ``cond(R) <= ||R||_F ||R^-1||_F``
before it would need the SVD.

Square root (information form, Gentleman's rotations without square roots)::

    U = Delta^-1/2 W,  v = W x      the state: W unit upper triangular, Delta
                                    diagonal positive, so P = W^-1 Delta W^-T
    Delta <- Delta / lam            predict (U <- sqrt(lam) U; W, v unchanged)
    fold the row [phi | z^T] of weight 1/r into [W | v], row i of W at a time:
        a_i: the new row's entry i, eta_0 = r
        eta_{i+1} = eta_i + a_i^2 delta_i
        delta_i <- delta_i eta_i / eta_{i+1},   k_i = a_i delta_i / eta_{i+1}
        a_j <- a_j - a_i W_ij,   W_ij <- W_ij + k_i a_j        (j > i)
        b   <- b - a_i v_i,      v_i  <- v_i + k_i b           (b: the z part)
    s = eta_n = phi P phi^T + r
    K = W^-1 (a o delta) / s        (the old factors; only when the gain is kept)
    x = W^-1 v                      unit triangular: no division

These are the numbers of the Givens rotations of ``[U d; phi/sqrt(r)
z^T/sqrt(r)]`` (``delta_i = 1 / U_ii^2``, ``delta_i eta_i / eta_{i+1}`` is
the squared cosine) without their square roots (Gentleman 1973): the
entries ``a_i`` after the eliminations are ``W^-T phi``, and each row costs
one division and two multiply-adds per entry. ``[W | v]`` is stored as one
array, so that ``v`` is rotated by the same loop as ``W``; the loop takes
four rows per pass over the columns (2.5 memory accesses per entry and row
instead of four), and ``x = W^-1 v`` four columns at a time.
``tests/test_kernels_window.py`` holds the kernels to the Givens reference
(``_reference.square_root_update``) at 1e-12.
"""

import math

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable
from ._kernels import gain
from ._kernels_shared import (
    _EPS,
    aligned_work,
    any_nan,
    back_substitute,
    copy2,
    diagonal_bad,
    factor_unhealthy,
    padded_width,  # noqa: F401  (SquareRootRLS reads it from here)
    singular_range,
    unhealthy,
    upper_inverse_gram,
)

__all__ = []


@njit(cache=True, error_model="numpy")
def sr_predict(delta, ilam):
    """``Delta <- Delta / lam`` in place (``ilam = 1 / lam``): ``P <- P / lam``
    with ``W`` and ``v = W x`` unchanged."""
    for i in range(delta.shape[0]):
        delta[i] = delta[i] * ilam


@njit(cache=True, error_model="numpy", inline="always")
def _unit_back_solve(Wv, xw):
    """``W xw_new = xw`` in place (the first n entries of `xw`) for the unit
    upper-triangular ``W = Wv[:, :n]``.

    By columns (once ``xw_i`` is solved it is taken off every row above,
    ``xw_q <- xw_q - W_qi xw_i``), four columns at a time: the 4 x 4 block on the
    diagonal first, then each row above reads its four contiguous entries
    ``W[q, i-3:i+1]``. The subtractions are those of the column-by-column
    loop, in its order.
    """
    one = np.uint64(1)
    i = np.uint64(Wv.shape[0])                 # one past the column being solved
    while i >= np.uint64(4):                   # columns i - 1, ..., i - 4
        i0, i1, i2, i3 = i - np.uint64(4), i - np.uint64(3), i - np.uint64(2), i - one
        x3 = xw[i3]
        x2 = xw[i2] - Wv[i2, i3] * x3
        x1 = (xw[i1] - Wv[i1, i3] * x3) - Wv[i1, i2] * x2
        x0 = ((xw[i0] - Wv[i0, i3] * x3) - Wv[i0, i2] * x2) - Wv[i0, i1] * x1
        xw[i2] = x2
        xw[i1] = x1
        xw[i0] = x0
        for q in range(i0):
            xw[q] = (((xw[q] - Wv[q, i3] * x3) - Wv[q, i2] * x2) - Wv[q, i1] * x1
                     - Wv[q, i0] * x0)
        i = i0
    while i >= np.uint64(2):
        i -= one
        xi = xw[i]
        for q in range(i):
            xw[q] -= Wv[q, i] * xi


@njit(cache=True, error_model="numpy")
def sr_covariance(Wv, delta, P):
    """``P = W^-1 Delta W^-T`` for the unit upper-triangular ``W = Wv[:, :n]``.

    ``V = W^-1`` by back substitution, column by column; then ``P_ij =
    sum_{k >= max(i, j)} V_ik delta_k V_jk`` for ``i <= j``, mirrored, so
    ``P`` is exactly symmetric.
    """
    n = delta.shape[0]
    V = np.zeros((n, n))
    for j in range(n):
        V[j, j] = 1.0
        for i in range(j - 1, -1, -1):
            acc = 0.0
            for k in range(i + 1, j + 1):
                acc += Wv[i, k] * V[k, j]
            V[i, j] = -acc
    for i in range(n):
        for j in range(i, n):
            acc = 0.0
            for k in range(j, n):
                acc += V[i, k] * delta[k] * V[j, k]
            P[i, j] = acc
            P[j, i] = acc


@njit(cache=True, error_model="numpy")
def sr_factor(Wv, delta, U):
    """The information square root ``U = Delta^-1/2 W`` (``U^T U = P^-1``).

    A row whose ``delta_i`` is not positive gets the diagonal entry
    ``-1 / sqrt(-delta_i)`` (or an infinite or NaN one), so that the health
    check's test of ``U``'s diagonal reports it.
    """
    n = delta.shape[0]
    for i in range(n):
        di = delta[i]
        f = 1.0 / math.sqrt(di) if di > 0.0 else -1.0 / math.sqrt(-di)
        for j in range(n):
            U[i, j] = Wv[i, j] * f if j > i else 0.0
        U[i, i] = f


@njit(cache=True, error_model="numpy")
def sr_unhealthy(Wv, delta, cond_max, U):
    """``factor_unhealthy`` of ``U = Delta^-1/2 W`` (formed in the workspace `U`)."""
    sr_factor(Wv, delta, U)
    return factor_unhealthy(U, cond_max)


@njit(cache=True, error_model="numpy", inline="always")
def _delta_bad(delta):
    """The cheap health check: a ``delta_i`` that is not positive and finite (``P``
    is positive definite exactly when every ``delta_i`` is positive)."""
    ok = True
    for i in range(delta.shape[0]):            # (no early exit: the loop vectorizes)
        di = delta[i]
        ok = ok & (di > 0.0) & (di < np.inf)
    return not ok


@njit(cache=True, error_model="numpy", inline="always")
def _rotate(delta, i, ai, eta):
    """Row ``i``'s numbers: ``delta_i <- delta_i eta_i / eta_{i+1}`` in place;
    returns ``k_i = a_i delta_i / eta_{i+1}`` and ``eta_{i+1}`` (``k_i = 0``
    and nothing changed when ``a_i = 0``)."""
    if ai == 0.0:
        return 0.0, eta
    g = ai * delta[i]
    eta_new = eta + g * ai                     # eta_{i+1} = eta_i + a_i^2 delta_i
    inv = 1.0 / eta_new
    delta[i] = delta[i] * (eta * inv)
    return g * inv, eta_new


@njit(cache=True, error_model="numpy", inline="always")
def _sr_step(Wv, delta, x, phi, z, r, y, K, gain, a, want_y):
    """One measurement update of the square-root-free factors ``[W | v] = Wv``
    and ``delta``, in place.

    Writes ``x`` (n, m), ``y`` (m,) when `want_y` and, when `gain`, ``K``
    (n,) (NaN and zero when `z` holds a NaN) and returns ``s = H P H^T +
    R``. The rows of ``Wv`` are padded with zeros to a multiple of 8
    entries (`padded_width`), and ``a`` (as long as a row) is zero past
    ``n + m``: the padding stays zero. The gain is not needed to update the
    factors, nor the residual: the batch kernel forms them for the last step
    only. A missing sample changes nothing.

    The rows of ``[W | v]`` are rotated four at a time: after the 4 x 4
    block on the diagonal, one pass over the columns right of the block
    applies the four rows (row ``i``'s new entries, then row ``i + 1``'s
    from them, ...), the numbers of four single-row passes. The block's
    pass starts at a multiple of 4 and ends at the padded width, and its
    indices are unsigned (``np.uint64``: no negative-index fix-up), so that
    the compiler vectorizes it.
    """
    n = delta.shape[0]
    m = x.shape[1]
    missing = any_nan(z)
    if want_y:
        for j in range(m):                     # y = z - phi x
            acc = 0.0
            for i in range(n):
                acc += phi[i] * x[i, j]
            y[j] = z[j] - acc
    if missing or gain:
        # the eliminations alone (W^T a = phi): a_i delta_i = (Delta W^-T phi)_i, and
        # s = r + sum_i a_i^2 delta_i, in the order the update below adds them
        for i in range(n):
            a[i] = phi[i]
        s = r
        for i in range(n):
            ai = a[i]
            g = ai * delta[i]
            K[i] = g
            s += g * ai
            row = Wv[i]
            for j in range(i + 1, n):
                a[j] -= ai * row[j]
        if missing:
            for j in range(m):
                y[j] = np.nan
            for i in range(n):
                K[i] = 0.0
            return s
        _unit_back_solve(Wv, K)                # K = W^-1 Delta W^-T phi (/ s below)
    for i in range(n):                         # the new row [phi | z^T], weight 1 / r
        a[i] = phi[i]
    for j in range(m):
        a[n + j] = z[j]
    eta = r
    L, un = np.uint64(Wv.shape[1]), np.uint64(n)
    one = np.uint64(1)
    i = np.uint64(0)
    while i + np.uint64(3) < un:               # rows i, ..., i + 3
        i1, i2, i3 = i + one, i + np.uint64(2), i + np.uint64(3)
        # the 4 x 4 block on the diagonal, row by row: a_j <- a_j - a_i W_ij and
        # W_ij <- W_ij + k_i a_j for the block's columns j right of row i
        a0 = a[i]
        k0, eta = _rotate(delta, i, a0, eta)
        w = Wv[i, i1]
        a1 = a[i1] - a0 * w
        Wv[i, i1] = w + k0 * a1
        w = Wv[i, i2]
        a2 = a[i2] - a0 * w
        Wv[i, i2] = w + k0 * a2
        w = Wv[i, i3]
        a3 = a[i3] - a0 * w
        Wv[i, i3] = w + k0 * a3
        k1, eta = _rotate(delta, i1, a1, eta)
        w = Wv[i1, i2]
        a2 = a2 - a1 * w
        Wv[i1, i2] = w + k1 * a2
        w = Wv[i1, i3]
        a3 = a3 - a1 * w
        Wv[i1, i3] = w + k1 * a3
        k2, eta = _rotate(delta, i2, a2, eta)
        w = Wv[i2, i3]
        a3 = a3 - a2 * w
        Wv[i2, i3] = w + k2 * a3
        k3, eta = _rotate(delta, i3, a3, eta)
        # the columns right of the block: the four rows' passes in one
        for j in range(i + np.uint64(4), L):
            w0, w1, w2, w3 = Wv[i, j], Wv[i1, j], Wv[i2, j], Wv[i3, j]
            t = a[j] - a0 * w0                 # a_j <- a_j - a_i W_ij
            Wv[i, j] = w0 + k0 * t             # W_ij <- W_ij + k_i a_j
            t = t - a1 * w1                    # then rows i + 1, i + 2, i + 3
            Wv[i1, j] = w1 + k1 * t
            t = t - a2 * w2
            Wv[i2, j] = w2 + k2 * t
            t = t - a3 * w3
            Wv[i3, j] = w3 + k3 * t
            a[j] = t
        i += np.uint64(4)
    while i < un:                              # the last rows, one at a time
        a0 = a[i]
        k0, eta = _rotate(delta, i, a0, eta)
        for j in range(i + one, L):
            w0 = Wv[i, j]
            t = a[j] - a0 * w0
            Wv[i, j] = w0 + k0 * t
            a[j] = t
        i += one
    s = eta                                    # S = H P H^T + R
    if gain:
        for i in range(n):
            K[i] = K[i] / s                    # K = P H^T / S
    for c in range(m):                         # x = W^-1 v, column by column
        for i in range(n):
            a[i] = Wv[i, n + c]
        _unit_back_solve(Wv, a)
        for i in range(n):
            x[i, c] = a[i]
    return s


@njit(cache=True, error_model="numpy")
def sr_update_kernel(Wv, delta, x, phi, z, r, y, K):
    """Streaming :meth:`SquareRootRLS.update`: `_sr_step` on the given arrays.

    Returns ``s`` and whether the new ``delta`` fails the cheap health check.
    """
    s = _sr_step(Wv, delta, x, phi, z, r, y, K, delta.shape[0] > 0, np.zeros(Wv.shape[1]),
                 True)
    return s, _delta_bad(delta)


@njit(cache=True, error_model="numpy")
def sr_batch_kernel(Wv, delta, x, Z, Hm, Rv, ilam, update_first, means, covs, covs_p,
                    x_prior, P_prior, P_post, y, K, check_every, step0, cond_max, U_fail):
    """Run `SquareRootRLS` over a record, in place on ``Wv``, ``delta`` and ``x``.

    ``ilam = 1 / lam`` (1.0: no time update). ``Rv`` has length N or 1 (one
    variance for all steps). ``covs``, ``covs_p`` (N, n, n) are written when
    their length is N. Leaves the last predict's ``x_prior``, ``P_prior``
    and the last update's ``P_post``, ``y`` and ``K`` (the last
    non-missing gain is not kept: a missing last sample leaves ``K`` zero,
    as the streaming step does).

    The health check of ``P`` runs after every update as
    :meth:`SquareRootRLS.update` runs it: the cheap test of ``delta`` each
    step and ``factor_unhealthy`` of ``U = Delta^-1/2 W`` when the update
    count ``step0 + k + 1`` is a multiple of ``check_every`` (0 disables
    both). The first failing ``U`` is written to ``U_fail`` and no further
    checks run.

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
    # work copies of the factors whose rows start on cache lines (written back
    # at the end); a (the new row) likewise
    a = aligned_work(Wv.shape[1])
    Wu, du = Wv, delta
    Wv = aligned_work(Wu.shape[0] * Wu.shape[1]).reshape(Wu.shape)
    copy2(Wu, Wv)
    delta = aligned_work(du.shape[0])
    delta[:] = du
    nm = x.shape[0] * x.shape[1]
    xflat = x.reshape(nm)                      # (views of the same numbers)
    mflat = means.reshape((N, nm))
    s = np.nan
    k_fail = -1
    # steps to the next full health check (a countdown: no division per step)
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    for k in range(N):
        last = k == N - 1
        if not update_first:
            if ilam != 1.0:
                sr_predict(delta, ilam)
            if store:
                sr_covariance(Wv, delta, covs_p[k])
            if last:
                copy2(x, x_prior)
                if store:
                    copy2(covs_p[k], P_prior)
                else:
                    sr_covariance(Wv, delta, P_prior)
        s = _sr_step(Wv, delta, x, Hm[k], Z[k], Rv[k if r_each else 0], y, K, last, a, last)
        if countdown > 0:
            countdown -= 1
            full = countdown == 0
            if full:
                countdown = check_every
            if _delta_bad(delta) or (full and sr_unhealthy(Wv, delta, cond_max, U_fail)):
                k_fail = k
                countdown = -1
                sr_factor(Wv, delta, U_fail)
        mk = mflat[k]                          # means[k] = x (flat: one loop)
        for i in range(nm):
            mk[i] = xflat[i]
        if store:
            sr_covariance(Wv, delta, covs[k])
        if last:
            if store:
                copy2(covs[k], P_post)
            else:
                sr_covariance(Wv, delta, P_post)
        if update_first:
            if ilam != 1.0:
                sr_predict(delta, ilam)
            if store:
                sr_covariance(Wv, delta, covs_p[k])
            if last:
                copy2(x, x_prior)
                if store:
                    copy2(covs_p[k], P_prior)
                else:
                    sr_covariance(Wv, delta, P_prior)
    copy2(Wv, Wu)
    du[:] = delta
    return s, k_fail


# ----------------------------------------------------------------------
# SlidingWindowRLS
# ----------------------------------------------------------------------
# the integer state ``ist`` of the sliding window
HEAD, NW, COUNT, NEXT_EXACT, EXACT = 0, 1, 2, 3, 4


@njit(cache=True, error_model="numpy")
def window_lstsq(wH, wZ, wR, nw, Lt, Ltx0, n_prior, x, P):
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
        if not any_nan(wZ[k]):
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
        if any_nan(wZ[k]):
            continue
        wk = 1.0 / math.sqrt(wR[k])
        for j in range(n):
            A[i, j] = wH[k, j] * wk
        for j in range(m):
            A[i, n + j] = wZ[k, j] * wk
        i += 1
    # Householder QR of the first n columns, applied to all n + m columns; the
    # reflection of the columns right of j runs along the rows (each column's sum
    # in row order, as a column-by-column loop would add it: contiguous, and the
    # columns' sums are independent chains)
    v = np.empty(rows)
    f = np.empty(n + m)
    for j in range(n):
        norm2 = 0.0
        for i in range(j, rows):               # v = A[j:, j] (below the diagonal,
            a = A[i, j]                        # column j is not read again)
            v[i] = a
            norm2 += a * a
        norm = math.sqrt(norm2)
        if norm == 0.0:
            continue
        alpha = -norm if A[j, j] >= 0.0 else norm
        v[j] -= alpha
        vnorm2 = norm2 - A[j, j] * A[j, j] + v[j] * v[j]
        A[j, j] = alpha
        if vnorm2 == 0.0:
            continue
        for col in range(j + 1, n + m):
            f[col] = 0.0
        i = j
        while i + 4 <= rows:                   # f = A^T v, four rows at a time
            v0, v1, v2, v3 = v[i], v[i + 1], v[i + 2], v[i + 3]
            a0, a1, a2, a3 = A[i], A[i + 1], A[i + 2], A[i + 3]
            for col in range(j + 1, n + m):
                f[col] = (((f[col] + v0 * a0[col]) + v1 * a1[col]) + v2 * a2[col]
                          + v3 * a3[col])
            i += 4
        while i < rows:
            vi = v[i]
            row = A[i]
            for col in range(j + 1, n + m):
                f[col] += vi * row[col]
            i += 1
        for col in range(j + 1, n + m):
            f[col] = 2.0 * f[col] / vnorm2
        i = j
        while i + 4 <= rows:                   # A -= v (2 A^T v / |v|^2)^T
            v0, v1, v2, v3 = v[i], v[i + 1], v[i + 2], v[i + 3]
            a0, a1, a2, a3 = A[i], A[i + 1], A[i + 2], A[i + 3]
            for col in range(j + 1, n + m):
                fc = f[col]
                a0[col] -= fc * v0
                a1[col] -= fc * v1
                a2[col] -= fc * v2
                a3[col] -= fc * v3
            i += 4
        while i < rows:
            vi = v[i]
            row = A[i]
            for col in range(j + 1, n + m):
                row[col] -= f[col] * vi
            i += 1
    Rf = np.empty((n, n))
    fro2 = 0.0
    for i in range(n):
        for j in range(n):
            Rf[i, j] = A[i, j] if j >= i else 0.0
            fro2 += Rf[i, j] * Rf[i, j]
    Pt = np.empty((n, n))
    upper_inverse_gram(Rf, Pt)                     # (R^T R)^-1
    if n_prior == 0:
        # full rank when s_min > s_max tol; cond(R) <= ||R||_F ||R^-1||_F =
        # sqrt(||R||_F^2 trace(P)) settles the clear case without the SVD
        tol = max(rows, n) * _EPS
        tr = 0.0
        for i in range(n):
            tr += Pt[i, i]
        if not fro2 * tr * tol * tol < 1.0:
            smin, smax = singular_range(Rf)
            if not smin > smax * tol:
                return False
    QtB = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            QtB[i, j] = A[i, n + j]
    back_substitute(Rf, QtB, x)
    copy2(Pt, P)
    return True


@njit(cache=True, error_model="numpy", inline="always")
def _sw_refit_due(ist, window, refreshing):
    """Whether the step that is about to add a sample ends with a refit, whatever
    its downdate gives: the window fills without the exact solution due, or the
    step ends a `refresh` period (`refreshing`; the counters as the step leaves
    them)."""
    nw = min(ist[NW] + 1, window)
    return refreshing or (nw == window and not ist[EXACT] and ist[COUNT] + 1 >= ist[NEXT_EXACT])


@njit(cache=True, error_model="numpy")
def sw_update_kernel(x, P, phi, z, r, wH, wZ, wR, ist, refresh, Lt, Ltx0, y, K):
    """Streaming :meth:`SlidingWindowRLS.update`: `sw_batch_kernel` on a record of
    one sample (the one implementation of the step: streaming and batch agree
    bit for bit; the caller runs the health check).

    Returns ``s`` and whether the diagonal of the new ``P`` fails the cheap
    health check (``diagonal_bad``).
    """
    n, m = x.shape
    Rv = np.empty(1)
    Rv[0] = r
    s, _ = sw_batch_kernel(x, P, z.reshape((1, m)), phi.reshape((1, n)), Rv, wH, wZ, wR, ist,
                           refresh, Lt, Ltx0, np.empty((1, n, m)), np.empty((0, n, n)), y, K,
                           np.empty((n, n)), 0, 0, 1.0, np.empty((n, n)))
    return s, diagonal_bad(P)


@njit(cache=True, error_model="numpy", inline="always")
def _sw_pass(W, V, oa, ob, ca, cb, H1, k1, H2, k2, o1, o2, n, npad):
    """``P <- (P + (a a^T) ca) + (b b^T) cb`` in one pass, rows four at a time,
    summing the gains ``g1 = P h1`` and ``g2 = P h2`` of the new ``P``, where
    ``h1 = H1[k1]`` and ``h2 = H2[k2]`` (rows of their arrays, read in place).

    ``P`` is row ``i`` of `W` at ``i npad``; ``a``, ``b``, ``g1``, ``g2`` are
    the `npad` entries of `V` at ``oa``, ``ob``, ``o1``, ``o2`` (the entries
    past ``n`` are zero and stay zero). Every index is unsigned (``np.uint64``)
    and the rows are padded to a multiple of 8: the compiler vectorizes the
    inner loop with no scalar remainder and no negative-index fix-up, and no
    row views (their reference counts) are made.

    Each gain is summed in row order (``g_j += P_ij h_i``, ``i`` ascending,
    from 0): the numbers `_kernels.gain` gives on the new ``P``. The new
    ``P`` is exactly symmetric when the old one is (``a_i a_j = a_j a_i`` in
    floating point).

    Returns whether the new diagonal is positive and finite (the cheap health
    check, `diagonal_bad`, read as the rows are done).
    """
    one = np.uint64(1)
    ok = True
    for j in range(npad):
        V[o1 + j] = 0.0
        V[o2 + j] = 0.0
    i = np.uint64(0)
    while i + np.uint64(3) < n:                # four rows at a time
        i1, i2, i3 = i + one, i + np.uint64(2), i + np.uint64(3)
        r0 = i * npad
        r1, r2, r3 = r0 + npad, r0 + np.uint64(2) * npad, r0 + np.uint64(3) * npad
        a0, a1, a2, a3 = V[oa + i], V[oa + i1], V[oa + i2], V[oa + i3]
        b0, b1, b2, b3 = V[ob + i], V[ob + i1], V[ob + i2], V[ob + i3]
        p0, p1, p2, p3 = H1[k1, i], H1[k1, i1], H1[k1, i2], H1[k1, i3]
        q0, q1, q2, q3 = H2[k2, i], H2[k2, i1], H2[k2, i2], H2[k2, i3]
        for j in range(npad):
            aj = V[oa + j]
            bj = V[ob + j]
            w0 = (W[r0 + j] + (a0 * aj) * ca) + (b0 * bj) * cb
            w1 = (W[r1 + j] + (a1 * aj) * ca) + (b1 * bj) * cb
            w2 = (W[r2 + j] + (a2 * aj) * ca) + (b2 * bj) * cb
            w3 = (W[r3 + j] + (a3 * aj) * ca) + (b3 * bj) * cb
            W[r0 + j] = w0
            W[r1 + j] = w1
            W[r2 + j] = w2
            W[r3 + j] = w3
            V[o1 + j] = (((V[o1 + j] + w0 * p0) + w1 * p1) + w2 * p2) + w3 * p3
            V[o2 + j] = (((V[o2 + j] + w0 * q0) + w1 * q1) + w2 * q2) + w3 * q3
        d0, d1, d2, d3 = W[r0 + i], W[r1 + i1], W[r2 + i2], W[r3 + i3]
        ok = (ok & (d0 > 0.0) & (d0 < np.inf) & (d1 > 0.0) & (d1 < np.inf)
              & (d2 > 0.0) & (d2 < np.inf) & (d3 > 0.0) & (d3 < np.inf))
        i += np.uint64(4)
    while i < n:                               # the last rows, one at a time
        r0 = i * npad
        a0, b0, p0, q0 = V[oa + i], V[ob + i], H1[k1, i], H2[k2, i]
        for j in range(npad):
            w0 = (W[r0 + j] + (a0 * V[oa + j]) * ca) + (b0 * V[ob + j]) * cb
            W[r0 + j] = w0
            V[o1 + j] += w0 * p0
            V[o2 + j] += w0 * q0
        d0 = W[r0 + i]
        ok = ok & (d0 > 0.0) & (d0 < np.inf)
        i += one
    return ok


@njit(cache=True, error_model="numpy", inline="always")
def _sw_load(P, W, npad):
    """Row ``i`` of `P` into `W` at ``i npad`` (the padding stays zero)."""
    n = P.shape[0]
    for i in range(n):
        row = P[i]
        o = i * npad
        for j in range(n):
            W[o + j] = row[j]


@njit(cache=True, error_model="numpy", inline="always")
def _sw_store(W, npad, P):
    """`P` from the padded rows of `W` (the inverse of `_sw_load`)."""
    n = P.shape[0]
    for i in range(n):
        row = P[i]
        o = i * npad
        for j in range(n):
            row[j] = W[o + j]


@njit(cache=True, error_model="numpy")
def sw_batch_kernel(x, P, Z, Hm, Rv, wH, wZ, wR, ist, refresh, Lt, Ltx0, means, covs, y, K,
                    P_last, check_every, step0, cond_max, P_fail):
    """Run `SlidingWindowRLS` over a record, in place on the state.

    ``Rv`` has length N or 1; ``covs`` (N, n, n) is written when its length
    is N. ``y`` and ``K`` are the last step's, ``P_last`` is ``P`` before
    the last step. (The window has no time update: the caller builds the
    predicted histories from these.)

    Each step updates with the new sample, slides the ring buffer, downdates
    with the leaving sample and refits when due, in place on ``x``, ``P``,
    the buffer and ``ist``, in one pass over ``P`` (`_sw_pass`). A step
    starts with the gains ``g = P phi`` of its sample and ``gl = P psi`` of
    the leaving one, both summed by the previous step's pass; the downdate's
    gain is ``h = P' psi = gl - g (phi gl) / s`` (``P' = P - g g^T / s``),
    and the pass applies ``P'' = P - g g^T / s + h h^T / d`` while it sums
    the next step's two gains. ``P`` lives in padded rows for the pass
    (`_sw_load`, `_sw_store` at the start, the end and where ``P`` itself is
    needed). A step that ends with a refit (`window_lstsq` replaces ``x``
    and ``P``) or changes nothing (a missing sample, nothing leaving) skips
    the pass; `_kernels.gain` then sums the gains of its ``P``.

    The health check runs after every update as
    :meth:`SlidingWindowRLS.update` runs it: the cheap diagonal test each
    step and ``unhealthy`` when the update count ``step0 + k + 1`` is a
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
    n, m = x.shape
    window = wH.shape[0]
    # P in padded rows (`_sw_pass`); the gains g = P phi and gl = P psi (then
    # h) of this step in V at og, ol, the next step's at the other two slots
    npad = (n + 7) // 8 * 8
    un, unpad = np.uint64(n), np.uint64(npad)
    W = aligned_work(n * npad)                 # every row on a cache line
    V = aligned_work(4 * npad)
    xflat = x.reshape(n * m)                   # (views of the same numbers)
    mflat = means.reshape((N, n * m))
    _sw_load(P, W, npad)
    cur = 0
    h = ist[HEAD]
    leaving = ist[NW] == window and not any_nan(wZ[h])   # a sample leaves at this step
    if N:
        gain(P, Hm[0], V[0:n])                 # later steps' gains come from the pass
        if leaving:
            gain(P, wH[h], V[npad:npad + n])
    s = np.nan
    k_fail = -1
    # steps to the next full health check and to the end of a refresh period
    # (countdowns: no division per step)
    countdown = check_every - step0 % check_every if check_every > 0 else -1
    to_refresh = refresh - ist[COUNT] % refresh if refresh > 0 else -1
    for k in range(N):
        if k == N - 1:
            _sw_store(W, npad, P_last)
        to_refresh -= 1
        refreshing = to_refresh == 0
        if refreshing:
            to_refresh = refresh
        # one step (see the module; written out here, not in a function: a call
        # that takes arrays costs reference counting that is most of a small
        # step's bookkeeping)
        r = Rv[k if r_each else 0]
        kn = min(k + 1, N - 1)                     # the next regressor's row
        og = 2 * cur * npad
        ol = og + npad
        s = r
        t = 0.0
        acc = 0.0
        for i in range(n):                         # (independent sums in one loop)
            s += Hm[k, i] * V[og + i]              # s = phi P phi^T + r
            t += Hm[k, i] * V[ol + i]              # t = phi P psi^T
            acc += Hm[k, i] * x[i, 0]              # phi x, first output
        missing = False
        for j in range(m):
            zj = Z[k, j]
            missing |= zj != zj
        c = 0.0
        if missing:
            for j in range(m):
                y[j] = np.nan
            for i in range(n):
                K[i] = 0.0
        else:
            y[0] = Z[k, 0] - acc                   # y = z - phi x
            for j in range(1, m):
                acc = 0.0
                for i in range(n):
                    acc += Hm[k, i] * x[i, j]
                y[j] = Z[k, j] - acc
            c = 1.0 / s
            y0 = y[0]
            for i in range(n):
                ki = V[og + i] * c                 # K = P phi^T / s
                K[i] = ki
                x[i, 0] = x[i, 0] + ki * y0        # x = x + K y^T
            for j in range(1, m):
                yj = y[j]
                for i in range(n):
                    x[i, j] = x[i, j] + K[i] * yj
        # ring buffer: slot `h` holds the oldest sample once the window is full
        refit = _sw_refit_due(ist, window, refreshing)
        cd = 0.0
        if leaving and not refit:                  # downdate with the leaving sample
            rl = wR[h]
            tc = t * c
            dd = rl
            acc = 0.0
            for i in range(n):
                hi = V[ol + i] - V[og + i] * tc    # h = P' psi^T = gl - g (phi gl) / s
                V[ol + i] = hi
                dd -= wH[h, i] * hi                # d = R - psi P' psi^T
                acc += wH[h, i] * x[i, 0]
            if dd > 1e-8 * rl:
                cd = 1.0 / dd
                for j in range(m):
                    if j:
                        acc = 0.0
                        for i in range(n):
                            acc += wH[h, i] * x[i, j]
                    e = wZ[h, j] - acc             # residual of the leaving sample
                    for i in range(n):
                        x[i, j] = x[i, j] - (V[ol + i] * cd) * e
            else:
                refit = True
        for j in range(n):
            wH[h, j] = Hm[k, j]
        for j in range(m):
            wZ[h, j] = np.nan if missing else Z[k, j]
        wR[h] = r
        h = h + 1 if h + 1 < window else 0
        ist[HEAD] = h
        ist[NW] = min(ist[NW] + 1, window)
        ist[COUNT] += 1
        leaving = ist[NW] == window                # at the next step
        for j in range(m):
            zj = wZ[h, j]
            leaving &= zj == zj
        cur = 1 - cur
        on = 2 * cur * npad                        # the next step's gains
        if refit or (missing and cd == 0.0):       # P from the refit, or unchanged
            if refit:
                nw = ist[NW]
                if window_lstsq(wH, wZ, wR, nw, Lt, Ltx0, n - n, x, P):   # (n - n: one typing)
                    ist[EXACT] = 1
                else:
                    ist[EXACT] = 0
                    ist[NEXT_EXACT] = ist[COUNT] + window
                    window_lstsq(wH, wZ, wR, nw, Lt, Ltx0, n, x, P)
                _sw_load(P, W, npad)
            else:
                _sw_store(W, npad, P)
            gain(P, Hm[kn], V[on:on + n])
            if leaving:
                gain(P, wH[h], V[on + npad:on + npad + n])
            healthy = not diagonal_bad(P)
        else:                                      # P'' and the next step's gains
            if cd == 0.0:
                for i in range(n):
                    V[ol + i] = 0.0
            healthy = _sw_pass(W, V, np.uint64(og), np.uint64(ol), -c, cd, Hm, kn, wH, h,
                               np.uint64(on), np.uint64(on + npad), un, unpad)
        if countdown > 0:
            countdown -= 1
            full = countdown == 0
            if full:
                countdown = check_every
                _sw_store(W, npad, P)
            if not healthy or (full and unhealthy(P, cond_max)):
                k_fail = k
                countdown = -1
                _sw_store(W, npad, P_fail)
        for i in range(n * m):                     # means[k] = x (flat: one loop)
            mflat[k, i] = xflat[i]
        if store:
            _sw_store(W, npad, covs[k])
    _sw_store(W, npad, P)
    return s, k_fail
