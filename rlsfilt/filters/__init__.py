"""Recursive least-squares filters."""

from .rls import RecursiveLeastSquares

__all__ = ["RecursiveLeastSquares"]
