"""ARX on real records: several experiments, IOData, operating points (offset)."""

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX, OperatingPointWarning
from rlsfilt.data import IOData, detrend
from rlsfilt.datasets import heat_exchanger
from rlsfilt.validation import fit_percent

A_TRUE, B_TRUE = [1.0, -1.5, 0.7], [0.0, 1.0, 0.5]


def _run(rng, n, level=0.0, u_level=0.0):
    u = u_level + rng.standard_normal(n)
    e = 0.1 * rng.standard_normal(n)
    y = level + lfilter(B_TRUE, A_TRUE, u - u_level) + lfilter([1.0], A_TRUE, e)
    return u, y


def _rows(u, y, na=2, nb=2, nk=1, const=False):
    """Oracle regressors built by hand: [-y(t-1), -y(t-2), u(t-1), u(t-2)] (+ 1)."""
    t0 = max(na, nk + nb - 1)
    t = np.arange(t0, len(y))
    cols = [-y[t - k] for k in range(1, na + 1)] + [u[t - nk - m] for m in range(nb)]
    if const:
        cols.append(np.ones(len(t)))
    return np.column_stack(cols), y[t]


def _stacked(runs, **kw):
    parts = [_rows(u, y, **kw) for u, y in runs]
    return np.vstack([p[0] for p in parts]), np.concatenate([p[1] for p in parts])


def test_two_experiments_equal_stacked_least_squares(rng):
    runs = [_run(rng, 400), _run(rng, 300, level=3.0)]
    model = ARX(2, 2, 1).fit(IOData([r[0] for r in runs], [r[1] for r in runs]))
    Phi, target = _stacked(runs)
    theta, *_ = np.linalg.lstsq(Phi, target, rcond=None)
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-10)
    resid = target - Phi @ theta
    sigma2 = resid @ resid / (len(target) - 4)
    np.testing.assert_allclose(model.theta_cov_, sigma2 * np.linalg.inv(Phi.T @ Phi),
                               rtol=1e-8)
    assert model.n_samples_ == 400 + 300 - 2 * 2 and model.n_experiments_ == 2
    # lists of arrays are experiments too, and regressors() gives the same stacked rows
    same = ARX(2, 2, 1).fit([r[0] for r in runs], [r[1] for r in runs])
    np.testing.assert_array_equal(same.theta_, model.theta_)
    Phi_m, target_m = model.regressors(IOData([r[0] for r in runs], [r[1] for r in runs]))
    np.testing.assert_array_equal(Phi_m, Phi)
    np.testing.assert_array_equal(target_m, target)
    # fitting the concatenation is a different (wrong) problem: rows straddle the seam
    glued = ARX(2, 2, 1).fit(np.concatenate([r[0] for r in runs]),
                             np.concatenate([r[1] for r in runs]))
    assert np.max(np.abs(glued.theta_ - model.theta_)) > 1e-3


def test_recursive_fit_restarts_regressors_at_each_boundary(rng):
    runs = [_run(rng, 300), _run(rng, 200, level=2.0)]
    data = IOData([r[0] for r in runs], [r[1] for r in runs])
    rls = ARX(2, 2, 1).fit(data, method="rls")
    ls = ARX(2, 2, 1).fit(data)
    np.testing.assert_allclose(rls.theta_, ls.theta_, rtol=1e-9)
    np.testing.assert_allclose(rls.theta_cov_, ls.theta_cov_, rtol=1e-7)
    # the first row of the second experiment uses only that experiment's past
    Phi, target = _stacked(runs)
    k = 300 - 2
    np.testing.assert_array_equal(Phi[k], [-runs[1][1][1], -runs[1][1][0], runs[1][0][1],
                                           runs[1][0][0]])
    expected = target[k] - Phi[k] @ rls.theta_history_[k - 1]
    assert rls.recursive_residuals_[k] == pytest.approx(expected, rel=1e-12)
    assert rls.theta_history_.shape == (len(target), 4)


def test_predict_and_simulate_per_experiment(rng):
    runs = [_run(rng, 120), _run(rng, 80)]
    data = IOData([r[0] for r in runs], [r[1] for r in runs])
    model = ARX(2, 2, 1).fit(data)
    preds, sims = model.predict(data), model.simulate(data)
    assert isinstance(preds, list) and [len(p) for p in preds] == [120, 80]
    for i, (u, y) in enumerate(runs):
        np.testing.assert_array_equal(preds[i], model.predict(u, y))
        np.testing.assert_array_equal(sims[i], model.simulate(u))
    np.testing.assert_array_equal(model.predict(data.getexp(1), horizon=3),
                                  model.predict(*runs[1], horizon=3))
    with pytest.raises(TypeError, match="`y` must be omitted when `u` is an IOData"):
        model.predict(data, runs[0][1])
    with pytest.raises(TypeError, match="`y` is required unless `u` is an IOData"):
        model.predict(runs[0][0])


@pytest.mark.parametrize("method", ["ls", "rls"])
def test_offset_equals_least_squares_with_a_constant_column(rng, method):
    u, y = _run(rng, 500, level=97.0, u_level=40.0)
    model = ARX(2, 2, 1, offset=True).fit(u, y, method=method)
    Phi, target = _rows(u, y, const=True)
    theta, *_ = np.linalg.lstsq(Phi, target, rcond=None)
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-9)
    resid = target - Phi @ theta
    cov = resid @ resid / (len(target) - 5) * np.linalg.inv(Phi.T @ Phi)
    np.testing.assert_allclose(model.theta_cov_, cov, rtol=1e-6)
    assert model.param_names_ == ["a1", "a2", "b1", "b2", "c"]
    assert model.intercept_ == pytest.approx(theta[-1], rel=1e-9)
    # the operating point: the mean input and the equilibrium output there
    a, b, c = theta[:2], theta[2:4], theta[4]
    y_op = (c + b.sum() * u.mean()) / (1 + a.sum())
    np.testing.assert_allclose(model.input_offset_, [u.mean()], rtol=1e-14)
    np.testing.assert_allclose(model.output_offset_, [y_op], rtol=1e-12)
    # predictions in data units: the regression form holds, and a constant input at the
    # operating point keeps the simulation at the equilibrium (no transient from zero)
    np.testing.assert_allclose(model.predict(u, y)[2:], Phi @ model.theta_, rtol=1e-12)
    np.testing.assert_allclose(model.simulate(np.full(50, u.mean())), y_op, rtol=1e-12)


def test_offset_mean_is_fit_on_deviations(rng):
    u, y = _run(rng, 500, level=97.0, u_level=40.0)
    model = ARX(2, 2, 1, offset="mean").fit(u, y)
    Phi, target = _rows(u - u.mean(), y - y.mean())
    theta, *_ = np.linalg.lstsq(Phi, target, rcond=None)
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-10)
    assert model.output_offset_[0] == pytest.approx(y.mean(), rel=1e-14)
    Phi_m, target_m = model.regressors(u, y)
    np.testing.assert_allclose(Phi_m, Phi, rtol=1e-12)
    np.testing.assert_allclose(model.predict(u, y)[2:] - y.mean(), Phi @ theta, rtol=1e-10,
                               atol=1e-12)
    # the same as detrending first, then adding the means back
    dd, trend = detrend(IOData(u, y))
    plain = ARX(2, 2, 1).fit(dd)
    np.testing.assert_allclose(plain.theta_, model.theta_, rtol=1e-12)
    np.testing.assert_allclose(model.simulate(u), plain.simulate(dd.u) + y.mean(), rtol=1e-12)


def test_operating_point_decides_the_answer():
    """The raw exchanger record (97 degC, 40 %) gives a wrong-sign gain and a diverging
    fit without offset handling; either kind of offset recovers the plant."""
    ds = heat_exchanger()
    est, val = ds.getexp(0), ds.getexp(1)
    with pytest.warns(OperatingPointWarning, match=r"ARX.fit: input 'flow' has mean 40.*"
                                                   r"output 'T_out' has mean 96.8.*offset=True"):
        raw = ARX(2, 2, 8, dt=1.0).fit(est)
    assert np.sum(raw.b_) / (1 + np.sum(raw.a_)) > 0          # true gain is -0.6
    for offset in (True, "mean"):
        model = ARX(2, 2, 8, dt=1.0, offset=offset).fit(est)
        gain = np.sum(model.b_) / (1 + np.sum(model.a_))
        assert gain == pytest.approx(-0.6, rel=0.02)
        assert fit_percent(val.y, model.simulate(val.u)) > 75.0
        assert model.input_offset_[0] == pytest.approx(40.0, abs=0.2)
        assert model.output_offset_[0] == pytest.approx(97.0, abs=0.3)
    assert "operating point" in repr(ARX(2, 2, 8, dt=1.0, offset=True).fit(est))


def test_offset_errors_and_repr(rng):
    u, y = _run(rng, 100)
    with pytest.raises(ValueError, match="`offset` must be False, True .* or 'mean' .*; "
                                         "got 'median'"):
        ARX(2, 2, offset="median").fit(u, y)
    assert repr(ARX(2, 2)) == "ARX(na=2, nb=2, nk=1, dt=True)"
    assert repr(ARX(2, 2, offset=True)) == "ARX(na=2, nb=2, nk=1, dt=True, offset=True)"
    model = ARX(2, 2).fit(u, y)
    np.testing.assert_array_equal(model.input_offset_, [0.0])
    assert not hasattr(model, "intercept_")
