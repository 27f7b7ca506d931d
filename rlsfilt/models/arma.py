r"""ARMA time-series models: ``A(q) y(t) = C(q) e(t)``."""

from ._family import family_structure
from ._polymodel import TimeSeriesModel

__all__ = ["ARMA"]


class ARMA(TimeSeriesModel):
    r"""ARMA model ``A(q) y(t) = C(q) e(t)`` of a time series (MATLAB ``armax`` without input).

    Parameters
    ----------
    na, nc : int
        Orders of :math:`A` and :math:`C` (``>= 0``, not both 0).
    dt : True or float, default True
        Sampling period.

    Attributes
    ----------
    theta_ : ndarray, shape (na + nc,)
        ``[a1 .. a_na, c1 .. c_nc]``; ``a_``, ``c_`` the blocks.
    theta_cov_, noise_variance_, residuals_, n_samples_, method_
        As :class:`~rlsfilt.ARMAX`.

    Notes
    -----
    The conditional (zero initial condition) prediction-error criterion; on
    long records it agrees with exact maximum likelihood (statsmodels'
    ``ARIMA(p, 0, q, trend="n")``; sign convention ``a_k = -phi_k``,
    ``c_k = theta_k``). ``C`` is kept stable (an MA part with zeros outside
    the unit circle is reflected: the same spectrum, the invertible model).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import ARMA
    >>> e = np.random.default_rng(4).standard_normal(5000)
    >>> y = lfilter([1, 0.6], [1, -0.8], e)
    >>> np.round(ARMA(1, 1).fit(y).theta_, 1)
    array([-0.8,  0.6])
    """

    _ORDERS = ("na", "nc")
    _EQUATION = "A(q) y(t) = C(q) e(t)"

    # the name a model file stores (rlsfilt.persistence: a closed set, not inherited)
    _FILE_NAME = "ARMA"

    def __init__(self, na, nc, dt=True):
        self.na = na
        self.nc = nc
        self.dt = dt

    def _family(self, n_inputs):
        return family_structure(na=self.na, nc=self.nc, n_inputs=0)
