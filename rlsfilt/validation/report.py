"""One call that validates a model: fit, residual tests, criteria, plant comparison."""

import html

import numpy as np

from .._validation import check_int, check_probability
from ..plotting import _axes, _figure
from ._model import model_name, n_params, one_step
from .criteria import _from_residuals
from .metrics import fit_percent
from .plant import PlantComparison
from .residuals import _residual_analysis
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
            rows += [row("max rel. frequency error vs plant", f"{p.frequency_error:.4g}"),
                     row("rel. DC-gain error vs plant", f"{p.dc_gain_error:.4g}"),
                     row("largest pole distance", f"{p.max_pole_distance:.4g}")]
        verdict = "passed" if self.passed else "FAILED"
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
        r = self.residuals[0]
        r.plot_autocorrelation(fig.add_subplot(gs[1, 0]))
        r.plot_cross_correlation(fig.add_subplot(gs[1, 1]))
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
    max_lag = check_int(max_lag, "max_lag", minimum=1)
    alpha = check_probability(alpha, "alpha")
    Phi, _, E = one_step(model, u, y, "validate")      # the regressors, built once
    residuals = tuple(_residual_analysis(Phi, E, u, max_lag, alpha, output=i)
                      for i in range(E.shape[1]))
    resid0 = residuals[0]
    Y = np.asarray(y, dtype=float)
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
        criteria=_from_residuals(E, n_params(model)),
        intervals=parameter_intervals(model),
        plant_comparison=None if plant is None else PlantComparison(model, plant),
    )


def _fmt_fit(fit):
    arr = np.atleast_1d(fit)
    return ", ".join(f"{v:.2f}%" for v in arr)
