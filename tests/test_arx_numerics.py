"""High-order recursive fits: the square-root form keeps ARX.fit(method='rls') on batch LS."""

import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX, NumericalWarning, RecursiveLeastSquares, SquareRootRLS
from rlsfilt._scale import unit_columns
from rlsfilt.models.regressors import arx_regressors


def _resonant_record(seed=1, n=4000):
    """A lightly damped plant (pole pairs at radius 0.995 and 0.99) driven by a colored input:
    high-order ARX regressors with condition numbers 1e6 .. 1e8."""
    rng = np.random.default_rng(seed)
    p = np.array([0.995 * np.exp(0.05j), 0.99 * np.exp(0.3j)])
    A = np.real(np.poly(np.r_[p, p.conj()]))
    u = lfilter([1.0], [1.0, -0.9], rng.standard_normal(n))
    y = lfilter([0, 1.0, 0.5, 0.2, 0.1], A, u) + 0.01 * rng.standard_normal(n)
    return u, y


def _rel(a, b):
    return np.max(np.abs(a - b)) / np.max(np.abs(b))


@pytest.mark.parametrize("order", [6, 10, 12, 16])
def test_high_order_recursive_fit_equals_batch_least_squares(order):
    u, y = _resonant_record()
    Phi, _ = arx_regressors(u, y, order, order, 1)
    cond = np.linalg.cond(unit_columns(Phi))
    assert 1e6 < cond < 1e8 and np.linalg.cond(Phi) > 5e6
    ls = ARX(order, order, 1).fit(u, y)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rls = ARX(order, order, 1).fit(u, y, method="rls")
    assert rls.form_ == "square_root" and isinstance(rls.filter_, SquareRootRLS)
    assert _rel(rls.theta_, ls.theta_) < 1e-8
    assert _rel(rls.theta_cov_, ls.theta_cov_) < 1e-8
    assert rls.to_dict()["form"] == "square_root"


def test_well_conditioned_fits_keep_the_covariance_form(rng):
    u = rng.standard_normal(800)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.1 * rng.standard_normal(800)
    cov = ARX(2, 2, 1).fit(u, y, method="rls")
    assert cov.form_ == "covariance" and isinstance(cov.filter_, RecursiveLeastSquares)
    sqrt = ARX(2, 2, 1).fit(u, y, method="rls", form="square_root")
    np.testing.assert_allclose(sqrt.theta_, cov.theta_, rtol=1e-10)
    np.testing.assert_allclose(sqrt.theta_history_[5:], cov.theta_history_[5:], rtol=1e-8,
                               atol=1e-10)
    # exponential forgetting: both forms compute the same weighted least squares
    f1 = ARX(2, 2, 1).fit(u, y, method="rls", lam=0.99, form="covariance")
    f2 = ARX(2, 2, 1).fit(u, y, method="rls", lam=0.99, form="square_root")
    np.testing.assert_allclose(f2.theta_, f1.theta_, rtol=1e-9)
    assert f2.lam_ == 0.99 and "lam=0.99" in repr(f2)


def test_warns_when_the_recursion_cannot_be_trusted():
    u, y = _resonant_record()
    with pytest.warns(NumericalWarning, match=r"ill-conditioned \(condition number 8.6e\+06\): "
                                              r"the covariance-form recursion may drift.*"
                                              r"form='covariance' was asked for"):
        ARX(12, 12, 1).fit(u, y, method="rls", form="covariance")
    with pytest.warns(NumericalWarning, match="`Q` rules out the square-root form"):
        model = ARX(12, 12, 1).fit(u, y, method="rls", Q=1e-12)
    assert model.form_ == "covariance"
    # beyond 1e10 even the square-root form loses digits, and says so
    rng = np.random.default_rng(0)
    w = lfilter([1.0], np.poly([0.995] * 3), rng.standard_normal(3000))
    v = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], w) + 1e-4 * rng.standard_normal(3000)
    with pytest.warns(NumericalWarning, match=r"even the square-root recursion keeps only "
                                              r"about \d+ digits"):
        ARX(3, 3, 1).fit(w, v, method="rls")


def test_form_errors():
    u, y = _resonant_record(n=300)
    with pytest.raises(ValueError, match="`form` must be 'auto', 'covariance' or "
                                         "'square_root'; got 'qr'"):
        ARX(2, 2, 1).fit(u, y, method="rls", form="qr")
    with pytest.raises(TypeError, match="form='square_root' .* takes lam, P0, x0, R, "
                                        "check_every and cond_max only; got `forgetting`"):
        ARX(2, 2, 1).fit(u, y, method="rls", form="square_root", forgetting="directional")
    with pytest.raises(TypeError, match="`form` only applies to method='rls'"):
        ARX(2, 2, 1).fit(u, y, form="square_root")


def _conditioned_rows(rng, rows, n, cond):
    """Rows ``U diag(s) V^T`` with singular values from 1 down to 1/cond, then columns
    multiplied by factors up to 1e3 apart (so the raw and the unit-column condition
    numbers differ)."""
    U, _ = np.linalg.qr(rng.standard_normal((rows, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    s = np.geomspace(1.0, 1.0 / cond, n)
    return (U * s) @ V.T * 10.0 ** rng.uniform(-1.5, 1.5, n)


def _decisions(cond, cond_raw):
    """Everything `_choose_form` and `_fit_rls` decide from the condition numbers: the
    thresholds of the form and of both warnings, and the health check's `cond_max`."""
    from rlsfilt.models.arx import _COND_ANY, _COND_AUTO, _COND_COVARIANCE
    return (cond > _COND_AUTO, cond > _COND_COVARIANCE, cond > _COND_ANY,
            max(1e12, 1e4 * cond_raw ** 2))


@pytest.mark.parametrize("n", [2, 4, 9])
def test_gram_condition_bound_takes_the_decisions_of_the_exact_qr(n):
    """The Gram matrix bound of `_condition_numbers` (the fast path of every recursive fit)
    against the exact condition numbers from QR, over records with condition numbers
    from 1 to 1e12 (dense around the thresholds 5e3 .. 1e4 and 1e6, 1e10): the same
    decisions; where the bound is used it is an upper bound within 1 % of the exact value,
    else the exact values themselves are returned."""
    from rlsfilt.models.arx import _condition_numbers, _exact_condition_numbers
    rng = np.random.default_rng(12)
    conds = np.r_[np.geomspace(1.0, 1e12, 60), np.geomspace(2e3, 2e4, 40),
                  np.geomspace(5e5, 2e6, 10), np.geomspace(5e9, 2e10, 10)]
    fast = 0
    for cond in conds:
        for scale in (1.0, 2.0 ** -600, 2.0 ** 530):   # a Gram under- or overflowing
            Phi = _conditioned_rows(rng, 600, n, cond) * scale
            got, exact = _condition_numbers(Phi), _exact_condition_numbers(Phi)
            assert _decisions(*got) == _decisions(*exact), (cond, got, exact)
            if got != exact:
                fast += 1
                assert got[0] <= 5e3 and got[1] <= 1e4 and scale == 1.0
                np.testing.assert_array_less(exact, np.array(got) * (1 + 1e-12))
                # the bound's slack: 8 (rows + n) eps n cond^2 <= 5e-4 on the fast path
                np.testing.assert_allclose(got, exact, rtol=1e-3)
            elif scale == 1.0:     # the bound decides every record well below the thresholds
                assert exact[0] > 4.9e3 or exact[1] > 0.99e4, (cond, exact)
    assert fast >= 5


def test_gram_condition_bound_of_degenerate_rows():
    """A zero column, a single row and rows in the signals' units without scaling take the
    exact path (infinite condition numbers where QR finds them)."""
    from rlsfilt.models.arx import _condition_numbers, _exact_condition_numbers
    rng = np.random.default_rng(3)
    Phi = rng.standard_normal((50, 3))
    Phi[:, 1] = 0.0
    assert _condition_numbers(Phi) == _exact_condition_numbers(Phi)
    assert _condition_numbers(Phi)[0] == np.inf
    one = rng.standard_normal((1, 3))
    assert _condition_numbers(one) == _exact_condition_numbers(one)
    wide = rng.standard_normal((50, 3)) * np.array([1e-3, 1.0, 1e3])   # cond_raw ~ 1e6
    assert _condition_numbers(wide) == _exact_condition_numbers(wide)
    # columns 30 apart (cond_raw ~ 30 to 1e3 < 1e4, which leaves cond_max at 1e12): the bound
    apart = rng.standard_normal((500, 3)) * np.array([1.0, 30.0, 0.3])
    got, exact = _condition_numbers(apart), _exact_condition_numbers(apart)
    assert got != exact and got[1] <= 1e4
    np.testing.assert_allclose(got, exact, rtol=1e-3)


def test_gram_condition_bound_with_exponents_is_that_of_the_scaled_rows():
    """With `exponents` the bound is that of ``Phi 2^exponents`` without the scaled copy:
    the same decision as on the copy, and a column whose scaled Gram entry underflows
    (far below its signal's size) takes the exact path on the copy, not a NaN bound."""
    from rlsfilt._scale import times_pow2
    from rlsfilt.models.arx import _condition_numbers, _exact_condition_numbers
    rng = np.random.default_rng(5)
    Phi = rng.standard_normal((400, 3)) * np.array([2.0 ** 40, 1.0, 2.0 ** -30])
    e = np.array([-41, 0, 29])
    got, on_copy = _condition_numbers(Phi, e), _condition_numbers(times_pow2(Phi, e))
    assert got[1] <= 1e4 and got != _exact_condition_numbers(times_pow2(Phi, e))
    np.testing.assert_allclose(got, on_copy, rtol=1e-12)
    tiny = rng.standard_normal((400, 3)) * np.array([1.0, 1e-100, 1.0])
    e = np.array([0, -1000, 0])           # the column's signal around 2^1000: its entry underflows
    with np.errstate(under="ignore"):
        expected = _exact_condition_numbers(times_pow2(tiny, e))
        assert _condition_numbers(tiny, e) == expected
    assert expected[0] == np.inf
