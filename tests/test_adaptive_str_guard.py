"""SelfTuningRegulator guards (#29): verified designs, no lock-in near a common factor, the
saturation watchdog, finite-value checks, offsets (the tank); rst_design(cancel_zeros=True)."""

import contextlib
import copy
import io
import re
import warnings
from pathlib import Path

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
    others = [_lockin(seed)[1] for seed in (0, 1, 3, 4, 5)]     # 0.42 .. 0.45 measured
    assert rms < 0.5 and sat < 0.01
    assert min(others) - 0.02 < rms < max(others) + 0.02, (rms, others)     # 0.45
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
    assert len(stre.history) == 4
    # the python-control system checks the same: see
    # test_the_python_control_system_refuses_the_same_measurements


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
    assert_allclose(char[:5], want, atol=1e-12)
    assert np.abs(char[5:]).max() < 1e-12
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
    # the prior's bias (1 / P0 against the data's information): 2.9e-9 and 3.3e-8 measured
    assert_allclose(stre.theta, np.r_[AW_A[1:], AW_B[1:]], rtol=0, atol=1e-8)
    assert_allclose(np.r_[ctrl.R, ctrl.S, ctrl.T], [1.0, r1, s0, s1, t0], rtol=0, atol=1e-7)
    # and every controller in use from step 20 on (1.4e-6 measured at most)
    h = stre.history
    used = np.column_stack([h.R[20:, :2], h.S[20:, :2], h.T[20:, :1]])
    assert_allclose(used, np.broadcast_to([1.0, r1, s0, s1, t0], used.shape), rtol=0, atol=3e-6)
    assert not np.column_stack([h.R[20:, 2:], h.S[20:, 2:], h.T[20:, 1:]]).any()


# ----------------------------------------------------------------------
# review of #29: each check of a design, the diverging loop, the python-control system,
# the second-order model on the tank, the guide's tank example, the anti-windup form
# ----------------------------------------------------------------------
INITIAL = RSTController([1.0], [0.5], [0.5])        # on A1, B1: A R + B S = 1 - 0.55 q^-1


@pytest.mark.parametrize("bad, stable_R, why", [
    # A R + B S = 1 - 0.55 q^-1, not the target claimed
    (RSTController([1.0], [0.5], [0.5], target=[1.0, 0.2]), False,
     r"misses its characteristic polynomial by 0\.75 \(A R \+ B S against target\)"),
    # A R + B S = 1 - 2.3 q^-1: a pole at 2.3
    (RSTController([1.0], [-3.0], [0.5]), False,
     r"gives an unstable loop on the estimate \(largest \|pole\| = 2\.3\)"),
    # R = 1 - 1.5 q^-1, S = 4.6 - 2.4 q^-1: A R + B S = 1 (deadbeat), but R unstable
    (RSTController([1.0, -1.5], [4.6, -2.4], [2.2]), True,
     r"has an unstable R \(a zero at \|z\| = 1\.5; stable_R=True\)"),
])
def test_each_check_of_a_design_rejects_it_and_names_why(bad, stable_R, why):
    """Every check of `_candidate` on its own: the design is rejected, the controller in
    use is kept, the warning after `patience` rejections names the check; the same
    controller without the flaw is accepted (the check is not what rejects everything)."""
    def run(ctrl, **kwargs):
        stre = SelfTuningRegulator(RecursiveLeastSquares(2, P0=1e-6, x0=[-0.8, 0.5]),
                                   lambda A_, B_: ctrl, na=1, nb=1, initial=INITIAL,
                                   patience=5, **kwargs)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            _run(stre, 10, (A1, B1), noise=0.0, dither=0.0)     # the estimate stays exact
        return stre, [str(w.message) for w in caught if w.category is RegulatorWarning]

    stre, messages = run(bad, stable_R=stable_R)
    assert stre.history.rejected.all()
    assert len(messages) == 1 and re.search(r"5 redesigns in a row up to step 4 were rejected "
                                            r"\(the last because the full design " + why,
                                            messages[0]), messages
    for name in "RST":
        assert_array_equal(np.trim_zeros(getattr(stre.controller, name), "b"),
                           getattr(INITIAL, name))
    if stable_R:                                # an unstable R is fine unless asked
        fine = bad
        assert not run(fine, stable_R=False)[0].history.rejected.any()
    elif bad.target is not None:                # the true characteristic polynomial passes
        fine = RSTController(bad.R, bad.S, bad.T, target=[1.0, -0.55])
        assert not run(fine)[0].history.rejected.any()


@pytest.mark.parametrize("signal_limit, match", [
    (1e100, r"the computed `u` = -5\.5e\+100 at step 36 exceeds signal_limit = 1e\+100: the "
            r"loop is diverging"),
    (1e300, r"the estimate became non-finite at step 68 \(`y` = -1\.8047e\+223, largest "
            r"\|phi\| = 1\.8044e\+223\): the loop or the estimator diverged"),
])
def test_a_diverging_loop_ends_in_a_clear_error_at_every_later_step(signal_limit, match):
    """An unstable plant, y = 1.5 y(t-1) + u(t-1), with the sign of b1 held wrong by the
    bounds: the loop diverges. It ends in a ValueError naming the signal and the step (it
    ended in LinAlgError: SVD did not converge, at every later step), not in one from
    deep inside; the next steps raise the same, and the regulator stays as it was."""
    stre = SelfTuningRegulator(RecursiveLeastSquares(2, P0=1.0, x0=[-1.5, -1.0]),
                               dict(Am=np.poly([0.5])), na=1, nb=1,
                               bounds=([-np.inf, -np.inf], [np.inf, -0.5]),
                               signal_limit=signal_limit)
    rng = np.random.default_rng(0)
    y = u = 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RegulatorWarning)
        with pytest.raises(ValueError, match=match):
            for _ in range(3000):
                y = 1.5 * y + u + 0.01 * rng.standard_normal()
                u = stre.step(y, 1.0)
        before, n = stre.state, len(stre.history)
        for _ in range(3):
            with pytest.raises(ValueError, match=match):
                stre.step(y, 1.0)
    assert_array_equal(stre.state, before)
    assert len(stre.history) == n and np.all(np.isfinite(stre.theta))


@pytest.mark.parametrize("value, match", [
    (np.nan, r"`y` must be finite; got nan at step 5"),
    (1e150, r"`y` = 1e\+150 at step 5 exceeds signal_limit = 1e\+100: the loop is diverging"),
])
def test_the_python_control_system_refuses_the_same_measurements(value, match):
    control = pytest.importorskip("control")
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), DESIGN, na=2, nb=2)
    before = stre.state
    T = np.arange(10)
    y = np.linspace(0.1, 1.0, 10)
    y[5] = value
    with pytest.raises(ValueError, match=match):
        control.input_output_response(stre.as_iosystem(), T, [y, np.ones(10), np.zeros(10)])
    assert_array_equal(stre.state, before)
    assert len(stre.history) == 0


@pytest.mark.parametrize("mode", ["plain", "offset", "deviation"])
def test_a_second_order_model_keeps_the_tank_under_control(mode):
    """#29: ARX(2, 2) on the tank lost the loop (level 10 against references up to 1.6),
    also on deviation variables. It tracks now, with or without the offset, and on
    deviations from h = 1.2 (the reduced design carries it)."""
    offset = mode == "offset"
    h_op, u_op = (1.2, OUTFLOW * np.sqrt(1.2)) if mode == "deviation" else (0.0, 0.0)
    stre = SelfTuningRegulator(RecursiveLeastSquares(4 + offset, lam=0.995, P0=100.0),
                               dict(Am=np.poly([0.8, 0.7]), Ao=np.poly([0.3, 0.3])), na=2,
                               nb=2, offset=offset, u_limits=(0.0 - u_op, 2.0 - u_op))

    class Deviations:            # the regulator on y - h_op, r - h_op; u = its output + u_op
        def step(self, y, r, dither):
            return stre.step(y - h_op, r - h_op, dither) + u_op

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RegulatorWarning)
        y, u, r = _tank(Deviations())
    rms = np.sqrt(np.mean((y[500:] - r[500:]) ** 2))
    assert rms < 0.2, rms                           # 0.16, 0.17, 0.17 measured
    assert y.max() < 2.2, y.max()                   # 1.64, 1.95, 1.71 measured
    assert np.mean(np.isclose(u, 0.0) | np.isclose(u, 2.0)) < 0.1


def _guide_section(title):
    text = (Path(__file__).resolve().parents[1] / "docs" / "guide" / "control.md").read_text()
    start = text.index(title)
    return text[start:text.index("\n## ", start)]


def test_the_guides_tank_example_prints_what_the_guide_says():
    """docs/guide/control.md, 'Operating points: a tank': its code run as written, and the
    numbers of its comments and of the prose on the run without the offset."""
    section = _guide_section("### Operating points: a tank")
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    namespace = dict(np=np, RecursiveLeastSquares=RecursiveLeastSquares,
                     SelfTuningRegulator=SelfTuningRegulator)
    out = io.StringIO()
    with warnings.catch_warnings(), contextlib.redirect_stdout(out):
        warnings.simplefilter("error")                    # with the offset: no warning
        exec(compile(code, "control.md", "exec"), namespace)
    theta_said, poles_said = re.findall(r"# .*?about \[?([-0-9., ]+?)\]?[:\n]", code)
    stre = namespace["stre"]
    assert_array_equal(np.round(stre.theta, 3), np.array(theta_said.split(","), dtype=float))
    A = [1.0, -(1 - 0.5 / (2 * np.sqrt(0.8)) / 5.0)]
    poles = np.sort(stre.controller.closed_loop(A, [0.0, 0.2]).poles.real)
    assert_array_equal(np.round(poles, 2), np.array(poles_said.split(","), dtype=float))
    # without the offset: the estimate of b1, the poles at h = 1.6, the warning's numbers
    plain = SelfTuningRegulator(RecursiveLeastSquares(2, lam=0.995, P0=100.0),
                                dict(Am=np.poly([0.8]), Ao=np.poly([0.3])), na=1, nb=1,
                                u_limits=(0.0, 2.0))
    with pytest.warns(RegulatorWarning, match="offset=True") as caught:
        y, _, _ = namespace["tank"](plain)
    b1, low, ratio, mean = re.search(
        r"estimate of \$b_1\$ is ([0-9.]+) instead of 0\.2.*?at least ([0-9.]+), ([0-9.]+) "
        r"standard deviations, about a\s+mean of ([0-9.]+)", section, re.S).groups()
    assert f"{plain.theta[1]:.3f}" == b1
    A16 = [1.0, -(1 - 0.5 / (2 * np.sqrt(1.6)) / 5.0)]
    said = re.search(r"\(at h = 1\.6\) are ([0-9.]+) and ([0-9.]+)", section).groups()
    poles = np.sort(plain.controller.closed_loop(A16, [0.0, 0.2]).poles.real)
    assert [f"{p:.2f}" for p in poles] == list(said)
    message = next(str(w.message) for w in caught if "offset=True" in str(w.message))
    assert f"at least {low} away" in message and f"mean {mean})" in message
    told = float(re.search(r"\(([0-9.]+) of its standard deviations", message).group(1))
    assert round(told, 1) == float(ratio)                 # the guide rounds 6.39 to 6.4
    assert f"{np.abs(y[:50]).min():.3g}" == low and f"{np.mean(y[:50]):.3g}" == mean


def test_the_anti_windup_form_is_the_books_with_Ao_equal_to_r0():
    """The documented difference (class Notes, guide 'Anti-windup'): with a fixed design,
    the regulator's law is Astrom & Wittenmark's A_o u = T r - S y + (A_o - R) sat(u)
    with A_o = r_0 = 1; inside the limits it is the same controller as the form with the
    design's A_o, and after a saturation the two differ."""
    Ao = np.poly([0.6, 0.5])
    ctrl = rst_design(AW_A, AW_B, AW_AM, Ao)              # integral action: R(1) = 0
    assert_array_equal(ctrl.Ao, Ao)
    assert abs(ctrl.R[0] - 1.0) < 1e-15                     # monic up to round-off

    def book(y, r, Ao_, lim):
        """The book's form on a record of y, r: returns the applied v = sat(u)."""
        L = 8
        R, S, T = (np.r_[p, np.zeros(L - len(p))] for p in (ctrl.R, ctrl.S, ctrl.T))
        Aop = np.r_[Ao_, np.zeros(L - len(Ao_))]
        us, vs = np.zeros(len(y) + L), np.zeros(len(y) + L)
        ys, rs = np.r_[np.zeros(L), y], np.r_[np.zeros(L), r]
        for k in range(L, len(y) + L):
            past = slice(k, k - L, -1)
            # u(t) = T r - S y + (Ao - R) v - (Ao - 1) u, the newest terms first
            us[k] = (T @ rs[past] - S @ ys[past] + (Aop - R)[1:] @ vs[k - 1:k - L:-1]
                     - Aop[1:] @ us[k - 1:k - L:-1])
            vs[k] = np.clip(us[k], -lim, lim)
        return vs[L:]

    for lim, saturates in [(1e6, False), (1.2, True)]:
        stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e-12, x0=np.r_[AW_A[1:],
                                                                               AW_B[1:]]),
                                   lambda A_, B_: ctrl, na=2, nb=2, initial=ctrl,
                                   u_limits=(-lim, lim))
        y, v, r = _run(stre, 200, (AW_A, AW_B), noise=0.0, dither=0.0, period=50)
        assert np.any(np.abs(v) == lim) == saturates
        assert_allclose(v, book(y, r, np.ones(1), lim), rtol=0, atol=1e-12)
        with_Ao = book(y, r, Ao, lim)
        if saturates:
            assert np.abs(v - with_Ao).max() > 0.1
        else:
            assert_allclose(v, with_Ao, rtol=0, atol=1e-12)


def test_the_watchdog_warns_at_the_first_saturated_block_whose_error_grew():
    """The lock-in run with the old rule: the watchdog's block, its saturation and its RMS
    errors against NumPy on the history (monitor_every = 200 blocks), once."""
    stre, _, _, messages = _lockin(2, reduce_tol=0.0, max_growth=1e300)
    h = stre.history
    watchdog = [m for m in messages if "sat at a limit" in m]
    assert len(watchdog) == 1
    first, last = map(int, re.search(r"in steps (\d+)\.\.(\d+)", watchdog[0]).groups())
    n = 200
    blocks = np.arange(len(h.u) // n)
    sat = np.array([np.mean(np.abs(h.u[b * n:(b + 1) * n]) == 2.0) for b in blocks])
    rms = np.array([np.sqrt(np.mean((h.r - h.y)[b * n:(b + 1) * n] ** 2)) for b in blocks])
    grew = np.r_[rms[0] >= 0.0, rms[1:] >= rms[:-1]]
    b = int(np.flatnonzero((sat >= 0.5) & grew)[0])
    assert (first, last) == (b * n, (b + 1) * n - 1)
    previous = rms[b - 1] if b else 0.0
    assert (f"sat at a limit {100 * sat[b]:.0f} % of the time and the RMS error r - y grew to "
            f"{rms[b]:.3g} (from {previous:.3g} in the block before)") in watchdog[0]
    # the same seed with the default rule saturates too little to warn
    assert not [m for m in _lockin(2)[3] if "sat at a limit" in m]


@pytest.mark.parametrize("signal", ["r", "dither"])
@pytest.mark.parametrize("value, match", [
    (np.nan, r"`{}` must be finite; got nan at step 1"),
    (-np.inf, r"`{}` must be finite; got -inf at step 1"),
    (1e150, r"`{}` = 1e\+150 at step 1 exceeds signal_limit = 1e\+100: the loop is diverging"),
])
def test_a_bad_reference_or_dither_is_named_and_changes_nothing(signal, value, match):
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), DESIGN, na=2, nb=2)
    stre.step(0.1, 1.0)
    before = stre.state
    with pytest.raises(ValueError, match=match.format(signal)):
        stre.step(0.2, **{"r": 1.0, signal: value})
    assert_array_equal(stre.state, before)
    assert len(stre.history) == 1


@pytest.mark.parametrize("scale_a, scale_b", [(2.0 ** 1000, 1.0), (1.0, 2.0 ** -1065),
                                              (2.0 ** -1000, 2.0 ** 830), (2.0 ** 530, 2.0 ** -530),
                                              (2.0 ** 1020, 2.0 ** -1070)])
def test_coprimeness_is_scale_invariant_over_the_double_range(scale_a, scale_b):
    """The Sylvester matrix of a, b scaled to unit norm: the same singular value at any
    scale (np.linalg.norm overflows above about 1e154 and underflows below 1e-162, and
    a / norm gave zeros, inf or NaN: a wrong degree, 'negative dimensions', or the
    'LinAlgError: SVD did not converge' of #29). Powers of two: the scaled polynomials
    are exact, also where subnormal coefficients keep a few bits only (the oracle is
    the same polynomial at unit size)."""
    from rlsfilt.adaptive._polynomials import coprimeness
    for a, b in [([1.0, -0.5], [0.0, 1.0, -0.5]), ([1.0, -1.5, 0.7], [0.0, 1.0, 0.5]),
                 ([1.0, -0.8], [0.0, 0.5, -0.4 + 1e-6])]:
        a_s, b_s = scale_a * np.array(a), scale_b * np.array(b)
        want = coprimeness(a_s / scale_a, b_s / scale_b)
        assert coprimeness(a_s, b_s) == pytest.approx(want, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("x0", [[1e300, 1e-300, 1e300, 1.0], [1e308, -1e308, 1e308, -1e308],
                                [0.0, 0.0, 1e-320, 0.0], [1e200, 1e200, 1e-200, 1e-200],
                                [-1.5, 0.7, 1e300, 1e300]])
@pytest.mark.parametrize("compiled", [True, False])
def test_an_extreme_but_finite_estimate_is_rejected_not_a_crash(x0, compiled):
    """Estimates at the ends of the double range (a diverging or vanishing estimate): the
    regulator starts and steps, with no controller, instead of raising IndexError,
    'negative dimensions are not allowed' or LinAlgError from the coprimeness check."""
    options = dict(Am=np.poly([0.5, 0.6]))
    design = options if compiled else (lambda A_, B_: rst_design(A_, B_, **options))
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e-300, x0=x0), design, na=2,
                               nb=2, patience=2)
    with pytest.warns(RegulatorWarning, match="there is no controller: the loop is open"):
        u = [stre.step(y, 1.0) for y in (0.1, 0.2, 0.3)]
    assert u == [0.0, 0.0, 0.0] and stre.controller is None
    assert stre.history.rejected.all()


def _affine_loop(stre, N=300, seed=4):
    """The plant with an affine equilibrium, y(t) = 0.9 y(t-1) + 0.2 u(t-1) + 0.5 + e."""
    rng = np.random.default_rng(seed)
    y = u = 0.0
    us = []
    for t in range(N):
        y = 0.9 * y + 0.2 * u + 0.5 + 0.01 * rng.standard_normal()
        u = stre.step(y, 6.0 if t % 100 < 50 else 4.0, dither=0.02 * rng.choice([-1.0, 1.0]))
        us.append(u)
    return np.array(us)


def _offset_regulator(integral):
    return SelfTuningRegulator(RecursiveLeastSquares(3, P0=100.0),
                               dict(Am=np.poly([0.6]), integral=integral), na=1, nb=1,
                               offset=True)


@pytest.mark.parametrize("integral", [False, True])
def test_the_offset_regulators_compiled_design_equals_its_numpy_path(integral):
    fast, slow = _offset_regulator(integral), _offset_regulator(integral)
    assert fast._fast is not None
    slow._fast = None                                      # the NumPy path only
    assert_array_equal(_affine_loop(fast), _affine_loop(slow))
    assert_array_equal(fast.state, slow.state)


@pytest.mark.parametrize("integral", [False, True])
def test_the_offset_regulator_inside_interconnect_equals_its_step_loop(integral):
    control = pytest.importorskip("control")
    stre = _offset_regulator(integral)
    ref = copy.deepcopy(stre)
    N = 200
    r = np.where(np.arange(N) % 100 < 50, 6.0, 4.0)
    d = 0.02 * np.random.default_rng(1).choice([-1.0, 1.0], N)
    x, y_ref, u_ref = 0.0, np.zeros(N), np.zeros(N)
    for k in range(N):
        y_ref[k] = x
        u_ref[k] = ref.step(x, r[k], d[k])
        x = 0.9 * x + 0.2 * u_ref[k] + 0.5
    plant = control.nlsys(lambda t, x, u, p: 0.9 * x + 0.2 * u + 0.5, lambda t, x, u, p: x,
                          inputs="u", outputs="y", states=1, dt=True, name="plant")
    loop = control.interconnect([plant, stre.as_iosystem()], inputs=["r", "dither"],
                                outputs=["y", "u"])
    resp = control.input_output_response(loop, np.arange(N), [r, d])
    assert_allclose(resp.outputs[0], y_ref, rtol=0, atol=1e-12)
    assert_allclose(resp.outputs[1], u_ref, rtol=0, atol=1e-12)
    assert abs(ref.theta[2] - 0.5) < 0.1                   # the offset is in use (0.45)


def test_a_nearly_cancelling_complex_pair_is_removed_with_its_conjugate():
    """The estimate A = (1 - 0.5 q^-1)(pole pair 0.6 e^{+-0.5j}), B = 0.8 q^-1 (zero pair
    0.6003 e^{+-0.5003j}): coprimeness 5.4e-6. The reduced model removes the pair and its
    conjugate, (1 - 0.5 q^-1) y = 0.8 q^-1 u; the controller is rst_design's on it; the
    loop on the full estimate keeps the pair, stable; the warning names it."""
    p, z = 0.6 * np.exp(0.5j), 0.6003 * np.exp(0.5003j)
    A = np.real(np.poly([0.5, p, np.conj(p)]))
    B = np.r_[0.0, 0.8 * np.real(np.poly([z, np.conj(z)]))]
    stre = SelfTuningRegulator(RecursiveLeastSquares(6, P0=1e-12, x0=np.r_[A[1:], B[1:]]),
                               dict(Am=np.poly([0.4])), na=3, nb=3)
    with pytest.warns(RegulatorWarning, match=r"nearly cancels a pole against a zero \(.*"
                                              r"closest pole 0\.52655\+0\.287655j / zero "
                                              r"0\.526726\+0\.287957j\)"):
        stre.step(0.0, 1.0)
    assert stre.history.reduced[0] and not stre.history.rejected[0]
    want = rst_design([1.0, -0.5], [0.0, 0.8], np.poly([0.4]))
    for name in "RST":
        assert_allclose(np.trim_zeros(getattr(stre.controller, name), "b"),
                        getattr(want, name), rtol=0, atol=1e-13)
    poles = np.sort(np.abs(stre.controller.closed_loop(A, B).poles))
    assert_allclose(poles[-2:], 0.6, atol=1e-3)            # the removed pair stays, stable
