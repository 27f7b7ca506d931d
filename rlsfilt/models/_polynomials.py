r"""Algebra of polynomials in the delay operator :math:`q^{-1}`.

A polynomial is a 1-D coefficient array of ascending powers of
:math:`q^{-1}` (MATLAB's convention: ``[1, a1, a2]`` is
:math:`1 + a_1 q^{-1} + a_2 q^{-2}`); a matrix polynomial is a nested list
``M[i][j]`` of such arrays. Products are convolutions. Nothing here knows a
model structure: the models give their polynomials to
:mod:`rlsfilt.models._conversion`, which uses these helpers.
"""

import numpy as np

__all__ = []


def same_poly(p, q):
    """Equal coefficient arrays to round-off (same length)."""
    return len(p) == len(q) and np.allclose(p, q, rtol=1e-12, atol=0)


def trim(p):
    """Drop trailing zeros of a polynomial in ``q^-1`` (keep at least one coefficient)."""
    p = np.asarray(p, dtype=float)
    nz = np.flatnonzero(p)
    return p[:nz[-1] + 1].copy() if len(nz) else np.zeros(1)


def padd(p, q):
    """``p + q`` for coefficient arrays of any lengths."""
    n = max(len(p), len(q))
    out = np.zeros(n)
    out[:len(p)] += p
    out[:len(q)] += q
    return out


def equalize(num, den):
    """Zero-pad two ``q^-1`` polynomials to equal length, then cancel common ``q^-1`` factors.

    Equal length makes the coefficient arrays valid in positive powers of
    ``z`` as they stand (both are multiplied by the same ``z^L``).
    """
    n = max(len(num), len(den))
    num = np.concatenate([num, np.zeros(n - len(num))])
    den = np.concatenate([den, np.zeros(n - len(den))])
    while n > 1 and num[-1] == 0.0 and den[-1] == 0.0:
        num, den, n = num[:-1], den[:-1], n - 1
    return num, den


def poly_det(M):
    """Determinant of a square matrix of ``q^-1`` polynomials (cofactor expansion)."""
    n = len(M)
    if n == 1:
        return M[0][0]
    det = np.zeros(1)
    for j in range(n):
        minor = [row[:j] + row[j + 1:] for row in M[1:]]
        term = np.convolve(M[0][j], poly_det(minor))
        det = padd(det, term if j % 2 == 0 else -term)
    return det


def poly_adj(M):
    """Adjugate of a square matrix of polynomials: ``adj(M) M = det(M) I``."""
    n = len(M)
    if n == 1:
        return [[np.array([1.0])]]
    adj = [[None] * n for _ in range(n)]
    for i in range(n):
        for j in range(n):
            minor = [row[:j] + row[j + 1:] for k, row in enumerate(M) if k != i]
            c = poly_det(minor)
            adj[j][i] = c if (i + j) % 2 == 0 else -c
    return adj


def poly_product(polys):
    """Product of a sequence of polynomials (``[1.0]`` for an empty one)."""
    out = np.array([1.0])
    for p in polys:
        out = np.convolve(out, p)
    return out


def evaluate(p, zinv):
    r"""``p(z^{-1}) = sum_k p[k] z^{-k}`` at the points `zinv` (any shape)."""
    zinv = np.asarray(zinv)
    out = np.zeros(zinv.shape, dtype=complex)
    for c in np.asarray(p)[::-1]:   # Horner in z^-1
        out = out * zinv + c
    return out


def observer_form(A, B):
    r"""Observer-canonical realization of :math:`A(q^{-1}) y = B(q^{-1}) u`.

    Parameters
    ----------
    A : ndarray, shape (ny, ny, na + 1)
        Matrix polynomial with ``A[:, :, 0] = I``.
    B : ndarray, shape (ny, nu, nb + 1)
        Matrix polynomial (``B[:, :, 0]`` is the feed-through).

    Returns
    -------
    F, G, H, D : ndarray
        ``x(t+1) = F x(t) + G u(t)``, ``y(t) = H x(t) + D u(t)`` with
        ``ny * n`` states, ``n = max(na, nb)``; block ``i`` of the state is
        the part of :math:`y(t+i)` that the past already determines,

        .. math::

            x_i(t+1) = x_{i+1}(t) - A_i y(t) + B_i u(t), \qquad
            y(t) = x_1(t) + B_0 u(t).
    """
    ny, nu = A.shape[0], B.shape[1]
    n = max(A.shape[2], B.shape[2]) - 1
    Ak = [A[:, :, k] if k < A.shape[2] else np.zeros((ny, ny)) for k in range(n + 1)]
    Bk = [B[:, :, k] if k < B.shape[2] else np.zeros((ny, nu)) for k in range(n + 1)]
    D = Bk[0].copy()
    F = np.zeros((n * ny, n * ny))
    G = np.zeros((n * ny, nu))
    for i in range(n):
        blk = slice(i * ny, (i + 1) * ny)
        F[blk, :ny] = -Ak[i + 1]
        if i + 1 < n:
            F[blk, (i + 1) * ny:(i + 2) * ny] = np.eye(ny)
        G[blk] = Bk[i + 1] - Ak[i + 1] @ D
    H = np.zeros((ny, n * ny))
    if n:
        H[:, :ny] = np.eye(ny)
    return F, G, H, D


def model_dt(obj, default=True):
    """The sampling period of a model (its ``dt``), or `default`."""
    dt = getattr(obj, "dt", default)
    return default if dt is None else dt
