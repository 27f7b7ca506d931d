"""rlsfilt.sklearn.RLSRegressor: scikit-learn's own estimator checks, and oracles.

Oracles: numpy lstsq on the ridge-augmented (and, with forgetting, row-weighted)
system, which is what RLS from ``P0 = delta I`` computes exactly; the
RecursiveLeastSquares filter stepped row by row on the same rows (bit for bit).
scikit-learn is part of the ``test`` extra: these tests are never skipped.
"""

import json
import subprocess
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from sklearn.utils.estimator_checks import parametrize_with_checks

from rlsfilt import RecursiveLeastSquares
from rlsfilt.sklearn import RLSRegressor


@parametrize_with_checks([RLSRegressor(), RLSRegressor(lam=0.95, delta=100.0,
                                                        fit_intercept=False)])
def test_sklearn_estimator_checks(estimator, check):
    """Every check of sklearn.utils.estimator_checks.check_estimator passes (none is
    expected to fail)."""
    check(estimator)


def _data(rng, n=60, p=3, targets=None):
    X = rng.standard_normal((n, p)) * [1.0, 3.0, 0.2][:p] + [0.5, -1.0, 2.0][:p]
    coef = np.array([1.5, -0.7, 4.0][:p])
    noise = 0.3 * rng.standard_normal(n if targets is None else (n, targets))
    y = (X @ coef + 2.0)
    y = y + noise if targets is None else y[:, None] * [1.0, -2.0][:targets] + noise
    return X, y


def _lstsq(X, y, lam, delta, intercept):
    """Exponentially weighted, ridge-regularized least squares by numpy lstsq: rows
    weighted by sqrt(lam^(N-k)), the prior rows I / sqrt(delta) by sqrt(lam^N)."""
    N = len(X)
    A = np.hstack([X, np.ones((N, 1))]) if intercept else X
    w = np.sqrt(lam ** np.arange(N - 1, -1, -1.0))
    prior = np.sqrt(lam ** N / delta) * np.eye(A.shape[1])
    Y = y.reshape(N, -1)
    rhs = np.vstack([w[:, None] * Y, np.zeros((A.shape[1], Y.shape[1]))])
    theta = np.linalg.lstsq(np.vstack([w[:, None] * A, prior]), rhs, rcond=None)[0]
    return theta


@pytest.mark.parametrize("lam", [1.0, 0.97])
@pytest.mark.parametrize("intercept", [True, False])
@pytest.mark.parametrize("delta", [1e4, 0.5])
def test_coefficients_equal_weighted_ridge_lstsq(lam, intercept, delta):
    X, y = _data(np.random.default_rng(1))
    reg = RLSRegressor(lam=lam, delta=delta, fit_intercept=intercept).fit(X, y)
    theta = _lstsq(X, y, lam, delta, intercept)[:, 0]
    assert_allclose(reg.coef_, theta[:3], rtol=1e-10, atol=1e-12)
    assert_allclose(reg.intercept_, theta[3] if intercept else 0.0, rtol=1e-10, atol=1e-12)
    Xt = np.random.default_rng(2).standard_normal((5, 3))
    expected = Xt @ theta[:3] + (theta[3] if intercept else 0.0)
    assert_allclose(reg.predict(Xt), expected, rtol=1e-10, atol=1e-12)


def test_equals_the_filter_stepped_row_by_row():
    """fit is the filter's predict/update on each row, [x, 1], from P0 = delta I."""
    X, y = _data(np.random.default_rng(3))
    reg = RLSRegressor(lam=0.98, delta=50.0).fit(X, y)
    rls = RecursiveLeastSquares(4, lam=0.98, P0=50.0)
    for row, target in zip(X, y):
        rls.predict()
        rls.update(target, np.append(row, 1.0))
    assert_array_equal(reg.coef_, rls.x[:3, 0])
    assert reg.intercept_ == rls.x[3, 0]
    assert_array_equal(reg.filter_.P, rls.P)
    assert reg.n_samples_seen_ == len(X)


def test_partial_fit_in_chunks_equals_one_fit():
    X, y = _data(np.random.default_rng(4), n=90)
    whole = RLSRegressor(lam=0.99).fit(X, y)
    chunks = RLSRegressor(lam=0.99)
    for i in range(0, 90, 25):
        chunks.partial_fit(X[i:i + 25], y[i:i + 25])
    assert_array_equal(chunks.coef_, whole.coef_)
    assert chunks.intercept_ == whole.intercept_
    assert chunks.n_samples_seen_ == 90
    # fit starts again from the prior
    assert_array_equal(chunks.fit(X, y).coef_, whole.coef_)


def test_several_targets_equal_one_fit_per_target():
    X, Y = _data(np.random.default_rng(5), targets=2)
    reg = RLSRegressor(lam=0.99).fit(X, Y)
    assert reg.coef_.shape == (2, 3) and reg.intercept_.shape == (2,)
    assert reg.predict(X).shape == (len(X), 2)
    for j in range(2):
        one = RLSRegressor(lam=0.99).fit(X, Y[:, j])
        assert_allclose(reg.coef_[j], one.coef_, rtol=1e-12)
        assert_allclose(reg.intercept_[j], one.intercept_, rtol=1e-12)
    theta = _lstsq(X, Y, 0.99, 1e4, True)
    assert_allclose(reg.coef_, theta[:3].T, rtol=1e-10)


@pytest.mark.parametrize("params, error, message", [
    ({"lam": 1.5}, ValueError, r"`lam` must be in \(0, 1\]; got 1.5"),
    ({"lam": 0.0}, ValueError, r"`lam` must be in \(0, 1\]; got 0.0"),
    ({"delta": 0.0}, ValueError, r"`delta` must be a positive finite number; got 0.0"),
    ({"delta": np.inf}, ValueError, r"`delta` must be a positive finite number; got inf"),
    ({"fit_intercept": "yes"}, TypeError, r"`fit_intercept` must be True or False; got 'yes'"),
])
def test_bad_parameters_are_named(params, error, message):
    X, y = _data(np.random.default_rng(6))
    with pytest.raises(error, match=message):
        RLSRegressor(**params).fit(X, y)
    with pytest.raises(error, match=message):
        RLSRegressor(**params).partial_fit(X, y)


def test_partial_fit_refuses_another_number_of_targets():
    X, Y = _data(np.random.default_rng(7), targets=2)
    reg = RLSRegressor().partial_fit(X, Y[:, 0])
    before = reg.coef_.copy()
    with pytest.raises(ValueError, match=r"`y` has shape \(60, 2\); expected \(n_samples,\)"):
        reg.partial_fit(X, Y)
    reg = RLSRegressor().partial_fit(X, Y)
    with pytest.raises(ValueError, match=r"`y` has shape \(60,\); expected \(n_samples, 2\)"):
        reg.partial_fit(X, Y[:, 0])
    assert_array_equal(RLSRegressor().partial_fit(X, Y[:, 0]).coef_, before)


def test_import_rlsfilt_does_not_import_sklearn_or_river():
    code = ("import json, sys, rlsfilt, rlsfilt.models, rlsfilt.filters, rlsfilt.validation; "
            "print(json.dumps([m for m in ('sklearn', 'river') if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert json.loads(out.strip().splitlines()[-1]) == []
