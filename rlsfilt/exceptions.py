"""Exceptions and warnings raised by rlsfilt.

They subclass the builtins a caller would expect, so ``except ValueError``
keeps working, while ``except NotFittedError`` lets a caller be precise.
"""

__all__ = ["NotFittedError", "NumericalWarning", "ForgettingSkippedWarning", "ExcitationWarning"]


class NotFittedError(ValueError, AttributeError):
    """A model was used before ``fit`` was called."""


class NumericalWarning(UserWarning):
    """A numerical quantity lost a property it must have (for example a
    covariance matrix that stopped being positive definite)."""


class ForgettingSkippedWarning(UserWarning):
    """``update`` ran twice without ``predict`` in between while forgetting
    (``lam < 1``) or a parameter random walk (``Q > 0``) was configured, so
    the time update of the covariance was skipped."""


class ExcitationWarning(UserWarning):
    """An online estimator stopped learning: its regressors no longer excite
    every parameter direction, or its covariance is winding up (see
    `rlsfilt.adaptive.SelfTuningRegulator`)."""
