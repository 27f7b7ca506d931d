"""The picture of a self-tuning regulator run: output, control, estimates, trace(P).

Called by `STRHistory.plot`; matplotlib is imported only here, when a plot is
asked for. The estimates are drawn by `rlsfilt.plotting.plot_parameters`,
so they look like every other parameter plot of rlsfilt.
"""

import numpy as np

from ..plotting import _figure, plot_parameters

__all__ = []


def plot_str_history(history, fig=None, true_theta=None):
    """Four stacked axes sharing the time axis; returns the figure.

    Parameters
    ----------
    history : STRHistory
    fig : matplotlib.figure.Figure, optional
        Figure to draw in (cleared); a new one if omitted.
    true_theta : array_like, shape (n,) or (N, n), optional
        True parameters, drawn dashed.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = _figure(fig, figsize=(9, 9))
    fig.clf()
    axes = fig.subplots(4, 1, sharex=True)
    t = history.t
    unit = "t [s]" if history.dt is not True else "t [samples]"
    ax = axes[0]
    ax.plot(t, history.r, "k:", linewidth=1, label="reference $r$")
    ax.plot(t, history.y, linewidth=1, label="output $y$")
    ax.set_ylabel("$y$, $r$")
    ax.set_title("self-tuning regulator")
    ax.legend(loc="best")
    ax = axes[1]
    ax.plot(t, history.u, linewidth=0.8, color="C2")
    ax.set_ylabel("control $u$")
    names = ([rf"$\hat a_{{{i + 1}}}$" for i in range(history.na)]
             + [rf"$\hat b_{{{i + 1}}}$" for i in range(history.theta.shape[1] - history.na)])
    plot_parameters(history.theta, t=t, names=names, true_values=true_theta, ax=axes[2])
    axes[2].set_title("")
    ax = axes[3]
    ax.plot(t, history.trace_P, linewidth=1, color="C3")
    if np.all(history.trace_P > 0):
        ax.set_yscale("log")
    ax.set_ylabel(r"$\mathrm{tr}\,P$")
    rejected = np.flatnonzero(history.rejected)
    if len(rejected):
        axes[1].plot(t[rejected], history.u[rejected], "x", color="C3", markersize=4,
                     label="design kept (rejected estimate)")
        axes[1].legend(loc="best")
    for a in axes:
        a.set_xlabel("")
    axes[-1].set_xlabel(unit)
    fig.align_ylabels(axes)
    return fig
