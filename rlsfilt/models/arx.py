r"""ARX models: structure, batch and recursive fits, and the python-control bridge.

`ARX` is an estimator in the scikit-learn manner (``__init__`` stores the
orders, ``fit`` returns ``self``, learned quantities end in ``_``) for the
model of MATLAB's System Identification Toolbox; its docstring holds the
convention and the translation table to SIPPY and the lecture notes.
"""

import html
import inspect
import numbers

import numpy as np
from scipy import signal
from scipy.linalg import lapack, solve_triangular

from .._validation import as_float_array, check_dt, check_finite, check_int, check_scalar
from ..exceptions import NotFittedError
from ..filters import RecursiveLeastSquares
from .regressors import (
    _as_signal,
    _build,
    _column_rank,
    _full_rank_rows,
    arx_structure,
    as_io_data,
)

__all__ = ["ARX", "ARXSummary"]

# learned attributes that only some fits set, and which ones
_ONLY_SET_BY = {name: "fit(..., method='rls')" for name in
                ("theta_history_", "recursive_residuals_", "k0_", "filter_")}
_ONLY_SET_BY["noise_covariance_"] = "a fit on 2-D `y` (several outputs)"

class ARX:
    r"""ARX model ``A(q) y(t) = B(q) u(t - nk) + e(t)`` fitted by batch or recursive least squares.

    Parameters
    ----------
    na : int
        Number of past outputs (``>= 0``; ``0`` is an FIR model).
    nb : int or sequence of int
        Number of input coefficients (``>= 1``), a scalar or one per input.
    nk : int or sequence of int, default 1
        Input delay in samples (``>= 0``); ``0`` gives direct feed-through.
        A scalar or one per input.
    dt : True or float, default True
        Sampling period, passed to python-control and scipy (``True``:
        discrete time with an unspecified period).

    Attributes
    ----------
    theta_ : ndarray, shape (n_params,) or (n_params, ny)
        Parameter vector in regressor order (see :meth:`regressors`); one
        column per output when `y` was 2-D.
    a_ : ndarray
        ``[a1, ..., a_na]`` (without the leading 1) of shape ``(na,)`` when
        `y` was 1-D; for 2-D `y`, shape ``(ny, ny, na)`` with ``a_[i, j, k-1]``
        the coefficient of ``y_j(t-k)`` in the equation of output ``i``.
    b_ : ndarray or list of ndarray
        ``[b1, ..., b_nb]`` with ``b1`` multiplying ``u(t-nk)``: shape
        ``(nb,)`` (1-D `y`) or ``(ny, nb)`` (2-D `y`); a list of such arrays,
        one per input, when `u` was 2-D.
    theta_cov_ : ndarray, shape (n_params, n_params) or (ny, n_params, n_params)
        Parameter covariance :math:`\hat\sigma^2 (\Phi^T\Phi)^{-1}`, one per
        output (the outputs share :math:`\Phi`).
    noise_variance_ : float or ndarray of shape (ny,)
        Unbiased residual variance :math:`\hat\sigma^2 = \|y - \Phi\hat\theta\|^2
        / (N_{rows} - n_{params})` (NaN when there are no spare equations).
    noise_covariance_ : ndarray, shape (ny, ny)
        2-D `y` only: unbiased covariance of the residuals of the outputs
        (its diagonal is ``noise_variance_``); the covariance of
        ``vec(theta_)`` is ``kron(noise_covariance_, (Phi^T Phi)^-1)``.
    residuals_ : ndarray, shape ``(n_samples_,)`` or ``(n_samples_, ny)``
        ``target - Phi @ theta_`` on the fitted rows.
    n_samples_ : int
        Number of equations (rows of ``Phi``) used: ``N - max_lag``.
    n_params_ : int
        Number of parameters per output, ``ny * na + sum(nb)``.
    n_inputs_, n_outputs_ : int
        Number of input and output signals.
    method_ : str
        ``"ls"`` or ``"rls"``.
    theta_history_ : ndarray, shape ``(n_samples_, n_params[, ny])``
        ``method="rls"`` only: the estimate after each row; rows before the
        batch start (``k0 - 1``) are NaN.
    recursive_residuals_ : ndarray, shape ``(n_samples_,)`` or ``(n_samples_, ny)``
        ``method="rls"`` only: the a-priori residuals
        :math:`y(t) - \varphi(t)\hat\theta(t-1)`, the errors the filter
        actually made (NaN for the rows of the batch start). Under forgetting
        these, not ``residuals_``, show how well the model tracked.
    k0_ : int
        ``method="rls"`` only: number of rows of the batch start.
    filter_ : RecursiveLeastSquares
        ``method="rls"`` only: the filter after the last sample, ready for
        more ``predict``/``update`` calls.

    Notes
    -----
    **Convention** (MATLAB's ``arx(data, [na nb nk])``), for one input:

    .. math::

        y(t) + a_1 y(t-1) + \dots + a_{n_a} y(t-n_a)
            = b_1 u(t-n_k) + \dots + b_{n_b} u(t-n_k-n_b+1) + e(t),

    i.e. :math:`A(q) y(t) = B(q) u(t) + e(t)` with
    :math:`A(q) = 1 + a_1 q^{-1} + \dots` and
    :math:`B(q) = q^{-n_k}(b_1 + b_2 q^{-1} + \dots)`. Translation table:

    ==================  ===========================  ==========================  ==================
    quantity            rlsfilt and MATLAB           SIPPY                       lecture notes
    ==================  ===========================  ==========================  ==================
    orders              ``na, nb, nk``               ``[na, nb, theta]``         ``n`` (``m = n``)
    delay               ``nk``: first term u(t-nk)   ``theta = nk - 1``          none: ``b0 u[k]``
    b numbering         ``b1 .. b_nb``               ``b1 .. b_nb``              ``b0 .. bn`` = our
                                                                                 ``b1 .. b_(n+1)``
    the notes' model    ``ARX(n, n + 1, nk=0)``      not expressible (theta=-1)  order ``n``
    sampled plant       ``ARX(2, 2, nk=1)``          ``[2, 2, 0]``               needs ``b0 = 0``
    MATLAB ``B``        ``[zeros(1, nk), b1 ..]``    ``NUMERATOR``               --
    ==================  ===========================  ==========================  ==================

    The model in regression form is :math:`y(t) = \varphi(t)\theta + e(t)`
    with

    .. math::

        \varphi(t) = [-y(t-1), \dots, -y(t-n_a), u(t-n_k), \dots,
        u(t-n_k-n_b+1)],

    one ``-y`` block per output followed by one ``u`` block per input, for
    :math:`t = t_0 \dots N-1`, :math:`t_0 = \max(n_a, n_k + n_b - 1)`. The
    lecture notes' model :math:`\hat y[k] = -a_1 y[k-1] - \dots - a_n y[k-n]
    + b_0 u[k] + \dots + b_n u[k-n]` is ``ARX(na=n, nb=n + 1, nk=0)``; its
    ``b0`` is our ``b1``.

    ``method="ls"`` solves :math:`\min\|\Phi\theta - Y\|` through the QR
    factorization :math:`\Phi = Q_1 R_1` (:math:`\hat\theta = R_1^{-1}Q_1^TY`,
    :math:`(\Phi^T\Phi)^{-1} = R_1^{-1}R_1^{-T}`), never through the normal
    equations. ``method="rls"`` runs `RecursiveLeastSquares`, started by
    batch least squares on the first ``k0`` rows as in the lecture notes;
    with ``lam = 1`` it ends at the batch answer. Under white equation error
    the estimate is consistent; with colored noise it is biased (Ljung 1999,
    sec. 8.3), which the colored-noise datasets of `rlsfilt.datasets` show.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 4.2 and 7.3.
    .. [2] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 2.

    Examples
    --------
    Identify ``y(t) - 1.5 y(t-1) + 0.7 y(t-2) = u(t-1) + 0.5 u(t-2) + e(t)``:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import ARX
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(2000)
    >>> e = 0.05 * rng.standard_normal(2000)
    >>> y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1], [1, -1.5, 0.7], e)
    >>> model = ARX(na=2, nb=2, nk=1).fit(u, y)
    >>> np.round(model.a_, 2), np.round(model.b_, 2)
    (array([-1.5,  0.7]), array([1. , 0.5]))
    """

    def __init__(self, na, nb, nk=1, dt=True):
        self.na = na
        self.nb = nb
        self.nk = nk
        self.dt = dt

    # ------------------------------------------------------------------
    # scikit-learn estimator protocol
    # ------------------------------------------------------------------
    def get_params(self, deep=True):
        """Constructor parameters as a dict (scikit-learn protocol).

        Parameters
        ----------
        deep : bool, default True
            Accepted for scikit-learn compatibility; ARX has no nested
            estimators.

        Returns
        -------
        dict
            ``{"na": .., "nb": .., "nk": .., "dt": ..}``.
        """
        return {"na": self.na, "nb": self.nb, "nk": self.nk, "dt": self.dt}

    def set_params(self, **params):
        """Set constructor parameters (scikit-learn protocol).

        Parameters
        ----------
        **params
            New values of ``na``, ``nb``, ``nk`` or ``dt``; call :meth:`fit`
            again afterwards.

        Returns
        -------
        self : ARX

        Raises
        ------
        TypeError
            For a name that is not a constructor parameter.
        """
        valid = self.get_params()
        for key, value in params.items():
            if key not in valid:
                raise TypeError(f"`{key}` is not a parameter of ARX; valid parameters are "
                                f"{sorted(valid)}")
            setattr(self, key, value)
        return self

    # ------------------------------------------------------------------
    # structure
    # ------------------------------------------------------------------
    def _structure(self, n_inputs, n_outputs):
        check_dt(self.dt)
        return arx_structure(self.na, self.nb, self.nk, n_inputs, n_outputs)

    def regressors(self, u, y):
        r"""Regressor matrix and target for this model's orders.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
            Input record (time on axis 0; pandas works too).
        y : array_like, shape (N,) or (N, ny)
            Output record.

        Returns
        -------
        Phi : ndarray, shape (N - max_lag, n_params)
            Rows :math:`\varphi(t)` for ``t = max_lag .. N-1``: blocks
            ``-y_1 .. -y_ny`` then ``u_1 .. u_nu``, each by increasing lag,
            ``[-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1)]``.
        target : ndarray, shape (N - max_lag,) or (N - max_lag, ny)
            ``y(t)`` on the same rows.
        """
        U, Y, info = as_io_data(u, y)
        s = self._structure(U.shape[1], Y.shape[1])
        Phi = _build(U, Y, s, s.max_lag)
        target = Y[s.max_lag:, 0] if info["y_1d"] else Y[s.max_lag:]
        return Phi, target.copy()

    # ------------------------------------------------------------------
    # fitting
    # ------------------------------------------------------------------
    def fit(self, u, y, method="ls", *, k0=None, lam=None, P0=None, R=None, Q=None, x0=None,
            **filter_options):
        r"""Estimate the parameters from an input/output record.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
            Input record; pandas Series/DataFrame work too.
        y : array_like, shape (N,) or (N, ny)
            Output record, same length.
        method : {"ls", "rls"}, default "ls"
            ``"ls"``: batch least squares through QR. ``"rls"``:
            `RecursiveLeastSquares` over the rows, started by batch least
            squares on the first `k0` rows.
        k0 : int, optional
            ``"rls"`` only: number of rows of the batch start. By default
            ``n_params`` (the lecture notes' choice), or, when those first
            rows do not determine every parameter (for example a PRBS held
            for several samples), the fewest leading rows that do. ``0``
            starts from the prior ``x0``, ``P0`` instead (MATLAB ``rarx``);
            that is the default when `P0` or `x0` is given.
        lam, P0, R, Q, x0
            ``"rls"`` only: passed to `RecursiveLeastSquares` (forgetting
            factor, initial covariance and estimate for a prior start with
            ``k0 = 0``, noise variance, random-walk covariance).
        **filter_options
            ``"rls"`` only: any other keyword argument of
            `RecursiveLeastSquares` (for example its forgetting mode), passed
            through unchanged.

        Returns
        -------
        self : ARX

        Raises
        ------
        ValueError
            NaN/inf in the data (the first bad index is named), mismatched
            lengths, bad orders, too few samples, or a regressor matrix
            without full column rank (input not persistently exciting).

        Notes
        -----
        With ``method="rls"``, ``theta_`` is the filter's last estimate and
        ``theta_cov_`` is ``noise_variance_ * P / R``, its covariance; with
        ``lam = 1``, ``Q = 0`` and a batch start both equal the batch answer.
        With forgetting they describe the exponentially weighted fit at the
        end of the record, while ``noise_variance_`` (residuals of the final
        estimate over all rows) overstates the noise if the plant changed.
        """
        if method not in ("ls", "rls"):
            raise ValueError(f"`method` must be 'ls' or 'rls'; got {method!r}")
        opts = {"k0": k0, "lam": lam, "P0": P0, "R": R, "Q": Q, "x0": x0}
        if method == "ls":
            given = [k for k, v in opts.items() if v is not None] + list(filter_options)
            if given:
                raise TypeError(f"`{given[0]}` only applies to method='rls'; got method='ls'")
        _check_filter_options(filter_options)
        opts["extra"] = filter_options
        U, Y, info = as_io_data(u, y)
        s = self._structure(U.shape[1], Y.shape[1])
        N = len(U)
        if N - s.max_lag < s.n_params:
            raise ValueError(
                f"`y` must have at least max_lag + n_params = {s.max_lag} + {s.n_params} = "
                f"{s.max_lag + s.n_params} samples for ARX(na={s.na}, nb={_fmt(s.nb)}, "
                f"nk={_fmt(s.nk)}); got {N}")
        Phi = _build(U, Y, s, s.max_lag)
        target = Y[s.max_lag:]
        rows = len(Phi)
        for name in ("theta_history_", "filter_", "k0_", "recursive_residuals_",
                     "noise_covariance_"):
            self.__dict__.pop(name, None)
        if method == "ls":
            theta, cov_unscaled = _qr_least_squares(Phi, target)
        else:
            theta, cov_unscaled, rls, history, x_start = self._fit_rls(Phi, target, s, opts)
            self.filter_ = rls
            self.theta_history_ = history[:, :, 0] if info["y_1d"] else history
            # a-priori (recursive) residuals y(t) - phi(t) theta(t-1) after the batch start
            prior = np.full_like(target, np.nan)
            k0 = self.k0_
            if k0 == 0 and rows:
                prior[0] = target[0] - Phi[0] @ x_start
                k0 = 1
            prior[k0:] = target[k0:] - np.einsum("ij,ijk->ik", Phi[k0:], history[k0 - 1:-1])
            self.recursive_residuals_ = prior[:, 0] if info["y_1d"] else prior
        resid = target - Phi @ theta
        dof = rows - s.n_params
        sigma2 = np.sum(resid ** 2, axis=0) / dof if dof > 0 else np.full(s.n_outputs, np.nan)
        self._store(theta, s, info)
        cov = sigma2[:, None, None] * cov_unscaled[None]
        self.theta_cov_ = cov[0] if info["y_1d"] else cov
        self.noise_variance_ = float(sigma2[0]) if info["y_1d"] else sigma2
        if not info["y_1d"]:
            self.noise_covariance_ = (resid.T @ resid / dof if dof > 0
                                      else np.full((s.n_outputs, s.n_outputs), np.nan))
        self.residuals_ = resid[:, 0] if info["y_1d"] else resid
        self.n_samples_ = rows
        self.method_ = method
        return self

    def _fit_rls(self, Phi, target, s, opts):
        n, rows = s.n_params, len(Phi)
        prior = opts["P0"] is not None or opts["x0"] is not None
        if opts["k0"] is not None:
            k0 = check_int(opts["k0"], "k0", minimum=0)
        else:  # a given prior means a prior start (MATLAB rarx); else the notes' batch start
            k0 = 0 if prior else _full_rank_rows(Phi)
            if k0 is None:  # not even all rows determine theta
                _qr_least_squares(Phi, target)  # raises with the rank in the message
        if k0 > rows:
            raise ValueError(f"`k0` must be <= the number of regressor rows ({rows}); got {k0}")
        if k0 > 0:
            given = [key for key in ("P0", "x0") if opts[key] is not None]
            if given:
                raise ValueError(
                    f"`{given[0]}` only applies to a prior start (k0=0); the batch start on "
                    f"k0={k0} rows sets both x0 and P0. Pass k0=0 to start from `{given[0]}`.")
        kw = {key: opts[key] for key in ("P0", "R", "Q", "x0") if opts[key] is not None}
        lam = 1.0 if opts["lam"] is None else opts["lam"]
        rls = RecursiveLeastSquares(n, dim_z=s.n_outputs, lam=lam, **kw, **opts["extra"])
        history = np.full((rows, n, s.n_outputs), np.nan)
        x_start = rls.x.copy()
        if k0 > 0:
            rls.initialize(target[:k0], Phi[:k0])
            history[k0 - 1] = rls.x
        if k0 < rows:
            means = rls.batch_filter(target[k0:], Phi[k0:], store_covariances=False)[0]
            history[k0:] = means
        self.k0_ = k0
        return rls.x.copy(), rls.P / rls.R, rls, history, x_start

    def _store(self, theta, s, info):
        """Set every fitted attribute derived from ``theta`` (n_params, ny)."""
        self.structure_ = s
        self._info = dict(info)
        self.n_params_ = s.n_params
        self.n_inputs_ = s.n_inputs
        self.n_outputs_ = s.n_outputs
        y_1d, u_1d = info["y_1d"], info["u_1d"]
        self.theta_ = theta[:, 0].copy() if y_1d else theta.copy()
        a_sl, b_sls = s.param_slices()
        A = theta[a_sl].reshape(s.n_outputs, s.na, s.n_outputs).transpose(2, 0, 1)
        self._A = A                                       # (ny, ny, na)
        self._B = [theta[sl].T.copy() for sl in b_sls]    # list of (ny, nb_j)
        self.a_ = A[0, 0].copy() if y_1d else A.copy()
        Bs = [b[0].copy() if y_1d else b.copy() for b in self._B]
        self.b_ = Bs[0] if u_1d else Bs

    # ------------------------------------------------------------------
    # fitted-model helpers
    # ------------------------------------------------------------------
    def __getattr__(self, name):
        # only reached when normal lookup fails (also when a property raised
        # AttributeError): say *why* a learned attribute is missing
        learned = name.endswith("_") or isinstance(getattr(type(self), name, None), property)
        if learned and not name.startswith("_"):
            if "theta_" not in self.__dict__:
                self._check_fitted(name)
            if name in _ONLY_SET_BY:
                raise AttributeError(f"`{name}` is only set by {_ONLY_SET_BY[name]}")
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def _check_fitted(self, what):
        if "theta_" not in self.__dict__:
            raise NotFittedError(
                f"This ARX instance is not fitted yet; call `fit(u, y)` before using `{what}`.")

    @property
    def n_params(self):
        """Number of parameters per output (``ny * na + sum(nb)``); needs a fit."""
        self._check_fitted("n_params")
        return self.n_params_

    @property
    def max_lag(self):
        """``max(na, nk + nb - 1)``: samples lost at the start of a record; needs a fit."""
        self._check_fitted("max_lag")
        return self.structure_.max_lag

    @property
    def std_errors_(self):
        """One standard error per parameter, the shape of ``theta_``."""
        self._check_fitted("std_errors_")
        cov = self.theta_cov_
        if cov.ndim == 2:
            return np.sqrt(np.diag(cov))
        return np.sqrt(np.diagonal(cov, axis1=1, axis2=2)).T

    @property
    def param_names_(self):
        """Names of the entries of ``theta_`` (``a1``, ``b2``, ``b1[u2]``, ``a1[y2]``)."""
        self._check_fitted("param_names_")
        s, info = self.structure_, self._info
        names = []
        for j in range(s.n_outputs):
            tag = "" if info["y_1d"] else f"[{self._y_name(j)}]"
            names += [f"a{k}{tag}" for k in range(1, s.na + 1)]
        for j in range(s.n_inputs):
            tag = "" if info["u_1d"] else f"[{self._u_name(j)}]"
            names += [f"b{k}{tag}" for k in range(1, s.nb[j] + 1)]
        return names

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

    def _theta2(self):
        return self.theta_.reshape(self.n_params_, -1)

    def _data(self, u, y=None):
        """Validate data against the fitted signal counts."""
        s = self.structure_
        if y is None:
            U, _, _ = _as_signal(u, "u")
            Y = None
        else:
            U, Y, _ = as_io_data(u, y)
            if Y.shape[1] != s.n_outputs:
                raise ValueError(f"`y` must have {s.n_outputs} output column(s) as in `fit`; "
                                 f"got {Y.shape[1]}")
        if U.shape[1] != s.n_inputs:
            raise ValueError(f"`u` must have {s.n_inputs} input column(s) as in `fit`; "
                             f"got {U.shape[1]}")
        return U, Y

    def _shape_out(self, Yh):
        return Yh[:, 0] if self._info["y_1d"] else Yh

    def _input_part(self, U):
        """``sum_j B_j(q) u_j(t)`` with zero inputs before t = 0, shape (N, ny)."""
        s = self.structure_
        Phi0 = _build(U, np.zeros((len(U), s.n_outputs)), s, 0)
        return Phi0 @ self._theta2()

    # ------------------------------------------------------------------
    # prediction and simulation
    # ------------------------------------------------------------------
    def predict(self, u, y, horizon=1):
        r"""``horizon``-step-ahead prediction (MATLAB ``predict``).

        ``yhat[t]`` is the prediction of ``y(t)`` from the outputs up to
        ``t - horizon`` and the inputs up to ``t``: the model is run
        ``horizon`` steps from the measured past, replacing the unmeasured
        outputs by their own predictions. Signals before ``t = 0`` are taken
        as zero (MATLAB's ``InitialCondition='z'``), so
        ``predict(u, y)[max_lag:] == Phi @ theta_`` on the rows of
        :meth:`regressors`, and a horizon ``>= N`` (or ``np.inf``) is
        :meth:`simulate`.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
            Input record.
        y : array_like, shape (N,) or (N, ny)
            Measured outputs.
        horizon : int or np.inf, default 1
            Prediction horizon ``>= 1``.

        Returns
        -------
        yhat : ndarray, shape (N,) or (N, ny)

        Examples
        --------
        Two-step-ahead prediction of ``y(t) = 0.9 y(t-1) + u(t-1)``: from
        ``y(t-2)`` the model first predicts ``y(t-1)``, then ``y(t)``.

        >>> import numpy as np
        >>> from rlsfilt import ARX
        >>> model = ARX.from_polynomials([-0.9], [1.0])
        >>> u = np.array([1.0, 0.0, 0.0, 0.0])
        >>> y = np.array([0.0, 1.0, 1.0, 0.5])   # measured, with disturbances
        >>> model.predict(u, y, horizon=1)
        array([0. , 1. , 0.9, 0.9])
        >>> model.predict(u, y, horizon=2)       # yhat(3) = 0.9 * 0.9 * y(1)
        array([0.  , 1.  , 0.9 , 0.81])
        """
        self._check_fitted("predict")
        U, Y = self._data(u, y)
        N = len(U)
        if isinstance(horizon, numbers.Real) and not isinstance(horizon, numbers.Integral) \
                and horizon == np.inf:
            horizon = N
        horizon = check_int(horizon, "horizon", minimum=1)
        if horizon >= N:
            return self.simulate(U if not self._info["u_1d"] else U[:, 0])
        bu = self._input_part(U)
        A, na = self._A, self.structure_.na
        preds = []  # preds[h - 1] is yhat_h; only the last na are needed
        for h in range(1, horizon + 1):
            yh = bu.copy()
            for k in range(1, na + 1):
                src = Y if k >= h else preds[h - k - 1]
                yh[k:] -= src[:-k] @ A[:, :, k - 1].T
            preds.append(yh)
            if len(preds) > na + 1:
                preds[h - na - 2] = None
        return self._shape_out(preds[-1])

    def simulate(self, u, y0=None):
        r"""Free-run simulation (MATLAB ``sim``): the output from the input alone.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
            Input record; inputs before ``t = 0`` are zero.
        y0 : array_like, shape (L,) or (L, ny), optional
            Known outputs ``y(0) .. y(L-1)`` (for example ``y[:na]`` of a
            measured record); the simulation continues from ``t = L``. By
            default everything before ``t = 0`` is zero, and the result
            equals ``scipy.signal.lfilter(B, A, u)`` and
            ``control.forced_response(model.to_tf(), T, u)``.

        Returns
        -------
        y_sim : ndarray, shape (N,) or (N, ny)

        Examples
        --------
        >>> import numpy as np
        >>> from rlsfilt import ARX
        >>> model = ARX.from_polynomials([-0.5], [1.0])   # y(t) = 0.5 y(t-1) + u(t-1)
        >>> model.simulate(np.ones(4))
        array([0.  , 1.  , 1.5 , 1.75])
        >>> model.simulate(np.ones(4), y0=[4.0])          # continue from y(0) = 4
        array([4.  , 3.  , 2.5 , 2.25])
        """
        self._check_fitted("simulate")
        U, _ = self._data(u)
        N, ny = len(U), self.n_outputs_
        bu = self._input_part(U)
        A, na = self._A, self.structure_.na
        L = 0
        Ysim = np.zeros((N, ny))
        if y0 is not None:
            Y0, _, _ = _as_signal(y0, "y0")
            if Y0.shape[1] != ny:
                raise ValueError(f"`y0` must have {ny} output column(s); got {Y0.shape[1]}")
            L = len(Y0)
            if L > N:
                raise ValueError(f"`y0` must have at most N = {N} samples; got {L}")
            Ysim[:L] = Y0
        if ny == 1:
            a = np.concatenate([[1.0], A[0, 0]])
            past = Ysim[max(L - na, 0):L, 0][::-1]
            zi = signal.lfiltic([1.0], a, past) if na else None
            if L < N:
                if zi is None:
                    Ysim[L:, 0] = bu[L:, 0]
                else:
                    Ysim[L:, 0] = signal.lfilter([1.0], a, bu[L:, 0], zi=zi)[0]
        else:
            Ak = [A[:, :, k - 1] for k in range(1, na + 1)]
            for t in range(L, N):
                acc = bu[t].copy()
                for k in range(1, min(na, t) + 1):
                    acc -= Ak[k - 1] @ Ysim[t - k]
                Ysim[t] = acc
        return self._shape_out(Ysim)

    # ------------------------------------------------------------------
    # polynomials and the python-control / scipy bridge
    # ------------------------------------------------------------------
    def polynomials(self):
        """``(A, B)`` in MATLAB's form, coefficients of ascending powers of ``q^-1``.

        Returns
        -------
        A : ndarray
            Single output and input: ``[1, a1, .., a_na]``; otherwise shape
            ``(ny, ny, na + 1)`` with ``A[:, :, 0]`` the identity.
        B : ndarray
            Single output and input: ``[0]*nk + [b1, .., b_nb]``; otherwise
            shape ``(ny, nu, max(nk + nb))``.

        Examples
        --------
        >>> from rlsfilt import ARX
        >>> A, B = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=2).polynomials()
        >>> A, B
        (array([ 1. , -1.5,  0.7]), array([0. , 0. , 1. , 0.5]))
        """
        self._check_fitted("polynomials")
        Apoly, Bpoly = self._poly_matrices()
        if self._info["y_1d"] and self._info["u_1d"]:
            return Apoly[0, 0], Bpoly[0, 0]
        return Apoly, Bpoly

    def _poly_matrices(self):
        s = self.structure_
        ny, nu = s.n_outputs, s.n_inputs
        Apoly = np.zeros((ny, ny, s.na + 1))
        Apoly[:, :, 0] = np.eye(ny)
        Apoly[:, :, 1:] = self._A
        lb = max(k + b for k, b in zip(s.nk, s.nb))
        Bpoly = np.zeros((ny, nu, lb))
        for j in range(nu):
            Bpoly[:, j, s.nk[j]:s.nk[j] + s.nb[j]] = self._B[j]
        return Apoly, Bpoly

    def _tf_data(self, noise):
        """Numerators and denominators ``[i][j]`` in powers of ``q^-1``, padded."""
        Apoly, Bpoly = self._poly_matrices()
        ny = Apoly.shape[0]
        Am = [[_trim(Apoly[i, j]) for j in range(ny)] for i in range(ny)]
        det = _trim(_poly_det(Am))
        adj = _poly_adj(Am)
        if noise:
            cols = [[np.array([1.0 if i == j else 0.0]) for j in range(ny)] for i in range(ny)]
        else:
            cols = [[Bpoly[i, j] for j in range(Bpoly.shape[1])] for i in range(ny)]
        nums, dens = [], []
        for i in range(ny):
            row_n, row_d = [], []
            for j in range(len(cols[0])):
                num = np.zeros(1)
                for k in range(ny):
                    num = _padd(num, np.convolve(adj[i][k], cols[k][j]))
                num, den = _equalize(num, det)
                row_n.append(num)
                row_d.append(den)
            nums.append(row_n)
            dens.append(row_d)
        return nums, dens

    def to_tf(self, noise=False):
        r"""The model as a ``control.TransferFunction`` with sampling time ``dt``.

        ``G(z) = z^{-nk} B(z^{-1}) / A(z^{-1})`` with numerator and
        denominator in positive powers of ``z``, zero-padded to equal length
        so that a feed-through ``b1`` (``nk = 0``) and every delay are exact.
        Several inputs or outputs give the matrix transfer function
        ``A(q)^{-1} B(q)`` (entries over the common denominator
        ``det A``).

        Parameters
        ----------
        noise : bool, default False
            Return the noise model ``H(z) = 1 / A(z^{-1})`` (matrix
            ``A^{-1}`` for several outputs) instead.

        Returns
        -------
        control.TransferFunction
            SISO, or ``ny`` x ``nu`` (``ny`` x ``ny`` for the noise model).

        Examples
        --------
        The lecture notes' ``y[k] = 0.5 y[k-1] + 2 u[k] + u[k-1]`` keeps its
        feed-through ``b0 = 2``; a delay of 3 samples gives ``z^3`` below:

        >>> from rlsfilt import ARX
        >>> G = ARX.from_polynomials([-0.5], [2.0, 1.0], nk=0, dt=0.1).to_tf()
        >>> G.num[0][0], G.den[0][0]
        (array([2., 1.]), array([ 1. , -0.5]))
        >>> G = ARX.from_polynomials([-0.5], [2.0], nk=3, dt=0.1).to_tf()
        >>> G.num[0][0], G.den[0][0]
        (array([2.]), array([ 1. , -0.5,  0. ,  0. ]))
        """
        self._check_fitted("to_tf")
        import control

        nums, dens = self._tf_data(noise)
        if len(nums) == 1 and len(nums[0]) == 1:
            return control.tf(nums[0][0], dens[0][0], self.dt)
        return control.tf(nums, dens, self.dt)

    def _ss_matrices(self, noise=False):
        """Observer-form realization ``(A, B, C, D)`` of the difference equation."""
        s = self.structure_
        ny = s.n_outputs
        if noise:
            nu = ny
            lb = 1
            Bt = np.zeros((1, ny, nu))
            Bt[0] = np.eye(ny)
        else:
            nu = s.n_inputs
            _, Bpoly = self._poly_matrices()
            lb = Bpoly.shape[2]
            Bt = Bpoly.transpose(2, 0, 1)  # Bt[k] multiplies u(t-k), (ny, nu)
        n = max(s.na, lb - 1)
        Ak = [self._A[:, :, k - 1] if k <= s.na else np.zeros((ny, ny)) for k in range(1, n + 1)]
        Bk = [Bt[k] if k < lb else np.zeros((ny, nu)) for k in range(n + 1)]
        D = Bk[0]
        Am = np.zeros((n * ny, n * ny))
        Bm = np.zeros((n * ny, nu))
        for i in range(n):
            blk = slice(i * ny, (i + 1) * ny)
            Am[blk, 0:ny] = -Ak[i]                 # x_i(t+1) = x_{i+1}(t) - A_i y(t) + B_i u(t)
            if i + 1 < n:
                Am[blk, (i + 1) * ny:(i + 2) * ny] = np.eye(ny)
            Bm[blk] = Bk[i + 1] - Ak[i] @ D        # y(t) = x_1(t) + D u(t)
        Cm = np.zeros((ny, n * ny))
        if n:  # a static gain (na = 0, nk = 0, nb = 1) has no state
            Cm[:, :ny] = np.eye(ny)
        return Am, Bm, Cm, D.copy()

    def to_ss(self, noise=False):
        r"""The model as a ``control.StateSpace`` (observer canonical form).

        States are ``x_1 = y(t) - D u(t)`` and the partial sums of the
        difference equation; the realization has ``ny * max(na, nk + nb - 1)``
        states and ``D = b1`` when ``nk = 0``.

        Parameters
        ----------
        noise : bool, default False
            Realize the noise model ``A(q)^{-1}`` instead of the input model.

        Returns
        -------
        control.StateSpace
            With sampling time ``dt``.
        """
        self._check_fitted("to_ss")
        import control

        return control.ss(*self._ss_matrices(noise), self.dt)

    def to_dlti(self, noise=False):
        """The model as a ``scipy.signal.dlti``.

        Parameters
        ----------
        noise : bool, default False
            Return the noise model ``A(q)^{-1}`` instead.

        Returns
        -------
        scipy.signal.dlti
            A ``TransferFunction`` (positive powers of ``z``) for one input
            and one output, a ``StateSpace`` (the realization of
            :meth:`to_ss`) otherwise.
        """
        self._check_fitted("to_dlti")
        if self.n_outputs_ == 1 and (self.n_inputs_ == 1 or noise):
            nums, dens = self._tf_data(noise)
            num = nums[0][0]
            lead = np.flatnonzero(num)
            num = num[lead[0]:] if len(lead) else np.zeros(1)  # exact: z^k factors, den kept
            return signal.dlti(num, dens[0][0], dt=self.dt)
        return signal.dlti(*self._ss_matrices(noise), dt=self.dt)

    # ------------------------------------------------------------------
    # construction from a true plant
    # ------------------------------------------------------------------
    @classmethod
    def from_polynomials(cls, a, b, nk=1, dt=True, noise_variance=0.0):
        """An ARX model with given coefficients (a true plant, no fit).

        Parameters
        ----------
        a : array_like, shape (na,)
            ``[a1, .., a_na]`` **without** the leading 1 (the layout of
            ``a_``); ``[]`` for an FIR model.
        b : array_like, shape (nb,), or a list of them (one per input)
            ``[b1, .., b_nb]``, ``b1`` multiplying ``u(t - nk)`` (the layout
            of ``b_``).
        nk : int or sequence of int, default 1
            Input delay(s).
        dt : True or float, default True
            Sampling period.
        noise_variance : float, default 0.0
            Variance of ``e(t)``, stored as ``noise_variance_``.

        Returns
        -------
        ARX
            A model usable as if fitted (``theta_cov_`` is zero and
            ``n_samples_`` is 0).

        Examples
        --------
        >>> from rlsfilt import ARX
        >>> true = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=1, dt=0.1)
        >>> [round(float(abs(p)), 4) for p in true.to_tf().poles()]
        [0.8367, 0.8367]
        """
        a = np.atleast_1d(as_float_array(a, "a"))
        if a.ndim != 1:
            raise ValueError(f"`a` must be 1-D [a1, ..., a_na]; got shape {a.shape}")
        check_finite(a, "a")
        multi = isinstance(b, (list, tuple)) and len(b) > 0 and np.ndim(b[0]) >= 1
        bs = []
        for j, bj in enumerate(b if multi else [b]):
            name = f"b[{j}]" if multi else "b"
            bj = np.atleast_1d(as_float_array(bj, name))
            if bj.ndim != 1 or bj.size == 0:
                raise ValueError(f"`b` must hold 1-D coefficient arrays with nb >= 1; got shape "
                                 f"{bj.shape}" + (f" for input {j}" if multi else ""))
            bs.append(check_finite(bj, name))
        noise_variance = check_scalar(noise_variance, "noise_variance")
        if not (np.isfinite(noise_variance) and noise_variance >= 0.0):
            raise ValueError(f"`noise_variance` must be a finite value >= 0; got {noise_variance}")
        nb = [len(bj) for bj in bs]
        model = cls(na=len(a), nb=nb if multi else nb[0], nk=nk, dt=dt)
        s = model._structure(len(bs), 1)
        theta = np.concatenate([a] + bs).reshape(-1, 1)
        info = {"u_1d": not multi, "y_1d": True, "u_names": None, "y_names": None}
        model._set_truth(theta, s, info, noise_variance)
        return model

    @classmethod
    def from_tf(cls, G):
        """An ARX model with the same input-output behaviour as the discrete plant `G`.

        ``G`` is a discrete ``control.TransferFunction`` (or anything
        ``control.tf`` accepts, such as a ``StateSpace``). Each output's
        entries are put over a common denominator ``A_i``, the product of
        the row's distinct denominators (minimal when they are equal or
        coprime); ``nk`` and ``nb`` per input are read off the numerators
        (leading zeros of ``B`` in powers of ``z^-1`` are the delay). A
        SISO ``G = (b1 z^{n-nk} + ..) / (z^n + a1 z^{n-1} + ..)`` gives
        exactly ``a_ = [a1, ..]``, ``b_ = [b1, ..]`` and that ``nk``.

        Parameters
        ----------
        G : control.TransferFunction or control.StateSpace
            A proper discrete-time system (``dt`` True or a number).

        Returns
        -------
        ARX
            A model usable as if fitted, with ``dt = G.dt``.

        Raises
        ------
        TypeError
            If `G` is not a python-control LTI system.
        ValueError
            If `G` is continuous-time, improper, or has a zero input column.

        Examples
        --------
        A continuous plant sampled with a zero-order hold is ``ARX(2, 2, 1)``:

        >>> import control
        >>> from rlsfilt import ARX
        >>> Gd = control.sample_system(control.tf([1.0], [1.0, 3.0, 2.0]), 0.1)
        >>> model = ARX.from_tf(Gd)
        >>> model.na, model.nb, model.nk
        (2, 2, 1)
        """
        import control

        if not isinstance(G, control.LTI):
            raise TypeError(f"`G` must be a discrete python-control LTI system (control.tf, "
                            f"control.ss); got {type(G).__name__}")
        if not isinstance(G, control.TransferFunction):
            G = control.tf(G)
        if not G.isdtime(strict=True):
            raise ValueError(f"`G` must be a discrete-time transfer function; got dt={G.dt!r}")
        ny, nu = G.noutputs, G.ninputs
        A_rows, B_rows = [], []
        for i in range(ny):
            # each entry in powers of q^-1: den_q = [1, a1, ..] (trailing zeros, i.e. poles
            # at z = 0, dropped), num_q = numerator shifted by the relative degree
            ents = []
            for j in range(nu):
                den = np.trim_zeros(np.asarray(G.den[i][j], float), "f")
                num = np.trim_zeros(np.asarray(G.num[i][j], float), "f")
                if len(num) > len(den):
                    raise ValueError(f"`G` must be proper (causal); entry ({i}, {j}) has a "
                                     f"numerator of degree {len(num) - 1} over a denominator "
                                     f"of degree {len(den) - 1}")
                num_q = np.concatenate([np.zeros(len(den) - len(num)), num]) / den[0]
                ents.append((num_q if len(num) else np.zeros(1), _trim(den / den[0])))
            common = []  # distinct denominators of the row; their product is A_i
            for _, d in ents:
                if not any(_same_poly(c, d) for c in common):
                    common.append(d)
            den = np.array([1.0])
            for c in common:
                den = np.convolve(den, c)
            row = []
            for num, d in ents:
                for c in common:
                    if not _same_poly(c, d):
                        num = np.convolve(num, c)
                row.append(_trim(num))
            A_rows.append(_trim(den))
            B_rows.append(row)
        na = max(len(a) for a in A_rows) - 1
        nk, nb = [], []
        for j in range(nu):
            cols = [B_rows[i][j] for i in range(ny)]
            nz = [np.flatnonzero(c) for c in cols]
            if not any(len(z) for z in nz):
                raise ValueError(f"`G` has a zero transfer function from input {j}; an ARX "
                                 "model needs nb >= 1 nonzero input coefficient per input")
            first = min(z[0] for z in nz if len(z))
            last = max(z[-1] for z in nz if len(z))
            nk.append(int(first))
            nb.append(int(last - first + 1))
        s = arx_structure(na, nb, nk, nu, ny)
        theta = np.zeros((s.n_params, ny))
        _, b_sls = s.param_slices()
        for i in range(ny):
            a = A_rows[i][1:]
            theta[i * na:i * na + len(a), i] = a
            for j in range(nu):
                c = np.concatenate([B_rows[i][j], np.zeros(nk[j] + nb[j])])
                theta[b_sls[j], i] = c[nk[j]:nk[j] + nb[j]]
        model = cls(na=na, nb=nb[0] if nu == 1 else nb, nk=nk[0] if nu == 1 else nk, dt=G.dt)
        info = {"u_1d": nu == 1, "y_1d": ny == 1, "u_names": None, "y_names": None}
        model._set_truth(theta, s, info, 0.0)
        return model

    def _set_truth(self, theta, s, info, noise_variance):
        self._store(theta, s, info)
        ny = s.n_outputs
        nv = np.broadcast_to(np.asarray(noise_variance, float), (ny,)).copy()
        zero = np.zeros((ny, s.n_params, s.n_params))
        self.theta_cov_ = zero[0] if info["y_1d"] else zero
        self.noise_variance_ = float(nv[0]) if info["y_1d"] else nv
        self.n_samples_ = 0
        self.method_ = "true"

    # ------------------------------------------------------------------
    # display
    # ------------------------------------------------------------------
    def _orders_text(self):
        return f"ARX(na={self.na!r}, nb={self.nb!r}, nk={self.nk!r}, dt={self.dt!r})"

    def summary(self):
        """A printable and notebook-friendly summary: equations with +- one standard error.

        Returns
        -------
        ARXSummary
            ``print`` it for text (with a parameter table), or display it in
            a notebook for HTML.
        """
        self._check_fitted("summary")
        return ARXSummary(self)

    def _equation_lines(self, style="text"):
        """The difference equation of each output with +- one standard error.

        `style` is ``"text"``, ``"html"`` (names escaped, ``&plusmn;``) or
        ``"latex"`` (an ``aligned`` row per output).
        """
        s = self.structure_
        se = self.std_errors_.reshape(self.n_params_, -1)
        th = self._theta2()
        _, b_sls = s.param_slices()
        fmt = _EQUATION_STYLES[style]
        lines = []
        for i in range(s.n_outputs):
            lhs = [fmt["signal"](self._y_name(i), 0)]
            lhs += [fmt["term"](th[p, i], se[p, i], fmt["signal"](self._y_name(j), k))
                    for j in range(s.n_outputs) for k in range(1, s.na + 1)
                    for p in [j * s.na + k - 1]]
            rhs = [fmt["term"](th[p, i], se[p, i], fmt["signal"](self._u_name(j), s.nk[j] + m))
                   for j in range(s.n_inputs) for m in range(s.nb[j])
                   for p in [b_sls[j].start + m]]
            # nb >= 1, so rhs is never empty; its first term carries its sign unspaced
            first = rhs[0][2:] if rhs[0].startswith("+ ") else "-" + rhs[0][2:]
            lines.append(" ".join(lhs) + fmt["equals"] + " ".join([first] + rhs[1:]) + " + e(t)")
        return lines

    def _summary_text(self):
        s = self.structure_
        how = {"ls": "batch least squares (QR)", "rls": "recursive least squares",
               "true": "given coefficients (no fit)"}[self.method_]
        if self.method_ == "rls":
            f = self.filter_
            start = (f"batch start on {self.k0_} rows" if self.k0_ else "prior start")
            how += f" (lam={f.lam:g}, {start})"
        out = [f"{self._orders_text()}: {s.n_inputs} input(s), {s.n_outputs} output(s), "
               f"{s.n_params} parameters per output",
               f"  estimated by {how} on {self.n_samples_} equations"]
        nv = np.atleast_1d(self.noise_variance_)
        out.append("  noise variance (unbiased): " + ", ".join(f"{v:.4g}" for v in nv))
        out.append("  difference equation (estimate +/- 1 standard error):")
        out += ["    " + line for line in self._equation_lines()]
        return "\n".join(out)

    def __repr__(self):
        if "theta_" not in self.__dict__:
            return self._orders_text()
        return self._summary_text()

    def _repr_latex_(self):
        """The difference equation(s) with one standard error, for notebooks."""
        if "theta_" not in self.__dict__:
            return None
        lines = self._equation_lines("latex")
        return "$$\\begin{aligned}" + " \\\\ ".join(lines) + "\\end{aligned}$$"

    def _repr_html_(self):
        if "theta_" not in self.__dict__:
            return f"<pre>{html.escape(self._orders_text())}</pre>"
        return ARXSummary(self)._repr_html_()

    def fit_many(self, u, y, method="ls", **options):
        """Fit these orders to every channel of a fleet: :func:`rlsfilt.models.fit_many`."""
        from .fleet import fit_many

        return fit_many(self, u, y, method, **options)


class ARXSummary:
    """Summary of a fitted `ARX`: ``print`` it, or display it in a notebook.

    Attributes
    ----------
    model : ARX
        The summarized model.
    """

    def __init__(self, model):
        self.model = model

    def as_text(self):
        """The summary as plain text, with a parameter table."""
        m = self.model
        names = m.param_names_
        th = m._theta2()
        se = m.std_errors_.reshape(m.n_params_, -1)
        lines = [m._summary_text(), ""]
        for i in range(m.n_outputs_):
            if m.n_outputs_ > 1:
                lines.append(f"  output {m._y_name(i)}")
            lines.append(f"  {'param':>12} {'estimate':>13} {'std err':>11} {'t':>9}")
            for p, name in enumerate(names):
                tval = th[p, i] / se[p, i] if se[p, i] > 0 else np.nan
                lines.append(f"  {name:>12} {th[p, i]:13.6g} {se[p, i]:11.4g} {tval:9.3g}")
        return "\n".join(lines)

    def __str__(self):
        return self.as_text()

    def __repr__(self):
        return self.as_text()

    def _repr_html_(self):
        m = self.model
        names = m.param_names_
        th = m._theta2()
        se = m.std_errors_.reshape(m.n_params_, -1)
        esc = html.escape
        parts = [f"<p><b>{esc(m._orders_text())}</b>, {m.n_samples_} equations, noise "
                 "variance " + ", ".join(f"{v:.4g}" for v in np.atleast_1d(m.noise_variance_))
                 + "</p>"]
        parts += [f"<p><code>{line}</code></p>" for line in m._equation_lines("html")]
        head = "".join(f"<th>{esc(m._y_name(i))} estimate</th><th>std err</th>"
                       for i in range(m.n_outputs_))
        rows = []
        for p, name in enumerate(names):
            cells = "".join(f"<td>{th[p, i]:.6g}</td><td>{se[p, i]:.4g}</td>"
                            for i in range(m.n_outputs_))
            rows.append(f"<tr><td>{esc(name)}</td>{cells}</tr>")
        parts.append(f"<table><tr><th>param</th>{head}</tr>{''.join(rows)}</table>")
        return "".join(parts)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _check_filter_options(options):
    """Reject keywords that `RecursiveLeastSquares` does not take, naming the valid ones."""
    if not options:
        return
    params = inspect.signature(RecursiveLeastSquares).parameters
    valid = [name for name, p in params.items()
             if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
             and name not in ("dim_x", "dim_z", "lam", "P0", "x0", "R", "Q")]
    for name in options:
        if name not in valid:
            raise TypeError(f"`{name}` is not an option of ARX.fit or RecursiveLeastSquares; "
                            f"the filter's other options are {valid}")


def _latex_name(name):
    """``y1`` -> ``y_{1}``; other names in \\mathrm."""
    if len(name) > 1 and name[0] in "uy" and name[1:].isdigit():
        return f"{name[0]}_{{{name[1:]}}}"
    if len(name) == 1:
        return name
    special = {c: "\\" + c for c in "&%$#_{}"}
    special.update({"~": "\\textasciitilde{}", "^": "\\textasciicircum{}",
                    "\\": "\\textbackslash{}"})
    return "\\mathrm{" + "".join(special.get(c, c) for c in name) + "}"


def _fmt(t):
    return t[0] if len(set(t)) == 1 and len(t) == 1 else list(t)


def _signal(name, lag):
    return f"{name}(t)" if lag == 0 else f"{name}(t-{lag})"


def _sign(value):
    return "-" if value < 0 else "+"


_EQUATION_STYLES = {
    "text": {"signal": _signal, "equals": " = ",
             "term": lambda v, e, arg: f"{_sign(v)} {abs(v):.5g} (+/-{e:.2g}) {arg}"},
    "html": {"signal": lambda name, lag: _signal(html.escape(name), lag), "equals": " = ",
             "term": lambda v, e, arg: f"{_sign(v)} {abs(v):.5g} (&plusmn;{e:.2g}) {arg}"},
    "latex": {"signal": lambda name, lag: _signal(_latex_name(name), lag), "equals": " &= ",
              "term": lambda v, e, arg: f"{_sign(v)} {abs(v):.5g}\\,(\\pm {e:.2g})\\, {arg}"},
}


def _qr_least_squares(Phi, target):
    """``theta`` (n, ny) and ``(Phi^T Phi)^-1`` from a QR factorization of ``Phi``."""
    n = Phi.shape[1]
    rank = _column_rank(Phi)
    if rank < n:
        raise ValueError(
            f"the regressor matrix has rank {rank} < n_params = {n}: the input is not "
            "persistently exciting for these orders (or the orders are too high); use a richer "
            "input, more data or lower orders")
    Qf, Rf = np.linalg.qr(Phi)
    c = Qf.T @ target
    # back substitution one column at a time, and the triangular inverse from
    # LAPACK's trtri: multi-column triangular solves hit a slow threaded BLAS
    # path for tiny matrices on loaded machines (measured: 2-10 ms per call)
    theta = np.column_stack([solve_triangular(Rf, c[:, i]) for i in range(c.shape[1])])
    Rinv, info = lapack.dtrtri(Rf, lower=0)
    cov = Rinv @ Rinv.T
    return theta, 0.5 * (cov + cov.T)


def _same_poly(p, q):
    """Equal coefficient arrays to round-off (same length)."""
    return len(p) == len(q) and np.allclose(p, q, rtol=1e-12, atol=0)


def _trim(p):
    """Drop trailing zeros of a polynomial in ``q^-1`` (keep at least one coefficient)."""
    p = np.asarray(p, dtype=float)
    nz = np.flatnonzero(p)
    return p[:nz[-1] + 1].copy() if len(nz) else np.zeros(1)


def _padd(p, q):
    n = max(len(p), len(q))
    out = np.zeros(n)
    out[:len(p)] += p
    out[:len(q)] += q
    return out


def _equalize(num, den):
    """Zero-pad two ``q^-1`` polynomials to equal length, then cancel common ``q^-1`` factors.

    Equal length makes the coefficient arrays valid in positive powers of
    ``z`` as they stand (both are multiplied by the same ``z^L``).
    """
    n = max(len(num), len(den))
    num = np.concatenate([num, np.zeros(n - len(num))])
    den = np.concatenate([den, np.zeros(n - len(den))])
    while n > 1 and num[-1] == 0.0 and den[-1] == 0.0:
        num, den, n = num[:-1], den[:-1], n - 1
    return num, den


def _poly_det(M):
    """Determinant of a square matrix of ``q^-1`` polynomials (cofactor expansion)."""
    n = len(M)
    if n == 1:
        return M[0][0]
    det = np.zeros(1)
    for j in range(n):
        minor = [row[:j] + row[j + 1:] for row in M[1:]]
        term = np.convolve(M[0][j], _poly_det(minor))
        det = _padd(det, term if j % 2 == 0 else -term)
    return det


def _poly_adj(M):
    """Adjugate of a square matrix of polynomials: ``adj(M) M = det(M) I``."""
    n = len(M)
    if n == 1:
        return [[np.array([1.0])]]
    adj = [[None] * n for _ in range(n)]
    for i in range(n):
        for j in range(n):
            minor = [row[:j] + row[j + 1:] for k, row in enumerate(M) if k != i]
            c = _poly_det(minor)
            adj[j][i] = c if (i + j) % 2 == 0 else -c
    return adj
