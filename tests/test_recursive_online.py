"""RecursiveARX, RecursiveAR and RecursiveOE with MATLAB's other online options (#31).

``method="nlms"``/``"lms"`` (recursiveARX's 'NormalizedGradient' and
'Gradient'): the estimates equal the gradient filter run by hand on the
regressor rows of the record (bit for bit, the rows before ``max_lag``
holding zero lags) and padasip's filter (1e-12). ``window=W`` (finite
history): after each sample the estimate equals ``numpy.linalg.lstsq`` on the last
``W`` regressor rows (1e-9); before the window first fills, the ridge
estimate with the prior ``x0``, ``P0`` (closed form, 1e-9).
"""

import copy
import pickle

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt import LMS, NLMS, RecursiveAR, RecursiveARX, RecursiveOE

pa = pytest.importorskip("padasip")


def _arx_record(seed=0, n=800, inputs=1):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, inputs))
    y = lfilter([0, 1.0, 0.5], [1, -1.2, 0.5], u[:, 0]) + 0.05 * rng.standard_normal(n)
    if inputs > 1:
        y += lfilter([0.7, 0.2], [1, -0.4], u[:, 1])
    return (u[:, 0] if inputs == 1 else u), y


def _rows(y, U, na, nb, nk):
    """The regressor row of every sample, lags before the start zero (as the
    streaming objects): [-y(t-1) .. -y(t-na), u_j(t-nk_j) .. u_j(t-nk_j-nb_j+1)]."""
    U = np.zeros((len(y), 0)) if U is None else np.asarray(U).reshape(len(y), -1)
    nb, nk = np.broadcast_to(nb, U.shape[1]), np.broadcast_to(nk, U.shape[1])
    rows = []
    for t in range(len(y)):
        row = [-y[t - i] if t - i >= 0 else 0.0 for i in range(1, na + 1)]
        for j in range(U.shape[1]):
            row += [U[t - nk[j] - i, j] if t - nk[j] - i >= 0 else 0.0 for i in range(nb[j])]
        rows.append(row)
    return np.array(rows)


@pytest.mark.parametrize("method, cls, options", [("nlms", NLMS, {"mu": 0.5}),
                                                  ("nlms", NLMS, {"mu": 0.2, "eps": 0.1,
                                                                  "leak": 0.01}),
                                                  ("lms", LMS, {"mu": 0.03})])
def test_gradient_arx_is_the_filter_on_the_rows(method, cls, options):
    u, y = _arx_record(inputs=2)
    est = RecursiveARX(2, [2, 1], [1, 0], method=method, **options)
    yhat, theta = est.batch(y, u)
    Phi = _rows(y, u, 2, [2, 1], [1, 0])
    f = cls(Phi.shape[1], **options)
    means, _, means_p, _ = f.batch_filter(y, Phi)
    assert_array_equal(theta, means[:, :, 0])
    assert_allclose(yhat, np.einsum("ti,ti->t", Phi, means_p[:, :, 0]), rtol=1e-13,
                    atol=1e-13)
    stream = RecursiveARX(2, [2, 1], [1, 0], method=method, **options)
    for t in range(len(y)):                        # step == batch, bit for bit
        yh, th = stream.step(y[t], u[t])
        assert yh == yhat[t]
        assert_array_equal(th, theta[t])
    assert est.method == method and "method='" + method in repr(est)
    with pytest.raises(AttributeError, match="no covariance"):
        _ = est.P


@pytest.mark.parametrize("method, padasip_filter, mu", [("nlms", "FilterNLMS", 0.5),
                                                        ("lms", "FilterLMS", 0.01)])
def test_gradient_ar_equals_padasip(method, padasip_filter, mu):
    rng = np.random.default_rng(4)
    y = lfilter([1.0], [1, -1.1, 0.3], rng.standard_normal(1000))
    est = RecursiveAR(2, method=method, mu=mu)
    yhat, theta = est.batch(y)
    Phi = _rows(y, None, 2, 0, 0)
    p = getattr(pa.filters, padasip_filter)(2, mu=mu, w="zeros")
    _, e, w = p.run(y, Phi)
    assert_allclose(theta[:-1], w[1:], rtol=1e-12, atol=1e-12)
    assert_allclose(y - yhat, e, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("window", [10, 60])
@pytest.mark.parametrize("kind", ["ARX", "AR", "OE"])
def test_window_is_least_squares_over_the_last_rows(kind, window):
    """After each sample the estimate is lstsq on the last `window` regressor rows
    (the rows the recursion formed, ``est.phi``); before the window first fills it
    is the ridge estimate with the prior ``x0``, ``P0``."""
    u, y = _arx_record(seed=2)
    if kind == "OE":
        y = lfilter([0, 1.0], [1, -0.7], u) + 0.1 * np.random.default_rng(3).standard_normal(
            len(u))
    P0, x0 = 100.0, {"ARX": [0.1, 0.0, 0.2, 0.0], "AR": [0.1, 0.0], "OE": [0.5, 0.0]}[kind]
    make = {"ARX": lambda: RecursiveARX(2, 2, 1, window=window, P0=P0, x0=x0),
            "AR": lambda: RecursiveAR(2, window=window, P0=P0, x0=x0),
            "OE": lambda: RecursiveOE(1, 1, 1, window=window, P0=P0, x0=x0)}[kind]
    est = make()
    rows, thetas = [], []
    for t in range(400):
        est.step(y[t]) if kind == "AR" else est.step(y[t], u[t])
        rows.append(est._state.phi.copy())
        thetas.append(est.theta)
    Phi, n = np.array(rows), len(x0)
    if kind != "OE":                               # the rows are those of the signals
        assert_array_equal(Phi, _rows(y[:400], None if kind == "AR" else u[:400], 2,
                                      0 if kind == "AR" else 2, 1))
    for t in range(400):
        lo = max(0, t - window + 1)
        if t + 1 < window:                         # the prior still counts (ridge)
            A = Phi[:t + 1].T @ Phi[:t + 1] + np.eye(n) / P0
            theta = np.linalg.solve(A, Phi[:t + 1].T @ y[:t + 1] + np.asarray(x0) / P0)
        else:
            theta = np.linalg.lstsq(Phi[lo:t + 1], y[lo:t + 1], rcond=None)[0]
        assert_allclose(thetas[t], theta, rtol=1e-9, atol=1e-9, err_msg=str(t))
    assert_allclose(est.P, np.linalg.inv(Phi[-window:].T @ Phi[-window:]), rtol=1e-8)
    assert est.window == window and f"window={window}" in repr(est)


def test_copies_reset_restart_and_errors():
    u, y = _arx_record(seed=6)
    for make in (lambda: RecursiveARX(2, 2, 1, method="nlms", mu=0.3),
                 lambda: RecursiveARX(2, 2, 1, window=40),
                 lambda: RecursiveOE(2, 2, 1, window=80)):
        est = make()
        est.batch(y[:300], u[:300])
        twin, pickled = copy.copy(est), pickle.loads(pickle.dumps(est))
        _, a = est.batch(y[300:], u[300:])
        for other in (twin, pickled):
            _, b = other.batch(y[300:], u[300:])
            assert_array_equal(a, b)
        est.reset()
        fresh = make()
        assert_array_equal(est.batch(y, u)[1], fresh.batch(y, u)[1])
        est.restart()
        fresh.restart()
        assert_array_equal(est.step(y[0], u[0])[1], fresh.step(y[0], u[0])[1])
    with pytest.raises(TypeError, match="`window` only applies to method='rls'"):
        RecursiveARX(2, 2, 1, method="nlms", window=50)
    with pytest.raises(ValueError, match="`method` must be 'rls', 'nlms' or 'lms'"):
        RecursiveAR(2, method="rpem")
    with pytest.raises(TypeError, match="`lam` does not apply with a `window`"):
        RecursiveARX(2, 2, 1, window=50, lam=0.99)
    with pytest.raises(TypeError, match="`P0` is not an option of method='nlms'"):
        RecursiveAR(2, method="nlms", P0=10.0)
    with pytest.raises(ValueError, match="`method` must be 'rplr'"):
        RecursiveOE(1, 1, 1, method="rpem", window=50)
    with pytest.raises(ValueError, match="`window` must be >= 4"):
        RecursiveARX(2, 2, 1, window=3)
