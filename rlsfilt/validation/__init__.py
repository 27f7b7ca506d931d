"""Model validation: fit, residual tests, information criteria, order
selection, CUSUM tests, uncertainty, and comparison against the true plant.

Identification is only trusted after validation (and structure comes
first: ``delayest`` estimates input delays, ``select_order`` the orders). This subpackage offers
what MATLAB users know as ``compare``, ``resid``, ``aic``/``fpe`` and
``arxstruc``/``selstruc``, the CUSUM tests of statsmodels' ``RecursiveLS``
(usable on any regression, including an ARX model's regressors), and a
comparison of the identified transfer function with the true plant through
python-control. Results are objects with named fields, ``summary()`` and
``plot()`` methods.
"""

from .bank_detection import BankChangeDetector
from .compare import Comparison, compare
from .criteria import InformationCriteria, criteria_from_loss, information_criteria
from .cusum import CusumResult, cusum, cusum_squares, recursive_residuals
from .delay import DelayEstimate, delayest
from .detection import ChangeDetector, cusum_threshold, glr_threshold
from .impulse import ImpulseResponse, impulseest
from .metrics import fit_percent
from .plant import PlantComparison
from .report import ValidationReport, validate
from .residuals import ResidualAnalysis, residual_analysis
from .segmentation import Segmentation, segment
from .selection import OrderSelection, select_order
from .structure import StructureSelection, select_structure
from .uncertainty import (
    FrequencyBand,
    ParameterIntervals,
    frequency_response_band,
    parameter_intervals,
)

__all__ = [
    "BankChangeDetector",
    "ChangeDetector",
    "Comparison",
    "CusumResult",
    "DelayEstimate",
    "FrequencyBand",
    "ImpulseResponse",
    "InformationCriteria",
    "OrderSelection",
    "ParameterIntervals",
    "PlantComparison",
    "ResidualAnalysis",
    "Segmentation",
    "StructureSelection",
    "ValidationReport",
    "compare",
    "criteria_from_loss",
    "cusum",
    "cusum_squares",
    "cusum_threshold",
    "delayest",
    "fit_percent",
    "frequency_response_band",
    "glr_threshold",
    "impulseest",
    "information_criteria",
    "parameter_intervals",
    "recursive_residuals",
    "residual_analysis",
    "segment",
    "select_order",
    "select_structure",
    "validate",
]
