"""Change detection over the channels of an RLSBank: every channel equal to its own
ChangeDetector on its own RecursiveLeastSquares, actions included."""

import numpy as np
import pytest
from numpy.testing import assert_array_equal

from rlsfilt import RecursiveLeastSquares, RLSBank
from rlsfilt.validation import BankChangeDetector, ChangeDetector

METHODS = ["cusum", "page_hinkley", "glr"]
ACTIONS = ["none", "reset", "boost", "lambda"]


def fleet(seed, C=6, N=700):
    """C channels with a bias and a gain: channel c's parameters jump at 200 + 40 c and
    450 (channels 0 and 1 never jump); a few missing samples."""
    rng = np.random.default_rng(seed)
    H = np.stack([np.ones((N, C)), rng.standard_normal((N, C))], axis=-1)
    x = np.empty((N, C, 2))
    x[:] = [1.0, 0.5]
    for c in range(2, C):
        x[200 + 40 * c:, c] = [1.4, 0.8]
        x[450:, c] = [0.8, 0.3]
    z = np.sum(H * x, axis=-1) + 0.1 * rng.standard_normal((N, C))
    z[rng.random((N, C)) < 0.01] = np.nan
    return H, z


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("action", ACTIONS)
def test_bank_detector_equals_one_detector_per_channel(method, action):
    H, z = fleet(11)
    N, C = z.shape
    options = dict(arl=5000.0, shift=2.0, window=40, action=action, boost=50.0,
                   alarm_lam=0.85, hold=7)
    bank = RLSBank(C, 2, lam=0.999, R=0.01, P0=100.0)
    det = BankChangeDetector(C, method, **options)
    filters = [RecursiveLeastSquares(2, lam=0.999, R=0.01, P0=100.0) for _ in range(C)]
    dets = [ChangeDetector(method, **options) for _ in range(C)]
    for k in range(N):
        bank.predict_update(z[k], H[k])
        alarm = det.step(bank)
        for c in range(C):
            filters[c].predict_update(None if np.isnan(z[k, c]) else z[k, c], H[k, c])
            assert dets[c].step(filters[c]) == alarm[c]
        assert_array_equal(det.g_plus, [d.g_plus for d in dets])
        assert_array_equal(det.g_minus, [d.g_minus for d in dets])
        assert_array_equal(bank.lam, [f.lam for f in filters])
    assert [d.alarms for d in dets] == det.alarms
    assert_array_equal(det.n_samples, [d.n_samples for d in dets])
    assert_array_equal(bank.x, np.array([f.x[:, 0] for f in filters]))
    assert_array_equal(bank.P, np.array([f.P for f in filters]))
    # the jumping channels alarmed near their jumps (counted in samples seen: a few missing)
    for c in range(2, C):
        assert any(-10 <= a - (200 + 40 * c) <= 25 for a in det.alarms[c]), (c, det.alarms[c])


def test_reset_of_some_channels_equals_their_own_filters_reset():
    H, z = fleet(2, C=4)
    bank = RLSBank(4, 2, lam=0.99, R=0.01, P0=[1.0, 10.0, 100.0, 1000.0],
                   x0=[[1.0, 2.0], [0.0, 0.0], [3.0, 4.0], [5.0, 6.0]])
    filters = [bank.channel(c) for c in range(4)]
    for k in range(50):
        bank.predict_update(np.nan_to_num(z[k]), H[k])
        for c in range(4):
            filters[c].predict_update(np.nan_to_num(z[k, c]), H[k, c])
    y_before, n_updates = bank.y.copy(), bank.n_updates
    bank.reset([1, 3])
    filters[1].reset()
    filters[3].reset()
    bank.reset(np.array([False, False, False, False]))         # (a mask: nothing)
    assert_array_equal(bank.x, np.array([f.x[:, 0] for f in filters]))
    assert_array_equal(bank.P, np.array([f.P for f in filters]))
    assert_array_equal(bank.y, y_before)
    assert bank.n_updates == n_updates
    for k in range(50, 80):
        bank.predict_update(np.nan_to_num(z[k]), H[k])
        for c in range(4):
            filters[c].predict_update(np.nan_to_num(z[k, c]), H[k, c])
    assert_array_equal(bank.x, np.array([f.x[:, 0] for f in filters]))
    with pytest.raises(ValueError, match=r"`channels` must be in \[-4, 4\); got 0 .. 4"):
        bank.reset([0, 4])
    with pytest.raises(ValueError, match=r"`channels` as a mask must have shape \(4,\)"):
        bank.reset([True, False])
    with pytest.raises(TypeError, match="`channels` must be channel indices"):
        bank.reset([0.5])
    assert_array_equal(bank.x, np.array([f.x[:, 0] for f in filters]))   # (unchanged)


def test_run_equals_update_and_validation():
    H, z = fleet(5, C=3)
    bank = RLSBank(3, 2, R=0.01)
    ys, Ss = [], []
    for k in range(len(z)):
        bank.predict_update(z[k], H[k])
        ys.append(bank.y.copy())
        Ss.append(bank.S.copy())
    online = BankChangeDetector(3, "glr", arl=1000.0, window=30)
    alarms = np.array([online.update(y, s) for y, s in zip(ys, Ss, strict=True)])
    offline = BankChangeDetector(3, "glr", arl=1000.0, window=30).run(ys, Ss)
    assert_array_equal(offline, alarms)
    assert alarms.sum(axis=0).tolist() == [len(a) for a in online.alarms]
    assert alarms.any()
    det = BankChangeDetector(3)
    with pytest.raises(ValueError, match=r"`y` and `S` must have shape \(3,\)"):
        det.update([0.0, 1.0], [1.0, 1.0])
    with pytest.raises(ValueError, match="`S` must be a positive finite variance; got 0.0 "
                                         "for channel 2"):
        det.update([0.0, 1.0, 2.0], [1.0, 1.0, 0.0])
    assert det.n_steps == 0 and not det.n_samples.any()           # (nothing changed)
    det.update([np.nan, 1.0, 2.0], [0.0, 1.0, 1.0])                # (a skipped channel's S)
    assert det.n_samples.tolist() == [0, 1, 1]
    with pytest.raises(ValueError, match="`n_channels` must be"):
        BankChangeDetector(0)
    with pytest.raises(ValueError, match="`method` must be one of"):
        BankChangeDetector(2, "adwin")
    with pytest.raises(ValueError, match=r"`ys` and `Ss` must both have shape \(N, 3\)"):
        det.run(ys[0], Ss[0])
    assert "glr" in repr(online) and "3 channels" in repr(online)


def test_lambda_hold_of_a_bank_ends_on_reset():
    bank = RLSBank(3, 1, lam=[0.99, 0.98, 0.97], R=1.0)
    det = BankChangeDetector(3, "glr", threshold=1e-9, action="lambda", alarm_lam=0.5,
                             hold=3)
    bank.predict_update([1.0, np.nan, 1.0], [[1.0], [1.0], [1.0]])
    assert det.step(bank).tolist() == [True, False, True]
    assert bank.lam.tolist() == [0.5, 0.98, 0.5]
    det.reset()
    assert bank.lam.tolist() == [0.99, 0.98, 0.97]


@pytest.mark.parametrize("window", [1, 7, 64, 100])
def test_glr_pruned_decisions_equal_full_scans(rng, window):
    """The bank's GLR scans only the channels its CUSUM bounds flag: on many channels
    with shifts of every size the alarms are those of detectors that scan every window."""
    C, N = 150, 400
    e = rng.standard_normal((N, C))
    e[200:] += np.linspace(-2.0, 2.0, C)                  # shifts from -2 to 2 sd
    e[rng.random((N, C)) < 0.02] = np.nan
    det = BankChangeDetector(C, "glr", arl=300.0, window=window)
    alarms = det.run(e, np.ones((N, C)))
    singles = [ChangeDetector("glr", arl=300.0, window=window) for _ in range(C)]
    for c in range(C):
        for k in range(N):
            assert singles[c].update(e[k, c], 1.0) == alarms[k, c]
    assert [d.alarms for d in singles] == det.alarms
    assert_array_equal(det.g_plus, [d.g_plus for d in singles])
    assert_array_equal(det.g_minus, [d.g_minus for d in singles])
    assert alarms.sum() > C // 2
