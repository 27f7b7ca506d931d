"""Change detection on a filter's normalized innovations: thresholds, false alarms,
detection of both changes of a piecewise plant, and the semantics of the actions."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import binomtest

from rlsfilt import RecursiveLeastSquares
from rlsfilt.validation import ChangeDetector, cusum_threshold

METHODS = ["cusum", "page_hinkley"]


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
        ChangeDetector("glr")
    with pytest.raises(ValueError, match="`action` must be one of"):
        ChangeDetector(action="restart")
    with pytest.raises(ValueError, match="`boost` must be"):
        ChangeDetector(boost=0.5)
    with pytest.raises(ValueError, match="`threshold` must be"):
        ChangeDetector(threshold=-1.0)
    with pytest.raises(ValueError, match="`S` must be a positive"):
        ChangeDetector().update(1.0, 0.0)
    assert ChangeDetector(threshold=3.0).threshold == 3.0


@pytest.mark.parametrize("method", METHODS)
def test_false_alarm_rate_on_a_filter_within_nominal(method):
    """A constant plant, R the true noise variance: the filter's normalized innovations
    are N(0, 1), and the alarms per sample are not more frequent than 1 / arl (binomial
    test at 1 %, over 40,000 samples)."""
    arl, alarms, samples = 200.0, 0, 0
    for seed in range(20):
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
