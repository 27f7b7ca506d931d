r"""ARMAX models: ``A(q) y(t) = B(q) u(t - nk) + C(q) e(t)``."""

from ._family import family_structure
from ._polymodel import PolynomialModel, fit_io

__all__ = ["ARMAX"]


class ARMAX(PolynomialModel):
    r"""ARMAX model ``A(q) y(t) = B(q) u(t) + C(q) e(t)`` (MATLAB ``armax``).

    The equation error of ARX is coloured by the moving average
    :math:`C(q) = 1 + c_1 q^{-1} + \dots + c_{n_c} q^{-n_c}`: this is the
    model of a disturbance that enters with the plant's own dynamics
    :math:`1/A`, and where ARX least squares is biased, the prediction-error
    estimate of ARMAX is consistent.

    Parameters
    ----------
    na : int
        Order of :math:`A` (``>= 0``).
    nb : int or sequence of int
        Number of ``b`` coefficients (``>= 1``), one per input or a scalar.
    nc : int
        Order of :math:`C` (``>= 0``; ``0`` is ARX fitted by prediction error).
    nk : int or sequence of int, default 1
        Input delay(s) in samples (``0``: direct feed-through).
    dt : True or float, default True
        Sampling period (``True``: unspecified, python-control's convention).

    Attributes
    ----------
    theta_ : ndarray, shape (n_params,)
        ``[a1 .. a_na, b1 .. b_nb (per input), c1 .. c_nc]`` (MATLAB's
        ``getpvec`` order; names in :attr:`param_names_`).
    theta_cov_ : ndarray, shape (n_params, n_params)
        ``"pem"``: :math:`\hat\sigma^2 (J^T J)^{-1}` from the Jacobian of
        the prediction errors at the minimum; ``"rpem"``/``"rplr"``:
        :math:`\hat\sigma^2 P / R` of the recursion.
    noise_variance_ : float
        :math:`\hat\sigma^2 = \sum\varepsilon^2 / (N - t_0 - n_\theta)`.
    a_, b_, c_ : ndarray
        Coefficients without the leading 1 (``b_`` without the ``nk``
        zeros; a list per input when ``u`` was 2-D).
    residuals_ : ndarray, shape ``(n_samples_,)``
        Prediction errors :math:`\varepsilon(t, \hat\theta)`, ``t >= t0``.
    n_samples_ : int
        Number of prediction errors of the criterion, ``N - max_lag``.
    method_ : str
        ``"pem"``, ``"rpem"`` or ``"rplr"``.
    fit_info_ : dict
        ``"pem"``: the search's report (``cost``, ``converged``, ``message``,
        ``n_fev``, ``n_iter``, the start ``theta0``, which start it was,
        ``start``, and the criterion of each, ``start_costs``, ``max_root``
        of ``C``, ``D``, ``F``, the ARX criterion ``arx_cost`` and the
        ``warnings`` given).
    theta_history_ : ndarray, shape (N, n_params)
        ``"rpem"``/``"rplr"``: the estimate after each sample.
    recursive_residuals_ : ndarray, shape (N,)
        ``"rpem"``/``"rplr"``: the a-priori prediction errors of the run.
    state_ : object
        ``"rpem"``/``"rplr"``: the recursion after the last sample.
    margins_ : dict
        ``"rplr"``: the positive-real margins at the final estimate.

    Notes
    -----
    ``fit(u, y, method="pem")`` minimizes :math:`\sum_{t \ge t_0}
    \varepsilon(t)^2` with :math:`\varepsilon = (A y - B u)/C` by
    a Levenberg-Marquardt search with the exact gradient, started from the
    Hannan-Rissanen estimate or the ARX of the same orders (the lower
    criterion), ``C`` kept stable by reflection;
    ``"rpem"`` and ``"rplr"`` (extended least squares) are the recursive
    forms. Translation: MATLAB ``armax(data, [na nb nc nk])`` is
    ``ARMAX(na, nb, nc, nk).fit(u, y)``; ``rarmax`` / ``recursiveARMAX``
    are ``fit(..., method="rpem")`` and :class:`~rlsfilt.RecursiveARMAX`;
    ``rplr`` is ``method="rplr"``. The noise model is
    ``to_tf(noise=True)`` :math:`= C/A`.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 4.2, 7.2 and 11.3.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import ARMAX
    >>> rng = np.random.default_rng(0)
    >>> u, e = rng.standard_normal(4000), rng.standard_normal(4000)
    >>> y = lfilter([0, 1, 0.5], [1, -1.5, 0.7], u) + lfilter([1, -1, 0.2], [1, -1.5, 0.7], e)
    >>> model = ARMAX(2, 2, 2, 1).fit(u, y)
    >>> np.round(model.theta_, 1)
    array([-1.5,  0.7,  1. ,  0.5, -1. ,  0.2])
    >>> model.param_names_
    ['a1', 'a2', 'b1', 'b2', 'c1', 'c2']
    """

    _ORDERS = ("na", "nb", "nc", "nk")
    _EQUATION = "A(q) y(t) = B(q) u(t) + C(q) e(t)"

    # the name a model file stores (rlsfilt.persistence: a closed set, not inherited)
    _FILE_NAME = "ARMAX"

    def __init__(self, na, nb, nc, nk=1, dt=True):
        self.na = na
        self.nb = nb
        self.nc = nc
        self.nk = nk
        self.dt = dt

    def _family(self, n_inputs):
        return family_structure(na=self.na, nb=self.nb, nc=self.nc, nk=self.nk,
                                n_inputs=n_inputs)

    def fit(self, u, y=None, method="pem", **options):
        """Estimate the parameters from an input/output record.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu), or IOData
            Input record (pandas works too), or an `IOData` (then `y` is
            omitted), or a list of input arrays, one per experiment.
        y : array_like, shape (N,), or a list of them
            Output record (a list: one per experiment). With several
            experiments the batch criterion is the sum over them, each
            predictor started from rest at its experiment's first sample; the
            recursive fits restart their regressor and filter signals at
            each boundary (estimate and ``P`` carry on) and their histories
            hold the experiments one after the other.
        method : {"pem", "rpem", "rplr"}, default "pem"
            Batch prediction-error minimization, recursive prediction error,
            or recursive pseudo-linear regression (extended least squares).
        **options
            ``"pem"``: ``theta0`` (start; the lowest criterion of the
            consistent estimates by default) or ``init_model`` (a fitted
            model of the same structure to start from: MATLAB's
            ``init_sys``), ``n_starts`` (default 1: searches from that start
            and ``n_starts - 1`` random stable ones, the best kept; seeded
            by ``rng``), ``ftol``, ``xtol``, ``gtol`` (stopping tolerances,
            default 1e-12), ``max_nfev`` (a positive integer: criterion
            evaluations per search), ``max_time`` (seconds), ``progress``
            (``"auto"``: a tqdm bar after 3 s if tqdm is installed; True,
            False). ``"rpem"``/``"rplr"``: the
            options of `RecursiveLeastSquares` (``lam``, ``P0``, ``x0``,
            ``R``, ``Q``, ``forgetting``, ``forgetting_params``, ``gate``,
            ``check_every``, ``cond_max``),
            the start-up forgetting profile ``lam_start``, ``lam_rate`` and
            ``project`` (keep ``C`` stable). ``P0``, ``R``, ``Q`` and ``x0``
            are in the signals' units, and so are their defaults (``P0 = 1e4
            I``, ``R = 1``, ``x0 = 0``: MATLAB's ``rarmax`` and the
            streaming :class:`~rlsfilt.RecursiveARMAX`, which the fit equals
            bit for bit).

        Returns
        -------
        self

        Raises
        ------
        ValueError
            Bad orders, NaN/inf data, mismatched lengths, too few samples,
            an input that is not persistently exciting; ``u`` and ``y`` in
            units whose ratio makes a ``b`` coefficient exceed the double
            range (the message names both); ``"rpem"``/``"rplr"`` with a
            ``P0`` (the default for signals around 1e160) too diffuse for
            double precision in the record's units, or an ``R`` outside the
            recursion's range there (the message names it and the scale).

        Warns
        -----
        OperatingPointWarning
            Any method, on a record around an operating point (a signal's
            mean above 5 standard deviations, no sample reaching zero): the
            family has no offset parameter, so the fit would mostly describe
            the operating point; detrend the record first
            (:func:`~rlsfilt.detrend`, also of an `IOData`). The same for
            `OE`, `BJ`, `AR` and `ARMA`.
        ConvergenceWarning
            ``"pem"``: the search ended with a zero of ``C`` (``F``, ``D``)
            on the stability boundary, stopped at ``max_nfev`` or
            ``max_time``, or with a larger criterion than the least-squares
            ARX of the same orders where that ARX is a point of the structure
            (ARMAX; OE with every ``nf_i`` equal; BJ also with ``nd >= nf``;
            ``fit_info_["arx_cost"]`` is None otherwise; see the guide,
            "Model family").
        NumericalWarning
            ``"rplr"`` when :math:`\\mathrm{Re}\\{1/C\\} > 1/2` fails at the
            estimate (extended least squares may not converge to the
            prediction-error estimate; use ``"rpem"``); ``"rpem"``/``"rplr"``
            when the default ``P0`` outweighs the data (signals far below
            unit size: around 1e-3 it biases the estimate by percents,
            around 1e-160 it holds it at ``x0``).

        Notes
        -----
        Every method runs on the record scaled to unit size (each signal
        divided by a power of two near its largest entry) and maps the
        results back exactly, so records around :math:`10^{\\pm 160}` give
        the fit of the same record at unit size, in their units. The
        recursions read ``P0``, ``R``, ``Q``, ``x0`` in the signals' units
        and run from their exact images in the scaled units: the same
        numbers, bit for bit, as the recursion in the signals' units
        wherever that stays in the double range (:mod:`rlsfilt.models._units`).
        """
        return fit_io(self, u, y, method, options)
