"""validate(), residual_analysis() and the report on time-series models (AR, ARMA: no input).

The whiteness test is the only residual test (nothing to cross-correlate with); its
statistic is statsmodels' Ljung-Box on the one-step prediction errors. There is no
simulation; the prediction fit and the criteria are those of the prediction errors.
"""

import json

import numpy as np
import pytest
from scipy.signal import lfilter
from statsmodels.stats.diagnostic import acorr_ljungbox

from rlsfilt import AR, ARMA, compare, validate
from rlsfilt.validation import fit_percent, information_criteria, residual_analysis


@pytest.fixture
def series():
    gen = np.random.default_rng(11)
    return lfilter([1.0, 0.4], [1.0, -1.1, 0.3], gen.standard_normal(1200))


def test_report_of_a_time_series_has_the_whiteness_test_only(series):
    model = ARMA(2, 1).fit(series)
    rep = validate(model, None, series, max_lag=20)
    assert rep.is_time_series
    (r,) = rep.residuals
    L = model.max_lag
    eps_all = series - model.predict(None, series)
    eps = eps_all[L:]
    np.testing.assert_allclose(r.residuals, eps, rtol=1e-12, atol=1e-13)
    lb = acorr_ljungbox(eps, lags=[20])
    np.testing.assert_allclose(r.q_statistic, lb["lb_stat"].iloc[0], rtol=1e-10)
    np.testing.assert_allclose(r.pvalue_white, lb["lb_pvalue"].iloc[0], rtol=1e-8)
    assert r.is_independent is None and not r.has_input and r.cross_correlation.shape == (0, 41)
    assert np.isnan(r.f_statistic) and np.isnan(r.pvalue_independent)
    assert rep.passed is (r.is_white is True)
    # the fits: no simulation; the one-step prediction as fit_percent computes it
    assert np.isnan(rep.simulation_fit)
    # from rest, the prediction is y - eps on every sample
    rep0 = validate(model, None, series, max_lag=20, initial="zero")
    np.testing.assert_allclose(rep0.prediction_fit, fit_percent(series, series - eps_all),
                               rtol=1e-12)
    # the default estimates the predictor's initial state: compare's fit, at least as good
    assert rep.initial == "estimate"
    assert rep.prediction_fit == compare(model, None, series, horizon=1).fit
    assert rep.prediction_fit >= rep0.prediction_fit
    ic = information_criteria(model, None, series)
    assert rep.criteria.bic == pytest.approx(ic.bic, rel=1e-12)
    # the same analysis called directly
    direct = residual_analysis(model, None, series, max_lag=20)
    assert direct.q_statistic == pytest.approx(r.q_statistic, rel=1e-12)
    assert direct.is_independent is None


def test_report_text_html_dict_and_plot_say_there_is_no_input(series):
    rep = validate(AR(2).fit(series), None, series)
    text = str(rep.summary())
    assert "Simulation fit      : not applicable (time series: no input)" in text
    assert "independence of inputs: not applicable (time series: no input)" in text
    assert "not applicable (time series: no input)" in rep._repr_html_()
    assert "no input (time series)" in repr(rep.residuals[0])
    out = rep.to_dict()
    assert json.loads(json.dumps(out, allow_nan=False)) == out
    assert out["time_series"] is True and out["fit_percent"] is None
    tests = out["residual_tests"]
    assert tests["independent"] is None and tests["independence_pvalue"] is None
    assert tests["white"] is rep.residuals[0].is_white
    fig = rep.plot()
    titles = [ax.get_title() for ax in fig.axes]
    assert "Input cross-correlation: not applicable" in titles
    assert "noise model C/(A D) (time series: no input)" in titles
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert "no simulation (time series: no input)" in labels


def test_two_experiments_and_the_input_argument(series):
    model = AR(2).fit(series)
    whole = validate(model, None, series)
    parts = validate(model, None, [series[:500], series[500:]])
    assert parts.experiment_lengths == (500, 700)
    # each experiment predicted from its own start: L more rows are lost
    assert len(parts.residuals[0].residuals) == len(whole.residuals[0].residuals) - 2
    with pytest.raises(ValueError, match="`u` must be None for the time-series model AR"):
        validate(model, np.ones(len(series)), series)
    with pytest.raises(TypeError, match="`y` is required"):
        validate(model, None)


def _free_responses(den, n, N):
    """Solutions of ``den(q) z = 0`` for t >= n, z(0..n-1) the unit vectors (a loop)."""
    Z = np.zeros((N, n))
    for j in range(n):
        Z[j, j] = 1.0
        for t in range(n, N):
            Z[t, j] = -sum(den[k] * Z[t - k, j] for k in range(1, len(den)))
    return Z


@pytest.mark.parametrize("make", [lambda: AR(2), lambda: ARMA(2, 1), lambda: ARMA(1, 2)],
                         ids=["AR(2)", "ARMA(2,1)", "ARMA(1,2)"])
def test_estimated_free_response_is_least_squares_over_the_noise_models_states(make):
    # C/(A D) realized with max(deg A D, deg C) states: for ARMA(1, 2) two, not deg A = 1
    gen = np.random.default_rng(0)
    ys = [lfilter([1, 0.4], [1, -1.2, 0.5], gen.standard_normal(N))
          + 3 * np.exp(-np.arange(N) / 10) for N in (80, 50)]
    model = make().fit(ys)
    p = model.polydata()
    den = np.convolve(p.A[0, 0], p.D[0])
    n = max(len(den), len(p.C[0])) - 1
    want = []
    for y in ys:
        Z = _free_responses(den, n, len(y))
        want.append(Z @ np.linalg.lstsq(Z, y, rcond=None)[0])
    c = compare(model, None, ys)
    np.testing.assert_allclose(c.y_hat, np.concatenate(want), rtol=1e-9, atol=1e-9)
    assert c.fit == pytest.approx(fit_percent(np.concatenate(ys), np.concatenate(want)),
                                  abs=1e-9)
    assert all(len(x0) == n for x0 in c.x0)
