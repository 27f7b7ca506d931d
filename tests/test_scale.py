"""Scale invariance over the whole double range (issue #18, item 7).

Least squares, order selection, the residual tests, the CUSUM tests and the
information criteria do not depend on the units of the signals. A record
multiplied by 1e-150 or 1e150 (and the audit's 1e-160 and 1e160, where the
squares themselves leave the double range) must give the same estimates in
its units, the same test statistics and p-values, and the same decisions.
The oracle is the record at scale 1, whose numbers the other test modules
check against statsmodels, numpy and closed forms.
"""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt import ARX, select_order, validate
from rlsfilt.validation import (
    cusum,
    cusum_squares,
    fit_percent,
    information_criteria,
    recursive_residuals,
    residual_analysis,
)

SCALES = [1e-150, 1.0, 1e150]
EXTREME = [1e-160, 1e160]


@pytest.fixture(scope="module")
def record():
    """A second-order ARX plant with white equation error (the true structure fits)."""
    rng = np.random.default_rng(18)
    n = 800
    u = rng.standard_normal(n)
    e = 0.1 * rng.standard_normal(n)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1], [1, -1.5, 0.7], e)
    return u, y


def _fit(u, y):
    return ARX(2, 2, 1).fit(u, y)


@pytest.mark.parametrize("su, sy", [(s, s) for s in SCALES] + [(1.0, s) for s in SCALES]
                         + [(s, 1.0) for s in SCALES])
def test_least_squares_estimates_scale_exactly(record, su, sy):
    """theta_ scales as (a unchanged, b by sy/su), theta_cov_ as its square, the noise
    variance by sy^2: relative 1e-12 against the unscaled fit."""
    u, y = record
    ref = _fit(u, y)
    m = _fit(u * su, y * sy)
    g = np.array([1.0, 1.0, sy / su, sy / su])
    assert_allclose(m.theta_, ref.theta_ * g, rtol=1e-12)
    assert_allclose(m.theta_cov_, ref.theta_cov_ * np.outer(g, g), rtol=1e-11)
    assert_allclose(m.noise_variance_, ref.noise_variance_ * sy * sy, rtol=1e-12)
    assert_allclose(m.std_errors_, ref.std_errors_ * g, rtol=1e-12)


@pytest.mark.parametrize("s", SCALES + EXTREME)
def test_fit_is_not_called_rank_deficient_or_exact(record, s):
    """The audit's records around 1e160 were "not persistently exciting"; around 1e-160
    the standard errors were inf."""
    u, y = record
    ref = _fit(u, y)
    m = _fit(u * s, y * s)
    assert_allclose(m.theta_, ref.theta_, rtol=1e-12)
    assert_allclose(m.std_errors_, ref.std_errors_, rtol=1e-11)


@pytest.mark.parametrize("s", SCALES + EXTREME)
def test_residual_tests_are_scale_invariant(record, s):
    u, y = record
    ref = residual_analysis(_fit(u, y), u, y)
    res = residual_analysis(_fit(u * s, y * s), u * s, y * s)
    for name in ("q_statistic", "pvalue_white", "f_statistic", "pvalue_independent"):
        assert_allclose(getattr(res, name), getattr(ref, name), rtol=1e-10, err_msg=name)
    assert_allclose(res.autocorrelation, ref.autocorrelation, rtol=1e-10, atol=1e-14)
    assert_allclose(res.cross_correlation, ref.cross_correlation, rtol=1e-10, atol=1e-14)
    assert (res.is_white, res.is_independent, res.df_independent) == \
        (ref.is_white, ref.is_independent, ref.df_independent)


@pytest.mark.parametrize("s", SCALES + EXTREME)
def test_information_criteria_shift_by_the_log_of_the_scale(record, s):
    """AIC, BIC and nAIC depend on log V: they shift by exactly 2 N log(s) (N log(s^2))."""
    u, y = record
    ref = information_criteria(_fit(u, y), u, y)
    ic = information_criteria(_fit(u * s, y * s), u * s, y * s)
    shift = 2.0 * math.log(s)
    N = ref.n_samples
    assert_allclose(ic.aic, ref.aic + N * shift, rtol=1e-12, atol=1e-9 * abs(ref.aic))
    assert_allclose(ic.bic, ref.bic + N * shift, rtol=1e-12, atol=1e-9 * abs(ref.bic))
    assert_allclose(ic.naic, ref.naic + shift, rtol=1e-12, atol=1e-12)
    if s in SCALES:   # V = s^2 V_1 is representable
        assert_allclose(ic.loss, ref.loss * s * s, rtol=1e-12)
        assert_allclose(ic.fpe, ref.fpe * s * s, rtol=1e-12)


@pytest.mark.parametrize("criterion", ["bic", "aic", "fpe", "mdl"])
@pytest.mark.parametrize("s", SCALES + EXTREME)
def test_order_selection_is_scale_invariant(record, s, criterion):
    u, y = record
    grid = {"na": range(1, 4), "nb": range(1, 4), "nk": range(1, 3)}
    ref = select_order(u, y, criterion=criterion, **grid)
    sel = select_order(u * s, y * s, criterion=criterion, **grid)
    assert sel.best == ref.best == (2, 2, 1)
    assert_allclose(sel.table["naic"], ref.table["naic"] + 2 * math.log(s), rtol=1e-12,
                    atol=1e-11)
    for t_ref, t in zip(ref.thetas, sel.thetas):
        assert_allclose(t, t_ref, rtol=1e-10, atol=1e-12)


def test_order_selection_with_validation_data_is_scale_invariant(record):
    u, y = record
    grid = {"na": range(1, 4), "nb": range(1, 4), "nk": [1]}
    ref = select_order(u[:500], y[:500], criterion="loss", validation=(u[500:], y[500:]), **grid)
    for s in EXTREME:
        sel = select_order(u[:500] * s, y[:500] * s, criterion="loss",
                           validation=(u[500:] * s, y[500:] * s), **grid)
        assert sel.best == ref.best


@pytest.mark.parametrize("s", SCALES + EXTREME)
def test_cusum_tests_are_scale_invariant(record, s):
    u, y = record
    Phi, target = _fit(u, y).regressors(u, y)
    for test in (cusum, cusum_squares):
        ref = test(target, Phi)
        res = test(target * s, Phi * s)
        assert_allclose(res.statistic, ref.statistic, rtol=1e-9, atol=1e-12)
        assert res.rejected == ref.rejected
        if ref.pvalue is not None:
            assert_allclose(res.pvalue, ref.pvalue, rtol=1e-9)
    if s in SCALES:
        w_ref, start_ref = recursive_residuals(target, Phi)
        w, start = recursive_residuals(target * s, Phi * s)
        assert start == start_ref
        assert_allclose(w, w_ref * s, rtol=1e-9, atol=1e-12 * s)


@pytest.mark.parametrize("s", SCALES + EXTREME)
def test_validate_and_fit_percent_are_scale_invariant(record, s):
    u, y = record
    ref = validate(_fit(u, y), u, y)
    rep = validate(_fit(u * s, y * s), u * s, y * s)
    assert_allclose(rep.simulation_fit, ref.simulation_fit, rtol=1e-10)
    assert_allclose(rep.prediction_fit, ref.prediction_fit, rtol=1e-10)
    assert_allclose(rep.residuals[0].pvalue_white, ref.residuals[0].pvalue_white, rtol=1e-10)
    assert rep.passed == ref.passed
    assert_allclose(fit_percent(y * s, 0.9 * y * s), fit_percent(y, 0.9 * y), rtol=1e-13)


def test_cusum_accepts_any_level_in_the_open_interval(record):
    """alpha = 1e-200 used to end in a scipy root-finder error; its line constant solves
    BDE's equation (checked in logarithms) and a smaller alpha gives wider lines."""
    from rlsfilt.validation.cusum import _bde_log_crossing_probability

    u, y = record
    Phi, target = _fit(u, y).regressors(u, y)
    widths = []
    for alpha in (0.05, 1e-10, 1e-200, 1e-320):
        res = cusum(target, Phi, alpha=alpha)
        if alpha != 0.05:   # 0.05 uses the paper's three-decimal 0.948
            assert_allclose(_bde_log_crossing_probability(res.critical_value),
                            math.log(alpha), rtol=1e-9)
        widths.append(res.critical_value)
    assert np.all(np.diff(widths) > 0)


def _bits(x):
    return np.ascontiguousarray(x, dtype=float).view(np.uint64)


def _wide_doubles(rng, size):
    """Doubles over the whole range: normal numbers of every exponent, subnormals, both
    zeros, both infinities, NaN."""
    x = rng.uniform(0.5, 1.0, size) * rng.choice([-1.0, 1.0], size)
    x = np.ldexp(x, rng.integers(-1075, 1025, size))
    special = [0.0, -0.0, np.inf, -np.inf, np.nan, 5e-324, -5e-324, np.finfo(float).max,
               np.finfo(float).tiny, 1.0, -1.5]
    x[:len(special)] = special
    return x


@pytest.mark.parametrize("lo, hi", [(-60, 60), (-1074, 1023), (-2200, 2200)])
def test_times_pow2_equals_ldexp_bit_for_bit(lo, hi):
    """`times_pow2` (a multiplication by 2^e where that is a double, else ldexp) against
    np.ldexp: the same bits for results that round to subnormals, overflow to inf, and
    exponents beyond the double range (the fallback), in place too."""
    from rlsfilt._scale import times_pow2
    rng = np.random.default_rng(7)
    x = _wide_doubles(rng, 20000)
    e = rng.integers(lo, hi + 1, x.size)
    with np.errstate(over="ignore", under="ignore"):
        expected = np.ldexp(x, e)
        np.testing.assert_array_equal(_bits(times_pow2(x, e)), _bits(expected))
        # broadcast exponents per column, as the units map a record's columns
        X = x.reshape(-1, 4)
        ec = rng.integers(lo, hi + 1, 4)
        np.testing.assert_array_equal(_bits(times_pow2(X, ec)), _bits(np.ldexp(X, ec)))
        Y = X.copy()
        assert times_pow2(Y, ec, out=Y) is Y
        np.testing.assert_array_equal(_bits(Y), _bits(np.ldexp(X, ec)))
    assert np.isinf(expected).any() or hi < 100
    assert (np.abs(expected[np.isfinite(expected)]) < np.finfo(float).tiny).sum() > 100


def test_times_pow2_rounds_subnormal_results_as_ldexp():
    """Every exponent from -1100 to 1030 on numbers whose scaled values round (ties
    included): the subnormal range is where a multiplication rounds."""
    from rlsfilt._scale import times_pow2
    x = np.array([1.0, 1.5, 1.25, 1.75, 1.0 + 2.0 ** -52, 3.0 - 2.0 ** -51, -1.375])
    for e in range(-1100, 1031):
        with np.errstate(over="ignore", under="ignore"):
            np.testing.assert_array_equal(_bits(times_pow2(x, e)), _bits(np.ldexp(x, e)))


def test_pow2_factors_are_the_exact_doubles_or_none():
    """`pow2_factors`: ``2^e`` exactly (subnormal factors included) while every exponent is
    in [-1074, 1023], None as soon as one is not (where `times_pow2` calls ldexp)."""
    from rlsfilt._scale import pow2_factors
    e = np.arange(-1074, 1024)
    f = pow2_factors(e)
    np.testing.assert_array_equal(f, np.ldexp(1.0, e))
    assert f[0] == 5e-324 and f[-1] == 2.0 ** 1023
    assert pow2_factors(np.array([3, 1024])) is None
    assert pow2_factors(np.array([-1075, 0])) is None
    assert pow2_factors(np.zeros((2, 0), dtype=int)).shape == (2, 0)


# ----------------------------------------------------------------------
# lam="tune" and Q="tune" (issue #30): the tune runs in the record's units
# ----------------------------------------------------------------------
TUNE_SCALES = [2.0 ** 531, 2.0 ** -531, 1e160, 1e-160]


@pytest.fixture(scope="module")
def tune_record():
    rng = np.random.default_rng(1)
    u = rng.standard_normal(600)
    y = lfilter([0, 1, 0.5], [1, -1.5, 0.7], u) + 0.1 * rng.standard_normal(600)
    return u, y


def _scaled_pair(u, y, which, s):
    """``(base, scaled, k)``: the record with `which` times the mantissa ``m`` of
    ``s = m 2^k`` (``m`` in [0.5, 1)), and with `which` times `s`: the second is the
    first times ``2^k`` exactly (one rounding either way)."""
    m, k = math.frexp(s)
    if which == "u":
        return (u * m, y), (u * s, y), k
    return (u, y * m), (u, y * s), k


def _assert_image(actual, ref, shift):
    """`actual` is ``ref 2^shift``: bit for bit where that is a normal double (or 0);
    within one subnormal spacing (2^-1074) where it underflows (`actual` is one rounding of
    the exact product, ``ldexp(ref, shift)`` a second one)."""
    with np.errstate(over="ignore", under="ignore"):
        expected = np.ldexp(ref, shift)
    normal = (np.abs(expected) >= np.finfo(float).tiny) | (expected == 0) | ~np.isfinite(expected)
    assert_array_equal(np.where(normal, actual, 0.0), np.where(normal, expected, 0.0))
    tiny = ~normal
    assert np.all(np.abs(np.asarray(actual)[tiny] - expected[tiny]) <= 2.0 ** -1074)


@pytest.mark.parametrize("s", TUNE_SCALES)
@pytest.mark.parametrize("which", ["u", "y"])
@pytest.mark.parametrize("param", ["lam", "Q"])
def test_tuned_recursive_fit_is_the_power_of_two_image(tune_record, param, which, s):
    """``ARX.fit(method="rls", lam="tune")`` (or ``Q="tune"``) with `u` or `y` scaled by
    ``2^+-531`` or ``1e+-160 = m 2^k``: the tuned ``lam`` / ``q``, the log-likelihood and
    ``lam_`` bit for bit those of the record scaled by ``m`` alone, ``tune_.R``,
    ``theta_``, ``theta_history_`` and ``filter_.Q`` their exact power-of-two images
    (``ldexp``); and the record scaled by ``2^+-531`` tunes to the bits of the unscaled
    one. ``Q="tune"`` on signals far below unit size, whose random walk a filter in the
    signals' units cannot hold (about ``q / max|phi_k|^2 > 1e150``), is a ValueError
    naming ``Q`` and ``R``."""
    base, scaled, k = _scaled_pair(*tune_record, which, s)
    ref = ARX(2, 2).fit(*base, method="rls", **{param: "tune"})
    if param == "Q" and s < 1:
        with pytest.raises(ValueError, match=r"`Q='tune'` .* beyond the filters' range .*`R`"):
            ARX(2, 2).fit(*scaled, method="rls", Q="tune")
        return
    m = ARX(2, 2).fit(*scaled, method="rls", **{param: "tune"})
    assert m.tune_.estimate == ref.tune_.estimate and m.tune_.loglik == ref.tune_.loglik
    assert m.tune_.n_evals == ref.tune_.n_evals and m.lam_ == ref.lam_
    if s in (2.0 ** 531, 2.0 ** -531):       # and those of the record itself
        one = ARX(2, 2).fit(*tune_record, method="rls", **{param: "tune"})
        assert m.tune_.estimate == one.tune_.estimate
    sy = k if which == "y" else 0
    d = np.array([sy, sy, 0, 0]) if which == "y" else np.array([0, 0, k, k])   # columns
    g = sy - d
    _assert_image(m.tune_.R, ref.tune_.R, 2 * sy)
    _assert_image(m.theta_, ref.theta_, g)
    _assert_image(m.theta_history_[5:], ref.theta_history_[5:], g)
    _assert_image(m.filter_.Q, ref.filter_.Q, -(d[:, None] + d[None, :]))


@pytest.mark.parametrize("param", ["lam", "Q"])
def test_fit_many_tunes_each_channel_as_arx_fit_at_any_scale(tune_record, param):
    """``fit_many(..., lam="tune")`` over channels scaled by ``2^+-531`` and ``1e+-160``
    (`u` or `y`): each channel's tuned value and ``R`` bit for bit those of ``ARX.fit`` on
    that channel (the same tune), ``theta_`` equal to 1e-13 (the bank's kernels against
    the single filter's: the same operations, summed in another order)."""
    from rlsfilt.models import fit_many

    u, y = tune_record
    scales = [s for s in TUNE_SCALES if param == "lam" or s > 1]   # (see above)
    pairs = [(u, y)] + [_scaled_pair(u, y, w, s)[1] for s in scales for w in ("u", "y")]
    U, Y = np.column_stack([p[0] for p in pairs]), np.column_stack([p[1] for p in pairs])
    fleet = fit_many(ARX(2, 2), U, Y, "rls", **{param: "tune"}, residual_tests=False)
    for c, (uc, yc) in enumerate(pairs):
        one = ARX(2, 2).fit(uc, yc, method="rls", **{param: "tune"})
        assert fleet.tune_.estimate[c] == one.tune_.estimate
        assert fleet.tune_.R[c] == one.tune_.R
        assert_allclose(fleet.theta_[c], one.theta_, rtol=1e-13)


@pytest.mark.parametrize("offset", [False, "mean", True])
@pytest.mark.parametrize("param", ["lam", "Q"])
def test_tuned_fit_of_two_outputs_is_the_power_of_two_image(param, offset):
    """Two outputs in different units (one noise variance in the likelihood: the tune
    divides both by one power of two), with each offset: ``y`` times ``2^531`` and ``u``
    times ``2^300`` tune to the bits of the record itself, and ``theta_`` is the exact
    image (the ``a`` rows unchanged, the ``b`` rows times ``2^(531 - 300)``, the intercept
    times ``2^531``)."""
    rng = np.random.default_rng(3)
    N = 800
    u = rng.standard_normal((N, 2))
    b = 1.0 + np.cumsum(0.02 * rng.standard_normal((N, 2)), axis=0)
    e = 0.05 * rng.standard_normal((N, 2))
    y = np.zeros((N, 2))
    for t in range(1, N):
        y[t] = 0.6 * y[t - 1] + b[t] * u[t - 1] + e[t]
    y[:, 1] *= 37.0
    ref = ARX(1, 1, offset=offset).fit(u, y, "rls", **{param: "tune"})
    m = ARX(1, 1, offset=offset).fit(u * 2.0 ** 300, y * 2.0 ** 531, "rls", **{param: "tune"})
    assert not ref.tune_.at_bound               # (an estimate inside the search interval)
    assert m.tune_.estimate == ref.tune_.estimate and m.lam_ == ref.lam_
    assert_array_equal(m.theta_[:2], ref.theta_[:2])
    assert_array_equal(m.theta_[2:4], np.ldexp(ref.theta_[2:4], 231))
    assert_array_equal(m.theta_[4:], np.ldexp(ref.theta_[4:], 531))     # the intercept
    d = np.array([531, 531, 300, 300] + [0] * (len(m.theta_) - 4))     # the columns
    _assert_image(m.filter_.Q, ref.filter_.Q, -(d[:, None] + d[None, :]))


@pytest.mark.parametrize("param", ["lam", "Q"])
def test_tune_from_a_given_prior_maps_it_exactly(tune_record, param):
    """A prior ``P0``, ``x0`` (and ``R``) given in the signals' units: the record with
    ``y`` times ``2^200`` and ``u`` times ``2^-20``, with those options mapped (``x0`` and
    ``P0`` as the parameters and their covariance, ``R`` by ``2^400``), tunes to the bits
    of the unscaled record and fits to the exact image (a prior start, ``k0 = 0``)."""
    u, y = tune_record
    x0 = np.array([-1.0, 0.5, 0.8, 0.2])
    P0 = np.array([[50.0, 3.0, 0, 0], [3.0, 40.0, 0, 0], [0, 0, 30.0, -2.0], [0, 0, -2.0, 20.0]])
    ref = ARX(2, 2).fit(u, y, method="rls", P0=P0, x0=x0, R=0.5, **{param: "tune"})
    g = np.array([0, 0, 220, 220])
    m = ARX(2, 2).fit(u * 2.0 ** -20, y * 2.0 ** 200, method="rls", P0=np.ldexp(
        P0, g[:, None] + g[None, :]), x0=np.ldexp(x0, g), R=np.ldexp(0.5, 400),
        **{param: "tune"})
    assert m.k0_ == 0 and not ref.tune_.at_bound
    assert m.tune_.estimate == ref.tune_.estimate and m.lam_ == ref.lam_
    assert m.tune_.R == np.ldexp(ref.tune_.R, 400)
    assert_array_equal(m.theta_, np.ldexp(ref.theta_, g))
    assert_array_equal(m.theta_cov_, np.ldexp(ref.theta_cov_, g[:, None] + g[None, :]))
