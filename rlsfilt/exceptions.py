"""Exceptions and warnings raised by rlsfilt.

They subclass the builtins a caller would expect, so ``except ValueError``
keeps working, while ``except NotFittedError`` lets a caller be precise.
"""

__all__ = ["NotFittedError", "InsufficientDataError", "ExactFitError", "NumericalWarning",
           "ForgettingSkippedWarning", "ExcitationWarning", "RegulatorWarning",
           "OperatingPointWarning", "OrderSelectionWarning", "ConvergenceWarning",
           "ConversionWarning"]


class NotFittedError(ValueError, AttributeError):
    """A model was used before ``fit`` was called."""


class InsufficientDataError(ValueError):
    """A record is too short for what was asked: too few samples for the model's
    orders, or too few residuals for the lags of a residual test."""


class ExactFitError(ValueError):
    """The residuals are zero or constant (noise-free data fitted exactly), so
    statistics that divide by their variance (residual tests, information
    criteria, CUSUM tests) are undefined."""


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


class RegulatorWarning(UserWarning):
    """A self-tuning regulator is not doing what it was asked: its designs are
    rejected (it keeps an older controller, or has none), it designs on a
    reduced model because the estimate nearly cancels a pole against a zero,
    or its control saturates while the error grows (see
    `rlsfilt.adaptive.SelfTuningRegulator`)."""


class OperatingPointWarning(UserWarning):
    """A record sits far from zero (its mean is large against its variation)
    and no offset handling was chosen: a linear model without an intercept
    then mostly fits the operating point (detrend the data, or fit with
    ``offset=True``)."""


class OrderSelectionWarning(UserWarning):
    """The best structure (or delay) found lies at the edge of the range that
    was searched; the message names the bound to widen."""


class ConvergenceWarning(UserWarning):
    """An iterative estimate may not be the optimum: a prediction-error search
    ended on the stability boundary, stopped at its evaluation or time limit,
    or ended with a larger criterion than the least-squares ARX of the same
    orders."""


class ConversionWarning(UserWarning):
    """A converted model cannot be used as the caller will likely use it: the
    transfer-function matrix of a model with several inputs or outputs, which
    the installed python-control cannot simulate without Slycot (``to_ss()``
    can); the message names the alternative."""
