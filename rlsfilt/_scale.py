r"""Scaling that keeps sums of squares inside the range of double precision.

Least squares, correlations, the residual tests and the CUSUM tests do not
depend on the units of the signals, but their sums of squares do: with
entries around :math:`10^{155}`, :math:`\sum x_t^2` overflows to ``inf``;
around :math:`10^{-155}` it underflows to subnormal numbers (losing digits)
and then to zero. A record of a pressure in pascal or a current in
attoampere must not be called "not persistently exciting" or an "exact fit"
for that reason.

The remedy used everywhere in rlsfilt: divide each signal (or column) by a
power of two near its largest entry before squaring, and undo the factor
where a result carries units. Dividing by a power of two changes only the
exponent, so it is exact; the scaled squares are near one; and a
scale-invariant quantity (a rank, a correlation, a test statistic, a
p-value) is then the same, to round-off, for the record multiplied by any
factor. Quantities that carry units (a noise variance of a record around
:math:`10^{160}`) are ``inf`` only when they are not representable.
"""

import numpy as np

__all__ = []


def pow2_scale(x, axis=None):
    """Powers of two ``2^e >= max|x|`` (along `axis`), 1 where `x` is all zero.

    Parameters
    ----------
    x : ndarray
        Finite values.
    axis : int, optional
        ``0`` for one scale per column; None for one scale for all of `x`.

    Returns
    -------
    float or ndarray
        ``x / pow2_scale(x)`` is exact and has entries in ``[-1, 1]``.
    """
    return np.ldexp(1.0, pow2_exponent(x, axis=axis))


def pow2_exponent(x, axis=None):
    """The exponents ``e`` of `pow2_scale`: ``2^e >= max|x|`` (along `axis`), 0 for zeros.

    Parameters
    ----------
    x : ndarray
        Finite values.
    axis : int, optional
        ``0`` for one exponent per column; None for one for all of `x`.

    Returns
    -------
    int or ndarray of int
        ``np.ldexp(x, -pow2_exponent(x))`` is exact and has entries in
        ``[-1, 1]``; a result computed from it is brought back to the units
        of `x` by ``np.ldexp`` as well, exactly unless it over- or
        underflows.
    """
    x = np.asarray(x, dtype=float)
    if x.size == 0:
        return 0 if axis is None else np.zeros(np.delete(x.shape, axis), dtype=int)
    _, exponent = np.frexp(_max_abs(x, axis))    # max = f 2^e, 0.5 <= f < 1
    return exponent                              # frexp(0) gives e = 0: scale 1


def _max_abs(x, axis):
    """``max|x|`` (along `axis`), without the temporary ``|x|`` of a whole record.

    ``max|x| = max(max x, -min x)`` exactly. A few columns of a long record are
    reduced one at a time: numpy's reduction along axis 0 of a C-ordered
    ``(N, 4)`` array is about 8x slower than four strided 1-D reductions.
    """
    if axis is None or x.ndim == 1:
        return max(float(np.max(x, axis=axis)), -float(np.min(x, axis=axis)))
    if axis == 0 and x.ndim == 2 and x.shape[1] <= _FEW_COLUMNS:
        return np.array([max(c.max(), -c.min()) for c in x.T])
    return np.maximum(np.max(x, axis=axis), -np.min(x, axis=axis))


_FEW_COLUMNS = 32   # up to this many columns, `_max_abs` reduces them one at a time


def times_pow2(x, e, out=None):
    r"""``x 2^e``, bit for bit ``np.ldexp(x, e)``, at the cost of a multiplication.

    Where :math:`2^e` is itself a double (:math:`-1074 \le e \le 1023`), the
    product with it is one correctly rounded IEEE multiplication by an exact
    value: the exact :math:`x 2^e`, rounded once, as ``ldexp`` rounds it (exact
    unless the result is subnormal; ``inf`` on overflow). ``np.ldexp`` is a slow
    ufunc (about 3x a multiplication on a long record); other exponents fall back
    to it.

    Parameters
    ----------
    x : ndarray
    e : int or ndarray of int
        Broadcastable to `x`.
    out : ndarray, optional
        Where to write the result (may be `x`: scaling in place).

    Returns
    -------
    ndarray

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt._scale import times_pow2
    >>> times_pow2(np.array([3.0, 5e-324]), np.array([-1, 1]))
    array([1.5e+000, 9.9e-324])
    """
    factors = pow2_factors(e)
    if factors is not None:
        return np.multiply(x, factors, out=out)
    return np.ldexp(x, e, out=out)


def pow2_factors(e):
    """The doubles ``2^e`` by which `times_pow2` multiplies, or None where one of them is
    not a double (there `times_pow2` calls ``np.ldexp``).

    A compiled loop that multiplies by them gives the bits of `times_pow2`.

    Parameters
    ----------
    e : int or ndarray of int

    Returns
    -------
    ndarray or None
    """
    e = np.asarray(e)
    if e.size == 0 or (e.min() >= _EXP_MIN and e.max() <= _EXP_MAX):
        return np.ldexp(1.0, e)
    return None


_EXP_MIN, _EXP_MAX = -1074, 1023   # 2^e is a double (subnormal below -1022)


def unit_columns(X):
    """`X` with every nonzero column scaled to unit 2-norm, without overflow or underflow.

    A rank decision on the result does not depend on the units of the
    columns (Householder QR, which solves the least-squares problems, is
    itself insensitive to column scaling; Golub & Van Loan 2013, sec. 5.3.7).
    """
    X = np.asarray(X, dtype=float)
    if X.shape[0] == 0:
        return X.copy()
    Xs = X / pow2_scale(X, axis=0)
    norms = np.linalg.norm(Xs, axis=0)
    return Xs / np.where(norms > 0, norms, 1.0)


def safe_norm(x, axis=None):
    """The 2-norm of `x` (of each column with ``axis=0``) without intermediate overflow.

    The result is ``inf`` only when the norm itself exceeds the largest
    double.
    """
    x = np.asarray(x, dtype=float)
    s = pow2_scale(x, axis=axis)
    with np.errstate(over="ignore"):
        return s * np.linalg.norm(x / s, axis=axis)
