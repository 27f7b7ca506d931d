"""Figures take the signal names and units from the data (or from the fitted model)."""

import io

import matplotlib
import numpy as np
import pytest
from numpy.testing import assert_allclose

from rlsfilt import ARX, validate
from rlsfilt.datasets import dc_motor, heat_exchanger
from rlsfilt.plotting import plot_comparison, plot_report

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


@pytest.fixture(autouse=True)
def _close():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def exchanger():
    ds = heat_exchanger()
    model = ARX(*ds.orders, dt=ds.dt, offset=True).fit(ds)
    return ds, model, validate(model, ds, plant=ds.plant)


def test_report_knows_the_signals_of_the_data(exchanger):
    ds, model, rep = exchanger
    assert rep.input_names == ("flow",) and rep.output_names == ("T_out",)
    assert rep.input_units == ("%",) and rep.output_units == ("degC",)
    assert rep.experiment_names == ("run1", "run2")


def test_heat_exchanger_report_figure_is_labelled_from_the_data(exchanger):
    ds, model, rep = exchanger
    fig = rep.plot()
    cmp_ax, over_ax, acf_ax, xcf_ax, mag_ax, phase_ax, step_ax = fig.axes
    assert cmp_ax.get_ylabel() == "T_out (degC)" and over_ax.get_ylabel() == "T_out (degC)"
    legend = [t.get_text() for t in cmp_ax.get_legend().get_texts()]
    assert legend[0] == "measured T_out"
    assert step_ax.get_ylabel() == "T_out (degC) per 1 % of flow"
    assert mag_ax.get_ylabel() == r"$|G(e^{j\omega T})|$ (dB re 1 degC/%)"
    assert mag_ax.get_title().split("\n")[0].endswith("(flow to T_out)")
    assert "run1 (1200), run2 (800)" in over_ax.get_title(loc="left")
    fig.savefig(io.BytesIO(), format="png")


def test_explicit_labels_win(exchanger):
    rep = exchanger[2]
    ax = plot_comparison(rep, output_name="outlet", output_unit="K")
    assert ax.get_ylabel() == "outlet (K)"
    fig = plot_report(rep, output_name="outlet")
    assert fig.axes[0].get_ylabel() == "outlet (degC)"


def test_model_names_when_the_validation_data_are_plain_arrays(exchanger):
    ds, model, _ = exchanger
    run = ds.getexp("run2")
    rep = validate(model, np.asarray(run.u), np.asarray(run.y))
    assert rep.output_names == ("T_out",) and rep.output_units == ("degC",)
    assert plot_comparison(rep).get_ylabel() == "T_out (degC)"


def test_unnamed_signals_keep_the_plain_labels():
    d = dc_motor(n_samples=300)
    rep = validate(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), d.u, d.y, plant=d.plant)
    fig = rep.plot()
    assert fig.axes[0].get_ylabel() == "y"
    assert fig.axes[-1].get_ylabel() == "step response $y(t)$"
    assert fig.axes[-3].get_ylabel() == r"$|G(e^{j\omega T})|$ (dB)"


def test_experiments_are_laid_one_after_the_other_and_never_joined(exchanger):
    ds, model, rep = exchanger
    ax = plot_comparison(rep, window=(1100, 1300))            # straddles the seam at 1200
    t = ax.get_lines()[0].get_xdata()
    y = ax.get_lines()[0].get_ydata()
    assert np.all(np.diff(t) > 0)                             # one increasing time axis
    gap = np.flatnonzero(np.isnan(y))
    assert len(gap) == 1 and t[gap[0]] == pytest.approx(1199.5)
    assert_allclose(np.delete(y, gap), rep.y[1100:1300])
    assert ax.get_title() == "Model output against the data (run1, run2)"
    # the default figure: the overview spans both runs and breaks the lines at the seam
    ax = plot_comparison(rep)
    over = ax.figure.axes[1]
    measured, error = [ln for ln in over.get_lines() if len(ln.get_xdata()) > 2]
    assert over.get_xlim() == pytest.approx((0.0, 1999.0))
    assert np.isnan(measured.get_ydata()).sum() == 1
    assert ax.get_title() == "Model output against the data (run2)"


def test_overview_error_is_drawn_around_an_operating_point(exchanger):
    ds, model, rep = exchanger
    over = plot_comparison(rep).figure.axes[1]
    measured, error = [ln for ln in over.get_lines() if len(ln.get_xdata()) > 2]
    mean = float(np.mean(rep.y))
    e = error.get_ydata()
    finite = np.isfinite(e)
    # the error keeps its shape and sits at the output's mean, inside the output's range
    expected = np.insert(rep.y - rep.y_simulated + mean, 1200, np.nan)
    assert_allclose(e, expected, rtol=0, atol=1e-12)
    assert "(+ 96.85, the mean)" in error.get_label()
    assert rep.y.min() < e[finite].min() and e[finite].max() < rep.y.max()


def test_predictions_from_an_assumed_past_are_not_drawn(exchanger):
    ds, model, rep_e = exchanger
    # the default (an estimated initial state) draws every sample: nothing is assumed
    assert rep_e.start == 0
    ax = plot_comparison(rep_e, window=(0, 100))
    assert np.isfinite(ax.get_lines()[2].get_ydata()).all()
    assert "x0 estimated" in ax.get_lines()[1].get_label()
    rep = validate(model, ds, plant=ds.plant, initial="measured")
    assert rep.start == 9                                        # max_lag of ARX(2, 2, 8)
    ax = plot_comparison(rep, window=(1100, 1300))
    predicted = ax.get_lines()[2].get_ydata()                   # NaN at the seam, then 9
    gap = int(np.flatnonzero(np.isnan(ax.get_lines()[0].get_ydata()))[0])
    assert np.all(np.isnan(predicted[gap:gap + 1 + 9])) and np.isfinite(predicted[gap + 10])
    assert np.isfinite(predicted[:gap]).all()
    ax = plot_comparison(rep, window=(0, 100))
    assert np.isnan(ax.get_lines()[2].get_ydata()[:9]).all()
    assert_allclose(ax.get_lines()[2].get_ydata()[9:], rep.y_predicted[9:100])


def test_bode_says_how_wide_its_band_is_and_labels_both_frequency_axes(exchanger):
    ds, model, _ = exchanger
    rep = validate(model, ds)                                    # no plant: band only
    fig = rep.plot()
    mag_ax, phase_ax = fig.axes[-2:]
    band = rep.frequency_band()
    width = 20 * np.log10(band.magnitude_upper / band.magnitude_lower)
    assert mag_ax.get_title().split("\n") == [
        "Frequency response (flow to T_out)",
        f"95% band (parameters): {width.min():.2g} to {width.max():.2g} dB wide"]
    assert mag_ax.get_xlabel() == phase_ax.get_xlabel() == r"$\omega$ (rad/s)"
