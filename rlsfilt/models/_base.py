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
from collections import namedtuple

import numpy as np

from .._serialize import jsonable
from .._validation import check_dt
from ..exceptions import NotFittedError
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
        raise NotFittedError(f"This {type(model).__name__} instance is not fitted yet; call "
                             f"`fit(u, y)` before using `{what}`.")


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
    def to_tf(self, noise=False):
        r"""The model as a ``control.TransferFunction`` with sampling time ``dt``.

        Numerator and denominator are in positive powers of ``z``,
        zero-padded to equal length so that a feed-through (``nk = 0``) and
        every delay are exact. Several inputs or outputs give the matrix
        transfer function :math:`A(q)^{-1} B(q)/F(q)` (entries over a
        common denominator).

        Parameters
        ----------
        noise : bool, default False
            Return the noise model :math:`H = A^{-1} C / D` (``ny`` x ``ny``)
            instead.

        Returns
        -------
        control.TransferFunction
        """
        self._check_fitted("to_tf")
        return _conversion.to_tf(self.polydata(), self._check_dt(), noise)

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
            With sampling time ``dt``.
        """
        self._check_fitted("to_ss")
        return _conversion.to_ss(self.polydata(), self._check_dt(), noise)

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
            :meth:`to_tf`, ``dt`` and ``variable``). Arrays are lists;
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
            "transfer_functions": tfs})

    # ------------------------------------------------------------------
    # display
    # ------------------------------------------------------------------
    def _orders_text(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
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

    def _shape_out(self, Yh):
        """An (N, ny) array in the shape `y` had in ``fit``."""
        return Yh[:, 0] if self._info["y_1d"] else Yh

    @staticmethod
    def _horizon_is_inf(horizon):
        return (isinstance(horizon, numbers.Real) and not isinstance(horizon, numbers.Integral)
                and horizon == np.inf)
