"""ARX: regressors, batch and recursive fits, prediction, simulation and the control bridge.

Every number is checked against an independent oracle: numpy's lstsq on
regressors built here by hand, scipy.signal.lfilter, control.forced_response,
closed-form polynomial identities, or a brute-force loop.
"""

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from rlsfilt import ARX, RecursiveLeastSquares
from rlsfilt.models import arx_regressors


# ----------------------------------------------------------------------
# helpers (independent of the implementation)
# ----------------------------------------------------------------------
def hand_regressors(u, y, na, nb, nk):
    """Rows [-y_1(t-1..t-na), ..., u_1(t-nk..t-nk-nb+1), ...] written as a plain loop."""
    U = u.reshape(len(u), -1)
    Y = y.reshape(len(y), -1)
    nu, ny = U.shape[1], Y.shape[1]
    nb = [nb] * nu if np.isscalar(nb) else list(nb)
    nk = [nk] * nu if np.isscalar(nk) else list(nk)
    t0 = max([na] + [k + b - 1 for b, k in zip(nb, nk)])
    rows = []
    for t in range(t0, len(U)):
        row = []
        for i in range(ny):
            row += [-Y[t - k, i] for k in range(1, na + 1)]
        for j in range(nu):
            row += [U[t - k, j] for k in range(nk[j], nk[j] + nb[j])]
        rows.append(row)
    return np.array(rows), y[t0:]


def arx_data(rng, a, b, nk, n=400, noise_std=0.1):
    """SISO data from A(q) y = q^-nk B(q) u + e with a white-noise input."""
    u = rng.standard_normal(n)
    A = np.r_[1.0, a]
    B = np.r_[np.zeros(nk), b]
    e = noise_std * rng.standard_normal(n)
    return u, signal.lfilter(B, A, u) + signal.lfilter([1.0], A, e)


def padded(model):
    """(num, den) of a SISO model in positive powers of z, padded to equal length."""
    A = np.r_[1.0, model.a_]
    B = np.r_[np.zeros(model.nk), model.b_]
    n = max(len(A), len(B))
    return np.r_[B, np.zeros(n - len(B))], np.r_[A, np.zeros(n - len(A))]


STRUCTURES = [  # (a, b, nk): includes feed-through, long delays, FIR, nb > na
    ([-1.5, 0.7], [1.0, 0.5], 1),
    ([-0.8], [0.4, -0.2, 0.1], 0),
    ([-1.2, 0.5, -0.1], [0.3], 3),
    ([], [1.0, 0.5, 0.25], 2),
    ([0.5], [2.0], 0),
    ([], [2.0], 0),  # a static gain: no state at all
]


# ----------------------------------------------------------------------
# regressors
# ----------------------------------------------------------------------
def test_regressor_layout_documented_example():
    u = np.arange(6.0)
    y = 10.0 * np.arange(6.0)
    Phi, target = ARX(na=2, nb=2, nk=1).regressors(u, y)
    # rows t = 2..5: [-y(t-1), -y(t-2), u(t-1), u(t-2)]
    expected = np.array([[-10, 0, 1, 0], [-20, -10, 2, 1], [-30, -20, 3, 2], [-40, -30, 4, 3]])
    np.testing.assert_array_equal(Phi, expected)
    np.testing.assert_array_equal(target, [20, 30, 40, 50])


@pytest.mark.parametrize("na, nb, nk", [(2, 2, 1), (1, 3, 0), (3, 1, 4), (0, 2, 2), (2, 3, 0)])
def test_regressors_match_hand_built(rng, na, nb, nk):
    u, y = rng.standard_normal(30), rng.standard_normal(30)
    Phi, target = ARX(na, nb, nk).regressors(u, y)
    Phi_h, target_h = hand_regressors(u, y, na, nb, nk)
    np.testing.assert_array_equal(Phi, Phi_h)
    np.testing.assert_array_equal(target, target_h)
    assert len(Phi) == 30 - max(na, nk + nb - 1)
    Phi_f, target_f = arx_regressors(u, y, na, nb, nk)
    np.testing.assert_array_equal(Phi_f, Phi)


def test_regressors_miso_mimo_layout(rng):
    u, y = rng.standard_normal((25, 2)), rng.standard_normal((25, 3))
    Phi, target = ARX(2, [1, 3], [0, 2]).regressors(u, y)
    Phi_h, target_h = hand_regressors(u, y, 2, [1, 3], [0, 2])
    np.testing.assert_array_equal(Phi, Phi_h)
    np.testing.assert_array_equal(target, target_h)
    assert Phi.shape == (25 - 4, 3 * 2 + 4) and target.shape == (21, 3)


def test_regressors_from_start_zero_pad(rng):
    u, y = rng.standard_normal(10), rng.standard_normal(10)
    Phi, target = arx_regressors(u, y, 2, 2, 1, start=0)
    up, yp = np.r_[0, 0, u], np.r_[0, 0, y]
    Phi_h, _ = hand_regressors(up, yp, 2, 2, 1)
    np.testing.assert_array_equal(Phi, Phi_h)
    np.testing.assert_array_equal(target, y)


# ----------------------------------------------------------------------
# batch fit
# ----------------------------------------------------------------------
@pytest.mark.parametrize("a, b, nk", STRUCTURES)
def test_fit_equals_lstsq_on_documented_regressors(rng, a, b, nk):
    u, y = arx_data(rng, a, b, nk)
    model = ARX(len(a), len(b), nk).fit(u, y)
    Phi, target = hand_regressors(u, y, len(a), len(b), nk)
    theta, res, _, _ = np.linalg.lstsq(Phi, target, rcond=None)
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(model.a_, theta[:len(a)], rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(model.b_, theta[len(a):], rtol=1e-10, atol=1e-12)
    dof = len(Phi) - len(theta)
    sigma2 = res[0] / dof
    assert model.noise_variance_ == pytest.approx(sigma2, rel=1e-10)
    np.testing.assert_allclose(model.theta_cov_, sigma2 * np.linalg.inv(Phi.T @ Phi), rtol=1e-8)
    np.testing.assert_allclose(model.residuals_, target - Phi @ theta, atol=1e-12)
    assert model.n_samples_ == len(Phi)
    assert model.n_params == model.n_params_ == len(theta)


@pytest.mark.parametrize("a, b, nk", STRUCTURES)
def test_fit_matches_statsmodels_ardl(rng, a, b, nk):
    """An independent implementation: statsmodels' ARDL (OLS) gives theta and standard errors."""
    ardl = pytest.importorskip("statsmodels.tsa.ardl")
    u, y = arx_data(rng, a, b, nk, n=300)
    model = ARX(len(a), len(b), nk).fit(u, y)
    res = ardl.ARDL(y, len(a), u[:, None], order={0: list(range(nk, nk + len(b)))},
                    trend="n").fit()
    sign = np.r_[-np.ones(len(a)), np.ones(len(b))]  # ARDL writes +phi y(t-i)
    np.testing.assert_allclose(model.theta_, sign * res.params, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(model.std_errors_, res.bse, rtol=1e-8)
    rows = len(res.resid)  # (ARDL's `nobs` counts from the AR lags only)
    assert model.n_samples_ == rows
    assert model.noise_variance_ == pytest.approx(res.ssr / (rows - len(res.params)), rel=1e-9)


def test_miso_matches_statsmodels_ardl(rng):
    ardl = pytest.importorskip("statsmodels.tsa.ardl")
    u = rng.standard_normal((300, 2))
    y = (signal.lfilter([0.5], [1, -0.8], u[:, 0]) + signal.lfilter([0, 0, 0, 1.0, -0.5],
                                                                  [1, -0.8], u[:, 1])
         + 0.1 * rng.standard_normal(300))
    model = ARX(1, [1, 2], [0, 3]).fit(u, y)
    res = ardl.ARDL(y, 1, u, order={0: [0], 1: [3, 4]}, trend="n").fit()
    np.testing.assert_allclose(model.theta_, [-1, 1, 1, 1] * res.params, rtol=1e-9)
    np.testing.assert_allclose(model.std_errors_, res.bse, rtol=1e-8)


def test_fit_returns_self_and_init_only_stores():
    model = ARX(2, 2)
    assert vars(model) == {"na": 2, "nb": 2, "nk": 1, "dt": True, "offset": False}
    u = np.random.default_rng(1).standard_normal(50)
    assert model.fit(u, np.sin(np.arange(50.0)) + u ** 2) is model
    assert model.get_params() == {"na": 2, "nb": 2, "nk": 1, "dt": True, "offset": False}
    assert model.set_params(na=3) is model and model.na == 3


def test_noiseless_recovery_is_exact(rng):
    a, b, nk = [-1.5, 0.7], [1.0, 0.5], 2
    u, y = arx_data(rng, a, b, nk, n=100, noise_std=0.0)
    model = ARX(2, 2, nk).fit(u, y)
    np.testing.assert_allclose(model.theta_, a + b, rtol=1e-11, atol=1e-12)


def test_lecture_notes_feedthrough_form(rng):
    """The notes' y[k] = -a1 y[k-1] - .. + b0 u[k] + .. + bn u[k-n] is ARX(n, n+1, 0)."""
    n, N = 2, 300
    a = np.array([-1.1, 0.3])
    bn = np.array([0.7, -0.4, 0.2])  # b0, b1, b2
    u = rng.standard_normal(N)
    y = np.zeros(N)
    for k in range(N):  # the notes' recursion, zero before k = 0
        y[k] = sum(-a[i - 1] * y[k - i] for i in range(1, n + 1) if k - i >= 0) + sum(
            bn[i] * u[k - i] for i in range(n + 1) if k - i >= 0)
    model = ARX(na=n, nb=n + 1, nk=0).fit(u, y)
    np.testing.assert_allclose(model.a_, a, atol=1e-12)
    np.testing.assert_allclose(model.b_, bn, atol=1e-12)   # our b1 is the notes' b0
    G = model.to_tf()
    # feed-through kept: G(inf) = b0, the impulse response starts with b0 at k = 0
    assert G.num[0][0][0] / G.den[0][0][0] == pytest.approx(bn[0], rel=1e-12)
    imp = control.impulse_response(G, T=np.arange(5.0)).outputs
    np.testing.assert_allclose(imp, signal.lfilter(bn, np.r_[1, a], np.r_[1.0, np.zeros(4)]),
                               atol=1e-12)
    assert model.to_ss().D[0, 0] == pytest.approx(bn[0], rel=1e-12)
    np.testing.assert_allclose(model.simulate(u), y, atol=1e-10)
    assert "0.7 (+/-" in str(model.summary()) and "u(t) " in str(model.summary())


# ----------------------------------------------------------------------
# simulation and the python-control / scipy bridge
# ----------------------------------------------------------------------
@pytest.mark.parametrize("a, b, nk", STRUCTURES)
def test_simulate_equals_lfilter_and_forced_response(rng, a, b, nk):
    u, y = arx_data(rng, a, b, nk, n=300)
    model = ARX(len(a), len(b), nk, dt=0.1).fit(u, y)
    num, den = padded(model)
    y_sim = model.simulate(u)
    np.testing.assert_allclose(y_sim, signal.lfilter(num, den, u), rtol=0, atol=1e-9)
    T = 0.1 * np.arange(len(u))
    resp = control.forced_response(model.to_tf(), T, u)
    np.testing.assert_allclose(resp.outputs, y_sim, rtol=0, atol=1e-9)
    resp_ss = control.forced_response(model.to_ss(), T, u)
    np.testing.assert_allclose(resp_ss.outputs, y_sim, rtol=0, atol=1e-9)
    _, y_dlti = signal.dlsim(model.to_dlti(), u, t=T)
    np.testing.assert_allclose(y_dlti[:, 0], y_sim, rtol=0, atol=1e-9)


@pytest.mark.parametrize("a, b, nk", STRUCTURES)
def test_to_tf_poles_and_dc_gain(rng, a, b, nk):
    model = ARX.from_polynomials(a, b, nk=nk, dt=0.5)
    G = model.to_tf()
    assert G.dt == 0.5
    num, den = padded(model)
    assert len(G.den[0][0]) == len(den)
    expected_poles = np.r_[np.roots(np.r_[1.0, a]), np.zeros(len(den) - 1 - len(a))]
    np.testing.assert_allclose(np.sort_complex(G.poles()), np.sort_complex(expected_poles),
                               atol=1e-9)
    A, B = model.polynomials()  # MATLAB's form for one input and one output
    np.testing.assert_array_equal(A, np.r_[1.0, a])
    np.testing.assert_array_equal(B, np.r_[np.zeros(nk), b])
    dc = np.sum(b) / (1.0 + np.sum(a))
    assert complex(G.dcgain()).real == pytest.approx(dc, rel=1e-12)
    assert complex(G(1.0)).real == pytest.approx(dc, rel=1e-12)


def test_to_tf_with_unspecified_dt_and_noise_model(rng):
    model = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=3)
    assert model.to_tf().dt is True and model.to_ss().dt is True
    H = model.to_tf(noise=True)
    imp = control.impulse_response(H, T=np.arange(20.0)).outputs
    np.testing.assert_allclose(imp, signal.lfilter([1.0], [1, -1.5, 0.7], np.eye(20)[0]),
                               atol=1e-12)
    _, h2 = signal.dimpulse(model.to_dlti(noise=True), n=20)
    np.testing.assert_allclose(h2[0][:, 0], imp, atol=1e-12)


def test_simulate_with_initial_outputs_continues_the_record(rng):
    a, b = np.array([-1.5, 0.7]), np.array([1.0, 0.5])
    u = rng.standard_normal(60)
    y = np.zeros(60)
    y[:2] = rng.standard_normal(2)
    for t in range(2, 60):
        y[t] = -a @ y[t - 2:t][::-1] + b @ u[t - 2:t][::-1]
    model = ARX.from_polynomials(a, b)
    np.testing.assert_allclose(model.simulate(u, y0=y[:2]), y, atol=1e-10)
    # a longer y0 is kept as given; the rest continues from it
    ys = model.simulate(u, y0=y[:10])
    np.testing.assert_allclose(ys, y, atol=1e-10)


@pytest.mark.parametrize("horizon", [1, 2, 3, 7])
def test_predict_k_steps_matches_brute_force(rng, horizon):
    a, b, nk = [-1.2, 0.5], [0.8, 0.3], 1
    u, y = arx_data(rng, a, b, nk, n=40, noise_std=0.2)
    model = ARX(2, 2, 1).fit(u, y)
    A, B = np.r_[1.0, model.a_], np.r_[0.0, model.b_]
    yhat = model.predict(u, y, horizon=horizon)
    for t in range(len(u)):
        # run the model from the measured past up to t - horizon (zeros before 0)
        ys = {s: (y[s] if s >= 0 else 0.0) for s in range(t - horizon - 5, t - horizon + 1)}
        for s in range(t - horizon + 1, t + 1):
            ys[s] = (-sum(A[i] * ys.get(s - i, 0.0) for i in range(1, 3))
                     + sum(B[i] * (u[s - i] if s - i >= 0 else 0.0) for i in range(3)))
        assert yhat[t] == pytest.approx(ys[t], abs=1e-12)


def test_predict_one_step_and_infinite_horizon(rng):
    u, y = arx_data(rng, [-1.5, 0.7], [1.0, 0.5], 1, n=200)
    model = ARX(2, 2, 1).fit(u, y)
    Phi, _ = model.regressors(u, y)
    np.testing.assert_allclose(model.predict(u, y)[model.max_lag:], Phi @ model.theta_,
                               atol=1e-12)
    np.testing.assert_allclose(model.predict(u, y, horizon=np.inf), model.simulate(u), atol=1e-12)
    np.testing.assert_allclose(model.predict(u, y, horizon=len(u)), model.simulate(u),
                               atol=1e-12)
    # long but finite horizons converge to the simulation once the past is forgotten
    np.testing.assert_allclose(model.predict(u, y, horizon=150)[150:],
                               model.simulate(u)[150:], atol=1e-9)


def test_from_tf_round_trip_and_sampled_plant():
    model = ARX.from_polynomials([-1.2, 0.5, -0.1], [0.3, 0.2], nk=3, dt=0.2)
    back = ARX.from_tf(model.to_tf())
    assert (back.na, back.nb, back.nk, back.dt) == (3, 2, 3, 0.2)
    np.testing.assert_allclose(back.theta_, model.theta_, atol=1e-14)
    feed = ARX.from_tf(control.tf([2.0, 1.0], [1.0, -0.5], 1.0))  # (2 z + 1)/(z - 0.5)
    assert (feed.na, feed.nb, feed.nk) == (1, 2, 0)
    np.testing.assert_allclose(feed.b_, [2.0, 1.0])
    Gc = control.tf([1.0], [1.0, 3.0, 2.0])
    Gd = control.sample_system(Gc, 0.1, method="zoh")
    m = ARX.from_tf(Gd)
    u = np.random.default_rng(3).standard_normal(100)
    resp = control.forced_response(Gd, 0.1 * np.arange(100), u).outputs
    np.testing.assert_allclose(m.simulate(u), resp, atol=1e-12)


def _random_plant(gen, na, nb):
    """Stable A with real poles of modulus in [0.1, 0.9]; b with nonzero ends."""
    poles = gen.uniform(0.1, 0.9, na) * gen.choice([-1.0, 1.0], na)
    a = np.poly(poles)[1:] if na else np.zeros(0)
    b = gen.standard_normal(nb)
    b[[0, -1]] = np.sign(b[[0, -1]]) * np.maximum(np.abs(b[[0, -1]]), 0.2)
    return a, b


@settings(max_examples=40, deadline=None)
@given(na=st.integers(0, 3), nb=st.integers(1, 3), nk=st.integers(0, 3),
       seed=st.integers(0, 2 ** 32 - 1))
def test_property_structure_round_trips(na, nb, nk, seed):
    """Any (na, nb, nk): exact recovery, lfilter == forced_response == simulate, tf round trip."""
    gen = np.random.default_rng(seed)
    a, b = _random_plant(gen, na, nb)
    u = gen.standard_normal(120)
    A, B = np.r_[1.0, a], np.r_[np.zeros(nk), b]
    y = signal.lfilter(B, A, u)
    model = ARX(na, nb, nk, dt=0.5).fit(u, y)
    np.testing.assert_allclose(model.theta_, np.r_[a, b], rtol=1e-8, atol=1e-9)
    true = ARX.from_polynomials(a, b, nk=nk, dt=0.5)
    scale = 1 + np.max(np.abs(y))
    np.testing.assert_allclose(true.simulate(u), y, rtol=0, atol=1e-10 * scale)
    resp = control.forced_response(true.to_tf(), 0.5 * np.arange(120), u).outputs
    np.testing.assert_allclose(resp, y, rtol=0, atol=1e-9 * scale)
    back = ARX.from_tf(true.to_tf())
    assert (back.na, back.nb, back.nk) == (na, nb, nk)
    np.testing.assert_allclose(back.theta_, true.theta_, rtol=1e-12, atol=1e-14)
    assert complex(true.to_tf().dcgain()).real == pytest.approx(b.sum() / A.sum(), rel=1e-9)


# ----------------------------------------------------------------------
# several inputs and outputs
# ----------------------------------------------------------------------
def test_from_tf_matrix_plants_keep_the_transfer_matrix():
    """Rows over a common denominator: the ARX has exactly the plant's transfer matrix."""
    G = control.tf([[[1.0], [0.5, 0.2]], [[2.0, 0.0], [1.0]]],
                   [[[1.0, -0.5], [1.0, -0.2, 0.1]], [[1.0, 0.3], [1.0, 0.3]]], 0.1)
    model = ARX.from_tf(G)
    assert model.a_.shape[:2] == (2, 2) and model.a_[0, 1].tolist() == [0.0] * model.na
    assert model.nk == [0, 1]  # (2 z)/(z + 0.3) has a direct term; input 2 is delayed
    H = model.to_tf()
    for z in (1.0, 0.4 + 0.7j, -1.3, 3.0j):
        np.testing.assert_allclose(H(z), G(z), rtol=1e-10)
        np.testing.assert_allclose(model.to_ss()(z), G(z), rtol=1e-10)
    miso = ARX.from_tf(G[0, :])
    assert miso.a_.ndim == 1 and isinstance(miso.b_, list)
    np.testing.assert_allclose(miso.to_tf()(0.3 + 0.2j), G[0, :](0.3 + 0.2j), rtol=1e-10)
    u = np.random.default_rng(0).standard_normal((50, 2))
    expected = (signal.lfilter([0, 1.0], [1, -0.5], u[:, 0])
                + signal.lfilter([0, 0.5, 0.2], [1, -0.2, 0.1], u[:, 1]))
    np.testing.assert_allclose(miso.simulate(u), expected, atol=1e-12)


def test_miso_per_input_orders_and_delays(rng):
    a = np.array([-1.2, 0.4])
    b1, b2 = np.array([0.5]), np.array([1.0, -0.6, 0.2])
    nk = [0, 3]
    N = 400
    u = rng.standard_normal((N, 2))
    A = np.r_[1.0, a]
    y = (signal.lfilter(np.r_[np.zeros(nk[0]), b1], A, u[:, 0])
         + signal.lfilter(np.r_[np.zeros(nk[1]), b2], A, u[:, 1]))
    model = ARX(2, [1, 3], nk).fit(u, y)
    np.testing.assert_allclose(model.a_, a, atol=1e-11)
    assert isinstance(model.b_, list) and len(model.b_) == 2
    np.testing.assert_allclose(model.b_[0], b1, atol=1e-11)
    np.testing.assert_allclose(model.b_[1], b2, atol=1e-11)
    assert model.max_lag == 5 and model.n_params == 6
    np.testing.assert_allclose(model.simulate(u), y, atol=1e-10)
    G = model.to_tf()
    assert (G.noutputs, G.ninputs) == (1, 2)
    for j, (bj, kj) in enumerate(zip([b1, b2], nk)):
        single = ARX.from_polynomials(a, bj, nk=kj)
        for z in (1.0, 0.3 + 0.8j, -0.9, 2.0j):
            assert complex(G(z)[0, j]) == pytest.approx(complex(single.to_tf()(z)), rel=1e-12)
    back = ARX.from_tf(G)  # the transfer function keeps every order and delay
    assert (back.na, back.nb, back.nk) == (2, [1, 3], [0, 3])
    np.testing.assert_allclose(back.theta_, model.theta_, rtol=1e-10, atol=1e-12)
    names = model.param_names_
    assert names == ["a1", "a2", "b1[u1]", "b1[u2]", "b2[u2]", "b3[u2]"]
    # with noise: lstsq on the documented regressors
    y_noisy = y + signal.lfilter([1.0], A, 0.1 * rng.standard_normal(N))
    model.fit(u, y_noisy)
    Phi, target = hand_regressors(u, y_noisy, 2, [1, 3], nk)
    np.testing.assert_allclose(model.theta_, np.linalg.lstsq(Phi, target, rcond=None)[0],
                               rtol=1e-10)


def _mimo_data(rng, N=500, noise_std=0.05):
    """Two coupled outputs, two inputs: A(q) y = B(q) u + e with matrix A."""
    A1 = np.array([[-0.9, 0.2], [0.1, -0.5]])
    A2 = np.array([[0.2, 0.0], [-0.05, 0.1]])
    B1 = np.array([[1.0, 0.3], [0.0, 0.8]])   # u(t-1)
    B2 = np.array([[0.5, 0.0], [0.2, -0.4]])  # u(t-2)
    u = rng.standard_normal((N, 2))
    y = np.zeros((N, 2))
    e = noise_std * rng.standard_normal((N, 2))
    for t in range(N):
        acc = e[t].copy()
        for k, Ak in ((1, A1), (2, A2)):
            if t - k >= 0:
                acc -= Ak @ y[t - k]
        for k, Bk in ((1, B1), (2, B2)):
            if t - k >= 0:
                acc += Bk @ u[t - k]
        y[t] = acc
    return u, y, (A1, A2, B1, B2)


def test_mimo_matches_separate_single_output_fits(rng):
    u, y, (A1, A2, B1, B2) = _mimo_data(rng)
    model = ARX(2, 2, 1).fit(u, y)
    assert model.theta_.shape == (2 * 2 + 4, 2)
    assert model.a_.shape == (2, 2, 2) and model.theta_cov_.shape == (2, 8, 8)
    for i in range(2):
        other = 1 - i
        # output i alone, with the other output as an extra input: -a[i, other] = b of y_other
        single = ARX(2, [2, 2, 2], [1, 1, 1]).fit(np.column_stack([y[:, other], u]), y[:, i])
        np.testing.assert_allclose(model.a_[i, i], single.a_, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(model.a_[i, other], -single.b_[0], rtol=1e-9, atol=1e-12)
        for j in range(2):
            np.testing.assert_allclose(model.b_[j][i], single.b_[1 + j], rtol=1e-9, atol=1e-12)
        assert model.noise_variance_[i] == pytest.approx(single.noise_variance_, rel=1e-9)
        se, se1 = model.std_errors_[:, i], single.std_errors_
        np.testing.assert_allclose(se[[2 * i, 2 * i + 1]], se1[[0, 1]], rtol=1e-8)
        np.testing.assert_allclose(se[[2 * other, 2 * other + 1]], se1[[2, 3]], rtol=1e-8)
        np.testing.assert_allclose(se[4:], se1[4:], rtol=1e-8)
    resid = model.residuals_
    np.testing.assert_allclose(model.noise_covariance_, resid.T @ resid / (len(resid) - 8),
                               rtol=1e-12)
    np.testing.assert_allclose(np.diag(model.noise_covariance_), model.noise_variance_,
                               rtol=1e-12)
    # truth recovered within noise
    np.testing.assert_allclose(model.a_[:, :, 0], A1, atol=0.05)
    np.testing.assert_allclose(model.b_[0][:, 0], B1[:, 0], atol=0.05)


def test_mimo_simulate_and_transfer_matrix(rng):
    u, y, _ = _mimo_data(rng, N=200, noise_std=0.0)
    model = ARX(2, 2, 1, dt=1.0).fit(u, y)
    np.testing.assert_allclose(model.simulate(u), y, atol=1e-9)
    A, B = model.polynomials()
    G = model.to_tf()
    sys = model.to_ss()
    assert (G.noutputs, G.ninputs) == (2, 2)
    for z in (1.0, 0.4 + 0.7j, -1.3, 3.0j):
        w = z ** -np.arange(A.shape[2])
        Az = A @ w
        Bz = B @ (z ** -np.arange(B.shape[2]))
        Gz = np.linalg.solve(Az, Bz)
        np.testing.assert_allclose(G(z), Gz, rtol=1e-10)
        np.testing.assert_allclose(sys(z), Gz, rtol=1e-10)
        Hz = model.to_tf(noise=True)(z)
        np.testing.assert_allclose(Hz, np.linalg.inv(Az), rtol=1e-10)
    resp = control.forced_response(sys, np.arange(200.0), u.T)
    np.testing.assert_allclose(resp.outputs.T, model.simulate(u), atol=1e-9)
    dl = model.to_dlti()
    _, yd, _ = signal.dlsim(dl, u)
    np.testing.assert_allclose(yd, y, atol=1e-9)


@settings(max_examples=25, deadline=None)
@given(ny=st.integers(1, 3), nu=st.integers(1, 2), na=st.integers(0, 2),
       nb=st.lists(st.integers(1, 3), min_size=2, max_size=2),
       nk=st.lists(st.integers(0, 2), min_size=2, max_size=2), seed=st.integers(0, 2 ** 32 - 1))
def test_property_transfer_matrix_of_any_structure(ny, nu, na, nb, nk, seed):
    """to_tf, to_ss and to_dlti are A(z)^-1 B(z) for any MIMO structure; simulate agrees."""
    gen = np.random.default_rng(seed)
    nb, nk = nb[:nu], nk[:nu]
    N = 40 + 10 * ny * nu
    u = gen.standard_normal((N, nu))
    y = gen.standard_normal((N, ny))
    model = ARX(na, nb, nk, dt=1.0).fit(u, y)
    A, B = model.polynomials()  # (ny, ny, na + 1) and (ny, nu, max(nk + nb)): 2-D signals
    G, sys = model.to_tf(), model.to_ss()
    for z in (1.3, 0.5 + 0.9j, -1.1 + 0.2j):
        Gz = np.linalg.solve(A @ z ** -np.arange(A.shape[2]), B @ z ** -np.arange(B.shape[2]))
        np.testing.assert_allclose(np.reshape(G(z), (ny, nu)), Gz, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(np.reshape(sys(z), (ny, nu)), Gz, rtol=1e-9, atol=1e-12)
    ys = model.simulate(u).reshape(N, ny)
    dl = model.to_dlti() if ny == 1 and nu == 1 else signal.dlti(sys.A, sys.B, sys.C, sys.D,
                                                                  dt=1.0)
    _, yd = signal.dlsim(dl, u)[:2]
    np.testing.assert_allclose(np.reshape(yd, (N, ny)), ys, rtol=1e-9,
                               atol=1e-9 * (1 + np.abs(ys).max()))


@settings(max_examples=20, deadline=None)
@given(ny=st.integers(1, 2), na=st.integers(0, 2), nk=st.integers(0, 2),
       horizon=st.integers(1, 4), seed=st.integers(0, 2 ** 32 - 1))
def test_property_k_step_prediction_any_structure(ny, na, nk, horizon, seed):
    """predict(horizon=k) runs the model k steps from the measured past (brute-force oracle)."""
    gen = np.random.default_rng(seed)
    N = 30
    u, y = gen.standard_normal((N, 2)), gen.standard_normal((N, ny))
    model = ARX(na, [2, 1], [nk, 1]).fit(u, y)
    A, B = model.polynomials()
    yhat = model.predict(u, y, horizon=horizon)

    def out(ys, s):
        return ys[s] if s >= 0 else np.zeros(ny)

    for t in range(N):
        ys = {s: out(y, s) for s in range(t - horizon - na, t - horizon + 1)}
        for s in range(t - horizon + 1, t + 1):
            acc = sum(B[:, :, k] @ (u[s - k] if s - k >= 0 else np.zeros(2))
                      for k in range(B.shape[2]))
            acc = acc - sum(A[:, :, k] @ ys.get(s - k, np.zeros(ny)) for k in range(1, na + 1))
            ys[s] = acc
        np.testing.assert_allclose(yhat[t], ys[t], rtol=1e-10, atol=1e-10)


def test_mimo_predict_one_step(rng):
    u, y, _ = _mimo_data(rng, N=100)
    model = ARX(2, 2, 1).fit(u, y)
    Phi, _ = model.regressors(u, y)
    np.testing.assert_allclose(model.predict(u, y)[2:], Phi @ model.theta_, atol=1e-12)
    np.testing.assert_allclose(model.predict(u, y, horizon=100), model.simulate(u), atol=1e-12)


# ----------------------------------------------------------------------
# recursive fit
# ----------------------------------------------------------------------
@pytest.mark.parametrize("a, b, nk", STRUCTURES[:3])
def test_rls_ends_at_batch_answer(rng, a, b, nk):
    u, y = arx_data(rng, a, b, nk, n=500)
    batch = ARX(len(a), len(b), nk).fit(u, y)
    rec = ARX(len(a), len(b), nk).fit(u, y, method="rls")
    np.testing.assert_allclose(rec.theta_, batch.theta_, rtol=1e-9, atol=1e-11)
    np.testing.assert_allclose(rec.theta_cov_, batch.theta_cov_, rtol=1e-7)
    assert rec.noise_variance_ == pytest.approx(batch.noise_variance_, rel=1e-9)
    n = rec.n_params
    hist = rec.theta_history_
    assert hist.shape == (rec.n_samples_, n)
    assert np.isnan(hist[:n - 1]).all() and not np.isnan(hist[n - 1:]).any()
    Phi, target = rec.regressors(u, y)
    for k in (n - 1, n + 3, 100, len(Phi) - 1):
        np.testing.assert_allclose(hist[k], np.linalg.lstsq(Phi[:k + 1], target[:k + 1],
                                                            rcond=None)[0], rtol=1e-8, atol=1e-9)
    assert isinstance(rec.filter_, RecursiveLeastSquares)
    np.testing.assert_allclose(rec.filter_.x[:, 0], rec.theta_)


def test_rls_forgetting_is_weighted_least_squares(rng):
    u, y = arx_data(rng, [-1.5, 0.7], [1.0, 0.5], 1, n=300)
    lam = 0.97
    model = ARX(2, 2, 1).fit(u, y, method="rls", lam=lam, k0=10)
    Phi, target = model.regressors(u, y)
    w = np.sqrt(lam ** np.arange(len(Phi) - 1, -1, -1.0))
    expected = np.linalg.lstsq(Phi * w[:, None], target * w, rcond=None)[0]
    np.testing.assert_allclose(model.theta_, expected, rtol=1e-8)


def test_rls_prior_start_is_ridge(rng):
    u, y = arx_data(rng, [-0.8], [0.5], 1, n=100)
    P0, x0 = 10.0, np.array([0.1, -0.2])
    model = ARX(1, 1, 1).fit(u, y, method="rls", k0=0, P0=P0, x0=x0)
    Phi, target = model.regressors(u, y)
    expected = np.linalg.solve(Phi.T @ Phi + np.eye(2) / P0, Phi.T @ target + x0 / P0)
    np.testing.assert_allclose(model.theta_, expected, rtol=1e-9)
    assert not np.isnan(model.theta_history_).any() and model.k0_ == 0
    same = ARX(1, 1, 1).fit(u, y, method="rls", P0=P0, x0=x0)  # a prior means k0 = 0
    np.testing.assert_array_equal(same.theta_, model.theta_)


def test_rls_options_pass_through_to_the_filter(rng):
    u, y = arx_data(rng, [-1.5, 0.7], [1.0, 0.5], 1, n=200)
    opts = {"lam": 0.98, "R": 0.5, "Q": 1e-4}
    model = ARX(2, 2, 1).fit(u, y, method="rls", k0=8, **opts)
    Phi, target = model.regressors(u, y)
    rls = RecursiveLeastSquares(4, **opts)
    rls.initialize(target[:8], Phi[:8])
    means = rls.batch_filter(target[8:], Phi[8:])[0]
    np.testing.assert_allclose(model.theta_history_[8:], means[:, :, 0], rtol=1e-12)
    np.testing.assert_allclose(model.theta_cov_, model.noise_variance_ * rls.P / 0.5, rtol=1e-12)
    assert model.filter_.lam == 0.98 and model.filter_.R == 0.5


def test_rls_default_start_grows_until_full_rank(rng):
    """A held input makes the first n_params rows rank-deficient: the start grows."""
    u = np.repeat(rng.standard_normal(40), 10)
    y = signal.lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.1 * rng.standard_normal(400)
    model = ARX(2, 2, 1).fit(u, y, method="rls")
    Phi, _ = model.regressors(u, y)
    ranks = [np.linalg.matrix_rank(Phi[:k]) for k in range(1, 40)]
    assert model.k0_ == 1 + ranks.index(4) and model.k0_ > 4
    np.testing.assert_allclose(model.theta_, ARX(2, 2, 1).fit(u, y).theta_, rtol=1e-9)
    assert ARX(2, 2, 1).fit(u[:100], y[:100], method="rls").k0_ == model.k0_


def test_rls_recursive_residuals_are_the_filter_innovations(rng):
    u, y = arx_data(rng, [-1.5, 0.7], [1.0, 0.5], 1, n=150)
    model = ARX(2, 2, 1).fit(u, y, method="rls", lam=0.95)
    Phi, target = model.regressors(u, y)
    rls = RecursiveLeastSquares(4, lam=0.95)
    rls.initialize(target[:4], Phi[:4])
    innov = []
    for z, phi in zip(target[4:], Phi[4:]):
        rls.predict_update(z, phi)
        innov.append(rls.y[0, 0])
    assert np.isnan(model.recursive_residuals_[:4]).all()
    np.testing.assert_allclose(model.recursive_residuals_[4:], innov, rtol=1e-10, atol=1e-12)
    prior = ARX(2, 2, 1).fit(u, y, method="rls", k0=0, x0=np.ones(4))
    assert prior.recursive_residuals_[0] == pytest.approx(target[0] - Phi[0] @ np.ones(4))


def test_rls_forwards_the_filter_s_other_options(rng, monkeypatch):
    """Options ARX does not name (a forgetting mode, a gate, ...) reach the filter unchanged."""
    seen = {}

    class SpyRLS(RecursiveLeastSquares):
        def __init__(self, dim_x, dim_z=1, lam=1.0, *, marker=None, **kwargs):
            seen["marker"] = marker
            super().__init__(dim_x, dim_z, lam, **kwargs)

    monkeypatch.setattr("rlsfilt.models.arx.RecursiveLeastSquares", SpyRLS)
    u, y = arx_data(rng, [-0.8], [0.5], 1, n=50)
    model = ARX(1, 1, 1).fit(u, y, method="rls", marker=42, R=2.0)
    assert seen == {"marker": 42} and isinstance(model.filter_, SpyRLS)
    assert model.filter_.R == 2.0


def test_rls_mimo_shares_one_covariance(rng):
    u, y, _ = _mimo_data(rng, N=300)
    batch = ARX(2, 2, 1).fit(u, y)
    rec = ARX(2, 2, 1).fit(u, y, method="rls")
    np.testing.assert_allclose(rec.theta_, batch.theta_, rtol=1e-9, atol=1e-11)
    assert rec.theta_history_.shape == (rec.n_samples_, 8, 2)
    assert rec.filter_.dim_z == 2
    rr = rec.recursive_residuals_
    assert rr.shape == (rec.n_samples_, 2) and np.isnan(rr[:7]).all() and np.isfinite(rr[8:]).all()


# ----------------------------------------------------------------------
# uncertainty calibration
# ----------------------------------------------------------------------
def test_uncertainty_is_calibrated_over_repeated_experiments():
    """z = (theta_hat - theta_true) / std must be standard normal over seeded experiments.

    With M = 1000 experiments the sample standard deviation of M standard
    normal values has standard error 1/sqrt(2 (M - 1)) = 0.022, and the
    mean 1/sqrt(M) = 0.032; the bands below are 4 standard errors wide, so a
    correct implementation fails them with probability about 1e-4 per
    parameter, while a covariance off by 25 % (std off by 12 %) fails with
    probability above 0.9. The noise-variance check is tighter still: its
    band (4 sqrt(2 / dof) / sqrt(M) = 0.013) rejects the biased divisor
    N_rows instead of N_rows - n_params (a 2 % bias here).
    """
    a, b, nk = np.array([-1.5, 0.7]), np.array([1.0, 0.5]), 1
    theta_true = np.r_[a, b]
    M, N, sigma = 1000, 200, 0.3
    z = np.empty((M, 4))
    ratio = np.empty(M)
    cover = np.empty((M, 4), dtype=bool)
    for m in range(M):
        gen = np.random.default_rng(1000 + m)
        u, y = arx_data(gen, a, b, nk, n=N, noise_std=sigma)
        model = ARX(2, 2, 1).fit(u, y)
        z[m] = (model.theta_ - theta_true) / model.std_errors_
        ratio[m] = model.noise_variance_ / sigma ** 2
        cover[m] = np.abs(z[m]) < 1.959964
    band_std = 4 / np.sqrt(2 * (M - 1))
    assert np.all(np.abs(z.std(axis=0, ddof=1) - 1) < band_std), z.std(axis=0, ddof=1)
    assert np.all(np.abs(z.mean(axis=0)) < 4 / np.sqrt(M)), z.mean(axis=0)
    # unbiased noise variance: E[s^2 / sigma^2] = 1, sd of the ratio sqrt(2 / dof)
    dof = N - 2 - 4
    assert abs(ratio.mean() - 1) < 4 * np.sqrt(2 / dof) / np.sqrt(M)
    # 95 % intervals cover about 95 % (binomial sd sqrt(.05 * .95 / M) = 0.0069)
    assert np.all(np.abs(cover.mean(axis=0) - 0.95) < 4 * np.sqrt(0.05 * 0.95 / M))


def test_colored_noise_breaks_calibration():
    """The same check fails for output-error data: ARX is biased there (it can fail)."""
    a, b = np.array([-1.5, 0.7]), np.array([1.0, 0.5])
    zs = []
    for m in range(30):
        gen = np.random.default_rng(m)
        u = gen.standard_normal(400)
        y = signal.lfilter([0, *b], [1, *a], u) + 0.5 * gen.standard_normal(400)
        model = ARX(2, 2, 1).fit(u, y)
        zs.append((model.theta_ - np.r_[a, b]) / model.std_errors_)
    assert np.abs(np.mean(zs, axis=0)).max() > 5


# ----------------------------------------------------------------------
# pandas and display
# ----------------------------------------------------------------------
def test_pandas_inputs_and_names(rng):
    pd = pytest.importorskip("pandas")
    u, y = arx_data(rng, [-1.5, 0.7], [1.0, 0.5], 1, n=200)
    ref = ARX(2, 2, 1).fit(u, y)
    model = ARX(2, 2, 1).fit(pd.Series(u, name="heater"), pd.Series(y, name="temp"))
    np.testing.assert_allclose(model.theta_, ref.theta_, rtol=1e-14)
    assert "temp(t)" in repr(model) and "heater(t-1)" in repr(model)
    frame = pd.DataFrame({"u1": u, "u2": rng.standard_normal(200)})
    m2 = ARX(2, [2, 1], [1, 0]).fit(frame, pd.DataFrame({"y": y}))
    np.testing.assert_allclose(m2.predict(frame, pd.DataFrame({"y": y}))[:, 0][2:],
                               m2.regressors(frame.to_numpy(), y[:, None])[0] @ m2.theta_[:, 0])
    assert m2.param_names_[-1] == "b1[u2]"


def test_summary_repr_and_html(rng):
    u, y = arx_data(rng, [-1.5, 0.7], [1.0, 0.5], 1, n=300)
    model = ARX(2, 2, 1, dt=0.1)
    assert repr(model) == "ARX(na=2, nb=2, nk=1, dt=0.1)"
    model.fit(u, y)
    text = str(model.summary())
    se = model.std_errors_
    assert "y(t) - 1.5" in text and f"(+/-{se[0]:.2g}) y(t-1)" in text
    assert f"(+/-{se[3]:.2g}) u(t-2)" in text and "+ e(t)" in text
    assert "batch least squares" in text and "a2" in text
    html = model._repr_html_()
    assert "<table>" in html and "&plusmn;" in html and "b2" in html
    assert model.summary()._repr_html_() == html
    latex = model._repr_latex_()
    assert latex.startswith("$$\\begin{aligned}y(t) - 1.5") and latex.endswith("\\end{aligned}$$")
    assert f"(\\pm {se[2]:.2g})\\, u(t-1)" in latex and "&= " in latex
    assert ARX(1, 1)._repr_latex_() is None
    rec = ARX(2, 2, 1).fit(u, y, method="rls", lam=0.99)
    assert "recursive least squares (lam=0.99, batch start on 4 rows)" in repr(rec)
    true = ARX.from_polynomials([-0.5], [1.0])
    assert "given coefficients (no fit)" in repr(true) and "(+/-0) u(t-1)" in repr(true)
    assert repr(model).startswith("ARX(na=2, nb=2, nk=1, dt=0.1):")


@settings(max_examples=30, deadline=None)
@given(n=st.integers(1, 4), silent=st.lists(st.integers(0, 30), min_size=4, max_size=4),
       rows=st.integers(1, 40), seed=st.integers(0, 2 ** 32 - 1))
def test_exact_start_rows_match_a_linear_scan(n, silent, rows, seed):
    """The batch start (ARX rls, CUSUM) is the first prefix of full column rank."""
    from rlsfilt.models.regressors import _full_rank_rows

    gen = np.random.default_rng(seed)
    Phi = gen.standard_normal((rows, n))
    for j in range(n):
        Phi[:silent[j], j] = 0.0  # regressor j silent for its first rows
    scan = next((k for k in range(n, rows + 1) if np.linalg.matrix_rank(Phi[:k]) == n), None)
    assert _full_rank_rows(Phi) == scan


def test_html_and_latex_escape_signal_names(rng):
    """pandas names with markup characters render as text, not as HTML or broken LaTeX."""
    pd = pytest.importorskip("pandas")
    u, y = arx_data(rng, [-0.8], [0.5], 1, n=100)
    model = ARX(1, 1).fit(pd.Series(u, name="P<in>"), pd.Series(y, name="T&out"))
    html = model._repr_html_()
    assert "P<in>" not in html and "P&lt;in&gt;(t-1)" in html and "T&amp;out(t)" in html
    assert "&plusmn;" in html
    assert "\\mathrm{T\\&out}(t)" in model._repr_latex_()
    assert "T&out(t) - 0.79" in repr(model) and "P<in>(t-1)" in repr(model)  # plain text


@pytest.mark.parametrize("su, sy", [(1e-8, 1e6), (1e-12, 1e10)])
def test_rank_decision_does_not_depend_on_units(rng, su, sy):
    """Signals in very different units (nA beside MPa) are not 'not persistently exciting'."""
    u, y = arx_data(rng, [-1.5, 0.7], [1.0, 0.5], 1, n=500, noise_std=0.01)
    ref = ARX(2, 2, 1).fit(u, y)
    scaled = ARX(2, 2, 1).fit(su * u, sy * y)
    np.testing.assert_allclose(scaled.a_, ref.a_, rtol=1e-8)
    np.testing.assert_allclose(scaled.b_ * su / sy, ref.b_, rtol=1e-8)
