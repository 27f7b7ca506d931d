"""Model validation: fit, residual tests, information criteria, order
selection, CUSUM tests and comparison against a true plant."""

from .cusum import CusumResult, cusum, cusum_squares, recursive_residuals
from .metrics import fit_percent

__all__ = [
    "CusumResult",
    "cusum",
    "cusum_squares",
    "fit_percent",
    "recursive_residuals",
]
