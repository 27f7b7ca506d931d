"""plot_str_history: the self-tuning regulator's figure follows the plotting conventions."""

import io

import matplotlib
import numpy as np
from matplotlib.colors import to_hex
from numpy.testing import assert_allclose

from rlsfilt import RecursiveLeastSquares
from rlsfilt.adaptive import SelfTuningRegulator
from rlsfilt.plotting import COLORS, plot_str_history

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

THETA = np.array([-1.5, 0.7, 1.0, 0.5])


def _history(N=300, dt=0.1):
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0),
                               dict(Am=np.poly([0.5, 0.5]), Ao=np.poly([0.2])), na=2, nb=2,
                               dt=dt)
    rng = np.random.default_rng(0)
    y, u = np.zeros(N), np.zeros(N)
    for t in range(N):
        y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2] \
            + 0.01 * rng.standard_normal()
        u[t] = stre.step(y[t], 1.0 if (t // 50) % 2 else -1.0,
                         dither=0.01 * rng.choice([-1.0, 1.0]))
    return stre.history


def test_the_regulator_figure_follows_the_conventions():
    h = _history()
    fig = plot_str_history(h, true_theta=THETA)
    out_ax, u_ax, a_ax, b_ax, trace_ax = fig.axes
    # the data drawn are the history's; the a's and the b's each on their own axis (#32: their
    # scales differ)
    assert_allclose(out_ax.get_lines()[1].get_ydata(), h.y)
    theta = np.asarray(h.theta)
    for ax, cols in ((a_ax, [0, 1]), (b_ax, [2, 3])):
        estimates = [ln for ln in ax.get_lines() if ln.get_linestyle() == "-"]
        assert len(estimates) == 2
        for ln, c in zip(estimates, cols):
            assert_allclose(ln.get_ydata(), theta[:, c])
    assert a_ax.get_ylabel() == r"estimates $\hat a$" and b_ax.get_ylabel() == r"estimates $\hat b$"
    assert_allclose(trace_ax.get_lines()[0].get_ydata(), h.trace_P)
    # colour-blind-safe palette, reference in black; legends beside the data
    colours = {to_hex(ln.get_color()) for ax in fig.axes for ln in ax.get_lines()}
    assert colours <= {c.lower() for c in COLORS} | {"#000000"}
    fig.savefig(io.BytesIO(), format="png", dpi=100)          # labels kept by the layout
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        legend = ax.get_legend()
        if legend is not None:
            assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
        box = ax.yaxis.label.get_window_extent(renderer)
        assert ax.get_ylabel() and box.x0 >= 0
    assert trace_ax.get_xlabel() == "time (s)" and trace_ax.get_yscale() == "log"
    # the history's own method is this function, into a given figure
    fig2 = plt.figure()
    assert h.plot(fig2, true_theta=THETA) is fig2 and len(fig2.axes) == 5
    plt.close("all")


def test_samples_when_the_regulator_has_no_sample_time():
    fig = plot_str_history(_history(N=120, dt=True))
    assert fig.axes[-1].get_xlabel() == "sample"
    plt.close("all")
