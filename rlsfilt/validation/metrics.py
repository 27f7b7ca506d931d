"""Goodness-of-fit numbers that compare a measured and a model output."""

import numpy as np

from .._scale import safe_norm
from .._validation import as_float_array, check_finite

__all__ = ["fit_percent"]


def fit_percent(y, yhat):
    r"""Normalized root-mean-square fit in percent, as MATLAB's ``compare``.

    .. math::

        \mathrm{fit} = 100 \left(1 - \frac{\lVert y - \hat y \rVert_2}
                                      {\lVert y - \bar y \rVert_2}\right)

    100 is a perfect match, 0 is no better than the mean of `y`, and the
    value is negative (unbounded below) for a model worse than the mean.

    Parameters
    ----------
    y : array_like, shape (N,) or (N, ny)
        Measured output; time on axis 0.
    yhat : array_like, same shape as `y`
        Model output (simulated or predicted).

    Returns
    -------
    fit : float or ndarray of shape (ny,)
        A float for one-dimensional inputs, one value per output column
        otherwise.

    Raises
    ------
    ValueError
        If the shapes differ, a signal is empty or not finite, or an output
        is constant (the denominator is zero).

    Notes
    -----
    This is MATLAB's ``goodnessOfFit(yhat, y, 'NRMSE')`` expressed as
    ``100 (1 - cost)``, the number ``compare`` prints (Ljung 1999, sec. 16.6
    uses the same normalization for model comparisons).

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 16.6.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.validation import fit_percent
    >>> y = np.array([0.0, 1.0, 2.0, 3.0])
    >>> round(fit_percent(y, y + 0.1), 3)
    91.056
    """
    Y = check_finite(as_float_array(y, "y"), "y")
    Yh = check_finite(as_float_array(yhat, "yhat"), "yhat")
    if Y.shape != Yh.shape:
        raise ValueError(f"`y` and `yhat` must have the same shape; got {Y.shape} and {Yh.shape}")
    if Y.ndim not in (1, 2) or Y.shape[0] == 0:
        raise ValueError(f"`y` must have shape (N,) or (N, ny) with N >= 1; got {Y.shape}")
    one = Y.ndim == 1
    if one:
        Y, Yh = Y[:, None], Yh[:, None]
    # norms without overflow or underflow, so the fit of a record in any units is the same
    num = safe_norm(Y - Yh, axis=0)
    den = safe_norm(Y - Y.mean(axis=0), axis=0)
    if np.any(den == 0.0):
        col = int(np.argmax(den == 0.0))
        raise ValueError(f"`y` must vary to define a fit; output {col} is constant")
    fit = 100.0 * (1.0 - num / den)
    return float(fit[0]) if one else fit
