"""Argument checks shared by the whole package.

Every message follows one grammar: the argument's name in backticks, what
was expected, and what was received, for example
"`lam` must be in (0, 1]; got 1.5".
"""

import math
import numbers

import numpy as np

from ._resources import check_memory

__all__ = []


def check_int(value, name, minimum=None):
    """Return `value` as an ``int``, rejecting floats, bools and small values.

    A 0-d integer array (``np.array(2)``) counts as its integer.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"`{name}` must be an integer; got {value!r} ({type(value).__name__})")
    value = int(value)
    if minimum is not None and value < minimum:
        raise ValueError(f"`{name}` must be >= {minimum}; got {value}")
    return value


def check_length(value, name, minimum=1, bytes_per_item=64):
    """A number of samples (or slots): an ``int >= minimum`` whose arrays fit in memory.

    `bytes_per_item` is what the caller allocates per unit (for example eight
    arrays of doubles: 64); beyond the available memory a `MemoryError`
    names the argument before anything is allocated.
    """
    n = check_int(value, name, minimum=minimum)
    check_memory(bytes_per_item * n, f"`{name}` = {n}")
    return n


#: Sizes (bytes) below which `check_dimension` does not ask the system for its memory
#: (a filter of up to about 90 parameters: reading /proc would cost more than the filter)
_SMALL = 1 << 20


def check_dimension(value, name, minimum=1):
    """A matrix dimension ``n``: an ``int >= minimum`` whose ``(n, n)`` matrices fit in memory
    (a filter keeps about a dozen of them)."""
    n = check_int(value, name, minimum=minimum)
    if 16 * 8 * n * n > _SMALL:       # reading the system's limits costs more than these
        check_memory(16 * 8 * n * n, f"`{name}` = {n} ({n} x {n} covariance matrices)")
    return n


def check_scalar(value, name):
    """Return `value` as a float, accepting a 0-d or single-element array."""
    if isinstance(value, (bool, np.bool_)):
        raise TypeError(f"`{name}` must be a real number; got {value!r}")
    if isinstance(value, numbers.Real):
        return float(value)
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise TypeError(f"`{name}` must be a real number; got {value!r}") from None
    if arr.size != 1:
        raise ValueError(f"`{name}` must be a scalar; got an array of shape {arr.shape}")
    return float(arr.reshape(()))


def check_real(value, name, minimum=None, strict=False):
    """A finite real number, ``>= minimum`` (``> minimum`` when `strict`) if given."""
    value = check_scalar(value, name)
    if minimum is None:
        ok, want = np.isfinite(value), "a finite number"
    elif strict:
        ok = np.isfinite(value) and value > minimum
        want = "a positive finite number" if minimum == 0 else f"a finite number > {minimum}"
    else:
        ok, want = np.isfinite(value) and value >= minimum, f"a finite value >= {minimum}"
    if not ok:
        raise ValueError(f"`{name}` must be {want}; got {value}")
    return value


def check_probability(value, name):
    """A significance or confidence level in the open interval (0, 1)."""
    value = check_scalar(value, name)
    if not 0.0 < value < 1.0:  # also rejects NaN
        raise ValueError(f"`{name}` must be in (0, 1); got {value}")
    return value


def as_generator(rng, name="rng"):
    """``np.random.default_rng(rng)`` with a message that names the argument."""
    try:
        return np.random.default_rng(rng)
    except TypeError:
        raise TypeError(f"`{name}` must be None, a non-negative integer seed or a "
                        f"numpy.random.Generator; got {rng!r}") from None
    except ValueError as exc:
        raise ValueError(f"`{name}` must be None, a non-negative integer seed or a "
                         f"numpy.random.Generator; got {rng!r} ({exc})") from None


def check_dt(dt, name="dt"):
    """A sampling period: ``True`` (unspecified, python-control's convention) or a
    positive finite number, returned as a Python ``float`` (numpy scalars such as
    ``np.float32(0.1)`` included, which python-control itself rejects)."""
    if dt is True:
        return dt
    ok = (isinstance(dt, numbers.Real) and not isinstance(dt, (bool, np.bool_))
          and np.isfinite(dt) and dt > 0)
    if not ok:
        raise ValueError(f"`{name}` must be True (unspecified sampling period) or a positive "
                         f"sampling period; got {dt!r}")
    return float(dt)


def check_lam(lam, name="lam"):
    """Forgetting factor in (0, 1]."""
    lam = check_scalar(lam, name)
    if not 0.0 < lam <= 1.0:  # also rejects NaN
        raise ValueError(f"`{name}` must be in (0, 1]; got {lam}")
    return lam


#: Range of the measurement-noise variances the filters take: their updates
#: multiply and divide by them, and the results must stay in the double range.
VARIANCE_RANGE = (1e-150, 1e150)


def check_variance(R, name="R"):
    """Measurement-noise variance: a positive finite scalar or a (1, 1) array, within
    `VARIANCE_RANGE`."""
    if isinstance(R, (bool, np.bool_)):
        raise TypeError(f"`{name}` must be a positive scalar variance; got {R!r}")
    if not isinstance(R, numbers.Real):
        arr = as_float_array(R, name)      # names the argument; rejects complex and text
        if arr.size != 1 or arr.ndim > 2:
            raise ValueError(f"`{name}` must be a positive scalar variance or a (1, 1) array; "
                             f"got an array of shape {arr.shape}")
        R = arr.reshape(())
    R = float(R)
    if not (np.isfinite(R) and R > 0.0):
        raise ValueError(f"`{name}` must be a positive finite variance; got {R}")
    lo, hi = VARIANCE_RANGE
    if not lo <= R <= hi:
        raise ValueError(f"`{name}` must be a variance in [{lo:.0e}, {hi:.0e}] (the update "
                         f"multiplies and divides by it); got {R:.3g}")
    return R


#: Largest magnitude of a covariance entry the filters take: their updates form
#: products of two entries (P h h^T P), which must not overflow.
COVARIANCE_MAX = 1e150


def check_covariance(C, n, name, definite=False):
    """Return a symmetric ``(n, n)`` covariance from a scalar or a matrix.

    A scalar ``c`` means ``c * I``. The matrix must be finite, real,
    symmetric (to round-off), no larger than `COVARIANCE_MAX` in any entry,
    and positive semidefinite, or positive definite when `definite` is true.
    The result is a new, exactly symmetric array.
    """
    arr = as_float_array(C, name)
    if arr.size == 1 and arr.ndim <= 2 and arr.shape != (n, n):
        c = float(arr.reshape(()))
        if math.isfinite(c) and abs(c) <= COVARIANCE_MAX and n:
            # c I: finite, symmetric, its eigenvalues are its diagonal; the checks
            # below, in O(n^2) instead of O(n^3), with the same numbers and messages
            v = 0.5 * c + 0.5 * c
            tol = n * np.finfo(float).eps * max(abs(c), np.finfo(float).tiny)
            if (definite and v <= 0.0) or v < -tol:
                kind = "definite" if definite and v <= 0.0 else "semidefinite"
                raise ValueError(f"`{name}` must be positive {kind}; got smallest "
                                 f"eigenvalue {v:.3g}")
            return v * np.eye(n)
        arr = c * np.eye(n)
    elif arr.shape != (n, n):
        raise ValueError(f"`{name}` must be a scalar or have shape ({n}, {n}); got {arr.shape}")
    else:
        arr = arr.copy()
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"`{name}` must be finite; got NaN or inf entries")
    scale = max(float(np.max(np.abs(arr))), np.finfo(float).tiny) if arr.size else 1.0
    if scale > COVARIANCE_MAX:
        raise ValueError(f"`{name}` must have entries of magnitude at most {COVARIANCE_MAX:.0e} "
                         f"(the update multiplies two of them); got {scale:.3g}")
    asym = float(np.max(np.abs(arr - arr.T))) if arr.size else 0.0
    if asym > 1e-10 * scale:
        raise ValueError(f"`{name}` must be symmetric; got max |{name} - {name}^T| = {asym:.3g}")
    arr = 0.5 * arr + 0.5 * arr.T
    diagonal = not np.any(arr[~np.eye(n, dtype=bool)])     # e.g. a scalar times I
    eig_min = (float(np.min(np.diagonal(arr))) if diagonal  # its eigenvalues, exactly
               else float(np.linalg.eigvalsh(arr)[0])) if n else 0.0
    tol = n * np.finfo(float).eps * scale
    if definite and eig_min <= 0.0:
        raise ValueError(
            f"`{name}` must be positive definite; got smallest eigenvalue {eig_min:.3g}"
        )
    if eig_min < -tol:
        raise ValueError(
            f"`{name}` must be positive semidefinite; got smallest eigenvalue {eig_min:.3g}"
        )
    return arr


def check_finite(arr, name):
    """Raise if `arr` holds NaN or inf, naming the first bad index.

    A small array (up to 64 entries, the per-sample calls) is tested entry by
    entry; a larger one is screened by one summation (a NaN or inf makes the
    sum NaN or inf), and the exact test runs only when the sum is not finite
    (a bad entry, or finite entries whose sum overflows).
    """
    if arr.size <= 64 and arr.dtype.kind != "O":     # small: cheaper than entering errstate
        if np.isfinite(arr).all():
            return arr
    else:
        with np.errstate(over="ignore", invalid="ignore"):
            if np.isfinite(np.sum(arr)):
                return arr
    bad = ~np.isfinite(arr)
    if bad.any():
        idx = np.unravel_index(int(np.argmax(bad)), arr.shape)
        idx = idx[0] if len(idx) == 1 else tuple(int(i) for i in idx)
        raise ValueError(f"`{name}` must be finite; got {arr[bad].flat[0]} at index {idx}")
    return arr


def as_float_array(value, name):
    """``np.asarray(value, float)`` with a message that names the argument.

    Complex values are rejected instead of silently losing their imaginary
    part, and text (``"1.0"``) instead of being parsed as a number.
    """
    if value is None:
        raise TypeError(f"`{name}` must be numeric array-like; got None")
    try:
        arr = np.asarray(value)
        complex_values = np.iscomplexobj(arr)
        if arr.dtype.kind in "USV":
            shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:37] + "..."
            raise TypeError(f"`{name}` must be numeric array-like; got text {shown}")
        check_not_dates([arr.dtype], name)
        if not complex_values:
            arr = np.asarray(arr, dtype=float)
    except (TypeError, ValueError) as exc:
        if str(exc).startswith(f"`{name}`"):
            raise TypeError(str(exc)) from None
        raise TypeError(
            f"`{name}` must be numeric array-like; got {type(value).__name__}: {exc}"
        ) from None
    if complex_values:
        raise TypeError(f"`{name}` must be real; got complex values (dtype {arr.dtype})")
    return arr


def check_not_dates(dtypes, name):
    """Refuse dates and durations as signal samples: a TypeError naming `name`.

    numpy and pandas would read them as counts of their unit (seconds or
    nanoseconds since 1970, ...); `dtypes` are the dtypes of an array or of the
    columns of a pandas object (``Series.dtype``, ``DataFrame.dtypes``), timezone-aware
    ones included.
    """
    for dtype in dtypes:
        if getattr(dtype, "kind", None) in ("m", "M"):
            raise TypeError(
                f"`{name}` must be numeric array-like; got {dtype} values (dates or "
                "durations, not signal samples): pass the time stamps as `dt` or the "
                "index of a DataFrame, and the signal's numbers here")


def check_bool(value, name):
    """A flag: ``True`` or ``False`` (numpy booleans included), never a truthy string."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise TypeError(f"`{name}` must be True or False; got {value!r}")
