"""SciPy functions used throughout the model fits, imported on their first call.

``import rlsfilt`` loads none of SciPy's submodules (importing
``scipy.signal`` alone takes about a second of CPU in a fresh process); a
module that filters signals on every call imports these names instead of
SciPy's, and the first call pays the import once. Each forwards its
arguments unchanged and returns what SciPy returns.
"""

__all__ = []


def lfilter(b, a, x, axis=-1, zi=None):
    """`scipy.signal.lfilter`, imported on the first call."""
    from scipy.signal import lfilter as _lfilter
    return _lfilter(b, a, x, axis=axis, zi=zi)


def lfiltic(b, a, y, x=None):
    """`scipy.signal.lfiltic`, imported on the first call."""
    from scipy.signal import lfiltic as _lfiltic
    return _lfiltic(b, a, y, x=x)


def least_squares(fun, x0, **kwargs):
    """`scipy.optimize.least_squares`, imported on the first call."""
    from scipy.optimize import least_squares as _least_squares
    return _least_squares(fun, x0, **kwargs)
