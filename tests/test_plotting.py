"""Tracking plots from batch_filter results and from objects with theta_history_."""

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from conftest import arx_record
from numpy.testing import assert_allclose

from rlsfilt import RecursiveLeastSquares
from rlsfilt.plotting import plot_parameters, plot_trace, plot_tracking

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


@pytest.fixture
def run(rng):
    Hs, zs = arx_record(rng, n_samples=202)
    rls = RecursiveLeastSquares(4, lam=0.98, R=0.01)
    return rls.batch_filter(zs, Hs)


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


def test_parameters_from_batch_filter_output(run):
    means, covs, _, _ = run
    fig, ax = plt.subplots()
    out = plot_parameters(run, ax=ax, n_std=3, true_values=[-1.5, 0.7, 1.0, 0.5])
    assert out is ax
    lines = ax.get_lines()
    assert len(lines) == 8                                  # estimates + true values
    assert_allclose(lines[0].get_ydata(), means[:, 0, 0])
    assert_allclose(lines[1].get_ydata(), -1.5)
    assert len(ax.collections) == 4                         # one band per parameter
    band = ax.collections[2].get_paths()[0].vertices[:, 1]
    upper = means[:, 2, 0] + 3 * np.sqrt(covs[:, 2, 2])
    lower = means[:, 2, 0] - 3 * np.sqrt(covs[:, 2, 2])
    assert_allclose(band.max(), upper.max())
    assert_allclose(band.min(), lower.min())
    assert [t.get_text() for t in ax.get_legend().get_texts()][0] == r"$\theta_{1}$"


def test_parameters_without_covariances_and_with_time(run):
    means = run[0]
    ax = plot_parameters(means, t=0.1 * np.arange(len(means)), names=list("abcd"))
    assert len(ax.collections) == 0
    assert_allclose(ax.get_lines()[3].get_xdata(), 0.1 * np.arange(len(means)))
    assert ax.get_xlabel() == "time"


def test_objects_with_theta_history(run):
    means, covs, _, _ = run
    model = SimpleNamespace(theta_history_=means[:, :, 0], P_history_=covs,
                            param_names_=["a1", "a2", "b1", "b2"])
    ax = plot_parameters(model)
    assert len(ax.collections) == 4
    assert [t.get_text() for t in ax.get_legend().get_texts()] == ["a1", "a2", "b1", "b2"]
    both = SimpleNamespace(theta_history_=means[:, :, 0], theta_cov_history_=covs * 4,
                           P_history_=covs)
    ax2 = plot_trace(both)                                  # theta_cov_history_ wins
    assert_allclose(ax2.get_lines()[0].get_ydata(), 4 * np.trace(covs, axis1=1, axis2=2))
    bare = SimpleNamespace(theta_history_=means[:, :, 0])
    assert len(plot_parameters(bare).collections) == 0
    # a multi-output history (N, n, ny) with NaN rows before a batch start
    hist = np.stack([means[:, :, 0], 2 * means[:, :, 0]], axis=2)
    hist[:5] = np.nan
    multi = SimpleNamespace(theta_history_=hist, param_names_=["a1[y1]"] * 8)
    ax3 = plot_parameters(multi, output=1)
    assert_allclose(ax3.get_lines()[0].get_ydata()[5:], 2 * means[5:, 0, 0])
    assert ax3.get_legend().get_texts()[0].get_text() == r"$\theta_{1}$"


def test_trace_and_tracking_figure(run):
    means, covs, _, _ = run
    ax = plot_trace(run)
    assert_allclose(ax.get_lines()[0].get_ydata(), np.trace(covs, axis1=1, axis2=2))
    assert ax.get_yscale() == "log"
    fig = plt.figure()
    out = plot_tracking(run, fig=fig, true_values=np.tile([-1.5, 0.7, 1.0, 0.5], (200, 1)))
    assert out is fig and len(fig.axes) == 2
    assert plot_tracking(run).axes[1].get_ylabel() == r"$\mathrm{tr}\,P$"


def test_bad_inputs(run):
    means, covs, _, _ = run
    with pytest.raises(ValueError, match=r"`covariances` are needed"):
        plot_trace(means)
    with pytest.raises(ValueError, match=r"`covariances` must have shape \(200, 4, 4\) to match"):
        plot_parameters(means, covs[:10])
    with pytest.raises(ValueError, match=r"`t` must have shape \(200,\)"):
        plot_parameters(run, t=np.arange(5))
    with pytest.raises(ValueError, match=r"`names` must have 4 entries"):
        plot_parameters(run, names=["a"])
    with pytest.raises(ValueError, match=r"`output` must be < 1"):
        plot_parameters(run, output=1)
    with pytest.raises(ValueError, match=r"`true_values` must have shape \(4,\) or \(200, 4\)"):
        plot_parameters(run, true_values=[1.0, 2.0])


def test_y_range_not_flattened_by_the_broad_prior(run):
    """The default P0 = 1e4 I makes the first bands +-200 wide; the y-range follows the
    estimates, the true values and the informative bands, so the trajectories stay readable."""
    means, covs, _, _ = run
    assert 2 * np.sqrt(covs[0].diagonal()).max() > 100          # the prior band is huge
    ax = plot_parameters(run, true_values=[-1.5, 0.7, 1.0, 0.5])
    lo, hi = ax.get_ylim()
    theta = means[:, :, 0]
    sd = np.sqrt(np.einsum("kii->ki", covs))
    narrow = 2 * sd <= theta.max() - theta.min()
    assert narrow[-1].all()
    assert lo <= min(theta.min(), (theta - 2 * sd)[narrow].min()) and \
        hi >= max(theta.max(), (theta + 2 * sd)[narrow].max())
    assert hi - lo < 1.2 * (theta.max() - theta.min()) + 4 * sd[narrow].max()
    assert len(ax.collections) == 4                             # the bands are still drawn
