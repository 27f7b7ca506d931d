"""Every figure rlsfilt draws: tracking, validation, frequency responses, order selection.

The result objects' ``plot`` methods (``ValidationReport.plot``,
``ResidualAnalysis.plot``, ``PlantComparison.plot``, ``FrequencyBand.plot``,
``OrderSelection.plot``, ``CusumResult.plot``, ``STRHistory.plot``) are
one-line calls into the functions of this module, so the report, the notebooks,
the documentation and the command line draw the same figures.

The tracking functions accept what the filters and models produce:

* the tuple returned by ``batch_filter`` (``means`` of shape ``(N, n, m)``
  and ``covariances`` of shape ``(N, n, n)``, or just its first two items);
* any object with a ``theta_history_`` attribute (``(N, n)``), such as a
  recursively fitted ARX model, with the covariances taken from its
  ``theta_cov_history_`` or, failing that, ``P_history_`` attribute;
* a plain array of estimates, with `covariances` given separately.

Conventions of every figure:

* colours from the colour-blind-safe palette of Okabe & Ito (2008), set per
  call (``COLORS``; matplotlib's global style is left alone); measured data
  and true systems are black;
* axes labelled with symbols and units (seconds when the model has a sample
  time, samples otherwise; rad/s or rad/sample; dB; degrees);
* legends outside the data area;
* long records drawn as a readable window plus an overview of the whole
  record; no line carries more than ``MAX_POINTS`` points (longer ones are
  reduced to their per-bin minima and maxima, which keeps every peak);
* new figures use matplotlib's constrained layout, so labels survive
  ``savefig`` without ``bbox_inches="tight"``.

matplotlib is imported only when a function is called, so ``import
rlsfilt`` stays light.

References
----------
.. [1] M. Okabe and K. Ito, "Color Universal Design (CUD): how to make
   figures and presentations that are friendly to colorblind people", 2008.
"""

import numpy as np

from ._validation import as_float_array, check_int

__all__ = [
    "COLORS",
    "MAX_POINTS",
    "plot_parameters",
    "plot_smoothed",
    "plot_profile_likelihood",
    "plot_trace",
    "plot_tracking",
    "plot_compare",
    "plot_comparison",
    "plot_autocorrelation",
    "plot_cross_correlation",
    "plot_residuals",
    "plot_bode",
    "plot_step",
    "plot_plant_comparison",
    "plot_frequency_band",
    "plot_order_selection",
    "plot_impulse",
    "plot_cusum",
    "plot_segmentation",
    "plot_report",
    "plot_str_history",
]

#: Okabe-Ito colours in the order lines are drawn (blue, vermillion, bluish green,
#: reddish purple, orange, sky blue, yellow); black is kept for data and true systems.
COLORS = ("#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442")
_BLACK = "#000000"
_GREY = "#7F7F7F"

#: Largest number of points of one drawn line; longer lines keep their per-bin extremes.
MAX_POINTS = 4000

#: Samples shown in the window of :func:`plot_comparison` when the record is longer.
_WINDOW = 400


def plot_profile_likelihood(result, ax=None, *, level=0.95, n_points=61):
    r"""Plot the profile log-likelihood of a tuned ``lam`` or ``q`` with its interval.

    Draws :math:`\ell_p(\theta) - \ell_p(\hat\theta)` over the parameter (``q``
    on a logarithmic axis), the estimate, the likelihood-ratio cut
    :math:`-\chi^2_1(\text{level}) / 2` (-1.92 at 95 %) and the interval
    where the curve lies above it (`TuneResult.likelihood_interval`), with the
    Wald interval of `TuneResult.interval` for comparison.

    Parameters
    ----------
    result : TuneResult
        What ``tune(..., "lam")`` or ``tune(..., "q")`` of a filter returns.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.
    level : float, default 0.95
        Confidence level of the intervals.
    n_points : int, default 61
        Points of the curve (one filter pass each).

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.plotting import plot_profile_likelihood
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((500, 1))
    >>> gain = 1 + np.cumsum(0.02 * rng.standard_normal(500))
    >>> z = H[:, 0] * gain + 0.1 * rng.standard_normal(500)
    >>> ax = plot_profile_likelihood(RecursiveLeastSquares(1).tune(z, H, "q"))
    >>> ax.get_xscale()
    'log'
    """
    n_points = check_int(n_points, "n_points", minimum=5)
    low, high = result.likelihood_interval(level)
    est = result.estimate
    cut = -0.5 * _chi2_ppf(level)
    is_q = result.param == "q"
    # the grid: on log q or log(1 - lam), the interval padded by 3/4 of its width (an
    # interval that reaches q = 0 or lam = 1 shown over 4 decades or 3 e-folds)
    if is_q:
        a, b = np.log(max(low, 1e-300)), np.log(high)
        a = max(a, b - np.log(1e4))
        pad = max(0.75 * min(b - a, np.log(10.0)), 0.05)
        grid = np.exp(np.linspace(a - pad, b + pad, n_points))
    else:
        a, b = np.log(max(1.0 - high, 1e-12)), np.log(1.0 - low)
        a = max(a, b - 3.0)
        pad = max(0.75 * min(b - a, 1.0), 0.05)
        grid = np.sort(1.0 - np.exp(np.linspace(a - pad, min(b + pad, np.log(0.999)),
                                                n_points)))
    rel = result.profile(grid) - result.loglik
    ax = _axes(ax)
    ax.plot(grid, rel, color=COLORS[0], lw=1.5, label=r"profile $\ell_p - \ell_p(\hat\theta)$")
    ax.axhline(cut, color=_GREY, lw=1.0, ls="--",
               label=rf"$-\chi^2_1({level:g})/2 = {cut:.2f}$")
    ax.axvline(est, color=COLORS[1], lw=1.2, label=f"estimate {est:.4g}")
    ax.axvspan(low, high, color=COLORS[0], alpha=0.12,
               label=f"{100 * level:g} % likelihood interval [{low:.4g}, {high:.4g}]")
    w_low, w_high = result.interval(level)
    if np.isfinite(w_low) and np.isfinite(w_high):
        ax.plot([w_low, w_high], [cut, cut], color=COLORS[2], lw=3, solid_capstyle="butt",
                label=f"Wald interval [{w_low:.4g}, {w_high:.4g}]")
    if is_q:
        from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

        ax.set_xscale("log")
        if grid[-1] / grid[0] < 300.0:                  # under 2.5 decades: 1, 2, 5 labelled
            ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
            ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:.3g}"))
            ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_ylim(max(float(np.nanmin(rel)), 4.0 * cut), 0.15 * -cut)
    symbol = r"$q = Q / R$" if is_q else r"$\lambda$"
    ax.set_xlabel(symbol)
    ax.set_ylabel(r"$\ell_p - \ell_p(\hat\theta)$")
    ax.set_title(f"profile log-likelihood of {symbol}")
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=2, fontsize="small")
    return ax


def _chi2_ppf(level):
    """The `level` quantile of chi-squared with one degree of freedom (scipy, lazily)."""
    from scipy.stats import chi2

    return float(chi2.ppf(level, 1))


# ----------------------------------------------------------------------
# tracking
# ----------------------------------------------------------------------
def plot_parameters(source, covariances=None, *, t=None, names=None, true_values=None,
                    n_std=2.0, output=0, xlabel=None, ax=None):
    r"""Plot parameter estimates over time with :math:`\pm` `n_std` standard-deviation bands.

    Parameters
    ----------
    source : tuple, array_like or object
        ``batch_filter`` output ``(means, covariances, ...)``, an array of
        estimates ``(N, n)`` or ``(N, n, m)``, or an object with
        ``theta_history_`` (see the module docstring).
    covariances : array_like, shape (N, n, n), optional
        Covariances of the estimates; overrides those found in `source`.
        Without covariances no bands are drawn.
    t : array_like, shape (N,), optional
        Time axis (sample index by default).
    names : sequence of str, optional
        Parameter names for the legend (``theta_1`` ... by default, or the
        object's ``param_names_`` if it has one).
    true_values : array_like, shape (n,) or (N, n), optional
        True parameters, drawn dashed (a trajectory when 2-D, e.g. for a
        parameter jump).
    n_std : float, default 2.0
        Half-width of the bands in standard deviations (2: about 95 %
        for Gaussian estimates). The band is :math:`\hat\theta_i \pm
        n_{std} \sqrt{P_{ii}}`, so ``P`` must be a covariance in the units
        of the parameters (``RecursiveLeastSquares.P`` is when ``R`` is the
        noise variance). The y-range covers the estimates, the true values
        and the bands wherever a band is narrower than the spread of the
        estimates; the broad prior of the first samples is drawn but does not
        set the scale.
    output : int, default 0
        Which output's column of ``(N, n, m)`` estimates to plot.
    xlabel : str, optional
        Label of the time axis (default ``"sample $k$"``, or ``"time"``
        when `t` is given).
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.plotting import plot_parameters
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((300, 2))
    >>> z = H @ [0.8, -0.3] + 0.1 * rng.standard_normal(300)
    >>> run = RecursiveLeastSquares(2, R=0.1 ** 2).batch_filter(z, H)
    >>> ax = plot_parameters(run, names=["a", "b"], true_values=[0.8, -0.3])
    >>> ax.get_ylabel()
    'estimate $\\hat\\theta$'
    """
    theta, covs, default_names = _resolve(source, covariances, output)
    N, n = theta.shape
    tt = _time_axis(t, N)
    names = _names(names, default_names, n)
    ax = _axes(ax)
    truth = None
    if true_values is not None:
        truth = as_float_array(true_values, "true_values")
        if truth.shape == (n,):
            truth = np.broadcast_to(truth, (N, n))
        elif truth.shape != (N, n):
            raise ValueError(f"`true_values` must have shape ({n},) or ({N}, {n}); got "
                             f"{truth.shape}")
    shown = [theta] if truth is None else [theta, truth]
    lo = min(float(np.nanmin(a)) for a in shown) if np.isfinite(theta).any() else np.nan
    hi = max(float(np.nanmax(a)) for a in shown) if np.isfinite(theta).any() else np.nan
    span = hi - lo
    widths = []                      # the median half-width of each band
    for i in range(n):
        color = _color(i)
        ax.plot(*_decimate(tt, theta[:, i]), color=color, lw=1.2, label=names[i])
        if covs is not None:
            sd = np.sqrt(np.clip(covs[:, i, i], 0.0, None))
            if np.isfinite(sd).any():
                widths.append(float(np.nanmedian(n_std * sd)))
            ax.fill_between(*_envelope(tt, theta[:, i] - n_std * sd, theta[:, i] + n_std * sd),
                            color=color, alpha=0.2, linewidth=0)
            # the y-range follows the bands only where they are informative: the broad prior
            # of the first samples (P0 = 1e4 I: +-200) would flatten every trajectory
            narrow = n_std * sd <= span
            if span > 0 and narrow.any():
                lo = min(lo, float(np.nanmin(theta[narrow, i] - n_std * sd[narrow])))
                hi = max(hi, float(np.nanmax(theta[narrow, i] + n_std * sd[narrow])))
        if truth is not None:
            ax.plot(*_decimate(tt, truth[:, i]), linestyle="--", color=_BLACK, lw=0.9)
    if covs is not None and span > 0:
        pad = 0.05 * (hi - lo)
        ax.set_ylim(lo - pad, hi + pad)
    ax.set_xlabel(_time_xlabel(xlabel, t))
    ax.set_ylabel(r"estimate $\hat\theta$")
    title = "parameter estimates"
    if covs is not None:
        # a band narrower than about 1 % of the axis is hidden under its line: say so
        # instead of promising bands the reader cannot see
        bottom, top = ax.get_ylim()
        if widths and max(widths) < 0.01 * (top - bottom):
            title += (rf" ($\pm{n_std:g}\sigma$ bands too narrow to see at this scale: "
                      rf"median ${n_std:g}\sigma \leq$ {max(widths):.2g})")
        else:
            title += rf" ($\pm{n_std:g}\sigma$ bands)"
    ax.set_title(title)
    extra = []
    if truth is not None:
        extra.append(_proxy(color=_BLACK, linestyle="--", lw=0.9, label="true"))
    _legend_outside(ax, extra=extra)
    return ax


def plot_smoothed(smoothed, *, t=None, names=None, true_values=None, n_std=2.0, output=0,
                  channel=0, filtered=True, xlabel=None, ax=None):
    r"""Plot the smoothed parameter trajectory over the filtered one, both with bands.

    Parameters
    ----------
    smoothed : SmoothedTrajectory
        What `rlsfilt.filters.smoother.rts_smoother` (or ``smooth()`` of a
        filter or bank) returns.
    t, names, true_values, n_std, output, xlabel
        As for :func:`plot_parameters`.
    channel : int, default 0
        Which channel of a bank's ``(N, C, n)`` trajectory to plot.
    filtered : bool, default True
        Draw the filtered estimates too (dotted, with fainter bands): they
        lag a drift and their bands are wider, the smoothed ones use the
        data after each step as well.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.plotting import plot_smoothed
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((300, 2))
    >>> drift = np.linspace(0.0, 0.5, 300)
    >>> z = H[:, 0] * (0.8 + drift) - 0.3 * H[:, 1] + 0.1 * rng.standard_normal(300)
    >>> rls = RecursiveLeastSquares(2, R=0.1 ** 2, Q=1e-5)
    >>> ax = plot_smoothed(rls.smooth(z, H), names=["a", "b"])
    >>> ax.get_title()
    'filtered (dotted) and smoothed estimates ($\\pm2\\sigma$ bands)'
    """
    means, covs = smoothed.means, smoothed.covariances
    f_means, f_covs = smoothed.filtered_means, smoothed.filtered_covariances
    if np.ndim(covs) == 4:                         # a bank: (N, C, n), (N, C, n, n)
        C = covs.shape[1]
        channel = check_int(channel, "channel", minimum=0)
        if channel >= C:
            raise ValueError(f"`channel` must be < {C} (the bank has {C} channels); "
                             f"got {channel}")
        means, covs = means[:, channel], covs[:, channel]
        f_means, f_covs = f_means[:, channel], f_covs[:, channel]
    ax = plot_parameters((means, covs), t=t, names=names, true_values=true_values,
                         n_std=n_std, output=output, xlabel=xlabel, ax=ax)
    extra = [_proxy(color=_GREY, lw=1.2, label="smoothed")]
    if filtered:
        ylim = ax.get_ylim()
        theta, fc, _ = _resolve((f_means, f_covs), None, output)
        tt = _time_axis(t, len(theta))
        for i in range(theta.shape[1]):
            sd = n_std * np.sqrt(np.clip(fc[:, i, i], 0.0, None))
            ax.plot(*_decimate(tt, theta[:, i]), color=_color(i), lw=0.9, linestyle=":")
            ax.fill_between(*_envelope(tt, theta[:, i] - sd, theta[:, i] + sd),
                            color=_color(i), alpha=0.07, linewidth=0)
        ax.set_ylim(*ylim)                         # the smoothed bands set the scale
        extra.append(_proxy(color=_GREY, lw=0.9, linestyle=":", label="filtered"))
    if true_values is not None:
        extra.append(_proxy(color=_BLACK, linestyle="--", lw=0.9, label="true"))
    ax.set_title(("filtered (dotted) and smoothed" if filtered else "smoothed")
                 + rf" estimates ($\pm{n_std:g}\sigma$ bands)")
    if ax.get_legend() is not None:
        ax.get_legend().remove()
    _legend_outside(ax, extra=extra)
    return ax


def plot_trace(source, covariances=None, *, t=None, log=True, xlabel=None, label=None,
               ax=None):
    r"""Plot :math:`\operatorname{tr} P` over time (covariance windup shows as growth).

    Parameters
    ----------
    source : tuple, array_like or object
        As for :func:`plot_parameters`; only the covariances are used.
    covariances : array_like, shape (N, n, n), optional
        Covariances; overrides those found in `source`.
    t : array_like, shape (N,), optional
        Time axis (sample index by default).
    log : bool, default True
        Logarithmic y axis (windup spans many decades).
    xlabel : str, optional
        Label of the time axis (as in :func:`plot_parameters`).
    label : str, optional
        Legend entry of the line, to compare several runs in one axes
        (the next colour of the palette is used for each further line).
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.plotting import plot_trace
    >>> H = np.column_stack([np.ones(200), np.r_[np.ones(100), np.zeros(100)]])
    >>> run = RecursiveLeastSquares(2, lam=0.95).batch_filter(H.sum(axis=1), H)
    >>> ax = plot_trace(run)          # tr P grows once the second regressor stops
    >>> ax.get_yscale()
    'log'
    """
    _, covs, _ = _resolve(source, covariances, 0, need_covariances=True)
    tr = np.trace(covs, axis1=1, axis2=2)
    tt = _time_axis(t, len(tr))
    ax = _axes(ax)
    color = _color(sum(1 for ln in ax.get_lines() if ln.get_label()[:1] != "_"))
    ax.plot(*_decimate(tt, tr), color=color, lw=1.2,
            label=label if label is not None else r"$\mathrm{tr}\,P$")
    _trace_axis(ax, tr, log)
    ax.set_xlabel(_time_xlabel(xlabel, t))
    ax.set_title("trace of the covariance")
    if label is not None:
        _legend_outside(ax)
    return ax


def plot_tracking(source, covariances=None, *, t=None, names=None, true_values=None,
                  n_std=2.0, output=0, log=True, xlabel=None, fig=None):
    r"""Parameter trajectories (top) and :math:`\mathrm{tr}\,P` or the a-priori errors (bottom).

    Parameters are those of :func:`plot_parameters` and :func:`plot_trace`;
    `fig` is a matplotlib Figure to draw in (a new one if omitted).

    The bottom panel shows :math:`\mathrm{tr}\,P` when covariances are
    available (``batch_filter`` output, `covariances`, or an object's
    ``theta_cov_history_`` / ``P_history_``). Otherwise it shows the
    a-priori residuals :math:`y(t) - \varphi(t)^T\hat\theta(t-1)` of an
    object that has ``recursive_residuals_`` (an ``ARX`` fitted with
    ``method="rls"``, which keeps no covariance history): the errors the
    filter made, which jump when the plant changes. Without either, a
    ``ValueError`` says what to pass.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import time_varying
    >>> from rlsfilt.plotting import plot_tracking
    >>> ds = time_varying(rng=0)
    >>> model = ARX(*ds.orders).fit(ds.u, ds.y, method="rls", lam=0.98)
    >>> fig = plot_tracking(model, true_values=ds.theta_true[model.max_lag:])
    >>> fig.axes[1].get_ylabel()
    'a-priori error $\\varepsilon(t)$'
    """
    _, covs, _ = _resolve(source, covariances, output)
    errors = None
    if covs is None:
        errors = getattr(source, "recursive_residuals_", None)
        if errors is None:
            raise ValueError(
                "plot_tracking needs covariances (batch_filter's (means, covariances), "
                "`covariances=`, or an object with theta_cov_history_ or P_history_) or an "
                "object with recursive_residuals_ (an ARX fitted with method='rls'); use "
                "plot_parameters for estimates alone")
    fig = _figure(fig, figsize=(8, 6), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1, sharex=True, height_ratios=[2, 1])
    plot_parameters(source, covariances, t=t, names=names, true_values=true_values,
                    n_std=n_std, output=output, xlabel=xlabel, ax=ax1)
    if covs is not None:
        plot_trace(source, covariances, t=t, log=log, xlabel=xlabel, ax=ax2)
    else:
        e = as_float_array(errors, "recursive_residuals_")
        e = e if e.ndim == 1 else e[:, output]
        tt = _time_axis(t, len(e))
        ax2.plot(*_decimate(tt, e), color=_color(0), lw=0.8)
        ax2.axhline(0.0, color=_BLACK, lw=0.6)
        ax2.set_ylabel(r"a-priori error $\varepsilon(t)$")
        ax2.set_title(r"one-step errors of the filter, $y(t) - \varphi(t)^T\hat\theta(t-1)$")
        ax2.set_xlabel(_time_xlabel(xlabel, t))
    ax1.set_xlabel("")
    return fig


# ----------------------------------------------------------------------
# model output against the data
# ----------------------------------------------------------------------
def plot_compare(comparison, ax=None, *, window=None, output=0):
    """Measured against simulated or predicted output of :func:`~rlsfilt.validation.compare`.

    Parameters
    ----------
    comparison : Comparison
        What :func:`~rlsfilt.validation.compare` returned.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure if omitted.
    window : (int, int), optional
        First and last-plus-one sample shown (default: the whole record).
    output : int, default 0
        Which output to show (for several outputs).

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import OE, compare
    >>> from rlsfilt.plotting import plot_compare
    >>> u = np.random.default_rng(0).standard_normal(300)
    >>> y = lfilter([0, 0.5], [1, -0.8], u)
    >>> ax = plot_compare(compare(OE(1, 1).fit(u, y), u, y))
    >>> ax.get_title()
    'Model output against the data: initial state estimated (least squares over the record)'
    """
    y = _column(comparison.y, output)
    yh = _column(comparison.y_hat, output)
    dt = comparison.model.dt
    t = (1.0 if dt is True else float(dt)) * np.arange(len(y))
    a, b = (0, len(y)) if window is None else (int(window[0]), int(window[1]))
    if ax is None:
        fig = _figure(None, figsize=(10, 4), layout="constrained")
        ax = fig.subplots()
    name, unit = _signal_label(comparison, "output", output)
    fit = np.atleast_1d(comparison.fit)[output]
    ax.plot(t[a:b], y[a:b], color=_BLACK, lw=3.2, alpha=0.8, solid_capstyle="butt",
            label=f"measured {name}")
    ax.plot(t[a:b], yh[a:b], color=COLORS[0], lw=1.1,
            label=f"{comparison.what} (fit {fit:.1f}%)")
    ax.set_xlabel(_time_unit(dt))
    ax.set_ylabel(name + (f" ({unit})" if unit else ""))
    ax.set_title(f"Model output against the data: {comparison.initial_text}")
    ax.set_xlim(t[a], t[b - 1])
    _legend_outside(ax)
    return ax


def plot_comparison(report, ax=None, *, window=None, ax_overview=None, output=0,
                    output_name=None, output_unit=None):
    """Measured, simulated and one-step predicted output (MATLAB ``compare``).

    A record longer than the window is drawn as a readable window (`ax`)
    plus, in `ax_overview`, the whole record with the window marked. The
    experiments of a record of several are drawn one after the other on one
    time axis, their seams dotted, no line joining two experiments.

    Parameters
    ----------
    report : ValidationReport
        What :func:`~rlsfilt.validation.validate` returned.
    ax : matplotlib.axes.Axes, optional
        Axes for the window. If omitted, a new figure is made with the
        window on top and, for a record longer than the window, an overview
        below.
    window : (int, int), optional
        First and last-plus-one sample of the window (indices into the
        report's record, the experiments one after the other). By default
        the last 400 samples (the whole record when it is shorter than 600
        samples). A window longer than ``MAX_POINTS`` samples is drawn
        through its per-bin extremes.
    ax_overview : matplotlib.axes.Axes, optional
        Axes for the overview of the whole record (none is drawn when `ax`
        is given without `ax_overview`). When the output sits far from zero
        (its mean more than 3 standard deviations away, an operating
        point), the simulation error is drawn around the output's mean, and
        its legend says so, so that both lines keep a readable scale.
    output : int, default 0
        Which output to show (for several outputs).
    output_name : str, optional
        Name of the output signal, for the labels. Default: the report's
        ``output_names`` (the data's names, or the model's), else ``"y"``.
    output_unit : str, optional
        Unit of the output, for the y label (e.g. ``"K"``). Default: the
        report's ``output_units`` (the data's or the model's), if any.

    Returns
    -------
    matplotlib.axes.Axes
        The window's axes.

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX, validate
    >>> from rlsfilt.datasets import dc_motor, heat_exchanger
    >>> from rlsfilt.plotting import plot_comparison
    >>> d = dc_motor()
    >>> report = validate(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), d.u, d.y)
    >>> ax = plot_comparison(report, output_name="speed", output_unit="rad/s")
    >>> ax.get_ylabel(), len(ax.figure.axes)          # window + overview of 2000 samples
    ('speed (rad/s)', 2)

    Names and units come from the data when it carries them:

    >>> he = heat_exchanger()
    >>> rep = validate(ARX(*he.orders, dt=he.dt, offset=True).fit(he), he)
    >>> plot_comparison(rep).get_ylabel()
    'T_out (degC)'
    """
    y = _column(report.y, output)
    ys = _column(report.y_simulated, output)
    yp = _column(report.y_predicted, output)
    output_name, output_unit = _signal_label(report, "output", output, output_name,
                                             output_unit)
    t, seams, exp_names = _record_time(report)
    # the first `start` (max_lag) predictions of each experiment come from an assumed past,
    # not from the measurements: the fits leave them out, and so does the figure
    start = int(getattr(report, "start", 0) or 0)
    if start:
        yp = yp.copy()
        for k in (0, *seams):
            yp[k:k + start] = np.nan
    N = len(y)
    a, b = _window(window, N)
    windowed = (a, b) != (0, N)
    if ax is None:
        if windowed:
            fig = _figure(None, figsize=(10, 5), layout="constrained")
            ax, ax_overview = fig.subplots(2, 1, height_ratios=[3, 1])
        else:
            fig = _figure(None, figsize=(10, 4), layout="constrained")
            ax = fig.subplots()
    sf = np.atleast_1d(report.simulation_fit)[output]
    pf = np.atleast_1d(report.prediction_fit)[output]
    time_label = _time_unit(report.model.dt)
    if seams:
        time_label += ", experiments one after the other"
    ylabel = output_name + (f" ({output_unit})" if output_unit else "")
    inside = [k for k in seams if a < k < b]
    # the measured output is a wide black line under the thinner model lines: where the
    # model is good it shows on both sides of them instead of disappearing underneath
    ax.plot(*_broken(t, y, a, b, inside), color=_BLACK, lw=3.2, alpha=0.8,
            solid_capstyle="butt", label=f"measured {output_name}")
    time_series = getattr(report, "is_time_series", False)
    if time_series:     # AR, ARMA: no input, nothing to simulate
        ax.plot([], [], color=COLORS[0], lw=1.2, label="no simulation (time series: no input)")
    elif getattr(report, "is_unstable", False):
        # a diverging simulation would set the scale and its "fit" means nothing: say so
        ax.plot([], [], color=COLORS[0], lw=1.2, label=f"simulated: {report.stability}")
    else:
        ax.plot(*_broken(t, ys, a, b, inside), color=COLORS[0], lw=1.1,
                label=f"simulated (fit {sf:.1f}%{_initial_tag(report)})")
    ax.plot(*_broken(t, yp, a, b, inside), color=COLORS[1], lw=1.0,
            linestyle="--", label=f"1-step predicted (fit {pf:.1f}%{_initial_tag(report)})")
    for k in inside:
        ax.axvline(_seam_time(t, k), color=_GREY, lw=1.0, linestyle=":")
    ax.set_xlabel(time_label)
    ax.set_ylabel(ylabel)
    title = "Model output against the data"
    if seams:
        first = int(np.searchsorted(seams, a, side="right"))
        last = int(np.searchsorted(seams, b - 1, side="right"))
        title += f" ({', '.join(exp_names[first:last + 1])})"
    ax.set_title(title)
    ax.set_xlim(t[a], t[b - 1])
    _legend_outside(ax)
    if ax_overview is not None:
        # per-bin extremes: a long record reads as its envelope, a single outlier stays visible
        ax_overview.plot(*_broken(t, y, 0, N, seams), color=_GREY, lw=0.7,
                         label=f"measured {output_name}")
        if not (getattr(report, "is_unstable", False) or time_series):
            # around an operating point the error (near 0) and the output (near its mean)
            # would squash each other to two flat lines: draw the error around the mean
            level, spread = float(np.mean(y)), float(np.std(y))
            shift = level if abs(level) > 3.0 * spread else 0.0
            tag = f" (+ {shift:.4g}, the mean)" if shift else ""
            ax_overview.plot(*_broken(t, y - ys + shift, 0, N, seams),
                             color=COLORS[1], lw=0.7,
                             label=f"error {output_name} - simulated{tag}")
        for k in seams:
            ax_overview.axvline(_seam_time(t, k), color=_BLACK, lw=0.8, linestyle=":")
        span = f"whole record ({N} samples)"
        if seams:
            lengths = np.diff([0, *seams, N])
            span = "whole record: " + ", ".join(
                f"{name} ({n})" for name, n in zip(exp_names, lengths)) + " samples"
        if windowed:
            # the window stays visible however long the record: at least 0.5 % of the width
            lo, hi = t[a], t[b - 1]
            grow = max(0.0, 0.005 * (t[-1] - t[0]) - (hi - lo))
            ax_overview.axvspan(lo - grow, hi, color=COLORS[4], alpha=0.35, linewidth=0,
                                zorder=0, label="window shown above")
            first, last = (a, b - 1) if report.model.dt is True else (t[a], t[b - 1])
            span += f"; window {first:g} .. {last:g} shaded"
        ax_overview.set_xlim(t[0], t[-1])
        ax_overview.set_xlabel(time_label)
        ax_overview.set_ylabel(ylabel)
        ax_overview.set_title(span, fontsize="medium", loc="left")
        _legend_outside(ax_overview)
    return ax


# ----------------------------------------------------------------------
# residual tests
# ----------------------------------------------------------------------
def plot_autocorrelation(analysis, ax=None):
    r"""Stem plot of the residual autocorrelation :math:`\hat\rho_\varepsilon(k)`, lags 1 .. max.

    Lag 0 (always 1) is left out, so the ``1 - alpha`` band under whiteness
    sets the scale.

    Parameters
    ----------
    analysis : ResidualAnalysis
        What :func:`~rlsfilt.validation.residual_analysis` returned.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import dc_motor
    >>> from rlsfilt.validation import residual_analysis
    >>> from rlsfilt.plotting import plot_autocorrelation
    >>> d = dc_motor()
    >>> ax = plot_autocorrelation(residual_analysis(ARX(2, 2, 1).fit(d.u, d.y), d.u, d.y))
    >>> float(ax.get_xlim()[0]) > 0                   # lag 0 is not drawn
    True
    """
    ax = _axes(ax)
    lags = np.asarray(analysis.lags)
    rho = np.asarray(analysis.autocorrelation, dtype=float)
    keep = lags > 0
    lags, rho = lags[keep], rho[keep]
    band = float(analysis.autocorrelation_band)
    ax.axhspan(-band, band, color=COLORS[5], alpha=0.35, linewidth=0)
    ax.vlines(lags, 0.0, rho, color=COLORS[0], lw=1.2)
    outside = np.abs(rho) > band
    ax.plot(lags[~outside], rho[~outside], "o", color=COLORS[0], ms=3.5)
    ax.plot(lags[outside], rho[outside], "o", color=COLORS[1], ms=4.5)
    _zero_line_and_scale(ax, band, rho)
    ax.set_xlim(0.4, lags.max() + 0.6 if lags.size else 1.6)
    ax.set_xlabel("lag $k$ (samples)")
    ax.set_ylabel(r"$\hat\rho_\varepsilon(k)$")
    _test_title(ax, "Residual autocorrelation", "white" if analysis.is_white else "NOT white",
                analysis.pvalue_white, analysis.alpha, "whiteness", "Ljung-Box test",
                int(outside.sum()), int(lags.size))
    return ax


def plot_cross_correlation(analysis, ax=None):
    r"""Cross-correlation :math:`\hat\rho_{\varepsilon u}(\tau)` of the residuals with each input.

    Parameters
    ----------
    analysis : ResidualAnalysis
        What :func:`~rlsfilt.validation.residual_analysis` returned.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import dc_motor
    >>> from rlsfilt.validation import residual_analysis
    >>> from rlsfilt.plotting import plot_cross_correlation
    >>> d = dc_motor()
    >>> ax = plot_cross_correlation(residual_analysis(ARX(2, 2, 1).fit(d.u, d.y), d.u, d.y))
    >>> ax.get_xlabel()
    'lag $\\tau$ (samples; $\\tau > 0$: past inputs)'
    """
    ax = _axes(ax)
    xc = np.asarray(analysis.cross_correlation, dtype=float)
    nu = xc.shape[0]
    if nu == 0:         # a time series (AR, ARMA): no input to correlate with
        ax.text(0.5, 0.5, "no input (time series):\nno cross-correlation, no independence test",
                ha="center", va="center", transform=ax.transAxes)
        ax.set_title("Input cross-correlation: not applicable", fontsize="medium")
        ax.set_axis_off()
        return ax
    bands = np.atleast_1d(analysis.cross_correlation_band)
    for j in range(nu):
        color = _color(j)
        ax.fill_between(analysis.cross_lags, -bands[j], bands[j], color=color, alpha=0.2,
                        linewidth=0)
        ax.plot(analysis.cross_lags, xc[j], "o-", ms=3, lw=1.0, color=color,
                label=f"input {j}" if nu > 1 else None)
    _zero_line_and_scale(ax, float(np.max(bands)), xc)
    ax.set_xlabel(r"lag $\tau$ (samples; $\tau > 0$: past inputs)")
    ax.set_ylabel(r"$\hat\rho_{\varepsilon u}(\tau)$")
    n_out = int(sum(np.sum(np.abs(xc[j]) > bands[j]) for j in range(nu)))
    _test_title(ax, "Input cross-correlation",
                "independent" if analysis.is_independent else "NOT independent",
                analysis.pvalue_independent, analysis.alpha, "independence", "F-test",
                n_out, int(xc.size))
    if nu > 1:
        _legend_outside(ax)
    return ax


def plot_residuals(analysis, fig=None):
    """Autocorrelation and input cross-correlations with their bands (MATLAB ``resid``).

    Parameters
    ----------
    analysis : ResidualAnalysis
        What :func:`~rlsfilt.validation.residual_analysis` returned.
    fig : matplotlib.figure.Figure, optional
        Figure to draw in (it should be empty); a new one if omitted.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import mass_spring_damper
    >>> from rlsfilt.validation import residual_analysis
    >>> from rlsfilt.plotting import plot_residuals
    >>> d = mass_spring_damper()
    >>> fig = plot_residuals(residual_analysis(ARX(1, 1, 1).fit(d.u, d.y), d.u, d.y))
    >>> "NOT white" in fig.axes[0].get_title()         # a first-order model is too simple
    True
    """
    fig = _figure(fig, figsize=(8, 6), layout="constrained")
    ax1, ax2 = fig.subplots(2, 1)
    plot_autocorrelation(analysis, ax1)
    plot_cross_correlation(analysis, ax2)
    return fig


# ----------------------------------------------------------------------
# frequency and step responses
# ----------------------------------------------------------------------
def plot_bode(source, ax_mag=None, ax_phase=None, *, band=None, plant=None):
    r"""Bode magnitude (dB) and phase (deg) on a logarithmic frequency axis.

    Parameters
    ----------
    source : PlantComparison or FrequencyBand
        A comparison with the true plant (model dashed over the plant) or a
        model's frequency response with its uncertainty band.
    ax_mag, ax_phase : matplotlib.axes.Axes, optional
        Axes for magnitude and phase; a new figure with both is made unless
        both are given.
    band : FrequencyBand, optional
        With a `PlantComparison`: the model's uncertainty band, drawn under
        the two responses (its frequencies may differ from the comparison's).
    plant : control.LTI, optional
        With a `FrequencyBand`: a discrete system with the model's sample
        time to overlay (black, dashed).

    Returns
    -------
    (matplotlib.axes.Axes, matplotlib.axes.Axes)
        The magnitude and phase axes.

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import dc_motor
    >>> from rlsfilt.validation import frequency_response_band
    >>> from rlsfilt.plotting import plot_bode
    >>> d = dc_motor()
    >>> band = frequency_response_band(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), rng=0)
    >>> ax_mag, ax_phase = plot_bode(band, plant=d.plant)
    >>> ax_mag.get_xscale(), ax_mag.get_ylabel()
    ('log', '$|G(e^{j\\omega T})|$ (dB)')
    """
    ax_mag, ax_phase = _bode_axes(ax_mag, ax_phase)
    if hasattr(source, "response_plant"):
        if band is not None:
            _draw_band(ax_mag, ax_phase, band, model_line=False)
        _draw_comparison_bode(ax_mag, ax_phase, source)
        unit = "rad/sample" if source.dt == 1.0 and source.model_tf.dt is True else "rad/s"
        ax_mag.set_title(f"Bode: max relative error {100 * source.frequency_error:.3g}%")
    elif hasattr(source, "magnitude_lower"):
        _draw_band(ax_mag, ax_phase, source)
        if plant is not None:
            _draw_plant_bode(ax_mag, ax_phase, source, plant)
        unit = "rad/sample" if source.dt_unspecified else "rad/s"
        ax_mag.set_title("Frequency response")
    else:
        raise TypeError("`source` must be a PlantComparison or a FrequencyBand; got "
                        f"{type(source).__name__}")
    drawn = band if band is not None else (source if hasattr(source, "magnitude_lower")
                                           else None)
    if drawn is not None:   # a band narrower than the line is there: say how wide it is
        ax_mag.set_title(ax_mag.get_title() + "\n" + _band_width_text(drawn),
                         fontsize="medium")
    ax_mag.set_ylabel("$|G(e^{j\\omega T})|$ (dB)")
    ax_phase.set_ylabel("phase (deg)")
    ax_phase.set_xlabel(f"$\\omega$ ({unit})")
    for ax in (ax_mag, ax_phase):
        ax.set_xscale("log")
        ax.grid(True, which="both", alpha=0.3)
    _legend_outside(ax_mag)
    return ax_mag, ax_phase


def plot_step(comparison, ax=None, *, input_unit=None, output_unit=None):
    """Unit-step responses of model (dashed) and true plant (black).

    Parameters
    ----------
    comparison : PlantComparison
        A comparison of a model with its true plant.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.
    input_unit, output_unit : str, optional
        Units of the input and output (one-input, one-output models): the y
        label then reads ``"T_out (degC) per 1 % of flow"``, with the signal
        names from the model (its python-control signal labels).

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import heat_exchanger, thermal_process
    >>> from rlsfilt.validation import PlantComparison
    >>> from rlsfilt.plotting import plot_step
    >>> d = thermal_process()
    >>> ax = plot_step(PlantComparison(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), d.plant))
    >>> ax.get_xlabel()
    'time (s)'
    >>> he = heat_exchanger()
    >>> cmp = PlantComparison(ARX(*he.orders, dt=he.dt, offset=True).fit(he), he.plant)
    >>> plot_step(cmp, input_unit="%", output_unit="degC").get_ylabel()
    'T_out (degC) per 1 % of flow'
    """
    ax = _axes(ax)
    for c, ((i, j), label) in enumerate(_channels(comparison.step_plant.shape[:2])):
        ax.step(comparison.time, comparison.step_plant[i, j], color=_BLACK, lw=1.6,
                where="post", label=f"plant{label}")
        ax.step(comparison.time, comparison.step_model[i, j], color=_color(c), lw=1.4,
                linestyle="--", where="post", label=f"model{label}")
    ax.set_xlabel("time" if comparison.model_tf.dt is True else "time (s)")
    ax.set_ylabel(_step_label(comparison.model_tf, input_unit, output_unit))
    ax.set_title(f"Step: relative error {100 * comparison.step_error:.3g}%")
    ax.grid(True, alpha=0.3)
    _legend_outside(ax)
    return ax


def _step_label(tf, input_unit, output_unit):
    """``"T_out (degC) per 1 % of flow"`` for a one-channel model with named signals,
    ``"step response $y(t)$"`` otherwise."""
    if tf.ninputs != 1 or tf.noutputs != 1:
        return "step response $y(t)$"
    u_name, y_name = _tf_label(tf, "input"), _tf_label(tf, "output")
    if u_name in (None, "u") and y_name in (None, "y") and not input_unit and not output_unit:
        return "step response $y(t)$"
    y_text = (y_name or "y") + (f" ({output_unit})" if output_unit else "")
    u_text = f"1 {input_unit} of " if input_unit else "a unit step of "
    return f"{y_text} per {u_text}{u_name or 'u'}"


def _tf_label(tf, kind):
    """The signal label of a one-channel python-control system, None for its defaults
    (``u[0]``, ``y[0]``)."""
    labels = getattr(tf, f"{kind}_labels", None) or []
    label = str(labels[0]) if labels else ""
    default = "u[0]" if kind == "input" else "y[0]"
    return None if not label or label == default else label


def plot_plant_comparison(comparison, fig=None, *, band=None):
    """Bode diagram and step responses of a model over its true plant.

    Parameters
    ----------
    comparison : PlantComparison
        A comparison of a model with its true plant.
    fig : matplotlib.figure.Figure, optional
        Figure to draw in (it should be empty); a new one if omitted.
    band : FrequencyBand, optional
        The model's uncertainty band, drawn in the Bode diagram.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import dc_motor
    >>> from rlsfilt.validation import PlantComparison
    >>> from rlsfilt.plotting import plot_plant_comparison
    >>> d = dc_motor()
    >>> fig = plot_plant_comparison(PlantComparison(ARX(2, 2, 1, dt=d.dt).fit(d.u, d.y),
    ...                                             d.plant))
    >>> len(fig.axes)
    3
    """
    fig = _figure(fig, figsize=(11, 6), layout="constrained")
    gs = fig.add_gridspec(2, 2)
    ax_mag = fig.add_subplot(gs[0, 0])
    ax_phase = fig.add_subplot(gs[1, 0], sharex=ax_mag)
    ax_step = fig.add_subplot(gs[:, 1])
    plot_bode(comparison, ax_mag, ax_phase, band=band)
    plot_step(comparison, ax_step)
    return fig


def plot_frequency_band(band, fig=None, *, plant=None):
    """Bode diagram of a model with its uncertainty band; optionally the true plant on top.

    Parameters
    ----------
    band : FrequencyBand
        What :func:`~rlsfilt.validation.frequency_response_band` returned.
    fig : matplotlib.figure.Figure, optional
        Figure to draw in (empty); a new one if omitted.
    plant : control.LTI, optional
        A discrete system with the model's sample time to overlay.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import dc_motor
    >>> from rlsfilt.validation import frequency_response_band
    >>> from rlsfilt.plotting import plot_frequency_band
    >>> d = dc_motor(n_samples=300)
    >>> band = frequency_response_band(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), rng=0)
    >>> [t.get_text() for t in plot_frequency_band(band, plant=d.plant).axes[0]
    ...  .get_legend().get_texts()]
    ['95% band', 'model', 'plant']
    """
    fig = _figure(fig, figsize=(8, 6), layout="constrained")
    ax_mag, ax_phase = fig.subplots(2, 1, sharex=True)
    plot_bode(band, ax_mag, ax_phase, plant=plant)
    return fig


# ----------------------------------------------------------------------
# order selection and structural change
# ----------------------------------------------------------------------
def plot_order_selection(selection, ax=None):
    """Criterion against the number of parameters (as MATLAB's ``selstruc``).

    Every candidate is a dot; the line joins the best candidate of each
    size, and the selected structure is marked.

    Parameters
    ----------
    selection : OrderSelection
        What :func:`~rlsfilt.validation.select_order` returned.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import select_order
    >>> from rlsfilt.datasets import dc_motor
    >>> from rlsfilt.plotting import plot_order_selection
    >>> d = dc_motor()
    >>> ax = plot_order_selection(select_order(d.u, d.y, na=range(1, 4), nb=range(1, 4)))
    >>> ax.get_ylabel()
    'BIC'
    """
    ax = _axes(ax)
    d = selection.table["n_params"]
    v = selection.values
    ax.plot(d, v, "o", color=COLORS[0], alpha=0.45, ms=4.5, label="candidates")
    sizes = np.unique(d)
    best_per = [np.nanmin(v[d == s]) for s in sizes]
    ax.plot(sizes, best_per, "-", color=COLORS[0], lw=1.2, label="best of each size")
    i = selection.best_index
    ax.plot(d[i], v[i], "*", color=COLORS[1], ms=15, mec=_BLACK, mew=0.6,
            label=f"selected (na, nb, nk) = {selection.best}")
    ax.set_xlabel("number of parameters $d$")
    crit = selection.criterion
    ax.set_ylabel(crit.upper() if crit != "loss" else "loss $V$")
    ax.set_title("ARX order selection")
    ax.grid(True, alpha=0.3)
    _legend_outside(ax)
    return ax


def plot_impulse(impulse, ax=None, *, level=0.99):
    r"""Impulse-response coefficients :math:`\hat g_j(k)` with their confidence band.

    One panel per input (MATLAB's ``impulseest`` plot with ``showConfidence``):
    stems for the coefficients, the shaded pointwise `level` band around zero
    (a coefficient outside it differs significantly from zero), the first
    significant lag marked.

    Parameters
    ----------
    impulse : ImpulseResponse
        What :func:`~rlsfilt.validation.impulseest` returned.
    ax : matplotlib.axes.Axes or sequence of them, optional
        One axes per input; a new figure is made if omitted.
    level : float, default 0.99
        Confidence level of the band.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.validation import impulseest
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(1000)
    >>> y = lfilter([0, 0, 1.0], [1, -0.5], u) + 0.1 * rng.standard_normal(1000)
    >>> fig = impulseest(u, y, n_coeffs=20).plot()
    >>> "first significant lag 2" in fig.axes[0].get_title()
    True
    """
    nu = impulse.n_inputs
    if ax is None:
        fig = _figure(figsize=(7, 2.2 + 2.2 * nu), layout="constrained")
        axes = np.atleast_1d(fig.subplots(nu, 1, sharex=True))
    else:
        axes = np.atleast_1d(ax)
        if axes.size != nu:
            raise ValueError(f"`ax` must hold one axes per input ({nu}); got {axes.size}")
        fig = axes[0].figure
    z = impulse.z_value(level)
    lags = impulse.lags * (1.0 if impulse.dt is True else float(impulse.dt))
    sig = impulse.significant(level)
    for j, axj in enumerate(axes):
        g, half = impulse.coefficients[:, j], z * impulse.stderr[:, j]
        axj.fill_between(lags, -half, half, step="mid", color=COLORS[5], alpha=0.35,
                         linewidth=0)
        axj.vlines(lags, 0.0, g, color=COLORS[0], lw=1.2)
        axj.plot(lags[~sig[:, j]], g[~sig[:, j]], "o", color=COLORS[0], ms=3.5)
        axj.plot(lags[sig[:, j]], g[sig[:, j]], "o", color=COLORS[1], ms=4.5)
        axj.axhline(0.0, color=_BLACK, lw=0.6)
        first = np.flatnonzero(sig[:, j])
        text = (f"first significant lag {first[0]}" if first.size else "no significant lag")
        if first.size:
            axj.axvline(lags[first[0]], color=COLORS[1], lw=0.8, ls="--")
        name = impulse.input_names[j]
        reg = impulse.regularization
        how = f" ({reg.upper()} kernel, posterior)" if reg else ""
        axj.set_title(f"Impulse response {name} to {impulse.output_name}{how}: {text}\n"
                      f"shaded: {100 * level:g}% band per lag (+-{z:.3g} standard errors)",
                      fontsize="medium")
        axj.set_ylabel(rf"$\hat g(k)$ ({name})")
    axes[-1].set_xlabel("lag $k$ (samples)" if impulse.dt is True else "lag (s)")
    return fig


def plot_cusum(result, ax=None, *, t=None, xlabel=None):
    r"""CUSUM or CUSUM-of-squares path with its significance lines.

    When the test rejects constancy, the stretches of the path outside the
    lines are drawn thick, and the sample where the path departs furthest
    from its expected course (zero for the CUSUM, the diagonal for the
    CUSUM of squares) is marked: it estimates when the parameters changed.
    The first crossing is not marked: the CUSUM of squares of a record whose
    noise grows after a change leaves the lines long before the change.
    When constancy is not rejected, nothing is marked.

    Parameters
    ----------
    result : CusumResult
        What :func:`~rlsfilt.validation.cusum` or
        :func:`~rlsfilt.validation.cusum_squares` returned.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.
    t : array_like, shape (N,), optional
        Time (or sample number) of each regression row ``zs[r]``, so the
        marks are read in the record's own samples. For an ARX regression
        ``model.regressors(u, y)`` row ``r`` is sample ``r + max_lag``:
        pass ``t=np.arange(max_lag, N)`` (or ``ds.t[max_lag:]``). By
        default the row index is used.
    xlabel : str, optional
        Label of the time axis (default ``"sample $t$"``).

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> import numpy as np
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import time_varying
    >>> from rlsfilt.validation import cusum_squares
    >>> from rlsfilt.plotting import plot_cusum
    >>> ds = time_varying(rng=0)                      # the parameters jump at t = 1000
    >>> Phi, z = ARX(*ds.orders).regressors(ds.u, ds.y)
    >>> ax = plot_cusum(cusum_squares(z, Phi), t=np.arange(2, len(ds.y)))
    >>> ax.get_legend().get_texts()[-1].get_text()
    'largest departure at $t$ = 999'
    """
    ax = _axes(ax)
    index = np.asarray(result.index)
    if t is None:
        x = index.astype(float)
    else:
        tt = as_float_array(t, "t")
        if tt.ndim != 1 or tt.shape[0] <= index.max():
            raise ValueError(f"`t` must have shape (N,) with one time per regression row "
                             f"(at least {index.max() + 1}); got {tt.shape}")
        x = tt[index]
    name = "CUSUM" if result.kind == "cusum" else "CUSUM of squares"
    stat = np.asarray(result.statistic, dtype=float)
    lower, upper = (np.asarray(b, dtype=float) for b in result.bounds)
    if result.kind == "cusum":
        centre = np.zeros_like(stat)
    else:
        m = len(index)
        centre = np.arange(1, m + 1) / m
    ax.fill_between(*_envelope(x, lower, upper), color=COLORS[5], alpha=0.25, linewidth=0,
                    label=f"{100 * (1 - result.alpha):g}% region under constancy")
    ax.plot(*_decimate(x, centre), color=_GREY, lw=0.8)
    ax.plot(*_decimate(x, lower), color=_BLACK, lw=1.0, linestyle="--")
    ax.plot(*_decimate(x, upper), color=_BLACK, lw=1.0, linestyle="--")
    ax.plot(*_decimate(x, stat), color=COLORS[0], lw=1.4, label=name)
    if result.rejected:
        # the path outside the lines, thick (NaN elsewhere breaks the line there)
        outside = np.where((stat < lower) | (stat > upper), stat, np.nan)
        ax.plot(*_decimate(x, outside), color=COLORS[1], lw=3.0, alpha=0.6,
                label="outside the lines")
        k = int(np.argmax(np.abs(stat - centre)))
        ax.axvline(x[k], color=COLORS[1], lw=1.2, alpha=0.8,
                   label=f"largest departure at $t$ = {x[k]:g}")
    ax.set_xlabel(xlabel if xlabel is not None else "sample $t$")
    ax.set_ylabel("$W_t$" if result.kind == "cusum" else "$S_t$")
    ax.set_title(f"{name}: constancy " + ("REJECTED" if result.rejected else "not rejected")
                 + f" at {100 * result.alpha:g}%")
    _legend_outside(ax)
    return ax


def plot_segmentation(segmentation, ax=None, *, names=None, true_values=None):
    r"""Piecewise-constant parameters of a segmentation, with its change times.

    Parameters
    ----------
    segmentation : Segmentation
        What :func:`~rlsfilt.validation.segment` returned.
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.
    names : sequence of str, optional
        Parameter names (:math:`\theta_1, \dots` by default).
    true_values : array_like, shape (N, n_params), optional
        True parameters per sample, drawn dashed.

    Returns
    -------
    matplotlib.axes.Axes

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.validation import segment
    >>> from rlsfilt.plotting import plot_segmentation
    >>> rng = np.random.default_rng(0)
    >>> y = np.r_[rng.standard_normal(100), 2 + rng.standard_normal(100)]
    >>> seg = segment(y[1:], np.ones(199), na=0, nb=1, nk=0, R2=1.0)
    >>> ax = plot_segmentation(seg)
    >>> len(ax.lines)
    2
    """
    ax = _axes(ax)
    theta = np.asarray(segmentation.theta, dtype=float)
    n = theta.shape[1]
    names = _names(names, None, n)
    for i in range(n):
        xs, ys = [], []
        for (a, b), th in zip(segmentation.segments, theta, strict=True):
            xs += [a, b - 1, np.nan]
            ys += [th[i], th[i], np.nan]
        ax.plot(xs, ys, color=COLORS[i % len(COLORS)], lw=1.6, label=names[i])
    if true_values is not None:
        tv = as_float_array(true_values, "true_values")
        if tv.ndim != 2 or tv.shape[1] != n:
            raise ValueError(f"`true_values` must have shape (N, {n}); got {tv.shape}")
        for i in range(n):
            ax.plot(np.arange(len(tv)), tv[:, i], color=COLORS[i % len(COLORS)], lw=1.0,
                    linestyle="--")
    for k, t in enumerate(segmentation.change_times):
        ax.axvline(t, color=_GREY, lw=1.0, linestyle=":",
                   label="change" if k == 0 else None)
    ax.set_xlabel("sample $t$")
    ax.set_ylabel("parameters")
    ax.set_title(f"{segmentation.n_segments} segment(s)")
    _legend_outside(ax)
    return ax


# ----------------------------------------------------------------------
# the validation report
# ----------------------------------------------------------------------
def plot_report(report, fig=None, *, window=None, output_name=None, output_unit=None):
    """One figure of a validation: output fit, residual tests, Bode with uncertainty, step.

    Rows: the model's output against the data (a window, and an overview of
    the whole record when it is longer); residual autocorrelation and input
    cross-correlation; the Bode diagram of the model with its 95 %
    uncertainty band (:func:`~rlsfilt.validation.frequency_response_band`,
    1000 draws, seed 0) and, when the report has a plant, the plant's
    response and both step responses. Only the first output is drawn.

    Parameters
    ----------
    report : ValidationReport
        What :func:`~rlsfilt.validation.validate` returned.
    fig : matplotlib.figure.Figure, optional
        Figure to draw in (empty); a new one if omitted.
    window, output_name, output_unit
        As in :func:`plot_comparison` (the names and units default to the
        data's, or the model's).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import ARX, validate
    >>> from rlsfilt.datasets import dc_motor
    >>> from rlsfilt.plotting import plot_report
    >>> d = dc_motor()
    >>> report = validate(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), d.u, d.y, plant=d.plant)
    >>> fig = plot_report(report)
    >>> [ax.get_ylabel() for ax in fig.axes][:2]
    ['y', 'y']
    """
    has_plant = report.plant_comparison is not None
    n = len(report.y)
    windowed = _window(window, n) != (0, n)
    fig = _figure(fig, figsize=(11, 13 if has_plant else 11), layout="constrained")
    heights = [3, 1.2] if windowed else [3]
    heights += [2.6, 2, 2]
    gs = fig.add_gridspec(len(heights), 2, height_ratios=heights)
    ax_cmp = fig.add_subplot(gs[0, :])
    ax_over = fig.add_subplot(gs[1, :]) if windowed else None
    plot_comparison(report, ax_cmp, window=window, ax_overview=ax_over,
                    output_name=output_name, output_unit=output_unit)
    row = 2 if windowed else 1
    if report.residuals:
        r = report.residuals[0]
        plot_autocorrelation(r, fig.add_subplot(gs[row, 0]))
        plot_cross_correlation(r, fig.add_subplot(gs[row, 1]))
    else:   # validate(..., skip_undefined=True) recorded why the tests were skipped
        ax = fig.add_subplot(gs[row, :])
        ax.text(0.5, 0.5, f"residual tests skipped:\n{report.skipped}", ha="center",
                va="center", transform=ax.transAxes)
        ax.set_axis_off()
    band = _report_band(report)
    if has_plant:
        ax_mag = fig.add_subplot(gs[row + 1, 0])
        ax_phase = fig.add_subplot(gs[row + 2, 0], sharex=ax_mag)
        plot_bode(report.plant_comparison, ax_mag, ax_phase, band=band)
        _, u_unit = _signal_label(report, "input", 0)
        _, y_unit = _signal_label(report, "output", 0)
        plot_step(report.plant_comparison, fig.add_subplot(gs[row + 1:, 1]),
                  input_unit=u_unit, output_unit=y_unit)
    else:
        ax_mag = fig.add_subplot(gs[row + 1:, 0])
        ax_phase = fig.add_subplot(gs[row + 1:, 1])
        plot_bode(band, ax_mag, ax_phase)
        ax_mag.set_xlabel(ax_phase.get_xlabel())   # side by side: both need the frequency
        ax_phase.set_title("phase")
        if getattr(report, "is_time_series", False):     # the Bode of H = C/(A D)
            ax_mag.set_title("noise model C/(A D) (time series: no input)")
    _label_gain(report, ax_mag)
    return fig


def _label_gain(report, ax_mag):
    """Name the channel and the unit of the gain of a one-input, one-output model in the
    report's Bode diagram: ``|G| (dB re 1 degC/%)`` under the title ``flow to T_out: ...``."""
    if report.model.n_inputs_ != 1 or report.model.n_outputs_ != 1:
        return
    u_name, u_unit = _signal_label(report, "input", 0)
    y_name, y_unit = _signal_label(report, "output", 0)
    if u_unit or y_unit:
        ratio = f"{y_unit or '1'}/{u_unit or '1'}"
        ax_mag.set_ylabel(f"$|G(e^{{j\\omega T}})|$ (dB re 1 {ratio})")
    if (u_name, y_name) != ("u", "y"):
        first, *rest = ax_mag.get_title().split("\n")
        ax_mag.set_title("\n".join([f"{first} ({u_name} to {y_name})", *rest]))


# ----------------------------------------------------------------------
# adaptive control
# ----------------------------------------------------------------------
def plot_str_history(history, fig=None, *, true_theta=None):
    r"""A self-tuning regulator's run: output and reference, control, estimates, trace of P.

    Stacked axes sharing the time axis: output and reference, control, the
    estimates of ``A`` (and the offset ``c``, when estimated), those of ``B``
    (on their own axis: their scale is often far from that of ``A``'s) and
    :math:`\mathrm{tr}\,P`. Steps where a due redesign was rejected (the
    last controller kept) are marked on the control.

    Parameters
    ----------
    history : STRHistory
        ``SelfTuningRegulator.history`` (anything with its attributes ``t``,
        ``y``, ``r``, ``u``, ``theta``, ``trace_P``, ``rejected``, ``na``
        and ``dt``).
    fig : matplotlib.figure.Figure, optional
        Figure to draw in (cleared); a new one if omitted.
    true_theta : array_like, shape (na + nb,) or (N, na + nb), optional
        True parameters ``[a1 .. a_na, b1 .. b_nb]``, drawn dashed.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> import matplotlib.pyplot as plt
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.adaptive import SelfTuningRegulator
    >>> from rlsfilt.plotting import plot_str_history
    >>> stre = SelfTuningRegulator(RecursiveLeastSquares(2, P0=100.0),
    ...                            dict(Am=[1, -0.5], Ao=[1.0]), na=1, nb=1, dt=0.1)
    >>> import numpy as np
    >>> dither = 0.05 * np.random.default_rng(0).standard_normal(100)  # excitation
    >>> y = 0.0
    >>> for t in range(100):
    ...     u = stre.step(y, r=1.0 if (t // 25) % 2 else -1.0, dither=dither[t])
    ...     y = 0.8 * y + 0.5 * u
    >>> fig = plot_str_history(stre.history, true_theta=[-0.8, 0.5])
    >>> [ax.get_ylabel() for ax in fig.axes]
    ['$y$, $r$', 'control $u$', 'estimates $\\hat a$', 'estimates $\\hat b$', '$\\mathrm{tr}\\,P$']
    >>> fig.axes[-1].get_xlabel()
    'time (s)'
    """
    if fig is None:
        fig = _figure(None, figsize=(9, 9), layout="constrained")
    else:
        fig.clf()
    theta = np.asarray(history.theta, dtype=float)
    offset = bool(getattr(history, "offset", False))
    na = int(history.na)
    nb = theta.shape[1] - na - offset
    # the estimates of A (and the offset), then those of B: a1 ~ -1.5 beside b1 ~ 0.002 on one
    # axis would draw the b's as a flat line at zero
    groups = [(list(range(na)) + [na + nb] * offset, r"estimates $\hat a$"
               + (r", $\hat c$" if offset else "")),
              (list(range(na, na + nb)), r"estimates $\hat b$")]
    axes = fig.subplots(4 + len(groups) - 1, 1, sharex=True)
    t = np.asarray(history.t, dtype=float)
    ax = axes[0]
    ax.plot(*_decimate(t, history.r), color=_BLACK, linestyle=":", lw=1.2, label="reference $r$")
    ax.plot(*_decimate(t, history.y), color=COLORS[0], lw=1.1, label="output $y$")
    ax.set_ylabel("$y$, $r$")
    ax.set_title("Self-tuning regulator")
    _legend_outside(ax)
    ax = axes[1]
    ax.plot(*_decimate(t, history.u), color=COLORS[2], lw=0.9, label="control $u$")
    rejected = np.flatnonzero(np.asarray(history.rejected, dtype=bool))
    if len(rejected):
        ax.plot(t[rejected], np.asarray(history.u)[rejected], "x", color=COLORS[1], ms=4,
                label="design kept\n(rejected estimate)")
    ax.set_ylabel("control $u$")
    _legend_outside(ax)
    names = ([rf"$\hat a_{{{i + 1}}}$" for i in range(na)]
             + [rf"$\hat b_{{{i + 1}}}$" for i in range(nb)] + [r"$\hat c$"] * offset)
    truth = None if true_theta is None else as_float_array(true_theta, "true_theta")
    if truth is not None and truth.shape[-1] != theta.shape[1]:
        raise ValueError(f"`true_theta` must have {theta.shape[1]} parameters on its last axis "
                         f"(na + nb{' + 1' if offset else ''}); got shape {truth.shape}")
    for k, (cols, label) in enumerate(groups):
        plot_parameters(theta[:, cols], t=t, names=[names[c] for c in cols],
                        true_values=None if truth is None else truth[..., cols],
                        ax=axes[2 + k])
        axes[2 + k].set_ylabel(label)
        axes[2 + k].set_title("")
    ax = axes[-1]
    trace = np.asarray(history.trace_P, dtype=float)
    ax.plot(*_decimate(t, trace), color=COLORS[3], lw=1.1)
    _trace_axis(ax, trace)
    for a in axes:
        a.set_xlabel("")
        a.grid(True, alpha=0.3)
    axes[-1].set_xlabel(_time_unit(history.dt))
    fig.align_ylabels(axes)
    return fig


# ----------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------
def _report_band(report):
    """The 95 % band of the report's model (seed 0: the same figure on every call), on the
    plant comparison's frequencies when there is one (`ValidationReport.frequency_band`;
    plotting imports nothing from rlsfilt.validation)."""
    return report.frequency_band()


def _draw_band(ax_mag, ax_phase, band, model_line=True):
    pct = f"{100 * band.level:g}%"
    for c, ((i, j), tag) in enumerate(_channels(band.response.shape[:2])):
        color = _color(c)
        ax_mag.fill_between(band.omega, _db(band.magnitude_lower[i, j]),
                            _db(band.magnitude_upper[i, j]), color=color, alpha=0.25,
                            linewidth=0, label=f"{pct} band{tag}")
        ax_phase.fill_between(band.omega, band.phase_lower[i, j], band.phase_upper[i, j],
                              color=color, alpha=0.25, linewidth=0)
        if model_line:   # a PlantComparison draws the model itself
            _bode_lines(ax_mag, ax_phase, band.omega, band.response[i, j], f"model{tag}",
                        color=color, lw=1.4)


def _band_width_text(band):
    """``"95% band (parameters): 0.04 to 0.76 dB wide"``: the band's width in words, for when it is
    thinner than the line drawn over it."""
    with np.errstate(divide="ignore", invalid="ignore"):
        width = _db(band.magnitude_upper) - _db(band.magnitude_lower)
    width = width[np.isfinite(width)]
    if not width.size:
        return f"{100 * band.level:g}% band"
    return (f"{100 * band.level:g}% band (parameters): {np.min(width):.2g} to "
            f"{np.max(width):.2g} dB wide")


def _draw_comparison_bode(ax_mag, ax_phase, comparison):
    for c, ((i, j), label) in enumerate(_channels(comparison.response_plant.shape[:2])):
        for resp, name, color, style, lw in (
                (comparison.response_plant, "plant", _BLACK, "-", 1.6),
                (comparison.response_model, "model", _color(c), "--", 1.4)):
            _bode_lines(ax_mag, ax_phase, comparison.omega, resp[i, j], f"{name}{label}",
                        color=color, linestyle=style, lw=lw)


def _draw_plant_bode(ax_mag, ax_phase, band, plant):
    import control

    z = np.exp(1j * band.omega * band.dt)
    G = np.asarray(control.tf(plant)(z, squeeze=False))
    ny, nu = band.response.shape[:2]
    first = True
    for i in range(min(ny, G.shape[0])):
        for j in range(min(nu, G.shape[1])):
            _bode_lines(ax_mag, ax_phase, band.omega, G[i, j], "plant" if first else None,
                        color=_BLACK, linestyle="--", lw=1.2)
            first = False


def _resolve(source, covariances, output, need_covariances=False):
    """Return ``theta (N, n)``, ``covs (N, n, n) or None`` and default names."""
    names = None
    covs = None
    if hasattr(source, "theta_history_"):
        theta = source.theta_history_
        for attr in ("theta_cov_history_", "P_history_"):
            if getattr(source, attr, None) is not None:
                covs = getattr(source, attr)
                break
        names = getattr(source, "param_names_", None)
    elif isinstance(source, (tuple, list)) and len(source) and np.ndim(source[0]) >= 2:
        theta = source[0]
        covs = source[1] if len(source) > 1 else None
    else:
        theta = source
    if covariances is not None:
        covs = covariances
    theta = as_float_array(theta, "source")
    if theta.ndim == 1:
        theta = theta.reshape(-1, 1)
    if theta.ndim == 3:
        output = check_int(output, "output", minimum=0)
        if output >= theta.shape[2]:
            raise ValueError(f"`output` must be < {theta.shape[2]} (the estimates have "
                             f"{theta.shape[2]} outputs); got {output}")
        theta = theta[:, :, output]
    if theta.ndim != 2:
        raise ValueError(f"the estimates must have shape (N, n) or (N, n, m); got {theta.shape}")
    N, n = theta.shape
    if covs is not None:
        covs = as_float_array(covs, "covariances")
        if covs.shape != (N, n, n):
            raise ValueError(f"`covariances` must have shape ({N}, {n}, {n}) to match the "
                             f"estimates; got {covs.shape}")
    elif need_covariances:
        raise ValueError("`covariances` are needed: pass batch_filter's (means, covariances), "
                         "an object with theta_cov_history_ or P_history_, or `covariances=`")
    return theta, covs, names


def _time_axis(t, N):
    if t is None:
        return np.arange(N)
    tt = as_float_array(t, "t")
    if tt.shape != (N,):
        raise ValueError(f"`t` must have shape ({N},) (one time per estimate); got {tt.shape}")
    return tt


def _names(names, default, n):
    if names is None:
        if default is not None and len(default) == n:
            names = default
        else:   # e.g. a multi-output model whose names cover every output
            names = [rf"$\theta_{{{i + 1}}}$" for i in range(n)]
    names = [str(s) for s in names]
    if len(names) != n:
        raise ValueError(f"`names` must have {n} entries (one per parameter); got {len(names)}")
    return names


def _initial_tag(result):
    """``"; x0 estimated"``: the initial condition of a comparison, for a legend entry."""
    initial = getattr(result, "initial", None)
    tags = {"estimate": "; x0 estimated", "zero": "; from rest",
            "measured": "; from the measured past"}
    return tags.get(initial, "")


def _signal_label(report, kind, index, name=None, unit=None):
    """``(name, unit)`` of input or output `index`: the arguments, else the report's
    ``output_names``/``output_units`` (the data's, or the model's), else the model's
    ``output_names_``/``output_units_``, else ``"y"`` (``"u"``) and no unit."""
    for source, suffix in ((report, ""), (getattr(report, "model", None), "_")):
        if name is None:
            names = getattr(source, f"{kind}_names{suffix}", None)
            if names is not None and index < len(names):
                name = str(names[index])
        if unit is None:
            units = getattr(source, f"{kind}_units{suffix}", None)
            if units is not None and index < len(units) and units[index]:
                unit = str(units[index])
    return (name if name is not None else kind[0]), unit


def _record_time(report):
    """Time axis of a report's record, the seams between experiments (sample indices) and
    the experiment names. Several experiments are laid one after the other on one axis
    (each starts one sample period after the previous one ends)."""
    t = np.asarray(report.time, dtype=float)
    lengths = tuple(getattr(report, "experiment_lengths", ()) or ())
    if len(lengths) < 2:
        return t, [], ()
    dt = 1.0 if report.model.dt is True else float(report.model.dt)
    seams = [int(k) for k in np.cumsum(lengths)[:-1]]
    names = tuple(getattr(report, "experiment_names", ()) or ())
    if len(names) != len(lengths):
        names = tuple(f"exp{k + 1}" for k in range(len(lengths)))
    return t[0] + dt * np.arange(len(t)), seams, names


def _broken(t, y, a, b, seams, max_points=MAX_POINTS):
    """``(t[a:b], y[a:b])`` ready to draw: each experiment (the pieces between the seams
    inside the slice) reduced by :func:`_decimate` to its share of `max_points`, with a
    NaN between two experiments, so that no line joins the end of one experiment to the
    start of the next."""
    bounds = [a, *(k for k in seams if a < k < b), b]
    xs, ys = [], []
    for lo, hi in zip(bounds[:-1], bounds[1:]):
        if xs:
            xs.append([_seam_time(t, lo)])
            ys.append([np.nan])
        share = max(4, int(max_points * (hi - lo) / (b - a)))
        x_i, y_i = _decimate(t[lo:hi], y[lo:hi], share)
        xs.append(x_i)
        ys.append(y_i)
    return np.concatenate(xs), np.concatenate(ys)


def _column(a, output):
    a = np.asarray(a, dtype=float)
    return a if a.ndim == 1 else a[:, output]


def _window(window, N):
    """``(start, stop)`` of the comparison window, validated."""
    if window is None:
        return (0, N) if N < 1.5 * _WINDOW else (N - _WINDOW, N)
    try:
        a, b = (int(w) for w in window)
    except (TypeError, ValueError):
        raise TypeError(f"`window` must be a pair (start, stop) of sample indices; got "
                        f"{window!r}") from None
    if not 0 <= a < b <= N or b - a < 2:
        raise ValueError(f"`window` must satisfy 0 <= start < stop <= {N} with at least 2 "
                         f"samples; got {window!r}")
    return a, b


def _color(i):
    return COLORS[i % len(COLORS)]


def _db(mag):
    return 20.0 * np.log10(np.maximum(mag, np.finfo(float).tiny))


def _bode_lines(ax_mag, ax_phase, omega, g, label, **style):
    """One response ``g(e^{j omega T})`` in a Bode diagram: ``|g|`` in dB over its unwrapped
    phase in degrees, the legend entry `label` on the magnitude."""
    ax_mag.plot(omega, _db(np.abs(g)), label=label, **style)
    ax_phase.plot(omega, np.degrees(np.unwrap(np.angle(g))), **style)


def _time_xlabel(xlabel, t):
    """The time axis of the tracking plots: `xlabel`, else ``"time"`` when a time axis
    `t` is given, else ``"sample $k$"``."""
    if xlabel is not None:
        return xlabel
    return "time" if t is not None else "sample $k$"


def _time_unit(dt):
    """``"sample"`` for a model without a sample time (``dt is True``), else ``"time (s)"``."""
    return "sample" if dt is True else "time (s)"


def _seam_time(t, k):
    """Where the seam before sample `k` is drawn: halfway between ``t[k - 1]`` and ``t[k]``."""
    return 0.5 * (t[k - 1] + t[k])


def _trace_axis(ax, trace, log=True):
    r"""The axis of a :math:`\mathrm{tr}\,P` panel: logarithmic when `log` and the trace is
    positive (windup spans many decades), and its label."""
    if log and trace.size and np.all(trace > 0):
        ax.set_yscale("log")
    ax.set_ylabel(r"$\mathrm{tr}\,P$")


def _zero_line_and_scale(ax, band, values):
    """A correlation panel's zero line and its y-range, symmetric about zero: 15 % above
    the larger of the (widest) `band` and the largest ``|values|``."""
    ax.axhline(0.0, color=_BLACK, lw=0.6)
    top = 1.15 * max(band, float(np.max(np.abs(values))) if values.size else band)
    ax.set_ylim(-top, top)


def _test_title(ax, what, verdict, pvalue, alpha, hypothesis, test, n_outside, n_lags):
    """The title of a residual-test panel: ``"<what>: <verdict> (<test>, joint over all lags,
    p = ...)"`` over the meaning of the shaded band: a per-lag ``1 - alpha`` band under
    `hypothesis`, which single lags leave by chance (``alpha * n_lags`` of them expected)
    even when the joint test passes."""
    ax.set_title(f"{what}: {verdict} ({test} joint over {n_lags} lags, p = {pvalue:.3g})\n"
                 f"shaded: {100 * (1 - alpha):g}% band per lag under {hypothesis}; "
                 f"{n_outside} outside (~{alpha * n_lags:.2g} by chance)", fontsize="medium")


def _decimate(x, y, max_points=MAX_POINTS):
    """``(x, y)``, or their per-bin minima and maxima in time order when longer than
    `max_points` (the line then looks the same at any screen resolution)."""
    x = np.asarray(x)
    y = np.asarray(y, dtype=float)
    n = len(y)
    if n <= max_points:
        return x, y
    edges = _bin_edges(n, max_points)
    bins = len(edges) - 1
    size = int(np.max(np.diff(edges)))
    # pad each bin to the same length with NaN, then take the extremes of each row
    idx = edges[:-1, None] + np.arange(size)[None, :]
    valid = idx < edges[1:, None]
    idx = np.where(valid, idx, edges[1:, None] - 1)
    block = np.where(valid, y[idx], np.nan)
    finite = np.isfinite(block)
    lo = np.argmin(np.where(finite, block, np.inf), axis=1)
    hi = np.argmax(np.where(finite, block, -np.inf), axis=1)
    rows = np.arange(bins)
    pick = np.sort(np.stack([idx[rows, lo], idx[rows, hi]], axis=1), axis=1).ravel()
    return x[pick], y[pick]


def _bin_edges(n, max_points):
    """The ``max_points // 2 + 1`` edges of the bins a line of `n` points is reduced to
    (two points, the minimum and the maximum, per bin)."""
    return np.linspace(0, n, max_points // 2 + 1).astype(int)


def _envelope(x, lower, upper, max_points=MAX_POINTS):
    """``(x, lower, upper)`` for ``fill_between``, reduced to per-bin extremes if long."""
    x = np.asarray(x)
    lower = np.asarray(lower, dtype=float)
    upper = np.asarray(upper, dtype=float)
    n = len(x)
    if n <= max_points:
        return x, lower, upper
    edges = _bin_edges(n, max_points)
    with np.errstate(invalid="ignore"):
        lo = np.fmin.reduceat(lower, edges[:-1])
        hi = np.fmax.reduceat(upper, edges[:-1])
    xs = x[edges[:-1]]
    return xs, lo, hi


def _legend_outside(ax, extra=()):
    """A legend to the right of the axes, off the data (nothing when there is nothing to
    label)."""
    handles, labels = ax.get_legend_handles_labels()
    for h in extra:
        handles.append(h)
        labels.append(h.get_label())
    if not handles:
        return None
    return ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                     borderaxespad=0.0, fontsize="small", frameon=False)


def _proxy(**kwargs):
    """A legend entry that is not drawn in the axes."""
    from matplotlib.lines import Line2D

    return Line2D([], [], **kwargs)


def _channels(shape):
    ny, nu = shape
    for i in range(ny):
        for j in range(nu):
            yield (i, j), (f" (u{j} to y{i})" if ny * nu > 1 else "")


def _axes(ax=None):
    """`ax`, or the axes of a new figure with constrained layout (matplotlib is imported
    only then), so labels are kept inside the figure when it is saved."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    return ax


def _figure(fig=None, **kwargs):
    """`fig`, or a new ``plt.figure(**kwargs)`` (matplotlib is imported only then)."""
    if fig is None:
        import matplotlib.pyplot as plt

        fig = plt.figure(**kwargs)
    return fig


def _bode_axes(ax_mag=None, ax_phase=None):
    """``(ax_mag, ax_phase)``, or magnitude over phase in a new figure unless both are given."""
    if ax_mag is None or ax_phase is None:
        import matplotlib.pyplot as plt

        _, (ax_mag, ax_phase) = plt.subplots(2, 1, sharex=True, figsize=(8, 6),
                                             layout="constrained")
    return ax_mag, ax_phase
