"""delayest: recovers known delays; every loss equals numpy lstsq on the aligned rows."""

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt.data import IOData
from rlsfilt.datasets import thermal_process
from rlsfilt.validation import delay as delay_module
from rlsfilt.validation.delay import delayest

A = [1.0, -1.5, 0.7]


def _plant(rng, nk, n=1500, noise=0.1, b=(1.0, 0.5)):
    u = rng.standard_normal(n)
    e = noise * rng.standard_normal(n)
    y = lfilter(np.r_[np.zeros(nk), b], A, u) + lfilter([1.0], A, e)
    return u, y


def _aligned_losses(blocks, na, nb, ks, t_max):
    """Oracle: np.linalg.lstsq on explicitly built ARX regressors, rows t_max.. per block."""
    out = []
    for k in ks:
        Phis, targets = [], []
        for u, y in blocks:
            t = np.arange(t_max, len(y))
            cols = [-y[t - i] for i in range(1, na + 1)] + [u[t - k - m] for m in range(nb)]
            Phis.append(np.column_stack(cols))
            targets.append(y[t])
        Phi, target = np.vstack(Phis), np.concatenate(targets)
        res = target - Phi @ np.linalg.lstsq(Phi, target, rcond=None)[0]
        out.append(res @ res / len(target))
    return np.array(out)


@pytest.mark.parametrize("nk", [0, 1, 3, 7, 12])
def test_recovers_the_delay(rng, nk):
    u, y = _plant(rng, nk)
    assert delayest(u, y) == nk
    assert delayest(IOData(u, y, dt=0.1)) == nk


def test_losses_equal_lstsq(rng):
    u, y = _plant(rng, 5, n=800)
    est = delayest(u, y, na=2, nb=3, nk_min=1, nk_max=9, full_output=True)
    assert est.nk == 5 and list(est.nk_range[0]) == list(range(1, 10))
    t_max = 9 + 3 - 1
    ref = _aligned_losses([(u, y)], 2, 3, range(1, 10), t_max)
    np.testing.assert_allclose(est.losses[0], ref, rtol=1e-10)
    assert est.n_rows == 800 - t_max


def test_first_order_plant_with_spare_coefficient():
    """nb = 2 on a plant with one b coefficient: nk - 1 (b1 = 0) fits as well; the tie
    rule returns the true delay (thermal_process: 3 samples of dead time + the hold)."""
    ds = thermal_process()
    assert ds.nk == 4
    assert delayest(ds.u, ds.y) == 4
    assert delayest(ds.u, ds.y, na=1, nb=1) == 4


def test_three_inputs_per_input_delays(rng):
    n = 3000
    U = rng.standard_normal((n, 3))
    delays, bs = (1, 4, 9), ([1.0, 0.5], [-0.8, 0.4], [0.6, 0.6])
    forced = sum(lfilter(np.r_[np.zeros(k), b], [1.0], U[:, j])
                 for j, (k, b) in enumerate(zip(delays, bs)))
    y = lfilter([1.0], A, forced + 0.1 * rng.standard_normal(n))
    assert delayest(U, y) == delays
    est = delayest(U, y, nk_max=[5, 8, 12], full_output=True)
    assert est.nk == delays and [len(r) for r in est.nk_range] == [6, 9, 13]
    # the curve of input 2 (others at their delays) equals lstsq with all three blocks
    t_max = 12 + 2 - 1
    t = np.arange(t_max, n)
    ref = []
    for k in range(0, 13):
        ks = (1, 4, k)
        cols = [-y[t - 1], -y[t - 2]] + [U[t - ks[j] - m, j] for j in range(3) for m in range(2)]
        Phi = np.column_stack(cols)
        res = y[t] - Phi @ np.linalg.lstsq(Phi, y[t], rcond=None)[0]
        ref.append(res @ res / len(t))
    np.testing.assert_allclose(est.losses[2], ref, rtol=1e-10)


def test_experiments_never_straddle(rng):
    u1, y1 = _plant(rng, 3, n=400)
    u2, y2 = _plant(rng, 3, n=300)
    y2 = y2 + 50.0  # a different level: a straddling row would notice
    est = delayest(IOData([u1, u2], [y1, y2]), nk_max=6, full_output=True)
    t_max = 6 + 2 - 1
    ref = _aligned_losses([(u1, y1), (u2, y2)], 2, 2, range(0, 7), t_max)
    np.testing.assert_allclose(est.losses[0], ref, rtol=1e-10)
    glued = _aligned_losses([(np.r_[u1, u2], np.r_[y1, y2])], 2, 2, range(0, 7), t_max)
    assert np.max(np.abs(glued / ref - 1)) > 1e-3
    assert est.n_rows == 400 + 300 - 2 * t_max


def test_blocks_and_units_do_not_change_the_answer(rng, monkeypatch):
    u, y = _plant(rng, 7, n=600)
    ref = delayest(u, y, full_output=True)
    monkeypatch.setattr(delay_module, "_BLOCK_ROWS", 7)
    blocked = delayest(u, y, full_output=True)
    np.testing.assert_allclose(blocked.losses[0], ref.losses[0], rtol=1e-10)
    scaled = delayest(1e6 * u, 1e-3 * y, full_output=True)
    assert scaled.nk == 7
    np.testing.assert_allclose(scaled.losses[0], 1e-6 * ref.losses[0], rtol=1e-8)


def test_edge_of_the_range_warns(rng):
    u, y = _plant(rng, 12)
    with pytest.warns(UserWarning, match="delay of input 'u' is nk_max=12, the edge of the "
                                         "range tried; widen `nk_max`"):
        assert delayest(u, y, nk_max=12) == 12
    u, y = _plant(rng, 3)
    with pytest.warns(UserWarning, match="nk_min=5, the edge .* widen `nk_min`"):
        delayest(u, y, nk_min=5, nk_max=10)


def test_errors(rng):
    u, y = _plant(rng, 2, n=300)
    with pytest.raises(ValueError, match=r"too short for delays up to nk_max=500: 300 samples "
                                         r"leave 0 aligned rows for 504 regressor columns "
                                         r"\(the largest lag is 501\); "
                                         r"lower `nk_max` \(at most nk_max=147 fits\)"):
        delayest(u, y, nk_max=500)
    with pytest.raises(ValueError, match="`nk_max` must be >= `nk_min`; got nk_max=2 < "
                                         "nk_min=4"):
        delayest(u, y, nk_min=4, nk_max=2)
    with pytest.raises(ValueError, match="`y` must hold one output; got 2"):
        delayest(u, np.column_stack([y, y]))
    with pytest.raises(ValueError, match=r"`nb` must be an integer or have one entry per input "
                                         r"\(1\); got 2 entries"):
        delayest(u, y, nb=[2, 2])
    with pytest.raises(TypeError, match="`y` must be omitted when `u` is an IOData"):
        delayest(IOData(u, y), y)
    with pytest.raises(TypeError, match="`y` is required"):
        delayest(u)
    with pytest.raises(ValueError, match="`na` must be >= 0"):
        delayest(u, y, na=-1)


def test_ties_go_to_the_shortest_delay_with_a_significant_leading_coefficient():
    """Truth nk = 4 with one input coefficient (the model's nb = 2 exceeds it), SNR 19:
    nk = 3 ties but its leading coefficient is zero, nk = 5 can tie through noise."""
    from scipy.signal import lfilter

    found = []
    for seed in range(40):
        r = np.random.default_rng(seed)
        u = r.standard_normal(300)
        y = lfilter([0] * 4 + [0.3], [1, -0.8], u)
        found.append(delayest(u, y + r.standard_normal(300) * y.std() / np.sqrt(19)))
    assert found.count(4) >= 38, np.bincount(found)


@pytest.mark.parametrize("scale", [1e-160, 1e150, 1e160])
def test_delay_does_not_depend_on_the_units(scale):
    from scipy.signal import lfilter

    r = np.random.default_rng(7)
    u = r.standard_normal(1000)
    y = lfilter([0] * 7 + [1.0, 0.5], [1, -1.5, 0.7], u) + 0.1 * r.standard_normal(1000)
    assert delayest(u * scale, y * scale) == delayest(u, y) == 7
    assert delayest(u, y * scale) == 7


def test_a_huge_nk_max_is_refused_at_once(monkeypatch):
    from rlsfilt.validation import delay

    calls = []
    rows = delay._rows
    monkeypatch.setattr(delay, "_rows", lambda *a: calls.append(1) or rows(*a))
    r = np.random.default_rng(1)
    with pytest.raises(ValueError, match=r"at most nk_max=497 fits"):
        delayest(r.standard_normal(1000), r.standard_normal(1000), nk_max=10**9)
    assert len(calls) < 100      # bisection, not one step per candidate delay


def test_an_edge_delay_is_checked_against_the_impulse_response():
    """Issue #28, 7: the ARX(2, 2) test models fit a long, rising response best at the
    largest delay tried, while the impulse response is plainly nonzero from lag 3 (the
    truth: g(k) = 0 for k < 3). delayest checks the edge against impulseest and returns 3,
    with a warning; the losses alone point to the edge."""
    from rlsfilt.exceptions import OrderSelectionWarning

    rng = np.random.default_rng(1)
    N = 3000
    g = np.r_[np.zeros(3), 0.02 * np.arange(1, 39)]
    u = rng.standard_normal(N)
    y = lfilter(g, [1.0], u) + 0.1 * rng.standard_normal(N)
    with pytest.warns(OrderSelectionWarning, match="smallest at the edge nk_max=20, but its "
                                                   "impulse response estimate .* significant "
                                                   "from lag 3 on: returning nk=3"):
        est = delayest(u, y, full_output=True)
    assert est.nk == 3
    assert int(np.argmin(est.losses[0])) == 20          # the losses alone: the edge


@pytest.mark.parametrize("method", ["linear", "logarithmic"])
def test_a_sweep_whose_delay_lies_beyond_the_range_keeps_the_losses_answer(method, monkeypatch):
    """A swept sine into a slow plant with a dead time of 12 samples, delays tried up to 10.
    An impulse estimate cut off at nk_max + nb + 10 = 22 lags, long before the response dies
    out, is biased and shows lag 3 or 0 as significant (it moved the answer there); the
    check lengthens it until its tail is insignificant, finds nothing before the range's
    end, and leaves the answer of the losses (at or next to the edge, with no impulse
    warning). With the range widened the delay is found."""
    import warnings

    from scipy.signal import chirp

    from rlsfilt.validation import impulseest

    N = 2000
    rng = np.random.default_rng(0)
    u = chirp(np.arange(N), f0=0.001, t1=N, f1=0.45, method=method)
    y = lfilter(np.r_[np.zeros(12), 0.3, 0.2], A, u) + 0.05 * rng.standard_normal(N)
    cut = impulseest(u, y, n_coeffs=22)
    assert cut.delay(familywise=True) < 5 and cut.truncated()
    assert "not died out within 22 lags" in str(cut.summary())
    assert not impulseest(u, y, n_coeffs=50).truncated()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        found = delayest(u, y, nk_max=10)
    assert not any("impulse" in str(w.message) for w in caught)
    with monkeypatch.context() as m, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        m.setattr(delay_module, "_impulse_check", lambda *args: [])
        assert found == delayest(u, y, nk_max=10) >= 9
    assert delayest(u, y, nk_max=20) == 12
