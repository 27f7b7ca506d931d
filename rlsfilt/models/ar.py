r"""Autoregressive time-series models: ``A(q) y(t) = e(t)``."""

from ._family import family_structure
from ._polymodel import TimeSeriesModel

__all__ = ["AR"]


class AR(TimeSeriesModel):
    r"""AR model ``A(q) y(t) = e(t)`` of a time series (MATLAB ``ar``).

    Parameters
    ----------
    na : int
        Order (``>= 1``).
    dt : True or float, default True
        Sampling period.

    Attributes
    ----------
    theta_ : ndarray, shape (na,)
        ``[a1 .. a_na]``; ``a_`` the same.
    theta_cov_, noise_variance_, residuals_, n_samples_, method_
        As :class:`~rlsfilt.ARMAX`.

    Notes
    -----
    ``fit(y)`` (``method="pem"``) is least squares on the rows
    ``t >= na`` (the criterion is quadratic: MATLAB ``ar(y, na, 'ls')``);
    the recursive methods are ``rarx`` without input. The model has no
    input: methods of the interface take ``u=None`` and
    ``to_tf(noise=True)`` is :math:`1/A`.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import AR
    >>> y = lfilter([1.0], [1, -1.2, 0.5], np.random.default_rng(3).standard_normal(5000))
    >>> np.round(AR(2).fit(y).theta_, 1)
    array([-1.2,  0.5])
    """

    _ORDERS = ("na",)
    _EQUATION = "A(q) y(t) = e(t)"

    # the name a model file stores (rlsfilt.persistence: a closed set, not inherited)
    _FILE_NAME = "AR"

    def __init__(self, na, dt=True):
        self.na = na
        self.dt = dt

    def _family(self, n_inputs):
        from .._validation import check_int

        return family_structure(na=check_int(self.na, "na", minimum=1), n_inputs=0)
