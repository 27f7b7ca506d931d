"""SlidingWindowRLS against least squares on the window."""

import numpy as np
import pytest
from conftest import arx_record
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import SlidingWindowRLS


def _window_lstsq(Hs, zs, k, window, Rs=None):
    lo = max(0, k - window + 1)
    H, z = Hs[lo:k + 1], zs[lo:k + 1]
    w = np.ones(len(H)) if Rs is None else 1.0 / np.sqrt(Rs[lo:k + 1])
    keep = ~np.isnan(z.reshape(len(z), -1)).any(axis=1)
    A = H[keep] * w[keep, None]
    B = z[keep] * (w[keep, None] if z.ndim == 2 else w[keep])
    return np.linalg.lstsq(A, B, rcond=None)[0], np.linalg.inv(A.T @ A)


@pytest.mark.parametrize("refresh", [None, 0])
def test_equals_windowed_lstsq_at_every_step(rng, refresh):
    Hs, zs = arx_record(rng, n_samples=1502)
    window = 30
    sw = SlidingWindowRLS(4, window, refresh=refresh)
    for k in range(len(zs)):
        sw.predict_update(zs[k], Hs[k])
        if k >= window - 1:
            x, P = _window_lstsq(Hs, zs, k, window)
            assert_allclose(sw.x[:, 0], x, rtol=0, atol=1e-7 * max(1.0, np.abs(x).max()))
            assert_allclose(sw.P, P, rtol=1e-7, atol=1e-9 * np.abs(P).max())
    assert sw.exact and sw.n_samples == window


def test_weighted_multi_output_and_missing(rng):
    Hs, zs1 = arx_record(rng, n_samples=402)
    zs = np.column_stack([zs1, 2.0 * zs1 + rng.standard_normal(len(zs1))])
    zs[[50, 51, 200, 333]] = np.nan
    Rs = rng.uniform(0.5, 2.0, len(zs))
    window = 25
    sw = SlidingWindowRLS(4, window, dim_z=2)
    means, covs, _, _ = sw.batch_filter(zs, Hs, Rs=Rs)
    for k in range(window - 1, len(zs)):
        x, P = _window_lstsq(Hs, zs, k, window, Rs)
        assert_allclose(means[k], x, rtol=0, atol=1e-7 * max(1.0, np.abs(x).max()))
        assert_allclose(covs[k], P, rtol=1e-7, atol=1e-9 * np.abs(P).max())


def test_prior_is_ridge_until_window_fills(rng):
    Hs, zs = arx_record(rng, n_samples=22)
    sw = SlidingWindowRLS(4, 20, P0=5.0)
    for k in range(19):
        sw.update(zs[k], Hs[k])
        H, z = Hs[:k + 1], zs[:k + 1]
        ridge = np.linalg.solve(H.T @ H + np.eye(4) / 5.0, H.T @ z)
        assert_allclose(sw.x[:, 0], ridge, rtol=1e-9, atol=1e-12)
        assert not sw.exact
    sw.update(zs[19], Hs[19])
    assert sw.exact
    assert_allclose(sw.x[:, 0], np.linalg.lstsq(Hs[:20], zs[:20], rcond=None)[0], rtol=1e-9)


def test_initialize_then_slide(rng):
    Hs, zs = arx_record(rng, n_samples=200)
    window = 15
    sw = SlidingWindowRLS(4, window, R=0.5)
    sw.initialize(zs[:40], Hs[:40])        # only the last `window` rows are kept
    assert sw.exact and sw.n_samples == window
    x, P = _window_lstsq(Hs, zs, 39, window)
    assert_allclose(sw.x[:, 0], x, rtol=1e-9)
    assert_allclose(sw.P, 0.5 * P, rtol=1e-9)
    for k in range(40, len(zs)):
        sw.update(zs[k], Hs[k])
        assert_allclose(sw.x[:, 0], _window_lstsq(Hs, zs, k, window)[0], rtol=0, atol=1e-7)
    short = SlidingWindowRLS(4, window)
    short.initialize(zs[:6], Hs[:6])       # fewer rows than the window: grows first
    for k in range(6, 30):
        short.update(zs[k], Hs[k])
        assert_allclose(short.x[:, 0], _window_lstsq(Hs, zs, k, window)[0], rtol=0, atol=1e-7)


def test_unexciting_window_falls_back_to_prior_and_recovers(rng):
    N, window = 400, 20
    u = rng.standard_normal(N)
    u[100:200] = 1.0                                  # regressors [u(t), u(t-1)] = [1, 1]
    Hs = np.column_stack([u[1:], u[:-1]])
    zs = Hs @ [2.0, -1.0] + 0.01 * rng.standard_normal(N - 1)
    sw = SlidingWindowRLS(2, window)
    means, covs, _, _ = sw.batch_filter(zs, Hs)
    assert np.isfinite(means).all() and np.isfinite(covs).all()
    assert np.all(np.linalg.eigvalsh(covs)[:, 0] > 0)
    assert sw.exact
    for k in range(260, N - 1):
        assert_allclose(means[k, :, 0], _window_lstsq(Hs, zs, k, window)[0], atol=1e-7)


def test_batch_filter_equals_stepwise(rng):
    Hs, zs = arx_record(rng, n_samples=150)
    a = SlidingWindowRLS(4, 12)
    m, c, mp, cp = a.batch_filter(zs, Hs, update_first=True)
    b = SlidingWindowRLS(4, 12)
    for k in range(len(zs)):
        b.update(zs[k], Hs[k])
        assert_array_equal(m[k], b.x)
        assert_array_equal(c[k], b.P)
        b.predict()
        assert_array_equal(mp[k], b.x)
    assert_array_equal(a.y, b.y)
    assert "window" in repr(a)
    a.reset()
    assert a.n_samples == 0 and not a.exact
    assert_array_equal(a.P, 1e4 * np.eye(4))


def test_bad_arguments(rng):
    with pytest.raises(ValueError, match=r"`window` must be >= 3; got 2"):
        SlidingWindowRLS(3, 2)
    with pytest.raises(TypeError, match=r"`window` must be an integer; got 2.5"):
        SlidingWindowRLS(1, 2.5)
    with pytest.raises(ValueError, match=r"`refresh` must be >= 0; got -1"):
        SlidingWindowRLS(1, 5, refresh=-1)
    sw = SlidingWindowRLS(2, 5)
    with pytest.raises(ValueError, match=r"`Hs` is rank-deficient: the last 5 samples have rank "
                                         r"1; need 2"):
        sw.initialize(np.ones(8), np.ones((8, 2)))
    with pytest.raises(ValueError, match=r"`H` must have shape \(2,\) or \(1, 2\)"):
        sw.update(1.0, [1.0, 2.0, 3.0])


def test_saver_round_trip(rng):
    from filterpy.common import Saver

    Hs, zs = arx_record(rng, n_samples=42)
    sw = SlidingWindowRLS(4, 10)
    saver = Saver(sw)
    means, covs, _, _ = sw.batch_filter(zs, Hs, saver=saver)
    saver.to_array()
    assert_array_equal(saver.x, means)
    assert_array_equal(saver.P, covs)
