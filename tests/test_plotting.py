"""Tracking plots from batch_filter results and from objects with theta_history_."""

from types import SimpleNamespace

import matplotlib
import numpy as np
import pytest
from conftest import arx_record
from numpy.testing import assert_allclose

from rlsfilt import RecursiveLeastSquares
from rlsfilt.plotting import (
    plot_autocorrelation,
    plot_bode,
    plot_comparison,
    plot_cross_correlation,
    plot_cusum,
    plot_parameters,
    plot_trace,
    plot_tracking,
)

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


# ----------------------------------------------------------------------
# what users see: colours, labels that survive savefig, long records, legends off the data
# ----------------------------------------------------------------------
import doctest  # noqa: E402
import io  # noqa: E402

from matplotlib.colors import to_hex  # noqa: E402

import rlsfilt.plotting as plotting  # noqa: E402
from rlsfilt import ARX, validate  # noqa: E402
from rlsfilt.datasets import dc_motor, mass_spring_damper, time_varying  # noqa: E402
from rlsfilt.validation import cusum, cusum_squares, frequency_response_band  # noqa: E402


@pytest.fixture(scope="module")
def motor_report():
    d = dc_motor()
    model = ARX(*d.orders, dt=d.dt).fit(d.u, d.y)
    return validate(model, d.u, d.y, plant=d.plant)


def _fake_report(n, rng, dt=0.01):
    """The fields plot_comparison reads, for a record of `n` samples."""
    y = np.cumsum(rng.standard_normal(n)) * 0.01
    y[n // 3] = 50.0                                       # one spike far outside the rest
    return SimpleNamespace(y=y, y_simulated=y + 0.1 * rng.standard_normal(n),
                           y_predicted=y + 0.01 * rng.standard_normal(n),
                           time=dt * np.arange(n), simulation_fit=90.0, prediction_fit=99.0,
                           model=SimpleNamespace(dt=dt))


def _saved_labels_inside(fig):
    """Save like a user (no bbox_inches) and return the axes whose y label is cut or empty."""
    fig.savefig(io.BytesIO(), format="png", dpi=150)
    renderer = fig.canvas.get_renderer()
    bad = []
    for ax in fig.axes:
        label = ax.yaxis.label
        box = label.get_window_extent(renderer)
        if not label.get_text() or box.x0 < 0 or box.y0 < 0 or box.x1 > fig.bbox.x1 \
                or box.y1 > fig.bbox.y1:
            bad.append(ax)
    return bad


def test_palette_is_okabe_ito_and_lines_get_distinct_colours(run):
    assert plotting.COLORS[:3] == ("#0072B2", "#D55E00", "#009E73")
    assert len(set(plotting.COLORS)) == len(plotting.COLORS)
    ax = plot_parameters(run, true_values=[-1.5, 0.7, 1.0, 0.5])
    estimate_colours = [to_hex(ln.get_color()) for ln in ax.get_lines()[::2]]
    assert estimate_colours == [c.lower() for c in plotting.COLORS[:4]]
    # the global style is left alone
    assert to_hex(matplotlib.rcParams["axes.prop_cycle"].by_key()["color"][0]) == "#1f77b4"


def test_comparison_colours_are_distinct_and_units_are_shown(motor_report):
    ax = plot_comparison(motor_report, output_name="speed", output_unit="rad/s")
    colours = [to_hex(ln.get_color()) for ln in ax.get_lines()]
    assert len(set(colours)) == 3 and "#000000" in colours     # measured data in black
    assert ax.get_ylabel() == "speed (rad/s)" and ax.get_xlabel() == "time (s)"
    assert [t.get_text() for t in ax.get_legend().get_texts()][0] == "measured speed"


def test_saved_figures_keep_their_y_labels(run):
    ax = plot_trace(run)
    assert _saved_labels_inside(ax.figure) == []
    assert ax.get_ylabel() == r"$\mathrm{tr}\,P$"
    d = dc_motor(n_samples=400)
    from rlsfilt import select_order
    sel_ax = select_order(d.u, d.y, na=range(1, 4), nb=range(1, 4), nk=range(1, 3)).plot()
    assert sel_ax.get_ylabel() == "BIC"
    assert _saved_labels_inside(sel_ax.figure) == []
    fig = plot_tracking(run)
    assert _saved_labels_inside(fig) == []


def test_report_figure_labels_legends_and_bands(motor_report):
    fig = motor_report.plot()
    assert _saved_labels_inside(fig) == []
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        assert ax.get_xlabel() or ax.get_title(), ax
        legend = ax.get_legend()
        if legend is not None:                               # legends sit beside the data
            assert not legend.get_window_extent(renderer).overlaps(ax.get_window_extent(renderer))
    cmp_ax, over_ax, acf_ax, xcf_ax, mag_ax, phase_ax, step_ax = fig.axes
    # the Bode diagram carries the model's 95% band (frequency_response_band, seed 0)
    band = frequency_response_band(motor_report.model, omega=motor_report.plant_comparison.omega,
                                   rng=0)
    labels = [t.get_text() for t in mag_ax.get_legend().get_texts()]
    assert labels == ["95% band", "plant", "model"]
    fill = mag_ax.collections[0].get_paths()[0].vertices
    assert_allclose(fill[:, 1].max(), 20 * np.log10(band.magnitude_upper.max()), rtol=1e-12)
    assert phase_ax.get_ylabel() == "phase (deg)" and mag_ax.get_xscale() == "log"
    # lag 0 (always 1) is not drawn: the band sets the scale of the autocorrelation
    r = motor_report.residuals[0]
    assert acf_ax.get_ylim()[1] < 0.5
    assert acf_ax.get_ylim()[1] >= r.autocorrelation_band
    assert 0 not in acf_ax.get_lines()[0].get_xdata()
    # window of the last 400 samples above, the whole record below
    assert_allclose(cmp_ax.get_lines()[0].get_xdata(), motor_report.time[-400:])
    assert "whole record (2000 samples)" in over_ax.get_title(loc="left")


def test_autocorrelation_scale_without_lag_zero(rng):
    d = mass_spring_damper()
    rep = validate(ARX(1, 1, 1, dt=d.dt).fit(d.u, d.y), d.u, d.y)   # too simple: not white
    ax = plot_autocorrelation(rep.residuals[0])
    rho = rep.residuals[0].autocorrelation[1:]
    lo, hi = ax.get_ylim()
    assert_allclose(hi, 1.15 * max(rep.residuals[0].autocorrelation_band, np.abs(rho).max()))
    assert "NOT white" in ax.get_title()


def test_long_records_are_windowed_and_decimated(rng):
    n = 400_000
    rep = _fake_report(n, rng)
    ax = plot_comparison(rep)                   # a new figure: window + overview
    fig = ax.figure
    assert len(fig.axes) == 2
    for line in ax.get_lines():
        assert len(line.get_xdata()) == 400
    over = fig.axes[1]
    measured, error = over.get_lines()
    for line in (measured, error):
        assert len(line.get_xdata()) <= plotting.MAX_POINTS
    # the overview keeps the spike (per-bin extremes, not every k-th sample)
    assert measured.get_ydata().max() == 50.0
    assert_allclose(error.get_ydata().min(), (rep.y - rep.y_simulated).min())
    # a window as long as the record is decimated too, and keeps the spike
    ax2 = plot_comparison(rep, window=(0, n))
    for line in ax2.get_lines():
        assert len(line.get_xdata()) <= plotting.MAX_POINTS
    assert ax2.get_lines()[0].get_ydata().max() == 50.0
    fig.savefig(io.BytesIO(), format="png")


def test_long_tracking_histories_are_decimated(rng):
    n = 400_000
    theta = np.cumsum(0.001 * rng.standard_normal((n, 2)), axis=0)
    covs = np.broadcast_to(0.01 * np.eye(2), (n, 2, 2))
    fig = plot_tracking((theta, covs), true_values=np.zeros(2))
    for ax in fig.axes:
        for line in ax.get_lines():
            assert len(line.get_xdata()) <= plotting.MAX_POINTS
    top = fig.axes[0].get_lines()[0].get_ydata()
    assert top.max() == theta[:, 0].max() and top.min() == theta[:, 0].min()
    fig.savefig(io.BytesIO(), format="png")


def test_decimate_keeps_every_bin_extreme(rng):
    x = np.arange(10_001)
    y = rng.standard_normal(10_001)
    y[[5, 6000]] = np.nan
    xs, ys = plotting._decimate(x, y, max_points=100)
    assert len(xs) == 100 and np.all(np.diff(xs) >= 0)
    edges = np.linspace(0, len(y), 51).astype(int)
    for a, b in zip(edges[:-1], edges[1:]):
        inside = (xs >= a) & (xs < b)
        assert np.nanmax(y[a:b]) in ys[inside] and np.nanmin(y[a:b]) in ys[inside]
    assert_allclose(ys, y[xs])                              # points of the data, not averages
    short = plotting._decimate(x[:50], y[:50])
    assert short[0] is not None and len(short[0]) == 50


def test_plot_tracking_of_an_arx_fitted_recursively():
    ds = time_varying(rng=0)
    model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y, method="rls", lam=0.98)
    lag = model.max_lag
    fig = plot_tracking(model, t=ds.t[lag:], true_values=ds.theta_true[lag:])
    top, bottom = fig.axes
    labels = [t.get_text() for t in top.get_legend().get_texts()]
    assert labels == list(model.param_names_) + ["true"]
    assert_allclose(bottom.get_lines()[0].get_ydata(), model.recursive_residuals_)
    assert bottom.get_ylabel() == r"a-priori error $\varepsilon(t)$"
    with pytest.raises(ValueError, match="plot_tracking needs covariances"):
        plot_tracking(model.theta_history_)


def test_cusum_marks_are_in_samples():
    ds = time_varying(rng=0)                                 # jump at t = 1000
    lag = 2
    Phi, z = ARX(*ds.orders).regressors(ds.u, ds.y)
    res = cusum_squares(z, Phi)
    ax = plot_cusum(res, t=np.arange(lag, len(ds.y)))
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert res.rejected and "outside the lines" in texts
    assert not any(t.startswith("first crossing") for t in texts)   # at t = 92: misleading
    departure = [t for t in texts if t.startswith("largest departure")][0]
    assert abs(int(departure.rsplit("= ", 1)[1]) - ds.change_time) <= 5
    path = [ln for ln in ax.get_lines() if ln.get_label() == "CUSUM of squares"][0]
    assert_allclose(path.get_xdata(), np.arange(lag, len(ds.y))[res.index])
    assert_allclose(path.get_ydata(), res.statistic)
    with pytest.raises(ValueError, match=r"`t` must have shape \(N,\)"):
        plot_cusum(res, t=np.arange(10))
    outside = [ln for ln in ax.get_lines() if ln.get_label() == "outside the lines"][0]
    inside = (res.statistic >= res.bounds[0]) & (res.statistic <= res.bounds[1])
    assert np.all(np.isnan(outside.get_ydata()[inside]))
    assert_allclose(outside.get_ydata()[~inside], res.statistic[~inside])


def test_cusum_not_rejected_has_no_marks():
    """A test that does not reject draws the path and its lines, and marks nothing."""
    ds = time_varying(rng=0)
    Phi, z = ARX(*ds.orders).regressors(ds.u, ds.y)
    res = cusum(z, Phi)
    assert not res.rejected
    ax = plot_cusum(res)
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert texts == ["95% region under constancy", "CUSUM"]
    assert "not rejected" in ax.get_title()


def test_bode_of_a_band_and_bad_source():
    d = dc_motor(n_samples=300)
    band = frequency_response_band(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), rng=0)
    ax_mag, ax_phase = plot_bode(band, plant=d.plant)
    model_line = ax_mag.get_lines()[0]
    assert_allclose(model_line.get_ydata(), 20 * np.log10(np.abs(band.response[0, 0])))
    assert to_hex(model_line.get_color()) != to_hex(ax_mag.get_lines()[1].get_color())
    with pytest.raises(TypeError, match="`source` must be a PlantComparison or a FrequencyBand"):
        plot_bode(np.zeros(3))


def test_window_argument(motor_report):
    ax = plot_comparison(motor_report, window=(100, 300))
    assert_allclose(ax.get_lines()[0].get_xdata(), motor_report.time[100:300])
    with pytest.raises(ValueError, match=r"`window` must satisfy 0 <= start < stop <= 2000"):
        plot_comparison(motor_report, window=(300, 100))
    with pytest.raises(TypeError, match=r"`window` must be a pair \(start, stop\)"):
        plot_comparison(motor_report, window=5)


def test_docstring_examples_run():
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report = []
    tests = finder.find(plotting, "rlsfilt.plotting", globs={})
    assert sum(len(t.examples) for t in tests) > 40
    for test in tests:
        runner.run(test, out=report.append)
        plt.close("all")                  # each example's figures (pyplot warns at 20 open)
    assert runner.summarize(verbose=False).failed == 0, "".join(report)


def test_residual_titles_say_the_verdict_is_a_joint_test():
    """Issue #28, 7: lags above the 99 % band under a title saying "independent (p = 0.18)"
    read as a contradiction. A well-specified ARX whose joint tests pass with one lag of each
    correlation outside its per-lag band: the titles name the joint test, its lags and p, what
    the band is, and the count outside (computed here from the analysis' arrays) against the
    count expected by chance."""
    from scipy.signal import lfilter

    from rlsfilt.validation import residual_analysis

    g = np.random.default_rng(1)
    u = g.standard_normal(600)
    y = lfilter([0, 1.0, 0.5], [1, -0.7], u) + lfilter([1.0], [1, -0.7],
                                                         0.2 * g.standard_normal(600))
    r = residual_analysis(ARX(1, 2, 1).fit(u, y), u, y)
    assert r.is_white and r.is_independent and r.max_lag == 25
    n_cross = int(np.sum(np.abs(r.cross_correlation[0]) > r.cross_correlation_band[0]))
    n_auto = int(np.sum(np.abs(r.autocorrelation[1:]) > r.autocorrelation_band))
    assert n_cross == 1 and n_auto == 1
    title = plot_cross_correlation(r).get_title()
    assert title == (f"Input cross-correlation: independent (F-test joint over 51 lags, "
                     f"p = {r.pvalue_independent:.3g})\nshaded: 99% band per lag under "
                     f"independence; 1 outside (~0.51 by chance)")
    title = plot_autocorrelation(r).get_title()
    assert title == (f"Residual autocorrelation: white (Ljung-Box test joint over 25 lags, "
                     f"p = {r.pvalue_white:.3g})\nshaded: 99% band per lag under whiteness; "
                     f"1 outside (~0.25 by chance)")
    plt.close("all")
