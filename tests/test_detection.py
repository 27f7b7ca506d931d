"""Change detection on a filter's normalized innovations: thresholds, false alarms,
detection of both changes of a piecewise plant, and the semantics of the actions."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import binomtest

from rlsfilt import RecursiveLeastSquares
from rlsfilt.validation import ChangeDetector, cusum_threshold, glr_threshold

METHODS = ["cusum", "page_hinkley", "glr"]


def simulated_run_length(h, k, page_hinkley, rng, paths=3000):
    """Mean run length of the two-sided test on N(0, 1) data, all paths at once."""
    gp, gm, mean = np.zeros(paths), np.zeros(paths), np.zeros(paths)
    done, length, t = np.zeros(paths, bool), np.zeros(paths), 0
    while not done.all():
        t += 1
        e = rng.standard_normal(paths)
        if page_hinkley:
            mean += (e - mean) / t
            e = e - mean
        gp, gm = np.maximum(0.0, gp + e - k), np.maximum(0.0, gm - e - k)
        new = ~done & ((gp > h) | (gm > h))
        length[new], done = t, done | new
    return length.mean(), length.std() / math.sqrt(paths)


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(("arl", "shift"), [(200.0, 1.0), (500.0, 2.0)])
def test_siegmund_threshold_gives_the_run_length_by_simulation(rng, method, arl, shift):
    h = cusum_threshold(arl, shift)
    mean, se = simulated_run_length(h, shift / 2, method == "page_hinkley", rng)
    assert abs(mean - arl) < max(4 * se, 0.1 * arl), (mean, se)


def test_threshold_closed_form_and_validation():
    # Siegmund: each side's run length (e^{2kb} - 2kb - 1) / (2k^2), b = h + 1.166, is 2 arl
    h, k = cusum_threshold(1000.0, 1.0), 0.5
    b = h + 1.166
    assert_allclose((math.exp(2 * k * b) - 2 * k * b - 1) / (2 * k * k), 2000.0, rtol=1e-10)
    assert cusum_threshold(10_000.0, 1.0) > h > cusum_threshold(1000.0, 2.0)
    with pytest.raises(ValueError, match="`arl` must be a finite number > 1"):
        cusum_threshold(0.5)
    with pytest.raises(ValueError, match="`shift` must be a positive"):
        cusum_threshold(100.0, -1.0)
    with pytest.raises(ValueError, match="`method` must be one of"):
        ChangeDetector("glrt")
    with pytest.raises(ValueError, match="`action` must be one of"):
        ChangeDetector(action="restart")
    with pytest.raises(ValueError, match="`boost` must be"):
        ChangeDetector(boost=0.5)
    with pytest.raises(ValueError, match="`threshold` must be"):
        ChangeDetector(threshold=-1.0)
    with pytest.raises(ValueError, match="`S` must be a positive"):
        ChangeDetector().update(1.0, 0.0)
    assert ChangeDetector(threshold=3.0).threshold == 3.0
    with pytest.raises(ValueError, match="`window` must be an integer >= 1; got 0"):
        ChangeDetector("glr", window=0)
    with pytest.raises(ValueError, match="`alarm_lam` must be in"):
        ChangeDetector(action="lambda", alarm_lam=1.5)
    with pytest.raises(ValueError, match="`hold` must be an integer"):
        ChangeDetector(action="lambda", hold=0)
    assert ChangeDetector("glr", arl=500.0, window=50).threshold == glr_threshold(500.0, 50)


def simulated_glr_run_length(h, window, rng, paths=2000):
    """Mean run length of the two-sided window-limited GLR on N(0, 1) data (the
    statistic written out from its definition, all paths at once)."""
    recent = np.zeros((window, paths))
    done, length, t = np.zeros(paths, bool), np.zeros(paths), 0
    inv = 1.0 / (2.0 * np.arange(1, window + 1))
    while not done.all():
        t += 1
        recent = np.roll(recent, 1, axis=0)
        recent[0] = rng.standard_normal(paths)
        n = min(t, window)
        sums = np.cumsum(recent[:n], axis=0)
        g = np.max(sums * sums * inv[:n, None], axis=0)
        new = ~done & (g > h)
        length[new], done = t, done | new
    return length.mean(), length.std() / math.sqrt(paths)


@pytest.mark.slow
@pytest.mark.parametrize(("arl", "window"), [(200.0, 20), (500.0, 50)])
def test_glr_threshold_gives_the_run_length_by_simulation(rng, arl, window):
    """Siegmund & Venkatraman's approximation, solved for h: the simulated run length
    is within 10 % of the wanted one."""
    h = glr_threshold(arl, window)
    mean, se = simulated_glr_run_length(h, window, rng)
    assert abs(mean - arl) < 0.1 * arl + 3 * se, (mean, se)


def test_glr_threshold_closed_form():
    """The threshold solves 1/arl = b phi(b) int_{b/sqrt(M + 1/2)}^{b/sqrt(1/2)} x nu(x)^2 dx,
    b = sqrt(2 h), with Siegmund's nu (written out here, integrated by scipy)."""
    from scipy.integrate import quad
    from scipy.stats import norm

    def nu(x):
        return (2 / x) * (norm.cdf(x / 2) - 0.5) / ((x / 2) * norm.cdf(x / 2) + norm.pdf(x / 2))

    for arl, M in [(1000.0, 100), (300.0, 10), (1e5, 1)]:
        b = math.sqrt(2 * glr_threshold(arl, M))
        integral = quad(lambda x: x * nu(x) ** 2, b / math.sqrt(M + 0.5), b / math.sqrt(0.5),
                        epsabs=0, epsrel=1e-12)[0]
        assert_allclose(1 / (b * norm.pdf(b) * integral), arl, rtol=1e-9)
    # a longer window: more chances of a false alarm, a higher threshold
    assert glr_threshold(1000.0, 200) > glr_threshold(1000.0, 100) > glr_threshold(1000.0, 10)
    with pytest.raises(ValueError, match="`arl` must be a finite number > 1"):
        glr_threshold(1.0)
    with pytest.raises(ValueError, match="`window` must be an integer"):
        glr_threshold(100.0, 2.5)


def test_glr_statistic_is_its_definition(rng):
    """g+ and g- at every step are max over the last M windows of S^2 / (2 L), split by the
    sign of S, recomputed from scratch; the window restarts after an alarm."""
    e = rng.standard_normal(400)
    e[200:] += 1.5
    det = ChangeDetector("glr", window=30, arl=1000.0)
    start = 0
    for t in range(len(e)):
        alarm = det.update(e[t], 1.0)
        if alarm:
            assert det.g_plus == det.g_minus == 0.0
            start = t + 1
            continue
        gp = gm = 0.0
        for j in range(max(start, t - 29), t + 1):
            s = e[j:t + 1].sum()
            g = s * s / (2 * (t - j + 1))
            gp, gm = (max(gp, g), gm) if s > 0 else (gp, max(gm, g))
        assert_allclose([det.g_plus, det.g_minus], [gp, gm], rtol=1e-12, atol=1e-14)
    assert det.alarms and 200 <= det.alarms[0] <= 215


@pytest.mark.parametrize("method", METHODS)
def test_false_alarm_rate_on_a_filter_within_nominal(method):
    """A constant plant, R the true noise variance: the filter's normalized innovations
    are N(0, 1), and the alarms per sample are not more frequent than 1 / arl (binomial
    test at 1 %, over 40,000 samples)."""
    arl, alarms, samples = 200.0, 0, 0
    for seed in range(20 if method != "glr" else 10):
        rng = np.random.default_rng(500 + seed)
        H = np.column_stack([np.ones(2000), rng.standard_normal(2000)])
        z = H @ [1.0, 0.5] + 0.1 * rng.standard_normal(2000)
        rls = RecursiveLeastSquares(2, R=0.01)
        det = ChangeDetector(method, arl=arl, shift=1.0)
        for k in range(len(z)):
            rls.predict_update(z[k], H[k])
            det.step(rls)
        alarms, samples = alarms + len(det.alarms), samples + det.n_samples
    assert binomtest(alarms, samples, 1.0 / arl, alternative="greater").pvalue > 0.01
    assert alarms > 0.5 * samples / arl            # and not a detector that never alarms


def test_temporary_lambda_holds_then_restores_the_filters_own():
    """action="lambda": the `hold` updates after an alarm run with `alarm_lam` (each
    equal to a filter given that lam), then the filter's own lam is back."""
    H, z = piecewise_plant(6)
    rls = RecursiveLeastSquares(2, lam=0.995, R=0.01)
    det = ChangeDetector(arl=10_000, shift=2.0, action="lambda", alarm_lam=0.8, hold=5)
    lams = []
    for k in range(len(z)):
        rls.predict_update(z[k], H[k])
        lams.append(rls.lam)
        det.step(rls)
    first = det.alarms[0]
    assert 300 <= first <= 310
    lams = np.array(lams)
    held = np.zeros(len(z), bool)                 # the 5 samples after each alarm
    for a in det.alarms:
        held[a + 1:a + 6] = True
    assert_allclose(lams, np.where(held, 0.8, 0.995), rtol=0, atol=0)
    assert held.sum() >= 10                        # (two alarms at least)
    # the hold is exactly a filter whose lam is 0.8 for those samples
    ref = RecursiveLeastSquares(2, lam=0.995, R=0.01)
    for k in range(len(z)):
        ref.lam = lams[k]
        ref.predict_update(z[k], H[k])
    assert_allclose(ref.x, rls.x, rtol=0, atol=0)
    # reset() of the detector ends a hold in force
    rls2 = RecursiveLeastSquares(2, lam=0.99, R=0.01)
    det2 = ChangeDetector("glr", threshold=1e-9, action="lambda", alarm_lam=0.7, hold=50)
    rls2.predict_update(1.0, [1.0, 0.0])
    assert det2.step(rls2) and rls2.lam == 0.7
    det2.reset()
    assert rls2.lam == 0.99
    with pytest.raises(TypeError, match='action="lambda" needs a filter'):
        ChangeDetector(action="lambda").step(object())


def piecewise_plant(seed, N=900):
    """A bias and a gain that jump at samples 300 and 600 (by 3 and 4 noise
    standard deviations in the bias)."""
    rng = np.random.default_rng(seed)
    H = np.column_stack([np.ones(N), rng.standard_normal(N)])
    x = np.empty((N, 2))
    x[:300], x[300:600], x[600:] = [1.0, 0.5], [1.3, 0.8], [0.9, 0.2]
    return H, np.sum(H * x, axis=1) + 0.1 * rng.standard_normal(N)


@pytest.mark.parametrize("method", METHODS)
def test_both_changes_of_a_piecewise_plant_found_within_10_samples(method):
    found = 0
    for seed in range(50):
        H, z = piecewise_plant(seed)
        rls = RecursiveLeastSquares(2, R=0.01)
        det = ChangeDetector(method, arl=10_000, shift=2.0, action="boost")
        for k in range(len(z)):
            rls.predict_update(z[k], H[k])
            det.step(rls)
        a = np.array(det.alarms)
        found += all(np.any(np.abs(a - c) <= 10) for c in (300, 600))
    assert found >= 45, found


def test_alarm_restarts_the_statistics_and_reset_restarts_the_filter():
    """action="reset": from the sample after the alarm, the filter and the detector run
    exactly as a new filter and a new detector started there."""
    H, z = piecewise_plant(3)
    rls = RecursiveLeastSquares(2, R=0.01)
    det = ChangeDetector(arl=10_000, shift=2.0, action="reset")
    first = None
    for k in range(len(z)):
        rls.predict_update(z[k], H[k])
        if det.step(rls) and first is None:
            first = k
            assert det.g_plus == det.g_minus == 0.0
            assert_allclose(rls.x, np.zeros((2, 1)), rtol=0, atol=0)      # x0
            assert_allclose(rls.P, 1e4 * np.eye(2), rtol=0, atol=0)       # P0
            rest_filter = RecursiveLeastSquares(2, R=0.01)
            rest_det = ChangeDetector(arl=10_000, shift=2.0, action="reset")
        elif first is not None:
            rest_filter.predict_update(z[k], H[k])
            rest_det.step(rest_filter)
    assert 300 <= first <= 310
    assert_allclose(rls.x, rest_filter.x, rtol=0, atol=0)
    assert [a - first - 1 for a in det.alarms[1:]] == rest_det.alarms
    assert det.alarms[1] - 600 in range(0, 11)


def test_boost_keeps_the_estimate_and_scales_P_and_missing_samples_are_skipped():
    H, z = piecewise_plant(4)
    rls = RecursiveLeastSquares(2, R=0.01)
    det = ChangeDetector("page_hinkley", arl=10_000, shift=2.0, action="boost", boost=100.0)
    for k in range(len(z)):
        rls.predict_update(z[k], H[k])
        x, P = rls.x.copy(), rls.P.copy()
        if det.step(rls):
            assert_allclose(rls.x, x, rtol=0, atol=0)
            assert_allclose(rls.P, 100.0 * P, rtol=1e-15)
            assert det._mean == 0.0 and det.statistic == 0.0
    before = (det.n_samples, det.g_plus, det.g_minus)
    rls.predict_update(None, H[0])                    # a missing sample
    assert det.step(rls) is False
    assert (det.n_samples, det.g_plus, det.g_minus) == before
    assert "page_hinkley" in repr(det)


def test_run_over_a_record_equals_streaming(rng):
    H, z = piecewise_plant(5)
    rls = RecursiveLeastSquares(2, R=0.01)
    ys, ss = [], []
    det = ChangeDetector(arl=500.0, shift=2.0)
    for k in range(len(z)):
        rls.predict_update(z[k], H[k])
        det.step(rls)
        ys.append(rls.y[0, 0])
        ss.append(rls.S[0, 0])
    offline = ChangeDetector(arl=500.0, shift=2.0).run(ys, ss)
    assert offline.tolist() == det.alarms
    with pytest.raises(ValueError, match="same length"):
        ChangeDetector().run(ys, ss[:-1])
