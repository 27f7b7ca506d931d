r"""The estimator shared by ARMAX, OE, BJ, AR and ARMA.

`PolynomialModel` implements the :class:`~rlsfilt.models.IdentifiedModel`
interface once for the general family

.. math::

    A(q)\, y(t) = \sum_i \frac{B_i(q)}{F_i(q)} u_i(t) + \frac{C(q)}{D(q)} e(t)

(one output, any number of inputs); each named model only chooses which
orders it estimates. Fitting is a thin call to the core modules:
``method="pem"`` to :func:`rlsfilt.models._pem.pem`, ``"rpem"`` and
``"rplr"`` to :func:`rlsfilt.models._recursive_pem.recursive_pem`.
"""

import html
import numbers

import numpy as np

from .._lazy_scipy import lfilter, lfiltic
from .._validation import check_int
from ._base import IdentifiedModel, Polynomials
from ._family import param_names, split_theta
from ._offset import warn_fit_operating_point
from ._pem import (
    _shift,
    criterion_rows,
    pem_records,
    prediction_error_parts,
    stacked_errors,
)
from ._recursive_pem import RecursionState, recursive_pem_records
from ._units import RecordUnits, equivariant_forgetting
from .regressors import _as_signal, as_records, check_input_rank, is_listed

__all__ = []

#: Options of the batch and recursive fits (anything else is a TypeError).
PEM_OPTIONS = ("theta0", "init_model", "ftol", "xtol", "gtol", "max_nfev", "n_starts", "rng",
               "progress", "max_time")
RECURSIVE_OPTIONS = ("lam", "lam_start", "lam_rate", "P0", "x0", "R", "Q", "forgetting",
                     "forgetting_params", "gate", "project", "check_every", "cond_max")
METHODS = ("pem", "rpem", "rplr")
_RECURSIVE_ONLY = "fit(..., method='rpem' or 'rplr')"


class PolynomialModel(IdentifiedModel):
    """Base of the models of the general polynomial family (see the module notes).

    A subclass stores its orders in ``__init__`` and implements
    ``_family(n_inputs)``, returning the validated
    :class:`~rlsfilt.models._family.FamilyStructure`; ``_ORDERS`` lists the
    orders it reports in :attr:`orders_` and ``_EQUATION`` its equation.
    """

    _ORDERS = ()
    _EQUATION = ""
    _TIME_SERIES = False
    _ONLY_SET_BY = {"theta_history_": _RECURSIVE_ONLY, "recursive_residuals_": _RECURSIVE_ONLY,
                    "state_": _RECURSIVE_ONLY, "margins_": "fit(..., method='rplr')",
                    "fit_info_": "fit(..., method='pem')"}

    def _family(self, n_inputs):
        raise NotImplementedError

    # ------------------------------------------------------------------
    # fitting
    # ------------------------------------------------------------------
    def _fit(self, records, info, method, options, stacklevel=2):
        """Validate, estimate, then assign every learned attribute (atomic).

        `records` is ``[(U (N_i, nu), y (N_i,)), ...]``, one per experiment:
        the batch criterion sums over them (each predictor from rest), the
        recursions restart their signals at each boundary.
        """
        if method not in METHODS:
            raise ValueError(f"`method` must be one of 'pem', 'rpem', 'rplr'; got {method!r}")
        allowed = PEM_OPTIONS if method == "pem" else RECURSIVE_OPTIONS
        for key in options:
            if key not in allowed:
                other = "'rpem'/'rplr'" if key in RECURSIVE_OPTIONS else "'pem'"
                if key in PEM_OPTIONS + RECURSIVE_OPTIONS:
                    raise TypeError(f"`{key}` only applies to method={other}; got "
                                    f"method={method!r}")
                raise TypeError(f"`{key}` is not an option of {type(self).__name__}.fit; the "
                                f"options of method={method!r} are {list(allowed)}")
        self._check_dt()
        s = self._family(records[0][0].shape[1])
        N = sum(len(y) for _, y in records)
        rows = criterion_rows(s, records)
        if rows <= s.n_params:
            per = (f" in each of {len(records)} experiments, or more in all"
                   if len(records) > 1 else "")
            raise ValueError(f"`y` must have more than t0 + n_params = {s.t0} + {s.n_params} = "
                             f"{s.t0 + s.n_params} samples{per} for {self._orders_text()}; got "
                             f"{N}")
        check_input_rank(records, s.nb, s.nk, s.t0)     # collinear inputs: as ARMAX, ARX
        warn_fit_operating_point(self, records, (info.get("u_names"), info.get("y_names")),
                                 stacklevel)

        learned = {"method_": method}
        if method == "pem":
            theta0 = _start_option(self, s, options)
            tol = {k: options[k] for k in PEM_OPTIONS[2:] if k in options}
            # the starts, the rank check and the search run in scaled units (`RecordUnits`);
            # the fit comes back in the units of the records
            fit = pem_records(records, s, theta0, stacklevel=stacklevel + 1, **tol)
            theta, cov, sigma2, eps = fit.theta, fit.cov, fit.noise_variance, fit.residuals
            learned["fit_info_"] = {
                "cost": fit.cost, "n_fev": fit.n_fev, "n_jev": fit.n_jev, "n_iter": fit.n_iter,
                "status": fit.status, "message": fit.message, "converged": fit.converged,
                "theta0": fit.theta0, "start": fit.start, "start_costs": fit.start_costs,
                "n_starts": fit.n_starts, "max_root": fit.max_root, "arx_cost": fit.arx_cost,
                "warnings": fit.warnings}
        else:
            fit, units, P, R = _recursive_fit(records, s, method, dict(options), stacklevel + 1)
            theta = units.estimate_from_unit(fit.theta)
            # residuals, noise variance and covariance from the fit in its units (sums of
            # squares in range), then mapped
            eps = stacked_errors(fit.theta, s, units.scale_records(records))
            sigma2_unit = float(eps @ eps) / (rows - s.n_params)
            sigma2 = units.output_from_unit(sigma2_unit, 2)
            eps = units.output_from_unit(eps)
            cov = units.cov_from_unit(sigma2_unit * P / R)
            cov = 0.5 * (cov + cov.T)
            learned.update(theta_history_=units.theta_from_unit(fit.theta_history),
                           recursive_residuals_=units.output_from_unit(fit.eps),
                           state_=fit.state)
            if method == "rplr":
                learned["margins_"] = fit.margins
        learned.update(theta_=theta.copy(), theta_cov_=cov, noise_variance_=float(sigma2),
                       residuals_=eps, n_samples_=rows, n_params_=s.n_params,
                       n_inputs_=s.n_inputs, n_outputs_=1, structure_=s,
                       n_experiments_=len(records), _info=dict(info))
        u_names = info.get("u_names") or ([("u" if info.get("u_1d", True) else f"u{j + 1}")
                                           for j in range(s.n_inputs)])
        learned.update(input_names_=tuple(u_names[:s.n_inputs]),
                       output_names_=tuple(info.get("y_names") or ("y",)),
                       input_units_=tuple(info.get("u_units") or ("",) * s.n_inputs),
                       output_units_=tuple(info.get("y_units") or ("",)))
        for name in ("theta_history_", "recursive_residuals_", "state_", "margins_",
                     "fit_info_", "trend_"):
            self.__dict__.pop(name, None)
        self.__dict__.update(learned)
        self._set_polynomials()
        return self

    def _restore_fitted(self, fitted):
        """Rebuild a saved model (:func:`rlsfilt.load_model`): attributes and derived state."""
        missing = [k for k in ("theta_", "structure_", "input_names_", "output_names_")
                   if k not in fitted]
        if missing:
            raise ValueError(f"the saved {type(self).__name__} model lacks its learned "
                             f"attributes {missing}; was it written by save()?")
        s = fitted["structure_"]
        n = s.n_inputs
        u_1d = n == 0 or (n == 1 and not isinstance(fitted.get("b_"), list))
        u_names, y_names = list(fitted["input_names_"]), list(fitted["output_names_"])
        default_u = ["u"] if u_1d else [f"u{j + 1}" for j in range(n)]
        info = {"u_1d": u_1d, "y_1d": True,
                "u_names": None if u_names in (default_u, []) else u_names,
                "y_names": None if y_names == ["y"] else y_names,
                "u_units": list(fitted.get("input_units_", [""] * n)),
                "y_units": list(fitted.get("output_units_", [""]))}
        for key, value in fitted.items():
            setattr(self, key, value)
        self.theta_ = np.asarray(fitted["theta_"], dtype=float)
        self._info = info
        self._set_polynomials()

    def _set_polynomials(self):
        A, B, C, D, F = split_theta(self.theta_, self.structure_)
        s, u_1d = self.structure_, self._info.get("u_1d", True)
        self.a_, self.c_, self.d_ = A[1:].copy(), C[1:].copy(), D[1:].copy()
        b = [B[i][s.nk[i]:].copy() for i in range(s.n_inputs)]
        f = [F[i][1:].copy() for i in range(s.n_inputs)]
        one = s.n_inputs == 1 and u_1d
        self.b_ = b[0] if one else b
        self.f_ = f[0] if one else f

    # ------------------------------------------------------------------
    # the IdentifiedModel interface
    # ------------------------------------------------------------------
    @property
    def max_lag(self):
        """``t0 = max(na, nk + nb - 1)``: the first sample of the criterion; needs a fit."""
        self._check_fitted("max_lag")
        return self.structure_.t0

    @property
    def param_names_(self):
        """Names of the entries of ``theta_`` (``a1``, ``b1``, ``c1``, ``d1``, ``f1[u2]`` ...)."""
        self._check_fitted("param_names_")
        s = self.structure_
        names = [self._u_name(j) for j in range(s.n_inputs)] if s.n_inputs > 1 else None
        return param_names(s, names)

    @property
    def orders_(self):
        """The fitted orders (those of ``na``, ``nb``, ``nc``, ``nd``, ``nf``, ``nk`` the model
        has)."""
        self._check_fitted("orders_")
        s = self.structure_
        return {k: getattr(s, k) for k in self._ORDERS}

    def polydata(self, theta=None):
        """The model as MATLAB's polynomials ``A, B, C, D, F`` (`Polynomials`).

        Parameters
        ----------
        theta : array_like, shape (n_params,), optional
            Parameters in ``theta_`` order (``theta_`` by default).

        Returns
        -------
        Polynomials
            ``A`` (1, 1, na + 1), ``B`` (1, nu, max(nk + nb)) with ``nk``
            leading zeros, ``C`` (1, nc + 1), ``D`` (1, nd + 1), ``F``
            (1, nu, max(nf) + 1), zero-padded.
        """
        self._check_fitted("polydata")
        s = self.structure_
        theta = self.theta_ if theta is None else np.asarray(theta, dtype=float).reshape(-1)
        if theta.size != s.n_params:
            raise ValueError(f"`theta` must have the shape of `theta_` ({s.n_params},); got "
                             f"{np.shape(theta)}")
        A, B, C, D, F = split_theta(theta, s)
        nu = s.n_inputs
        lb = max([1] + [len(b) for b in B])
        lf = max([1] + [len(f) for f in F])
        Bp = np.zeros((1, nu, lb))
        Fp = np.zeros((1, nu, lf))
        for i in range(nu):
            Bp[0, i, :len(B[i])] = B[i]
            Fp[0, i, :len(F[i])] = F[i]
        return Polynomials(A=A.reshape(1, 1, -1), B=Bp, C=C.reshape(1, -1), D=D.reshape(1, -1),
                           F=Fp)

    def _signals(self, u, y):
        """Validated ``U (N, nu)`` and ``y (N,)`` against the fitted signals."""
        U, Y = self._data(u, y)
        return U, Y[:, 0]

    def regressors(self, u, y=None):
        r"""The pseudo-linear regressors of the one-step predictor, computed with ``theta_``.

        .. math::

            \varphi(t) = [-y(t-k)]_{k \le n_a},\ [u_i(t - n_{k,i} - k)]_{k < n_{b,i}},\
                         [\varepsilon(t-k)]_{k \le n_c},\ [-v(t-k)]_{k \le n_d},\
                         [-w_i(t-k)]_{k \le n_{f,i}}

        with :math:`w_i = B_i/F_i\, u_i`, :math:`v = A y - \sum_i w_i`,
        :math:`\varepsilon = D/C\, v` (all from rest), so that
        ``predict(u, y)[max_lag:] == Phi @ theta_`` (Ljung 1999, sec. 4.2).

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu), or IOData
            Input record, or an `IOData` (then `y` is omitted; several
            experiments give their rows one after the other).
        y : array_like, shape (N,)

        Returns
        -------
        Phi : ndarray, shape (N - max_lag, n_params)
        target : ndarray, shape (N - max_lag,)
        """
        self._check_fitted("regressors")
        out = self._each_experiment(self._regressors, u, y)
        if isinstance(out, list):
            return np.vstack([o[0] for o in out]), np.concatenate([o[1] for o in out])
        return out

    def _regressors(self, u, y):
        U, y = self._signals(u, y)
        s = self.structure_
        eps, v, w = prediction_error_parts(self.theta_, s, U, y)
        cols = [-_shift(y, k) for k in range(1, s.na + 1)]
        for i in range(s.n_inputs):
            cols += [_shift(U[:, i], s.nk[i] + k) for k in range(s.nb[i])]
        cols += [_shift(eps, k) for k in range(1, s.nc + 1)]
        cols += [-_shift(v, k) for k in range(1, s.nd + 1)]
        for i in range(s.n_inputs):
            cols += [-_shift(w[i], k) for k in range(1, s.nf[i] + 1)]
        Phi = np.column_stack(cols)[s.t0:]
        return Phi, y[s.t0:].copy()

    def predict(self, u, y=None, horizon=1):
        r"""``horizon``-step-ahead prediction (MATLAB ``predict``).

        With :math:`G = B/(A F)`, :math:`H = C/(A D)` and the one-step
        prediction errors :math:`\varepsilon = H^{-1}(y - G u)`, the
        ``k``-step predictor is (Ljung 1999, ch. 3)

        .. math::

            \hat y(t \mid t-k) = y(t) - \bar H_k(q)\, \varepsilon(t),
            \qquad \bar H_k(q) = \sum_{i=0}^{k-1} h_i q^{-i},

        with :math:`h_i` the impulse response of :math:`H`. Signals before
        ``t = 0`` are zero. ``k = 1`` is :math:`y - \varepsilon`; a horizon
        ``>= N`` (or ``np.inf``) is :meth:`simulate`.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
        y : array_like, shape (N,)
        horizon : int or np.inf, default 1

        Returns
        -------
        yhat : ndarray, shape (N,)
        """
        self._check_fitted("predict")
        return self._each_experiment(self._predict, u, y, horizon)

    def _predict(self, u, y, horizon):
        U, yv = self._signals(u, y)
        N = len(yv)
        if self._horizon_is_inf(horizon):
            horizon = max(N, 1)
        horizon = check_int(horizon, "horizon", minimum=1)
        if horizon >= N:
            return self.simulate(U if not self._info.get("u_1d", True) else U[:, 0]) \
                if not self._TIME_SERIES else np.zeros(N)
        eps = prediction_error_parts(self.theta_, self.structure_, U, yv)[0]
        if horizon == 1:
            return yv - eps
        A, _, C, D, _ = split_theta(self.theta_, self.structure_)
        impulse = np.zeros(horizon)
        impulse[0] = 1.0
        h = lfilter(C, np.convolve(A, D), impulse)          # h_0 .. h_{k-1} of H = C/(A D)
        return yv - np.convolve(eps, h)[:N]

    def simulate(self, u, y0=None):
        r"""Free-run simulation ``sum_i B_i/(A F_i) u_i`` (MATLAB ``sim``).

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu)
            Input record; inputs before ``t = 0`` are zero.
        y0 : array_like, shape (L,), optional
            Known outputs ``y(0) .. y(L-1)``; the simulation continues from
            ``t = L`` with the equivalent difference equation
            :math:`A \prod_i F_i\, y = \sum_i B_i \prod_{l \ne i} F_l\, u_i`
            (earlier outputs zero). By default everything before ``t = 0``
            is zero and the result equals ``scipy.signal.lfilter`` of the
            entries of :meth:`to_tf`.

        Returns
        -------
        y_sim : ndarray, shape (N,)
        """
        self._check_fitted("simulate")
        return self._each_experiment(lambda uu, y0_: self._simulate(self._data(uu)[0], y0_), u,
                                     None, y0, outputs=False)

    def _simulate(self, U, y0):
        N = len(U)
        A, B, _, _, F = split_theta(self.theta_, self.structure_)
        nu = U.shape[1]
        if y0 is None:
            out = np.zeros(N)
            for i in range(nu):
                out += lfilter(B[i], np.convolve(A, F[i]), U[:, i])
            return out
        Y0, _, _ = _as_signal(y0, "y0")
        if Y0.shape[1] != 1:
            raise ValueError(f"`y0` must have 1 output column; got {Y0.shape[1]}")
        L = len(Y0)
        if L > N:
            raise ValueError(f"`y0` must have at most N = {N} samples; got {L}")
        a_t = A
        for f in F:
            a_t = np.convolve(a_t, f)
        x = np.zeros(N)
        for i in range(nu):
            b_t = B[i]
            for j in range(nu):
                if j != i:
                    b_t = np.convolve(b_t, F[j])
            x += lfilter(b_t, [1.0], U[:, i])
        out = np.zeros(N)
        out[:L] = Y0[:, 0]
        if L < N:
            n_a = len(a_t) - 1
            past = out[max(L - n_a, 0):L][::-1]
            zi = lfiltic([1.0], a_t, past) if n_a else None
            out[L:] = x[L:] if zi is None else lfilter([1.0], a_t, x[L:], zi=zi)[0]
        return out

    # ------------------------------------------------------------------
    # display
    # ------------------------------------------------------------------
    def _poly_text(self, name, p, lag0=0, style="text"):
        terms = []
        for k, c in enumerate(p):
            if c == 0.0 and k > 0:
                continue
            power = k + lag0
            q = "" if power == 0 else (f" q^-{power}" if style == "text"
                                        else f" q<sup>-{power}</sup>")
            mag = f"{abs(c):.5g}"
            sign = "-" if c < 0 else "+"
            terms.append((sign, mag + q))
        if not terms:
            return f"{name}(q) = 0"
        first_sign, first = terms[0]
        text = ("-" if first_sign == "-" else "") + first
        text += "".join(f" {sg} {t}" for sg, t in terms[1:])
        return f"{name}(q) = {text}"

    def _summary_lines(self, style="text"):
        s = self.structure_
        A, B, C, D, F = split_theta(self.theta_, s)
        how = {"pem": "prediction-error minimization (batch)",
               "rpem": "recursive prediction-error method (RPEM)",
               "rplr": "recursive pseudo-linear regression (RPLR)"}[self.method_]
        polys = []
        if s.na:
            polys.append(self._poly_text("A", A, style=style))
        for i in range(s.n_inputs):
            tag = "" if s.n_inputs == 1 else f"_{i + 1}"
            polys.append(self._poly_text("B" + tag, B[i][s.nk[i]:], s.nk[i], style))
        if s.nc:
            polys.append(self._poly_text("C", C, style=style))
        if s.nd:
            polys.append(self._poly_text("D", D, style=style))
        for i in range(s.n_inputs):
            if s.nf[i]:
                tag = "" if s.n_inputs == 1 else f"_{i + 1}"
                polys.append(self._poly_text("F" + tag, F[i], style=style))
        nv = f"{self.noise_variance_:.4g}"
        n_exp = self.__dict__.get("n_experiments_", 1)
        exps = f" of {n_exp} experiments" if n_exp > 1 else ""
        if style == "html":
            esc = html.escape
            return ([f"<p><b>{esc(self._orders_text())}</b>: {esc(self._EQUATION)}, estimated "
                     f"by {esc(how)} on {self.n_samples_} prediction errors{exps}, noise "
                     f"variance "
                     f"{nv}</p>"]
                    + [f"<p><code>{line}</code></p>" for line in polys])
        return ([f"{self._orders_text()}: {self._EQUATION}",
                 f"  estimated by {how} on {self.n_samples_} prediction errors{exps}",
                 f"  noise variance: {nv}"] + ["  " + line for line in polys])


class TimeSeriesModel(PolynomialModel):
    """`PolynomialModel` without inputs (AR, ARMA): ``fit(y)``; ``u`` is None.

    The methods of the interface keep their ``(u, y)`` signature; pass
    ``u=None`` (or an array of shape ``(N, 0)``). :meth:`simulate` of a
    time series is zero (there is no input); give ``u`` as the number of
    samples or an ``(N, 0)`` array. The input model does not exist:
    :meth:`to_tf` and the other conversions need ``noise=True``.
    """

    _TIME_SERIES = True

    def fit(self, y, method="pem", **options):
        """Estimate the parameters from a time series.

        Parameters
        ----------
        y : array_like, shape (N,), or a list of them
            The signal (pandas Series works too); a list holds several
            experiments (records of the same process): the criterion sums
            over them, each predictor started from rest, and the recursions
            restart their signals at each boundary.
        method : {"pem", "rpem", "rplr"}, default "pem"
            As for the input/output models.
        **options
            Of the method (see :meth:`ARMAX.fit`).

        Returns
        -------
        self
        """
        listed = is_listed(y)
        records, y_names = [], None
        for i, yi in enumerate(y if listed else [y]):
            label = f"y[{i}]" if listed else "y"
            Y, _, names = _as_signal(yi, label)
            if Y.shape[1] != 1:
                raise ValueError(f"`{label}` must have shape (N,) (one signal); got "
                                 f"{np.shape(yi)}")
            records.append((np.zeros((len(Y), 0)), Y[:, 0]))
            y_names = y_names or names
        info = {"u_1d": True, "y_1d": True, "u_names": None, "y_names": y_names}
        return self._fit(records, info, method, options, stacklevel=3)

    def _each_experiment(self, fn, u, y, *args, outputs=True):
        """As `IdentifiedModel._each_experiment`, and a list of series `y` (one per
        experiment; `u` None) gives one result per experiment."""
        if outputs and is_listed(y):
            if u is not None:
                raise ValueError(f"`u` must be None for the time-series model "
                                 f"{type(self).__name__}; got {type(u).__name__}")
            outs = [fn(None, yi, *args) for yi in y]
            return outs[0] if len(outs) == 1 else outs
        return super()._each_experiment(fn, u, y, *args, outputs=outputs)

    def _data(self, u, y=None):
        if y is not None:
            Y, _, _ = _as_signal(y, "y")
            if Y.shape[1] != 1:
                raise ValueError(f"`y` must have 1 output column as in `fit`; got {Y.shape[1]}")
            N = len(Y)
        else:
            Y = None
            N = None
        if u is None:
            if N is None:
                raise ValueError("`u` must give the number of samples of a time-series "
                                 "simulation (an int or an (N, 0) array); got None")
        elif isinstance(u, numbers.Integral) and not isinstance(u, bool):
            N = check_int(u, "u", minimum=0) if N is None else N
        else:
            arr = np.asarray(u, dtype=float)
            if arr.ndim != 2 or arr.shape[1] != 0:
                raise ValueError(f"`u` must have 0 input column(s) as in `fit` (a time series: "
                                 f"pass None); got shape {arr.shape}")
            if N is not None and len(arr) != N:
                raise ValueError(f"`u` and `y` must have the same length; got {len(arr)} and "
                                 f"{N}")
            N = len(arr)
        return np.zeros((N, 0)), Y

    def _no_input_model(self, noise, what):
        if not noise:
            raise ValueError(f"{type(self).__name__} is a time-series model: it has no input "
                             f"model; use {what}(noise=True) for the noise model C/(A D)")

    def to_tf(self, noise=True, **options):
        """The noise model ``C/(A D)`` as a ``control.TransferFunction`` (see
        :meth:`IdentifiedModel.to_tf`); ``noise`` must be True."""
        self._check_fitted("to_tf")
        self._no_input_model(noise, "to_tf")
        return super().to_tf(noise=True, **options)

    def poles(self, noise=True):
        """Poles of the noise model (the zeros of ``A D``); ``noise`` must be True."""
        self._check_fitted("poles")
        self._no_input_model(noise, "poles")
        return super().poles(noise=True)

    def dc_gain(self):
        """NaN: a time series has no input model (the static gain is undefined)."""
        self._check_fitted("dc_gain")
        return float("nan")

    def to_ss(self, noise=True):
        """The noise model as a ``control.StateSpace``; ``noise`` must be True."""
        self._check_fitted("to_ss")
        self._no_input_model(noise, "to_ss")
        return super().to_ss(noise=True)

    def to_dlti(self, noise=True):
        """The noise model as a ``scipy.signal.dlti``; ``noise`` must be True."""
        self._check_fitted("to_dlti")
        self._no_input_model(noise, "to_dlti")
        return super().to_dlti(noise=True)

    def frequency_response(self, omega, theta=None, noise=True):
        """Frequency response of the noise model; ``noise`` must be True."""
        self._check_fitted("frequency_response")
        self._no_input_model(noise, "frequency_response")
        return super().frequency_response(omega, theta, noise=True)


def _start_option(model, s, options):
    """The start of the batch search from ``theta0=`` or ``init_model=`` (None: the default
    starts), validated against the structure `s`."""
    theta0, init = options.get("theta0"), options.get("init_model")
    if theta0 is not None and init is not None:
        raise TypeError("give `theta0` or `init_model`, not both")
    if init is not None:
        if not isinstance(init, PolynomialModel):
            raise TypeError(f"`init_model` must be a fitted ARMAX, OE, BJ, AR or ARMA model; got "
                            f"{type(init).__name__}")
        init._check_fitted("init_model")
        if init.structure_ != s:
            raise ValueError(f"`init_model` must have the structure being fitted "
                             f"({model._orders_text()} with {s.n_inputs} input(s)); got "
                             f"{init._orders_text()} with {init.structure_.n_inputs} input(s)")
        theta0 = init.theta_
    if theta0 is not None:
        theta0 = np.array(theta0, dtype=float).reshape(-1)
        if theta0.shape != (s.n_params,) or not np.isfinite(theta0).all():
            raise ValueError(f"`theta0` must hold n_params = {s.n_params} finite "
                             f"values; got shape {theta0.shape}")
    return theta0


def _recursive_fit(records, s, method, options, stacklevel):
    """`recursive_pem_records` in the units the recursion runs in: ``(fit, units, P, R)``.

    The recursion runs on the records scaled to unit size, with ``P0``, ``R``, ``Q`` and
    ``x0`` mapped exactly: the numbers of the recursion in the signals' units times
    powers of two wherever both are exact (:mod:`rlsfilt.models._units`), and in range
    for records of any size. The returned ``fit.state`` is the recursion in the signals'
    units with the final state of the scaled run, while ``P`` and ``R`` are those of the
    run (``P / R`` maps to the signals' units with ``units.cov_from_unit``). Forgetting
    modes whose constants bound ``trace(P)`` or its eigenvalues, and a default ``P0``
    that outweighs the data (warned about), run in the signals' units (``units`` the
    identity); a ``P0`` too diffuse for the data is a ValueError naming it
    (`RecordUnits.recursion_start`).
    """
    units = RecordUnits(records, s)
    user = RecursionState(s, method, **options)      # validates every option
    units.check_ratio()
    x0 = units.start_to_unit(user.theta, "x0")
    Q = None if user.q_zero else user.Q
    r = units.r_for(user.R, gate=options.get("gate") is not None)
    scaled = equivariant_forgetting(options.get("forgetting", "exponential"),
                                    options.get("forgetting_params"))
    start = units.recursion_start(user.P, user.R, Q, r=r, default_P0="P0" not in options,
                                  stacklevel=stacklevel + 1) if scaled else None
    if start is None:
        fit = recursive_pem_records(records, s, method, stacklevel=stacklevel + 1, **options)
        return fit, units.unscaled(), fit.P, fit.state.R
    opts = dict(options, P0=start["P0"], R=start["R"], x0=x0)
    if Q is not None:
        opts["Q"] = start["Q"]
    fit = recursive_pem_records(units.scale_records(records), s, method,
                                stacklevel=stacklevel + 1, **opts)
    P, R = fit.P, fit.state.R
    with np.errstate(over="ignore", under="ignore"):
        user.adopt(fit.state, units.theta_from_unit(fit.theta), units.P_from_unit(fit.P, r=r),
                   units.input_exponents, units.output_exponent)
    fit.state = user
    return fit, units, P, R


def fit_io(model, u, y, method, options):
    """``fit(u, y)`` of an input/output model of the family (single output; `u` may be an
    `IOData`, with `y` omitted, or lists of arrays: several experiments)."""
    records, info = as_records(u, y)
    Y = records[0][1]
    if Y.shape[1] != 1:
        raise ValueError(f"`y` must have shape (N,) (one output; {type(model).__name__} is a "
                         f"single-output model, use ARX for several outputs); got {Y.shape}")
    return model._fit([(U, Yi[:, 0]) for U, Yi in records], info, method, options,
                      stacklevel=4)
