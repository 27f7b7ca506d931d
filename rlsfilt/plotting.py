"""Plots for tracking: parameter trajectories with confidence bands and trace(P).

The functions accept what the filters and models produce:

* the tuple returned by ``batch_filter`` (``means`` of shape ``(N, n, m)``
  and ``covariances`` of shape ``(N, n, n)``, or just its first two items);
* any object with a ``theta_history_`` attribute (``(N, n)``), such as a
  recursively fitted ARX model, with the covariances taken from its
  ``theta_cov_history_`` or, failing that, ``P_history_`` attribute;
* a plain array of estimates, with `covariances` given separately.

matplotlib is imported only when a function is called, so ``import
rlsfilt`` stays light.
"""

import numpy as np

from ._validation import as_float_array, check_int

__all__ = ["plot_parameters", "plot_trace", "plot_tracking"]


def plot_parameters(source, covariances=None, *, t=None, names=None, true_values=None,
                    n_std=2.0, output=0, ax=None):
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
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes
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
    for i in range(n):
        (line,) = ax.plot(tt, theta[:, i], label=names[i])
        if covs is not None:
            sd = np.sqrt(np.clip(covs[:, i, i], 0.0, None))
            ax.fill_between(tt, theta[:, i] - n_std * sd, theta[:, i] + n_std * sd,
                            color=line.get_color(), alpha=0.2, linewidth=0)
            # the y-range follows the bands only where they are informative: the broad prior
            # of the first samples (P0 = 1e4 I: +-200) would flatten every trajectory
            narrow = n_std * sd <= span
            if span > 0 and narrow.any():
                lo = min(lo, float(np.nanmin(theta[narrow, i] - n_std * sd[narrow])))
                hi = max(hi, float(np.nanmax(theta[narrow, i] + n_std * sd[narrow])))
        if truth is not None:
            ax.plot(tt, truth[:, i], linestyle="--", color=line.get_color(), linewidth=1)
    if covs is not None and span > 0:
        pad = 0.05 * (hi - lo)
        ax.set_ylim(lo - pad, hi + pad)
    ax.set_xlabel("time" if t is not None else "sample $k$")
    ax.set_ylabel(r"estimate $\hat\theta$")
    title = "parameter estimates"
    if covs is not None:
        title += rf" ($\pm{n_std:g}\sigma$)"
    ax.set_title(title)
    ax.legend(loc="best")
    return ax


def plot_trace(source, covariances=None, *, t=None, log=True, ax=None):
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
    ax : matplotlib.axes.Axes, optional
        Axes to draw in; a new figure is made if omitted.

    Returns
    -------
    matplotlib.axes.Axes
    """
    _, covs, _ = _resolve(source, covariances, 0, need_covariances=True)
    tr = np.trace(covs, axis1=1, axis2=2)
    tt = _time_axis(t, len(tr))
    ax = _axes(ax)
    ax.plot(tt, tr, label=r"$\mathrm{tr}\,P$")
    if log and np.all(tr > 0):
        ax.set_yscale("log")
    ax.set_xlabel("time" if t is not None else "sample $k$")
    ax.set_ylabel(r"$\mathrm{tr}\,P$")
    ax.set_title("trace of the covariance")
    return ax


def plot_tracking(source, covariances=None, *, t=None, names=None, true_values=None,
                  n_std=2.0, output=0, log=True, fig=None):
    """Parameter trajectories (top) and ``trace(P)`` (bottom) on a shared time axis.

    Parameters are those of :func:`plot_parameters` and :func:`plot_trace`;
    `fig` is a matplotlib Figure to draw in (a new one if omitted).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = _figure(fig, figsize=(7, 6))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    plot_parameters(source, covariances, t=t, names=names, true_values=true_values,
                    n_std=n_std, output=output, ax=ax1)
    plot_trace(source, covariances, t=t, log=log, ax=ax2)
    ax1.set_xlabel("")
    return fig


# ----------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------
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


def _axes(ax=None):
    """`ax`, or the axes of a new figure (matplotlib is imported only then)."""
    if ax is None:
        import matplotlib.pyplot as plt

        _, ax = plt.subplots()
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

        _, (ax_mag, ax_phase) = plt.subplots(2, 1, sharex=True)
    return ax_mag, ax_phase
