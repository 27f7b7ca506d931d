"""rlsfilt: recursive least-squares identification of dynamic systems.

A filterpy-style toolkit: `RecursiveLeastSquares` mirrors filterpy's
``KalmanFilter`` API (``predict``/``update(z, H)``/``batch_filter``, ``x``,
``P``, ``K``, ``y``, ``S``) so it drops in beside Kalman filters.
"""

# first, so that the subpackages can read it (the JSON results carry it)
__version__ = "0.1.0"

from . import adaptive, datasets, validation  # public subpackages
from .exceptions import (
    ExactFitError,
    ExcitationWarning,
    ForgettingSkippedWarning,
    InsufficientDataError,
    NotFittedError,
    NumericalWarning,
)
from .filters import RecursiveLeastSquares, SlidingWindowRLS, SquareRootRLS
from .models import (
    AR,
    ARMA,
    ARMAX,
    ARX,
    BJ,
    OE,
    RecursiveAR,
    RecursiveARMA,
    RecursiveARMAX,
    RecursiveARX,
    RecursiveBJ,
    RecursiveIV,
    RecursiveOE,
)
from .validation import fit_percent, select_order, select_structure, validate

__all__ = [
    "RecursiveLeastSquares",
    "SlidingWindowRLS",
    "SquareRootRLS",
    "ARX",
    "ARMAX",
    "OE",
    "BJ",
    "AR",
    "ARMA",
    "RecursiveARMAX",
    "RecursiveOE",
    "RecursiveBJ",
    "RecursiveARX",
    "RecursiveAR",
    "RecursiveARMA",
    "RecursiveIV",
    "adaptive",
    "datasets",
    "validation",
    "validate",
    "select_order",
    "select_structure",
    "fit_percent",
    "NotFittedError",
    "InsufficientDataError",
    "ExactFitError",
    "NumericalWarning",
    "ForgettingSkippedWarning",
    "ExcitationWarning",
    "__version__",
]
