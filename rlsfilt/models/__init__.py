"""Models identified from input/output data: `ARX` and its regressors."""

from .arx import ARX, ARXSummary
from .fleet import ARXBank, fit_many
from .regressors import ARXStructure, arx_regressors, arx_structure

__all__ = ["ARX", "ARXSummary", "ARXStructure", "arx_regressors", "arx_structure", "ARXBank",
           "fit_many"]
