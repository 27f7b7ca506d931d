"""Recursive least-squares filters."""

from .rls import RecursiveLeastSquares
from .sliding_window import SlidingWindowRLS

__all__ = ["RecursiveLeastSquares", "SlidingWindowRLS"]
