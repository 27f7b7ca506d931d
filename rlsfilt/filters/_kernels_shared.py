"""Compiled (numba) helpers shared by the kernels of every filter.

Small array loops, triangular solves and the health decisions of
:mod:`rlsfilt.filters._health` (which defines them in NumPy and words the
warnings). Every function is ``njit(cache=True)``: compiled once, then
loaded from the disk cache by later processes.
"""

import math

import numba
import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable

__all__ = []

_EPS = float(np.finfo(np.float64).eps)


def padded_width(n, m):
    """Row length of a padded work array: ``n + m`` rounded up to a multiple of 8.

    The kernels that sweep a matrix row by row keep it in rows of this length,
    zero past its ``n + m`` columns (``[W | v]`` of the square-root filter, the
    covariance of `RecursiveLeastSquares`'s fused batch loop): the inner loops
    then run over a multiple of 8 entries, which the compiler vectorizes with no
    scalar remainder.
    """
    return -(-(n + m) // 8) * 8


def aligned_zeros(shape, align=64):
    """A C-contiguous float64 array of zeros whose data start at a multiple of
    `align` bytes (a cache line).

    With rows of `padded_width` entries every row then starts on a cache
    line, and no vector load or store of a sweep straddles two lines (where
    ``numpy.zeros`` puts the data depends on the allocator's state: the same
    loop ran up to 20 % slower in some processes than in others).
    """
    size = int(np.prod(shape)) * 8
    raw = np.zeros(size + align, dtype=np.uint8)
    start = -raw.ctypes.data % align
    return raw[start:start + size].view(np.float64).reshape(shape)


@njit(cache=True, error_model="numpy")
def aligned_work(size):
    """`aligned_zeros` inside compiled code: ``size`` float64 zeros whose data
    start on a cache line (64 bytes; numba's allocator gives 32).

    The work arrays of the window kernels' sweeps come from here: a row of
    `padded_width` entries then never straddles two cache lines.
    """
    raw = np.zeros(size + 8)
    off = (-raw.ctypes.data % 64) // 8
    return raw[off:off + size]


@njit(cache=True, error_model="numpy", inline="always")
def copy2(a, b):
    """``b[:] = a`` for 2-D arrays."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            b[i, j] = a[i, j]


@njit(cache=True, error_model="numpy", inline="always")
def any_nan(z):
    for v in z:
        if v != v:
            return True
    return False


@njit(cache=True, error_model="numpy", inline="always")
def diagonal_bad(A):
    """True when a diagonal entry of ``A`` is not positive and finite (the cheap
    check: a positive definite ``P``, or the factor ``U`` of one, has a positive
    diagonal)."""
    for i in range(A.shape[0]):
        v = A[i, i]
        if not (v > 0.0 and v < np.inf):
            return True
    return False


@njit(cache=True, error_model="numpy")
def back_substitute(U, B, X):
    """Solve ``U X = B`` (``U`` upper triangular); `X` may be `B`."""
    n, m = B.shape
    for c in range(m):
        for i in range(n - 1, -1, -1):
            acc = B[i, c]
            for k in range(i + 1, n):
                acc -= U[i, k] * X[k, c]
            X[i, c] = acc / U[i, i]


@njit(cache=True, error_model="numpy")
def upper_inverse_gram(U, P):
    """``P = U^-1 U^-T`` for an upper-triangular `U` with a nonzero diagonal.

    ``V = U^-1`` by back substitution, column by column; then ``P_ij =
    sum_{k >= max(i, j)} V_ik V_jk`` for ``i <= j``, mirrored, so ``P`` is
    exactly symmetric.
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


@njit(cache=True, error_model="numpy")
def singular_range(R):
    """Smallest and largest singular value of the square `R` (one-sided Jacobi).

    Hestenes' method: plane rotations orthogonalize the columns of a copy of
    `R`; the column norms are then the singular values, to high relative
    accuracy (Demmel & Veselic 1992), without LAPACK.
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


# ----------------------------------------------------------------------
# health decisions (the NumPy definitions are in _health)
# ----------------------------------------------------------------------
@njit(cache=True, error_model="numpy")
def unhealthy(P, cond_max, exact=True):
    """True when ``_health.symmetric_problem(P, cond_max)`` finds a problem:
    non-finite, not symmetric to 1e-8, not positive definite, or condition
    number above `cond_max` (`unhealthy_sym` of ``(P + P^T) / 2``)."""
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
    return unhealthy_sym(A, cond_max, np.empty((n, n)), np.empty((n, n)), exact)


@njit(cache=True, error_model="numpy")
def unhealthy_sym(A, cond_max, W, X, exact=True):
    """`unhealthy` of an exactly symmetric `A`, without allocating in the usual
    healthy case (`W`, `X`: (n, n) work space).

    The decision is the one ``eigvalsh`` gives, but a Cholesky factor
    ``A = U^T U`` settles the usual healthy case in about ``2 n^3 / 3``
    operations: ``cond(A) <= trace(A) trace(A^-1) = trace(A) ||U^-T||_F^2``,
    and a bound well inside `cond_max` (and below 1e12, where the computed
    eigenvalues are safely positive) means healthy. Otherwise the eigenvalues
    decide. Both factorizations run along rows (their inner loops are
    ``axpy``), so the compiler vectorizes them. Not `exact`, only the bound
    decides: what it cannot call healthy counts as unhealthy (the re-arming
    test of a warned filter, which need not pay for ``eigvalsh``).
    """
    n = A.shape[0]
    trace = 0.0
    for i in range(n):
        for j in range(n):
            W[i, j] = A[i, j]
        trace += A[i, i]
    finite = 0.0
    for i in range(n):                       # NaN or inf anywhere makes this NaN
        for j in range(n):
            finite += 0.0 * W[i, j]
    if finite != 0.0:
        return True
    chol = True
    for k in range(n):                       # W <- U, row by row (right-looking)
        d = W[k, k]
        if not d > 0.0:
            chol = False
            break
        ukk = math.sqrt(d)
        W[k, k] = ukk
        inv = 1.0 / ukk
        for j in range(k + 1, n):
            W[k, j] = W[k, j] * inv
        for i in range(k + 1, n):            # trailing upper triangle -= u_k^T u_k
            a = W[k, i]
            for j in range(i, n):
                W[i, j] = W[i, j] - a * W[k, j]
    if chol and trace * inverse_norm2(W, X) < min(0.5 * cond_max, 1e12):
        return False
    if not exact:
        return True
    # the eigenvalues, through Python: `eigen_unhealthy` is compiled on its first call,
    # not into every kernel that checks health (most runs never need it: a third of a
    # second of a first run's compile work)
    with numba.objmode(bad="boolean"):
        bad = _eigen_unhealthy_call(A, cond_max)
    return bad


@njit(cache=True, error_model="numpy")
def eigen_unhealthy(A, cond_max):
    """The eigenvalue decision of `unhealthy_sym`: ``A`` (exactly symmetric, finite) is not
    positive definite or its condition number is above `cond_max`."""
    w = np.linalg.eigvalsh(A)
    return w[0] <= 0.0 or w[A.shape[0] - 1] > cond_max * w[0]


def _eigen_unhealthy_call(A, cond_max):
    """`eigen_unhealthy` called from a compiled kernel's object-mode block."""
    return bool(eigen_unhealthy(A, cond_max))


@njit(cache=True, error_model="numpy", inline="always")
def inverse_norm2(U, X):
    """``||U^-1||_F^2`` of the upper-triangular `U` (nonzero diagonal; only its upper
    triangle is read), from the rows of ``X = U^-T`` (lower; `X` (n, n) work):
    ``X_i = (e_i - sum_{k<i} U_ki X_k) / U_ii``, row ``axpy`` loops."""
    n = U.shape[0]
    acc = 0.0
    for i in range(n):
        for j in range(i + 1):
            X[i, j] = 0.0
        X[i, i] = 1.0
        for k in range(i):                   # X_i -= U_ki X_k
            a = U[k, i]
            for j in range(k + 1):
                X[i, j] = X[i, j] - a * X[k, j]
        inv = 1.0 / U[i, i]
        for j in range(i + 1):
            v = X[i, j] * inv
            X[i, j] = v
            acc += v * v
    return acc


@njit(cache=True, error_model="numpy")
def unhealthy_on(P, basis, cond_max, exact=True):
    """`unhealthy` of ``basis^T P basis`` (``P`` under constraints; `basis` an
    orthonormal basis of the null space of ``A``), or of ``P`` when `basis`
    has no columns (no constraints)."""
    n, p = basis.shape
    if p == 0:
        return unhealthy(P, cond_max, exact)
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
    return unhealthy(R, cond_max, exact)


@njit(cache=True, error_model="numpy")
def factor_unhealthy(U, cond_max):
    """True when ``_health.factor_problem(U, cond_max)`` finds a problem with
    ``P = U^-1 U^-T``: non-finite ``U``, a diagonal entry that is not
    positive, or ``cond(P) = cond(U)^2`` above `cond_max`, without forming
    ``P``. As in `unhealthy_sym`, the bound ``cond(P) <= trace(P) trace(P^-1)
    = ||U^-1||_F^2 ||U||_F^2`` (one triangular inverse, ``n^3 / 3``) settles
    the usual healthy case; otherwise the singular values of ``U`` decide
    (`singular_range`, one-sided Jacobi)."""
    n = U.shape[0]
    norm2 = 0.0
    for i in range(n):
        for j in range(n):
            v = U[i, j]
            if v - v != 0.0:
                return True
            norm2 += v * v
    if diagonal_bad(U):
        return True
    if norm2 * inverse_norm2(U, np.empty((n, n))) < min(0.5 * cond_max, 1e12):
        return False
    smin, smax = singular_range(U)
    if not smin > 0.0:
        return True
    ratio = smax / smin
    return ratio * ratio > cond_max
