"""rlsfilt: recursive least-squares identification of dynamic systems.

A filterpy-style toolkit: `RecursiveLeastSquares` mirrors filterpy's
``KalmanFilter`` API (``predict``/``update(z, H)``/``batch_filter``, ``x``,
``P``, ``K``, ``y``, ``S``) so it drops in beside Kalman filters.
"""

from . import datasets, validation  # public subpackages: rlsfilt.datasets, rlsfilt.validation
from .exceptions import ForgettingSkippedWarning, NotFittedError, NumericalWarning
from .filters import RecursiveLeastSquares, RLSBank, SlidingWindowRLS, SquareRootRLS
from .models import ARX, ARXBank, fit_many
from .validation import fit_percent, select_order, validate

__version__ = "0.1.0"

__all__ = [
    "RecursiveLeastSquares",
    "SlidingWindowRLS",
    "SquareRootRLS",
    "RLSBank",
    "ARX",
    "ARXBank",
    "fit_many",
    "datasets",
    "validation",
    "validate",
    "select_order",
    "fit_percent",
    "NotFittedError",
    "NumericalWarning",
    "ForgettingSkippedWarning",
    "__version__",
]
