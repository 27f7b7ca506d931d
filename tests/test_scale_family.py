"""Scale invariance of ARX's IV and recursive fits and of RPEM/RPLR over the double range (#18, 7).

Every model is linear in its signals: fitting ``(c_u u, c_y y)`` must give the
``b`` coefficients times ``c_y / c_u``, the ``a`` (and ``c``, ``d``, ``f``)
coefficients unchanged, an intercept times ``c_y``, residuals and recursive
residuals times ``c_y``, the noise variance times ``c_y^2``, the covariance
``G P G`` and the histories of the estimate scaled as the estimate. ARX's
batch and recursive instrumental variables (``"iv"``, ``"riv"``), its
recursive least squares (``"rls"``) and the recursive prediction-error fits
(``"rpem"``, ``"rplr"``) overflowed around 1e160 and underflowed around
1e-160 (sums of products of the signals) before they learned to run in
power-of-two scaled units (`rlsfilt.models._units.RecordUnits`).

The oracle is the fit of the same record at scale 1 (checked against batch
IV, least squares and the reference recursions in `test_iv.py`,
`test_arx.py`, `test_recursive_pem.py`). Where a quantity is not
representable in the user's units (a variance of 1e-2 * 1e320) the expected
value is what double precision makes of the exact product (`assert_in_units`).

The options of a recursion (``P0``, ``R``, ``Q``, ``x0``) and their defaults
(``P0 = 1e4 I``, ``R = 1``) are in the signals' units, as MATLAB's and as
those of the streaming estimators, which `test_model_family.py` holds equal
to the batch fits bit for bit. So a fit from an exact start (``"rls"``,
``"riv"`` by default) is scale-invariant with its defaults, while a prior
start is the same fit only with options that carry the units (``P0 / R``
times ``(c_theta / c_y)^2``); the default prior of a record far from unit size
is reported: a NumericalWarning naming ``P0`` when it outweighs the data, a
ValueError naming it when it is too diffuse for double precision.

Tolerances. For power-of-two factors the scaled record is the same bits, and
so is every number of the fit, mapped (``assert_array_equal``). The
recursions run in the scaled units compute the numbers of the same recursion
in the signals' units times powers of two: held bit for bit against the
filter and the streaming estimator run in the signals' units. For other
factors (1e160 is not a power of two) the scaled record differs from the
scale-1 one by a factor in [1/2, 2] and one rounding of every sample.
Measured: the final estimates and covariances of the recursions and of
delayed-input IV agree to 2e-14 relative (rtol 1e-12); refined IV with
auxiliary-model instruments iterates until its step is below 1e-10 relative,
and its estimate moves by up to 2e-12 (rtol 1e-10); histories agree to 3e-13
of each parameter's largest value (the first rows after the start are
ill-conditioned; rtol 1e-11). The covariance is compared relative to
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

from rlsfilt import (
    ARMAX,
    ARX,
    BJ,
    OE,
    NumericalWarning,
    RecursiveARMAX,
    RecursiveLeastSquares,
    SquareRootRLS,
)

#: (c_u, c_y): the audit's extremes, both signals and the two mixed ways.
EXTREME = [(1e160, 1e160), (1e-160, 1e-160), (1e150, 1e-150), (1e-150, 1e150), (1e-160, 1.0),
           (1.0, 1e160)]
#: Powers of two: the scaled record is the same bits, so is the fit.
POW2 = [pytest.param(2.0 ** 500, 2.0 ** 500, id="2^500-2^500"),
        pytest.param(2.0 ** -40, 2.0 ** 30, id="2^-40-2^30"),
        pytest.param(2.0 ** 200, 2.0 ** -200, id="2^200-2^-200"),
        pytest.param(2.0 ** -600, 2.0 ** -600, id="2^-600-2^-600")]


def _record(seed=7, n=1500, offset=0.0):
    """ARX(2, 2) plant with coloured (ARMA) equation error: IV is consistent, LS is not."""
    rng = np.random.default_rng(seed)
    u, e = rng.standard_normal(n), rng.standard_normal(n)
    y = (lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u)
         + 0.5 * lfilter([1, -1, 0.2], [1, -1.5, 0.7], e) + offset)
    return u, y


def _fit(make, *signals, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return make().fit(*signals, **options)


# name: (constructor, options, offset of the record, rtol of the final numbers)
ARX_FITS = {
    "iv": (lambda: ARX(2, 2), dict(method="iv"), 0.0, 1e-10),
    "iv-delayed": (lambda: ARX(2, 2), dict(method="iv", instruments="delayed"), 0.0, 1e-12),
    "iv-intercept": (lambda: ARX(2, 2, offset=True), dict(method="iv"), 3.0, 1e-10),
    "riv": (lambda: ARX(2, 2), dict(method="riv"), 0.0, 1e-12),
    "riv-delayed": (lambda: ARX(2, 2), dict(method="riv", instruments="delayed", lam=0.995),
                    0.0, 1e-12),
    "rls": (lambda: ARX(2, 2), dict(method="rls"), 0.0, 1e-12),
    "rls-square-root": (lambda: ARX(2, 2), dict(method="rls", form="square_root"), 0.0, 1e-12),
    "rls-directional": (lambda: ARX(2, 2), dict(method="rls", lam=0.98,
                                                forgetting="directional"), 0.0, 1e-12),
    "rls-intercept": (lambda: ARX(2, 2, offset=True), dict(method="rls"), 3.0, 1e-12),
    "rls-mean": (lambda: ARX(2, 2, offset="mean"), dict(method="rls", lam=0.99), 3.0, 1e-12),
}


def _gain(model, cu, cy):
    """Per-parameter factor of ARX(2, 2): a by 1, b by c_y / c_u, an intercept by c_y."""
    g = np.array([1.0, 1.0, cy / cu, cy / cu])
    return np.append(g, cy) if model.n_params_ == 5 else g


def _instrument_gain(model, options, cu, cy):
    """Columns of the instruments: the auxiliary output's lags by c_y, input lags by c_u
    (all by c_u for delayed inputs), the intercept's constant by 1."""
    g = np.array([cu, cu, cu, cu]) if options.get("instruments") == "delayed" else \
        np.array([cy, cy, cu, cu])
    return np.append(g, 1.0) if model.n_params_ == 5 else g


def _check_arx(m, ref, options, cu, cy, rtol, exact=False):
    """Every learned number of `m` against the scale-1 fit `ref`, in the user's units."""
    g = _gain(ref, cu, cy)
    if exact:
        assert_array_equal(m.theta_, ref.theta_ * g)
    else:
        assert_allclose(m.theta_, ref.theta_ * g, rtol=rtol, atol=0)
    sd = np.sqrt(np.diag(ref.theta_cov_))
    cov_ref = scaled_by(scaled_by(ref.theta_cov_, g[:, None]), g[None, :])
    if exact:
        assert_array_equal(m.theta_cov_, cov_ref)
    else:
        cov_scale = scaled_by(scaled_by(np.outer(sd, sd), g[:, None]), g[None, :])
        assert_in_units(m.theta_cov_, cov_ref, rtol, np.abs(cov_scale))
    var_ref = scaled_by(scaled_by(ref.noise_variance_, cy), cy)
    res_ref = scaled_by(ref.residuals_, cy)
    if exact:
        assert m.noise_variance_ == var_ref
        assert_array_equal(m.residuals_, res_ref)
    else:
        assert_in_units(m.noise_variance_, var_ref, rtol, np.abs(var_ref))
        assert_in_units(m.residuals_, res_ref, rtol, np.abs(res_ref).max())
    assert_array_equal(m.input_offset_, ref.input_offset_ * cu) if exact else \
        assert_allclose(m.input_offset_, ref.input_offset_ * cu, rtol=rtol)
    assert_array_equal(m.output_offset_, ref.output_offset_ * cy) if exact else \
        assert_allclose(m.output_offset_, ref.output_offset_ * cy, rtol=1e3 * rtol)
    if "theta_history_" in ref.__dict__:
        hist_ref = scaled_by(ref.theta_history_, g)
        rec_ref = scaled_by(ref.recursive_residuals_, cy)
        if exact:
            assert_array_equal(m.theta_history_, hist_ref)
            assert_array_equal(m.recursive_residuals_, rec_ref)
        else:
            assert_array_equal(np.isnan(m.theta_history_), np.isnan(hist_ref))
            ok = ~np.isnan(hist_ref)
            col = np.nanmax(np.abs(hist_ref), axis=0)          # each parameter's largest
            assert np.all(np.abs(m.theta_history_ - hist_ref)[ok]
                          <= (1e-11 * np.broadcast_to(col, hist_ref.shape))[ok])
            assert_in_units(m.recursive_residuals_, rec_ref, 1e-11,
                            np.nanmax(np.abs(rec_ref)))
    if "instruments_" in ref.__dict__:
        z_ref = scaled_by(ref.instruments_, _instrument_gain(ref, options, cu, cy))
        if exact:
            assert_array_equal(m.instruments_, z_ref)
        else:
            assert_in_units(m.instruments_, z_ref, rtol, np.abs(z_ref).max(axis=0))
    if "filter_" in ref.__dict__:
        assert_array_equal(m.filter_.x[:, 0], m.theta_)


# ----------------------------------------------------------------------
# ARX: instrumental variables and recursive least squares
# ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def arx_refs():
    out = {}
    for name, (make, options, offset, _) in ARX_FITS.items():
        u, y = _record(offset=offset)
        out[name] = _fit(make, u, y, **options)
    return out


@pytest.mark.parametrize("cu, cy", EXTREME)
@pytest.mark.parametrize("name", list(ARX_FITS))
def test_arx_fit_scales_exactly_in_the_users_units(arx_refs, name, cu, cy):
    make, options, offset, rtol = ARX_FITS[name]
    u, y = _record(offset=offset)
    m = _fit(make, u * cu, y * cy, **options)
    _check_arx(m, arx_refs[name], options, cu, cy, rtol)


@pytest.mark.parametrize("cu, cy", POW2)
@pytest.mark.parametrize("name", list(ARX_FITS))
def test_arx_fit_with_power_of_two_factors_is_bit_identical(arx_refs, name, cu, cy):
    make, options, offset, _ = ARX_FITS[name]
    u, y = _record(offset=offset)
    m = _fit(make, u * cu, y * cy, **options)
    _check_arx(m, arx_refs[name], options, cu, cy, 0.0, exact=True)


def test_user_instruments_are_read_in_their_own_units(arx_refs):
    """An array of instrument rows (here delayed inputs, built by hand) in any units: the
    estimate does not depend on them, and `instruments_` gives them back unchanged."""
    u, y = _record()
    Z = np.column_stack([np.concatenate([np.zeros(k), u[:-k]]) for k in (3, 4, 1, 2)])
    ref = _fit(lambda: ARX(2, 2), u, y, method="iv", instruments=Z)
    for cz, (cu, cy) in [(1e-200, (1e160, 1e160)), (2.0 ** 700, (2.0 ** -500, 2.0 ** -500))]:
        m = _fit(lambda: ARX(2, 2), u * cu, y * cy, method="iv", instruments=Z * cz)
        assert_allclose(m.theta_, ref.theta_ * _gain(ref, cu, cy), rtol=1e-12)
        assert_array_equal(m.instruments_, (Z * cz)[2:])


def test_two_outputs_get_their_own_factors():
    """ARX with two outputs in different units (delayed-input IV and RLS): the coefficient
    of y_i(t-k) in the equation of y_j scales by c_j / c_i, of u by c_j / c_u."""
    rng = np.random.default_rng(11)
    n = 1500
    u = rng.standard_normal(n)
    y1 = lfilter([0, 1.0], [1, -0.8], u) + 0.1 * rng.standard_normal(n)
    y2 = lfilter([0, 0.5, 0.3], [1, -0.5], u) + 0.1 * rng.standard_normal(n)
    Y = np.column_stack([y1, y2])
    c = np.array([1e150, 1e-150])
    cu = 1e-100
    for options in (dict(method="iv", instruments="delayed"), dict(method="rls"),
                    dict(method="riv", instruments="delayed")):
        ref = _fit(lambda: ARX(1, 2), u, Y, **options)
        m = _fit(lambda: ARX(1, 2), u * cu, Y * c, **options)
        # theta_ rows: a1 of y1, a1 of y2, b1, b2; columns: the equations of y1, y2
        g = np.vstack([c / c[0], c / c[1], c / cu, c / cu])
        assert_allclose(m.theta_, ref.theta_ * g, rtol=1e-12)
        assert_allclose(m.noise_variance_, ref.noise_variance_ * c ** 2, rtol=1e-12)


def test_two_outputs_whose_ratio_is_beyond_the_double_range_are_a_clear_error():
    """y1 around 1e160 and y2 around 1e-160: the coefficient of y2(t-1) in the equation of
    y1 is about 1e320."""
    rng = np.random.default_rng(12)
    u = rng.standard_normal(800)
    Y = np.column_stack([lfilter([0, 1.0], [1, -0.5], u), lfilter([0, 1.0], [1, -0.3], u)])
    Y += 0.1 * rng.standard_normal(Y.shape)
    with pytest.raises(ValueError, match=r"`y` must have outputs in units whose ratios"):
        ARX(1, 1).fit(u, Y * [1e160, 1e-160])


@pytest.mark.parametrize("cu, cy", [(1e150, 1e-150), (1e-160, 1e-160)])
def test_several_experiments_scale_together(cu, cy):
    """A list of records: one factor per signal over every experiment; the recursions
    carry the estimate over the seam as at scale 1."""
    u, y = _record()
    parts = [slice(0, 700), slice(700, None)]
    for options in (dict(method="riv"), dict(method="rls"), dict(method="iv")):
        ref = _fit(lambda: ARX(2, 2), [u[p] for p in parts], [y[p] for p in parts], **options)
        m = _fit(lambda: ARX(2, 2), [u[p] * cu for p in parts], [y[p] * cy for p in parts],
                 **options)
        assert_allclose(m.theta_, ref.theta_ * _gain(ref, cu, cy),
                        rtol=1e-10 if options["method"] == "iv" else 1e-12)


# ----------------------------------------------------------------------
# the recursions compute the unscaled numbers times powers of two
# ----------------------------------------------------------------------
def _filter_in_signal_units(model, u, y, options):
    """The oracle of an ``ARX.fit(method="rls")``: the filter it names, built with the
    same options and run in the signals' units on `model.regressors` (batch start on the
    first ``k0_`` rows, then `batch_filter`)."""
    opts = {k: v for k, v in options.items() if k not in ("k0", "form")}
    cls = SquareRootRLS if model.form_ == "square_root" else RecursiveLeastSquares
    opts.setdefault("cond_max", model.filter_.cond_max)
    f = cls(model.n_params_, lam=opts.pop("lam", 1.0), **opts)
    Phi, target = model.regressors(u, y)
    k0 = model.k0_
    if k0:
        f.initialize(target[:k0], Phi[:k0])
    means = f.batch_filter(target[k0:], Phi[k0:])[0]
    return f, means[:, :, 0]


@pytest.mark.parametrize("options", [
    dict(), dict(form="square_root"), dict(lam=0.98, forgetting="directional"),
    dict(k0=0, P0=100.0, R=0.25, lam=0.99), dict(k0=0, x0=np.ones(4), Q=1e-6, lam=0.995),
    dict(gate=3.0, lam=0.99, R=0.25)],
    ids=["batch-start", "square-root", "directional", "prior", "random-walk", "gate"])
def test_rls_in_scaled_units_is_the_filter_in_the_signals_units_bit_for_bit(options):
    """`ARX.fit` runs its recursion on the rows scaled to unit size; the filter with the
    same options run on the rows in the signals' units (u up to 2^-3, y up to 2^4 here)
    gives the same bits: every estimate, and `filter_` (x, P, the last gain, residual and
    its variance), which continues as the filter does."""
    u, y = _record()
    u = u / 8
    m = _fit(lambda: ARX(2, 2), u, y, method="rls", **options)
    f, means = _filter_in_signal_units(m, u, y, options)
    assert_array_equal(m.theta_history_[m.k0_:], means)
    for name in ("x", "P", "K", "y", "S", "x_prior", "P_prior"):
        assert_array_equal(getattr(m.filter_, name), getattr(f, name), err_msg=name)
    assert m.filter_.n_updates == f.n_updates
    phi = m.regressors(u, y)[0][-1]
    m.filter_.predict_update(y[-1], phi)
    f.predict_update(y[-1], phi)
    assert_array_equal(m.filter_.x, f.x)
    assert_array_equal(m.filter_.P, f.P)


@pytest.mark.parametrize("method", ["rpem", "rplr"])
@pytest.mark.parametrize("options", [dict(), dict(P0=50.0, R=0.5, lam=0.999),
                                     dict(gate=4.0, Q=1e-7, lam=0.995),
                                     dict(forgetting="directional", lam=0.99)],
                         ids=["defaults", "prior", "gate", "directional"])
def test_rpem_in_scaled_units_is_the_streaming_recursion_bit_for_bit(method, options):
    """The fit runs on the record scaled to unit size; the streaming estimator (the same
    compiled step, in the signals' units) gives the same bits: the histories, and
    `state_` (estimate, P, signal lags), which continues as the estimator does."""
    u, y = _record()
    u = u / 8
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)    # rplr's positive-real check
        m = ARMAX(2, 2, 1).fit(u, y, method=method, **options)
    est = RecursiveARMAX(2, 2, 1, 1, method=method, **options)
    _, hist = est.batch(y, u)
    assert_array_equal(m.theta_history_, hist)
    for name in ("theta", "P", "buf"):
        assert_array_equal(getattr(m.state_, name), getattr(est._state, name), err_msg=name)
    assert m.state_.step(1.0, np.array([0.5])) == est._state.step(1.0, np.array([0.5]))
    assert_array_equal(m.state_.theta, est._state.theta)


@pytest.mark.parametrize("k", [600, -400])
@pytest.mark.parametrize("make, method", [(lambda: ARMAX(2, 2, 1), "rpem"),
                                          (lambda: OE(2, 2), "rplr"),
                                          (lambda: BJ(2, 1, 1, 2), "rpem"),
                                          (lambda: ARX(2, 2), "rls")],
                         ids=["ARMAX-rpem", "OE-rplr", "BJ-rpem", "ARX-rls"])
def test_prior_in_the_users_units_gives_the_unit_fit_far_from_unit_size(make, method, k):
    """A prior start in records scaled by 2^600 or 2^-400, with P0 and R that carry the
    units (the prior of the scale-1 fit: P0 / R times 2^-2k, split so that each is in the
    range the filters take, 1e+-150): the scale-1 fit, bit for bit. In the signals' units
    the recursion would over- or underflow; it runs in the scaled units."""
    u, y = _record()
    options = {"k0": 0} if method == "rls" else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)    # rplr's positive-real check
        ref = make().fit(u, y, method=method, P0=100.0, R=1.0, lam=0.999, **options)
        c = 2.0 ** k
        R = 2.0 ** (400 if k > 0 else -400)
        m = make().fit(u * c, y * c, method=method, P0=np.ldexp(100.0, (400 if k > 0 else -400)
                                                               - 2 * k), R=R, lam=0.999,
                       **options)
    assert_array_equal(m.theta_, ref.theta_)
    assert_array_equal(m.theta_history_, ref.theta_history_)
    assert_array_equal(m.recursive_residuals_, scaled_by(ref.recursive_residuals_, c))


# ----------------------------------------------------------------------
# the defaults stay in the signals' units: what a record far from unit size gets
# ----------------------------------------------------------------------
@pytest.mark.parametrize("fit", [
    lambda u, y: ARMAX(2, 2, 1).fit(u, y, method="rpem"),
    lambda u, y: OE(2, 2).fit(u, y, method="rpem"),
    lambda u, y: ARX(2, 2).fit(u, y, method="riv", k0=0),
    lambda u, y: ARX(2, 2).fit(u, y, method="rls", x0=np.zeros(4))],
    ids=["ARMAX-rpem", "OE-rpem", "ARX-riv-prior", "ARX-rls-prior"])
def test_a_default_prior_that_outweighs_the_data_is_named(fit):
    """P0 = 1e4 I for signals around 1e-160 holds the estimate at x0: a NumericalWarning
    naming P0 and the scale (the estimate is that of the prior, as MATLAB's would be)."""
    u, y = _record()
    with pytest.warns(NumericalWarning, match=r"P0 = 1e4 I \(the default; P0 and R are in the "
                      r"signals' units\) is about 1e-31\d times .*`u` up to .*e-16\d, `y` up "
                      r"to .*e-1[56]\d.*outweighs the data"):
        m = fit(u * 1e-160, y * 1e-160)
    assert np.all(np.abs(m.theta_) < 1e-300)
    # signals around 1e-3: the default prior biases the estimate by percents; said too
    with pytest.warns(NumericalWarning, match=r"about 1e-0?[56] times .*outweighs the data"):
        fit(u * 1e-3, y * 1e-3)


@pytest.mark.parametrize("fit", [
    lambda u, y: ARMAX(2, 2, 1).fit(u, y, method="rpem"),
    lambda u, y: BJ(2, 1, 1, 2).fit(u, y, method="rplr"),
    lambda u, y: ARX(2, 2).fit(u, y, method="riv", k0=0),
    lambda u, y: ARX(2, 2).fit(u, y, method="rls", k0=0)],
    ids=["ARMAX-rpem", "BJ-rplr", "ARX-riv-prior", "ARX-rls-prior"])
def test_a_default_prior_too_diffuse_for_double_precision_is_a_clear_error(fit):
    """P0 = 1e4 I for signals around 1e160 is about 1e320 times the unit-size prior: the
    first covariance update would lose every digit (NaN before); a ValueError naming P0
    and the scale, and the model stays unfitted."""
    u, y = _record()
    with pytest.raises(ValueError, match=r"`P0` must suit the scale of the data \(`u` up to "
                       r".*e\+16\d, `y` up to .*e\+16\d\): P0 = 1e4 I .* about 1e\+32\d times"):
        fit(u * 1e160, y * 1e160)


def test_the_default_prior_at_unit_scale_is_silent_and_unchanged():
    """No warning for signals of a few units; the fit is the streaming estimator's (P0 =
    1e4 I in the signals' units), bit for bit, as `test_model_family.py` checks at length."""
    u, y = _record()
    m = _fit(lambda: ARMAX(2, 2, 1), u, y, method="rpem")
    est = RecursiveARMAX(2, 2, 1, 1)
    _, hist = est.batch(y, u)
    assert_array_equal(hist, m.theta_history_)


def test_a_gate_needs_R_in_the_signals_units():
    """The outlier gate compares residuals with sqrt(R): R = 1 for signals around 1e160 is a
    clear error naming R; R of the size of the noise variance (the scale-1 R times c^2)
    gives the scale-1 fit, bit for bit."""
    u, y = _record()
    with pytest.raises(ValueError, match=r"`R` must suit the scale of the data \(`u` up to "
                       r".*e\+16\d, `y` up to .*e\+16\d\): R = 1 in the signals' units"):
        ARX(2, 2).fit(u * 1e160, y * 1e160, method="rls", gate=4.0)
    for options in (dict(), dict(k0=0, lam=0.99)):
        ref = _fit(lambda: ARX(2, 2), u, y, method="rls", gate=3.0, R=0.25, **options)
        c = 2.0 ** 200
        m = _fit(lambda: ARX(2, 2), u * c, y * c, method="rls", gate=3.0, R=0.25 * c * c,
                 **options)
        assert_array_equal(m.theta_history_, ref.theta_history_)
        assert m.filter_.n_gated == ref.filter_.n_gated > 0


# ----------------------------------------------------------------------
# errors naming the argument
# ----------------------------------------------------------------------
@pytest.mark.parametrize("make, method", [
    (lambda: ARX(2, 2), "ls"), (lambda: ARX(2, 2), "iv"), (lambda: ARX(2, 2), "riv"),
    (lambda: ARX(2, 2), "rls"), (lambda: ARMAX(2, 2, 1), "pem"),
    (lambda: ARMAX(2, 2, 1), "rpem"), (lambda: OE(2, 2), "rplr")])
def test_b_coefficients_beyond_the_double_range_are_one_clear_error(make, method):
    """u ~ 1e-160 and y ~ 1e160: b ~ 1e320 is not a double. Every method says so with the
    same message naming `u` and `y` (no overflow warning, no inf coefficients, no error
    about P0 first), and the model stays unfitted."""
    u, y = _record()
    model = make()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"^`u` and `y` must have units whose ratio double "
                           r"precision can hold; got b coefficients of about 2\^10[67]\d"):
            model.fit(u * 1e-160, y * 1e160, method=method)
    assert "theta_" not in model.__dict__


def test_x0_beyond_the_scaled_units_is_a_clear_error():
    """x0 = 1e300 for b where u ~ 1e150 and y ~ 1e-150 is 1e600 in unit-size signals."""
    u, y = _record()
    with pytest.raises(ValueError, match="`x0` must have b coefficients"):
        ARMAX(2, 2, 1).fit(u * 1e150, y * 1e-150, method="rpem", x0=[0, 0, 1e300, 1e300, 0])


def test_time_series_recursions_scale_too():
    """ARMA by RPEM at 2^600 with the prior in the signals' units is the scale-1 fit, bit
    for bit; AR by RPLR with the default prior around 1e-160 names P0."""
    from rlsfilt import AR, ARMA

    y = lfilter([1, 0.6], [1, -0.8], np.random.default_rng(5).standard_normal(2000))
    ref = _fit(lambda: ARMA(1, 1), y, method="rpem", P0=100.0, R=1.0)
    c = 2.0 ** 600
    m = _fit(lambda: ARMA(1, 1), y * c, method="rpem", P0=np.ldexp(100.0, 400 - 1200),
             R=2.0 ** 400)
    assert_array_equal(m.theta_, ref.theta_)
    assert_array_equal(m.theta_history_, ref.theta_history_)
    assert_array_equal(m.residuals_, ref.residuals_ * c)
    with pytest.warns(NumericalWarning, match=r"P0 = 1e4 I .*\(`y` up to .*e-1[56]\d\)"):
        AR(2).fit(y * 1e-160, method="rplr")


def test_a_gate_on_outputs_in_different_units_runs_in_the_signals_units():
    """One R for two outputs in different units: the gate's decisions depend on those
    units, so the recursion runs in them (the filter with the same options, bit for bit)."""
    rng = np.random.default_rng(13)
    u = rng.standard_normal(600)
    Y = np.column_stack([lfilter([0, 1.0], [1, -0.5], u), lfilter([0, 0.3], [1, -0.2], u)])
    Y = (Y + 0.1 * rng.standard_normal(Y.shape)) * [8.0, 0.25]
    m = _fit(lambda: ARX(1, 1), u, Y, method="rls", gate=3.0, lam=0.99)
    f = RecursiveLeastSquares(3, dim_z=2, lam=0.99, gate=3.0, cond_max=m.filter_.cond_max)
    Phi, target = m.regressors(u, Y)
    f.initialize(target[:m.k0_], Phi[:m.k0_])
    means = f.batch_filter(target[m.k0_:], Phi[m.k0_:])[0]
    assert_array_equal(m.theta_history_[m.k0_:], means)
    assert m.filter_ is not None and m.filter_.n_gated == f.n_gated


@pytest.mark.parametrize("options", [dict(), dict(lam=0.99, k0=0, P0=100.0, R=0.25)],
                         ids=["batch-start", "prior"])
def test_rls_on_the_rows_as_they_are_equals_the_run_on_scaled_copies(monkeypatch, options):
    """The covariance-form fit runs on the rows as they are, the powers of two of the
    scaled units applied on the fly (`_scales`); where one of them is not a double it
    scales copies of the rows instead. Both ways give the same bits (forced onto the
    copies, u and y in different units here)."""
    from rlsfilt.models import arx as arx_module
    u, y = _record()
    u = u / 8
    fast = _fit(lambda: ARX(2, 2), u, y, method="rls", **options)
    monkeypatch.setattr(arx_module, "_scales", lambda units: None)
    copies = _fit(lambda: ARX(2, 2), u, y, method="rls", **options)
    for name in ("theta_", "theta_history_", "recursive_residuals_", "residuals_",
                 "noise_variance_", "theta_cov_"):
        assert_array_equal(getattr(fast, name), getattr(copies, name), err_msg=name)
    for name in ("x", "P", "K", "y", "S", "H", "z"):
        assert_array_equal(getattr(fast.filter_, name), getattr(copies.filter_, name),
                           err_msg=name)


def test_rls_near_the_subnormal_range_runs_on_scaled_copies(monkeypatch):
    """A record around 2^-1030 (its scale factor 2^1030 is not a double) runs on scaled
    copies of its rows, and gives the numbers of the same record at unit scale (only its
    bits that survived the scaling): the a and b coefficients (no units when u and y share
    theirs) bit for bit, the residuals mapped by ldexp."""
    from rlsfilt.models import arx as arx_module
    u, y = _record()
    e = -1030
    us, ys = scaled_by(u, 2.0 ** e), scaled_by(y, 2.0 ** e)   # subnormal: low bits rounded
    ref = _fit(lambda: ARX(2, 2), np.ldexp(us, -e), np.ldexp(ys, -e), method="rls")
    calls, run = [], arx_module._run_on_copies
    monkeypatch.setattr(arx_module, "_run_on_copies", lambda *a: calls.append(1) or run(*a))
    tiny = _fit(lambda: ARX(2, 2), us, ys, method="rls")
    assert calls
    assert_array_equal(tiny.theta_history_, ref.theta_history_)
    with np.errstate(under="ignore"):
        assert_array_equal(tiny.recursive_residuals_, np.ldexp(ref.recursive_residuals_, e))
