"""Stability said plainly: poles, is_stable, dc_gain, and reports of unstable models."""

import control
import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX
from rlsfilt.data import IOData
from rlsfilt.exceptions import OperatingPointWarning
from rlsfilt.validation import validate


def test_poles_and_gain_of_a_siso_model():
    model = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=3, dt=0.1)
    np.testing.assert_allclose(np.sort_complex(model.poles()),
                               np.sort_complex(np.roots([1.0, -1.5, 0.7])), rtol=1e-14)
    assert len(model.poles()) == 2            # the delay adds no poles at the origin
    assert model.is_stable
    assert model.dc_gain() == pytest.approx(1.5 / 0.2, rel=1e-14)
    assert model.dc_gain() == pytest.approx(float(control.dcgain(model.to_tf())), rel=1e-12)
    assert model.stability_text() == "stable (largest pole magnitude 0.837)"


def test_mimo_poles_and_gain_equal_python_control(rng):
    u = rng.standard_normal((600, 2))
    y = np.column_stack([lfilter([0, 1.0], [1, -0.5], u[:, 0]) + 0.3 * u[:, 1],
                         lfilter([0, 0.4], [1, -0.8], u[:, 1])])
    y += 0.01 * rng.standard_normal(y.shape)
    model = ARX(1, 1, 1).fit(u, y)
    ss_poles = np.linalg.eigvals(model.to_ss().A)
    ss_poles = ss_poles[np.abs(ss_poles) > 1e-12]
    np.testing.assert_allclose(np.sort_complex(model.poles()), np.sort_complex(ss_poles),
                               rtol=1e-10)
    np.testing.assert_allclose(model.dc_gain(), control.dcgain(model.to_tf()), rtol=1e-10)
    assert model.dc_gain().shape == (2, 2)


def test_unstable_and_integrating_models():
    unstable = ARX.from_polynomials([-2.04, 1.0404], [1.0])        # double pole at 1.02
    assert not unstable.is_stable
    np.testing.assert_allclose(np.abs(unstable.poles()), [1.02, 1.02], rtol=1e-7)
    assert unstable.stability_text() == ("unstable model, largest pole magnitude 1.02, "
                                         "simulation diverges")
    integrator = ARX.from_polynomials([-1.0], [0.5])
    assert not integrator.is_stable and integrator.dc_gain() == np.inf
    assert "marginally stable" in integrator.stability_text()
    fir = ARX.from_polynomials([], [1.0, 2.0])
    assert fir.is_stable and len(fir.poles()) == 0 and fir.dc_gain() == 3.0


def test_validate_reports_an_unstable_model_instead_of_a_huge_fit(rng):
    u = rng.standard_normal(400)
    y = lfilter([0, 1.0], [1, -0.9], u) + 0.05 * rng.standard_normal(400)
    unstable = ARX.from_polynomials([-2.04, 1.0404], [1.0], dt=1.0)
    report = validate(unstable, u, y, max_lag=10)
    assert report.is_unstable and report.max_pole_magnitude == pytest.approx(1.02, rel=1e-6)
    assert np.isnan(report.simulation_fit)
    message = "unstable model, largest pole magnitude 1.02, simulation diverges"
    text = str(report.summary())
    assert f"Simulation fit      : {message}" in text and "e+" not in text.split("\n")[3]
    assert message in report._repr_html_()
    ax = report.plot_comparison()
    assert any(message in t.get_text() for t in ax.get_legend().get_texts())
    stable = validate(ARX(1, 1).fit(u, y), u, y, max_lag=10)
    assert not stable.is_unstable and stable.stability.startswith("stable")
    assert 0 < stable.simulation_fit < 100


def test_validate_takes_iodata_of_several_experiments(rng):
    runs = []
    for n in (300, 200):
        u = rng.standard_normal(n)
        runs.append((u, lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u)
                     + lfilter([1], [1, -1.5, 0.7], 0.1 * rng.standard_normal(n))))
    data = IOData([r[0] for r in runs], [r[1] for r in runs], dt=0.5, tstart=[0, 1000])
    model = ARX(2, 2, 1, dt=0.5).fit(data)
    report = validate(model, data, max_lag=10)
    assert report.experiment_lengths == (300, 200) and len(report.y) == 500
    assert "on 500 samples of 2 experiments" in str(report.summary())
    # each experiment is simulated from its own start, and the fit covers both
    single = [validate(model, u, y, max_lag=10) for u, y in runs]
    np.testing.assert_array_equal(report.y_simulated[300:], single[1].y_simulated)
    e = np.concatenate([s.y - s.y_simulated for s in single])     # each from its own x0
    y_all = np.concatenate([s.y for s in single])
    expected = 100 * (1 - np.linalg.norm(e) / np.linalg.norm(y_all - y_all.mean()))
    assert report.simulation_fit == pytest.approx(expected, rel=1e-12)
    np.testing.assert_allclose(report.time[300:], 1000 + 0.5 * np.arange(200))
    # the residuals are those of the stacked regression
    np.testing.assert_allclose(report.residuals[0].residuals, model.residuals_, rtol=1e-10,
                               atol=1e-12)


def test_validate_warns_about_an_ignored_operating_point(rng):
    u = 40.0 + rng.standard_normal(300)
    y = 97.0 + lfilter([0, 0.5], [1, -0.9], u - 40.0) + 0.05 * rng.standard_normal(300)
    with pytest.warns(OperatingPointWarning, match=r"^ARX.fit: input 'u' has mean 39.9.*"
                                                   r"offset=True"):
        raw = ARX(1, 1).fit(u, y)                 # the fit says so, and validate again
    with pytest.warns(OperatingPointWarning, match=r"input 'u' has mean 39.9.*output 'y' has "
                                                   r"mean 96.6.* and the model has no offset "
                                                   r"handling.*offset=True"):
        validate(raw, u, y, max_lag=10)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        validate(ARX(1, 1, offset=True).fit(u, y), u, y, max_lag=10)
        validate(ARX(1, 1).fit(u - 40, y - 97), u - 40, y - 97, max_lag=10)


def test_json_says_unstable_and_carries_the_operating_point(rng):
    import json

    u = rng.standard_normal(400)
    y = lfilter([0, 1.0], [1, -0.9], u) + 0.05 * rng.standard_normal(400)
    out = validate(ARX.from_polynomials([-2.04, 1.0404], [1.0], dt=1.0), u, y,
                   max_lag=10).to_dict()
    assert out["fit_percent"] is None and out["unstable"] is True
    assert out["stability"] == "unstable model, largest pole magnitude 1.02, simulation diverges"
    assert out["max_pole_magnitude"] == pytest.approx(1.02, rel=1e-6)
    assert json.loads(json.dumps(out, allow_nan=False)) == out
    model = ARX(1, 1, offset=True).fit(40 + u, 97 + y)
    d = model.to_dict()
    assert d["offset"] is True and d["stable"] is True and len(d["poles"]) == 1
    assert d["input_offset"] == [pytest.approx(40 + u.mean())]
    assert d["intercept"] == pytest.approx(model.intercept_)
    assert d["dc_gain"] == pytest.approx(model.dc_gain())
