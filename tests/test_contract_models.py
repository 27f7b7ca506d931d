"""The contract every model class passes (the scikit-learn ``parametrize_with_checks`` idea).

A new model class gets every check below by adding one `ModelCase` to `MODELS`:
a factory of the unfitted model, the record it is fitted on, and whether its fit is
ordinary least squares on its own regressors. Nothing here knows a parameter layout;
the checks use the `IdentifiedModel` interface only. A time-series model (AR, ARMA:
no input) has a record ``(None, y)``; it is fitted by ``fit(y)``, simulated over a
number of samples, and its transfer function is the noise model ``C/(A D)``.
"""

import copy
import pickle
from dataclasses import dataclass, field

import control
import numpy as np
import pytest
from _toy_models import FirstOrderOE
from scipy.signal import lfilter

from rlsfilt import AR, ARMA, ARMAX, ARX, BJ, OE, NotFittedError, compare, fit_percent, validate
from rlsfilt.models import IdentifiedModel


def _siso(seed=1, n=400):
    gen = np.random.default_rng(seed)
    u = gen.standard_normal(n)
    a = [1.0, -1.5, 0.7]
    y = lfilter([0.0, 1.0, 0.5], a, u) + lfilter([1.0], a, 0.1 * gen.standard_normal(n))
    return u, y


def _miso(seed=2, n=400):
    gen = np.random.default_rng(seed)
    u = gen.standard_normal((n, 2))
    a = [1.0, -0.8]
    y = (lfilter([2.0, 1.0], a, u[:, 0]) + lfilter([0.0, 0.5], a, u[:, 1])
         + 0.1 * gen.standard_normal(n))
    return u, y


def _mimo(seed=3, n=400):
    gen = np.random.default_rng(seed)
    u = gen.standard_normal(n)
    y1 = lfilter([0.0, 1.0], [1.0, -0.6], u) + 0.05 * gen.standard_normal(n)
    y2 = lfilter([0.0, 0.5, 0.2], [1.0, -0.3], u) + 0.5 * np.r_[0.0, y1[:-1]] \
        + 0.05 * gen.standard_normal(n)
    return u, np.column_stack([y1, y2])


def _series(seed=5, n=600):
    gen = np.random.default_rng(seed)
    return None, lfilter([1.0, 0.4], [1.0, -1.1, 0.3], gen.standard_normal(n))


def _oe(seed=4, n=600):
    gen = np.random.default_rng(seed)
    u = gen.standard_normal(n)
    return u, lfilter([0.0, 0.5], [1.0, -0.8], u) + 0.1 * gen.standard_normal(n)


@dataclass
class ModelCase:
    """One registered model: ``make()`` an unfitted model, ``data()`` a record ``(u, y)``."""

    name: str
    make: object
    data: object
    fit_kwargs: dict = field(default_factory=dict)
    least_squares: bool = True   # the fit is ordinary least squares on `regressors`

    def fitted(self):
        u, y = self.data()
        return self.fit(self.make(), u, y), u, y

    def fit(self, model, u, y):
        """``fit(u, y)``, or ``fit(y)`` for a time series (``u`` None)."""
        return model.fit(y, **self.fit_kwargs) if u is None else \
            model.fit(u, y, **self.fit_kwargs)


def _sim_input(u, y):
    """What `simulate` takes: the input, or the number of samples of a time series."""
    return len(y) if u is None else u


# --- the registry: one line per model class (and per distinct configuration) ---
MODELS = [
    ModelCase("ARX-siso", lambda: ARX(2, 2, 1, dt=0.1), _siso),
    ModelCase("ARX-feedthrough-2-inputs", lambda: ARX(1, [2, 1], [0, 1]), _miso),
    ModelCase("ARX-2-outputs", lambda: ARX(1, 2, 1, dt=0.5), _mimo),
    ModelCase("ARX-rls", lambda: ARX(2, 2, 1), _siso, {"method": "rls"}),
    ModelCase("ARX-rls-window", lambda: ARX(2, 2, 1), _siso, {"method": "rls", "window": 150},
              least_squares=False),
    ModelCase("ARX-nlms", lambda: ARX(2, 2, 1), _siso, {"method": "nlms", "mu": 0.5},
              least_squares=False),
    ModelCase("ARX-lms-2-outputs", lambda: ARX(1, 2, 1, dt=0.5), _mimo,
              {"method": "lms", "mu": 0.05}, least_squares=False),
    ModelCase("ARX-fir", lambda: ARX(0, 3, 1), _siso),
    ModelCase("FirstOrderOE", lambda: FirstOrderOE(dt=0.2), _oe, least_squares=False),
    ModelCase("ARX-iv", lambda: ARX(2, 2, 1), _siso, {"method": "iv"}, least_squares=False),
    ModelCase("ARX-riv-delayed", lambda: ARX(2, 2, 1), _siso,
              {"method": "riv", "instruments": "delayed"}, least_squares=False),
    ModelCase("ARX-iv-2-outputs", lambda: ARX(1, 2, 1, dt=0.5), _mimo,
              {"method": "iv", "instruments": "delayed"}, least_squares=False),
    # the prediction-error family (time-series AR/ARMA: tests/test_model_family.py)
    ModelCase("ARMAX-pem", lambda: ARMAX(2, 2, 1, 1, dt=0.1), _siso, least_squares=False),
    ModelCase("ARMAX-nc0-is-least-squares", lambda: ARMAX(2, 2, 0, 1), _siso),
    ModelCase("ARMAX-rpem-2-inputs", lambda: ARMAX(1, [2, 1], 1, [0, 1]), _miso,
              {"method": "rpem"}, least_squares=False),
    ModelCase("ARMAX-rplr", lambda: ARMAX(2, 2, 1, 1), _siso, {"method": "rplr", "lam": 0.999},
              least_squares=False),
    ModelCase("OE-pem", lambda: OE(1, 1, 1, dt=0.2), _oe, least_squares=False),
    ModelCase("OE-feedthrough-2-inputs", lambda: OE([2, 2], [1, 1], [0, 1]), _miso,
              least_squares=False),
    ModelCase("OE-rpem", lambda: OE(1, 1, 1), _oe, {"method": "rpem"}, least_squares=False),
    ModelCase("BJ-pem", lambda: BJ(2, 1, 1, 2, 1), _siso, least_squares=False),
    ModelCase("BJ-feedthrough-2-inputs", lambda: BJ([2, 1], 1, 0, [1, 1], [0, 1]), _miso,
              least_squares=False),
    ModelCase("AR-pem-is-least-squares", lambda: AR(2, dt=0.5), _series),
    ModelCase("ARMA-pem", lambda: ARMA(2, 1), _series, least_squares=False),
    ModelCase("ARMA-rpem", lambda: ARMA(1, 1), _series, {"method": "rpem"},
              least_squares=False),
]

cases = pytest.mark.parametrize("case", MODELS, ids=[c.name for c in MODELS])


def _two_d(x):
    x = np.asarray(x, dtype=float)
    return x[:, None] if x.ndim == 1 else x


@cases
def test_is_an_identified_model(case):
    model = case.make()
    assert isinstance(model, IdentifiedModel)
    fitted, u, y = case.fitted()
    assert fitted.n_params == fitted.n_params_ == len(fitted.param_names_)
    assert np.shape(fitted.theta_)[0] == fitted.n_params_
    assert fitted.std_errors_.shape == np.shape(fitted.theta_)


@cases
def test_fit_is_least_squares_on_its_regressors(case):
    if not case.least_squares:
        pytest.skip(f"{case.name} is not fitted by least squares on its regressors")
    model, u, y = case.fitted()
    Phi, target = model.regressors(u, y)
    theta = np.linalg.lstsq(Phi, target, rcond=None)[0]
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-9, atol=1e-12)
    # and the covariance is statsmodels' sigma^2 (Phi' Phi)^-1 with sigma^2 = RSS / (N - d)
    E = _two_d(target) - Phi @ _two_d(theta)
    sigma2 = np.sum(E ** 2, axis=0) / (len(Phi) - Phi.shape[1])
    inv = np.linalg.inv(Phi.T @ Phi)
    cov = np.asarray(model.theta_cov_).reshape(-1, *inv.shape)
    for i, s2 in enumerate(sigma2):
        np.testing.assert_allclose(cov[i], s2 * inv, rtol=1e-7, atol=1e-15)
    np.testing.assert_allclose(model.noise_variance_, sigma2 if len(sigma2) > 1 else sigma2[0],
                               rtol=1e-9)


@cases
def test_one_step_prediction_is_the_regression(case):
    model, u, y = case.fitted()
    Phi, target = model.regressors(u, y)
    L = model.max_lag
    assert len(Phi) == len(target) == len(y) - L
    pred = _two_d(model.predict(u, y, horizon=1))
    np.testing.assert_allclose(pred[L:], Phi @ _two_d(model.theta_), rtol=1e-10, atol=1e-12)
    assert np.shape(model.predict(u, y)) == np.shape(y)


@cases
def test_simulate_is_the_transfer_function(case):
    model, u, y = case.fitted()
    if u is None:   # a time series: to_tf() is the noise model, y = H eps from rest
        _check_noise_model_gives_the_series(model, y)
        return
    G = model.to_tf()
    dt = 1.0 if model.dt is True else model.dt
    T = dt * np.arange(len(u))
    U = _two_d(u)
    sim = _two_d(model.simulate(u))
    # entry by entry with scipy's lfilter (numerator, denominator in powers of z)
    Y = np.zeros_like(sim)
    for i in range(model.n_outputs_):
        for j in range(model.n_inputs_):
            num, den = np.asarray(G.num[i][j]), np.asarray(G.den[i][j])
            num = np.r_[np.zeros(len(den) - len(num)), num]      # same length: powers of z^-1
            Y[:, i] += lfilter(num, den, U[:, j])
    np.testing.assert_allclose(sim, Y, rtol=1e-9, atol=1e-10)
    if model.n_inputs_ == model.n_outputs_ == 1:   # python-control simulates MIMO tf via slycot
        ref = control.forced_response(G, T, U[:, 0]).outputs
        np.testing.assert_allclose(sim[:, 0], ref, rtol=1e-9, atol=1e-10)
    # the state-space realization behaves the same
    ss = control.forced_response(model.to_ss(), T, U.T).outputs
    np.testing.assert_allclose(np.atleast_2d(ss).T, sim, rtol=1e-8, atol=1e-10)
    # an infinite horizon is the simulation
    np.testing.assert_allclose(_two_d(model.predict(u, y, horizon=np.inf)), sim, rtol=1e-12,
                               atol=1e-13)


def _check_noise_model_gives_the_series(model, y):
    """Time series: ``y = C/(A D) eps`` with the one-step prediction errors from rest,
    by scipy's lfilter and by python-control on the transfer function and its state space;
    the free run (an infinite horizon) is zero."""
    eps = y - model.predict(None, y)
    H = model.to_tf()
    num, den = np.asarray(H.num[0][0]).ravel(), np.asarray(H.den[0][0]).ravel()
    num = np.r_[np.zeros(len(den) - len(num)), num]
    np.testing.assert_allclose(lfilter(num, den, eps), y, rtol=1e-9, atol=1e-10)
    dt = 1.0 if model.dt is True else model.dt
    T = dt * np.arange(len(y))
    np.testing.assert_allclose(control.forced_response(H, T, eps).outputs, y, rtol=1e-9,
                               atol=1e-10)
    np.testing.assert_allclose(control.forced_response(model.to_ss(), T, eps).outputs, y,
                               rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(model.simulate(len(y)), np.zeros(len(y)))
    np.testing.assert_array_equal(model.predict(None, y, horizon=np.inf), np.zeros(len(y)))


@cases
def test_no_caller_array_is_written(case):
    u, y = case.data()
    u, y = (None if u is None else np.array(u)), np.array(y)
    for x in (u, y):
        if x is not None:
            x.flags.writeable = False
    u0, y0 = (None if u is None else u.copy()), y.copy()
    model = case.fit(case.make(), u, y)
    model.regressors(u, y)
    model.predict(u, y, horizon=2)
    model.simulate(_sim_input(u, y))
    validate(model, u, y, max_lag=10)
    if u is not None:
        np.testing.assert_array_equal(u, u0)
    np.testing.assert_array_equal(y, y0)


def _state(model):
    return pickle.dumps(model.__dict__)


@cases
def test_rejected_input_leaves_the_model_unchanged(case):
    model, u, y = case.fitted()
    before = _state(model)
    bad = np.array(y, dtype=float)
    bad[len(bad) // 2] = np.nan
    with pytest.raises(ValueError, match="`y`"):
        case.fit(model, u, bad)
    if u is not None:
        with pytest.raises(ValueError, match="same length"):
            model.fit(u, np.asarray(y)[:-3], **case.fit_kwargs)
    if case.least_squares and u is not None:   # no excitation: the regressors lose rank
        with pytest.raises(ValueError, match="not persistently exciting"):
            model.fit(np.zeros_like(u), y, **case.fit_kwargs)
    U = np.zeros((len(y), 1)) if u is None else _two_d(u)
    with pytest.raises(ValueError, match="`u` must have"):
        model.predict(np.column_stack([U, U]), y)
    with pytest.raises(ValueError):
        model.simulate(np.column_stack([U, U]))
    with pytest.raises(TypeError, match="is not a parameter of"):
        model.set_params(bogus=1)
    assert _state(model) == before


@cases
def test_copies_and_pickles_predict_identically(case):
    model, u, y = case.fitted()
    ref = model.predict(u, y, horizon=2)
    for other in (copy.copy(model), copy.deepcopy(model), pickle.loads(pickle.dumps(model))):
        assert type(other) is type(model)
        np.testing.assert_array_equal(other.predict(u, y, horizon=2), ref)
        np.testing.assert_array_equal(other.simulate(_sim_input(u, y)),
                                      model.simulate(_sim_input(u, y)))
        np.testing.assert_array_equal(other.theta_, model.theta_)


@cases
def test_not_fitted_wording(case):
    model = case.make()
    u, y = case.data()
    name = type(model).__name__
    fit_call = r"fit\(y\)" if u is None else r"fit\(u, y\)"
    for what, call in (("predict", lambda m: m.predict(u, y)),
                       ("simulate", lambda m: m.simulate(_sim_input(u, y))),
                       ("regressors", None), ("to_tf", lambda m: m.to_tf()),
                       ("theta_", lambda m: m.theta_), ("param_names_", lambda m: m.param_names_),
                       ("max_lag", lambda m: m.max_lag), ("validate", lambda m: validate(m, u, y))):
        if call is None:
            continue   # ARX builds regressors from its orders alone, without a fit
        with pytest.raises(NotFittedError, match=rf"^This {name} instance is not fitted yet; "
                                                 rf"call `{fit_call}` before using `{what}`"):
            call(model)
    assert "theta_" not in vars(model)


@cases
def test_get_params_set_params_round_trip(case):
    model, u, y = case.fitted()
    params = model.get_params()
    clone = type(model)(**params)
    assert clone.get_params() == params
    refit = case.fit(clone, u, y)
    assert refit is clone
    np.testing.assert_array_equal(refit.theta_, model.theta_)
    assert clone.set_params(**params) is clone and clone.get_params() == params
    # the repr shows every parameter up to dt, and later options (offset, ...) when set
    shown = case.make()._display_params()
    params = case.make().get_params()
    names = list(params)
    cut = names.index("dt") + 1 if "dt" in names else len(names)
    assert set(names[:cut]) <= set(shown) and set(shown) <= set(names)
    assert repr(case.make()) == f"{type(model).__name__}(" + ", ".join(
        f"{k}={v!r}" for k, v in shown.items()) + ")"


@cases
def test_report_of_every_model_is_json_ready(case):
    import json

    model, u, y = case.fitted()
    out = validate(model, u, y, max_lag=10).to_dict()
    assert json.loads(json.dumps(out, allow_nan=False)) == out
    assert out["model"] == type(model).__name__ and out["theta_names"] == model.param_names_


@cases
def test_compare_validate_simulate_and_forced_response_agree(case):
    """Issue #28: under the stated initial condition the simulation fit, the prediction
    fit, ``simulate``/``predict`` and python-control's ``forced_response`` of ``to_ss()``
    tell one story, for every registered class."""
    model, u, y = case.fitted()
    N = len(y)
    dt = 1.0 if model.dt is True else model.dt
    T = dt * np.arange(N)
    ss = model.to_ss()
    U = np.zeros((N, ss.ninputs)) if u is None else _two_d(u)   # a time series: no noise
    # from rest: compare is simulate and predict
    sim0 = compare(model, u, y, initial="zero")
    np.testing.assert_allclose(_two_d(sim0.y_hat),
                               _two_d(model.simulate(_sim_input(u, y))) if u is not None
                               else np.zeros((N, 1)), rtol=1e-10, atol=1e-10)
    for k in (1, 2):
        np.testing.assert_allclose(compare(model, u, y, initial="zero", horizon=k).y_hat,
                                   model.predict(u, y, horizon=k), rtol=1e-10, atol=1e-10)
    # the estimated initial state is a state of to_ss(): forced_response reproduces it
    sim = compare(model, u, y)
    ref = control.forced_response(ss, T, U.T, X0=sim.x0[0]).outputs
    np.testing.assert_allclose(_two_d(sim.y_hat), np.atleast_2d(ref).T, rtol=1e-8, atol=1e-9)
    assert np.all(sim.fit >= sim0.fit - 1e-9)          # the least-squares state is no worse
    # validate reports these fits, and they are fit_percent of what it holds
    rep = validate(model, u, y, max_lag=10)
    assert rep.initial == "estimate" and rep.start == 0
    pred = compare(model, u, y, horizon=1)
    np.testing.assert_array_equal(rep.prediction_fit, pred.fit)
    np.testing.assert_allclose(rep.prediction_fit, fit_percent(y, rep.y_predicted), rtol=1e-12)
    if u is None:
        assert np.isnan(rep.simulation_fit)
        return
    np.testing.assert_array_equal(rep.simulation_fit, sim.fit)
    np.testing.assert_allclose(rep.simulation_fit, fit_percent(y, rep.y_simulated), rtol=1e-12)
    np.testing.assert_allclose(_two_d(rep.y_simulated), np.atleast_2d(ref).T, rtol=1e-8,
                               atol=1e-9)
    A, _, C, D, _ = model.polydata()
    if np.all(A[:, :, 1:] == 0) and np.all(C[:, 1:] == 0) and np.all(D[:, 1:] == 0):
        # no noise model (OE, FIR): the one-step prediction is the simulation
        np.testing.assert_allclose(rep.prediction_fit, rep.simulation_fit, rtol=1e-9)
        np.testing.assert_allclose(rep.y_predicted, rep.y_simulated, rtol=1e-9, atol=1e-9)
