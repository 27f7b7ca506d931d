"""The model classes beyond ARX: ARMAX, OE, BJ, AR, ARMA and their streaming forms.

Oracles: transfer functions written by hand in python-control; the k-step
predictor computed by running the model equations with the unknown future
noise set to zero; numpy least squares (AR); the batch recursion (streaming
objects); statsmodels is in test_family_oracles.py.
"""

import pickle
import re
import warnings

import control
import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import (
    AR,
    ARMA,
    ARMAX,
    ARX,
    BJ,
    OE,
    NotFittedError,
    NumericalWarning,
    RecursiveAR,
    RecursiveARMA,
    RecursiveARMAX,
    RecursiveARX,
    RecursiveBJ,
    RecursiveOE,
    validate,
)
from rlsfilt.models import IdentifiedModel, arx_regressors


def armax_data(rng, N=3000, c=(1.0, -1.0, 0.2)):
    u, e = rng.standard_normal(N), rng.standard_normal(N)
    a = [1.0, -1.5, 0.7]
    return u, lfilter([0, 1.0, 0.5], a, u) + lfilter(list(c), a, e), e


def bj_data(rng, N=4000):
    u, e = rng.standard_normal(N), rng.standard_normal(N)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1, 0.5], [1, -0.9], e)
    return u, y


def miso_data(rng, N=4000):
    U = rng.standard_normal((N, 2))
    e = 0.3 * rng.standard_normal(N)
    y = (lfilter([2.0, 1.0], [1, -0.8], U[:, 0]) + lfilter([0, 0, 0.5], [1, -0.5], U[:, 1])
         + lfilter([1, 0.6], [1, -0.7], e))
    return U, y


# ----------------------------------------------------------------------
# MATLAB conventions: parameters, polynomials, transfer functions
# ----------------------------------------------------------------------
def test_classes_are_identified_models():
    for model in (ARMAX(1, 1, 1), OE(1, 1), BJ(1, 1, 1, 1), AR(1), ARMA(1, 1)):
        assert isinstance(model, IdentifiedModel)
    assert repr(ARMAX(2, 2, 1)) == "ARMAX(na=2, nb=2, nc=1, nk=1, dt=True)"
    assert BJ(2, 1, 1, 2, nk=0).get_params() == {"nb": 2, "nc": 1, "nd": 1, "nf": 2, "nk": 0,
                                                 "dt": True}


def test_parameter_order_and_names_follow_matlab(rng):
    U, y = miso_data(rng)
    bj = BJ(nb=[2, 1], nc=1, nd=1, nf=[1, 1], nk=[0, 2]).fit(U, y)
    assert bj.param_names_ == ["b1[u1]", "b2[u1]", "b1[u2]", "c1", "d1", "f1[u1]", "f1[u2]"]
    np.testing.assert_allclose(bj.theta_, [2.0, 1.0, 0.5, 0.6, -0.7, -0.8, -0.5], atol=0.05)
    assert bj.orders_ == {"nb": (2, 1), "nc": 1, "nd": 1, "nf": (1, 1), "nk": (0, 2)}
    p = bj.polydata()
    assert p.A.shape == (1, 1, 1) and p.B.shape == (1, 2, 3) and p.F.shape == (1, 2, 2)
    np.testing.assert_allclose(p.B[0, 1], [0, 0, bj.theta_[2]])
    assert isinstance(bj.b_, list) and len(bj.f_) == 2


def test_to_tf_is_b_over_a_f_with_exact_delays(rng):
    u, y, _ = armax_data(rng)
    m = ARMAX(2, 2, 2, nk=1, dt=0.5).fit(u, y)
    a1, a2, b1, b2, c1, c2 = m.theta_
    G = control.tf([b1, b2], [1, a1, a2], 0.5)
    H = control.tf([1, c1, c2], [1, a1, a2], 0.5)
    for sys, ref in ((m.to_tf(), G), (m.to_tf(noise=True), H)):
        np.testing.assert_allclose(sys.num[0][0].ravel()[-2:], np.ravel(ref.num[0][0])[-2:],
                                   rtol=1e-14)
        np.testing.assert_allclose(np.sort_complex(sys.poles()), np.sort_complex(ref.poles()),
                                   rtol=1e-12)
    # OE with a feed-through and a three-sample delay on two inputs
    U = rng.standard_normal((3000, 2))
    y2 = (lfilter([0.7, 0.2], [1, -0.5], U[:, 0]) + lfilter([0, 0, 0, 1.0], [1, -0.3], U[:, 1])
          + 0.1 * rng.standard_normal(3000))
    oe = OE([2, 1], [1, 1], [0, 3], dt=0.1).fit(U, y2)
    b10, b11, b2, f1, f2 = oe.theta_
    z = np.exp(1j * np.linspace(0.1, 3.0, 5) * 0.1)
    G = oe.to_tf()
    np.testing.assert_allclose(G(z)[0, 0], (b10 + b11 / z) / (1 + f1 / z), rtol=1e-12)
    np.testing.assert_allclose(G(z)[0, 1], b2 * z ** -3 / (1 + f2 / z), rtol=1e-12)
    np.testing.assert_allclose(oe.to_tf(noise=True)(z), np.ones(5), rtol=1e-14)
    bj = BJ(2, 1, 1, 2).fit(*bj_data(rng))
    b1, b2, c1, d1, f1, f2 = bj.theta_
    np.testing.assert_allclose(bj.to_tf(noise=True)(z[0]), (1 + c1 / z[0]) / (1 + d1 / z[0]),
                               rtol=1e-12)


@pytest.mark.parametrize("horizon", [2, 3, 7])
def test_k_step_prediction_runs_the_model_with_future_noise_zero(horizon, rng):
    """yhat(t|t-k): the ARMAX equations A y = B u + C e run from t-k with measured y and
    reconstructed e up to t-k, and e = 0 afterwards (Ljung 1999, sec. 3.2)."""
    u, y, _ = armax_data(rng, N=200)
    m = ARMAX(2, 2, 2).fit(u, y)
    a1, a2, b1, b2, c1, c2 = m.theta_
    eps = y - m.predict(u, y)                # the one-step errors: the innovations estimate
    N = len(y)

    def z(x, t):
        return x[t] if t >= 0 else 0.0

    ref = np.zeros(N)
    for t in range(N):
        yy, ee = {}, {}
        for s in range(t - horizon - 3, t + 1):
            known = s <= t - horizon
            ee[s] = z(eps, s) if known else 0.0
            if known:
                yy[s] = z(y, s)
            else:
                yy[s] = (-a1 * yy[s - 1] - a2 * yy[s - 2] + b1 * z(u, s - 1) + b2 * z(u, s - 2)
                         + ee[s] + c1 * ee[s - 1] + c2 * ee[s - 2])
        ref[t] = yy[t]
    np.testing.assert_allclose(m.predict(u, y, horizon=horizon), ref, rtol=1e-10, atol=1e-10)


def test_simulate_continues_from_known_outputs(rng):
    u, y = bj_data(rng, 500)
    m = OE(2, 2).fit(u, y)
    sim = m.simulate(u, y0=y[:5])
    b1, b2, f1, f2 = m.theta_
    ref = np.zeros(500)
    ref[:5] = y[:5]
    for t in range(5, 500):
        ref[t] = -f1 * ref[t - 1] - f2 * ref[t - 2] + b1 * u[t - 1] + b2 * u[t - 2]
    np.testing.assert_allclose(sim, ref, rtol=1e-10, atol=1e-10)


# ----------------------------------------------------------------------
# what ARX gets wrong and the family gets right
# ----------------------------------------------------------------------
def test_armax_residuals_are_white_where_arx_residuals_are_not(rng):
    u, y, _ = armax_data(rng, N=5000)
    arx = ARX(2, 2, 1).fit(u, y)
    armax = ARMAX(2, 2, 2, 1).fit(u, y)
    assert not validate(arx, u, y).residuals[0].is_white
    rep = validate(armax, u, y)
    assert rep.residuals[0].is_white and rep.residuals[0].is_independent
    assert rep.criteria.bic < validate(arx, u, y).criteria.bic
    assert rep.intervals.contains([-1.5, 0.7, 1.0, 0.5, -1.0, 0.2]).all()


def test_fit_of_an_arx_structure_is_arx_least_squares(rng):
    u, y, _ = armax_data(rng)
    np.testing.assert_allclose(ARMAX(2, 2, 0).fit(u, y).theta_, ARX(2, 2).fit(u, y).theta_,
                               rtol=1e-10)
    Phi, target = arx_regressors(np.zeros(len(y)), y, 2, 1, 1)
    ar = AR(2).fit(y)
    np.testing.assert_allclose(ar.theta_, np.linalg.lstsq(Phi[:, :2], target, rcond=None)[0],
                               rtol=1e-10)


# ----------------------------------------------------------------------
# recursive fits
# ----------------------------------------------------------------------
@pytest.mark.parametrize("method", ["rpem", "rplr"])
def test_recursive_fits_keep_their_history(method, rng):
    u, y, _ = armax_data(rng, N=6000, c=(1.0, 0.5, 0.2))
    m = ARMAX(2, 2, 2).fit(u, y, method=method, lam=1.0)
    assert m.method_ == method
    assert m.theta_history_.shape == (6000, 6)
    np.testing.assert_array_equal(m.theta_history_[-1], m.theta_)
    assert m.recursive_residuals_.shape == (6000,)
    np.testing.assert_allclose(m.theta_, [-1.5, 0.7, 1.0, 0.5, 0.5, 0.2], atol=0.05)
    if method == "rplr":
        assert m.margins_["1/C"][0] > 0
    else:
        with pytest.raises(AttributeError, match="only set by fit\\(..., method='rplr'\\)"):
            m.margins_  # noqa: B018
    batch = ARMAX(2, 2, 2).fit(u, y)
    with pytest.raises(AttributeError, match="only set by fit\\(..., method='rpem' or 'rplr'"):
        batch.theta_history_  # noqa: B018
    assert batch.fit_info_["n_fev"] >= 1


def test_rplr_warns_where_armax_c_is_not_positive_real(rng):
    u, y, _ = armax_data(rng, N=4000, c=(1.0, 1.6, 0.8))
    with pytest.warns(NumericalWarning, match="use method='rpem'") as rec:
        ARMAX(2, 2, 2).fit(u, y, method="rplr")
    assert rec[0].filename == __file__          # the warning points at the caller


def test_recursive_fit_takes_the_filter_options(rng):
    u, y, _ = armax_data(rng, N=2000)
    for opts in (dict(lam=0.99, forgetting="directional"), dict(lam=0.995, Q=1e-6),
                 dict(forgetting="efra", lam=0.99), dict(gate=4.0, R=1.0, P0=100.0)):
        m = OE(2, 2).fit(u, y, method="rpem", **opts)
        assert np.isfinite(m.theta_).all()


# ----------------------------------------------------------------------
# streaming objects
# ----------------------------------------------------------------------
@pytest.mark.parametrize("make, fitted", [
    (lambda: RecursiveARMAX(2, 2, 2, 1), lambda u, y: ARMAX(2, 2, 2).fit(u, y, method="rpem")),
    (lambda: RecursiveOE(2, 2, 1, method="rplr"),
     lambda u, y: OE(2, 2).fit(u, y, method="rplr")),
    (lambda: RecursiveBJ(2, 1, 1, 2, 1), lambda u, y: BJ(2, 1, 1, 2).fit(u, y, method="rpem")),
])
def test_streaming_equals_the_recursive_fit_bit_for_bit(make, fitted, rng):
    u, y = bj_data(rng, 1500)
    est = make()
    preds, thetas = [], []
    for t in range(len(y)):
        yhat, theta = est.step(y[t], u[t])
        preds.append(yhat)
        thetas.append(theta)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)     # rplr's condition is not tested here
        model = fitted(u, y)
    np.testing.assert_array_equal(np.array(thetas), model.theta_history_)
    np.testing.assert_allclose(np.array(preds), y - model.recursive_residuals_, rtol=1e-14,
                               atol=1e-14)
    yhat_b, hist_b = make().batch(y, u)
    np.testing.assert_array_equal(hist_b, model.theta_history_)


def test_streaming_arx_is_recursive_least_squares(rng):
    from rlsfilt import RecursiveLeastSquares

    u, y = bj_data(rng, 800)
    est = RecursiveARX(2, 2, 1, lam=0.99, lam_start=1.0)
    _, hist = est.batch(y, u)
    Phi, target = arx_regressors(u, y, 2, 2, 1, start=0)
    rls = RecursiveLeastSquares(4, lam=0.99)
    np.testing.assert_allclose(hist, rls.batch_filter(target, Phi)[0][:, :, 0], rtol=1e-9,
                               atol=1e-10)


def test_streaming_time_series_and_polynomials(rng):
    e = rng.standard_normal(30000)
    y = lfilter([1, 0.5], [1, -0.8], e)
    arma = RecursiveARMA(1, 1)
    for v in y:
        arma.step(v)
    np.testing.assert_allclose(arma.theta, [-0.8, 0.5], atol=0.03)
    np.testing.assert_allclose(arma.A, [1, arma.theta[0]])
    np.testing.assert_allclose(arma.C, [1, arma.theta[1]])
    ar = RecursiveAR(1)
    ar.batch(y)
    assert ar.n_steps == 30000 and ar.param_names == ["a1"]
    ar.reset()
    assert ar.n_steps == 0 and np.all(ar.theta == 0)


def test_streaming_input_errors():
    est = RecursiveARMAX(1, [1, 1], 1, [1, 1])
    with pytest.raises(ValueError, match="`u` must have 2 entries \\(one per input\\); got 1"):
        est.step(1.0, 0.5)
    with pytest.raises(ValueError, match="`y` must be finite; got nan"):
        est.step(np.nan, [0.0, 0.0])
    with pytest.raises(ValueError, match="`u` must be given: the model has 2 input"):
        est.step(1.0)
    with pytest.raises(ValueError, match="`u` must be omitted"):
        RecursiveAR(2).step(1.0, 3.0)
    with pytest.raises(ValueError, match="`lam` must be in \\(0, 1\\]; got 2.0"):
        RecursiveOE(1, 1, lam=2.0)
    assert est.n_steps == 0


# ----------------------------------------------------------------------
# time series
# ----------------------------------------------------------------------
def test_time_series_models_take_u_none(rng):
    e = rng.standard_normal(3000)
    y = lfilter([1, 0.6], [1, -0.8], e)
    m = ARMA(1, 1).fit(y)
    Phi, target = m.regressors(None, y)
    np.testing.assert_allclose(m.predict(None, y)[m.max_lag:], Phi @ m.theta_, rtol=1e-12)
    np.testing.assert_array_equal(m.simulate(10), np.zeros(10))
    np.testing.assert_array_equal(m.predict(None, y, horizon=np.inf), np.zeros(3000))
    a, c = m.theta_
    H = m.to_tf(noise=True)
    np.testing.assert_allclose(H(2.0), (1 + c / 2) / (1 + a / 2), rtol=1e-13)
    with pytest.raises(ValueError, match="time-series model: it has no input model"):
        m.to_tf(noise=False)
    with pytest.raises(ValueError, match="`u` must have 0 input column"):
        m.predict(np.ones((3000, 1)), y)
    with pytest.raises(ValueError, match="`y` must have shape \\(N,\\)"):
        AR(2).fit(np.ones((100, 2)))


# ----------------------------------------------------------------------
# errors, the fitted check, copies
# ----------------------------------------------------------------------
def test_fit_errors_leave_the_model_unchanged(rng):
    u, y, _ = armax_data(rng, N=500)
    m = ARMAX(1, 1, 1).fit(u, y)
    before = pickle.dumps(m.__dict__)
    with pytest.raises(ValueError, match="`method` must be one of 'pem', 'rpem', 'rplr'"):
        m.fit(u, y, method="els")
    with pytest.raises(TypeError, match="`lam` only applies to method='rpem'/'rplr'"):
        m.fit(u, y, lam=0.99)
    with pytest.raises(TypeError, match="`theta0` only applies to method='pem'"):
        m.fit(u, y, method="rpem", theta0=[0, 0, 0])
    with pytest.raises(TypeError, match="`bogus` is not an option of ARMAX.fit"):
        m.fit(u, y, bogus=1)
    with pytest.raises(ValueError, match="`theta0` must hold n_params = 3 finite values"):
        m.fit(u, y, theta0=[0.0, 1.0])
    with pytest.raises(ValueError, match="`y` must have shape \\(N,\\) \\(one output"):
        m.fit(u, np.column_stack([y, y]))
    with pytest.raises(ValueError, match="`y` must have more than t0 \\+ n_params = 1 \\+ 3"):
        m.fit(u[:4], y[:4])
    with pytest.raises(ValueError, match="`y` must be finite; got inf at index 3"):
        y2 = y.copy()
        y2[3] = np.inf
        m.fit(u, y2)
    with pytest.raises(ValueError, match="not persistently exciting"):
        OE(2, 2).fit(np.zeros(500), y)
    with pytest.raises(ValueError, match="`nc` must be >= 0; got -1"):
        ARMAX(1, 1, -1).fit(u, y)
    assert pickle.dumps(m.__dict__) == before


def test_not_fitted_wording():
    for model in (ARMAX(1, 1, 1), OE(1, 1), BJ(1, 1, 1, 1), AR(1), ARMA(1, 1)):
        name = type(model).__name__
        with pytest.raises(NotFittedError, match=f"^This {name} instance is not fitted yet"):
            model.to_tf(noise=True)
        with pytest.raises(NotFittedError, match="before using `theta_`"):
            model.theta_  # noqa: B018


def test_summary_shows_the_polynomials(rng):
    u, y = bj_data(rng, 2000)
    m = BJ(2, 1, 1, 2).fit(u, y)
    text = str(m.summary())
    assert "y(t) = B(q)/F(q) u(t) + C(q)/D(q) e(t)" in text
    assert re.search(r"B\(q\) = [01]\.\d+ q\^-1 \+ 0\.\d+ q\^-2", text)
    assert re.search(r"F\(q\) = 1 - 1\.\d+ q\^-1 \+ 0\.\d+ q\^-2", text)
    assert "coef" in text and "d1" in text
    assert "<table>" in m._repr_html_()


def test_unexciting_data_does_not_break_the_recursion():
    """Constant input and output: the estimate is not determined, but the recursion (and its
    projection of C into the stability region) runs without error and stays finite; the
    health check (as RecursiveLeastSquares') says once that P lost its conditioning."""
    est = RecursiveARMAX(1, 1, 1, 1)
    with pytest.warns(NumericalWarning, match=r"rpem: `P` is ill-conditioned \(condition "
                                              r"number .* > 1e\+12\) after sample \d+00\. "
                                              r"Lower P0"):
        for _ in range(3000):
            est.step(0.1, 0.2)
    assert np.isfinite(est.theta).all() and np.isfinite(est.P).all()
    m = ARMAX(1, 1, 1).fit(np.full(500, 0.2), np.full(500, 0.1), method="rpem",
                           check_every=0)      # the check off
    assert np.isfinite(m.theta_).all()
    with pytest.warns(NumericalWarning, match="ill-conditioned"):
        ARMAX(1, 1, 1).fit(np.full(500, 0.2), np.full(500, 0.1), method="rpem", cond_max=10.0)
    with pytest.raises(ValueError, match="`check_every` must be"):
        RecursiveARMAX(1, 1, 1, check_every=-1)


@pytest.mark.parametrize("make", [lambda: AR(2, dt=0.5), lambda: ARMA(1, 1),
                                  lambda: ARMA(2, 1)], ids=["AR", "ARMA11", "ARMA21"])
def test_time_series_contract(make, rng):
    """The checks of tests/test_contract_models.py that apply to a time series (no input)."""
    import copy

    y = lfilter([1, 0.4], [1, -1.1, 0.3], rng.standard_normal(800))
    model = make().fit(y)
    assert model.n_params == len(model.param_names_) == len(model.theta_)
    Phi, target = model.regressors(None, y)
    assert len(Phi) == len(y) - model.max_lag
    np.testing.assert_allclose(model.predict(None, y)[model.max_lag:], Phi @ model.theta_,
                               rtol=1e-10, atol=1e-12)
    for other in (copy.deepcopy(model), pickle.loads(pickle.dumps(model))):
        np.testing.assert_array_equal(other.predict(None, y, horizon=2),
                                      model.predict(None, y, horizon=2))
    clone = type(model)(**model.get_params()).fit(y)
    np.testing.assert_array_equal(clone.theta_, model.theta_)
    before = pickle.dumps(model.__dict__)
    bad = y.copy()
    bad[5] = np.nan
    with pytest.raises(ValueError, match="`y`"):
        model.fit(bad)
    with pytest.raises(TypeError, match="is not a parameter of"):
        model.set_params(bogus=1)
    assert pickle.dumps(model.__dict__) == before
    # the noise model H = C/A: its impulse response is lfilter's
    H = model.to_tf(noise=True)
    A, C = model.polydata().A[0, 0], model.polydata().C[0]
    imp = np.zeros(30)
    imp[0] = 1.0
    num, den = np.asarray(H.num[0][0]).ravel(), np.asarray(H.den[0][0]).ravel()
    num = np.r_[np.zeros(len(den) - len(num)), num]
    np.testing.assert_allclose(lfilter(num, den, imp), lfilter(C, A, imp), rtol=1e-12,
                               atol=1e-14)
    import json
    json.dumps(model.to_dict(), allow_nan=False)


def test_save_load_and_iodata(rng, tmp_path):
    """A saved model predicts bit for bit as the original; an IOData record fits as arrays."""
    from rlsfilt import IOData, load_model

    U, y = miso_data(rng, 1500)
    oe = OE([1, 2], [1, 1], [0, 2]).fit(U, y)
    armax = ARMAX(1, 1, 1).fit(U[:, 0], y, method="rpem")
    arma = ARMA(1, 1).fit(y)
    for model, u in ((oe, U), (armax, U[:, 0]), (arma, None)):
        path = tmp_path / f"{type(model).__name__}.json"
        model.save(path)
        back = load_model(path)
        assert type(back) is type(model) and back.param_names_ == model.param_names_
        np.testing.assert_array_equal(back.predict(u, y, horizon=3),
                                      model.predict(u, y, horizon=3))
        np.testing.assert_array_equal(back.theta_cov_, model.theta_cov_)
        assert back.stability_text() == model.stability_text()
    io = IOData(u=U, y=y, input_names=["flow", "valve"], output_names=["T"])
    named = OE([1, 2], [1, 1], [0, 2]).fit(io)
    np.testing.assert_array_equal(named.theta_, oe.theta_)
    assert named.param_names_[0] == "b1[flow]"
    np.testing.assert_array_equal(named.predict(io), oe.predict(U, y))
    # several experiments: one criterion summed over them (tests/test_family_experiments.py)
    two_io = IOData(u=[U[:700, 0], U[700:, 0]], y=[y[:700], y[700:]])
    two = OE(1, 1).fit(two_io)
    assert two.n_experiments_ == 2 and len(two.predict(two_io)) == 2
