"""The compiled per-sample design of SelfTuningRegulator (#29 item 5) equals its NumPy path.

`_kernels_design.design_full` takes the common branch of the regulator's
design (coprime estimate, `rst_design` without cancelled zeros, verified,
size bounded); every other branch runs the NumPy path. The oracle is the
NumPy path itself (`rst_design`, the verification and the graded coprimeness
of the regulator), run with the compiled path switched off.
"""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from test_adaptive_str_guard import A1, B1, DESIGN, _run

from rlsfilt import RecursiveLeastSquares
from rlsfilt.adaptive import SelfTuningRegulator, rst_design
from rlsfilt.adaptive._polynomials import coprimeness


def _regulator(na, nb, nk, design, fast=True, **kwargs):
    stre = SelfTuningRegulator(RecursiveLeastSquares(na + nb, P0=100.0), design, na=na,
                               nb=nb, nk=nk, **kwargs)
    if not fast:
        stre._fast = None           # the NumPy path only
    return stre


def _designs(stre, A, B):
    """Whether the compiled path takes the estimate ``A, B`` (monic ``A``, ``B`` with
    its ``nk`` leading zeros) and installs its full design."""
    theta = np.r_[A[1:], B[stre.nk:]]
    return stre._fast_design(theta, 0.0, 0.0) is not None


def _random_case(rng):
    na, nb, nk = int(rng.integers(1, 4)), int(rng.integers(1, 4)), int(rng.integers(1, 3))
    A = np.r_[1.0, rng.uniform(-1.5, 1.5, na)]
    B = np.r_[np.zeros(nk), rng.uniform(-2.0, 2.0, nb)]
    integral = bool(rng.integers(2))
    room = na + int(integral) + nk + nb - 1 - 1          # deg A1 + deg B - 1
    nm = int(rng.integers(1, min(room, 2) + 1))
    no = int(rng.integers(0, room - nm + 1))
    design = dict(Am=np.poly(rng.uniform(-0.8, 0.8, nm)), integral=integral)
    if no:
        design["Ao"] = np.poly(rng.uniform(-0.5, 0.5, no))
    return na, nb, nk, A, B, design


def test_random_designs_equal_the_numpy_path():
    rng = np.random.default_rng(29)
    accepted = 0
    for _ in range(300):
        na, nb, nk, A, B, design = _random_case(rng)
        fast = _regulator(na, nb, nk, design)
        slow = _regulator(na, nb, nk, design, fast=False)
        theta = np.r_[A[1:], B[nk:]]
        took = _designs(fast, A.copy(), B.copy())
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ctrl, kind, _ = slow._try_design(A.copy(), B.copy(), theta)
        sigma = coprimeness(A, B)
        # the compiled path takes exactly the accepted full designs away from a common factor
        assert took == (kind == "full" and sigma >= slow.reduce_tol), (A, B, design, kind)
        if took:
            accepted += 1
            slow._install(ctrl, "design")
            assert_allclose(fast._ctrl, slow._ctrl, rtol=1e-12, atol=1e-12 * np.abs(
                slow._ctrl).max())
            assert_allclose(fast._scalars, slow._scalars, rtol=1e-12)   # size_last
            # and rst_design itself, padded
            ref = rst_design(A, B, **design)
            for row, p in zip(fast._ctrl, (ref.R, ref.S, ref.T)):
                assert_allclose(row[:len(p)], p, rtol=1e-12, atol=1e-12 * np.abs(p).max())
                assert not row[len(p):].any()
    assert accepted > 100           # the test exercises the compiled path


def test_a_near_common_factor_and_a_refused_design_go_to_the_numpy_path():
    fast = _regulator(2, 2, 1, DESIGN)
    # A and B share the root z = 0.5: coprimeness 0, the graded (reduced) design decides
    A, B = np.poly([0.5, 0.9]), np.r_[0.0, np.poly([0.5]) * 2.0]
    assert not _designs(fast, A, B)
    # B(1) = 0: rst_design refuses (a zero at z = 1 against the integrator)
    assert not _designs(fast, np.poly([0.5, 0.9]), np.r_[0.0, 1.0, -1.0])
    # a controller more than max_growth times the one in use (B 1000 times smaller)
    assert _designs(fast, np.poly([0.5, 0.9]), np.r_[0.0, 1.0, 0.5])
    before = fast._ctrl.copy()
    assert not _designs(fast, np.poly([0.5, 0.9]), np.r_[0.0, 1e-3, 0.5e-3])
    assert_array_equal(fast._ctrl, before)


def _history(stre, run):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run(stre)
    return stre.history, [str(w.message) for w in caught]


@pytest.fixture
def fast_design_calls(monkeypatch):
    """Whether each design went through the compiled path (`_fast_design` gave a control)."""
    calls = []
    original = SelfTuningRegulator._fast_design

    def counting(self, theta, y, r):
        u = original(self, theta, y, r)
        calls.append(u is not None)
        return u

    monkeypatch.setattr(SelfTuningRegulator, "_fast_design", counting)
    return calls


@pytest.mark.parametrize("seed", [1, 2, 5])
def test_the_lock_in_scenario_equals_the_numpy_path(seed, fast_design_calls):
    calls = fast_design_calls
    kw = dict(u_limits=(-2.0, 2.0))

    def run(stre):
        return _run(stre, 1600, (A1, B1), seed=seed)

    hf, mf = _history(_regulator(2, 2, 1, DESIGN, **kw), run)
    hs, ms = _history(_regulator(2, 2, 1, DESIGN, fast=False, **kw), run)
    # both paths were taken (an over-parameterized model: mostly near a common factor)
    assert any(calls) and not all(calls)
    for name in ("u", "y", "e", "R", "S", "T", "theta", "trace_P"):
        a, b = getattr(hf, name), getattr(hs, name)
        assert_allclose(a, b, rtol=1e-12, atol=1e-12 * max(np.abs(b).max(), 1.0), err_msg=name)
    for name in ("rejected", "reduced", "updated"):
        assert_array_equal(getattr(hf, name), getattr(hs, name), err_msg=name)
    assert mf == ms


def test_a_square_wave_loop_equals_the_numpy_path(fast_design_calls):
    calls = fast_design_calls
    A, B = np.array([1.0, -1.5, 0.7]), np.array([0.0, 1.0, 0.5])

    def run(stre):
        return _run(stre, 600, (A, B), seed=3, dither=0.1, period=80)

    hf, mf = _history(_regulator(2, 2, 1, DESIGN), run)
    hs, ms = _history(_regulator(2, 2, 1, DESIGN, fast=False), run)
    assert sum(calls) > 550                     # nearly every design was the compiled one
    assert_allclose(hf.u, hs.u, rtol=1e-12, atol=1e-12)
    assert_allclose(hf.R, hs.R, rtol=1e-12, atol=1e-12)
    assert_array_equal(hf.rejected, hs.rejected)
    assert mf == ms


def test_a_design_callable_or_cancelled_zeros_or_stable_R_use_the_numpy_path():
    A, B = np.poly([0.5, 0.9]), np.r_[0.0, 1.0, 0.5]
    assert _designs(_regulator(2, 2, 1, DESIGN), A, B)
    assert not _designs(_regulator(2, 2, 1, dict(DESIGN, cancel_zeros=True)), A, B)
    assert not _designs(_regulator(2, 2, 1, DESIGN, stable_R=True), A, B)
    stre = _regulator(2, 2, 1, lambda a, b: rst_design(a, b, **DESIGN))
    assert not _designs(stre, A, B)


@pytest.mark.parametrize("sa, sb", [(1e160, 1.0), (1.0, 1e-170), (1e-300, 1e300), (1e-305, 1.0)])
def test_the_compiled_coprimeness_is_scale_invariant(sa, sb):
    """The compiled coprimeness decision on ``(sa a, sb b)`` is that on ``(a, b)`` over the
    double range (the 2-norm of 1e160 coefficients overflowed, of subnormal ones
    underflowed: a coprime pair was called near-common, or LinAlgError), and equal to
    ``coprimeness`` of the NumPy path."""
    from rlsfilt.adaptive import _kernels_design

    a, b = np.array([1.0, -1.5, 0.7]), np.array([1.0, 0.5])
    want = coprimeness(a, b)
    for tau in (0.1 * want, 0.9 * want, 1.1 * want):
        ok, sigma = _kernels_design._coprime_at_least(sa * a, sb * b, tau)
        assert ok == (want >= tau)
        assert ok == _kernels_design._coprime_at_least(a, b, tau)[0]
    assert coprimeness(sa * a, sb * b) == pytest.approx(want, rel=1e-12)
