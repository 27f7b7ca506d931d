"""The declared model interface: validation, the report, criteria, intervals, bands,
the plant comparison and plotting take any `IdentifiedModel`, not only ARX.

`FirstOrderOE` (tests/_toy_models.py) is written against the interface alone and
has a non-ARX predictor (the simulated output)."""

import json

import control
import matplotlib.pyplot as plt
import numpy as np
import pytest
from _toy_models import FirstOrderOE
from scipy.signal import lfilter

from rlsfilt import ARX, NotFittedError, validate
from rlsfilt.models import IdentifiedModel, check_is_fitted
from rlsfilt.validation import (
    PlantComparison,
    frequency_response_band,
    information_criteria,
    parameter_intervals,
    residual_analysis,
)

F_TRUE, B_TRUE = -0.8, 0.5


@pytest.fixture
def oe_record():
    """Output error: white measurement noise on the output of b / (1 + f q^-1) q^-1."""
    gen = np.random.default_rng(11)
    u = gen.standard_normal(1500)
    y = lfilter([0.0, B_TRUE], [1.0, F_TRUE], u) + 0.2 * gen.standard_normal(1500)
    return u, y


def test_the_toy_model_is_an_identified_model(oe_record):
    u, y = oe_record
    model = FirstOrderOE().fit(u, y)
    assert isinstance(model, IdentifiedModel)
    np.testing.assert_allclose(model.theta_, [F_TRUE, B_TRUE], atol=0.03)
    # its predictor in regression form: predict(horizon=1) == Phi @ theta_ on the rows
    Phi, target = model.regressors(u, y)
    np.testing.assert_allclose(model.predict(u, y)[model.max_lag:], Phi @ model.theta_,
                               rtol=1e-12, atol=1e-12)
    # and it is not the ARX predictor: measured outputs do not enter it
    np.testing.assert_array_equal(model.predict(u, y), model.predict(u, np.zeros_like(y)))


def test_conversions_come_from_the_polynomials(oe_record):
    u, y = oe_record
    model = FirstOrderOE(dt=0.1).fit(u, y)
    f, b = model.theta_
    G = model.to_tf()
    np.testing.assert_allclose(G.poles(), [-f], rtol=1e-14)
    np.testing.assert_allclose(G.dcgain(), b / (1 + f), rtol=1e-13)
    T = 0.1 * np.arange(len(u))
    y_ctrl = control.forced_response(G, T, u).outputs
    np.testing.assert_allclose(model.simulate(u), y_ctrl, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(model.simulate(u), lfilter([0.0, b], [1.0, f], u), rtol=1e-13)
    ss = model.to_ss()
    y_ss = control.forced_response(ss, T, u).outputs
    np.testing.assert_allclose(y_ss, y_ctrl, rtol=1e-9, atol=1e-12)
    om = np.linspace(0.1, np.pi / 0.1, 7)
    z = np.exp(1j * om * 0.1)
    np.testing.assert_allclose(model.frequency_response(om)[0, 0], b / (z + f), rtol=1e-12)
    # the noise model of an output-error model is 1
    np.testing.assert_allclose(model.frequency_response(om, noise=True)[0, 0], 1.0)


def test_validate_report_and_plot_accept_a_non_arx_model(oe_record):
    u, y = oe_record
    model = FirstOrderOE().fit(u, y)
    plant = control.tf([B_TRUE], [1.0, F_TRUE], True)
    rep = validate(model, u, y, plant=plant)
    # residuals are the simulation errors: white measurement noise, independent of u
    assert rep.passed
    Phi, target = model.regressors(u, y)
    np.testing.assert_allclose(rep.residuals[0].residuals, target - Phi @ model.theta_,
                               rtol=1e-13)
    assert rep.plant_comparison.frequency_error < 0.1
    assert rep.criteria.n_params == 2
    text = str(rep.summary())
    assert "Validation of FirstOrderOE(n_iter=50) on 1500 samples" in text
    assert "f1" in text and "b1" in text
    assert "FirstOrderOE" in rep._repr_html_()
    fig = rep.plot()
    assert len(fig.axes) == 7   # output (window + overview), 2 residual tests, Bode (2), step
    plt.close("all")
    d = json.loads(json.dumps(rep.to_dict(), allow_nan=False))
    assert d["model"] == "FirstOrderOE" and d["orders"] == {"nb": 1, "nf": 1, "nk": 1}
    assert d["theta_names"] == ["f1", "b1"] and d["theta"] == model.theta_.tolist()
    assert d["polynomials"]["F"] == [[[1.0, model.theta_[0]]]]
    assert d["residual_tests"]["white"] is True


def test_criteria_compare_model_classes(oe_record):
    """Order-selection reporting across classes: on output-error data the OE model beats
    the ARX model with as many parameters, and the numbers are the textbook formulas."""
    u, y = oe_record
    oe = FirstOrderOE().fit(u, y)
    arx = ARX(1, 1).fit(u, y)
    ic_oe, ic_arx = information_criteria(oe, u, y), information_criteria(arx, u, y)
    assert ic_oe.n_params == ic_arx.n_params == 2
    assert ic_oe.bic < ic_arx.bic
    Phi, target = oe.regressors(u, y)
    e = target - Phi @ oe.theta_
    V = float(e @ e) / len(e)
    np.testing.assert_allclose(ic_oe.loss, V, rtol=1e-13)
    N = len(e)
    np.testing.assert_allclose(ic_oe.bic, N * np.log(V) + 2 * np.log(N)
                               + N * (np.log(2 * np.pi) + 1), rtol=1e-13)


def test_intervals_bands_and_plant_comparison(oe_record):
    u, y = oe_record
    model = FirstOrderOE(dt=0.5).fit(u, y)
    ci = parameter_intervals(model)
    assert ci.names == ["f1", "b1"]
    assert ci.contains([F_TRUE, B_TRUE]).all()
    band = frequency_response_band(model, n_draws=300, rng=0)
    z = np.exp(1j * band.omega * 0.5)
    np.testing.assert_allclose(band.response[0, 0], model.to_tf()(z), rtol=1e-10)
    assert band.plot().axes[0].get_ylabel()
    cmp = PlantComparison(model, control.tf([B_TRUE], [1.0, F_TRUE], 0.5))
    assert cmp.max_pole_distance < 0.03
    assert len(cmp.plot().axes) == 3
    res = residual_analysis(model, u, y)
    assert res.is_white
    plt.close("all")


def test_one_fitted_check_with_one_wording(oe_record):
    u, y = oe_record
    for call in (lambda m: validate(m, u, y), lambda m: information_criteria(m, u, y),
                 lambda m: parameter_intervals(m), lambda m: m.to_tf(), lambda m: m.summary(),
                 lambda m: m.theta_, lambda m: m.param_names_):
        with pytest.raises(NotFittedError, match=r"^This FirstOrderOE instance is not fitted "
                                                 r"yet; call `fit\(u, y\)` before using `"):
            call(FirstOrderOE())
    with pytest.raises(TypeError, match="`model` must be a fitted ARX model or another rlsfilt "
                                        "model"):
        check_is_fitted(object(), "validate")
    check_is_fitted(FirstOrderOE().fit(u, y), "validate")  # fitted: no error


def test_summary_of_any_model_has_the_coefficient_table(oe_record):
    u, y = oe_record
    model = FirstOrderOE().fit(u, y)
    text = str(model.summary())
    assert "coef" in text and "P>|t|" in text and "[0.025" in text
    assert "<table>" in model._repr_html_()
    assert repr(FirstOrderOE()) == "FirstOrderOE(n_iter=50, dt=True)"
    assert FirstOrderOE().get_params() == {"n_iter": 50, "dt": True}


def test_an_incomplete_model_cannot_be_instantiated():
    class Half(IdentifiedModel):
        def __init__(self, dt=True):
            self.dt = dt

        def fit(self, u, y):
            return self

    with pytest.raises(TypeError, match="abstract"):
        Half()
