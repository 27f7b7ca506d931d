"""Residual analysis: statsmodels oracles, the level of both tests over many
seeded experiments, and detection of underfitted structures."""

import numpy as np
import pytest
import statsmodels.api as sm
from scipy.signal import lfilter
from scipy.stats import binom
from statsmodels.stats.diagnostic import acorr_ljungbox
from statsmodels.tsa.stattools import acf

from rlsfilt import ARX
from rlsfilt.validation import ResidualAnalysis, residual_analysis

A_TRUE, B_TRUE = [1, -1.5, 0.7], [0, 1.0, 0.5]


def _record(rng, n=1000, noise=0.1, colored_input=False):
    u = rng.standard_normal(n)
    if colored_input:
        u = lfilter([1.0], [1.0, -0.8], u)
    e = noise * rng.standard_normal(n)
    y = lfilter(B_TRUE, A_TRUE, u) + lfilter([1.0], A_TRUE, e)
    return u, y


def test_ljung_box_and_acf_match_statsmodels(rng):
    u, y = _record(rng)
    model = ARX(2, 2).fit(u, y)
    r = residual_analysis(model, u, y, max_lag=20)
    np.testing.assert_allclose(r.residuals, model.residuals_, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(r.autocorrelation, acf(r.residuals, nlags=20, fft=False),
                               rtol=1e-10, atol=1e-13)
    for model_df in (0, 2):
        r = residual_analysis(model, u, y, max_lag=20, model_df=model_df)
        lb = acorr_ljungbox(r.residuals, lags=[20], model_df=model_df)
        assert r.q_statistic == pytest.approx(lb["lb_stat"].iloc[0], rel=1e-10)
        assert r.pvalue_white == pytest.approx(lb["lb_pvalue"].iloc[0], rel=1e-8)
        assert r.df_white == 20 - model_df


def test_cross_correlation_matches_definition(rng):
    u, y = _record(rng, n=600, colored_input=True)
    model = ARX(2, 2).fit(u, y)
    r = residual_analysis(model, u, y, max_lag=8)
    e = model.residuals_ - model.residuals_.mean()
    uc = u - u.mean()
    t = np.arange(2, 600)                       # times of the residuals
    for i, tau in enumerate(range(-8, 9)):
        ok = (t - tau >= 0) & (t - tau < 600)
        expected = np.sum(e[ok] * uc[t[ok] - tau]) / len(e)
        expected /= np.sqrt(np.mean(e ** 2) * np.mean(uc ** 2))
        assert r.cross_correlation[0, i] == pytest.approx(expected, rel=1e-10, abs=1e-14)
    # the regressors' own lags (tau = nk .. nk + nb - 1) are zero by least squares
    assert np.max(np.abs(r.cross_correlation[0, [9, 10]])) < 0.02
    assert r.autocorrelation_band == pytest.approx(2.5758293 / np.sqrt(598), rel=1e-6)


def test_independence_f_test_matches_statsmodels(rng):
    """The joint test is the F test of lagged inputs in an auxiliary regression."""
    u, y = _record(rng, n=500, colored_input=True)
    model = ARX(2, 2).fit(u, y)
    M = 5
    r = residual_analysis(model, u, y, max_lag=M)
    Phi, _ = model.regressors(u, y)
    t = np.arange(2, 500)
    rows = (t - M >= 0) & (t + M <= 499)
    tr = t[rows]
    X0 = np.column_stack([np.ones(rows.sum()), Phi[rows]])
    lags = [tau for tau in range(-M, M + 1) if tau not in (1, 2)]   # 1, 2 are regressors
    X1 = np.column_stack([X0] + [u[tr - tau] for tau in lags])
    e = model.residuals_[rows]
    full, restricted = sm.OLS(e, X1).fit(), sm.OLS(e, X0).fit()
    F, p, df = full.compare_f_test(restricted)
    assert r.df_independent == df == 2 * M + 1 - 2
    assert r.f_statistic == pytest.approx(F, rel=1e-8)
    assert r.pvalue_independent == pytest.approx(p, rel=1e-6)


@pytest.mark.parametrize("colored_input", [False, True])
def test_tests_hold_their_level(colored_input):
    """Right structure, white noise: each test rejects about alpha of 200 experiments."""
    n_exp, alpha = 200, 0.05
    rej_white = rej_indep = 0
    for seed in range(n_exp):
        u, y = _record(np.random.default_rng(seed), n=500, noise=0.3,
                       colored_input=colored_input)
        r = residual_analysis(ARX(2, 2).fit(u, y), u, y, max_lag=10, alpha=alpha)
        rej_white += not r.is_white
        rej_indep += not r.is_independent
    lo, hi = binom.ppf(0.0005, n_exp, alpha), binom.ppf(0.9995, n_exp, alpha)
    # the plain chi2(M) Ljung-Box is at most slightly conservative for a fitted
    # AR part (Box & Pierce 1970)
    assert lo <= rej_white <= hi
    assert lo <= rej_indep <= hi


def test_underfitting_is_flagged(rng):
    u, y = _record(rng, n=1000)
    assert residual_analysis(ARX(2, 2).fit(u, y), u, y).is_white
    too_few_poles = residual_analysis(ARX(1, 2).fit(u, y), u, y)
    assert not too_few_poles.is_white
    assert too_few_poles.pvalue_white < 1e-6
    too_few_zeros = residual_analysis(ARX(2, 1).fit(u, y), u, y)
    assert not too_few_zeros.is_independent
    wrong_delay = residual_analysis(ARX(2, 2, nk=2).fit(u, y), u, y)
    assert not wrong_delay.is_independent and wrong_delay.pvalue_independent < 1e-6


def test_validation_data_and_several_inputs(rng):
    n = 1500
    U = rng.standard_normal((n, 2))
    y = lfilter([0, 1.0], [1, -0.7], U[:, 0]) + lfilter([0, 0, 0.5], [1, -0.7], U[:, 1])
    y += lfilter([1.0], [1, -0.7], 0.1 * rng.standard_normal(n))
    model = ARX(1, [1, 2], nk=[1, 1]).fit(U[:1000], y[:1000])
    r = residual_analysis(model, U[1000:], y[1000:], max_lag=10)
    assert r.cross_correlation.shape == (2, 21)
    assert r.cross_correlation_band.shape == (2,)
    assert r.is_white and r.is_independent
    missing = residual_analysis(ARX(1, [1, 1], nk=[1, 1]).fit(U, y), U, y, max_lag=10)
    assert not missing.is_independent
    assert np.argmax(np.abs(missing.cross_correlation[1])) == 10 + 2   # lag tau = 2


def test_several_outputs_pick_one(rng):
    u = rng.standard_normal(800)
    Y = np.column_stack([lfilter([0, 1.0], [1, -0.5], u), lfilter([0, 0.3], [1, -0.2], u)])
    Y += 0.1 * rng.standard_normal((800, 2))
    model = ARX(1, 1).fit(u, Y)
    r1 = residual_analysis(model, u, Y, output=1)
    np.testing.assert_allclose(r1.residuals, model.residuals_[:, 1], rtol=1e-12, atol=1e-15)
    assert r1.output == 1


def test_plot_and_text(rng):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    u, y = _record(rng, n=400)
    r = residual_analysis(ARX(1, 1).fit(u, y), u, y)
    assert isinstance(r, ResidualAnalysis)
    fig = r.plot()
    assert len(fig.axes) == 2
    assert "NOT white" in fig.axes[0].get_title()
    assert "NOT white" in str(r.summary())
    assert "white=False" in repr(r)
    plt.close("all")


def test_residual_analysis_errors(rng):
    u, y = _record(rng, n=100)
    model = ARX(2, 2).fit(u, y)
    with pytest.raises(ValueError, match=r"`max_lag` must be small against the 98 residuals"):
        residual_analysis(model, u, y, max_lag=60)
    with pytest.raises(ValueError, match=r"`alpha` must be in \(0, 1\); got 0.0"):
        residual_analysis(model, u, y, alpha=0.0)
    with pytest.raises(ValueError, match=r"`output` must be < 1 \(the number of outputs\); got 1"):
        residual_analysis(model, u, y, output=1)
    with pytest.raises(ValueError, match="`max_lag` must exceed `model_df` = 10"):
        residual_analysis(model, u, y, max_lag=10, model_df=10)
    with pytest.raises(TypeError, match="`max_lag` must be an integer; got 2.5"):
        residual_analysis(model, u, y, max_lag=2.5)


@pytest.mark.parametrize("su, sy", [(1e-8, 1e6), (1e-12, 1e10)])
def test_tests_do_not_depend_on_units(rng, su, sy):
    """Rescaled signals give the same statistics (was: lagged inputs miscounted)."""
    u, y = _record(rng, n=1000)
    ref = residual_analysis(ARX(2, 2).fit(u, y), u, y)
    scaled = residual_analysis(ARX(2, 2).fit(su * u, sy * y), su * u, sy * y)
    assert scaled.df_independent == ref.df_independent == 2 * 25 + 1 - 2
    assert scaled.pvalue_independent == pytest.approx(ref.pvalue_independent, rel=1e-9)
    assert scaled.pvalue_white == pytest.approx(ref.pvalue_white, rel=1e-9)
    np.testing.assert_allclose(scaled.cross_correlation, ref.cross_correlation, atol=1e-10)


def test_max_lag_auto_is_the_default_and_works_on_a_short_record(rng):
    """Issue #28, 3: a short validation record (MATLAB's hair-dryer example validates on 101
    samples) leaves too few rows for 25 lags. ``max_lag="auto"`` (the default, as in
    `validate` and the CLI) starts at ``min(25, n // 4)`` and halves the lag until the tests
    are defined; the result is that of the integer it chose, checked against statsmodels."""
    import inspect

    from rlsfilt import validate
    from rlsfilt.exceptions import InsufficientDataError

    assert inspect.signature(residual_analysis).parameters["max_lag"].default == "auto"
    u, y = _record(rng, n=1101)
    u2 = np.column_stack([u, rng.standard_normal(1101)])
    model = ARX(2, [2, 2], [1, 1]).fit(u2[:1000], y[:1000])
    uv, yv = u2[1000:], y[1000:]                      # 101 validation samples, 99 residuals
    with pytest.raises(InsufficientDataError, match="`max_lag` = 25 leaves too few rows"):
        residual_analysis(model, uv, yv, max_lag=25)
    with pytest.raises(InsufficientDataError, match="`max_lag` = 24 leaves too few rows"):
        residual_analysis(model, uv, yv, max_lag=24)   # min(25, 99 // 4): too many lags
    r = residual_analysis(model, uv, yv)
    assert r.max_lag == 12                             # 24 halved once
    fixed = residual_analysis(model, uv, yv, max_lag=12)
    assert r.q_statistic == fixed.q_statistic and r.f_statistic == fixed.f_statistic
    lb = acorr_ljungbox(r.residuals, lags=[12])
    assert r.q_statistic == pytest.approx(lb["lb_stat"].iloc[0], rel=1e-10)
    assert validate(model, uv, yv).residuals[0].max_lag == 12
    # a long record: "auto" is MATLAB resid's 25 lags, the same numbers as max_lag=25
    long = residual_analysis(model, u2[:1000], y[:1000])
    assert long.max_lag == 25
    assert long.q_statistic == residual_analysis(model, u2[:1000], y[:1000],
                                                 max_lag=25).q_statistic
    # the Ljung-Box test keeps a degree of freedom: the lag is not halved to model_df
    with pytest.raises(InsufficientDataError):
        residual_analysis(model, uv, yv, model_df=13)  # 24 fails, 12 would leave none
    assert residual_analysis(model, uv, yv, model_df=11).max_lag == 12
    with pytest.raises(TypeError, match="`max_lag` must be an integer"):
        residual_analysis(model, uv, yv, max_lag="twelve")
