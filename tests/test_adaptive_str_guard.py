"""SelfTuningRegulator guards (#29): verified designs, no lock-in near a common factor, the
saturation watchdog, finite-value checks, offsets (the tank); rst_design(cancel_zeros=True)."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import RecursiveLeastSquares, RegulatorWarning
from rlsfilt.adaptive import RSTController, SelfTuningRegulator, rst_design

# the lock-in scenario of #29: a first-order plant, ARX(2, 2, 1) estimated, |u| <= 2
A1, B1 = np.array([1.0, -0.8]), np.array([0.0, 0.5])
DESIGN = dict(Am=np.poly([0.5, 0.6]), Ao=np.poly([0.2, 0.3]))


def _run(stre, N, plant, noise=0.01, seed=0, dither=0.01, period=100):
    """Close the loop around A y = B u + e (zero before t = 0), square-wave reference."""
    Ap, Bp = plant
    rng = np.random.default_rng(seed)
    r = np.where(np.arange(N) % period < period // 2, 1.0, -1.0)
    d = dither * rng.choice([-1.0, 1.0], N)
    e = noise * rng.standard_normal(N)
    L = max(len(Ap), len(Bp))
    y, u = np.zeros(N + L), np.zeros(N + L)
    for k in range(L, N + L):
        y[k] = (-Ap[1:] @ y[k - 1:k - len(Ap):-1] + Bp[1:] @ u[k - 1:k - len(Bp):-1]
                + e[k - L])
        u[k] = stre.step(y[k], r[k - L], dither=d[k - L])
    return y[L:], u[L:], r


def _lockin(seed, **kwargs):
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), DESIGN, na=2, nb=2, nk=1,
                               u_limits=(-2.0, 2.0), **kwargs)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        y, u, r = _run(stre, 1600, (A1, B1), seed=seed)
    rms = float(np.sqrt(np.mean((y - r) ** 2)))
    return stre, rms, float(np.mean(np.abs(u) == 2.0)), [str(w.message) for w in caught
                                                          if w.category is RegulatorWarning]


def test_the_lock_in_of_issue_29_is_reproduced_by_the_single_threshold_and_now_warned():
    """Seed 2 with the old acceptance rule (one threshold, any size): a controller of size
    ~1e3 accepted just above coprime_tol, later designs rejected, u saturated most of the time."""
    stre, rms, sat, messages = _lockin(2, reduce_tol=0.0, max_growth=1e300)
    h = stre.history
    assert rms > 1.2 and sat > 0.5 and h.rejected.sum() > 700
    assert np.abs(h.R[-1]).max() > 100                     # a controller root far outside
    # the watchdog says so, once, and so does the run of rejected designs
    watchdog = [m for m in messages if "sat at a limit" in m]
    assert len(watchdog) == 1 and "RMS error r - y grew" in watchdog[0]
    assert any("redesigns in a row" in m and "still in use" in m for m in messages)


def test_the_lock_in_scenario_ends_like_the_other_seeds_with_a_warning():
    stre, rms, sat, messages = _lockin(2)
    others = [_lockin(seed)[1] for seed in (1, 5)]          # seeds the old rule handled well
    assert rms < 0.5 and sat < 0.01
    assert abs(rms - np.mean(others)) < 0.05
    assert any("nearly cancels a pole against a zero" in m and "consider smaller na, nb" in m
               for m in messages)
    h = stre.history
    assert h.reduced.sum() > 1000                          # the reduced model carries the loop
    # every installed controller: a stable loop on its estimate, growth within max_growth
    installed = np.flatnonzero(h.redesigned & ~h.rejected)
    sizes = []
    for t in installed:
        A = np.r_[1.0, h.theta[t, :2]]
        B = np.r_[0.0, h.theta[t, 2:]]
        char = np.polyadd(np.convolve(A, h.R[t])[::-1], np.convolve(B, h.S[t])[::-1])[::-1]
        assert np.abs(np.roots(np.trim_zeros(char, "b"))).max() < 1.0
        sizes.append((np.abs(h.R[t]).sum() + np.abs(h.S[t]).sum() + np.abs(h.T[t]).sum())
                     / abs(h.R[t, 0]))
    growth = np.array(sizes[1:]) / np.array(sizes[:-1])
    assert growth.max() <= 10.0 * (1 + 1e-12)
    # the controller in the end is the first-order design on the (nearly) true plant
    want = rst_design(A1, B1, DESIGN["Am"], [1.0])
    assert_allclose(np.trim_zeros(h.R[-1], "b"), want.R, atol=0.02)
    assert_allclose(np.trim_zeros(h.S[-1], "b"), want.S, atol=0.05)


def test_a_design_that_always_fails_warns_once_that_the_loop_is_open():
    def never(A_, B_):
        raise ValueError("no design today")

    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), never, na=2, nb=2,
                               patience=20)
    with pytest.warns(RegulatorWarning, match=r"20 redesigns in a row up to step 19 were "
                                              r"rejected \(the last because the full design "
                                              r"raised ValueError: no design today\); there is "
                                              r"no controller: the loop is open") as caught:
        _run(stre, 100, (A1, B1))
    assert len([w for w in caught if w.category is RegulatorWarning]) == 1
    assert stre.controller is None and stre.history.rejected.all()
    # with an initial controller the warning says it is kept
    initial = rst_design(A1, B1, np.poly([0.5]), [1.0])
    kept = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), never, na=2, nb=2,
                               initial=initial, patience=20)
    with pytest.warns(RegulatorWarning, match=r"controller designed at an earlier step is "
                                              r"still in use"):
        _run(kept, 60, (A1, B1))
    assert_array_equal(np.trim_zeros(kept.controller.R, "b"), initial.R)


def test_a_design_that_grows_too_fast_is_rejected_and_named():
    def huge(A_, B_):
        return RSTController([1.0, -1.0], [0.3], [3000.0])   # a stable loop, a huge T

    initial = RSTController([1.0, -1.0], [0.3], [0.3])
    stre = SelfTuningRegulator(RecursiveLeastSquares(2, P0=1e-6, x0=[-0.8, 0.5]), huge, na=1,
                               nb=1, initial=initial, patience=5)
    with pytest.warns(RegulatorWarning, match=r"the full design has size 3e\+03, more than "
                                              r"max_growth = 10 times the size 2\.6"):
        _run(stre, 10, (A1, B1))
    assert stre.history.rejected.all()


@pytest.mark.parametrize("value, match", [
    (1e150, r"`y` = 1e\+150 at step 3 exceeds signal_limit = 1e\+100: the loop is diverging"),
    (np.nan, r"`y` must be finite; got nan at step 3"),
    (np.inf, r"`y` must be finite; got inf at step 3"),
])
def test_a_huge_or_nan_measurement_is_a_clear_error_and_changes_nothing(value, match):
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), DESIGN, na=2, nb=2)
    for y in (0.1, 0.2, 0.3):
        stre.step(y, 1.0)
    before = stre.state
    with pytest.raises(ValueError, match=match):
        stre.step(value, 1.0)
    assert_array_equal(stre.state, before)
    assert len(stre.history) == 3
    with pytest.raises(ValueError, match=r"`r` must be finite; got nan at step 3"):
        stre.step(0.4, np.nan)
    stre.step(0.4, 1.0)                                    # and it goes on
    # the python-control system checks the same
    sys = stre.as_iosystem()
    assert sys.nstates == len(stre.state)


def test_a_computed_control_beyond_the_limit_is_a_clear_error():
    initial = RSTController([1.0], [0.0], [1e120])
    stre = SelfTuningRegulator(RecursiveLeastSquares(2, P0=1e-6, x0=[-0.8, 0.5]),
                               lambda A_, B_: initial, na=1, nb=1, initial=initial)
    with pytest.raises(ValueError, match=r"the computed `u` = 1e\+120 at step 0 exceeds "
                                         r"signal_limit"):
        stre.step(0.0, 1.0)
    assert len(stre.history) == 0


# ----------------------------------------------------------------------
# operating points: the tank with square-root outflow, a plant with an affine equilibrium
# ----------------------------------------------------------------------
AREA, OUTFLOW = 5.0, 0.5            # A dh/dt = u - a sqrt(h), Euler with dt = 1


def _tank(stre, N=1500, seed=0):
    rng = np.random.default_rng(seed)
    r = np.where(np.arange(N) % 200 < 100, 1.6, 0.8)
    h, y, u = 1.0, np.zeros(N), np.zeros(N)
    for t in range(N):
        y[t] = h + 0.002 * rng.standard_normal()
        u[t] = stre.step(y[t], r[t], dither=0.02 * rng.choice([-1.0, 1.0]))
        h = max(h + (u[t] - OUTFLOW * np.sqrt(h)) / AREA, 0.0)
    return y, u, r


@pytest.mark.parametrize("offset", [False, True])
def test_the_tank_needs_the_offset_for_the_designed_poles(offset):
    Am, Ao = np.poly([0.8]), np.poly([0.3])
    stre = SelfTuningRegulator(RecursiveLeastSquares(2 + offset, lam=0.995, P0=100.0),
                               dict(Am=Am, Ao=Ao), na=1, nb=1, offset=offset,
                               u_limits=(0.0, 2.0))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        y, u, r = _tank(stre)
    # without the offset, one warning at the end of the first 50 samples says so (the level
    # stays above 0.905 there, 6.4 standard deviations from zero); with it, none
    level = [w for w in caught if "offset=True" in str(w.message)]
    assert len(level) == (0 if offset else 1), [str(w.message) for w in caught]
    if not offset:
        assert level[0].category is RegulatorWarning
        low, std = np.abs(y[:50]).min(), np.std(y[:50])            # the oracle: NumPy
        message = str(level[0].message)
        assert f"at least {low:.3g} away from zero ({low / std:.3g} of its" in message
        assert f"mean {np.mean(y[:50]):.3g})" in message
        assert "Operating points: a tank" in message
    # the plant linearized at the last reference level: h(t+1) = p h(t) + u(t) / area
    level = r[-1]
    A = np.array([1.0, -(1.0 - OUTFLOW / (2 * np.sqrt(level)) / AREA)])
    B = np.array([0.0, 1.0 / AREA])
    poles = np.sort(stre.controller.closed_loop(A, B).poles.real)
    error = np.abs(poles - [0.3, 0.8]).max()
    if offset:
        assert error < 0.03                                       # 0.012 measured
        assert abs(stre.theta[1] - 1.0 / AREA) < 0.01             # b1, unbiased
        assert stre.history.theta.shape == (1500, 3)
    else:
        assert error > 0.2                                        # 0.27 measured
        assert abs(stre.theta[1] - 1.0 / AREA) > 0.04             # biased by the level


def test_an_affine_equilibrium_is_estimated_with_the_offset():
    """y(t) = 0.9 y(t-1) + 0.2 u(t-1) + 0.5 + e: linear, equilibrium far from zero."""
    def run(offset):
        stre = SelfTuningRegulator(RecursiveLeastSquares(2 + offset, P0=100.0),
                                   dict(Am=np.poly([0.6]), integral=False),
                                   na=1, nb=1, offset=offset)
        rng = np.random.default_rng(4)
        y, u = 0.0, 0.0
        ys, rs = [], []
        for t in range(800):
            y = 0.9 * y + 0.2 * u + 0.5 + 0.01 * rng.standard_normal()
            r = 6.0 if t % 100 < 50 else 4.0
            u = stre.step(y, r, dither=0.02 * rng.choice([-1.0, 1.0]))
            ys.append(y)
            rs.append(r)
        return stre, np.array(ys), np.array(rs)

    with warnings.catch_warnings():
        warnings.simplefilter("error")                           # no warning with the offset
        stre, y, r = run(True)
    assert_allclose(stre.theta, [-0.9, 0.2, 0.5], atol=0.02)
    # without integral action the offset's input u_c = -c / B(1) gives zero static error
    assert abs(y[40:50].mean() - 6.0) < 0.05 and abs(y[90:100].mean() - 4.0) < 0.05
    plain, y0, _ = run(False)       # started from rest at zero: no operating-point warning
    assert np.abs(plain.theta - [-0.9, 0.2]).max() > 0.05         # biased by the equilibrium


def test_a_loop_from_rest_stepping_to_a_constant_reference_gets_no_offset_warning():
    """Its first window's mean is several standard deviations from zero, but it starts at 0."""
    stre = SelfTuningRegulator(RecursiveLeastSquares(2, P0=1.0, x0=[-0.9, 0.2]),
                               dict(Am=np.poly([0.3])), na=1, nb=1)
    y, u, rng = 0.0, 0.0, np.random.default_rng(5)
    ys = []
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for _ in range(60):
            y = 0.9 * y + 0.2 * u + 0.01 * rng.standard_normal()
            u = stre.step(y, 1.0, dither=0.02 * rng.choice([-1.0, 1.0]))
            ys.append(y)
    ys = np.array(ys[:50])
    assert abs(ys.mean()) > 3.0 * ys.std()            # a mean-only test would have warned


def test_offset_argument_checks():
    with pytest.raises(ValueError, match=r"`estimator` must have dim_x = na \+ nb \+ 1 "
                                         r"\(offset\) = 3"):
        SelfTuningRegulator(RecursiveLeastSquares(2), DESIGN, na=1, nb=1, offset=True)
    with pytest.raises(TypeError, match=r"`offset` must be True or False"):
        SelfTuningRegulator(RecursiveLeastSquares(2), DESIGN, na=1, nb=1, offset=1)


# ----------------------------------------------------------------------
# rst_design(cancel_zeros=True): Astrom & Wittenmark, Adaptive Control, Examples 3.1 and 3.4
# ----------------------------------------------------------------------
# G(s) = 1 / (s (s + 1)) sampled with h = 0.5 (zero-order hold), Am from w = 1, zeta = 0.7
_E = np.exp(-0.5)
AW_A = np.array([1.0, -(1.0 + _E), _E])                      # a1 = -1.6065, a2 = 0.6065
AW_B = np.array([0.0, _E - 0.5, 1.0 - 1.5 * _E])              # b0 = 0.1065, b1 = 0.0902
_pm = np.exp(0.5 * np.roots([1.0, 1.4, 1.0]))
AW_AM = np.real(np.poly(_pm))                                 # am1 = -1.3205, am2 = 0.4966


def _example_3_1():
    """The book's closed form: R = q + b1/b0, S = s0 q + s1, T = t0 q."""
    (a1, a2), (b0, b1), (am1, am2) = AW_A[1:], AW_B[1:], AW_AM[1:]
    return b1 / b0, (am1 - a1) / b0, (am2 - a2) / b0, (1 + am1 + am2) / b0


def test_cancel_zeros_is_example_3_1():
    assert_allclose(AW_A[1:], [-1.6065, 0.6065], atol=5e-5)
    assert_allclose(AW_B[1:], [0.1065, 0.0902], atol=5e-5)
    assert_allclose(AW_AM[1:], [-1.3205, 0.4966], atol=5e-5)
    r1, s0, s1, t0 = _example_3_1()
    ctrl = rst_design(AW_A, AW_B, AW_AM, integral=False, cancel_zeros=True)
    assert_allclose(ctrl.R, [1.0, r1], rtol=0, atol=1e-13)
    assert_allclose(ctrl.S, [s0, s1], rtol=0, atol=1e-13)
    assert_allclose(ctrl.T, [t0], rtol=0, atol=1e-13)
    assert_allclose([r1, s0, s1, t0], [0.8467, 2.6852, -1.0321, 1.6531], atol=1e-3)
    # the zero -b1/b0 is a closed-loop pole; A R + B S = B+ Am = target
    loop = ctrl.closed_loop(AW_A, AW_B)
    assert_allclose(np.sort(loop.poles.real), np.sort(np.r_[-r1, _pm.real]), atol=1e-12)
    assert_allclose(loop.characteristic, ctrl.target, atol=1e-14)
    assert_allclose(ctrl.target, np.convolve([1.0, r1], AW_AM), atol=1e-15)
    assert abs(loop.dcgain - 1.0) < 1e-12


def test_cancel_zeros_radius_keeps_the_poorly_damped_zero():
    Ao = np.poly([0.0])
    kept = rst_design(AW_A, AW_B, AW_AM, Ao, integral=False, cancel_zeros=0.5)
    plain = rst_design(AW_A, AW_B, AW_AM, Ao, integral=False)
    for name in "RST":
        assert_array_equal(getattr(kept, name), getattr(plain, name))
    # an unstable zero (2) is never cancelled, a stable one (-0.5) is; with integral action
    B = np.r_[0.0, np.convolve([1.0, -2.0], [1.0, 0.5])]
    ctrl = rst_design(AW_A, B, AW_AM, np.poly([0.2]), cancel_zeros=True)
    loop = ctrl.closed_loop(AW_A, B)
    want = np.convolve([1.0, 0.5], np.convolve(AW_AM, np.poly([0.2])))    # B+ Am Ao
    assert_allclose(ctrl.target, want, atol=1e-15)
    char = loop.characteristic                  # round-off where deg R + deg A exceeds
    assert_allclose(char[:5], want, atol=1e-12) and np.abs(char[5:]).max() < 1e-12
    assert abs(ctrl.R.sum()) < 1e-12                                # the integrator
    with pytest.raises(ValueError, match=r"`cancel_zeros` must be True, False or a radius"):
        rst_design(AW_A, AW_B, AW_AM, cancel_zeros=1.5)


def test_example_3_4_indirect_self_tuner_with_zero_cancellation():
    """The self-tuner's controller converges to Example 3.1's, the design on the true plant."""
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e8),
                               dict(Am=AW_AM, integral=False, cancel_zeros=True), na=2, nb=2)
    _run(stre, 400, (AW_A, AW_B), noise=0.0, dither=0.01, period=50)
    r1, s0, s1, t0 = _example_3_1()
    ctrl = stre.controller
    assert_allclose(stre.theta, np.r_[AW_A[1:], AW_B[1:]], atol=1e-6)    # the prior's bias
    assert_allclose(np.r_[ctrl.R, ctrl.S, ctrl.T], [1.0, r1, s0, s1, t0], atol=1e-4)
