"""Models identified from input/output data: `ARX`, its regressors, and the
interface every model implements (`IdentifiedModel`)."""

from ._base import IdentifiedModel, Polynomials, check_is_fitted
from ._summary import ModelSummary
from .arx import ARX, ARXSummary
from .regressors import ARXStructure, arx_regressors, arx_structure

__all__ = ["ARX", "ARXSummary", "ARXStructure", "IdentifiedModel", "ModelSummary",
           "Polynomials", "arx_regressors", "arx_structure", "check_is_fitted"]
