"""rst_design: closed-loop poles against python-control, integral action, conversions, errors."""

import re

import control
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import ARX
from rlsfilt.adaptive import ClosedLoop, RSTController, rst_design

# (na, deg B counted from q^0 with nk leading zeros: nk, nb) of the random plants
STRUCTURES = [(2, 1, 2), (3, 2, 2), (1, 1, 3), (2, 3, 1), (4, 1, 2), (2, 0, 3)]


def _random_case(seed, na, nk, nb, integral):
    """A, B with distinct random roots (some unstable), Am, Ao of the full degree."""
    rng = np.random.default_rng(seed)
    pa = _real_poly(rng, na, 0.3, 1.3)
    zb = _real_poly(rng, nb - 1, 0.2, 1.5)
    A = pa
    B = np.concatenate([np.zeros(nk), rng.uniform(0.5, 2.0) * zb])
    n_cl = na + int(integral) + (nk + nb - 1) - 1
    n_m = max(1, n_cl // 2)
    Am = _real_poly(rng, n_m, 0.1, 0.85)
    Ao = _real_poly(rng, n_cl - n_m, 0.05, 0.6)
    return A, B, Am, Ao


def _real_poly(rng, n, rmin, rmax):
    """Monic real polynomial with n distinct random roots (pairs are complex conjugate)."""
    roots = []
    while len(roots) < n:
        r = rng.uniform(rmin, rmax)
        if n - len(roots) >= 2 and rng.uniform() < 0.5:
            ang = rng.uniform(0.3, 2.5)
            roots += [r * np.exp(1j * ang), r * np.exp(-1j * ang)]
        else:
            roots.append(r * rng.choice([-1.0, 1.0]))
    return np.atleast_1d(np.real(np.poly(roots)))


def _tf(num, den, dt=True):
    n = max(len(num), len(den))
    return control.tf(np.pad(num, (0, n - len(num))), np.pad(den, (0, n - len(den))), dt)


def _without_origin(poles, n_expected, tol=0.0):
    """Drop the extra poles at z = 0 that padding to powers of z adds.

    Exactly zero for roots of a polynomial with trailing zeros; a Jordan
    block at 0 gives eigenvalues of size eps**(1/k) in a state-space
    realization, hence `tol`.
    """
    poles = np.asarray(poles)
    extra = len(poles) - n_expected
    order = np.argsort(np.abs(poles))
    assert np.all(np.abs(poles[order[:extra]]) <= tol), poles
    return np.sort_complex(poles[order[extra:]])


def _match(a, b):
    """Max distance between two sets of roots, each root matched to its nearest."""
    a, b = np.asarray(a), list(np.asarray(b))
    worst = 0.0
    for z in a:
        j = int(np.argmin([abs(z - w) for w in b]))
        worst = max(worst, abs(z - b.pop(j)))
    return worst


@pytest.mark.parametrize("integral", [True, False])
@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("na, nk, nb", STRUCTURES)
def test_closed_loop_poles_from_python_control_equal_roots_of_Am_Ao(na, nk, nb, seed, integral):
    A, B, Am, Ao = _random_case(1000 * na + 100 * nk + 10 * nb + seed, na, nk, nb, integral)
    ctrl = rst_design(A, B, Am, Ao, integral=integral)
    K = ctrl.to_tf()                       # u = K[0,0] r + K[0,1] y
    G = _tf(B, A)
    target = np.roots(np.convolve(Am, Ao))
    # u = K01 y is positive feedback of K01 around G
    cl_tf = control.feedback(G, K[0, 1], sign=1)
    assert _match(_without_origin(cl_tf.poles(), len(target)), target) < 1e-9
    # the state-space controller gives the same loop (eigenvalues of the closed-loop A)
    cl_ss = control.feedback(control.ss(G), ctrl.to_ss()[0, 1], sign=1)
    assert _match(_without_origin(cl_ss.poles(), len(target), 1e-5), target) < 1e-9
    # and the design equation itself, coefficient by coefficient
    char = np.polyadd(np.convolve(A, ctrl.R)[::-1], np.convolve(B, ctrl.S)[::-1])[::-1]
    want = np.convolve(Am, Ao)
    assert_allclose(np.trim_zeros(char, "b"), want, rtol=0, atol=1e-11 * np.abs(want).max())
    if integral:
        assert abs(ctrl.R.sum()) < 1e-12 * np.abs(ctrl.R).max()


def test_the_loop_report_matches_python_control():
    A, B, Am, Ao = _random_case(7, 2, 1, 2, True)
    ctrl = rst_design(A, B, Am, Ao)
    loop = ctrl.closed_loop(A, B)
    assert isinstance(loop, ClosedLoop) and loop.stable
    assert _match(loop.poles, np.roots(np.convolve(Am, Ao))) < 1e-9
    G, K = _tf(B, A), ctrl.to_tf()
    S = control.feedback(1, -G * K[0, 1])           # 1 / (1 - G K01)
    oracle = {"Gyr": G * K[0, 0] * S, "Gur": K[0, 0] * S, "Gyv": G * S, "Gyn": S,
              "Gun": K[0, 1] * S}
    for name, ref in oracle.items():
        for z in np.exp(1j * np.array([0.05, 0.3, 1.1, 2.9])):  # not z = 1: a pole of K
            assert abs(getattr(loop, name)(z) - ref(z)) < 1e-10 * max(1.0, abs(ref(z))), name
    assert abs(loop.dcgain - 1.0) < 1e-12
    assert "stable" in repr(loop) and "A R + B S" in str(loop.summary())


def test_to_ss_and_to_tf_are_the_same_controller():
    A, B, Am, Ao = _random_case(3, 3, 2, 2, True)
    ctrl = rst_design(A, B, Am, Ao, dt=0.05)
    Ktf, Kss = ctrl.to_tf(), ctrl.to_ss()
    assert Ktf.dt == Kss.dt == 0.05
    assert Ktf.input_labels == Kss.input_labels == ["r", "y"]
    for w in [0.05, 0.7, 2.0]:                # not z = 1: the integrator
        z = np.exp(1j * w)
        assert_allclose(Kss(z), Ktf(z), rtol=1e-11)


def test_the_control_law_as_python_control_computes_it():
    """forced_response of to_ss() equals the difference equation R u = T r - S y."""
    ctrl = RSTController(R=[2.0, -1.5, -0.5], S=[0.7, -0.2], T=[0.4, 0.1, -0.05])
    rng = np.random.default_rng(5)
    N = 60
    r, y = rng.standard_normal(N), rng.standard_normal(N)
    u = np.zeros(N)
    for t in range(N):
        acc = sum(ctrl.T[i] * r[t - i] for i in range(len(ctrl.T)) if t - i >= 0)
        acc -= sum(ctrl.S[i] * y[t - i] for i in range(len(ctrl.S)) if t - i >= 0)
        acc -= sum(ctrl.R[i] * u[t - i] for i in range(1, len(ctrl.R)) if t - i >= 0)
        u[t] = acc / ctrl.R[0]
    resp = control.forced_response(ctrl.to_ss(), np.arange(N), np.vstack([r, y]))
    assert_allclose(np.asarray(resp.outputs).reshape(-1), u, rtol=0, atol=1e-12)


def _loop_with_load(ctrl, A, B, N, t_load, load):
    """python-control closed loop: plant y = B/A (u + v), controller to_ss(); r = 1 step."""
    plant = control.ss(_tf(B, A), inputs="w", outputs="y")
    summer = control.summing_junction(["u", "v"], "w")
    K = control.ss(ctrl.to_ss(), inputs=["r", "y"], outputs="u")
    loop = control.interconnect([plant, summer, K], inputs=["r", "v"], outputs=["y", "u"])
    T = np.arange(N)
    v = np.where(T >= t_load, load, 0.0)
    return control.forced_response(loop, T, np.vstack([np.ones(N), v])).outputs


def test_integral_action_zero_steady_state_error_and_rejects_a_load():
    A, B = np.array([1.0, -1.5, 0.7]), np.array([0.0, 1.0, 0.5])
    Am, Ao = np.poly([0.6, 0.65]), np.poly([0.3, 0.35])
    ctrl = rst_design(A, B, Am, Ao)
    y, u = _loop_with_load(ctrl, A, B, N=400, t_load=150, load=0.5)
    assert abs(y[140] - 1.0) < 1e-12          # before the load: the reference
    assert abs(y[-1] - 1.0) < 1e-12           # after the load: rejected
    # the control absorbs the load exactly: u + v = A(1)/B(1) y
    assert abs(u[-1] + 0.5 - A.sum() / B.sum()) < 1e-11
    # without integral action the load leaves an offset (the test can fail)
    Am2 = np.poly([0.6, 0.65])
    plain = rst_design(A, B, Am2, np.poly([0.3]), integral=False)
    y2, _ = _loop_with_load(plain, A, B, N=400, t_load=150, load=0.5)
    assert abs(y2[140] - 1.0) < 1e-12 and abs(y2[-1] - 1.0) > 1e-2


def test_a_model_gives_the_same_design_and_its_dt():
    model = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=2, dt=0.1)
    Am, Ao = np.poly([0.5, 0.6]), np.poly([0.2, 0.3, 0.1])
    a = rst_design(model, Am=Am, Ao=Ao)
    b = rst_design(*model.polynomials(), Am, Ao)
    assert_array_equal(a.R, b.R)
    assert_array_equal(a.S, b.S)
    assert_array_equal(a.T, b.T)
    assert a.dt == 0.1 and b.dt is True


def test_no_argument_is_mutated_and_the_controller_keeps_copies():
    A, B = np.array([1.0, -1.5, 0.7]), np.array([0.0, 1.0, 0.5])
    Am, Ao = np.poly([0.5, 0.6]), np.poly([0.2, 0.3])
    saved = [x.copy() for x in (A, B, Am, Ao)]
    ctrl = rst_design(A, B, Am, Ao)
    for x, s in zip((A, B, Am, Ao), saved):
        assert_array_equal(x, s)
    R = np.array([1.0, -1.0])
    c = RSTController(R, [1.0], [1.0])
    R[1] = 5.0
    assert c.R[1] == -1.0
    T0 = ctrl.T.copy()
    loop = ctrl.closed_loop(A, B)
    loop.A[0] = 9.0
    assert_array_equal(A, saved[0])
    assert_array_equal(ctrl.T, T0)


def test_repr_shows_the_control_law():
    ctrl = RSTController(R=[1, -1], S=[2, -1], T=[2, -1], dt=0.1)
    assert ctrl.control_law() == "(1 - q^-1) u(t) = (2 - q^-1) r(t) - (2 - q^-1) y(t)"
    assert "RSTController(dt=0.1)" in repr(ctrl)


# ----------------------------------------------------------------------
# bad designs: clear errors naming the argument
# ----------------------------------------------------------------------
A0, B0 = np.array([1.0, -1.5, 0.7]), np.array([0.0, 1.0, 0.5])
AM, AO = np.poly([0.5, 0.6]), np.poly([0.2, 0.3])


def test_common_factor_is_rejected_with_the_pair():
    A = np.poly([0.5, 0.8])                    # poles 0.5, 0.8
    B = np.concatenate([[0.0], np.poly([0.5])])  # zero at 0.5: common factor
    with pytest.raises(ValueError, match=r"`A` and `B` must be coprime.*pole z = 0\.5, zero "
                                         r"z = 0\.5"):
        rst_design(A, B, AM, AO)
    # nearly common (1e-11 apart) is caught by the tolerance, and named
    B2 = np.concatenate([[0.0], np.poly([0.5 + 1e-11])])
    with pytest.raises(ValueError, match=r"coprime_tol = 1e-08"):
        rst_design(A, B2, AM, AO)
    # 1e-3 apart is a (poorly conditioned) coprime pair: designed, exact poles
    B3 = np.concatenate([[0.0], np.poly([0.501])])
    ctrl = rst_design(A, B3, AM, AO)
    assert _match(ctrl.closed_loop(A, B3).poles, np.roots(np.convolve(AM, AO))) < 1e-8


def test_a_zero_at_one_conflicts_with_integral_action():
    B = np.concatenate([[0.0], np.poly([1.0])])
    with pytest.raises(ValueError, match=r"`B` has B\(1\) = 0.*zero at z = 1"):
        rst_design(A0, B, AM, AO)
    with pytest.raises(ValueError, match=r"`B` has B\(1\) = 0.*no T gives a unit static gain"):
        rst_design(A0, B, AM, np.poly([0.2]), integral=False)


@pytest.mark.parametrize("kwargs, exc, match", [
    (dict(Am=np.poly([0.5, 1.2])), ValueError, r"`Am` must be stable .*\|z\| = 1\.2"),
    (dict(Am=np.poly([0.5, 1.0])), ValueError, r"`Am` must be stable"),
    (dict(Ao=np.poly([-1.1])), ValueError, r"`Ao` must be stable"),
    (dict(Am=2 * np.poly([0.5])), ValueError, r"`Am` must be monic .*got Am\[0\] = 2"),
    (dict(Ao=np.poly([0.1, 0.2, 0.3])), ValueError,
     r"`Am` and `Ao` have deg\(Am\) \+ deg\(Ao\) = 5, more than .* = 4"),
    (dict(Am=None), TypeError, r"`Am` is required"),
    (dict(integral=1), TypeError, r"`integral` must be True or False"),
    (dict(coprime_tol=-1.0), ValueError, r"`coprime_tol` must be"),
    (dict(Am=[1.0, np.nan]), ValueError, r"`Am` must be finite"),
])
def test_bad_arguments_name_the_argument(kwargs, exc, match):
    args = dict(Am=AM, Ao=AO)
    args.update(kwargs)
    with pytest.raises(exc, match=match):
        rst_design(A0, B0, **args)


@pytest.mark.parametrize("A, B, match", [
    ([2.0, -1.0], B0, r"`A` must be monic"),
    (A0, [1.0], r"`B` must have degree >= 1"),
    (A0, [0.0, 0.0], r"`B` must be a nonzero polynomial"),
    (A0, [[0.0, 1.0]], r"`B` must be a 1-D array"),
])
def test_bad_plants_name_the_argument(A, B, match):
    with pytest.raises(ValueError, match=match):
        rst_design(A, B, AM, AO)


def test_a_plant_without_B_must_be_a_model():
    with pytest.raises(TypeError, match=r"`B` is required unless `A` is a model"):
        rst_design(A0, Am=AM)


def test_non_causal_controllers_are_rejected():
    with pytest.raises(ValueError, match=r"`R` must have R\[0\] != 0"):
        RSTController([0.0, 1.0], [1.0], [1.0])
    with pytest.raises(ValueError, match=r"`dt` must be True"):
        RSTController([1.0], [1.0], [1.0], dt=-1)


@pytest.mark.parametrize("options", [
    dict(Am=AM, Ao=AO),
    dict(Am=AM, integral=False),
    dict(Am=AM, Ao=AO, cancel_zeros=True, dt=0.5),
])
def test_the_regulators_prepared_design_equals_rst_design(options):
    # SelfTuningRegulator checks the options once; every design is rst_design's, bit for bit
    from rlsfilt.adaptive.rst import _prepared_design

    design = _prepared_design(**options)
    rng = np.random.default_rng(3)
    for _ in range(20):
        A = np.r_[1.0, 0.3 * rng.standard_normal(2)]
        B = np.r_[0.0, 1.0, 0.4 * rng.standard_normal()]
        try:
            ref = rst_design(A, B, **options)
        except ValueError as exc:
            with pytest.raises(ValueError, match=re.escape(str(exc))):
                design(A, B)
            continue
        got = design(A, B)
        for name in ("R", "S", "T", "Ao", "target"):
            assert_array_equal(getattr(got, name), getattr(ref, name))
        assert got.dt == ref.dt
    with pytest.raises(ValueError, match=r"`Am` must be stable"):
        _prepared_design(Am=[1.0, -1.5])
