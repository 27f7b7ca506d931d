"""Minimum-variance and generalized minimum-variance control of simulated ARMAX plants."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt.adaptive import (
    MinimumVarianceController,
    generalized_minimum_variance,
    minimum_variance,
    rst_design,
)

# A y = q^-d B' u + C e: an unstable open loop, a stable B', a colored noise
A = np.array([1.0, -1.7, 0.8, -0.05])
BP = np.array([1.0, 0.6])
C = np.array([1.0, -0.4, 0.3])
D = 2
B = np.concatenate([np.zeros(D), BP])
SIGMA = 0.5


def _assert_same_poly(p, q, atol):
    """Equal coefficients after zero-padding to one length (round-off tails allowed)."""
    n = max(len(p), len(q))
    assert_allclose(np.pad(p, (0, n - len(p))), np.pad(q, (0, n - len(q))), rtol=0, atol=atol)


def _simulate(ctrl, e, r=None):
    """The loop R u = T r - S y around A y = B u + C e, sample by sample (zero past)."""
    N = len(e)
    r = np.zeros(N) if r is None else r
    R, S, T = ctrl.R, ctrl.S, ctrl.T
    L = max(len(A), len(B), len(C), len(R), len(S), len(T))
    # signals with L zeros in front; p[::-1] @ x[t-len(p)+1 : t+1] = sum_i p_i x(t-i)
    yp, up = np.zeros(N + L), np.zeros(N + L)
    ep, rp = np.r_[np.zeros(L), e], np.r_[np.zeros(L), r]
    a1, b1, r1 = A[1:][::-1], B[1:][::-1], R[1:][::-1]
    cr, sr, tr = C[::-1], S[::-1], T[::-1]
    for k in range(L, N + L):
        yp[k] = (-a1 @ yp[k - len(a1):k] + b1 @ up[k - len(b1):k]
                 + cr @ ep[k - len(cr) + 1:k + 1])
        up[k] = (tr @ rp[k - len(tr) + 1:k + 1] - sr @ yp[k - len(sr) + 1:k + 1]
                 - r1 @ up[k - len(r1):k]) / R[0]
    return yp[L:], up[L:]


def test_F_is_the_impulse_response_of_C_over_A_and_the_identity_holds():
    mv = minimum_variance(A, B, C)
    assert isinstance(mv, MinimumVarianceController) and mv.d == D
    impulse = lfilter(C, A, np.r_[1.0, np.zeros(10)])
    assert_allclose(mv.F, impulse[:D], rtol=0, atol=1e-14)
    # C = A F + q^-d G
    lhs = np.convolve(A, mv.F)
    rhs = np.zeros(max(len(lhs), D + len(mv.G)))
    rhs[:len(lhs)] += lhs
    rhs[D:D + len(mv.G)] += mv.G
    assert_allclose(rhs, np.pad(C, (0, len(rhs) - len(C))), rtol=0, atol=1e-14)
    # the closed loop is B' C
    char = mv.closed_loop(A, B).characteristic
    _assert_same_poly(char, np.convolve(BP, C), 1e-13)


def test_minimum_variance_reaches_the_theoretical_output_variance():
    """Long seeded run: var(y) = sigma^2 sum_{i<d} f_i^2 within 5 % (MC error ~0.6 %)."""
    mv = minimum_variance(A, B, C)
    theory = SIGMA ** 2 * float(np.sum(lfilter(C, A, np.r_[1.0, np.zeros(D - 1)]) ** 2))
    assert abs(mv.output_variance(SIGMA ** 2) - theory) < 1e-14
    N = 100_000
    e = SIGMA * np.random.default_rng(11).standard_normal(N)
    y, _ = _simulate(mv, e)
    measured = np.mean(y[100:] ** 2)
    assert abs(measured / theory - 1.0) < 0.05
    # pathwise: the closed-loop output is exactly F e (the loop starts at rest)
    assert_allclose(y, lfilter(mv.F, [1.0], e), rtol=0, atol=1e-9)
    # any other controller does worse, e.g. pole placement on the same plant
    pp = rst_design(A, B, np.poly([0.5, 0.5]), np.poly([0.2, 0.2, 0.1, 0.1]))
    y_pp, _ = _simulate(pp, e[:20_000])
    assert np.mean(y_pp[100:] ** 2) > 1.2 * theory


def test_minimum_variance_tracks_the_reference_delayed_by_d():
    mv = minimum_variance(A, B, C)
    N = 300
    r = np.where(np.arange(N) % 60 < 30, 1.0, -1.0)
    e = 0.1 * np.random.default_rng(2).standard_normal(N)
    y, _ = _simulate(mv, e, r)
    # y(t) = r(t - d) + F e(t)
    want = np.r_[np.zeros(D), r[:-D]] + lfilter(mv.F, [1.0], e)
    assert_allclose(y, want, rtol=0, atol=1e-9)


def test_gmv_with_default_weights_is_minimum_variance():
    mv = minimum_variance(A, B, C)
    g = generalized_minimum_variance(A, B, C)
    for name in ("R", "S", "T", "F", "G"):
        assert_allclose(getattr(g, name), getattr(mv, name), rtol=0, atol=0)


@pytest.mark.parametrize("P, Q", [([1.0, -0.5], [0.3]), ([1.0], [0.5, -0.5]), ([2.0, 0.4], 1.0)])
def test_gmv_closed_loop_and_auxiliary_output(P, Q):
    """Characteristic C (P B' + (q0/b0) Q A); phi(t+d) = P y(t+d) + (q0/b0) Q u(t) - r(t) = F e."""
    g = generalized_minimum_variance(A, B, C, P=P, Q=Q)
    P, Q = np.atleast_1d(np.asarray(P, float)), np.atleast_1d(np.asarray(Q, float))
    q0b0 = Q[0] / BP[0]
    inner = np.polyadd(np.convolve(P, BP)[::-1], q0b0 * np.convolve(Q, A)[::-1])[::-1]
    want = np.convolve(C, inner)
    char = g.closed_loop(A, B).characteristic
    _assert_same_poly(char, want, 1e-13)
    N = 400
    rng = np.random.default_rng(3)
    e = 0.2 * rng.standard_normal(N)
    r = np.where(np.arange(N) % 80 < 40, 1.0, 0.0)
    y, u = _simulate(g, e, r)
    phi = lfilter(P, [1.0], y)[D:] + q0b0 * lfilter(Q, [1.0], u)[:-D] - r[:-D]
    assert_allclose(phi, lfilter(g.F, [1.0], e)[D:], rtol=0, atol=1e-9)


def test_gmv_controls_a_non_minimum_phase_plant():
    Bn = np.array([0.0, 1.0, 1.5])                 # zero at z = -1.5
    with pytest.raises(ValueError, match=r"`B` must be minimum phase .*z = -1\.5"):
        minimum_variance([1.0, -0.9], Bn)
    g = generalized_minimum_variance([1.0, -0.9], Bn, Q=1.0)
    assert g.closed_loop([1.0, -0.9], Bn).stable
    with pytest.raises(ValueError, match=r"`P` and `Q` give an unstable closed loop"):
        generalized_minimum_variance([1.0, -0.9], Bn, Q=0.01)


class _ARMAXLike:
    def __init__(self, out):
        self._out = out
        self.dt = 0.5

    def polynomials(self):
        return self._out


@pytest.mark.parametrize("out", [(A, B, C), {"a": A, "b": B, "c": C}, {"A": A, "B": B, "C": C}])
def test_models_with_polynomials_are_accepted(out):
    ref = minimum_variance(A, B, C)
    mv = minimum_variance(_ARMAXLike(out))
    assert mv.dt == 0.5
    assert_array_equal(mv.R, ref.R)
    assert_array_equal(mv.S, ref.S)
    assert_array_equal(mv.T, ref.T)


def test_an_arx_model_has_C_equal_to_one():
    from rlsfilt import ARX

    model = ARX.from_polynomials(A[1:], BP, nk=D)
    mv = minimum_variance(model)
    assert_array_equal(mv.T, [1.0])
    assert_allclose(mv.F, lfilter([1.0], A, np.r_[1.0, 0.0])[:D], atol=1e-15)


def test_no_argument_is_mutated():
    args = [A.copy(), B.copy(), C.copy()]
    generalized_minimum_variance(*args, P=np.array([1.0, -0.5]), Q=np.array([0.3]))
    for a, ref in zip(args, (A, B, C)):
        assert_array_equal(a, ref)


@pytest.mark.parametrize("kwargs, match", [
    (dict(C=[1.0, -1.2]), r"`C` must be stable"),
    (dict(C=[2.0, 0.1]), r"`C` must be monic"),
    (dict(d=3), r"`d` must equal the number of leading zeros of B \(2"),
    (dict(B=[1.0, 0.5]), r"`B` must start with at least one zero"),
    (dict(B=[0.0, 0.0]), r"`B` must be a nonzero polynomial"),
    (dict(d=0), r"`d` must be >= 1"),
])
def test_bad_arguments_name_the_argument(kwargs, match):
    args = dict(A=A, B=B, C=C)
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        minimum_variance(**args)


def test_gmv_bad_weights():
    with pytest.raises(ValueError, match=r"`P` must have P\(0\) != 0"):
        generalized_minimum_variance(A, B, C, P=[0.0, 1.0])
    with pytest.raises(TypeError, match=r"`B` is required"):
        generalized_minimum_variance(A)
