"""One call that validates a model: fit, residual tests, criteria, plant comparison."""

import html

import numpy as np

from .. import __version__
from .._resources import check_memory
from .._serialize import jsonable
from .._validation import check_int, check_probability
from ..exceptions import ExactFitError, InsufficientDataError
from ..plotting import _axes, _figure
from ._model import model_name, n_params, one_step
from .criteria import _from_residuals
from .metrics import fit_percent
from .plant import PlantComparison
from .residuals import _residual_analysis
from .uncertainty import parameter_intervals

__all__ = ["ValidationReport", "validate"]


class ValidationReport:
    """Everything :func:`validate` found, with text, HTML, a figure and a dict.

    Attributes
    ----------
    model : IdentifiedModel
        The validated model.
    time : ndarray, shape (N,)
        Time axis of the record (``dt`` times the sample index; sample index
        when ``dt`` is unspecified).
    y : ndarray, shape (N,) or (N, ny)
        Measured output.
    y_simulated : ndarray
        Free-run simulation from the input, started from the measured first
        ``max_lag`` outputs.
    y_predicted : ndarray
        One-step-ahead prediction.
    start : int
        ``max_lag``: the first sample the fits are computed on.
    simulation_fit, prediction_fit : float or ndarray of shape (ny,)
        :func:`fit_percent` of the simulation and of the one-step prediction
        on samples ``start .. N-1``.
    residuals : tuple of ResidualAnalysis
        One analysis per output (empty when the tests were skipped).
    criteria : InformationCriteria or None
        On the given record (None when skipped: an exact fit).
    intervals : ParameterIntervals
        95% confidence intervals of the parameters.
    plant_comparison : PlantComparison or None
        Present when a plant was given.
    skipped : str or None
        Why the residual tests were skipped (``validate(...,
        skip_undefined=True)`` on too short a record or on an exact fit).
    metadata : dict
        What the caller passed as ``validate(..., metadata=...)``.
    """

    def __init__(self, **fields):
        self.skipped = None
        self.metadata = {}
        for key, value in fields.items():
            setattr(self, key, value)

    @property
    def passed(self):
        """True if every residual test passed (white and independent for every output);
        False when the tests were skipped."""
        if not self.residuals:
            return False
        return all(r.is_white and r.is_independent for r in self.residuals)

    def __repr__(self):
        return self.summary()

    def summary(self):
        """The report as plain text, with the model's coefficient table."""
        dt = "" if self.model.dt is True else f" (sample time {float(self.model.dt):g})"
        lines = [f"Validation of {self._model_name()} on {len(self.y)} samples{dt}",
                 "=" * 64,
                 f"Simulation fit      : {_fmt_fit(self.simulation_fit)}",
                 f"1-step prediction fit: {_fmt_fit(self.prediction_fit)}",
                 ""]
        if self.residuals:
            r0 = self.residuals[0]
            lines.append(f"Residual tests (alpha = {r0.alpha:g}, max lag {r0.max_lag}):")
            for i, r in enumerate(self.residuals):
                if len(self.residuals) > 1:
                    lines.append(f" output {i}:")
                lines.append(r.summary())
        else:
            lines.append(f"Residual tests skipped: {self.skipped}")
        c = self.criteria
        if c is not None:
            lines += ["",
                      f"Information criteria (N = {c.n_samples}, d = {c.n_params}):",
                      f"  loss V = {c.loss:.6g}   FPE = {c.fpe:.6g}   MDL = {c.mdl:.6g}",
                      f"  AIC = {c.aic:.6g}   AICc = {c.aicc:.6g}   BIC = {c.bic:.6g}   "
                      f"nAIC = {c.naic:.6g}"]
        lines += ["",
                  f"Parameters ({100 * self.intervals.level:g}% confidence intervals):",
                  self.model.summary().as_text()]
        if self.plant_comparison is not None:
            lines += ["", self.plant_comparison.summary()]
        if self.residuals:
            verdict = ("residual tests passed" if self.passed
                       else "residual tests FAILED: consider other orders")
        else:
            verdict = "residual tests skipped"
        lines += ["", "Verdict: " + verdict]
        return "\n".join(lines)

    def to_dict(self):
        """The report as a JSON-ready dict (what ``rlsfilt identify --json`` prints).

        Returns
        -------
        dict
            ``rlsfilt_version``; the model's own fields
            (:meth:`IdentifiedModel.to_dict`: ``model``, ``orders``,
            ``theta_names``, ``theta``, ``theta_std``, ``noise_variance``,
            ``transfer_functions``, ...); ``theta_lower``, ``theta_upper``
            and ``confidence_level`` (:attr:`intervals`); ``n_samples`` (the
            record), ``n_used`` (rows with a complete predictor);
            ``fit_percent`` (simulation) and ``fit_percent_prediction``;
            ``validation_skipped`` (None or the reason); when the tests ran,
            ``residual_tests`` (a dict; a list of dicts, one per output, for
            several outputs) and ``information_criteria``; with a plant,
            ``plant_comparison``; and ``metadata``.

        Notes
        -----
        Arrays are lists, complex poles ``[real, imag]`` pairs, and every
        non-finite number (NaN, +-inf, for example an infinite t statistic
        or AICc) is ``None``, so ``json.dumps(report.to_dict(),
        allow_nan=False)`` always works.

        Examples
        --------
        >>> import json
        >>> from rlsfilt import ARX, datasets, validate
        >>> d = datasets.thermal_process()
        >>> rep = validate(ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y), d.u, d.y)
        >>> out = rep.to_dict()
        >>> out["model"], out["theta_names"], out["residual_tests"]["white"]
        ('ARX', ['a1', 'b1'], True)
        >>> json.loads(json.dumps(out, allow_nan=False)) == out
        True
        """
        ci = self.intervals
        out = {"rlsfilt_version": __version__}
        out.update(self.model.to_dict())
        out.update(
            theta_lower=ci.lower, theta_upper=ci.upper, confidence_level=ci.level,
            n_samples=len(self.y), n_used=len(self.y) - self.start,
            fit_percent=self.simulation_fit, fit_percent_prediction=self.prediction_fit,
            validation_skipped=self.skipped)
        if self.residuals:
            tests = [_residual_dict(r) for r in self.residuals]
            out["residual_tests"] = tests[0] if len(tests) == 1 else tests
        if self.criteria is not None:
            out["information_criteria"] = self.criteria.as_dict()
        if self.plant_comparison is not None:
            out["plant_comparison"] = _plant_dict(self.plant_comparison)
        out["metadata"] = self.metadata
        return jsonable(out)

    def _repr_html_(self):
        def row(name, value):
            return f"<tr><th style='text-align:left'>{html.escape(name)}</th>" \
                   f"<td style='text-align:left'>{html.escape(value)}</td></tr>"

        c = self.criteria
        rows = [row("simulation fit", _fmt_fit(self.simulation_fit)),
                row("1-step prediction fit", _fmt_fit(self.prediction_fit))]
        if not self.residuals:
            rows.append(row("residual tests", f"skipped: {self.skipped}"))
        for i, r in enumerate(self.residuals):
            tag = f" (output {i})" if len(self.residuals) > 1 else ""
            rows.append(row(f"whiteness{tag}",
                            f"{'white' if r.is_white else 'NOT white'} "
                            f"(Ljung-Box p = {r.pvalue_white:.3g})"))
            rows.append(row(f"independence{tag}",
                            f"{'independent' if r.is_independent else 'NOT independent'} "
                            f"(p = {r.pvalue_independent:.3g})"))
        if c is not None:
            rows += [row("loss V / FPE", f"{c.loss:.6g} / {c.fpe:.6g}"),
                     row("AIC / AICc / BIC", f"{c.aic:.6g} / {c.aicc:.6g} / {c.bic:.6g}")]
        if self.plant_comparison is not None:
            p = self.plant_comparison
            rows += [row("max rel. frequency error vs plant", f"{p.frequency_error:.4g}"),
                     row("rel. DC-gain error vs plant", f"{p.dc_gain_error:.4g}"),
                     row("largest pole distance", f"{p.max_pole_distance:.4g}")]
        verdict = ("skipped" if not self.residuals else "passed" if self.passed else "FAILED")
        color = "#2a7" if self.passed else "#c33"
        return (f"<div><h4>Validation of {html.escape(self._model_name())} on {len(self.y)} "
                f"samples: <span style='color:{color}'>residual tests {verdict}</span></h4>"
                f"<table>{''.join(rows)}</table>"
                f"<details><summary>parameters</summary><pre>"
                f"{html.escape(self.intervals.summary())}</pre></details></div>")

    def plot(self, fig=None):
        """One figure: measured vs simulated and predicted output, residual
        correlations, and (with a plant) Bode and step against the plant.

        Parameters
        ----------
        fig : matplotlib.figure.Figure, optional
            Figure to draw in (empty); a new one if omitted.

        Returns
        -------
        matplotlib.figure.Figure
        """
        has_plant = self.plant_comparison is not None
        fig = _figure(fig, figsize=(11, 11 if has_plant else 7), layout="constrained")
        gs = fig.add_gridspec(4 if has_plant else 2, 2)
        ax_cmp = fig.add_subplot(gs[0, :])
        self.plot_comparison(ax_cmp)
        if self.residuals:
            r = self.residuals[0]
            r.plot_autocorrelation(fig.add_subplot(gs[1, 0]))
            r.plot_cross_correlation(fig.add_subplot(gs[1, 1]))
        else:
            ax = fig.add_subplot(gs[1, :])
            ax.text(0.5, 0.5, f"residual tests skipped:\n{self.skipped}", ha="center",
                    va="center", transform=ax.transAxes)
            ax.set_axis_off()
        if has_plant:
            ax_mag = fig.add_subplot(gs[2, 0])
            ax_ph = fig.add_subplot(gs[3, 0], sharex=ax_mag)
            self.plant_comparison.plot_bode(ax_mag, ax_ph)
            self.plant_comparison.plot_step(fig.add_subplot(gs[2:, 1]))
        return fig

    def plot_comparison(self, ax=None):
        """Measured, simulated and one-step predicted output (MATLAB ``compare``).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw in; a new figure is made if omitted.

        Returns
        -------
        matplotlib.axes.Axes
        """
        ax = _axes(ax)
        y = self.y if self.y.ndim == 1 else self.y[:, 0]
        ys = self.y_simulated if self.y_simulated.ndim == 1 else self.y_simulated[:, 0]
        yp = self.y_predicted if self.y_predicted.ndim == 1 else self.y_predicted[:, 0]
        sf = np.atleast_1d(self.simulation_fit)[0]
        pf = np.atleast_1d(self.prediction_fit)[0]
        ax.plot(self.time, y, "k-", lw=1, label="measured $y$")
        ax.plot(self.time, ys, "C0-", lw=1, label=f"simulated (fit {sf:.1f}%)")
        ax.plot(self.time, yp, "C1--", lw=0.8, label=f"1-step predicted (fit {pf:.1f}%)")
        ax.set_xlabel("sample" if self.model.dt is True else "time (s)")
        ax.set_ylabel("output $y$")
        ax.set_title("Model output against the data")
        ax.legend(loc="best")
        return ax

    def _model_name(self):
        return model_name(self.model)


def validate(model, u, y, plant=None, *, max_lag=25, alpha=0.01, skip_undefined=False,
             metadata=None):
    """Validate a fitted model on a record (and against the true plant if known).

    Parameters
    ----------
    model : IdentifiedModel
        A fitted model (`ARX` or any other model class of rlsfilt).
    u : array_like, shape (N,) or (N, nu)
        Input record; validation data not used for the fit is the honest
        choice, the estimation data show the fit itself.
    y : array_like, shape (N,) or (N, ny)
        Output record.
    plant : control.LTI, optional
        The true system, for simulated experiments (see
        :class:`PlantComparison`).
    max_lag : int or "auto", default 25
        Largest lag of the residual correlations. ``"auto"``: ``min(25, n //
        4)`` for ``n`` residuals, halved while the record is too short for
        the tests at that lag (down to 1).
    alpha : float, default 0.01
        Significance level of the residual tests.
    skip_undefined : bool, default False
        When the residual tests or the information criteria are undefined
        on these data (too few residuals, `InsufficientDataError`; zero or
        constant residuals, `ExactFitError`), record the reason in
        ``report.skipped`` and leave ``residuals`` empty (and ``criteria``
        None) instead of raising. The fits, intervals and plant comparison
        are still computed.
    metadata : dict, optional
        JSON-ready facts about the data (source, signal names, ...), kept
        as ``report.metadata`` and included in :meth:`ValidationReport.to_dict`.

    Returns
    -------
    ValidationReport
        ``.summary()`` (text), ``_repr_html_()`` (notebooks), ``.plot()``
        (one figure), ``.to_dict()`` (JSON-ready) and every number as an
        attribute.

    Raises
    ------
    InsufficientDataError
        Too few residuals for the residual tests at `max_lag` (unless
        `skip_undefined`).
    ExactFitError
        Zero or constant residuals (unless `skip_undefined`).
    MemoryError
        Before anything large is allocated, when the estimated working
        memory exceeds what the process can get (see Notes).

    Notes
    -----
    **Memory.** The work is :math:`O(N)` in memory with small constants:
    the regressors, residuals, simulation and prediction, and the residual
    tests' regression accumulated over blocks of rows (tall-skinny QR), never
    a dense matrix of lagged inputs. For ``ARX(2, 2, 1)`` with one input and
    one output the peak is about 150 bytes per sample (measured with
    tracemalloc on 2e5 samples; the test suite holds it below 250), about
    ``8 (2 n_params + 12)`` bytes per sample in general.


    The simulation starts from the measured outputs ``y[:max_lag]`` of the
    model's largest lag and the fits are computed from there on; the
    one-step prediction uses the measured past (:meth:`ARX.predict`), so on
    the same rows it equals ``Phi @ theta_`` (MATLAB's ``compare`` with
    prediction horizon 1).

    Examples
    --------
    >>> from rlsfilt import ARX, datasets
    >>> from rlsfilt.validation import validate
    >>> d = datasets.thermal_process()
    >>> model = ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y)
    >>> report = validate(model, d.u, d.y, plant=d.plant)
    >>> report.passed, bool(report.plant_comparison.frequency_error < 0.1)
    (True, True)
    """
    auto = isinstance(max_lag, str) and max_lag == "auto"
    lag = None if auto else check_int(max_lag, "max_lag", minimum=1)
    alpha = check_probability(alpha, "alpha")
    if metadata is not None and not isinstance(metadata, dict):
        raise TypeError(f"`metadata` must be a dict; got {type(metadata).__name__}")
    Phi, _, E = one_step(model, u, y, "validate")      # the regressors, built once
    n = E.shape[0]
    # what is still to come: simulation and prediction (their regressors, inputs and
    # outputs) and the record's copies in the report (the residual tests check their own)
    n_par, ny, nu = Phi.shape[1], E.shape[1], model.n_inputs_
    check_memory(8 * n * (n_par + 8 + 2 * nu + 4 * ny), f"validate on {n} rows of `u`, `y`")
    if auto:
        lag = max(1, min(25, n // 4))
    residuals, criteria, skipped = (), None, None
    while True:
        try:
            residuals = tuple(_residual_analysis(Phi, E, u, lag, alpha, output=i)
                              for i in range(E.shape[1]))
            criteria = _from_residuals(E, n_params(model))
            break
        except InsufficientDataError:
            if auto and lag > 1:    # a shorter lag needs fewer rows: try it
                lag = max(1, lag // 2)
                continue
            if not skip_undefined:
                raise
            skipped = f"only {n} residuals, too few for the residual tests" + (
                "" if auto else f" at max_lag = {lag}")
            residuals = ()
            break
        except ExactFitError:
            if not skip_undefined:
                raise
            skipped = "the residuals are zero or constant (an exact fit)"
            residuals = ()
            break
    Y = np.asarray(y, dtype=float)
    start = len(Y) - n  # max_lag of the model
    y0 = Y[:start]
    y_sim = np.asarray(model.simulate(u, y0=y0 if start else None), dtype=float)
    y_pred = np.asarray(model.predict(u, y, horizon=1), dtype=float)
    dt = 1.0 if model.dt is True else float(model.dt)
    return ValidationReport(
        model=model, time=np.arange(len(Y)) * dt, y=Y, y_simulated=y_sim, y_predicted=y_pred,
        start=start,
        simulation_fit=fit_percent(Y[start:], y_sim[start:]),
        prediction_fit=fit_percent(Y[start:], y_pred[start:]),
        residuals=residuals,
        criteria=criteria,
        intervals=parameter_intervals(model),
        plant_comparison=None if plant is None else PlantComparison(model, plant),
        skipped=skipped, metadata=dict(metadata or {}),
    )


def _residual_dict(r):
    return {"output": r.output, "alpha": r.alpha, "max_lag": r.max_lag,
            "ljung_box": r.q_statistic, "ljung_box_df": r.df_white,
            "ljung_box_pvalue": r.pvalue_white, "white": r.is_white,
            "independence_f": r.f_statistic, "independence_df": r.df_independent,
            "independence_pvalue": r.pvalue_independent, "independent": r.is_independent,
            "autocorr_max": float(np.max(np.abs(r.autocorrelation[1:]))),
            "autocorr_band": r.autocorrelation_band}


def _plant_dict(pc):
    def scalar_or_matrix(x):
        x = np.real(np.asarray(x))
        return x.reshape(()) if x.size == 1 else x

    return {"frequency_error": pc.frequency_error, "dc_gain_error": pc.dc_gain_error,
            "step_error": pc.step_error, "max_pole_distance": pc.max_pole_distance,
            "dc_gain_model": scalar_or_matrix(pc.dc_gain_model),
            "dc_gain_true": scalar_or_matrix(pc.dc_gain_plant),
            "poles_model": np.sort_complex(np.ravel(pc.poles_model)),
            "poles_true": np.sort_complex(np.ravel(pc.poles_plant)),
            "unmatched_model_poles": np.ravel(pc.unmatched_model_poles),
            "unmatched_true_poles": np.ravel(pc.unmatched_plant_poles)}


def _fmt_fit(fit):
    arr = np.atleast_1d(fit)
    return ", ".join(f"{v:.2f}%" for v in arr)
