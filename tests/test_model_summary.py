"""The coefficient table of model summaries against statsmodels' OLS on the same regressors."""

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX
from rlsfilt.models import ModelSummary
from rlsfilt.models._summary import coefficient_statistics


def _record(rng, n=300, noise=0.3):
    u = rng.standard_normal((n, 2))
    a = [1.0, -1.5, 0.7]
    y = (lfilter([0.0, 1.0, 0.5], a, u[:, 0]) + lfilter([0.0, 0.0, 0.3], a, u[:, 1])
         + lfilter([1.0], a, noise * rng.standard_normal(n)))
    return u, y


def test_table_equals_statsmodels_ols(rng):
    sm = pytest.importorskip("statsmodels.api")
    u, y = _record(rng)
    model = ARX(2, [2, 1], [1, 2]).fit(u, y)
    Phi, target = model.regressors(u, y)
    ols = sm.OLS(target, Phi).fit()
    tab = model.summary().table
    assert tab["names"] == ["a1", "a2", "b1[u1]", "b2[u1]", "b1[u2]"]
    assert tab["dof"] == ols.df_resid
    np.testing.assert_allclose(tab["coef"][:, 0], ols.params, rtol=1e-11)
    np.testing.assert_allclose(tab["std_err"][:, 0], ols.bse, rtol=1e-9)
    np.testing.assert_allclose(tab["t"][:, 0], ols.tvalues, rtol=1e-9)
    # small p-values only agree relatively where they are representable
    np.testing.assert_allclose(tab["pvalue"][:, 0], ols.pvalues, rtol=1e-7, atol=1e-300)
    ci = ols.conf_int(alpha=0.05)
    np.testing.assert_allclose(tab["lower"][:, 0], ci[:, 0], rtol=1e-9)
    np.testing.assert_allclose(tab["upper"][:, 0], ci[:, 1], rtol=1e-9)


def test_table_of_each_output_equals_its_own_ols(rng):
    sm = pytest.importorskip("statsmodels.api")
    u, y1 = _record(rng)
    y2 = np.roll(y1, 3) + 0.2 * rng.standard_normal(len(y1))
    Y = np.column_stack([y1, y2])
    model = ARX(1, 2, 1).fit(u, Y)
    Phi, target = model.regressors(u, Y)
    tab = model.summary().table
    for i in range(2):
        ols = sm.OLS(target[:, i], Phi).fit()
        np.testing.assert_allclose(tab["coef"][:, i], ols.params, rtol=1e-10)
        np.testing.assert_allclose(tab["std_err"][:, i], ols.bse, rtol=1e-9)
        np.testing.assert_allclose(tab["pvalue"][:, i], ols.pvalues, rtol=1e-7, atol=1e-300)
    text = str(model.summary())
    assert "output y1" in text and "output y2" in text


def test_text_and_html_columns(rng):
    u, y = _record(rng)
    model = ARX(2, 2, 1).fit(u[:, 0], y)
    summ = model.summary()
    assert isinstance(summ, ModelSummary)
    text = str(summ)
    head = next(line for line in text.splitlines() if "coef" in line)
    assert head.split() == ["coef", "std", "err", "t", "P>|t|", "[0.025", "0.975]"]
    tab = summ.table
    row = next(line for line in text.splitlines() if line.split()[:1] == ["a1"]).split()
    assert len(row) == 7
    assert float(row[1]) == pytest.approx(tab["coef"][0, 0], rel=1e-5)
    assert float(row[5]) == pytest.approx(tab["lower"][0, 0], rel=1e-5)
    assert f"t distribution with {tab['dof']} degrees of freedom" in text
    page = summ._repr_html_()
    for col in ("coef", "std err", "P&gt;|t|", "[0.025", "0.975]"):
        assert f"<th>{col}</th>" in page


def test_exact_fit_and_given_coefficients_keep_the_columns(rng):
    """Noise-free data: standard errors near round-off, t near 1e15, the row keeps 7 fields;
    given coefficients: zero standard errors, a zero-width interval, no p-value."""
    u = rng.standard_normal(200)
    model = ARX(1, 1).fit(u, lfilter([0.0, 1.0], [1.0, -0.5], u))
    row = next(line for line in str(model.summary()).splitlines()
               if line.split()[:1] == ["a1"]).split()
    assert len(row) == 7
    true = ARX.from_polynomials([-0.5], [1.0])
    tab = true.summary().table
    np.testing.assert_array_equal(tab["lower"], tab["coef"])
    assert np.all(np.isnan(tab["pvalue"]))
    assert np.all(np.isinf(tab["t"]))


def test_coefficient_statistics_closed_forms():
    from scipy import stats

    out = coefficient_statistics(np.array([2.0, -1.0, 0.0]), np.array([1.0, 0.5, 0.0]), dof=10,
                                 level=0.9)
    q = stats.t.ppf(0.95, 10)
    np.testing.assert_allclose(out["t"][:2], [2.0, -2.0])
    assert np.isnan(out["t"][2])
    np.testing.assert_allclose(out["pvalue"][:2], 2 * stats.t.sf(2.0, 10), rtol=1e-14)
    np.testing.assert_allclose(out["lower"], [2 - q, -1 - 0.5 * q, 0.0], rtol=1e-14)
    assert out["quantile"] == pytest.approx(q, rel=1e-14)
    assert np.isnan(out["pvalue"][2])                 # 0 / 0: nothing to test
    # an exact fit (zero standard error): t is infinite and P>|t| is its limit 0
    # (statsmodels leaves round-off in the standard error and reports about 1e-89)
    exact = coefficient_statistics(np.array([3.0, -2.0]), np.zeros(2), dof=5)
    assert np.array_equal(exact["t"], [np.inf, -np.inf])
    assert np.array_equal(exact["pvalue"], [0.0, 0.0])
    assert np.array_equal(exact["lower"], exact["upper"])
    none = coefficient_statistics(np.array([1.0]), np.array([0.1]), dof=0)
    assert none["quantile"] == np.inf and np.isnan(none["pvalue"][0]) and np.isnan(none["t"][0])
