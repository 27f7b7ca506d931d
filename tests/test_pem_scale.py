"""Scale invariance of the prediction-error fits over the whole double range (issue #18, item 7).

ARMAX, OE, BJ, AR and ARMA are linear in the signals: fitting
``(c_u u, c_y y)`` must give the ``b`` coefficients times ``c_y / c_u``, the
``a, c, d, f`` coefficients unchanged, the prediction errors times ``c_y``,
the noise variance times ``c_y^2``, the covariance ``G P G`` (``G`` the
diagonal of those factors), predictions and simulations times ``c_y`` in the
user's units, and the same fit percentages and residual-test p-values. The
criterion is a sum of squares: around 1e160 it overflowed, around 1e-160 it
underflowed, before the fit learned to run in power-of-two scaled units
(`rlsfilt.models._units.RecordUnits`).

The oracle is the fit of the same record at scale 1, whose numbers
`test_pem.py` and `test_family_oracles.py` check against least squares,
statsmodels and the true plants. Where a quantity is not representable in
the user's units (a noise variance of 1e-2 * 1e320) the expected result is
what double precision makes of the exact product: ``inf`` above the range,
a number below the normal range (subnormal or zero) under it.

Tolerances. For power-of-two factors the scaled records are the same bits,
so the fit is the same bits (checked with ``assert_array_equal``). For other
factors (1e160 is not a power of two) the scaled record differs from the
scale-1 one by a factor in [1/2, 2] and by one rounding of every sample, and
the trust-region search (``scipy.optimize.least_squares``, invariant to that
factor in exact arithmetic) sees round-off-level differences. Where it takes
Gauss-Newton steps to convergence (ARMAX, BJ, ARMA; AR is one exact linear
step) every number agrees to about 1e-14 (measured): rtol 1e-12 (1e-13 for
AR). OE's refined-IV start is already within about 1e-11 of the minimum,
and the one step left is accepted or rejected on a cost difference below
round-off (1e-26 relative), so its estimates agree only to the size of that
step (measured 5e-13 here, up to 3e-11 on other seeds; the residual
p-values 2e-11): rtol 1e-10. (On a misspecified structure whose criterion
is flat, e.g. ARMA(2, 1) of an input-driven output, the search stops on
``ftol`` before it has converged to round-off, and factors that are not
powers of two move the estimate by up to 1e-8, as any rescaling or a
different BLAS would: a property of the search tolerance, not of the units.
The tests use the true structures.) The covariance is compared relative to
``sqrt(P_ii P_jj)``.

pytest runs with ``-W error``; the fits are also wrapped in
``warnings.simplefilter("error")`` so an overflow warning fails here too.
"""

import warnings

import numpy as np
import pytest
from conftest import assert_in_units, scaled_by
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt import AR, ARMA, ARMAX, BJ, OE, validate
from rlsfilt.validation import fit_percent, residual_analysis

#: (c_u, c_y): the audit's extremes, both signals and the two mixed ways.
EXTREME = [(1e160, 1e160), (1e-160, 1e-160), (1e150, 1e-150), (1e-150, 1e150), (1e-160, 1.0),
           (1.0, 1e160)]
#: Powers of two: the scaled record is the same bits, so is the fit.
POW2 = [pytest.param(2.0 ** 500, 2.0 ** 500, id="2^500-2^500"),
        pytest.param(2.0 ** -40, 2.0 ** 30, id="2^-40-2^30"),
        pytest.param(2.0 ** 200, 2.0 ** -200, id="2^200-2^-200")]


def _record(seed, b, f, c, d, n=1500, sigma=0.3):
    """``y = B/F u + sigma C/D e`` with white ``u`` and ``e`` (seeded)."""
    rng = np.random.default_rng(seed)
    u, e = rng.standard_normal(n), rng.standard_normal(n)
    return u, lfilter(b, f, u) + sigma * lfilter(c, d, e)


# name: (constructor, record, indices of the b coefficients in theta_, rtol of theta_)
IO_MODELS = {
    # A y = B u + C e: [a1 a2 b1 b2 c1]
    "ARMAX": (lambda: ARMAX(2, 2, 1),
              _record(1, [0, 1.0, 0.5], [1, -1.5, 0.7], [1, -0.5], [1, -1.5, 0.7]), [2, 3],
              1e-12),
    # y = B/F u + e: [b1 b2 f1 f2]; see the module notes for its rtol
    "OE": (lambda: OE(2, 2), _record(2, [0, 1.0, 0.5], [1, -1.5, 0.7], [1.0], [1.0]), [0, 1],
           1e-10),
    # y = B/F u + C/D e: [b1 b2 c1 d1 f1 f2]
    "BJ": (lambda: BJ(2, 1, 1, 2),
           _record(3, [0, 1.0, 0.5], [1, -1.5, 0.7], [1, 0.5], [1, -0.9]), [0, 1], 1e-12),
}
TS_MODELS = {
    # A y = e: [a1 a2] (linear least squares: one exact step)
    "AR": (lambda: AR(2), lfilter([1.0], [1, -1.2, 0.5],
                                  np.random.default_rng(4).standard_normal(1500)), 1e-13),
    # A y = C e: [a1 c1]
    "ARMA": (lambda: ARMA(1, 1), lfilter([1, 0.6], [1, -0.8],
                                         np.random.default_rng(5).standard_normal(1500)), 1e-12),
}


def _fit(make, *signals, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return make().fit(*signals, **options)


def _gain(n_params, b_index, cu, cy):
    """Per-parameter factor: ``c_y / c_u`` on the b coefficients, 1 elsewhere."""
    g = np.ones(n_params)
    g[b_index] = cy / cu
    return g


def _check_fit(m, ref, g, cy, rtol, exact=False):
    """Every learned number of `m` against the scale-1 fit `ref` in the user's units."""
    check = assert_array_equal if exact else None
    # parameters: b by c_y/c_u, the others unchanged (all representable in these cases)
    if exact:
        check(m.theta_, ref.theta_ * g)
    else:
        assert_allclose(m.theta_, ref.theta_ * g, rtol=rtol, atol=0)
    # covariance G P G; entries compared relative to sqrt(P_ii P_jj) in the same units
    cov_ref = scaled_by(scaled_by(ref.theta_cov_, g[:, None]), g[None, :])
    sd = np.sqrt(np.diag(ref.theta_cov_))
    cov_scale = scaled_by(scaled_by(np.outer(sd, sd), g[:, None]), g[None, :])
    if exact:
        check(m.theta_cov_, cov_ref)
    else:
        assert_in_units(m.theta_cov_, cov_ref, rtol, np.abs(cov_scale))
    # noise variance by c_y^2 (inf around 1e160, subnormal around 1e-160)
    var_ref = scaled_by(scaled_by(ref.noise_variance_, cy), cy)
    if exact:
        assert m.noise_variance_ == var_ref
    else:
        assert_in_units(m.noise_variance_, var_ref, rtol, np.abs(var_ref))
    # prediction errors by c_y
    res_ref = scaled_by(ref.residuals_, cy)
    if exact:
        check(m.residuals_, res_ref)
    else:
        assert_in_units(m.residuals_, res_ref, rtol, np.abs(res_ref).max())
    # the optimizer's report: the start in theta units, the cost in y units squared
    if exact:
        check(m.fit_info_["theta0"], ref.fit_info_["theta0"] * g)
    else:
        assert_allclose(m.fit_info_["theta0"], ref.fit_info_["theta0"] * g, rtol=1e-10)
    cost_ref = scaled_by(scaled_by(ref.fit_info_["cost"], cy), cy)
    assert_in_units(m.fit_info_["cost"], cost_ref, 0.0 if exact else rtol, np.abs(cost_ref))


# ----------------------------------------------------------------------
# input/output models
# ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def io_refs():
    return {name: _fit(make, u, y) for name, (make, (u, y), _, _) in IO_MODELS.items()}


@pytest.mark.parametrize("cu, cy", EXTREME)
@pytest.mark.parametrize("name", list(IO_MODELS))
def test_io_fit_scales_exactly_in_the_users_units(io_refs, name, cu, cy):
    make, (u, y), b_index, rtol = IO_MODELS[name]
    ref = io_refs[name]
    m = _fit(make, u * cu, y * cy)
    _check_fit(m, ref, _gain(ref.n_params_, b_index, cu, cy), cy, rtol)


@pytest.mark.parametrize("cu, cy", POW2)
@pytest.mark.parametrize("name", list(IO_MODELS))
def test_io_fit_with_power_of_two_factors_is_bit_identical(io_refs, name, cu, cy):
    """The record is scaled by powers of two, exactly: the fit is the same bits, mapped."""
    make, (u, y), b_index, _ = IO_MODELS[name]
    ref = io_refs[name]
    m = _fit(make, u * cu, y * cy)
    _check_fit(m, ref, _gain(ref.n_params_, b_index, cu, cy), cy, 0.0, exact=True)
    assert m.fit_info_["n_fev"] == ref.fit_info_["n_fev"]


@pytest.mark.parametrize("cu, cy", EXTREME)
@pytest.mark.parametrize("name", list(IO_MODELS))
def test_predictions_and_simulations_are_in_the_users_units(io_refs, name, cu, cy):
    """predict (one and three steps ahead), simulate, fit % and the residual tests."""
    make, (u, y), _, rtol = IO_MODELS[name]
    ref = io_refs[name]
    m = _fit(make, u * cu, y * cy)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for horizon in (1, 3):
            p, p_ref = m.predict(u * cu, y * cy, horizon=horizon), ref.predict(u, y, horizon)
            assert_allclose(p, p_ref * cy, rtol=0, atol=rtol * np.abs(p_ref * cy).max())
        s, s_ref = m.simulate(u * cu), ref.simulate(u)
        assert_allclose(s, s_ref * cy, rtol=0, atol=rtol * np.abs(s_ref * cy).max())
        assert_allclose(fit_percent(y * cy, s), fit_percent(y, s_ref), rtol=rtol)
        rep, rep_ref = validate(m, u * cu, y * cy), validate(ref, u, y)
        ra, ra_ref = residual_analysis(m, u * cu, y * cy), residual_analysis(ref, u, y)
    assert_allclose(rep.simulation_fit, rep_ref.simulation_fit, rtol=rtol)
    assert_allclose(rep.prediction_fit, rep_ref.prediction_fit, rtol=rtol)
    assert rep.passed == rep_ref.passed
    for key in ("q_statistic", "pvalue_white", "f_statistic", "pvalue_independent"):
        assert_allclose(getattr(ra, key), getattr(ra_ref, key), rtol=rtol, err_msg=key)
    assert (ra.is_white, ra.is_independent) == (ra_ref.is_white, ra_ref.is_independent)


@pytest.mark.parametrize("cu, cy", [(1e160, 1e160), (1e150, 1e-150)])
def test_theta0_is_read_in_the_users_units(io_refs, cu, cy):
    """A start given in the record's units: the scale-1 estimate scaled is a start at the
    minimum, and the fit from it equals the scale-1 fit from the scale-1 estimate."""
    make, (u, y), b_index, _ = IO_MODELS["ARMAX"]
    ref = io_refs["ARMAX"]
    g = _gain(ref.n_params_, b_index, cu, cy)
    m = _fit(make, u * cu, y * cy, theta0=ref.theta_ * g)
    again = _fit(make, u, y, theta0=ref.theta_)
    assert_allclose(m.fit_info_["theta0"], ref.theta_ * g, rtol=1e-15)
    assert_allclose(m.theta_, again.theta_ * g, rtol=1e-12)


def test_theta0_that_overflows_the_scaled_units_is_a_clear_error():
    """b = 1e300 where u ~ 1e150 and y ~ 1e-150 is 1e600 in unit-size signals."""
    make, (u, y), _, _ = IO_MODELS["ARMAX"]
    with pytest.raises(ValueError, match="`theta0` must have b coefficients"):
        _fit(make, u * 1e150, y * 1e-150, theta0=[-1.5, 0.7, 1e300, 1e300, -0.5])


@pytest.mark.parametrize("name", list(IO_MODELS))
def test_b_coefficients_beyond_the_double_range_are_a_clear_error(name):
    """u ~ 1e-160 and y ~ 1e160: b ~ 1e320 is not a double; the fit says so (naming `u` and
    `y`) instead of returning a model with infinite coefficients, and the model stays
    unfitted."""
    make, (u, y), _, _ = IO_MODELS[name]
    model = make()
    with pytest.raises(ValueError, match=r"`u` and `y` must have units .* about 2\^10[67]\d"):
        model.fit(u * 1e-160, y * 1e160)
    assert not hasattr(model, "theta_")


@pytest.mark.parametrize("cu, cy", [(1e150, 1e-150), (1e-150, 1e150)])
def test_several_experiments_scale_together(io_refs, cu, cy):
    """A list of records: one factor per signal over every experiment (the criterion sums
    over them), so the split fit scales as the joined one does."""
    make, (u, y), b_index, rtol = IO_MODELS["BJ"]
    parts = [slice(0, 700), slice(700, None)]
    ref = _fit(make, [u[p] for p in parts], [y[p] for p in parts])
    m = _fit(make, [u[p] * cu for p in parts], [y[p] * cy for p in parts])
    g = _gain(ref.n_params_, b_index, cu, cy)
    assert_allclose(m.theta_, ref.theta_ * g, rtol=rtol)
    assert_in_units(m.residuals_, ref.residuals_ * cy, rtol, np.abs(ref.residuals_ * cy).max())


def test_two_inputs_get_their_own_factors():
    """Inputs in different units (1e150 and 1e-150): each b block scales by c_y / c_u_i."""
    rng = np.random.default_rng(6)
    n = 1500
    U = rng.standard_normal((n, 2))
    y = (lfilter([0, 1.0, 0.5], [1, -0.8], U[:, 0]) + lfilter([0, -0.7], [1, -0.5], U[:, 1])
         + 0.2 * rng.standard_normal(n))
    make = lambda: OE([2, 1], [1, 1])                    # [b1 b2 | b1], [f1 | f1]  # noqa: E731
    ref = _fit(make, U, y)
    c = np.array([1e150, 1e-150])
    m = _fit(make, U * c, y * 1e-10)
    g = np.array([1e-160, 1e-160, 1e140, 1.0, 1.0])
    assert_allclose(m.theta_, ref.theta_ * g, rtol=1e-10)
    assert_allclose(m.noise_variance_, ref.noise_variance_ * 1e-20, rtol=1e-10)


# ----------------------------------------------------------------------
# time series
# ----------------------------------------------------------------------
@pytest.mark.parametrize("c", [1e160, 1e-160, pytest.param(2.0 ** 700, id="2^700"),
                               pytest.param(2.0 ** -700, id="2^-700")])
@pytest.mark.parametrize("name", list(TS_MODELS))
def test_time_series_fit_scales_exactly(name, c):
    make, y, rtol = TS_MODELS[name]
    ref = _fit(make, y)
    m = _fit(make, y * c)
    exact = np.frexp(c)[0] == 0.5
    _check_fit(m, ref, np.ones(ref.n_params_), c, rtol, exact=exact)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        p, p_ref = m.predict(None, y * c), ref.predict(None, y)
        ra, ra_ref = residual_analysis(m, None, y * c), residual_analysis(ref, None, y)
    if exact:
        assert_array_equal(p, p_ref * c)
    else:
        assert_allclose(p, p_ref * c, rtol=0, atol=rtol * np.abs(p_ref * c).max())
    assert_allclose(ra.pvalue_white, ra_ref.pvalue_white, rtol=rtol)
    assert ra.is_white == ra_ref.is_white
