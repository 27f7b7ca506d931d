"""rlsfilt: recursive least-squares identification of dynamic systems.

A filterpy-style toolkit: `RecursiveLeastSquares` mirrors filterpy's
``KalmanFilter`` API (``predict``/``update(z, H)``/``batch_filter``, ``x``,
``P``, ``K``, ``y``, ``S``) so it drops in beside Kalman filters.
"""

from . import adaptive, data, datasets, validation  # public subpackages
from ._version import __version__
from .continuous import d2c
from .data import IOData, Trend, detrend, retrend
from .exceptions import (
    ConvergenceWarning,
    ConversionWarning,
    ExactFitError,
    ExcitationWarning,
    ForgettingSkippedWarning,
    InsufficientDataError,
    NotFittedError,
    NumericalWarning,
    OperatingPointWarning,
    OrderSelectionWarning,
    RegulatorWarning,
)
from .filters import RecursiveLeastSquares, RLSBank, SlidingWindowRLS, SquareRootRLS
from .models import (
    AR,
    ARMA,
    ARMAX,
    ARX,
    BJ,
    OE,
    ARXBank,
    RecursiveAR,
    RecursiveARMA,
    RecursiveARMAX,
    RecursiveARX,
    RecursiveBJ,
    RecursiveIV,
    RecursiveOE,
    fit_many,
)
from .persistence import load_model, save_model
from .validation import (
    compare,
    delayest,
    fit_percent,
    select_order,
    select_structure,
    validate,
)

__all__ = [
    "RecursiveLeastSquares",
    "SlidingWindowRLS",
    "SquareRootRLS",
    "RLSBank",
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
    "IOData",
    "Trend",
    "detrend",
    "retrend",
    "delayest",
    "d2c",
    "save_model",
    "load_model",
    "adaptive",
    "data",
    "ARXBank",
    "fit_many",
    "datasets",
    "validation",
    "validate",
    "compare",
    "select_order",
    "select_structure",
    "fit_percent",
    "NotFittedError",
    "InsufficientDataError",
    "ExactFitError",
    "NumericalWarning",
    "ForgettingSkippedWarning",
    "ExcitationWarning",
    "OperatingPointWarning",
    "RegulatorWarning",
    "OrderSelectionWarning",
    "ConvergenceWarning",
    "ConversionWarning",
    "__version__",
]
