"""to_kalman: filterpy predictions equal ARX.predict (1 and k steps); from_kalman goes back."""

import copy

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt import ARX
from rlsfilt.adaptive import InnovationsModel, from_kalman, minimum_variance, to_kalman


def kalman_predictions(kf, u, y, horizon):
    """k-step predictions with filterpy only: from the posterior at t - k, k predicts.

    ``yhat[t] = H x(t|t-k) + D u(t)``; before ``t = 0`` everything is zero (the
    filter's initial posterior at ``t = -1``).
    """
    U = np.asarray(u, float).reshape(len(u), -1)
    Y = np.asarray(y, float).reshape(len(y), -1)
    (N, nu), D = U.shape, kf.D
    uprev = [np.zeros((nu, 1))] + [U[t].reshape(-1, 1) for t in range(N - 1)]
    posts, f = [copy.deepcopy(kf)], copy.deepcopy(kf)
    for t in range(N):
        f.predict(u=uprev[t] if nu else None)           # (no input: AR, ARMA)
        f.update((Y[t] - D @ U[t]).reshape(-1, 1))
        posts.append(copy.deepcopy(f))
    out = np.zeros_like(Y)
    for t in range(N):
        s = max(t - horizon, -1)           # the last measured sample
        g = copy.deepcopy(posts[s + 1])
        for j in range(s + 1, t + 1):
            g.predict(u=uprev[j] if nu else None)
        out[t] = (g.H @ g.x).ravel() + D @ U[t]
    return out


def _siso_data(seed=1, N=60):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    e = 0.1 * rng.standard_normal(N)
    y = lfilter([0, 1, 0.5], [1, -1.5, 0.7], u) + lfilter([1], [1, -1.5, 0.7], e)
    return u, y


@pytest.mark.parametrize("orders", [(2, 2, 1), (2, 3, 0), (1, 2, 3), (3, 1, 1), (0, 3, 1)])
@pytest.mark.parametrize("horizon", [1, 2, 5])
def test_siso_predictions_equal_arx_predict(orders, horizon):
    u, y = _siso_data()
    model = ARX(*orders).fit(u, y)
    kf = to_kalman(model)
    got = kalman_predictions(kf, u, y, horizon)[:, 0]
    want = model.predict(u, y, horizon=horizon)
    assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())


def test_a_horizon_beyond_the_record_is_the_simulation():
    u, y = _siso_data(N=30)
    model = ARX(2, 2, 1).fit(u, y)
    got = kalman_predictions(to_kalman(model), u, y, 30)[:, 0]
    assert_allclose(got, model.simulate(u), rtol=0, atol=1e-10 * np.abs(got).max())


@pytest.mark.parametrize("horizon", [1, 3])
def test_multi_input_multi_output_predictions_equal_arx_predict(horizon):
    rng = np.random.default_rng(2)
    N = 60
    U = rng.standard_normal((N, 2))
    u, y = _siso_data(seed=3, N=N)
    Y = np.column_stack([y + lfilter([0, 0.2], [1], U[:, 1]),
                         lfilter([0, 0.3], [1, -0.5], U[:, 1])
                         + lfilter([0, 0, 0.4], [1, -0.2], U[:, 0])
                         + 0.1 * rng.standard_normal(N)])
    model = ARX(2, [2, 1], [1, 2]).fit(U, Y)
    kf = to_kalman(model)
    assert kf.dim_z == 2 and kf.dim_u == 2
    got = kalman_predictions(kf, U, Y, horizon)
    want = model.predict(U, Y, horizon=horizon)
    assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())
    # a single output with two inputs
    miso = ARX(2, [2, 1], [1, 0]).fit(U, Y[:, 0])
    got = kalman_predictions(to_kalman(miso), U, Y[:, 0], horizon)[:, 0]
    want = miso.predict(U, Y[:, 0], horizon=horizon)
    assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())


def test_the_filter_is_in_steady_state_and_its_innovations_are_the_residuals():
    u, y = _siso_data(N=80)
    model = ARX(2, 2, 1).fit(u, y)
    kf = to_kalman(model)
    innovations = []
    for t in range(len(u)):
        kf.predict(u=u[t - 1] if t else 0.0)
        kf.update(y[t])
        innovations.append(kf.y.item())
        assert_allclose(kf.K.ravel(), np.r_[np.zeros(kf.dim_x - 1), 1.0], rtol=0, atol=1e-15)
        assert abs(kf.S.item() - model.noise_variance_) < 1e-15
    # after max_lag the innovations are the least-squares residuals y - Phi theta
    assert_allclose(innovations[2:], model.residuals_, rtol=0, atol=1e-12)


def test_round_trip_gives_the_polynomials_and_the_model_back():
    for orders in [(2, 2, 1), (2, 3, 0), (1, 2, 3)]:
        u, y = _siso_data()
        model = ARX(*orders).fit(u, y)
        back = from_kalman(to_kalman(model))
        A, B = model.polynomials()
        assert_allclose(back.A, A, rtol=0, atol=1e-12)
        assert_allclose(back.B, B, rtol=0, atol=1e-12)
        assert_array_equal(back.C, [1.0])
        assert abs(back.noise_variance - model.noise_variance_) < 1e-15
        arx = back.to_arx()
        assert (arx.na, arx.nb, arx.nk) == orders
        assert_allclose(arx.theta_, model.theta_, rtol=0, atol=1e-12)


def test_armax_predictions_equal_the_armax_predictor():
    """C yhat = (C - A) y + B u (zero past), the textbook one-step ARMAX predictor."""
    A, B, C = np.array([1.0, -1.2, 0.5]), np.array([0.0, 0.8, 0.3]), np.array([1.0, 0.4, 0.2])
    model = InnovationsModel(A, B, C, noise_variance=0.04)
    u, y = _siso_data(seed=5, N=70)
    got = kalman_predictions(to_kalman(model), u, y, 1)[:, 0]
    want = lfilter(np.r_[C - A], C, y) + lfilter(B, C, u)
    assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())
    back = from_kalman(to_kalman(model))
    assert_allclose(back.C, C, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match=r"the noise polynomial C = .* is not 1 .* ARMAX"):
        back.to_arx()
    mv = minimum_variance(back)                       # polynomials() carries C
    assert_allclose(mv.T, C, atol=1e-12)


def _generic_kalman_filter():
    kf = KalmanFilter(dim_x=3, dim_z=1, dim_u=1)
    kf.F = np.array([[0.9, 0.2, 0.0], [-0.1, 0.7, 0.3], [0.0, 0.05, 0.5]])
    kf.H = np.array([[1.0, -0.5, 0.25]])
    kf.B = np.array([[1.0], [0.0], [0.5]])
    kf.Q = np.diag([0.1, 0.05, 0.02])
    kf.R = np.array([[0.3]])
    return kf


def test_a_kalman_filter_becomes_its_innovations_model():
    """Spectrum and input response of (F, H, Q, R, B) equal those of A y = B u + C e."""
    kf = _generic_kalman_filter()
    model = from_kalman(kf)
    F, H, G, Q, R = kf.F, kf.H, kf.B, kf.Q, kf.R
    for w in [0.01, 0.4, 1.3, 3.0]:
        z = np.exp(1j * w)
        M = np.linalg.inv(z * np.eye(3) - F)
        spectrum_ss = (H @ M @ Q @ M.conj().T @ H.T + R).item().real
        zi = 1 / z
        Az = np.polyval(model.A[::-1], zi)
        Cz = np.polyval(model.C[::-1], zi)
        Bz = np.polyval(model.B[::-1], zi)
        assert abs(model.noise_variance * abs(Cz / Az) ** 2 - spectrum_ss) < 1e-10 * spectrum_ss
        assert abs(Bz / Az - (H @ M @ G).item()) < 1e-10
    assert np.all(np.abs(np.roots(model.C)) < 1)                 # the minimum-phase factor


def test_to_kalman_of_the_innovations_model_predicts_as_the_steady_state_filter():
    kf = _generic_kalman_filter()
    model = from_kalman(kf)
    from scipy.linalg import solve_discrete_are

    P = solve_discrete_are(kf.F.T, kf.H.T, kf.Q, kf.R)     # steady prior covariance
    rng = np.random.default_rng(7)
    N = 300
    u, y = rng.standard_normal(N), rng.standard_normal(N)
    steady = copy.deepcopy(kf)
    steady.x = np.zeros((3, 1))
    steady.P = P.copy()
    mine = to_kalman(model)
    a, b = [], []
    for t in range(N):
        # filterpy's own filter: prior at t from the posterior at t - 1
        if t:
            steady.predict(u=u[t - 1])
        a.append((steady.H @ steady.x).item())
        steady.update(y[t])
        mine.predict(u=u[t - 1] if t else 0.0)
        b.append((mine.H @ mine.x).item())
        mine.update(y[t])
    # different starts, the same stationary predictor: equal once the start has decayed
    assert_allclose(a[200:], b[200:], rtol=0, atol=1e-9)


def test_from_an_explicit_innovations_form():
    F = np.array([[1.5, 1.0], [-0.7, 0.0]])        # observer form of A = 1 - 1.5 q^-1 + 0.7 q^-2
    H = np.array([[1.0, 0.0]])
    G = np.array([[1.0], [0.5]])
    K = np.array([1.9, -0.5])                      # C - A = [0, 0.4, 0.2]: C = [1, -1.1, 0.9]
    model = from_kalman(F=F, H=H, G=G, K=K, noise_variance=0.5, dt=0.1)
    assert_allclose(model.A, [1.0, -1.5, 0.7], atol=1e-14)
    assert_allclose(model.B, [0.0, 1.0, 0.5], atol=1e-14)
    assert_allclose(model.C, [1.0, 0.4, 0.2], atol=1e-14)
    assert model.noise_variance == 0.5 and model.dt == 0.1
    # K = 0 (no noise model): C = A, an output-error model
    oe = from_kalman(F=F, H=H, G=G)
    assert_allclose(oe.C, oe.A, atol=1e-14)


def test_to_kalman_uses_the_noise_variance_and_copies():
    model = ARX.from_polynomials([-0.9], [1.0], noise_variance=0.25)
    kf = to_kalman(model)
    assert kf.Q[-1, -1] == 0.25
    assert to_kalman(model, noise_variance=2.0).Q[-1, -1] == 2.0
    a0 = model.a_.copy()
    kf.F[0, 0] = 99.0
    assert_array_equal(model.a_, a0)
    free = ARX.from_polynomials([-0.9], [1.0])          # noise variance 0: the scale is 1
    assert to_kalman(free).Q[-1, -1] == 1.0


def test_errors_name_the_argument():
    with pytest.raises(TypeError, match=r"`model` must have polydata\(\) or polynomials\(\)"):
        to_kalman(object())
    with pytest.raises(TypeError, match=r"give either `kf` or the innovations form"):
        from_kalman(_generic_kalman_filter(), F=np.eye(2))
    with pytest.raises(TypeError, match=r"`F` and `H` are required"):
        from_kalman()
    with pytest.raises(ValueError, match=r"`H` must have shape \(1, 2\) \(one output\)"):
        from_kalman(F=np.eye(2), H=np.eye(2))
    with pytest.raises(ValueError, match=r"`F` must be finite"):
        from_kalman(F=[[np.nan]], H=[[1.0]])

    class Bad:
        def polynomials(self):
            return np.array([2.0, 1.0]), np.array([0.0, 1.0])

    with pytest.raises(ValueError, match=r"A\(0\) must be the identity"):
        to_kalman(Bad())


def test_the_model_method_is_the_function():
    from rlsfilt import NotFittedError

    u, y = _siso_data()
    model = ARX(2, 2, 1, dt=0.1).fit(u, y)
    a, b = model.to_kalman(), to_kalman(model)
    for name in ("F", "B", "H", "Q", "R", "x", "P", "D"):
        assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.dt == 0.1
    with pytest.raises(NotFittedError, match=r"not fitted yet"):
        ARX(2, 2, 1).to_kalman()


@pytest.mark.parametrize("kind", ["AR", "ARMA"])
@pytest.mark.parametrize("horizon", [1, 3])
def test_time_series_models_become_filters_that_predict_as_they_do(kind, horizon):
    # AR and ARMA have no input: a filter with dim_u = 0 (it crashed in max() of no B)
    from rlsfilt import AR, ARMA
    y = lfilter([1, 0.4], [1, -0.7, 0.2], np.random.default_rng(5).standard_normal(80))
    model = AR(2).fit(y) if kind == "AR" else ARMA(2, 1).fit(y)
    kf = to_kalman(model)
    assert kf.dim_u == 0 and kf.D.shape == (1, 0)
    got = kalman_predictions(kf, np.zeros((80, 0)), y, horizon)[:, 0]
    want = model.predict(None, y, horizon=horizon)
    assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())


@pytest.mark.parametrize("offset", [True, "mean"])
@pytest.mark.parametrize("horizon", [1, 3])
def test_a_model_with_an_operating_point_warns_and_its_filter_runs_on_deviations(offset,
                                                                                 horizon):
    # the filter is the model of the deviations: fed the data themselves its predictions are
    # off by a constant, which went unsaid while the docstring promised model.predict
    from rlsfilt import OperatingPointWarning
    u, y = _siso_data(N=80)
    u, y = u + 5.0, y + 40.0
    model = ARX(2, 2, 1, offset=offset).fit(u, y)
    with pytest.warns(OperatingPointWarning, match="feed it u - input_offset_"):
        kf = to_kalman(model)
    u_op, y_op = model.input_offset_[0], model.output_offset_[0]
    got = kalman_predictions(kf, u - u_op, y - y_op, horizon)[:, 0] + y_op
    want = model.predict(u, y, horizon=horizon)
    assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())
    raw = kalman_predictions(kf, u, y, horizon)[:, 0]
    assert np.max(np.abs(raw - want)) > 1.0      # what the warning is about


def test_a_model_without_an_operating_point_does_not_warn():
    u, y = _siso_data(N=40)
    to_kalman(ARX(2, 2, 1).fit(u, y))             # warnings are errors in the test suite
    to_kalman(ARX(2, 2, 1, offset=False).fit(u + 1e-3, y))


@pytest.mark.parametrize("kind", ["OE", "BJ", "ARMAX", "OE-2-inputs"])
def test_streaming_estimators_become_filters_of_their_whole_model(kind):
    # their polynomials() are (A, B, C, D, F): D and F were dropped, so the filter of a
    # RecursiveOE predicted B u instead of B/F u, silently
    from rlsfilt import RecursiveARMAX, RecursiveBJ, RecursiveOE
    gen = np.random.default_rng(0)
    U = gen.standard_normal((300, 2))
    y = (lfilter([0, 1, 0.5], [1, -0.8], U[:, 0]) + lfilter([0, 0, 0.4], [1, -0.5], U[:, 1])
         + lfilter([1, 0.3], [1, -0.6], 0.1 * gen.standard_normal(300)))
    est = {"OE": lambda: RecursiveOE(2, 1, 1), "BJ": lambda: RecursiveBJ(2, 1, 1, 1, 1),
           "ARMAX": lambda: RecursiveARMAX(1, 2, 1, 1),
           "OE-2-inputs": lambda: RecursiveOE([2, 1], [1, 1], [1, 2])}[kind]()
    two = kind.endswith("2-inputs")
    u = U if two else U[:, 0]
    for t in range(len(y)):
        est.step(y[t], u[t])
    A, B, C, D, F = est.polynomials()
    # the one-step predictor y - D/C (A y - sum B_j/F_j u_j), by lfilter
    Uc = U if two else U[:, :1]
    v = lfilter(A, [1.0], y) - sum(lfilter(B[j], F[j], Uc[:, j]) for j in range(len(B)))
    want = y - lfilter(D, C, v)
    got = kalman_predictions(to_kalman(est), Uc, y, 1)[:, 0]
    assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())


def test_polynomials_of_another_count_are_refused():
    class Four:
        def polynomials(self):
            return np.array([1.0, -0.5]), np.array([0.0, 1.0]), np.ones(1), np.ones(1)

    with pytest.raises(ValueError, match=r"\(A, B\), \(A, B, C\) or \(A, B, C, D, F\); got 4"):
        to_kalman(Four())
