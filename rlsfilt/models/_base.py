r"""The interface of every identified input/output model.

`IdentifiedModel` is what the rest of rlsfilt may rely on: validation
(:mod:`rlsfilt.validation`), the report, information criteria, parameter
intervals, frequency-response bands, the plant comparison, plotting and the
command line use the members declared here and nothing else. A new model
class (ARMAX, OE, BJ, ...) subclasses it, implements the abstract members,
and is validated, reported and converted to python-control with no change
anywhere else.

The one-step predictor is declared in (pseudo-)linear regression form
(Ljung 1999, sec. 4.2 and 7.5): for every model,

.. math::

    \hat y(t \mid t-1) = \varphi(t, \hat\theta)^T \hat\theta ,

where :math:`\varphi` holds past outputs and inputs for ARX, and also past
prediction errors (ARMAX) or past simulated outputs (OE, BJ) computed with
the estimate :math:`\hat\theta`. :meth:`IdentifiedModel.regressors` returns
those rows, so residual tests and criteria need no model-specific code.
"""

import abc
import html
import inspect
import numbers
import warnings
from collections import namedtuple

import numpy as np

from .._serialize import jsonable
from .._validation import check_dt
from ..exceptions import ConversionWarning, NotFittedError
from . import _conversion
from .regressors import _as_signal, as_io_data

__all__ = ["IdentifiedModel", "Polynomials", "check_is_fitted"]


class Polynomials(namedtuple("Polynomials", "A B C D F")):
    r"""A model in MATLAB's general polynomial form (what ``polydata`` returns).

    .. math::

        A(q)\, y(t) = \sum_j \frac{B_j(q)}{F_j(q)} u_j(t) + \frac{C(q)}{D(q)} e(t)

    Every polynomial holds coefficients of ascending powers of :math:`q^{-1}`
    (``[1, a1, a2]`` is :math:`1 + a_1 q^{-1} + a_2 q^{-2}`); ``B`` starts
    with ``nk`` zeros for a delay of ``nk`` samples.

    Attributes
    ----------
    A : ndarray, shape (ny, ny, na + 1)
        Matrix polynomial of the outputs; ``A[:, :, 0]`` is the identity.
    B : ndarray, shape (ny, nu, lb)
        ``B[i, j]`` from input ``j`` to output ``i``, delay included.
    C : ndarray, shape (ny, nc + 1)
        Numerator of the noise model of each output (``C[i, 0] = 1``).
    D : ndarray, shape (ny, nd + 1)
        Denominator of the noise model of each output (``D[i, 0] = 1``).
    F : ndarray, shape (ny, nu, nf + 1)
        Denominator of each input channel (``F[i, j, 0] = 1``).

    Notes
    -----
    ARX: ``C = D = F = 1``; ARMAX: ``D = F = 1``; OE: ``A = C = D = 1``;
    Box-Jenkins: ``A = 1`` (Ljung 1999, table 4.1).
    """

    __slots__ = ()


def check_is_fitted(model, what, name="model"):
    """Raise unless `model` is a fitted :class:`IdentifiedModel`: the one fitted check.

    Parameters
    ----------
    model : object
        The object to check.
    what : str
        What the caller is about to use (a method, attribute or function
        name), quoted in the message.
    name : str, default "model"
        The argument name used in the `TypeError` message.

    Raises
    ------
    TypeError
        If `model` is not an :class:`IdentifiedModel`.
    NotFittedError
        ``"This ARX instance is not fitted yet; call `fit(u, y)` before using
        `what`."`` if `model` has no ``theta_`` yet.
    """
    if not isinstance(model, IdentifiedModel):
        raise TypeError(f"`{name}` must be a fitted ARX model or another rlsfilt model (an "
                        f"IdentifiedModel); got {type(model).__name__}")
    if "theta_" not in vars(model):
        call = "fit(y)" if getattr(model, "_TIME_SERIES", False) else "fit(u, y)"
        raise NotFittedError(f"This {type(model).__name__} instance is not fitted yet; call "
                             f"`{call}` before using `{what}`.")


class IdentifiedModel(abc.ABC):
    r"""Abstract base of the input/output models of rlsfilt (`ARX`, ...).

    A model is a scikit-learn style estimator: ``__init__`` only stores its
    parameters (the orders and ``dt``), ``fit(u, y, ...)`` validates the
    data and returns ``self``, and what was learned ends in ``_``. Using a
    learned attribute or a method before ``fit`` raises `NotFittedError`
    ("This ARX instance is not fitted yet; call `fit(u, y)` before using
    ...") through :func:`check_is_fitted`, the one fitted check.

    **A subclass implements**

    - ``__init__(self, <orders>, dt=True)`` storing each argument under its
      own name (``get_params``/``set_params``/``repr`` read the signature);
    - ``fit(u, y, ...)``, setting at least the learned attributes listed
      below and ``self._info``, the metadata dict of :func:`as_io_data`
      (signal names and whether `u`/`y` were 1-D);
    - :meth:`regressors` (the one-step predictor in regression form),
      :meth:`predict`, :meth:`simulate` and :meth:`polydata`;
    - the properties :attr:`param_names_`, :attr:`orders_` and
      :attr:`max_lag`.

    It may override ``_summary_lines(style)`` (extra lines, such as the
    difference equation, at the top of :meth:`summary`) and the class
    attribute ``_ONLY_SET_BY`` (learned attributes that only some fits set,
    mapped to the fit that sets them, for a precise `AttributeError`).

    Everything else is derived here from those members: :attr:`n_params`,
    :attr:`std_errors_`, :meth:`to_tf`, :meth:`to_ss`, :meth:`to_dlti`,
    :meth:`frequency_response`, :meth:`summary`, the notebook displays and
    the estimator protocol.

    Attributes
    ----------
    theta_ : ndarray, shape (n_params,) or (n_params, ny)
        Estimated parameters in the order of :attr:`param_names_` and of
        the columns of :meth:`regressors`; one column per output for 2-D `y`.
    theta_cov_ : ndarray, shape (n_params, n_params) or (ny, n_params, n_params)
        Covariance of ``theta_`` (one block per output).
    noise_variance_ : float or ndarray of shape (ny,)
        Variance of the innovations :math:`e(t)`.
    n_samples_ : int
        Number of equations (prediction errors) the fit used; the
        confidence intervals use ``n_samples_ - n_params`` degrees of
        freedom.
    n_params_ : int
        Number of parameters per output.
    n_inputs_, n_outputs_ : int
        Number of input and output signals seen by ``fit``.
    noise_covariance_ : ndarray, shape (ny, ny), optional
        Several outputs only, when known: the covariance of the innovations
        of the outputs; frequency-response bands then draw correlated
        parameters (``vec(theta_)`` with covariance
        ``kron(noise_covariance_, theta_cov_[0] / noise_variance_[0])``).
    trend_ : Trend, optional
        A loaded model only, when it was saved with ``save(path,
        trend=...)``: the trend :func:`rlsfilt.detrend` removed from the
        estimation record. The model describes the deviations from it;
        ``trend_.remove(data)`` prepares new data and ``retrend`` puts
        results back in the units of the data. ``fit`` drops it.

    Notes
    -----
    The one-step predictor is declared in regression form:
    ``predict(u, y, horizon=1)[max_lag:] == Phi @ theta_`` with
    ``Phi, target = regressors(u, y)``, so the prediction errors are
    ``target - Phi @ theta_`` (linear regression for ARX and FIR,
    pseudo-linear regression for ARMAX, OE and BJ; Ljung 1999, sec. 7.5).
    ``simulate(u)`` equals ``scipy.signal.lfilter`` of the transfer
    functions of :meth:`to_tf` from zero initial conditions.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 4.2, 7.5 and 9.2.

    Examples
    --------
    Every model, here an ARX model, answers the same questions:

    >>> import numpy as np
    >>> from rlsfilt.models import ARX, IdentifiedModel
    >>> model = ARX.from_polynomials([-0.5], [1.0])
    >>> isinstance(model, IdentifiedModel), model.param_names_, model.max_lag
    (True, ['a1', 'b1'], 1)
    >>> model.polydata().A
    array([[[ 1. , -0.5]]])
    """

    # learned attributes that only some fits set: name -> the fit that sets them
    _ONLY_SET_BY = {}

    # ------------------------------------------------------------------
    # what a subclass implements
    # ------------------------------------------------------------------
    @abc.abstractmethod
    def fit(self, u, y, **kwargs):
        """Estimate the parameters from an input/output record; return ``self``."""

    @abc.abstractmethod
    def regressors(self, u, y):
        r"""The one-step predictor in regression form on a record.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
            Input record.
        y : array_like, shape (N,) or (N, ny)
            Output record.

        Returns
        -------
        Phi : ndarray, shape (N - max_lag, n_params)
            Rows :math:`\varphi(t)^T` for ``t = max_lag .. N-1`` (for models
            with a noise or output filter, computed with ``theta_``).
        target : ndarray, shape (N - max_lag,) or (N - max_lag, ny)
            ``y(t)`` on the same rows; ``target - Phi @ theta_`` are the
            one-step prediction errors.
        """

    @abc.abstractmethod
    def predict(self, u, y, horizon=1):
        """``horizon``-step-ahead prediction of `y` (MATLAB ``predict``).

        Parameters
        ----------
        u, y : array_like
            Input and measured output records (time on axis 0).
        horizon : int or np.inf, default 1
            Prediction horizon; ``np.inf`` (or ``>= N``) is :meth:`simulate`.

        Returns
        -------
        ndarray, the shape of `y`
        """

    @abc.abstractmethod
    def simulate(self, u, y0=None):
        """Free-run simulation from the input alone (MATLAB ``sim``).

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
            Input record; everything before ``t = 0`` is zero.
        y0 : array_like, optional
            Known first outputs to continue from.

        Returns
        -------
        ndarray, shape (N,) or (N, ny)
        """

    @abc.abstractmethod
    def polydata(self, theta=None):
        """The model (or the same structure with parameters `theta`) as `Polynomials`.

        Parameters
        ----------
        theta : array_like, shape of ``theta_``, optional
            Parameters in ``theta_`` order; ``theta_`` by default. Used to
            evaluate parameter draws (frequency-response bands).

        Returns
        -------
        Polynomials
            ``(A, B, C, D, F)`` in the full multi-signal shapes.
        """

    @property
    @abc.abstractmethod
    def param_names_(self):
        """Names of the entries of ``theta_`` (for example ``a1``, ``b1[u2]``)."""

    @property
    @abc.abstractmethod
    def orders_(self):
        """The fitted structure as a dict of plain ints / tuples (for example
        ``{"na": 2, "nb": (2,), "nk": (1,)}``)."""

    @property
    @abc.abstractmethod
    def max_lag(self):
        """Samples lost at the start of a record: the first row of :meth:`regressors`."""

    # ------------------------------------------------------------------
    # scikit-learn estimator protocol
    # ------------------------------------------------------------------
    @classmethod
    def _param_names(cls):
        sig = inspect.signature(cls.__init__)
        return [p.name for p in sig.parameters.values()
                if p.name != "self" and p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)]

    def get_params(self, deep=True):
        """Constructor parameters as a dict (scikit-learn protocol).

        Parameters
        ----------
        deep : bool, default True
            Accepted for scikit-learn compatibility; models have no nested
            estimators.

        Returns
        -------
        dict
            For example ``{"na": .., "nb": .., "nk": .., "dt": ..}`` for ARX.
        """
        return {name: getattr(self, name) for name in self._param_names()}

    def set_params(self, **params):
        """Set constructor parameters (scikit-learn protocol).

        Parameters
        ----------
        **params
            New values of constructor parameters (orders, ``dt``); call
            ``fit`` again afterwards.

        Returns
        -------
        self

        Raises
        ------
        TypeError
            For a name that is not a constructor parameter.
        """
        valid = self.get_params()
        for key in params:  # check every name first: a rejected call changes nothing
            if key not in valid:
                raise TypeError(f"`{key}` is not a parameter of {type(self).__name__}; valid "
                                f"parameters are {sorted(valid)}")
        for key, value in params.items():
            setattr(self, key, value)
        return self

    # ------------------------------------------------------------------
    # fitted checks
    # ------------------------------------------------------------------
    def __getattr__(self, name):
        # only reached when normal lookup fails (also when a property raised
        # AttributeError): say *why* a learned attribute is missing
        learned = name.endswith("_") or isinstance(getattr(type(self), name, None), property)
        if learned and not name.startswith("_"):
            if "theta_" not in self.__dict__:
                self._check_fitted(name)
            if name in self._ONLY_SET_BY:
                raise AttributeError(f"`{name}` is only set by {self._ONLY_SET_BY[name]}")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _check_fitted(self, what):
        check_is_fitted(self, what)

    @property
    def n_params(self):
        """Number of parameters per output; needs a fit."""
        self._check_fitted("n_params")
        return self.n_params_

    @property
    def std_errors_(self):
        """One standard error per parameter, the shape of ``theta_``."""
        self._check_fitted("std_errors_")
        cov = self.theta_cov_
        if cov.ndim == 2:
            return np.sqrt(np.diag(cov))
        return np.sqrt(np.diagonal(cov, axis1=1, axis2=2)).T

    # ------------------------------------------------------------------
    # python-control / scipy bridge, from the polynomials
    # ------------------------------------------------------------------
    def to_tf(self, noise=False, *, continuous=False, method="zoh", pade=None):
        r"""The model as a ``control.TransferFunction`` with sampling time ``dt``.

        Numerator and denominator are in positive powers of ``z``,
        zero-padded to equal length so that a feed-through (``nk = 0``) and
        every delay are exact. Several inputs or outputs give the matrix
        transfer function :math:`A(q)^{-1} B(q)/F(q)` (entries over a
        common denominator). Signal names of the data (pandas columns,
        `IOData` names) become python-control's signal labels.

        Parameters
        ----------
        noise : bool, default False
            Return the noise model :math:`H = A^{-1} C / D` (``ny`` x ``ny``)
            instead.
        continuous : bool, default False
            Return the continuous-time equivalent (:func:`rlsfilt.d2c`; needs
            a numeric ``dt``), the delay of ``nk`` samples kept as the
            attributes ``input_delay``/``io_delay`` in seconds.
        method : {"zoh", "tustin"}, default "zoh"
            The sampling the continuous model is read through (with
            `continuous`).
        pade : int, optional
            With `continuous`: replace the delays by Pade approximations of
            this order.

        Returns
        -------
        control.TransferFunction

        Warns
        -----
        ConversionWarning
            For several inputs or outputs when Slycot is not installed:
            python-control (0.10) turns a transfer-function *matrix* into
            state space, which its ``forced_response``, ``step_response``,
            ``feedback`` and ``ss`` need, only through Slycot, and raises
            ``ControlMIMONotImplemented`` without it. :meth:`to_ss` gives
            the same model as a ``control.StateSpace`` that needs no Slycot.

        Notes
        -----
        A single-input, single-output transfer function works everywhere in
        python-control. For several inputs or outputs, simulate
        :meth:`to_ss` (or the model's own :meth:`simulate`), or install
        Slycot (``pip install "rlsfilt[mimo]"``: manylinux wheels exist for
        CPython 3.11), with which python-control converts the matrix itself.
        Frequency responses and poles of the matrix need no Slycot.
        """
        self._check_fitted("to_tf")
        if not continuous and (method != "zoh" or pade is not None):
            raise TypeError("`method` and `pade` only apply with continuous=True")
        G = _labelled(_conversion.to_tf(self.polydata(), self._check_dt(), noise),
                      self._signal_labels(noise))
        if (G.ninputs > 1 or G.noutputs > 1) and not _has_slycot():
            warnings.warn(
                f"the {G.noutputs}x{G.ninputs} transfer-function matrix cannot be simulated or "
                "turned into state space by python-control without Slycot "
                "(ControlMIMONotImplemented); use model.to_ss() (same model, no Slycot "
                "needed) or install slycot", ConversionWarning, stacklevel=2)
        if continuous:
            from ..continuous import d2c

            if self.dt is True:
                raise ValueError("`continuous=True` needs the sampling period: the model has "
                                 "dt=True (unspecified); fit it with dt=<seconds>")
            G = d2c(G, method, pade=pade)
        return G

    def _signal_labels(self, noise=False):
        """``(inputs, outputs)`` labels from the data's signal names, or None when unnamed."""
        info = self.__dict__.get("_info", {})
        outs = info.get("y_names")
        ins = info.get("u_names") if not noise else None
        if noise and outs:
            ins = [f"e[{name}]" for name in outs]
        return (list(ins) if ins else None, list(outs) if outs else None)

    # ------------------------------------------------------------------
    # stability, said plainly
    # ------------------------------------------------------------------
    def poles(self, noise=False):
        r"""Poles of the model in the z-plane (MATLAB ``pole``).

        The roots of :math:`\det(A(z) F(z))` for the input model (of
        :math:`\det(A(z)) D(z)` for the noise model), from the polynomials:
        no realization, so delays add no poles at the origin.

        Parameters
        ----------
        noise : bool, default False
            Poles of the noise model instead.

        Returns
        -------
        ndarray of complex
            Sorted by decreasing magnitude.

        Examples
        --------
        >>> from rlsfilt import ARX
        >>> model = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=3)
        >>> abs(model.poles()).round(4)
        array([0.8367, 0.8367])
        """
        self._check_fitted("poles")
        from ._polynomials import poly_det, trim

        A_t, _ = _conversion.arx_form(self.polydata(), noise)
        ny = A_t.shape[0]
        det = trim(poly_det([[trim(A_t[i, j]) for j in range(ny)] for i in range(ny)]))
        roots = np.roots(det) if len(det) > 1 else np.zeros(0, dtype=complex)
        roots = roots.astype(complex)
        return roots[np.argsort(-np.abs(roots), kind="stable")]

    @property
    def is_stable(self):
        """True when every pole of the input model lies strictly inside the unit circle."""
        self._check_fitted("is_stable")
        p = self.poles()
        return bool(np.all(np.abs(p) < 1.0))

    def dc_gain(self):
        """Static gain :math:`G(z = 1)` of the input model (MATLAB ``dcgain``).

        Returns
        -------
        float or ndarray of shape (ny, nu)
            A float for one input and one output; ``inf`` for a model with
            a pole at ``z = 1`` (an integrator).

        Examples
        --------
        >>> from rlsfilt import ARX
        >>> ARX.from_polynomials([-0.5], [1.0]).dc_gain()      # 1 / (1 - 0.5)
        2.0
        """
        self._check_fitted("dc_gain")
        from ._polynomials import evaluate

        A_t, B_t = _conversion.arx_form(self.polydata(), False)
        ny, nu = A_t.shape[0], B_t.shape[1]
        A1 = np.array([[evaluate(A_t[i, j], 1.0).real for j in range(ny)] for i in range(ny)])
        B1 = np.array([[evaluate(B_t[i, j], 1.0).real for j in range(nu)] for i in range(ny)])
        if abs(np.linalg.det(A1)) <= 1e-14 * max(1.0, np.abs(A1).max()) ** ny:
            G = np.where(B1 == 0, np.nan, np.inf * np.sign(B1))
        else:
            G = np.linalg.solve(A1, B1)
        return float(G[0, 0]) if G.shape == (1, 1) else G

    def stability_text(self):
        """``"stable (largest pole magnitude 0.95)"`` or ``"unstable model, largest pole
        magnitude 1.02, simulation diverges"``: what a report prints."""
        self._check_fitted("stability_text")
        p = self.poles()
        r = float(np.max(np.abs(p))) if len(p) else 0.0
        if r >= 1.0 + 1e-9:
            return f"unstable model, largest pole magnitude {r:.4g}, simulation diverges"
        if r > 1.0 - 1e-9:
            return "marginally stable model (a pole on the unit circle), simulation may drift"
        return f"stable (largest pole magnitude {r:.3g})"

    # ------------------------------------------------------------------
    # saving
    # ------------------------------------------------------------------
    def save(self, path, *, include_data=False, trend=None):
        """Write the fitted model to a JSON file (:func:`rlsfilt.save_model`).

        Parameters
        ----------
        path : str or os.PathLike
        include_data : bool, default False
            Also write the per-sample diagnostics (residuals, histories).
        trend : Trend, optional
            The trend :func:`rlsfilt.detrend` removed from the estimation
            record (constant or linear); :meth:`load` restores it as
            ``trend_``, so ``retrend`` puts predictions back in the units of
            the data. By default the model's own ``trend_``, if any.

        Returns
        -------
        dict
            The document written.
        """
        self._check_fitted("save")
        from .._model_file import save_model

        return save_model(self, path, include_data=include_data, trend=trend)

    @classmethod
    def load(cls, path):
        """A model of this class read from a file written by :meth:`save`.

        Parameters
        ----------
        path : str or os.PathLike

        Returns
        -------
        model
            Predicts, simulates and reports standard errors exactly as the
            saved one; ``trend_`` holds the trend saved with it, if any.
        """
        from .._model_file import load_model

        return load_model(path, cls=cls)

    def to_ss(self, noise=False):
        """The model as a ``control.StateSpace`` (observer canonical form).

        The realization is that of the difference equation
        :math:`\\tilde A(q) y = \\tilde B(q) u` equivalent to the polynomial
        form (for ARX: ``ny * max(na, nk + nb - 1)`` states, ``D = b1`` when
        ``nk = 0``).

        Parameters
        ----------
        noise : bool, default False
            Realize the noise model instead of the input model.

        Returns
        -------
        control.StateSpace
            With sampling time ``dt`` and, like :meth:`to_tf`, the data's
            signal names as its input and output labels.
        """
        self._check_fitted("to_ss")
        return _labelled(_conversion.to_ss(self.polydata(), self._check_dt(), noise),
                         self._signal_labels(noise))

    def to_dlti(self, noise=False):
        """The model as a ``scipy.signal.dlti``.

        Parameters
        ----------
        noise : bool, default False
            Return the noise model instead.

        Returns
        -------
        scipy.signal.dlti
            A ``TransferFunction`` (positive powers of ``z``) for one input
            and one output, a ``StateSpace`` (the realization of
            :meth:`to_ss`) otherwise.
        """
        self._check_fitted("to_dlti")
        return _conversion.to_dlti(self.polydata(), self._check_dt(), noise)

    def to_kalman(self):
        """The model as a filterpy ``KalmanFilter``: `rlsfilt.adaptive.to_kalman`."""
        from ._kalman import to_kalman
        return to_kalman(self)

    def frequency_response(self, omega, theta=None, noise=False):
        r"""Frequency response :math:`G(e^{j\omega\,dt})` of every channel.

        Parameters
        ----------
        omega : array_like, shape (n_points,)
            Frequencies in rad per time unit (rad/sample when ``dt`` is
            unspecified).
        theta : array_like, optional
            Parameters in ``theta_`` order (for example a draw from their
            distribution); ``theta_`` by default.
        noise : bool, default False
            The noise model instead of the input model.

        Returns
        -------
        ndarray of complex, shape (ny, nu, n_points)
            (``(ny, ny, n_points)`` for the noise model.)
        """
        self._check_fitted("frequency_response")
        dt = self._check_dt()
        dt = 1.0 if dt is True else dt
        return _conversion.frequency_response(self.polydata(theta), omega, dt, noise)

    # ------------------------------------------------------------------
    # results as data
    # ------------------------------------------------------------------
    def to_dict(self):
        """The fitted model as a JSON-ready dict.

        Returns
        -------
        dict
            ``model`` (class name), ``params`` (constructor parameters),
            ``orders`` (:attr:`orders_`), ``dt``, ``input_names``,
            ``output_names``, ``theta_names``, ``theta``, ``theta_std``,
            ``noise_variance``, ``n_equations`` (``n_samples_``),
            ``polynomials`` (``A`` .. ``F`` of :meth:`polydata`) and
            ``transfer_functions`` (one dict per output and input with
            ``num``, ``den`` in positive powers of ``z`` as in
            :meth:`to_tf`, ``dt`` and ``variable``), ``poles`` (``[real,
            imag]`` pairs), ``stable``, ``stability`` (the sentence of
            :meth:`stability_text`) and ``dc_gain``. Arrays are lists;
            non-finite numbers are ``None``, so ``json.dumps(d,
            allow_nan=False)`` works. Subclasses add their own fields.

        Examples
        --------
        >>> import json
        >>> from rlsfilt import ARX
        >>> d = ARX.from_polynomials([-0.5], [1.0]).to_dict()
        >>> d["model"], d["theta_names"], d["theta"]
        ('ARX', ['a1', 'b1'], [-0.5, 1.0])
        >>> json.loads(json.dumps(d, allow_nan=False)) == d
        True
        """
        self._check_fitted("to_dict")
        p = self.polydata()
        with warnings.catch_warnings():   # only the coefficients are read
            warnings.simplefilter("ignore", ConversionWarning)
            G = self.to_tf()
        tfs = [{"output": i, "input": j, "num": G.num[i][j], "den": G.den[i][j],
                "dt": self._check_dt(), "variable": "z"}
               for i in range(self.n_outputs_) for j in range(self.n_inputs_)]
        return jsonable({
            "model": type(self).__name__, "params": self.get_params(), "orders": self.orders_,
            "dt": self._check_dt(),
            "input_names": [self._u_name(j) for j in range(self.n_inputs_)],
            "output_names": [self._y_name(i) for i in range(self.n_outputs_)],
            "theta_names": self.param_names_, "theta": self.theta_,
            "theta_std": self.std_errors_, "noise_variance": self.noise_variance_,
            "n_equations": self.n_samples_,
            "polynomials": {name: getattr(p, name) for name in p._fields},
            "transfer_functions": tfs,
            "poles": self.poles(), "stable": self.is_stable,
            "stability": self.stability_text(), "dc_gain": self.dc_gain()})

    # ------------------------------------------------------------------
    # display
    # ------------------------------------------------------------------
    def _display_params(self):
        """Constructor parameters worth showing: all up to ``dt``, later ones (options such
        as ``offset``) only when they differ from their default."""
        sig = inspect.signature(type(self).__init__).parameters
        names = self._param_names()
        cut = names.index("dt") + 1 if "dt" in names else len(names)
        shown = {}
        for i, (k, v) in enumerate(self.get_params().items()):
            default = sig[k].default
            if i < cut or default is inspect.Parameter.empty or not _same_value(v, default):
                shown[k] = v
        return shown

    def _orders_text(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self._display_params().items())
        return f"{type(self).__name__}({args})"

    def _summary_lines(self, style="text"):
        """Lines describing the fitted model above the coefficient table.

        `style` is ``"text"`` or ``"html"``; subclasses add their equations.
        """
        return []

    def summary(self):
        """A printable and notebook-friendly summary with a coefficient table.

        Returns
        -------
        ModelSummary
            ``print`` it for text, or display it in a notebook for HTML.
        """
        self._check_fitted("summary")
        from ._summary import ModelSummary

        return ModelSummary(self)

    def __repr__(self):
        if "theta_" not in self.__dict__:
            return self._orders_text()
        return "\n".join(self._summary_lines("text")) or self._orders_text()

    def _repr_html_(self):
        if "theta_" not in self.__dict__:
            return f"<pre>{html.escape(self._orders_text())}</pre>"
        return self.summary()._repr_html_()

    # ------------------------------------------------------------------
    # helpers for subclasses: data against the fitted signals
    # ------------------------------------------------------------------
    def _check_dt(self):
        """``dt`` validated: True or a Python float (what python-control accepts)."""
        return check_dt(self.dt)

    def _y_name(self, i):
        names = self._info.get("y_names")
        if names:
            return names[i]
        return "y" if self._info["y_1d"] else f"y{i + 1}"

    def _u_name(self, j):
        names = self._info.get("u_names")
        if names:
            return names[j]
        return "u" if self._info["u_1d"] else f"u{j + 1}"

    def _data(self, u, y=None):
        """Validate data against the fitted signal counts: ``(U (N, nu), Y (N, ny) or None)``."""
        if y is None:
            U, _, _ = _as_signal(u, "u")
            Y = None
        else:
            U, Y, _ = as_io_data(u, y)
            if Y.shape[1] != self.n_outputs_:
                raise ValueError(f"`y` must have {self.n_outputs_} output column(s) as in "
                                 f"`fit`; got {Y.shape[1]}")
        if U.shape[1] != self.n_inputs_:
            raise ValueError(f"`u` must have {self.n_inputs_} input column(s) as in `fit`; "
                             f"got {U.shape[1]}")
        return U, Y

    def _each_experiment(self, fn, u, y, *args, outputs=True):
        """``fn(u, y, *args)`` on one record, or on every experiment of an `IOData`.

        With an `IOData` (`y` omitted) the result is one array for one
        experiment and a list of arrays, one per experiment, otherwise.
        `outputs` false: `fn` takes no `y` (``fn(u, *args)``, simulation).
        """
        from ..data.iodata import IOData

        if not isinstance(u, IOData):
            if not outputs:
                return fn(u, *args)
            if y is None:
                raise TypeError("`y` is required unless `u` is an IOData")
            return fn(u, y, *args)
        if y is not None:
            raise TypeError(f"`y` must be omitted when `u` is an IOData (it holds the outputs); "
                            f"got {type(y).__name__}")
        outs = [fn(U, Y, *args) if outputs else fn(U, *args) for U, Y in u.arrays()]
        return outs[0] if len(outs) == 1 else outs

    def _shape_out(self, Yh):
        """An (N, ny) array in the shape `y` had in ``fit``."""
        return Yh[:, 0] if self._info["y_1d"] else Yh

    @staticmethod
    def _horizon_is_inf(horizon):
        return (isinstance(horizon, numbers.Real) and not isinstance(horizon, numbers.Integral)
                and horizon == np.inf)


def _same_value(a, b):
    """``a == b`` for parameter values, without numpy's elementwise comparison."""
    try:
        return type(a) is type(b) and bool(a == b)
    except (TypeError, ValueError):
        return False


def _labelled(G, labels):
    """`G` with signal labels (python-control keeps them through its conversions)."""
    import control

    ins, outs = labels
    if ins is None and outs is None:
        return G
    kw = {}
    if ins is not None and len(ins) == G.ninputs:
        kw["inputs"] = ins
    if outs is not None and len(outs) == G.noutputs:
        kw["outputs"] = outs
    if not kw:
        return G
    if isinstance(G, control.StateSpace):
        return control.ss(G.A, G.B, G.C, G.D, G.dt, **kw)
    if G.issiso():
        return control.tf(G.num[0][0], G.den[0][0], G.dt, **kw)
    return control.tf(G.num, G.den, G.dt, **kw)


def _has_slycot():
    """True when python-control can convert transfer-function matrices (Slycot importable)."""
    import importlib.util

    return importlib.util.find_spec("slycot") is not None
