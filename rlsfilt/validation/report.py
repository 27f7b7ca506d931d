"""One call that validates a model: fit, residual tests, criteria, plant comparison."""

import html
import warnings

import numpy as np

from .._display import Summary
from .._resources import check_memory
from .._serialize import jsonable
from .._validation import check_int, check_probability
from .._version import __version__
from ..exceptions import ExactFitError, InsufficientDataError, OperatingPointWarning
from ..models._base import check_is_fitted
from ..models._offset import model_offset_mode, offset_messages, operating_point_remedy
from ..models._residual_tests import auto_max_lag
from ..models.regressors import as_records
from ..plotting import plot_comparison, plot_report
from ._model import model_name, n_params, one_step
from .compare import _time_series_records, compare, initial_text
from .criteria import _from_residuals
from .plant import PlantComparison
from .residuals import _residual_analysis
from .uncertainty import frequency_response_band, parameter_intervals

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
        Free-run simulation from the input (:func:`compare` with an infinite
        horizon) from the initial state :attr:`initial` (zeros for a time
        series: no input to simulate from).
    y_predicted : ndarray
        One-step-ahead prediction (:func:`compare` with ``horizon=1``) from
        the same kind of initial state. For a model without a noise model
        (OE) it is the simulation.
    initial : str
        The initial condition: ``"estimate"`` (the default, MATLAB
        ``compare``'s ``'e'``: the state that fits the record best, by least
        squares), ``"zero"`` (from rest) or ``"measured"``;
        :attr:`initial_text` says it in words.
    x0 : tuple of ndarray
        The simulation's initial state of every experiment, a state of
        ``model.to_ss()`` (of the predictor for a time series).
    start : int
        The first sample of every experiment the fits cover: 0, or for
        ``initial="measured"`` the samples that set the state.
    n_used : int
        Number of one-step residuals (rows with a complete regressor) the
        residual tests and criteria use.
    simulation_fit, prediction_fit : float or ndarray of shape (ny,)
        :func:`fit_percent` of the simulation and of the one-step prediction
        on samples ``start .. N-1`` (of every experiment): the fits of
        :func:`compare` under :attr:`initial`. NaN for the simulation of an
        unstable model, whose simulation diverges, and of a time series (no
        input).
    is_time_series : bool
        True for a model without input (`AR`, `ARMA`): the residuals get
        the whiteness test only (no cross-correlation, no independence
        test), there is no simulation, and the stability and Bode diagram
        are those of the noise model ``C/(A D)``.
    stability : str
        ``"stable (largest pole magnitude 0.93)"``, or ``"unstable model,
        largest pole magnitude 1.02, simulation diverges"``.
    is_unstable : bool
        True when a pole of the input model lies outside the unit circle.
    max_pole_magnitude : float
        Largest pole magnitude of the input model.
    experiment_lengths : tuple of int
        Samples per experiment (`y`, `y_simulated`, `y_predicted` and `time`
        hold the experiments one after the other).
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
    input_names, output_names, input_units, output_units : tuple of str
        The signals' names and units, for the labels of :meth:`plot`: those
        of the validation record (an `IOData` or named pandas columns), else
        those the model was fitted on (units ``""`` when unknown).
    experiment_names : tuple of str
        The experiments' names (``"exp1"``, ... unless the `IOData` names them).
    """

    def __init__(self, **fields):
        self.skipped = None
        self.metadata = {}
        self.stability = ""
        self.is_unstable = False
        self.max_pole_magnitude = float("nan")
        self.experiment_lengths = ()
        self.experiment_names = ()
        self.input_names = self.output_names = self.input_units = self.output_units = ()
        self.is_time_series = False
        self.initial, self.x0, self.start, self.n_used = "zero", (), 0, 0
        for key, value in fields.items():
            setattr(self, key, value)

    @property
    def judged_by_input(self):
        """True when the verdict rests on the input test alone: a model without a noise
        model (OE, FIR: ``C = D = A = 1`` in ``C/(A D)``) or an instrumental-variable fit,
        whose residuals are not meant to be white (Ljung 1999, sec. 16.6)."""
        return _judged_by_input(self.model) and not self.is_time_series

    @property
    def passed(self):
        """True if the residual tests that apply to the model passed; False when the
        tests were skipped.

        White and independent of the input for every output for a model with a noise
        model (ARX, ARMAX, BJ); white for a time series; independent of the input only
        for a model without a noise model (OE, FIR) or an instrumental-variable fit
        (:attr:`judged_by_input`): no order of such a model can whiten its residuals.
        """
        if not self.residuals:
            return False
        if self.judged_by_input:
            return all(r.is_independent is not False for r in self.residuals)
        return all(r.is_white and r.is_independent is not False for r in self.residuals)

    @property
    def verdict(self):
        """The verdict and the advice in one sentence (what :meth:`summary` ends with)."""
        if not self.residuals:
            return "residual tests skipped"
        white = all(r.is_white for r in self.residuals)
        independent = all(r.is_independent is not False for r in self.residuals)
        if self.judged_by_input:
            kind = "an instrumental-variable fit" if _is_iv(self.model) else \
                f"{type(self.model).__name__} has no noise model"
            if not independent:
                return (f"input test FAILED ({kind}: judged by the residual-input "
                        f"cross-correlation): consider other orders or delays of the input "
                        f"model")
            if white:
                return f"residual tests passed ({kind}: judged by the input test)"
            return (f"passed: residuals independent of the input ({kind}, judged by the input "
                    f"test); they are not white, which no order of this structure changes: "
                    f"for a noise model (and better prediction) fit BJ or ARMAX")
        if self.passed:
            return "residual tests passed"
        if independent and not white:
            return ("residual tests FAILED: residuals not white; consider other orders or a "
                    "noise model (ARMAX, BJ)")
        return "residual tests FAILED: consider other orders"

    def __repr__(self):
        return self.summary().as_text()

    def summary(self):
        """The report: text with the model's coefficient table, or a table in a notebook.

        Returns
        -------
        Summary
            ``print`` it for the text (what ``rlsfilt identify`` prints), or
            display it in a notebook (the HTML of the report).
        """
        dt = "" if self.model.dt is True else f" (sample time {float(self.model.dt):g})"
        lines = [f"Validation of {self._model_name()} on {len(self.y)} samples"
                 f"{self._experiments_text()}{dt}",
                 "=" * 64,
                 f"Model               : {self.stability}",
                 f"Simulation fit      : {self._simulation_text()}",
                 f"1-step prediction fit: {_fmt_fit(self.prediction_fit)}",
                 f"Initial condition   : {self.initial_text}",
                 ""]
        if self.residuals:
            r0 = self.residuals[0]
            lines.append(f"Residual tests (alpha = {r0.alpha:g}, max lag {r0.max_lag}):")
            for i, r in enumerate(self.residuals):
                if len(self.residuals) > 1:
                    lines.append(f" output {i}:")
                lines.append(r.summary().as_text())
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
            lines += ["", self.plant_comparison.summary().as_text()]
        lines += ["", "Verdict: " + self.verdict]
        return Summary("\n".join(lines), self._html())

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
            ``fit_percent`` (simulation; None for an unstable model) and
            ``fit_percent_prediction``; ``initial_condition`` (``"estimate"``,
            ``"zero"`` or ``"measured"``), ``initial_condition_text`` (in
            words), ``initial_state`` (one list per experiment) and
            ``fit_start``; ``passed``, ``verdict`` and ``judged_by_input``
            (True for OE, FIR and instrumental-variable fits, judged by the
            input test alone); ``stability`` (the sentence of
            :attr:`stability`), ``unstable`` and ``max_pole_magnitude``;
            ``experiment_lengths``; ``time_series`` (True for a model
            without input: ``fit_percent`` and the independence entries of
            ``residual_tests`` are then None);
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
            n_samples=len(self.y), n_used=self.n_used,
            fit_percent=self.simulation_fit, fit_percent_prediction=self.prediction_fit,
            initial_condition=self.initial, initial_condition_text=self.initial_text,
            initial_state=[np.asarray(x) for x in self.x0], fit_start=self.start,
            judged_by_input=self.judged_by_input, passed=self.passed, verdict=self.verdict,
            stability=self.stability, unstable=self.is_unstable,
            max_pole_magnitude=self.max_pole_magnitude,
            experiment_lengths=list(self.experiment_lengths),
            time_series=self.is_time_series, validation_skipped=self.skipped)
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
        return self.summary().as_html()

    def _html(self):
        def row(name, value):
            return f"<tr><th style='text-align:left'>{html.escape(name)}</th>" \
                   f"<td style='text-align:left'>{html.escape(value)}</td></tr>"

        c = self.criteria
        rows = [row("model", self.stability),
                row("simulation fit", self._simulation_text()),
                row("1-step prediction fit", _fmt_fit(self.prediction_fit)),
                row("initial condition", self.initial_text)]
        if not self.residuals:
            rows.append(row("residual tests", f"skipped: {self.skipped}"))
        for i, r in enumerate(self.residuals):
            tag = f" (output {i})" if len(self.residuals) > 1 else ""
            rows.append(row(f"whiteness{tag}",
                            f"{'white' if r.is_white else 'NOT white'} "
                            f"(Ljung-Box p = {r.pvalue_white:.3g})"))
            if not r.has_input:
                rows.append(row(f"independence{tag}", "not applicable (time series: no input)"))
                continue
            rows.append(row(f"independence{tag}",
                            f"{'independent' if r.is_independent else 'NOT independent'} "
                            f"(p = {r.pvalue_independent:.3g})"))
        if c is not None:
            rows += [row("loss V / FPE", f"{c.loss:.6g} / {c.fpe:.6g}"),
                     row("AIC / AICc / BIC", f"{c.aic:.6g} / {c.aicc:.6g} / {c.bic:.6g}")]
        if self.plant_comparison is not None:
            p = self.plant_comparison
            rows += [row("max rel. frequency error vs plant", f"{100 * p.frequency_error:.4g}%"),
                     row("rel. DC-gain error vs plant", f"{100 * p.dc_gain_error:.4g}%"),
                     row("rel. step-response error vs plant", f"{100 * p.step_error:.4g}%"),
                     row("largest pole distance", f"{p.max_pole_distance:.4g}")]
        # the verdict in words (and a mark), the colour only repeats it
        if not self.residuals:
            verdict = "SKIPPED: residual tests skipped"
        elif self.passed:
            verdict = "PASS: residual tests passed"
        else:
            verdict = "FAIL: residual tests FAILED"
        color = "#009E73" if self.passed else "#D55E00"
        mark = "&#10004;" if self.passed else "&#10008;"
        rows.append(row("verdict", self.verdict))
        return (f"<div><h4>Validation of {html.escape(self._model_name())} on {len(self.y)} "
                f"samples{html.escape(self._experiments_text())}: "
                f"<span style='color:{color}'>{mark} {verdict}</span></h4>"
                f"<table>{''.join(rows)}</table>"
                f"<details><summary>parameters</summary><pre>"
                f"{html.escape(self.intervals.summary().as_text())}</pre></details></div>")

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

    def frequency_band(self, level=0.95, n_draws=1000, rng=0):
        """The model's frequency response with its uncertainty band, on the plant
        comparison's frequencies when there is one (what `plot` draws).

        Parameters
        ----------
        level : float, default 0.95
            Pointwise coverage of the band.
        n_draws : int, default 1000
            Parameter draws from ``theta_cov_``.
        rng : int or numpy.random.Generator, default 0
            Seed of the draws (0: the same band on every call).

        Returns
        -------
        FrequencyBand
            :func:`~rlsfilt.validation.frequency_response_band` of the model.
        """
        omega = None if self.plant_comparison is None else self.plant_comparison.omega
        return frequency_response_band(self.model, omega=omega, level=level, n_draws=n_draws,
                                       rng=rng)

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

    @property
    def initial_text(self):
        """The initial condition of the simulation and prediction, in words."""
        return initial_text(self.initial, self.start)

    def _model_name(self):
        return model_name(self.model)

    def _simulation_text(self):
        if self.is_time_series:
            return "not applicable (time series: no input)"
        if self.is_unstable:
            return self.stability
        return _fmt_fit(self.simulation_fit)

    def _experiments_text(self):
        n = len(self.experiment_lengths)
        return f" of {n} experiments" if n > 1 else ""


def validate(model, u, y=None, plant=None, *, initial="estimate", max_lag="auto", alpha=0.01,
             skip_undefined=False, metadata=None):
    """Validate a fitted model on a record (and against the true plant if known).

    Parameters
    ----------
    model : IdentifiedModel
        A fitted model (`ARX` or any other model class of rlsfilt).
    u : array_like, shape (N,) or (N, nu), or IOData, or None
        Input record, or an `IOData` holding inputs and outputs (then `y` is
        omitted; pass `plant` by keyword); validation data not used for the
        fit is the honest choice, the estimation data show the fit itself.
        None for a time-series model (`AR`, `ARMA`): the report then has
        the whiteness test only (no input to correlate with), no
        simulation, the prediction fit and the criteria.
    y : array_like, shape (N,) or (N, ny), or a list of them
        Output record (a list: one per experiment).
    plant : control.LTI, optional
        The true system, for simulated experiments (see
        :class:`PlantComparison`).
    initial : {"estimate", "zero", "measured"}, default "estimate"
        Initial state of the simulation and the one-step prediction (see
        :func:`compare`): ``"estimate"`` is MATLAB ``compare``'s default, so
        the fits are those a MATLAB user gets for the same model.
        ``"measured"`` applies to ARX only: validate needs it for both the
        simulation and the one-step prediction, and the measured past
        defines the predictor's state only without ``C`` and ``F`` (a
        ValueError says so; ``compare(..., initial="measured")`` simulates
        ARMAX from its measured past too).
    max_lag : int or "auto", default "auto"
        Largest lag of the residual correlations. ``"auto"`` (also the
        command line's): ``min(25, n // 4)`` for ``n`` residuals, halved
        while the record is too short for the tests at that lag (down to 1),
        so a short validation record (100 samples) is validated.
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

    Warns
    -----
    OperatingPointWarning
        When a signal's mean is large against its variation (more than 5
        standard deviations) and none of its samples reaches zero (a record
        from rest at the origin is not flagged), and the model has no offset
        handling (its ``offset`` is False or it has none): detrend the data
        or fit with ``offset=True``. The model's ``fit`` warns by the same
        rule.

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


    **Fits.** The simulation and the one-step prediction are
    :func:`compare`'s, from the initial state `initial`, and their fits
    are MATLAB's NRMSE fits over the record: with the default
    ``"estimate"`` the numbers MATLAB's ``compare(data, sys)`` and
    ``compare(data, sys, 1)`` print. Every model class is simulated from a
    consistent state (its realization ``to_ss()``), so an OE or BJ model is
    not penalized for a start the model cannot have. For an OE model the
    one-step prediction is the simulation, and the two fits are equal. An
    unstable model is reported as such ("unstable model, largest pole
    magnitude 1.02, simulation diverges") and its simulation fit is NaN
    instead of a meaningless huge negative number.

    **Verdict.** A model with a noise model (ARX, ARMAX, BJ) passes when its
    residuals are white and independent of the input. A model without one
    (OE, FIR) and an instrumental-variable fit are judged by the
    input test alone (their residuals are the output disturbance, white or
    not); when those residuals are not white, the verdict points to BJ or
    ARMAX instead of other orders.

    With several experiments every experiment is simulated and predicted
    from its own start, the fits cover the rows of all of them, and the
    residual tests run on the residuals of all experiments one after the
    other (correlations at lag ``k`` pair ``k`` samples across each seam).

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
    if not isinstance(initial, str) or initial not in ("estimate", "zero", "measured"):
        raise ValueError(f"`initial` must be 'estimate', 'zero' or 'measured'; got {initial!r}")
    alpha = check_probability(alpha, "alpha")
    if metadata is not None and not isinstance(metadata, dict):
        raise TypeError(f"`metadata` must be a dict; got {type(metadata).__name__}")
    check_is_fitted(model, "validate")
    from ..data.iodata import IOData

    u_arg = u
    time_series = getattr(model, "n_inputs_", None) == 0
    if time_series:                                       # AR, ARMA: u is None
        records, info = _time_series_records(model, u, y)
        parts = [(None, Y[:, 0]) for _, Y in records]
    elif (records_info := as_records(u, y))[1]["n_experiments"] == 1 and y is not None:
        records, info = records_info
        parts = [(u, y)]                                  # as given (1-D stays 1-D)
    else:
        records, info = records_info
        parts = [(U if U.shape[1] > 1 else U[:, 0], Y if Y.shape[1] > 1 else Y[:, 0])
                 for U, Y in records]
    # the regressors, residuals, simulation and prediction (their regressors, inputs and
    # outputs) and the record's copies in the report (the residual tests check their own)
    n_total = sum(len(Y) for _, Y in records)
    n_par = np.asarray(model.theta_).shape[0]
    nu = 0 if time_series else records[0][0].shape[1]
    ny = records[0][1].shape[1]
    check_memory(8 * n_total * (2 * n_par + 8 + 2 * nu + 4 * ny),
                 f"validate on `u`, `y` of {n_total} samples")
    if model_offset_mode(model) == "none":
        msgs = offset_messages(records, (info.get("u_names"), info.get("y_names")))
        if msgs:
            warnings.warn("; ".join(msgs) + ", and the model has no offset handling: the "
                          "fit mostly describes the operating point. "
                          + operating_point_remedy(model), OperatingPointWarning, stacklevel=2)
    Phis, Es, glued_u = [], [], []
    for k, (uk, yk) in enumerate(parts):
        Phi_k, _, E_k = one_step(model, uk, yk, "validate")   # the regressors, built once
        Phis.append(Phi_k)
        Es.append(E_k)
        Uk = np.asarray(records[k][0], dtype=float)
        glued_u.append(Uk if k == 0 else Uk[len(Uk) - len(E_k):])  # residual rows across seams
    # the simulation and the one-step prediction from the stated initial state (compare)
    pred = compare(model, u_arg, y, initial=initial, horizon=1)
    sim = None if time_series else compare(model, u_arg, y, initial=initial)
    Phi, E = np.vstack(Phis), np.vstack(Es)
    u = np.vstack(glued_u) if len(parts) > 1 or time_series else parts[0][0]
    n = E.shape[0]
    if auto:
        lag = auto_max_lag(n)
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
    Y, y_pred = pred.y, pred.y_hat
    y_sim = np.zeros_like(Y) if time_series else sim.y_hat   # a time series: no input
    lengths = pred.experiment_lengths
    dt = 1.0 if model.dt is True else float(model.dt)
    tstarts = list(u_arg.tstart) if isinstance(u_arg, IOData) else [0.0] * len(lengths)
    time = np.concatenate([t0 + dt * np.arange(n_k) for t0, n_k in zip(tstarts, lengths)])
    stability = model.stability_text()
    poles = model.poles()
    r_max = float(np.max(np.abs(poles))) if len(poles) else 0.0
    unstable = r_max >= 1.0 + 1e-9
    sim_fit = pred.fit if time_series else sim.fit
    if unstable or time_series:  # a diverging simulation (or none) has no meaningful fit
        sim_fit = np.full(np.shape(sim_fit), np.nan)
        sim_fit = float(sim_fit) if sim_fit.ndim == 0 else sim_fit
    return ValidationReport(
        model=model, time=time, y=Y, y_simulated=y_sim, y_predicted=y_pred,
        start=pred.start if time_series else sim.start, experiment_lengths=lengths,
        initial=initial, x0=pred.x0 if time_series else sim.x0, n_used=n,
        stability=stability, is_unstable=unstable, max_pole_magnitude=r_max,
        simulation_fit=sim_fit,
        prediction_fit=pred.fit,
        residuals=residuals,
        criteria=criteria,
        intervals=parameter_intervals(model),
        plant_comparison=None if plant is None else PlantComparison(model, plant),
        skipped=skipped, metadata=dict(metadata or {}), is_time_series=time_series,
        experiment_names=(tuple(u_arg.experiment_names) if isinstance(u_arg, IOData)
                          else tuple(f"exp{k + 1}" for k in range(len(lengths)))),
        **_signal_labels(model, info),
    )


def _signal_labels(model, info):
    """Names and units of the signals for the figures: the record's when it names them
    (an IOData, pandas columns), else the fitted model's, else ``u``/``y`` and no unit."""
    out = {}
    for kind, key, n in (("input", "u", model.n_inputs_), ("output", "y", model.n_outputs_)):
        names = info.get(f"{key}_names") or getattr(model, f"{kind}_names_", None)
        if not names or len(names) != n:
            names = [key] if n == 1 else [f"{key}{i + 1}" for i in range(n)]
        units = info.get(f"{key}_units")
        if not units or not any(units):
            units = getattr(model, f"{kind}_units_", None)
        if not units or len(units) != n:
            units = [""] * n
        out[f"{kind}_names"] = tuple(str(v) for v in names)
        out[f"{kind}_units"] = tuple(str(v) for v in units)
    return out


def _is_iv(model):
    return str(getattr(model, "method_", "")) in ("iv", "riv")


def _judged_by_input(model):
    """No noise model (``C/(A D) = 1``: OE, FIR) or an instrumental-variable fit."""
    if _is_iv(model):
        return True
    A, _, C, D, _ = model.polydata()
    return bool(np.all(A[:, :, 1:] == 0) and np.all(C[:, 1:] == 0) and np.all(D[:, 1:] == 0))


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
