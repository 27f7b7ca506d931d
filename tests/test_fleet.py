"""fit_many: one ARX model per channel equals ARX.fit and validate, channel by channel.

Oracles: ``ARX(...).fit(u[:, i], y[:, i])`` (batch QR least squares and the
recursive filter with its batch start), ``rlsfilt.validation.validate`` (fit
percentages) and ``residual_analysis`` (Ljung-Box and input-independence
tests) on each channel; ``ARX.regressors`` for the regressors. Estimates to
1e-10 relative, p-values to 1e-9 (the same computations in a different
summation order).
"""

import warnings

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

import rlsfilt
from rlsfilt import ARX, ARXBank, NumericalWarning, fit_many
from rlsfilt.models import arx_structure, fleet
from rlsfilt.validation import validate


def _fleet(rng, C=10, N=400, nu=1, noise=0.2):
    """C stable second-order plants with white equation error, different per channel."""
    u = rng.standard_normal((N, C, nu))
    y = np.zeros((N, C))
    for c in range(C):
        r, w = rng.uniform(0.5, 0.85), rng.uniform(0.3, 1.2)
        a = [1.0, -2 * r * np.cos(w), r * r]
        for j in range(nu):
            y[:, c] += lfilter([0.0, 1.0 + j, rng.uniform(-0.5, 0.5)], a, u[:, c, j])
        y[:, c] += lfilter([1.0], a, noise * rng.standard_normal(N))
    return (u[:, :, 0] if nu == 1 else u), y


def _assert_channel_equals_arx(bank, c, model, u, y):
    """Row `c` of `bank` against a fitted ARX and its validation report."""
    # the bank starts its simulation from the measured past, as validate(initial="measured")
    rep = validate(model, u, y, max_lag=bank.max_lag, alpha=bank.alpha, initial="measured")
    res = rep.residuals[0]
    assert_allclose(bank.theta_[c], model.theta_, rtol=1e-10, atol=1e-13)
    assert_allclose(bank.theta_cov_[c], model.theta_cov_, rtol=1e-9, atol=1e-16)
    assert_allclose(bank.std_errors_[c], model.std_errors_, rtol=1e-9)
    assert_allclose(bank.noise_variance_[c], model.noise_variance_, rtol=1e-10)
    assert_allclose(bank.residuals_[:, c], model.residuals_, rtol=1e-9, atol=1e-12)
    assert_allclose(bank.simulation_fit_[c], rep.simulation_fit, rtol=1e-10)
    assert_allclose(bank.prediction_fit_[c], rep.prediction_fit, rtol=1e-10)
    assert_allclose(bank.q_statistic_[c], res.q_statistic, rtol=1e-10)
    assert_allclose(bank.pvalue_white_[c], res.pvalue_white, rtol=1e-9, atol=1e-15)
    assert_allclose(bank.f_statistic_[c], res.f_statistic, rtol=1e-10)
    assert_allclose(bank.pvalue_independent_[c], res.pvalue_independent, rtol=1e-9,
                    atol=1e-15)
    assert bank.df_independent_[c] == res.df_independent
    assert bank.df_white_ == res.df_white
    assert bank.is_white_[c] == res.is_white and bank.is_independent_[c] == res.is_independent


# ----------------------------------------------------------------------
# regressors
# ----------------------------------------------------------------------
@pytest.mark.parametrize("orders, nu", [((2, 2, 1), 1), ((0, 3, 0), 1), ((3, 1, 2), 1),
                                        ((2, [2, 3], [1, 0]), 2)])
def test_regressors_equal_arx_regressors(rng, orders, nu):
    u, y = _fleet(rng, C=4, N=30, nu=nu)
    U = u[:, :, None] if nu == 1 else u
    s = arx_structure(*orders, n_inputs=nu)
    Phi, target = fleet._regressors(U, y, s)
    for c in range(4):
        P, t = ARX(*orders).regressors(U[:, c, 0] if nu == 1 else U[:, c], y[:, c])
        assert_array_equal(Phi[:, c], P)
        assert_array_equal(target[:, c], t)


# ----------------------------------------------------------------------
# fits, channel by channel
# ----------------------------------------------------------------------
def test_least_squares_equals_arx_fit_and_validate(rng):
    u, y = _fleet(rng)
    bank = fit_many(ARX(2, 2, 1), u, y)
    assert isinstance(bank, ARXBank) and len(bank) == 10
    assert bank.theta_.shape == (10, 4) and bank.param_names_ == ["a1", "a2", "b1", "b2"]
    for c in range(10):
        model = ARX(2, 2, 1).fit(u[:, c], y[:, c])
        _assert_channel_equals_arx(bank, c, model, u[:, c], y[:, c])
    assert_allclose(bank.a_, bank.theta_[:, :2])
    assert_allclose(bank.b_, bank.theta_[:, 2:])


@pytest.mark.parametrize("options", [
    {},
    {"lam": 0.98},
    {"lam": "per channel", "R": "per channel"},
    {"forgetting": "directional", "lam": 0.97},
    {"forgetting": "constant_trace", "lam": 0.99},
    {"k0": 0, "P0": 100.0},
    {"k0": 12},
    {"Q": 1e-6},
])
def test_recursive_equals_arx_fit_and_validate(rng, options):
    u, y = _fleet(rng, C=8)
    per = {key: rng.uniform(0.95, 1.0, 8) if key == "lam" else rng.uniform(0.5, 2.0, 8)
           for key, value in options.items() if value == "per channel"}
    opts = {**options, **per}
    bank = fit_many(ARX(2, 2, 1), u, y, "rls", **opts)
    for c in range(8):
        ch = {key: (value[c] if key in per else value) for key, value in opts.items()}
        model = ARX(2, 2, 1).fit(u[:, c], y[:, c], "rls", **ch)
        _assert_channel_equals_arx(bank, c, model, u[:, c], y[:, c])
        assert bank.k0_[c] == model.k0_
        assert_allclose(bank.recursive_residuals_[:, c], model.recursive_residuals_,
                        rtol=1e-9, atol=1e-12)
    assert bank.healthy_.all()


def test_channels_with_different_batch_starts(rng):
    """A PRBS held for several samples needs more rows for the batch start: the
    channels are grouped by k0, each channel as ARX.fit chooses it."""
    u, y = _fleet(rng, C=6, N=300)
    u[:8, 2] = 1.0                         # channel 2: constant input at first
    u[:5, 4] = -1.0
    y[:, 2] = lfilter([0, 1.0, 0.5], [1, -1.2, 0.5], u[:, 2]) + 0.1 * rng.standard_normal(300)
    y[:, 4] = lfilter([0, 1.0, 0.5], [1, -1.2, 0.5], u[:, 4]) + 0.1 * rng.standard_normal(300)
    bank = fit_many(ARX(2, 2, 1), u, y, "rls", lam=0.99)
    k0 = [ARX(2, 2, 1).fit(u[:, c], y[:, c], "rls", lam=0.99).k0_ for c in range(6)]
    assert_array_equal(bank.k0_, k0)
    assert len(set(k0)) > 1
    for c in range(6):
        model = ARX(2, 2, 1).fit(u[:, c], y[:, c], "rls", lam=0.99)
        assert_allclose(bank.theta_[c], model.theta_, rtol=1e-10)


def test_several_inputs_per_channel(rng):
    u, y = _fleet(rng, C=5, nu=2)
    model = ARX(2, [2, 1], [1, 2])
    bank = model.fit_many(u, y)
    assert bank.param_names_ == ["a1", "a2", "b1[u1]", "b2[u1]", "b1[u2]"]
    assert [b.shape for b in bank.b_] == [(5, 2), (5, 1)]
    for c in range(5):
        ref = ARX(2, [2, 1], [1, 2]).fit(u[:, c], y[:, c])
        _assert_channel_equals_arx(bank, c, ref, u[:, c], y[:, c])


@pytest.mark.parametrize("method", ["ls", "rls"])
def test_several_inputs_with_a_channel_dropped(rng, method):
    """The compiled passes read the record itself: with two inputs and a channel that
    cannot be fitted in the middle (the other channels are then not consecutive),
    every fitted channel still equals ARX.fit and validate."""
    u, y = _fleet(rng, C=6, nu=2)
    u[:, 2] = 0.0                           # channel 2: no excitation at all
    model = ARX(3, [2, 1], [1, 0])
    bank = model.fit_many(u, y, method, on_error="nan")
    assert [e is None for e in bank.errors_] == [True, True, False, True, True, True]
    for c in (0, 1, 3, 4, 5):
        ref = ARX(3, [2, 1], [1, 0]).fit(u[:, c], y[:, c], method)
        _assert_channel_equals_arx(bank, c, ref, u[:, c], y[:, c])


def test_arx_fit_many_is_fit_many(rng):
    u, y = _fleet(rng, C=4)
    a = ARX(2, 2, 1).fit_many(u, y, "rls", lam=0.99, residual_tests=False)
    b = fit_many(ARX(2, 2, 1), u, y, "rls", lam=0.99, residual_tests=False)
    pd.testing.assert_frame_equal(a.to_dataframe(), b.to_dataframe(), check_exact=True)
    assert "q_statistic" not in a.to_dataframe() and a.pvalue_white_ is None


# ----------------------------------------------------------------------
# a channel's numbers do not depend on the others (what makes Dask exact)
# ----------------------------------------------------------------------
@pytest.mark.parametrize("method", ["ls", "rls"])
def test_results_do_not_depend_on_the_chunking(rng, monkeypatch, method):
    u, y = _fleet(rng, C=13, N=250)
    whole = fit_many(ARX(2, 2, 1), u, y, method).to_dataframe()
    part = fit_many(ARX(2, 2, 1), u[:, 3:8], y[:, 3:8], method,
                    channels=range(3, 8)).to_dataframe()
    pd.testing.assert_frame_equal(part, whole.iloc[3:8], check_exact=True)
    single = fit_many(ARX(2, 2, 1), u[:, [7]], y[:, [7]], method, channels=[7]).to_dataframe()
    pd.testing.assert_frame_equal(single, whole.iloc[[7]], check_exact=True)
    monkeypatch.setattr(fleet, "_CHUNK_BYTES", 1)           # one channel per chunk
    monkeypatch.setattr(fleet, "_TEST_BYTES", 1)
    pd.testing.assert_frame_equal(fit_many(ARX(2, 2, 1), u, y, method).to_dataframe(), whole,
                                  check_exact=True)


# ----------------------------------------------------------------------
# the result object
# ----------------------------------------------------------------------
def test_model_returns_an_ordinary_fitted_arx(rng):
    u, y = _fleet(rng, C=5)
    y = pd.DataFrame(y, columns=[f"loop{c}" for c in range(5)])
    bank = fit_many(ARX(2, 2, 1), u, y, "rls", lam=np.linspace(0.96, 1.0, 5))
    assert bank.channels_ == ["loop0", "loop1", "loop2", "loop3", "loop4"]
    m = bank.model(3)
    assert type(m) is ARX and m.method_ == "rls" and m.filter_.lam == 0.99
    assert_allclose(m.theta_, bank.theta_[3], rtol=1e-10)
    assert m.theta_history_.shape == (len(y) - 2, 4)
    assert_allclose(bank.model("loop3").theta_, m.theta_, rtol=0)
    directional = fit_many(ARX(2, 2, 1), u, y, "rls", lam=0.97, forgetting="directional",
                           k0=0, P0=np.linspace(10.0, 50.0, 5), residual_tests=False)
    m1 = directional.model(1)
    assert m1.filter_.forgetting == "directional" and m1.k0_ == 0
    assert_allclose(m1.theta_, directional.theta_[1], rtol=1e-10)
    m1.filter_.reset()                      # back to the channel's own prior
    assert_allclose(m1.filter_.P, 20.0 * np.eye(4))
    assert_allclose(bank.model(-2).theta_, m.theta_, rtol=0)
    with pytest.raises(IndexError, match=r"`i` must be a channel position in \[-5, 5\)"):
        bank.model(5)
    with pytest.raises(KeyError, match="one of the channel labels; got 'loop9'"):
        bank.model("loop9")


def test_summary_is_one_row_per_channel(rng):
    u, y = _fleet(rng, C=6)
    bank = fit_many(ARX(2, 2, 1), u, y, channels=list("abcdef"))
    table = bank.to_dataframe()
    assert list(table.index) == list("abcdef") and table.index.name == "channel"
    assert list(table.columns) == [
        "n_samples", "a1", "a2", "b1", "b2", "se_a1", "se_a2", "se_b1", "se_b2",
        "noise_variance", "simulation_fit", "prediction_fit", "q_statistic", "pvalue_white",
        "f_statistic", "pvalue_independent", "is_white", "is_independent"]
    assert_array_equal(table["b1"], bank.theta_[:, 2])
    assert_array_equal(table["se_a2"], bank.std_errors_[:, 1])
    worst = table.sort_values("simulation_fit").index[0]
    assert worst == list("abcdef")[int(np.argmin(bank.simulation_fit_))]
    assert "ARXBank: 6 channels of ARX(na=2, nb=2, nk=1)" in repr(bank)
    assert "<table" in bank._repr_html_()
    rls = fit_many(ARX(2, 2, 1), u, y, "rls").to_dataframe()
    assert list(rls.columns[-2:]) == ["k0", "healthy"]


def test_progress_bar(rng, capsys):
    u, y = _fleet(rng, C=3)
    fit_many(ARX(2, 2, 1), u, y, progress=True, residual_tests=False)
    assert "3/3" in capsys.readouterr().err


def test_unhealthy_channels_are_named_in_one_warning(rng):
    u, y = _fleet(rng, C=4, N=600)
    u[300:, 1] = 0.0                       # channel 1: no excitation for 300 samples
    with pytest.warns(NumericalWarning, match=r"failed the health check of RLSBank: \[1\]") as rec:
        bank = fit_many(ARX(2, 2, 1), u, y, "rls", lam=0.9, residual_tests=False)
    assert rec[0].filename == __file__      # the caller's line
    assert_array_equal(bank.healthy_, [True, False, True, True])
    with pytest.warns(NumericalWarning) as rec:
        ARX(2, 2, 1).fit_many(u, y, "rls", lam=0.9, residual_tests=False)
    assert rec[0].filename == __file__
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fit_many(ARX(2, 2, 1), u, y, "rls", lam=0.9, forgetting="directional",
                 residual_tests=False)


# ----------------------------------------------------------------------
# bad channels and bad arguments
# ----------------------------------------------------------------------
def test_bad_channels_raise_or_give_nan(rng):
    u, y = _fleet(rng, C=5)
    y[17, 1] = np.nan                       # channel 1: a missing sample
    u[:, 3] = 0.0                           # channel 3: no excitation at all
    with pytest.raises(ValueError, match=r"`y` must be finite; got nan at index \(17, 1\) "
                                         r"\(channel 1\)"):
        fit_many(ARX(2, 2, 1), u, y)
    y1 = y.copy()
    y1[17, 1] = 0.0
    with pytest.raises(ValueError, match=r"channel 3: the regressor matrix has rank"):
        fit_many(ARX(2, 2, 1), u, y1)
    for method in ("ls", "rls"):
        bank = fit_many(ARX(2, 2, 1), u, y, method, on_error="nan")
        assert [e is None for e in bank.errors_] == [True, False, True, False, True]
        table = bank.to_dataframe()
        assert table.loc[[1, 3], ["a1", "simulation_fit", "pvalue_white"]].isna().all().all()
        assert table["error"][3].startswith("the regressor matrix has rank")
        assert np.isnan(bank.residuals_[:, 1]).all()
        ref = fit_many(ARX(2, 2, 1), u[:, [0, 2, 4]], y[:, [0, 2, 4]], method)
        assert_array_equal(bank.theta_[[0, 2, 4]], ref.theta_)
        with pytest.raises(ValueError, match="channel 1 was not fitted"):
            bank.model(1)


def test_argument_errors(rng):
    u, y = _fleet(rng, C=4)
    model = ARX(2, 2, 1)
    with pytest.raises(ValueError, match=r"`u` must have one column per channel of `y` \(4\); "
                                         r"got 3"):
        fit_many(model, u[:, :3], y)
    with pytest.raises(ValueError, match="`u` and `y` must have the same length"):
        fit_many(model, u[:-1], y)
    with pytest.raises(ValueError, match=r"`y` must have shape \(N, C\)"):
        fit_many(model, u[:, 0], y[:, 0])
    with pytest.raises(ValueError, match=r"`lam` must be a scalar or have shape \(4,\)"):
        fit_many(model, u, y, "rls", lam=[0.9, 0.9])
    with pytest.raises(TypeError, match="`lam` only applies to method='rls'"):
        fit_many(model, u, y, lam=0.9)
    with pytest.raises(TypeError, match="`gate` is not an option of fit_many or RLSBank"):
        fit_many(model, u, y, "rls", gate=3.0)
    with pytest.raises(ValueError, match="`forgetting_params` key 'alpha' is not supported "
                                         r"by RLSBank \(mode 'exponential'\); supported: "
                                         "'spread_max', 'trace_max'"):
        fit_many(model, u, y, "rls", lam=0.99, forgetting_params={"alpha": 10.0})
    with pytest.raises(ValueError, match="`method` must be 'ls', 'rls', 'nlms' or 'lms'"):
        fit_many(model, u, y, "ml")
    with pytest.raises(ValueError, match="`on_error` must be 'raise' or 'nan'"):
        fit_many(model, u, y, on_error="skip")
    with pytest.raises(ValueError, match=r"`channels` must have one label per channel \(4\)"):
        fit_many(model, u, y, channels=[1, 2])
    with pytest.raises(ValueError, match="at least max_lag \\+ n_params"):
        fit_many(model, u[:5], y[:5])
    with pytest.raises(ValueError, match="`max_lag` must be small against"):
        fit_many(model, u[:40], y[:40], max_lag=25)
    with pytest.raises(ValueError, match="`P0` only applies to a prior start"):
        fit_many(model, u, y, "rls", k0=10, P0=10.0)


def test_no_caller_array_is_mutated(rng):
    u, y = _fleet(rng, C=4)
    lam = np.full(4, 0.99)
    saved = u.copy(), y.copy(), lam.copy()
    bank = fit_many(ARX(2, 2, 1), u, y, "rls", lam=lam)
    bank.model(1)
    for a, b in zip((u, y, lam), saved):
        assert_array_equal(a, b)
    u[5, 2] += 1.0                          # the bank refers to the record: it notices
    with pytest.raises(ValueError, match="the record of channel 2 was modified after fit_many"):
        bank.model(2)
    assert_allclose(bank.model(3).theta_, bank.theta_[3], rtol=1e-10)


def test_exports():
    assert rlsfilt.fit_many is fit_many and "ARXBank" in rlsfilt.__all__
    assert rlsfilt.models.fit_many is fit_many


# ----------------------------------------------------------------------
# fleets fit exactly the model given (#27)
# ----------------------------------------------------------------------
@pytest.mark.parametrize("offset", [True, "mean"])
@pytest.mark.parametrize("method", ["ls", "rls"])
def test_offset_models_equal_arx_fit_and_validate(rng, offset, method):
    """fit_many(ARX(..., offset=...)) reported the numbers of offset=False while
    model(i) was the offset model (fit 36 % instead of 70 % in the audit)."""
    u, y = _fleet(rng, C=4)
    u, y = u + 1.0, y + 3.0 + 0.5 * np.arange(4)          # an operating point per channel
    bank = fit_many(ARX(2, 2, 1, offset=offset), u, y, method)
    plain = fit_many(ARX(2, 2, 1), u, y, method)
    assert (bank.simulation_fit_ > plain.simulation_fit_ + 10).all()
    for c in range(4):
        model = ARX(2, 2, 1, offset=offset).fit(u[:, c], y[:, c], method)
        _assert_channel_equals_arx(bank, c, model, u[:, c], y[:, c])
        assert_allclose(bank.model(c).theta_, bank.theta_[c], rtol=1e-10)
        if offset is True:
            assert bank.intercept_[c] == bank.theta_[c, -1]
            assert_allclose(bank.intercept_[c], model.intercept_, rtol=1e-10)
        else:
            assert_allclose(bank.output_offset_[c], model.output_offset_[0], rtol=1e-12)
    names = ["a1", "a2", "b1", "b2"] + (["c"] if offset is True else [])
    assert bank.param_names_ == names
    assert list(bank.to_dataframe().columns[1:len(names) + 1]) == names
    assert "offset=" in repr(bank)


@pytest.mark.parametrize("cls, args", [("ARMAX", (2, 2, 1)), ("OE", (2, 2)), ("AR", (2,))])
def test_other_model_classes_are_refused(rng, cls, args):
    u, y = _fleet(rng, C=3, N=100)
    with pytest.raises(TypeError, match=rf"`model` must be an ARX .*; got {cls}"):
        fit_many(getattr(rlsfilt, cls)(*args), u, y)


def test_pandas_inputs_are_paired_with_outputs_by_label(rng):
    u, y = _fleet(rng, C=4)
    labels = ["d", "a", "c", "b"]
    U, Y = pd.DataFrame(u, columns=labels), pd.DataFrame(y, columns=labels)
    expected = fit_many(ARX(2, 2, 1), u, y, channels=labels)
    got = fit_many(ARX(2, 2, 1), U[["a", "b", "c", "d"]], Y)        # u in another order
    assert got.channels_ == labels
    assert_array_equal(got.theta_, expected.theta_)
    with pytest.raises(ValueError, match=r"`u` lacks \['d'\], and has \['e'\] that `y` lacks"):
        fit_many(ARX(2, 2, 1), U.rename(columns={"d": "e"}), Y)
    with pytest.raises(ValueError, match="`u` and `y` must have the same index"):
        fit_many(ARX(2, 2, 1), U.set_index(U.index + 1), Y)


def test_max_lag_auto_on_short_channels(rng):
    """Issue #28, 3 for fleets: 101 samples per channel failed with the old default of 25
    lags (too few rows for the independence test). max_lag="auto" (the default, as in
    validate) halves the lag until the tests are defined; every channel is then the ARX and
    validate report at that lag, and on a long record "auto" is 25."""
    import inspect

    from rlsfilt.exceptions import InsufficientDataError

    assert inspect.signature(fit_many).parameters["max_lag"].default == "auto"
    u, y = _fleet(rng, C=3, N=101)
    model = ARX(2, 2, 1)
    with pytest.raises(InsufficientDataError, match="`max_lag` = 25 leaves too few rows"):
        fit_many(model, u, y, max_lag=25)
    bank = fit_many(model, u, y)
    assert bank.max_lag == 12                     # min(25, 99 // 4) = 24, halved once
    fixed = fit_many(model, u, y, max_lag=12)
    assert_allclose(bank.q_statistic_, fixed.q_statistic_, rtol=0, atol=0)
    for c in range(3):
        _assert_channel_equals_arx(bank, c, ARX(2, 2, 1).fit(u[:, c], y[:, c]), u[:, c],
                                   y[:, c])
    u, y = _fleet(rng, C=2, N=400)
    assert fit_many(model, u, y).max_lag == 25


@pytest.mark.parametrize("nu", [1, 2])
@pytest.mark.parametrize("method", ["ls", "rls"])
def test_mean_offset_removes_the_means_arx_fit_removes(method, nu):
    """offset="mean": each channel's means are ARX.fit's to the bit (a mean over axis 0
    of the fleet's (N, C) record adds its rows in turn, the channel on its own is summed
    pairwise: means 1 ulp apart, and a batch start of a few rows turned that into 2e-12
    of the recursive estimate)."""
    rng = np.random.default_rng(7)
    u, y = _fleet(rng, C=6, N=200, nu=nu)
    u, y = 1.0 + 3.0 * u, y + 3.0 + rng.uniform(0, 1, 6)
    kw = {"nb": [2] * nu, "nk": list(range(1, nu + 1))} if nu > 1 else {"nb": 2, "nk": 1}
    bank = fit_many(ARX(2, offset="mean", **kw), u, y, method, residual_tests=False)
    for c in range(6):
        model = ARX(2, offset="mean", **kw).fit(u[:, c], y[:, c], method)
        assert_array_equal(bank.output_offset_[c], model.output_offset_[0])
        assert_array_equal(bank.input_offset_[c], model.input_offset_)
        scale = np.max(np.abs(model.theta_))
        assert_allclose(bank.theta_[c], model.theta_, rtol=0, atol=1e-14 * scale)


@settings(max_examples=20, deadline=None)
@given(na=st.integers(0, 2), nb=st.lists(st.integers(1, 2), min_size=1, max_size=2),
       nk0=st.integers(0, 2), offset=st.sampled_from([False, True, "mean"]),
       route=st.sampled_from([("ls", {}), ("rls", {}), ("rls", {"lam": 0.98}),
                              ("rls", {"lam": 0.97, "forgetting": "directional"}),
                              ("rls", {"k0": 0, "P0": 100.0, "R": 2.0})]),
       exponent=st.sampled_from([0, -500, 500]), seed=st.integers(0, 2 ** 16))
def test_every_channel_is_its_own_arx_fit(na, nb, nk0, offset, route, exponent, seed):
    """Cross-route parity: orders with nk = 0 and inputs of different delays, the three
    offsets, the batch and recursive methods, records around 2^+-500: each channel of a
    fleet of 3 is ARX.fit on its record (estimates and covariances to a few ulp of the
    recursion, the removed means to the bit)."""
    method, options = route
    nu = len(nb)
    nk = [nk0 + j for j in range(nu)]
    rng = np.random.default_rng(seed)
    u, y = _fleet(rng, C=3, N=120, nu=nu)
    u, y = np.ldexp(u + 0.5, exponent), np.ldexp(y + 2.0, exponent)
    if options.get("P0") is not None and exponent:
        return                      # a prior in the signals' units: only for unit-size data
    kw = {"nb": nb if nu > 1 else nb[0], "nk": nk if nu > 1 else nk[0], "offset": offset}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bank = fit_many(ARX(na, **kw), u, y, method, residual_tests=False, **options)
        for c in range(3):
            model = ARX(na, **kw).fit(u[:, c], y[:, c], method, form="covariance", **options) \
                if method == "rls" else ARX(na, **kw).fit(u[:, c], y[:, c], method)
            scale = np.max(np.abs(model.theta_))
            assert_allclose(bank.theta_[c], model.theta_, rtol=0, atol=1e-12 * scale)
            assert_allclose(bank.theta_cov_[c], model.theta_cov_, rtol=1e-9,
                            atol=1e-12 * np.max(np.abs(model.theta_cov_)))
            if offset == "mean":
                assert_array_equal(bank.output_offset_[c], model.output_offset_[0])
                assert_array_equal(bank.input_offset_[c], model.input_offset_)


def test_health_verdict_is_arx_fits_on_ill_conditioned_regressors():
    """ARX.fit's health check allows P the condition number the regressors give it
    (cond_max = max(1e12, 1e4 cond(Phi)^2)); the bank's is 1e12 for every channel, so a
    fleet flagged (healthy_ False, a NumericalWarning) a channel whose own ARX.fit
    passes, with an estimate as close to batch least squares as ARX.fit's."""
    rng = np.random.default_rng(7)        # (channel 0 failed the bank's check)
    N, nb = 3000, 8
    smooth = [1.0], [1.0, -0.9999]
    u = np.column_stack([lfilter(*smooth, lfilter(*smooth, rng.standard_normal(N)))
                         for _ in range(2)])
    y = np.column_stack([lfilter([0, 1, .5], [1, -1.5, .7], u[:, c])
                         + 1e-8 * rng.standard_normal(N) for c in range(2)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)   # no health warning
        bank = fit_many(ARX(2, nb, 1), u, y, "rls", residual_tests=False)
    assert bank.healthy_.all()
    for c in range(2):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            model = ARX(2, nb, 1).fit(u[:, c], y[:, c], "rls", form="covariance")
        assert not [w for w in caught if "health" in str(w.message)]
        ls = ARX(2, nb, 1).fit(u[:, c], y[:, c])
        scale = np.max(np.abs(ls.theta_))
        assert_allclose(bank.theta_[c], ls.theta_, rtol=0, atol=1e-9 * scale)
        assert_allclose(bank.theta_[c], model.theta_, rtol=0, atol=1e-9 * scale)
    # a channel that fails with the data's own cond_max still fails (a user cond_max holds)
    with pytest.warns(NumericalWarning, match="health check"):
        tight = fit_many(ARX(2, nb, 1), u, y, "rls", residual_tests=False, cond_max=1e6)
    assert not tight.healthy_.any()
