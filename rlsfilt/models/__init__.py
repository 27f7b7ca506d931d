"""Models identified from input/output data: `ARX` and the models beyond it
(`ARMAX`, `OE`, `BJ`, `AR`, `ARMA`), their streaming forms, the regressors,
and the interface every model implements (`IdentifiedModel`)."""

from ._base import IdentifiedModel, Polynomials, check_is_fitted
from ._summary import ModelSummary
from .ar import AR
from .arma import ARMA
from .armax import ARMAX
from .arx import ARX, ARXSummary
from .bj import BJ
from .fleet import ARXBank, fit_many
from .oe import OE
from .recursive import (
    RecursiveAR,
    RecursiveARMA,
    RecursiveARMAX,
    RecursiveARX,
    RecursiveBJ,
    RecursiveOE,
)
from .recursive_iv import RecursiveIV
from .regressors import ARXStructure, arx_regressors, arx_structure

__all__ = ["ARX", "ARXSummary", "ARXStructure", "IdentifiedModel", "ModelSummary",
           "Polynomials", "arx_regressors", "arx_structure", "check_is_fitted",
           "ARMAX", "OE", "BJ", "AR", "ARMA",
           "RecursiveARMAX", "RecursiveOE", "RecursiveBJ", "RecursiveARX", "RecursiveAR",
           "RecursiveARMA", "RecursiveIV", "ARXBank", "fit_many"]
