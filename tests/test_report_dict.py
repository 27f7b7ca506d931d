"""`ValidationReport.to_dict`, the named exceptions, and `validate`'s options for records
on which the residual tests are undefined (what the command line relies on)."""

import json

import control
import numpy as np
import pytest
from scipy.signal import lfilter

import rlsfilt
from rlsfilt import ARX, ExactFitError, InsufficientDataError, datasets, validate
from rlsfilt.validation import information_criteria, residual_analysis, select_order


def _strict_json(d):
    return json.loads(json.dumps(d, allow_nan=False))


def test_to_dict_holds_the_report_numbers():
    d = datasets.thermal_process()
    model = ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y)
    rep = validate(model, d.u, d.y, plant=d.plant, metadata={"source": "thermal"})
    out = rep.to_dict()
    assert _strict_json(out) == out
    assert out["rlsfilt_version"] == rlsfilt.__version__
    assert out["model"] == "ARX" and out["orders"] == {"na": 1, "nb": [1], "nk": [4]}
    assert (out["na"], out["nb"], out["nk"]) == (1, [1], [4])
    assert out["theta_names"] == model.param_names_
    assert out["theta"] == model.theta_.tolist()
    assert out["theta_std"] == model.std_errors_.tolist()
    assert out["theta_lower"] == rep.intervals.lower.tolist()
    assert out["noise_variance"] == model.noise_variance_
    assert out["fit_percent"] == rep.simulation_fit
    assert out["fit_percent_prediction"] == rep.prediction_fit
    assert out["n_samples"] == len(d.y) and out["n_used"] == len(d.y) - model.max_lag
    r = rep.residuals[0]
    tests = out["residual_tests"]
    assert (tests["ljung_box"], tests["ljung_box_pvalue"], tests["white"]) == (
        r.q_statistic, r.pvalue_white, r.is_white)
    assert tests["independence_f"] == r.f_statistic and tests["max_lag"] == 25
    assert out["information_criteria"]["bic"] == rep.criteria.bic
    pc = out["plant_comparison"]
    assert pc["frequency_error"] == rep.plant_comparison.frequency_error
    assert pc["dc_gain_true"] == pytest.approx(float(np.real(d.plant.dcgain())), rel=1e-9)
    assert out["validation_skipped"] is None and out["metadata"] == {"source": "thermal"}
    # the transfer functions rebuild the model in python-control
    tf = out["transfer_functions"][0]
    G = control.tf(tf["num"], tf["den"], tf["dt"])
    z = np.exp(1j * np.linspace(0.01, 3.0, 9))
    np.testing.assert_allclose(G(z), model.to_tf()(z), rtol=1e-12)


def test_non_finite_numbers_become_null():
    """No spare equations: NaN noise variance, infinite quantiles; JSON has no NaN."""
    rng = np.random.default_rng(1)
    u = rng.standard_normal(6)
    y = rng.standard_normal(6)
    model = ARX(2, 2).fit(u, y)                    # exactly 4 rows for 4 parameters
    assert np.isnan(model.noise_variance_)
    rep = validate(model, u, y, skip_undefined=True, max_lag=25)
    out = rep.to_dict()
    assert _strict_json(out) == out
    assert out["noise_variance"] is None and out["theta_std"] == [None] * 4
    assert "residual_tests" not in out and "information_criteria" not in out
    assert out["validation_skipped"] == "only 4 residuals, too few for the residual tests at " \
                                        "max_lag = 25"
    assert not rep.passed and "Residual tests skipped: only 4 residuals" in str(rep.summary())


def test_exact_fit_is_a_named_error_or_a_skipped_test():
    u = np.sign(np.random.default_rng(4).standard_normal(300))
    y = lfilter([0.0, 1.0], [1.0], u)
    model = ARX.from_polynomials([], [1.0])       # the plant itself: zero residuals
    for call in (lambda: residual_analysis(model, u, y), lambda: information_criteria(model, u, y),
                 lambda: validate(model, u, y)):
        with pytest.raises(ExactFitError, match="exact fit"):
            call()
        with pytest.raises(ValueError):   # and still a ValueError, as before
            call()
    rep = validate(model, u, y, skip_undefined=True)
    assert rep.skipped == "the residuals are zero or constant (an exact fit)"
    assert rep.residuals == () and rep.criteria is None and rep.simulation_fit == 100.0
    assert "Verdict: residual tests skipped" in str(rep.summary())
    assert "skipped" in rep._repr_html_()
    fig = rep.plot()   # output, the note on the skipped tests, Bode (2)
    assert len(fig.axes) == 4
    assert any("residual tests skipped" in t.get_text() for ax in fig.axes for t in ax.texts)
    with pytest.raises(ExactFitError, match="fits the data exactly"):
        select_order(u, y, na=[0], nb=[1, 2], nk=[1])


def test_too_little_data_is_a_named_error(rng):
    u, y = rng.standard_normal(60), rng.standard_normal(60)
    with pytest.raises(InsufficientDataError, match="`y` must have at least max_lag"):
        ARX(2, 2).fit(u[:5], y[:5])
    model = ARX(2, 2).fit(u, y)
    with pytest.raises(InsufficientDataError, match="`max_lag` must be small against"):
        validate(model, u, y, max_lag=40)
    with pytest.raises(InsufficientDataError, match="too short for these orders"):
        select_order(u[:8], y[:8], na=range(3), nb=range(1, 4))
    assert issubclass(InsufficientDataError, ValueError) and issubclass(ExactFitError, ValueError)


def test_automatic_max_lag_is_the_explicit_one_it_chose(rng):
    u = rng.standard_normal(400)
    y = lfilter([0.0, 1.0, 0.5], [1.0, -1.5, 0.7], u) + 0.1 * rng.standard_normal(400)
    model = ARX(2, 2).fit(u, y)
    auto = validate(model, u, y, max_lag="auto")
    assert auto.residuals[0].max_lag == 25                     # min(25, 398 // 4)
    short = validate(model, u[:60], y[:60], max_lag="auto")
    lag = short.residuals[0].max_lag
    # 58 // 4 = 14 leaves too few rows for the independence test: halved to 7
    assert lag == 7
    with pytest.raises(InsufficientDataError):
        validate(model, u[:60], y[:60], max_lag=14)
    ref = validate(model, u[:60], y[:60], max_lag=lag)
    assert short.residuals[0].pvalue_white == ref.residuals[0].pvalue_white
    assert short.residuals[0].pvalue_independent == ref.residuals[0].pvalue_independent


def test_validate_rejects_bad_options(rng):
    u, y = rng.standard_normal(100), rng.standard_normal(100)
    model = ARX(1, 1).fit(u, y)
    with pytest.raises(TypeError, match="`metadata` must be a dict; got list"):
        validate(model, u, y, metadata=[1])
    with pytest.raises(TypeError, match="`max_lag` must be an integer"):
        validate(model, u, y, max_lag="many")
