"""ARX.fit's online methods of MATLAB's recursiveARX: gradient and finite history (#31).

Oracles: the gradient filters (`NLMS`, `LMS`) run by hand on the regressor
rows ``ARX.regressors`` gives (bit for bit), padasip's ``FilterNLMS`` and
``FilterLMS`` on the same rows (1e-12), and ``numpy.linalg.lstsq`` on the
last ``window`` rows at every step (1e-9) for ``window=``. The model contract
(save/load, summary, predict, ...) runs on these fits in
``tests/test_contract_models.py`` (``ARX-nlms``, ``ARX-lms-2-outputs``,
``ARX-rls-window``).
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt import ARX, LMS, NLMS, SlidingWindowRLS, SquareRootRLS

pa = pytest.importorskip("padasip")


def _siso(seed=0, n=600):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.05 * rng.standard_normal(n)
    return u, y


def _mimo(seed=1, n=500):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((n, 2))
    y1 = lfilter([0, 1.0], [1, -0.6], u[:, 0]) + 0.05 * rng.standard_normal(n)
    y2 = lfilter([0, 0.5], [1, -0.3], u[:, 1]) + 0.3 * np.r_[0.0, y1[:-1]] \
        + 0.05 * rng.standard_normal(n)
    return u, np.column_stack([y1, y2])


@pytest.mark.parametrize("method, cls, options", [
    ("nlms", NLMS, {"mu": 0.5}),
    ("nlms", NLMS, {"mu": 0.3, "eps": 0.1, "leak": 0.01}),
    ("lms", LMS, {"mu": 0.05}),
    ("lms", LMS, {"mu": 0.02, "leak": 0.1}),
])
@pytest.mark.parametrize("data", [_siso, _mimo])
def test_gradient_fit_is_the_filter_on_the_regressors(method, cls, options, data):
    u, y = data()
    model = ARX(2, [2, 1] if np.ndim(u) == 2 else 2, 1) if data is _mimo else ARX(2, 2, 1)
    model.fit(u, y, method=method, **options)
    Phi, target = model.regressors(u, y)
    ny = 1 if np.ndim(y) == 1 else y.shape[1]
    f = cls(Phi.shape[1], ny, **options)
    means, _, means_p, _ = f.batch_filter(target, Phi)
    assert_array_equal(model.theta_, f.x[:, 0] if ny == 1 else f.x)
    assert_array_equal(model.theta_history_, means[:, :, 0] if ny == 1 else means)
    assert model.method_ == method and model.k0_ == 0
    assert np.isnan(model.theta_cov_).all() and np.isnan(model.std_errors_).all()
    T = target.reshape(len(target), -1)
    assert_allclose(model.recursive_residuals_.reshape(T.shape),
                    T - np.einsum("ti,tij->tj", Phi, means_p), rtol=1e-12, atol=1e-12)
    assert_allclose(model.residuals_.reshape(T.shape),
                    T - Phi @ model.theta_.reshape(Phi.shape[1], -1), rtol=1e-12, atol=1e-12)
    assert isinstance(model.filter_, cls)


@pytest.mark.parametrize("method, padasip_filter", [("nlms", "FilterNLMS"), ("lms", "FilterLMS")])
def test_gradient_fit_equals_padasip(method, padasip_filter):
    """padasip on the same regressor rows (zero start; its ``run`` returns the weights
    before each row and the a-priori errors) to 1e-12."""
    u, y = _siso(seed=3)
    mu = 0.5 if method == "nlms" else 0.05
    model = ARX(2, 2, 1).fit(u, y, method=method, mu=mu, **({"eps": 1e-3} if method == "nlms"
                                                             else {}))
    Phi, target = model.regressors(u, y)
    p = getattr(pa.filters, padasip_filter)(Phi.shape[1], mu=mu, w="zeros")
    _, e, w = p.run(target, Phi)
    assert_allclose(model.theta_history_[:-1], w[1:], rtol=1e-12, atol=1e-12)
    assert_allclose(model.recursive_residuals_, e, rtol=1e-12, atol=1e-12)


def test_gradient_fit_starts_from_x0_and_refuses_rls_options():
    u, y = _siso()
    x0 = np.array([-1.4, 0.6, 0.9, 0.4])
    model = ARX(2, 2, 1).fit(u, y, method="nlms", mu=0.2, x0=x0)
    Phi, target = model.regressors(u, y)
    f = NLMS(4, mu=0.2, x0=x0)
    f.batch_filter(target, Phi)
    assert_array_equal(model.theta_, f.x[:, 0])
    for bad, match in (({"lam": 0.99}, "`lam` does not apply to method='nlms'"),
                       ({"P0": 10.0}, "`P0` does not apply"),
                       ({"eps": 0.1, "method": "lms"}, "`eps` is not an option of "
                                                       "method='lms'"),
                       ({"window": 50}, "`window` only applies to method='rls'"),
                       ({"step": 0.1}, "`step` is not an option")):
        kw = {"method": "nlms"} | bad
        with pytest.raises(TypeError, match=match):
            ARX(2, 2, 1).fit(u, y, **kw)
    with pytest.raises(ValueError, match="`mu` must be"):
        ARX(2, 2, 1).fit(u, y, method="nlms", mu=-1.0)
    with pytest.raises(ValueError, match="'nlms' or 'lms'"):
        ARX(2, 2, 1).fit(u, y, method="gradient")


@pytest.mark.parametrize("window", [8, 25, 120])
@pytest.mark.parametrize("data", [_siso, _mimo])
def test_window_is_least_squares_over_the_window(window, data):
    """After each row the estimate is numpy's lstsq on the last `window` rows (fewer at
    the start), to 1e-9; ``theta_cov_`` is that of the last window."""
    u, y = data()
    model = ARX(2, 2, 1) if data is _siso else ARX(1, [1, 1], 1)
    model.fit(u, y, method="rls", window=window)
    Phi, target = model.regressors(u, y)
    k0 = model.k0_
    assert k0 == Phi.shape[1] and model.form_ == "window" and model.lam_ == 1.0
    hist = model.theta_history_
    for t in range(k0 - 1, len(Phi)):
        lo = max(0, t - window + 1)
        theta = np.linalg.lstsq(Phi[lo:t + 1], target[lo:t + 1], rcond=None)[0]
        assert_allclose(hist[t], theta, rtol=1e-9, atol=1e-9, err_msg=str(t))
    assert np.isnan(hist[:k0 - 1]).all()
    assert_array_equal(model.theta_, hist[-1])
    W = Phi[-window:]
    resid = model.residuals_.reshape(len(Phi), -1)
    sigma2 = (resid ** 2).sum(axis=0) / (len(Phi) - Phi.shape[1])
    cov = sigma2[:, None, None] * np.linalg.inv(W.T @ W)[None]
    assert_allclose(model.theta_cov_.reshape(cov.shape), cov, rtol=1e-8)
    assert isinstance(model.filter_, SlidingWindowRLS) and model.filter_.window == window
    assert f"over a window of {window} rows" in str(model.summary())


@pytest.mark.parametrize("data", [_siso, _mimo])
def test_window_filter_is_in_the_signals_units(data):
    """The window runs in power-of-two scaled units; ``filter_`` gets its state back in
    the signals' units: its window holds the user's last rows (bit for bit, the maps are
    powers of two) and, continued on new rows, it is lstsq over the last `window` rows."""
    u, y = data(n=400)
    model = ARX(2, 2, 1) if data is _siso else ARX(1, [1, 1], 1)
    window = 40
    model.fit(u[:300], y[:300], method="rls", window=window)
    Phi, target = model.regressors(u, y)
    rows = len(model.regressors(u[:300], y[:300])[0])
    f = model.filter_
    state = f.get_state()
    order = (np.arange(window) + state["head"]) % window      # oldest first
    assert_array_equal(state["window_H"][order], Phi[rows - window:rows])
    assert_array_equal(state["window_z"][order], target[rows - window:rows].reshape(window, -1))
    assert_array_equal(state["window_R"], 1.0)
    assert_array_equal(f.x.reshape(model.theta_.shape), model.theta_)
    W = Phi[rows - window:rows]
    assert_allclose(f.P, np.linalg.inv(W.T @ W), rtol=1e-9)
    means = f.batch_filter(target[rows:], Phi[rows:])[0]
    for t in range(rows, len(Phi)):
        theta = np.linalg.lstsq(Phi[t - window + 1:t + 1], target[t - window + 1:t + 1],
                                rcond=None)[0]
        assert_allclose(means[t - rows].reshape(theta.shape), theta, rtol=1e-9, atol=1e-9)


SCALES = [(2.0 ** 40, 1.0), (1e-150, 1.0), (1.0, 1e150), (1e120, 1e-120)]


@pytest.mark.parametrize("k0, su, sy", [(None, *s) for s in SCALES]
                         + [(0, 2.0 ** 40, 1.0), (0, 1e-60, 1.0), (0, 1e50, 1e-50)])
def test_window_fit_is_scale_invariant(k0, su, sy):
    """``u * su`` and ``y * sy`` give the fit of the unscaled record with the ``b``
    coefficients times ``sy / su``: estimates, histories, recursive residuals and
    covariance (the window runs in power-of-two units, #18 item 7); bit for bit for
    powers of two. A prior start (``k0=0``) gets ``P0`` and ``R`` in the signals' units
    (``P0`` of a ``b`` coefficient times ``(sy / su)^2``: within the range `P0` takes)."""
    u, y = _siso()
    g = np.array([1.0, 1.0, sy / su, sy / su])
    kw, ref_kw = {}, {}
    if k0 == 0:
        ref_kw = {"k0": 0, "P0": 1e6, "R": 1.0}
        kw = {"k0": 0, "P0": np.diag(1e6 * g ** 2), "R": sy ** 2}
    ref = ARX(2, 2, 1).fit(u, y, method="rls", window=50, **ref_kw)
    model = ARX(2, 2, 1).fit(u * su, y * sy, method="rls", window=50, **kw)
    exact = su == 2.0 ** 40
    check = assert_array_equal if exact else (
        lambda a, b: assert_allclose(a, b, rtol=1e-10, atol=1e-10 * np.nanmax(np.abs(b))))
    check(model.theta_, ref.theta_ * g)
    check(model.theta_history_, ref.theta_history_ * g)
    check(model.recursive_residuals_, ref.recursive_residuals_ * sy)
    check(model.theta_cov_, ref.theta_cov_ * np.outer(g, g))


def test_window_options():
    u, y = _siso()
    model = ARX(2, 2, 1).fit(u, y, method="rls", window=30, k0=10)
    Phi, target = model.regressors(u, y)
    assert_allclose(model.theta_history_[9], np.linalg.lstsq(Phi[:10], target[:10],
                                                             rcond=None)[0], rtol=1e-10)
    assert_allclose(model.theta_, np.linalg.lstsq(Phi[-30:], target[-30:], rcond=None)[0],
                    rtol=1e-9)
    with pytest.raises(ValueError, match="`window` must be >= 4"):
        ARX(2, 2, 1).fit(u, y, method="rls", window=3)
    with pytest.raises(ValueError, match="`k0` must be <= `window`"):
        ARX(2, 2, 1).fit(u, y, method="rls", window=10, k0=20)
    for name, value in (("lam", 0.99), ("Q", 1e-3), ("forgetting", "directional")):
        with pytest.raises(TypeError, match=f"`{name}` does not apply to method='rls' with a "
                                            "`window`"):
            ARX(2, 2, 1).fit(u, y, method="rls", window=30, **{name: value})


@pytest.mark.parametrize("options", [{"method": "nlms", "mu": 0.5}, {"method": "lms", "mu": 0.05},
                                     {"method": "rls", "window": 60}])
def test_save_and_load_keep_the_fit(options, tmp_path):
    """A saved gradient fit (NaN covariance) or window fit loads with the same numbers."""
    from rlsfilt import load_model, save_model

    u, y = _siso()
    model = ARX(2, 2, 1).fit(u, y, **options)
    save_model(model, tmp_path / "m.json")
    again = load_model(tmp_path / "m.json")
    assert again.method_ == model.method_
    assert again.__dict__.get("form_") == model.__dict__.get("form_")
    for name in ("theta_", "theta_cov_", "noise_variance_"):
        assert_array_equal(getattr(again, name), getattr(model, name), err_msg=name)
    assert_array_equal(again.predict(u, y), model.predict(u, y))


@pytest.mark.parametrize("R", [0.3, 2.0, 3.0, 8.0])
@pytest.mark.parametrize("form, cls, options", [
    ("window", SlidingWindowRLS, {"window": 40}),
    ("square_root", SquareRootRLS, {"lam": 0.98}),
])
def test_prior_start_with_any_R_is_the_filter_on_the_regressors(R, form, cls, options):
    """The fit runs in power-of-two units from the images of P0 and R; the window's QR
    refit and the square-root form whiten rows by sqrt(R), so the shift of R must be even
    for the run to be the filter's in the signals' units, bit for bit (R = 2 shifted by
    2^-1 made the window's estimate differ in the last digits)."""
    u, y = _siso(3, 300)
    model = ARX(2, 2, 1)
    kw = {"form": form} if form == "square_root" else {}
    fit = model.fit(u, y, "rls", k0=0, P0=100.0, R=R, **kw, **options)
    Phi, target = model.regressors(u, y)
    f = cls(4, P0=100.0, R=R, **options)
    f.batch_filter(target, Phi)
    assert_array_equal(fit.theta_, f.x.reshape(fit.theta_.shape))
    assert_array_equal(fit.filter_.x, f.x)
