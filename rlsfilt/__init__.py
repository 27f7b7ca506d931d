"""rlsfilt: recursive least-squares identification of dynamic systems.

A filterpy-style toolkit: `RecursiveLeastSquares` mirrors filterpy's
``KalmanFilter`` API (``predict``/``update(z, H)``/``batch_filter``, ``x``,
``P``, ``K``, ``y``, ``S``) so it drops in beside Kalman filters.
"""

from . import adaptive, datasets, validation  # public subpackages
from ._version import __version__
from .exceptions import (
    ExactFitError,
    ExcitationWarning,
    ForgettingSkippedWarning,
    InsufficientDataError,
    NotFittedError,
    NumericalWarning,
)
from .filters import RecursiveLeastSquares, SlidingWindowRLS, SquareRootRLS
from .models import ARX
from .validation import fit_percent, select_order, validate

__all__ = [
    "RecursiveLeastSquares",
    "SlidingWindowRLS",
    "SquareRootRLS",
    "ARX",
    "adaptive",
    "datasets",
    "validation",
    "validate",
    "select_order",
    "fit_percent",
    "NotFittedError",
    "InsufficientDataError",
    "ExactFitError",
    "NumericalWarning",
    "ForgettingSkippedWarning",
    "ExcitationWarning",
    "__version__",
]
