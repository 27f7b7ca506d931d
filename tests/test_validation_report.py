"""validate(): numbers equal their building blocks; text, HTML and one figure."""

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from scipy.signal import lfilter  # noqa: E402

import rlsfilt  # noqa: E402
from rlsfilt import ARX, compare, datasets  # noqa: E402
from rlsfilt.validation import (  # noqa: E402
    PlantComparison,
    ValidationReport,
    fit_percent,
    information_criteria,
    residual_analysis,
    validate,
)


@pytest.fixture
def motor():
    d = datasets.dc_motor()
    return d, ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u[:1200], d.y[:1200])


def test_report_numbers_are_the_building_blocks(motor):
    d, model = motor
    u, y = d.u[1200:], d.y[1200:]
    rep = validate(model, u, y, plant=d.plant, initial="measured")
    assert isinstance(rep, ValidationReport)
    L = 2     # from the measured past: the fits start after the max_lag samples that set it
    assert rep.start == L and rep.initial == "measured"
    y_sim = model.simulate(u, y0=y[:L])
    assert rep.simulation_fit == pytest.approx(fit_percent(y[L:], y_sim[L:]), rel=1e-12)
    Phi, target = model.regressors(u, y)
    assert rep.prediction_fit == pytest.approx(fit_percent(target, Phi @ model.theta_),
                                               rel=1e-12)
    ra = residual_analysis(model, u, y)
    assert rep.residuals[0].pvalue_white == ra.pvalue_white
    assert rep.residuals[0].pvalue_independent == ra.pvalue_independent
    assert rep.criteria.bic == information_criteria(model, u, y).bic
    pc = PlantComparison(model, d.plant)
    assert rep.plant_comparison.frequency_error == pc.frequency_error
    assert rep.passed
    assert rep.simulation_fit > 90 and rep.prediction_fit > rep.simulation_fit - 5
    assert rlsfilt.validate is validate
    # the default: MATLAB compare's estimated initial state, fits over the whole record
    rep_e = validate(model, u, y, plant=d.plant)
    assert rep_e.start == 0 and rep_e.initial == "estimate"
    assert rep_e.simulation_fit == compare(model, u, y).fit
    assert rep_e.prediction_fit == compare(model, u, y, horizon=1).fit
    assert rep_e.simulation_fit == pytest.approx(rep.simulation_fit, abs=0.1)


def test_report_renders_text_html_and_figure(motor):
    d, model = motor
    rep = validate(model, d.u, d.y, plant=d.plant)
    text = str(rep.summary())
    for piece in ("Validation of ARX(na=2, nb=2, nk=1) on 2000 samples", "Simulation fit",
                  "whiteness (Ljung-Box", "BIC =", "95% confidence intervals", "b2",
                  "Comparison with the true plant", "Verdict: residual tests passed"):
        assert piece in text, piece
    assert repr(rep) == text
    html = rep._repr_html_()
    assert html.startswith("<div>") and "<table>" in html and "residual tests passed" in html
    assert "max rel. frequency error vs plant" in html
    fig = rep.plot()
    assert isinstance(fig, Figure)
    # output window and overview, 2 residual panels, Bode (2) with the band, step
    assert len(fig.axes) == 7
    titles = [ax.get_title() for ax in fig.axes]
    assert titles[0] == "Model output against the data"
    assert any(t.startswith("Bode") for t in titles) and any(t.startswith("Step") for t in titles)
    fig.savefig(__import__("io").BytesIO(), format="png")
    plt.close("all")


def test_report_without_plant_and_for_an_underfit():
    d = datasets.mass_spring_damper()
    model = ARX(1, 1, 1, dt=d.dt).fit(d.u, d.y)
    rep = validate(model, d.u, d.y)
    assert rep.plant_comparison is None
    assert not rep.passed
    assert "FAILED" in str(rep.summary()) and "NOT white" in str(rep.summary())
    assert "Comparison with the true plant" not in str(rep.summary())
    assert "FAILED" in rep._repr_html_()
    fig = plt.figure()
    assert rep.plot(fig=fig) is fig
    assert len(fig.axes) == 6            # window, overview, 2 residual panels, Bode (2)
    assert fig.axes[0].get_xlabel() == "time (s)"
    plt.close("all")


def test_report_several_outputs(rng):
    u = rng.standard_normal(800)
    Y = np.column_stack([lfilter([0, 1.0], [1, -0.5], u), lfilter([0, 0.3], [1, -0.2], u)])
    Y += 0.05 * rng.standard_normal((800, 2))
    model = ARX(1, 1).fit(u, Y)
    rep = validate(model, u, Y, max_lag=10, alpha=0.05)
    assert len(rep.residuals) == 2
    assert rep.simulation_fit.shape == (2,)
    assert rep.residuals[1].output == 1 and rep.residuals[0].max_lag == 10
    assert "output 1:" in str(rep.summary())
    assert len(rep.plot().axes) == 6
    assert rep.plot().axes[0].get_xlabel() == "sample"
    plt.close("all")


def test_validate_errors():
    d = datasets.thermal_process()
    with pytest.raises(rlsfilt.NotFittedError, match="not fitted yet"):
        validate(ARX(1, 1), d.u, d.y)
    model = ARX(1, 1, 4).fit(d.u, d.y)
    with pytest.raises(ValueError, match="`u` and `y` must have the same length"):
        validate(model, d.u[:500], d.y)


def test_report_accepts_pandas_recursive_and_true_models():
    pd = pytest.importorskip("pandas")
    d = datasets.dc_motor()
    df = pd.DataFrame({"u": d.u, "y": d.y})
    model = ARX(2, 2, 1, dt=d.dt).fit(df[["u"]], df["y"])
    rep = validate(model, df[["u"]], df["y"], plant=d.plant)
    assert rep.passed and rep.simulation_fit > 90
    rls = ARX(2, 2, 1, dt=d.dt).fit(d.u, d.y, method="rls", lam=0.999)
    assert validate(rls, d.u, d.y).simulation_fit > 90
    true = ARX.from_polynomials(d.a, d.b, nk=d.nk, dt=d.dt)
    rep_true = validate(true, d.u, d.y, plant=d.plant)
    assert rep_true.plant_comparison.frequency_error < 1e-9
    np.testing.assert_array_equal(rep_true.intervals.lower, rep_true.intervals.upper)
    assert "Validation of ARX" in str(rep_true.summary())


def test_signal_counts_must_match_the_fitted_model():
    """Data with more inputs/outputs than the fit is named, not a NumPy matmul error."""
    from rlsfilt.validation import information_criteria, residual_analysis

    d = datasets.thermal_process()
    model = ARX(1, 1, 4).fit(d.u, d.y)
    u2 = np.column_stack([d.u, d.u])
    y2 = np.column_stack([d.y, d.y])
    msg = (r"`u` and `y` must have the 1 input and 1 output column\(s\) the model was fitted "
           r"with; got `u` of shape \(1000, 2\) and `y` of shape \(1000,\)")
    for call in (residual_analysis, information_criteria, validate):
        with pytest.raises(ValueError, match=msg):
            call(model, u2, d.y)
        with pytest.raises(ValueError, match=r"1 output column\(s\) .* `y` of shape \(1000, 2\)"):
            call(model, d.u, y2)


def test_true_model_validates_without_any_warning():
    """An exact model (zero covariance, no spare equations) emits no warning at all
    and no floating-point error that is not handled on purpose."""
    import warnings

    d = datasets.dc_motor(n_samples=800)
    true = ARX.from_polynomials(d.a, d.b, nk=d.nk, dt=d.dt)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rep = validate(true, d.u, d.y, plant=d.plant)
        text, page = str(rep.summary()), rep._repr_html_()
    assert caught == [], [str(w.message) for w in caught]
    assert rep.intervals.quantile == np.inf
    np.testing.assert_array_equal(rep.intervals.lower, rep.intervals.upper)
    assert "Validation of ARX" in text and "<" in page
