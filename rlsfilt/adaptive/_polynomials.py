r"""Polynomials in the backward shift :math:`q^{-1}`: checks, algebra and realizations.

Convention of the whole package (MATLAB's System Identification Toolbox, and
Astrom & Wittenmark's *Computer-Controlled Systems* when they write
:math:`A(q^{-1})`): a polynomial is the 1-D array of its coefficients of
**ascending powers of** :math:`q^{-1}`,

.. math::

    P(q^{-1}) = p_0 + p_1 q^{-1} + \dots + p_n q^{-n}
    \quad\leftrightarrow\quad ``[p_0, p_1, \dots, p_n]``,

so ``A = [1, a1, .., a_na]`` and a delay of ``nk`` samples is ``nk`` leading
zeros of ``B``. The same array read as **descending powers of** :math:`z`
is :math:`z^n P(z^{-1})`, so ``np.roots(P)`` are the zeros of ``P`` in the
z-plane (a trailing zero coefficient is a root at :math:`z = 0`; leading
zeros, a delay, are roots at infinity and not returned).
"""

import numbers

import numpy as np

from .._validation import as_float_array, check_finite

__all__ = []


def as_poly(p, name, *, monic=False):
    """A new 1-D float array of coefficients of ascending powers of ``q^-1``.

    A scalar is the constant polynomial. With `monic`, ``p[0]`` must be 1.
    """
    arr = np.atleast_1d(as_float_array(p, name)).astype(float, copy=True)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"`{name}` must be a 1-D array of coefficients of ascending powers of "
                         f"q^-1; got shape {np.shape(p)}")
    check_finite(arr, name)
    if monic and arr[0] != 1.0:
        raise ValueError(f"`{name}` must be monic ({name}[0] = 1, coefficients of ascending "
                         f"powers of q^-1); got {name}[0] = {arr[0]:.6g}")
    return arr


def _nonzero(p):
    """``np.flatnonzero(p)`` without its generic reshaping (called many times per sample)."""
    a = p if type(p) is np.ndarray and p.ndim == 1 else np.ravel(p)
    return a.nonzero()[0]


def trim(p):
    """Drop trailing zero coefficients (highest powers of ``q^-1``); keep one."""
    nz = _nonzero(p)
    return p[:nz[-1] + 1].copy() if len(nz) else np.zeros(1)


def degree(p):
    """Degree in ``q^-1`` (index of the last nonzero coefficient; -1 for zero)."""
    nz = _nonzero(p)
    return int(nz[-1]) if len(nz) else -1


def padd(p, q):
    """``p + q`` for coefficient arrays of any lengths."""
    out = np.zeros(max(len(p), len(q)))
    out[:len(p)] += p
    out[:len(q)] += q
    return out


def pad(p, n):
    """`p` zero-padded to length `n` (``n >= len(p)``)."""
    out = np.zeros(n)
    out[:len(p)] = p
    return out


def roots(p):
    """Zeros of ``z^n P(z^-1)`` in the z-plane (``np.roots`` of the array)."""
    p = trim(np.asarray(p, dtype=float))
    return np.roots(p) if len(p) > 1 else np.zeros(0, dtype=complex)


def check_stable(p, name):
    """Raise unless every zero of `p` lies strictly inside the unit circle."""
    r = roots(p)
    if len(r) and np.max(np.abs(r)) >= 1.0:
        worst = r[np.argmax(np.abs(r))]
        raise ValueError(f"`{name}` must be stable (all zeros of z^n {name}(z^-1) inside the "
                         f"unit circle); got a zero at z = {fmt_complex(worst)} "
                         f"(|z| = {abs(worst):.6g})")


def sylvester(a, b):
    r"""The Sylvester matrix of the Diophantine equation :math:`a x + b y = c`.

    Unknowns are ``x`` of degree ``deg b - 1`` and ``y`` of degree
    ``deg a - 1`` (``n = deg a + deg b`` of them, in that order); row ``k``
    is the coefficient of :math:`q^{-k}`, ``k = 0 .. n - 1``. It is
    nonsingular exactly when ``a`` and ``b`` are coprime (given
    ``a[0] != 0``, so that no common factor hides at :math:`q^{-1} = 0`).
    """
    na, nb = degree(a), degree(b)
    n = na + nb
    M = np.zeros((n, n))
    for j in range(nb):                 # x_j q^-j a
        M[j:j + na + 1, j] = a[:na + 1]
    for j in range(na):                 # y_j q^-j b
        M[j:j + nb + 1, nb + j] = b[:nb + 1]
    return M


def coprimeness(a, b):
    r"""Smallest singular value of the Sylvester matrix of ``a / ||a||`` and ``b / ||b||``.

    Zero when ``a`` and ``b`` share a root; small when a root of one is close
    to a root of the other (it bounds the size of the smallest perturbation
    of the unit-norm coefficient vectors that creates a common root, up to a
    factor ``sqrt(deg a + deg b)``: Beckermann & Labahn, *J. Symbolic
    Computation* 26, 1998). Scale invariant; ``inf`` when the matrix is
    empty (one of them is a nonzero constant).
    """
    a, b = trim(a), trim(b)
    if degree(b) < 0:
        return 0.0
    M = sylvester(_unit(a), _unit(b))
    if M.size == 0:
        return np.inf
    return float(np.linalg.svd(M, compute_uv=False)[-1])


def _unit(p):
    """`p` scaled to unit 2-norm, by its largest magnitude first: ``np.linalg.norm``
    overflows for coefficients around 1e155 and more, and underflows to zero for
    subnormal ones (a diverging or a vanishing estimate), where ``p / norm`` would give
    zeros, inf or NaN (then a wrong degree or ``LinAlgError: SVD did not converge``)."""
    p = p / np.max(np.abs(p))
    return p / np.linalg.norm(p)


def closest_roots(a, b):
    """The pair (root of `a`, root of `b`) closest to each other in the z-plane, or None."""
    ra, rb = roots(a), roots(b)
    if not (len(ra) and len(rb)):
        return None
    dist = np.abs(ra[:, None] - rb[None, :])
    i, j = np.unravel_index(int(np.argmin(dist)), dist.shape)
    return ra[i], rb[j]


def tf_pair(num, den):
    """``num``, ``den`` in ``q^-1`` zero-padded to equal length: valid in powers of ``z``.

    Multiplying both by the same :math:`z^L` changes nothing, and equal
    lengths keep a feed-through ``num[0]`` and every delay exact (a common
    trailing zero, a pole-zero pair at z = 0, is dropped).
    """
    n = max(len(num), len(den))
    num, den = pad(num, n), pad(den, n)
    while n > 1 and num[-1] == 0.0 and den[-1] == 0.0:
        num, den, n = num[:-1], den[:-1], n - 1
    return num, den




def model_polynomials(obj, name, want):
    r"""``(A, B)`` (the plant) or ``(A, B, C)`` (ARMAX) of a one-input, one-output model.

    Reads the model interface's ``polydata()`` (``A, B, C, D, F`` of
    :class:`rlsfilt.models.Polynomials`, so ARX, ARMAX, OE and BJ models all
    work) and brings it to the ARMAX form over a common denominator:

    .. math::

        A F D\, y = B D\, u + C F\, e
        \quad\text{from}\quad
        A y = \frac{B}{F} u + \frac{C}{D} e ,

    where the plant alone is ``(A F, B)`` (`want` = 2). Without
    ``polydata()``, ``polynomials()`` may return a tuple ``(A, B[, C])``, a
    mapping with keys ``a, b, c`` (either case) or an object with such
    attributes; a missing ``C`` is 1. Returns 1-D arrays (raw values for
    ``polynomials()``, checked by the caller).
    """
    if hasattr(obj, "polydata"):
        p = obj.polydata()
        A, B = np.asarray(p.A, dtype=float), np.asarray(p.B, dtype=float)
        if A.shape[0] != 1 or B.shape[1] != 1:
            raise ValueError(f"`{name}` must be a model with one input and one output; got "
                             f"{A.shape[0]} output(s) and {B.shape[1]} input(s)")
        a, b = trim(A[0, 0]), trim(B[0, 0])
        c, d = trim(np.asarray(p.C, float)[0]), trim(np.asarray(p.D, float)[0])
        f = trim(np.asarray(p.F, float)[0, 0])
        return _armax_form(a, b, c, d, f, want)
    src = obj.polynomials() if hasattr(obj, "polynomials") else obj
    if isinstance(src, tuple) and len(src) == 5 and hasattr(obj, "polynomials"):
        # (A, B, C, D, F) of the streaming estimators (RecursiveOE, RecursiveBJ, ...): B and
        # F one per input; D and F must not be dropped
        a, b, c, d, f = src
        bs = list(b) if isinstance(b, (list, tuple)) else [b]
        fs = list(f) if isinstance(f, (list, tuple)) else [f]
        if len(bs) != 1:
            raise ValueError(f"`{name}` must be a model with one input and one output; got "
                             f"{len(bs)} input(s)")
        return _armax_form(*(trim(np.asarray(x, dtype=float)) for x in (a, bs[0], c, d, fs[0])),
                           want)
    if isinstance(src, dict):
        lower = {str(k).lower(): v for k, v in src.items()}
        vals = [lower.get(k) for k in "abc"[:want]]
    elif isinstance(src, (tuple, list)) and not _is_number_list(src):
        vals = list(src[:want]) + [None] * (want - len(src))
    elif any(hasattr(src, k) or hasattr(src, k.upper()) for k in "abc"):
        vals = [getattr(src, k.upper(), getattr(src, k, None)) for k in "abc"[:want]]
    else:
        raise TypeError(f"`{name}` must be a model with polydata() or polynomials() (such as a "
                        f"fitted ARX), or a tuple of polynomials; got {type(obj).__name__}")
    if vals[0] is None or vals[1] is None:
        raise ValueError(f"`{name}`: polynomials() must give at least A and B; got "
                         f"{type(src).__name__}")
    if want == 3 and vals[2] is None:
        vals[2] = np.ones(1)
    return tuple(vals)




def _armax_form(a, b, c, d, f, want):
    """``(A F, B)`` (`want` 2) or ``(A F D, B D, C F)`` of ``A y = B/F u + C/D e``."""
    if want == 2:
        return np.convolve(a, f), b
    return np.convolve(np.convolve(a, f), d), np.convolve(b, d), np.convolve(c, f)


def _is_number_list(seq):
    return len(seq) > 0 and all(isinstance(v, numbers.Real) for v in seq)


def fmt_complex(z):
    z = complex(z)
    if abs(z.imag) <= 1e-12 * max(abs(z.real), 1.0):
        return f"{z.real:.6g}"
    return f"{z.real:.6g}{z.imag:+.6g}j"


def format_poly(p):
    """``1 - 1.5 q^-1 + 0.7 q^-2``: a polynomial in ``q^-1`` for printing."""
    terms = []
    for k, c in enumerate(p):
        if c == 0.0:
            continue
        mag = abs(c)
        power = "" if k == 0 else f"q^-{k}"
        if k == 0:
            body = f"{mag:.6g}"
        elif mag == 1.0:
            body = power
        else:
            body = f"{mag:.6g} {power}"
        terms.append(("-" if c < 0 else "+", body))
    if not terms:
        return "0"
    out = ("-" if terms[0][0] == "-" else "") + terms[0][1]
    for sign, body in terms[1:]:
        out += f" {sign} {body}"
    return out
