r"""Box-Jenkins models: ``y(t) = B(q)/F(q) u(t - nk) + C(q)/D(q) e(t)``."""

from ._family import family_structure
from ._polymodel import PolynomialModel, fit_io

__all__ = ["BJ"]


class BJ(PolynomialModel):
    r"""Box-Jenkins model ``y(t) = B(q)/F(q) u(t) + C(q)/D(q) e(t)`` (MATLAB ``bj``).

    Independent dynamics for the plant (:math:`B/F`) and the disturbance
    (:math:`C/D`, an ARMA process): the most flexible single-output
    structure, and the one to try when ARX and ARMAX residuals stay coloured.

    Parameters
    ----------
    nb : int or sequence of int
        Number of ``b`` coefficients per input (``>= 1``).
    nc, nd : int
        Orders of :math:`C` and :math:`D` (``>= 0``).
    nf : int or sequence of int
        Order of :math:`F` per input (``>= 0``).
    nk : int or sequence of int, default 1
        Input delay(s).
    dt : True or float, default True
        Sampling period.

    Attributes
    ----------
    theta_ : ndarray, shape (n_params,)
        ``[b (per input), c, d, f (per input)]`` (MATLAB's order).
    b_, c_, d_, f_
        Coefficients (without leading ones and delays).
    theta_cov_, noise_variance_, residuals_, n_samples_, method_
        As :class:`~rlsfilt.ARMAX`; also its recursive attributes.

    Notes
    -----
    The predictor is :math:`\hat y = y - \frac{D}{C}(y - \frac{B}{F} u)`;
    ``"pem"`` starts from the lowest criterion of refined IV for
    :math:`B/F`, the ARX of the same orders (``F_i = A``, ``D = A`` when
    ``nd >= nf``) and a high-order ARX reduced per input, each with a
    Hannan-Rissanen ARMA fit of the output error for :math:`C/D`; ``C``,
    ``D`` and ``F`` are kept stable by reflection (``init_model=``,
    ``n_starts=``: see :meth:`ARMAX.fit`). MATLAB ``bj(data, [nb nc nd nf nk])`` is
    ``BJ(nb, nc, nd, nf, nk).fit(u, y)``; ``recursiveBJ`` is
    :class:`~rlsfilt.RecursiveBJ`. ``to_tf(noise=True)`` is :math:`C/D`.

    The `ConvergenceWarning` for a criterion above the ARX's applies where the
    least-squares ARX of the same orders is a point of the structure (every
    ``nf_i`` equal and ``nd >= nf``): its criterion bounds the optimum. With
    ``nd < nf`` the two structures do not contain each other, ``fit_info_
    ["arx_cost"]`` is None and only ``n_starts=`` can tell a poor local
    minimum.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import BJ
    >>> rng = np.random.default_rng(2)
    >>> u, e = rng.standard_normal(5000), rng.standard_normal(5000)
    >>> y = lfilter([0, 1, 0.5], [1, -1.5, 0.7], u) + lfilter([1, 0.5], [1, -0.9], e)
    >>> model = BJ(nb=2, nc=1, nd=1, nf=2, nk=1).fit(u, y)
    >>> np.round(model.theta_, 1)
    array([ 1. ,  0.5,  0.5, -0.9, -1.5,  0.7])
    """

    _ORDERS = ("nb", "nc", "nd", "nf", "nk")
    _EQUATION = "y(t) = B(q)/F(q) u(t) + C(q)/D(q) e(t)"

    # the name a model file stores (rlsfilt.persistence: a closed set, not inherited)
    _FILE_NAME = "BJ"

    def __init__(self, nb, nc, nd, nf, nk=1, dt=True):
        self.nb = nb
        self.nc = nc
        self.nd = nd
        self.nf = nf
        self.nk = nk
        self.dt = dt

    def _family(self, n_inputs):
        return family_structure(nb=self.nb, nc=self.nc, nd=self.nd, nf=self.nf, nk=self.nk,
                                n_inputs=n_inputs)

    def fit(self, u, y=None, method="pem", **options):
        """Estimate the parameters from an input/output record.

        Parameters and options as :meth:`ARMAX.fit`.

        Returns
        -------
        self
        """
        return fit_io(self, u, y, method, options)
