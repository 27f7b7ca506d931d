"""Recursive least-squares filters."""

from .bank import RLSBank
from .rls import RecursiveLeastSquares
from .sliding_window import SlidingWindowRLS
from .square_root import SquareRootRLS

__all__ = ["RecursiveLeastSquares", "SlidingWindowRLS", "SquareRootRLS", "RLSBank"]
