"""segment (MATLAB's segment): change times of a piecewise ARX plant, per-segment
least squares, and the dynamic programme's optimality against brute force."""

import itertools
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.signal import lfilter

from rlsfilt.models import arx_regressors
from rlsfilt.validation import Segmentation, segment


def piecewise_arx(seed, N=900):
    """y(t) = -a y(t-1) + b1 u(t-1) + b2 u(t-2) + e(t), the parameters jumping at
    samples 300 and 600."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    e = 0.1 * rng.standard_normal(N)
    theta = np.empty((N, 3))
    theta[:300], theta[300:600], theta[600:] = [-0.5, 1.0, 0.3], [-0.8, 0.6, 0.5], \
        [-0.3, 1.2, -0.2]
    y = np.zeros(N)
    for t in range(2, N):
        a, b1, b2 = theta[t]
        y[t] = -a * y[t - 1] + b1 * u[t - 1] + b2 * u[t - 2] + e[t]
    return u, y, theta


@pytest.mark.slow
@pytest.mark.parametrize("R2", [0.01, None])
def test_both_changes_of_a_piecewise_plant_within_10_samples(R2):
    found = 0
    for seed in range(50):
        u, y, _ = piecewise_arx(seed)
        seg = segment(y, u, na=1, nb=2, R2=R2)
        c = seg.change_times
        found += len(c) == 2 and abs(c[0] - 300) <= 10 and abs(c[1] - 600) <= 10
    assert found >= 45, found


def test_per_segment_parameters_are_least_squares_on_their_rows():
    u, y, theta = piecewise_arx(3)
    seg = segment(y, u, na=1, nb=2, R2=0.01)
    assert isinstance(seg, Segmentation)
    Phi, z = arx_regressors(u, y, na=1, nb=2)          # row r is sample r + 2
    assert seg.max_lag == 2 and seg.segments[0][0] == 2 and seg.segments[-1][1] == 900
    for (a, b), th, cov, rss in zip(seg.segments, seg.theta, seg.covariances, seg.rss,
                                    strict=True):
        A, t = Phi[a - 2:b - 2], z[a - 2:b - 2]
        ref, res = np.linalg.lstsq(A, t, rcond=None)[:2]
        assert_allclose(th, ref, rtol=1e-10, atol=1e-12)
        assert_allclose(rss, res[0], rtol=1e-10)
        assert_allclose(cov, 0.01 * np.linalg.inv(A.T @ A), rtol=1e-10)
        assert_allclose(th, theta[a], atol=0.06)                    # (and near the truth)
    params = seg.parameters
    assert np.isnan(params[:2]).all()
    assert_allclose(params[seg.segments[1][0]], seg.theta[1], rtol=0, atol=0)
    unknown = segment(y, u, na=1, nb=2)                             # R2 estimated per segment
    for (a, b), var, rss in zip(unknown.segments, unknown.noise_variances, unknown.rss,
                                strict=True):
        assert_allclose(var, rss / (b - a - 3), rtol=1e-12)


def brute_force(Phi, z, R2, penalty, m):
    """The best criterion over every segmentation into segments of >= m rows, each
    segment's loss by numpy lstsq."""
    N, best = len(z), (math.inf, None)

    def loss(a, b):
        r = z[a:b] - Phi[a:b] @ np.linalg.lstsq(Phi[a:b], z[a:b], rcond=None)[0]
        rss = r @ r
        return rss / R2 if R2 is not None else (b - a) * math.log(rss / (b - a))

    for k in range(N // m):                                    # k changes
        for cuts in itertools.combinations(range(m, N - m + 1), k):
            edges = (0, *cuts, N)
            if any(b - a < m for a, b in itertools.pairwise(edges)):
                continue
            v = sum(loss(a, b) for a, b in itertools.pairwise(edges)) + penalty * k
            if v < best[0]:
                best = (v, list(edges[:-1]))
    return best


@pytest.mark.parametrize(("R2", "penalty", "seed"), [(0.04, 3.0, 0), (0.04, 0.5, 1),
                                                     (None, 2.0, 2), (None, 8.0, 3)])
def test_dynamic_programme_finds_the_brute_force_optimum(R2, penalty, seed):
    rng = np.random.default_rng(seed)
    N = 16
    u = rng.standard_normal(N + 1)
    y = np.r_[0.0, np.where(np.arange(N) < 7, 1.0, -0.5) * u[:-1]
              + 0.2 * rng.standard_normal(N)]
    seg = segment(y, u, na=0, nb=1, nk=1, R2=R2, penalty=penalty, min_length=3)
    Phi, z = arx_regressors(u, y, na=0, nb=1, nk=1)
    v, starts = brute_force(Phi, z, R2, penalty, 3)
    assert_allclose(seg.objective, v, rtol=1e-9)
    assert [a - seg.max_lag for a, _ in seg.segments] == starts


def test_ar_model_validation_summary_and_plot():
    rng = np.random.default_rng(4)
    y = np.zeros(600)
    for t in range(2, 600):
        a1, a2 = (-1.2, 0.5) if t < 250 else (-0.4, 0.3)
        y[t] = -a1 * y[t - 1] - a2 * y[t - 2] + rng.standard_normal()
    seg = segment(y, na=2, R2=1.0)
    assert seg.n_segments == 2 and abs(seg.change_times[0] - 250) <= 10
    Phi = np.column_stack([-y[1:-1], -y[:-2]])
    a = seg.segments[0][0] - 2
    b = seg.segments[0][1] - 2
    assert_allclose(seg.theta[0], np.linalg.lstsq(Phi[a:b], y[2:][a:b], rcond=None)[0],
                    rtol=1e-10)
    assert "2 segment(s)" in str(seg.summary()) and "changes at" in repr(seg)
    assert seg._repr_html_().startswith("<pre class='rlsfilt-summary'>Segmentation, 2 segment(s)")
    assert seg.std_errors().shape == (2, 2)
    ax = seg.plot(names=["a1", "a2"], true_values=np.zeros((600, 2)))
    assert ax.get_title() == "2 segment(s)"
    with pytest.raises(ValueError, match="`nb` must be 0 for an AR model"):
        segment(y, na=2, nb=1)
    with pytest.raises(ValueError, match="`q` must be in"):
        segment(y, na=2, q=1.0)
    with pytest.raises(ValueError, match="`R2` must be a positive"):
        segment(y, na=2, R2=-1.0)
    with pytest.raises(ValueError, match="`min_length` must be"):
        segment(y, na=2, min_length=2)
    with pytest.raises(ValueError, match="`penalty` must be"):
        segment(y, na=2, penalty=-1.0)
    with pytest.raises(ValueError, match="`y` must have shape"):
        segment(np.zeros((5, 2)), na=1)
    with pytest.raises(ValueError, match="regression rows"):
        segment(y[:8], na=2)


def piecewise_armax(seed, N=900, c=0.7):
    """The plant of `piecewise_arx` with coloured noise e(t) + c e(t-1): an ARMAX
    whose a, b jump at samples 300 and 600 (c constant); returns u, y, theta, e."""
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    e = 0.1 * rng.standard_normal(N)
    theta = np.empty((N, 4))
    theta[:300], theta[300:600], theta[600:] = [-0.5, 1.0, 0.3, c], [-0.8, 0.6, 0.5, c], \
        [-0.3, 1.2, -0.2, c]
    y = np.zeros(N)
    for t in range(2, N):
        a, b1, b2, c1 = theta[t]
        y[t] = -a * y[t - 1] + b1 * u[t - 1] + b2 * u[t - 2] + e[t] + c1 * e[t - 1]
    return u, y, theta, e


@pytest.mark.slow
@pytest.mark.parametrize("R2", [0.01, None])
def test_armax_changes_within_10_samples_and_estimates_within_their_standard_errors(R2):
    found, z = 0, []
    for seed in range(50):
        u, y, theta, _ = piecewise_armax(seed)
        seg = segment(y, u, na=1, nb=2, nc=1, R2=R2)
        c = seg.change_times
        ok = len(c) == 2 and abs(c[0] - 300) <= 10 and abs(c[1] - 600) <= 10
        found += ok
        if ok:
            for (a, b), th, se in zip(seg.segments, seg.theta, seg.std_errors(), strict=True):
                z.append((th - theta[(a + b) // 2]) / se)
    assert found >= 45, found
    z = np.array(z)                          # ~N(0, 1): the covariances are honest
    assert np.abs(z).max() < 4.0, np.abs(z).max(axis=0)
    assert np.all((np.std(z, axis=0) > 0.75) & (np.std(z, axis=0) < 1.25)), np.std(z, axis=0)


def test_armax_segments_are_least_squares_on_the_extended_rows():
    u, y, theta, _ = piecewise_armax(5)
    seg = segment(y, u, na=1, nb=2, nc=1, R2=0.01)
    assert seg.orders == (1, 2, 1, 1) and seg.theta.shape == (3, 4)
    assert seg.change_times.tolist() == [300, 600]
    e = seg.innovations
    m = seg.max_lag                          # the long ARX model's lags, then e(t - 1)
    assert m > 2 and np.isnan(e[:m - 1]).all() and np.isfinite(e[m - 1:]).all()
    Phi, z = arx_regressors(u, y, na=1, nb=2)                       # row r is sample r + 2
    ext = np.column_stack([Phi[m - 2:], e[m - 1:-1]])
    z = z[m - 2:]
    for (a, b), th, cov, rss in zip(seg.segments, seg.theta, seg.covariances, seg.rss,
                                    strict=True):
        A, t = ext[a - m:b - m], z[a - m:b - m]
        ref, res = np.linalg.lstsq(A, t, rcond=None)[:2]
        assert_allclose(th, ref, rtol=1e-10, atol=1e-12)
        assert_allclose(rss, res[0], rtol=1e-10)
        # the pseudo-linear regression's covariance, psi = phi / C(q)
        Psi = lfilter([1.0], [1.0, th[3]], A, axis=0)
        M = np.linalg.inv(A.T @ Psi)
        assert_allclose(cov, 0.01 * M @ (A.T @ A) @ M.T, rtol=1e-10)
        assert np.all(np.abs(th - theta[(a + b) // 2]) < 4 * np.sqrt(np.diag(cov)))
    # the innovations are those of the piecewise model: e = (y - phi^T [a; b]) / C(q)
    # (up to the last round's update of the parameters)
    _, _, _, e_true = piecewise_armax(5)
    assert np.std(e[m:] - e_true[m:]) < 0.02


@pytest.mark.parametrize(("R2", "penalty", "seed"), [(0.04, 3.0, 0), (0.04, 0.5, 1),
                                                     (None, 2.0, 2), (None, 8.0, 3)])
def test_armax_dynamic_programme_with_given_innovations_is_the_brute_force_optimum(
        R2, penalty, seed):
    rng = np.random.default_rng(seed)
    N = 16
    u = rng.standard_normal(N + 1)
    e = 0.2 * rng.standard_normal(N + 1)
    y = np.r_[0.0, np.where(np.arange(N) < 7, 1.0, -0.5) * u[:-1] + e[1:] + 0.6 * e[:-1]]
    seg = segment(y, u, na=0, nb=1, nk=1, nc=1, innovations=e, R2=R2, penalty=penalty,
                  min_length=3)
    assert seg.max_lag == 1 and seg.innovations is not None
    Phi, z = arx_regressors(u, y, na=0, nb=1, nk=1)
    ext = np.column_stack([Phi, e[:-1]])
    v, starts = brute_force(ext, z, R2, penalty, 3)
    assert_allclose(seg.objective, v, rtol=1e-9)
    assert [a - seg.max_lag for a, _ in seg.segments] == starts
    for (a, b), th, cov in zip(seg.segments, seg.theta, seg.covariances, strict=True):
        A = ext[a - 1:b - 1]
        assert_allclose(th, np.linalg.lstsq(A, z[a - 1:b - 1], rcond=None)[0], rtol=1e-10)
        if R2 is not None:                   # given innovations: the ordinary covariance
            assert_allclose(cov, R2 * np.linalg.inv(A.T @ A), rtol=1e-10)


def test_arma_segmentation_and_armax_argument_errors():
    rng = np.random.default_rng(6)
    e = rng.standard_normal(800)
    y = np.zeros(800)
    for t in range(1, 800):
        a = -0.5 if t < 400 else 0.5
        y[t] = -a * y[t - 1] + e[t] + 0.7 * e[t - 1]
    seg = segment(y, na=1, nc=1, R2=1.0)
    assert seg.orders == (1, 0, 1, 0) and seg.n_segments == 2
    assert abs(seg.change_times[0] - 400) <= 10
    assert np.all(np.abs(seg.theta - [[-0.5, 0.7], [0.5, 0.7]]) < 4 * seg.std_errors())
    assert "orders (1, 0, 1, 0)" in str(seg.summary())
    ma = segment(y, na=0, nc=1)                  # a moving average: [c_1] per segment
    assert ma.theta.shape[1] == 1
    u = rng.standard_normal(800)
    with pytest.raises(ValueError, match="`innovations` are regressed on only in an ARMAX"):
        segment(y, u, na=1, nb=1, innovations=e)
    with pytest.raises(ValueError, match=r"`innovations` must be finite with the shape"):
        segment(y, u, na=1, nb=1, nc=1, innovations=e[:-1])
    with pytest.raises(ValueError, match="non-finite"):
        segment(y, u, na=1, nb=1, nc=1, innovations=np.r_[np.nan, e[1:]])
    with pytest.raises(ValueError, match="`nc` must be"):
        segment(y, u, na=1, nb=1, nc=-1)
    with pytest.raises(ValueError, match="`n_iter` must be"):
        segment(y, u, na=1, nb=1, nc=1, n_iter=0)
    with pytest.raises(ValueError, match=r"`na` \(or `nc`\) must be >= 1"):
        segment(y, na=0)
