"""Everything that takes (u, y) also takes an IOData: residual tests, criteria, regressors."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import ARX, IOData, validate
from rlsfilt.datasets import dc_motor, heat_exchanger
from rlsfilt.models import arx_regressors
from rlsfilt.validation import criteria_from_loss, information_criteria, residual_analysis


@pytest.fixture(scope="module")
def exchanger():
    ds = heat_exchanger()
    return ds, ARX(*ds.orders, dt=ds.dt, offset=True).fit(ds)


def test_one_experiment_iodata_equals_the_arrays():
    d = dc_motor(n_samples=600)
    model = ARX(*d.orders, dt=d.dt).fit(d.u, d.y)
    data = IOData(d.u, d.y, dt=d.dt)
    a, b = residual_analysis(model, data, max_lag=20), residual_analysis(model, d.u, d.y, 20)
    assert_array_equal(a.residuals, b.residuals)
    assert_array_equal(a.cross_correlation, b.cross_correlation)
    assert (a.q_statistic, a.f_statistic) == (b.q_statistic, b.f_statistic)
    assert vars(information_criteria(model, data)) == vars(information_criteria(model, d.u, d.y))
    # a Dataset is an IOData too
    assert vars(information_criteria(model, d)) == vars(information_criteria(model, d.u, d.y))


def test_two_experiments_use_the_residuals_of_each_run(exchanger):
    ds, model = exchanger
    # oracle: the one-step residuals of each run from its own regressors, stacked
    resid = []
    for k in range(ds.n_experiments):
        run = ds.getexp(k)
        Phi, target = model.regressors(run.u, run.y)
        resid.append(np.asarray(target) - Phi @ model.theta_)
    e = np.concatenate(resid)
    ic = information_criteria(model, ds)
    ref = criteria_from_loss(np.mean(e ** 2), len(e), model.theta_.size)
    assert ic.n_samples == len(e) == 2000 - 2 * 9
    assert_allclose([ic.loss, ic.aic, ic.bic, ic.fpe], [ref.loss, ref.aic, ref.bic, ref.fpe],
                    rtol=1e-12)
    # not the concatenation treated as one record (its rows straddle the seam)
    glued = information_criteria(model, np.concatenate([ds.getexp(k).u for k in (0, 1)]),
                                 np.concatenate([ds.getexp(k).y for k in (0, 1)]))
    assert glued.n_samples == ic.n_samples + 9
    ra = residual_analysis(model, ds, max_lag=10)
    assert_allclose(ra.residuals, e[:, 0] if e.ndim == 2 else e, rtol=0, atol=1e-12)
    # the same tests as validate runs on the same record
    rep = validate(model, ds, max_lag=10)
    r = rep.residuals[0]
    assert_allclose([ra.q_statistic, ra.f_statistic], [r.q_statistic, r.f_statistic],
                    rtol=1e-12)
    assert_allclose(ra.cross_correlation, r.cross_correlation, rtol=0, atol=1e-14)
    # lists of arrays, one per experiment, are the same record
    us = [np.asarray(ds.getexp(k).u) for k in (0, 1)]
    ys = [np.asarray(ds.getexp(k).y) for k in (0, 1)]
    assert_allclose(residual_analysis(model, us, ys, max_lag=10).q_statistic, ra.q_statistic,
                    rtol=1e-12)
    assert vars(information_criteria(model, us, ys)) == vars(ic)


def test_arrays_without_y_are_refused(exchanger):
    ds, model = exchanger
    with pytest.raises(TypeError, match="`y` is required unless `u` is an IOData"):
        residual_analysis(model, np.asarray(ds.getexp(0).u))
    with pytest.raises(TypeError, match="`y` is required unless `u` is an IOData"):
        information_criteria(model, np.asarray(ds.getexp(0).u))


def test_arx_regressors_of_several_experiments_are_stacked_per_experiment(exchanger):
    ds, model = exchanger
    parts = [arx_regressors(ds.getexp(k).u, ds.getexp(k).y, 2, 2, 8) for k in (0, 1)]
    Phi, target = arx_regressors(ds, na=2, nb=2, nk=8)
    assert_array_equal(Phi, np.vstack([p[0] for p in parts]))
    assert_array_equal(target, np.concatenate([p[1] for p in parts]))
    # the model's own regressors are the same rows (plus its intercept column)
    Phi_m, target_m = model.regressors(ds)
    assert_array_equal(Phi_m[:, :-1], Phi)
    assert_array_equal(target_m, target)
    # start applies to each experiment
    Phi0, _ = arx_regressors(ds, na=2, nb=2, nk=8, start=0)
    assert Phi0.shape == (2000, 4)
    with pytest.raises(TypeError, match="`na` is required"):
        arx_regressors(ds, nb=2)
    with pytest.raises(ValueError, match=r"`start` must be <= N = 800; got 900"):
        arx_regressors(ds, na=2, nb=2, start=900)


def test_signal_names_become_python_control_labels_of_tf_and_ss(exchanger):
    import control
    import pandas as pd

    ds, model = exchanger
    for sys in (model.to_tf(), model.to_ss()):
        assert list(sys.input_labels) == ["flow"] and list(sys.output_labels) == ["T_out"]
    # pandas column names, two inputs: the state-space realization keeps them and
    # simulates as the model does
    rng = np.random.default_rng(3)
    df = pd.DataFrame(rng.standard_normal((400, 2)), columns=["valve", "pump"])
    df["level"] = 0.5 * df["valve"].shift(1, fill_value=0) - 0.2 * df["pump"].shift(2,
                                                                              fill_value=0)
    m = ARX(1, [1, 1], [1, 2]).fit(df[["valve", "pump"]], df["level"])
    ss = m.to_ss()
    assert list(ss.input_labels) == ["valve", "pump"] and list(ss.output_labels) == ["level"]
    T = np.arange(30)
    U = rng.standard_normal((2, 30))
    assert_allclose(control.forced_response(ss, T, U).y[0], m.simulate(U.T), rtol=1e-10,
                    atol=1e-12)
    noise = m.to_ss(noise=True)
    assert list(noise.input_labels) == ["e[level]"]
