"""One call that validates a model: fit, residual tests, criteria, plant comparison."""

import html

import numpy as np

from ..plotting import plot_comparison, plot_report
from .criteria import information_criteria
from .metrics import fit_percent
from .plant import PlantComparison
from .residuals import residual_analysis
from .uncertainty import parameter_intervals

__all__ = ["ValidationReport", "validate"]


class ValidationReport:
    """Everything :func:`validate` found, with text, HTML and a figure.

    Attributes
    ----------
    model : ARX
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
        One analysis per output.
    criteria : InformationCriteria
        On the given record.
    intervals : ParameterIntervals
        95% confidence intervals of the parameters.
    plant_comparison : PlantComparison or None
        Present when a plant was given.
    """

    def __init__(self, **fields):
        for key, value in fields.items():
            setattr(self, key, value)

    @property
    def passed(self):
        """True if every residual test passed (white and independent for every output)."""
        return all(r.is_white and r.is_independent for r in self.residuals)

    def __repr__(self):
        return self.summary()

    def summary(self):
        """The report as plain text."""
        r0 = self.residuals[0]
        lines = [f"Validation of {self._model_name()} on {len(self.y)} samples",
                 "=" * 64,
                 f"Simulation fit      : {_fmt_fit(self.simulation_fit)}",
                 f"1-step prediction fit: {_fmt_fit(self.prediction_fit)}",
                 "",
                 f"Residual tests (alpha = {r0.alpha:g}, max lag {r0.max_lag}):"]
        for i, r in enumerate(self.residuals):
            if len(self.residuals) > 1:
                lines.append(f" output {i}:")
            lines.append(r.summary())
        c = self.criteria
        lines += ["",
                  f"Information criteria (N = {c.n_samples}, d = {c.n_params}):",
                  f"  loss V = {c.loss:.6g}   FPE = {c.fpe:.6g}   MDL = {c.mdl:.6g}",
                  f"  AIC = {c.aic:.6g}   AICc = {c.aicc:.6g}   BIC = {c.bic:.6g}   "
                  f"nAIC = {c.naic:.6g}",
                  "",
                  f"Parameters ({100 * self.intervals.level:g}% confidence intervals):",
                  self.intervals.summary()]
        if self.plant_comparison is not None:
            lines += ["", self.plant_comparison.summary()]
        lines += ["", "Verdict: " + ("residual tests passed" if self.passed
                                     else "residual tests FAILED: consider other orders")]
        return "\n".join(lines)

    def _repr_html_(self):
        def row(name, value):
            return f"<tr><th style='text-align:left'>{html.escape(name)}</th>" \
                   f"<td style='text-align:left'>{html.escape(value)}</td></tr>"

        c = self.criteria
        rows = [row("simulation fit", _fmt_fit(self.simulation_fit)),
                row("1-step prediction fit", _fmt_fit(self.prediction_fit))]
        for i, r in enumerate(self.residuals):
            tag = f" (output {i})" if len(self.residuals) > 1 else ""
            rows.append(row(f"whiteness{tag}",
                            f"{'white' if r.is_white else 'NOT white'} "
                            f"(Ljung-Box p = {r.pvalue_white:.3g})"))
            rows.append(row(f"independence{tag}",
                            f"{'independent' if r.is_independent else 'NOT independent'} "
                            f"(p = {r.pvalue_independent:.3g})"))
        rows += [row("loss V / FPE", f"{c.loss:.6g} / {c.fpe:.6g}"),
                 row("AIC / AICc / BIC", f"{c.aic:.6g} / {c.aicc:.6g} / {c.bic:.6g}")]
        if self.plant_comparison is not None:
            p = self.plant_comparison
            rows += [row("max rel. frequency error vs plant", f"{100 * p.frequency_error:.4g}%"),
                     row("rel. DC-gain error vs plant", f"{100 * p.dc_gain_error:.4g}%"),
                     row("rel. step-response error vs plant", f"{100 * p.step_error:.4g}%"),
                     row("largest pole distance", f"{p.max_pole_distance:.4g}")]
        # the verdict in words (and a mark), the colour only repeats it
        verdict = "PASS: residual tests passed" if self.passed else "FAIL: residual tests FAILED"
        color = "#009E73" if self.passed else "#D55E00"
        mark = "&#10004;" if self.passed else "&#10008;"
        rows.append(row("verdict", verdict + ("" if self.passed
                                              else " (consider other orders)")))
        return (f"<div><h4>Validation of {html.escape(self._model_name())} on {len(self.y)} "
                f"samples: <span style='color:{color}'>{mark} {verdict}</span></h4>"
                f"<table>{''.join(rows)}</table>"
                f"<details><summary>parameters</summary><pre>"
                f"{html.escape(self.intervals.summary())}</pre></details></div>")

    def plot(self, fig=None, window=None):
        """One figure: measured vs simulated and predicted output, residual
        correlations, Bode with its uncertainty band and (with a plant) the
        plant's Bode and step (:func:`rlsfilt.plotting.plot_report`).

        Parameters
        ----------
        fig : matplotlib.figure.Figure, optional
            Figure to draw in (empty); a new one if omitted.
        window : (int, int), optional
            Samples shown in the output panel (by default the last 400 of a
            longer record, with an overview of the whole record).

        Returns
        -------
        matplotlib.figure.Figure
        """
        return plot_report(self, fig, window=window)

    def plot_comparison(self, ax=None, window=None):
        """Measured, simulated and one-step predicted output (MATLAB ``compare``;
        :func:`rlsfilt.plotting.plot_comparison`).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw in; a new figure (window and overview) if omitted.
        window : (int, int), optional
            Samples shown (by default the last 400 of a longer record).

        Returns
        -------
        matplotlib.axes.Axes
        """
        return plot_comparison(self, ax, window=window)

    def _model_name(self):
        m = self.model
        return f"{type(m).__name__}(na={m.na!r}, nb={m.nb!r}, nk={m.nk!r})"


def validate(model, u, y, plant=None, *, max_lag=25, alpha=0.01):
    """Validate a fitted model on a record (and against the true plant if known).

    Parameters
    ----------
    model : ARX
        A fitted model.
    u : array_like, shape (N,) or (N, nu)
        Input record; validation data not used for the fit is the honest
        choice, the estimation data show the fit itself.
    y : array_like, shape (N,) or (N, ny)
        Output record.
    plant : control.LTI, optional
        The true system, for simulated experiments (see
        :class:`PlantComparison`).
    max_lag : int, default 25
        Largest lag of the residual correlations.
    alpha : float, default 0.01
        Significance level of the residual tests.

    Returns
    -------
    ValidationReport
        ``.summary()`` (text), ``_repr_html_()`` (notebooks), ``.plot()``
        (one figure) and every number as an attribute.

    Notes
    -----
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
    resid0 = residual_analysis(model, u, y, max_lag=max_lag, alpha=alpha)
    Y = np.asarray(y, dtype=float)
    ny = 1 if Y.ndim == 1 else Y.shape[1]
    residuals = (resid0,) + tuple(
        residual_analysis(model, u, y, max_lag=max_lag, alpha=alpha, output=i)
        for i in range(1, ny))
    start = len(Y) - len(resid0.residuals)  # max_lag of the model
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
        criteria=information_criteria(model, u, y),
        intervals=parameter_intervals(model),
        plant_comparison=None if plant is None else PlantComparison(model, plant),
    )


def _fmt_fit(fit):
    arr = np.atleast_1d(fit)
    return ", ".join(f"{v:.2f}%" for v in arr)
