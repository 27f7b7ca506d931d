r"""Output-error models: ``y(t) = B(q)/F(q) u(t - nk) + e(t)``."""

from ._family import family_structure
from ._polymodel import PolynomialModel, fit_io

__all__ = ["OE"]


class OE(PolynomialModel):
    r"""Output-error model ``y(t) = B(q)/F(q) u(t) + e(t)`` (MATLAB ``oe``).

    The disturbance is white noise on the output, so the one-step predictor
    is the simulated output :math:`\hat y = B/F\,u`: whatever the colour of
    the real disturbance, the prediction-error estimate of ``B/F`` is
    consistent in open loop (Ljung 1999, ch. 8).

    Parameters
    ----------
    nb : int or sequence of int
        Number of ``b`` coefficients per input (``>= 1``).
    nf : int or sequence of int
        Order of :math:`F` per input (``>= 0``).
    nk : int or sequence of int, default 1
        Input delay(s) (``0``: direct feed-through).
    dt : True or float, default True
        Sampling period.

    Attributes
    ----------
    theta_ : ndarray, shape (n_params,)
        ``[b (per input), f (per input)]`` (MATLAB's order).
    b_, f_ : ndarray or list of ndarray
        Coefficients per input (``f_`` without the leading 1).
    theta_cov_, noise_variance_, residuals_, n_samples_, method_
        As :class:`~rlsfilt.ARMAX`; also its recursive attributes.

    Notes
    -----
    ``"pem"`` starts from the lowest criterion of the simplified refined IV
    estimate of each path (Young's SRIV, whose fixed point is the
    output-error estimate), the ARX of the same orders (``F_i = A``) and a
    high-order ARX reduced per input, and keeps ``F`` stable by reflection
    (``init_model=``, ``n_starts=``: see :meth:`ARMAX.fit`); ``"rplr"``
    is the output-error pseudo-linear regression (regressor
    ``[u(t-nk..), -yhat(t-1..)]``), which converges when
    :math:`1/F - 1/2` is strictly positive real (warned otherwise);
    ``"rpem"`` filters it by :math:`1/F`. MATLAB ``oe(data, [nb nf nk])`` is
    ``OE(nb, nf, nk).fit(u, y)``; ``roe`` / ``recursiveOE`` are
    ``method="rpem"`` and :class:`~rlsfilt.RecursiveOE`. ``to_tf()`` is
    :math:`B/F`, ``to_tf(noise=True)`` is 1.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import OE
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(3000)
    >>> y = lfilter([0, 1, 0.5], [1, -1.5, 0.7], u) + 0.5 * rng.standard_normal(3000)
    >>> model = OE(nb=2, nf=2, nk=1).fit(u, y)
    >>> np.round(model.b_, 1), np.round(model.f_, 1)
    (array([1. , 0.5]), array([-1.5,  0.7]))
    """

    _ORDERS = ("nb", "nf", "nk")
    _EQUATION = "y(t) = B(q)/F(q) u(t) + e(t)"

    # the name a model file stores (rlsfilt.persistence: a closed set, not inherited)
    _FILE_NAME = "OE"

    def __init__(self, nb, nf, nk=1, dt=True):
        self.nb = nb
        self.nf = nf
        self.nk = nk
        self.dt = dt

    def _family(self, n_inputs):
        return family_structure(nb=self.nb, nf=self.nf, nk=self.nk, n_inputs=n_inputs)

    def fit(self, u, y=None, method="pem", **options):
        """Estimate the parameters from an input/output record.

        Parameters and options as :meth:`ARMAX.fit`; ``"rplr"`` warns when
        :math:`\\mathrm{Re}\\{1/F\\} > 1/2` fails at the estimate.

        Returns
        -------
        self
        """
        return fit_io(self, u, y, method, options)
