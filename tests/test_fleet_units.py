"""fit_many in the units of each channel (#27): scale-invariant over the double range as
ARX.fit is, the same bits at ordinary scales.

Oracles: ``ARX(...).fit`` of each channel (which runs in power-of-two units,
``rlsfilt.models._units``), and the fit of the same record with each channel multiplied
by powers of two, whose results are those powers of two times the unscaled ones, bit for
bit (dividing by a power of two is exact, and every operation of the fit is
homogeneous).
"""

import warnings

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt import ARX, NumericalWarning, fit_many
from rlsfilt.models.fleet import _summary_long

C, N = 4, 400
# powers of two per channel: (input, output)
EXPONENTS = [(0, 0), (-531, 0), (0, 531), (40, -520)]


def _record(rng, offset=0.0):
    u = rng.standard_normal((N, C))
    y = np.column_stack([lfilter([0, 1.0, 0.5], [1, -1.2, 0.5], u[:, c])
                         + 0.05 * rng.standard_normal(N) + offset for c in range(C)])
    return u, y


def _scaled(u, y, exps):
    eu, ey = np.array(exps).T
    return np.ldexp(u, eu[None, :]), np.ldexp(y, ey[None, :])


FIELDS = ("theta_", "std_errors_", "noise_variance_", "residuals_", "simulation_fit_",
          "prediction_fit_", "q_statistic_", "pvalue_white_", "f_statistic_",
          "pvalue_independent_")


def _unit_map(bank, exps, field, offset):
    """A field of the bank of the unscaled record -> the scaled record's, exactly."""
    eu, ey = (np.array(e) for e in zip(*exps))
    value = getattr(bank, field)
    na, nb = bank.structure_.na, bank.n_params_ - bank.structure_.na - (offset is True)
    if field in ("theta_", "std_errors_"):
        g = np.concatenate([np.zeros((C, na), int), np.repeat((ey - eu)[:, None], nb, 1)]
                           + ([ey[:, None]] if offset is True else []), axis=1)
        return np.ldexp(value, g)
    if field == "noise_variance_":
        return np.ldexp(value, 2 * ey)
    if field in ("residuals_", "recursive_residuals_"):
        return np.ldexp(value, ey[None, :])
    return value                      # fits, statistics and p-values: no units


@pytest.mark.parametrize("method, options", [("ls", {}), ("rls", {}),
                                             ("rls", {"lam": 0.98}),
                                             ("rls", {"forgetting": "directional",
                                                      "lam": 0.97})])
@pytest.mark.parametrize("offset", [False, True, "mean"])
def test_channels_scaled_by_powers_of_two_give_the_same_bits(rng, method, options, offset):
    """Each channel times 2^e_u, 2^e_y (up to 2^+-531, about 1e+-160): every number of the
    fleet is the unscaled one times its power of two, bit for bit."""
    u, y = _record(rng, offset=3.0 if offset else 0.0)
    base = fit_many(ARX(2, 2, offset=offset), u, y, method, **options)
    bank = fit_many(ARX(2, 2, offset=offset), *_scaled(u, y, EXPONENTS), method, **options)
    fields = FIELDS + (("recursive_residuals_",) if method == "rls" else ())
    for field in fields:
        with np.errstate(over="ignore"):     # (a variance around 1e320: inf, as the fleet's)
            expected = _unit_map(base, EXPONENTS, field, offset)
        assert_array_equal(getattr(bank, field), expected, err_msg=field)
    if offset is True:
        assert_array_equal(bank.intercept_, bank.theta_[:, -1])
    if offset == "mean":
        eu, ey = (np.array(e) for e in zip(*EXPONENTS))
        assert_array_equal(bank.input_offset_[:, 0], np.ldexp(base.input_offset_[:, 0], eu))
        assert_array_equal(bank.output_offset_, np.ldexp(base.output_offset_, ey))
    assert_array_equal(bank.healthy_, base.healthy_)


@pytest.mark.parametrize("method", ["ls", "rls"])
def test_channels_in_their_own_units_equal_arx_fit(rng, method):
    """Channels around 1e-160, 1e160 and in mixed units: each equals ARX.fit of its record
    (which the catalogue of test_audit.py checks against the unscaled fit)."""
    u, y = _scaled(*_record(rng), EXPONENTS)
    bank = fit_many(ARX(2, 2), u, y, method, residual_tests=False)
    for c in range(C):
        model = ARX(2, 2).fit(u[:, c], y[:, c], method)
        assert_allclose(bank.theta_[c], model.theta_, rtol=1e-12)
        # (ARX's from theta_cov_, whose variances over- or underflow: see below)
        finite = np.isfinite(model.std_errors_) & (model.std_errors_ > 0)
        assert_allclose(bank.std_errors_[c, finite], model.std_errors_[finite], rtol=1e-9)
        assert_allclose(bank.noise_variance_[c], model.noise_variance_, rtol=1e-9)
        assert_allclose(bank.residuals_[:, c], model.residuals_, rtol=1e-8,
                        atol=1e-10 * np.abs(model.residuals_).max())
    # around 1e160 the b coefficients' standard errors are about 1e157, around 1e-160
    # 1e-171: representable (their variances, 1e314 and 1e-342, are not: inf and 0 in
    # ARX.theta_cov_, from which ARX.std_errors_ is inf or 0)
    assert np.isfinite(bank.std_errors_).all() and (bank.std_errors_ > 1e-200).all()
    se = np.sqrt(np.diagonal(fit_many(ARX(2, 2), *_record(np.random.default_rng(7)), method,
                                      residual_tests=False).theta_cov_, axis1=1, axis2=2))
    assert np.isfinite(se).all()
    assert np.isinf(bank.theta_cov_[2, 2, 2]) and np.isinf(bank.noise_variance_[2])


def test_coefficients_beyond_the_largest_double_name_the_channel(rng):
    """``u`` around 1e-160 and ``y`` around 1e160: b coefficients of about 1e320, the error
    ARX.fit gives, for that channel (or NaN and ``errors_``)."""
    u, y = _scaled(*_record(rng), [(0, 0), (-531, 531), (0, 0), (0, 0)])
    with pytest.raises(ValueError, match=r"channel 1: `u` and `y` must have units") as info:
        fit_many(ARX(2, 2), u, y)
    with pytest.raises(ValueError) as single:
        ARX(2, 2).fit(u[:, 1], y[:, 1])
    assert str(single.value) in str(info.value)
    bank = fit_many(ARX(2, 2), u, y, on_error="nan")
    assert np.isnan(bank.theta_[1]).all() and np.isnan(bank.residuals_[:, 1]).all()
    assert bank.errors_[1].startswith("`u` and `y` must have units")
    assert [e is None for e in bank.errors_] == [True, False, True, True]
    assert np.isfinite(bank.theta_[[0, 2, 3]]).all()


def test_a_prior_start_maps_p0_and_warns_where_it_outweighs_the_data(rng):
    """``k0=0`` (a prior start from ``P0 = 1e4 I`` in the signals' units): mapped into
    each channel's units as ARX.fit maps it; a channel around 1e-160 hears that the prior
    outweighs its data (ARX.fit's NumericalWarning) and equals ARX.fit, run in its own
    units; one around 1e160 is refused naming `P0`, as ARX.fit refuses it."""
    u, y = _scaled(*_record(rng), [(0, 0), (-531, -531), (3, 1), (0, 0)])
    with pytest.warns(NumericalWarning, match=r"P0 .* outweighs the data of 1 channel\(s\) "
                                              r"scaled to unit size: \[1\]"):
        bank = fit_many(ARX(2, 2), u, y, "rls", k0=0, residual_tests=False)
    for c in range(C):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            model = ARX(2, 2).fit(u[:, c], y[:, c], "rls", k0=0)
        assert_allclose(bank.theta_[c], model.theta_, rtol=1e-12)
    u, y = _scaled(*_record(rng), [(0, 0), (531, 531), (0, 0), (0, 0)])
    with pytest.raises(ValueError, match="`P0` must suit the scale of the data"):
        fit_many(ARX(2, 2), u, y, "rls", k0=0)
    with pytest.raises(ValueError, match="`P0` must suit the scale of the data"):
        ARX(2, 2).fit(u[:, 1], y[:, 1], "rls", k0=0)


def test_modes_bounding_the_trace_and_gradients_run_in_the_signals_units(rng):
    """Constant-trace forgetting (its trace bounds P in the signals' units) and the
    gradient methods are not scaled: the same numbers as before, per channel as
    ARX.fit."""
    u, y = _record(rng)
    u[:, 1] *= 1e3
    for method, options in (("rls", {"forgetting": "constant_trace", "lam": 0.98}),
                            ("nlms", {})):
        bank = fit_many(ARX(2, 2), u, y, method, residual_tests=False, **options)
        for c in range(C):
            model = ARX(2, 2).fit(u[:, c], y[:, c], method, **options)
            assert_allclose(bank.theta_[c], model.theta_, rtol=1e-9)


def test_long_frames_refuse_dates_as_samples(rng):
    """A long-format frame (the command line's, rlsfilt.dask's) whose input or output
    column holds dates or durations: a TypeError naming it, not nanoseconds since 1970."""
    u, y = _record(rng)
    frame = pd.DataFrame({"ch": np.repeat(["a", "b"], N), "u": u[:, :2].T.ravel(),
                          "y": y[:, :2].T.ravel()})
    _summary_long(ARX(1, 1), frame, "ch", ["u"], "y")
    dates = frame.assign(u=pd.to_datetime(1_700_000_000_000 + np.arange(2 * N), unit="ms"))
    with pytest.raises(TypeError, match="`input` must be numeric array-like; got datetime64"):
        _summary_long(ARX(1, 1), dates, "ch", ["u"], "y")
    durations = frame.assign(y=pd.to_timedelta(np.arange(2 * N), unit="s"))
    with pytest.raises(TypeError, match="`output` must be numeric array-like; got timedelta"):
        _summary_long(ARX(1, 1), durations, "ch", ["u"], "y")


def test_labelled_inputs_with_unlabelled_outputs_pair_by_label(rng):
    """`u` a DataFrame, `y` an array (#27 review: `u`'s columns were paired with `y`'s by
    position whatever their labels): with `channels`, `u`'s columns are taken by those
    labels; without, the channels are `u`'s columns, in their order."""
    u, y = _record(rng)
    labels = ["d", "a", "c", "b"]
    U = pd.DataFrame(u, columns=labels)
    expected = fit_many(ARX(2, 2), u, y, channels=labels)
    got = fit_many(ARX(2, 2), U[["a", "b", "c", "d"]], y, channels=labels)
    assert got.channels_ == labels
    assert_array_equal(got.theta_, expected.theta_)
    assert fit_many(ARX(2, 2), U, y).channels_ == labels
    assert_array_equal(fit_many(ARX(2, 2), U, y).theta_, expected.theta_)
    with pytest.raises(ValueError, match=r"the labels `channels` must carry the same channel "
                                         r"labels .* `u` lacks \['e'\], and has \['d'\]"):
        fit_many(ARX(2, 2), U, y, channels=["e", "a", "c", "b"])
    with pytest.raises(ValueError, match="`channels` must be distinct labels"):
        fit_many(ARX(2, 2), U, y, channels=["a", "a", "c", "b"])


def test_unscaled_forgetting_with_intercept_on_a_tiny_record():
    """constant-trace forgetting runs in the signals' units; beside the intercept's
    column of ones, signals around 1e-150 give cond(Phi)^2 beyond the double range, and
    ARX.fit's health threshold 1e4 cond^2 was inf: a ValueError about `cond_max` (never
    passed) where fit_many fits the channel."""
    rng = np.random.default_rng(3)
    u = rng.standard_normal((200, 2))
    y = np.column_stack([lfilter([0, 0.5, 0.2], [1, -0.6], u[:, c])
                         + 0.1 * rng.standard_normal(200) + 3.0 for c in range(2)])
    u, y = 1e-150 * u, 1e-150 * y
    opts = {"lam": 0.99, "forgetting": "constant_trace"}
    bank = fit_many(ARX(1, 1, 1, offset=True), u, y, "rls", residual_tests=False, **opts)
    for c in range(2):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            model = ARX(1, 1, 1, offset=True).fit(u[:, c], y[:, c], "rls", **opts)
        assert np.isfinite(model.filter_.cond_max)
        assert_allclose(bank.theta_[c], model.theta_, rtol=1e-12)
        assert_allclose(bank.theta_cov_[c], model.theta_cov_, rtol=1e-10)
