"""filterpy code runs unchanged on the rlsfilt filters (issue #29, item 4).

filterpy's own ``IMMEstimator`` with one Kalman filter replaced by a
`RecursiveLeastSquares` equals the IMM of Kalman filters configured the same
way (``F = I``, the same ``Q``, ``H``, ``R``); a loop that sets ``f.H`` and
calls ``f.update(z)`` equals ``f.update(z, H)``; ``alpha`` is filterpy's fading
memory (``alpha**2 = 1 / lam``); ``get_update`` is filterpy's; and the filterpy
names least squares does not use (``F``, ``B``, ``inv``, ``predict(u)``) are
refused with an error that names them.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import RecursiveLeastSquares, SlidingWindowRLS, SquareRootRLS
from rlsfilt.filters import APA, LMS, NLMS

filterpy = pytest.importorskip("filterpy")
from filterpy.common import Saver, kinematic_kf  # noqa: E402
from filterpy.kalman import IMMEstimator, KalmanFilter  # noqa: E402

N_X = 3
STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H")
FILTERS = {
    "rls": lambda: RecursiveLeastSquares(N_X, lam=0.98),
    "square_root": lambda: SquareRootRLS(N_X, lam=0.98),
    "sliding_window": lambda: SlidingWindowRLS(N_X, window=20),
}
# the gradient filters share the filterpy surface (F, B, inv, alpha, predict(u))
GRADIENT = {
    "lms": lambda: LMS(N_X, mu=0.05),
    "nlms": lambda: NLMS(N_X, mu=0.5),
    "apa": lambda: APA(N_X, mu=0.5),
}


def _kalman(q, r=1.0, p0=1e4, alpha=1.0):
    """filterpy's KalmanFilter as RLS: F = I, Q = q I, H set per step, R = r."""
    kf = KalmanFilter(dim_x=N_X, dim_z=1)
    kf.F = np.eye(N_X)
    kf.Q = q * np.eye(N_X)
    kf.R = np.array([[r]])
    kf.P = p0 * np.eye(N_X)
    kf.alpha = alpha
    return kf


def _record(rng, N=120):
    Hs = rng.standard_normal((N, N_X))
    theta = np.where(np.arange(N)[:, None] < N // 2, [1.0, -0.5, 0.3], [0.2, 0.8, -1.0])
    return Hs, np.einsum("ij,ij->i", Hs, theta) + 0.1 * rng.standard_normal(N)


def _state(f):
    return {name: np.array(getattr(f, name), copy=True) for name in STATE}


# ----------------------------------------------------------------------
# filterpy's IMMEstimator
# ----------------------------------------------------------------------
def _imm_step(imms, H, z):
    """One sample of each IMM, its filters given the regressor row as filterpy's ``H``."""
    for imm in imms:
        imm.predict()
        for f in imm.filters:
            f.H = H.reshape(1, -1)
        imm.update(z)


def test_imm_with_rls_equals_imm_of_kalman_filters(rng):
    """One model of filterpy's IMM is an RLS (random walk Q, H set each step): the IMM's
    estimate, covariance and mode probabilities equal those of the IMM of Kalman
    filters with F = I and the same Q, to round-off."""
    Hs, zs = _record(rng)
    q_slow, q_fast = 1e-6, 1e-2
    mu, M = [0.5, 0.5], np.array([[0.97, 0.03], [0.03, 0.97]])
    rls = RecursiveLeastSquares(N_X, Q=q_slow)
    imm_rls = IMMEstimator([rls, _kalman(q_fast)], mu, M)
    imm_kf = IMMEstimator([_kalman(q_slow), _kalman(q_fast)], mu, M)
    fast = []
    for H, z in zip(Hs, zs):
        _imm_step((imm_rls, imm_kf), H, z)
        assert_allclose(imm_rls.x, imm_kf.x, rtol=1e-12, atol=1e-12)
        assert_allclose(imm_rls.P, imm_kf.P, rtol=1e-11, atol=1e-14)
        assert_allclose(imm_rls.mu, imm_kf.mu, rtol=1e-12, atol=1e-14)
        fast.append(imm_rls.mu[1])
    assert_array_equal(rls.H, Hs[-1].reshape(1, -1))
    # the switch of the parameters at t = 60 shows in the mode probabilities: the fast
    # model (the Kalman filter) takes over for a while (about 0.3 before, 0.8-0.95 after)
    assert max(fast[40:60]) < 0.4 < 0.7 < max(fast[60:80])


def test_filterpys_own_imm_example_with_one_model_replaced_by_rls():
    """The example of filterpy's ``IMMEstimator`` docstring, run as written (two
    ``kinematic_kf`` filters, the second with ``Q = 0``, ``mu = [0.5, 0.5]``, the 0.97/0.03
    transition matrix, measurements ``i + noise``, ``imm.predict(); imm.update(z)``) with
    order 0, where ``F = I`` (least squares cannot follow a velocity), and its first
    Kalman filter replaced by the RLS with the same ``P``, ``Q``, ``R`` and ``H``."""
    def example(first):
        kf1, kf2 = first, kinematic_kf(1, 0)
        kf2.Q *= 0   # no prediction error in second filter
        return IMMEstimator([kf1, kf2], [0.5, 0.5], np.array([[0.97, 0.03], [0.03, 0.97]]))

    ref = kinematic_kf(1, 0)
    assert_array_equal(ref.F, [[1.0]])
    rls = RecursiveLeastSquares(1, P0=ref.P[0, 0], Q=ref.Q[0, 0], R=ref.R[0, 0])
    rls.H = ref.H                               # set once, as a filterpy user would
    imm_rls, imm_kf = example(rls), example(kinematic_kf(1, 0))
    rng = np.random.default_rng(29)
    for i in range(100):
        z = np.array([[i + rng.standard_normal() * np.sqrt(ref.R[0, 0])]])
        for imm in (imm_rls, imm_kf):
            imm.predict()
            imm.update(z)
        assert_allclose(imm_rls.x, imm_kf.x, rtol=1e-14, atol=0)
        assert_allclose(imm_rls.P, imm_kf.P, rtol=5e-14, atol=0)
        assert_allclose(imm_rls.mu, imm_kf.mu, rtol=0, atol=5e-14)
        assert_allclose(imm_rls.likelihood, imm_kf.likelihood, rtol=1e-12, atol=0)
    # the ramp is tracked by the model with process noise, the RLS
    assert imm_rls.mu[0] > 0.8
    assert abs(imm_rls.x[0, 0] - 99.0) < 5.0


@pytest.mark.parametrize("make", [lambda: SquareRootRLS(N_X, P0=1e4),
                                  lambda: SlidingWindowRLS(N_X, window=1000, P0=1e4)],
                         ids=["square_root", "sliding_window"])
def test_imm_with_the_other_least_squares_filters(make, rng):
    """The square-root filter and a window longer than the record in filterpy's IMM (the
    IMM assigns their x and P when it mixes) equal a Kalman filter with F = I, Q = 0."""
    Hs, zs = _record(rng)
    M = np.array([[0.97, 0.03], [0.03, 0.97]])
    ours = IMMEstimator([make(), _kalman(1e-2)], [0.5, 0.5], M)
    ref = IMMEstimator([_kalman(0.0), _kalman(1e-2)], [0.5, 0.5], M)
    for H, z in zip(Hs, zs):
        _imm_step((ours, ref), H, z)
        assert_allclose(ours.x, ref.x, rtol=0, atol=1e-12)      # 7e-15, 4e-14 measured
        assert_allclose(ours.P, ref.P, rtol=0, atol=1e-12 * np.abs(ref.P).max())
        assert_allclose(ours.mu, ref.mu, rtol=0, atol=1e-12)


# ----------------------------------------------------------------------
# update(z) with self.H
# ----------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FILTERS))
def test_update_without_H_uses_self_H(name, rng):
    """The filterpy loop ``f.H = row; f.update(z)`` gives the bits of ``update(z, row)``,
    and ``H`` reads as the row of the last update."""
    Hs, zs = _record(rng, N=60)
    a, b = FILTERS[name](), FILTERS[name]()
    for H, z in zip(Hs, zs):
        a.predict()
        a.H = H.reshape(1, -1)
        a.update(z)
        b.predict()
        b.update(z, H)
        assert_array_equal(b.H, H.reshape(1, -1))
    for key in STATE:
        assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)


@pytest.mark.parametrize("name", sorted(FILTERS))
def test_H_is_zeros_before_any_update_and_a_bad_H_is_refused(name):
    f = FILTERS[name]()
    assert_array_equal(f.H, np.zeros((1, N_X)))
    f.H = [1.0, 2.0]
    before = _state(f)
    with pytest.raises(ValueError, match=r"`H` must have shape \(3,\) or \(1, 3\)"):
        f.update(1.0)
    for key, value in before.items():
        assert_array_equal(getattr(f, key), value, err_msg=key)


def test_update_with_H_set_equals_kalman_filter(rng):
    Hs, zs = _record(rng, N=80)
    rls, kf = RecursiveLeastSquares(N_X, Q=1e-4), _kalman(1e-4)
    for H, z in zip(Hs, zs):
        for f in (rls, kf):
            f.predict()
            f.H = H.reshape(1, -1)
            f.update(z)
        assert_allclose(rls.x, kf.x, rtol=1e-12, atol=1e-12)
        assert rls.log_likelihood == pytest.approx(kf.log_likelihood, rel=1e-12)


# ----------------------------------------------------------------------
# alpha: filterpy's fading memory
# ----------------------------------------------------------------------
def test_alpha_is_fading_memory(rng):
    """``alpha = a`` sets ``lam = 1 / a**2``, and the filter then equals filterpy's
    KalmanFilter with the same alpha."""
    Hs, zs = _record(rng, N=100)
    rls, kf = RecursiveLeastSquares(N_X), _kalman(0.0, alpha=1.02)
    rls.alpha = 1.02
    assert rls.lam == 1.0 / 1.02 ** 2
    assert rls.alpha == pytest.approx(1.02, rel=1e-15)
    for H, z in zip(Hs, zs):
        for f in (rls, kf):
            f.predict()
            f.update(z, H=H.reshape(1, -1))
    # 5e-14 relative measured over the 100 steps (P grows like 1.02**200)
    assert_allclose(rls.x, kf.x, rtol=0, atol=1e-12 * np.abs(kf.x).max())
    assert_allclose(rls.P, kf.P, rtol=0, atol=1e-12 * np.abs(kf.P).max())
    sr = SquareRootRLS(N_X)
    sr.alpha = 2.0
    assert sr.lam == 0.25
    assert RecursiveLeastSquares(N_X, lam=0.25).alpha == 2.0


@pytest.mark.parametrize("bad", [0.5, np.nan, np.inf, -1.0])
def test_alpha_out_of_range_is_refused(bad):
    f = RecursiveLeastSquares(N_X, lam=0.9)
    with pytest.raises(ValueError, match=r"`alpha` must be a finite number >= 1"):
        f.alpha = bad
    assert f.lam == 0.9


def test_alpha_of_the_sliding_window_is_refused():
    f = SlidingWindowRLS(N_X, window=10)
    assert f.alpha == 1.0
    with pytest.raises(AttributeError, match=r"`alpha` cannot be assigned: SlidingWindowRLS "
                                             r"forgets by its window"):
        f.alpha = 1.1


# ----------------------------------------------------------------------
# F, B, inv and predict(u): refused
# ----------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FILTERS))
@pytest.mark.parametrize("attribute, match", [
    ("F", r"`F` cannot be assigned: the state transition of least squares is the identity"),
    ("B", r"`B` cannot be assigned: least squares has no control input"),
    ("inv", r"`inv` cannot be assigned: \w+ never inverts a matrix"),
])
def test_assigning_F_B_inv_is_refused(name, attribute, match):
    f = FILTERS[name]()
    before = _state(f)
    with pytest.raises(AttributeError, match=match):
        setattr(f, attribute, np.eye(N_X))
    for key, value in before.items():
        assert_array_equal(getattr(f, key), value, err_msg=key)
    assert_array_equal(f.F, np.eye(N_X))
    assert f.B is None


@pytest.mark.parametrize("name", sorted(FILTERS))
@pytest.mark.parametrize("call, arg", [
    (lambda f: f.predict(np.ones(1)), "u"),
    (lambda f: f.predict(1e-4), "u"),                  # not taken as Q
    (lambda f: f.predict(u=0.0), "u"),
    (lambda f: f.predict(B=np.ones((N_X, 1))), "B"),
    (lambda f: f.predict(F=np.eye(N_X)), "F"),
])
def test_filterpy_predict_arguments_are_refused(name, call, arg, rng):
    f = FILTERS[name]()
    f.predict()
    f.update(1.0, rng.standard_normal(N_X))
    before = _state(f)
    with pytest.raises(TypeError, match=rf"`{arg}` is not an argument {type(f).__name__}"
                                        r"\.predict\(\) uses: least squares has F = I and no "
                                        r"control input"):
        call(f)
    for key, value in before.items():
        assert_array_equal(getattr(f, key), value, err_msg=key)


def test_predict_of_none_and_of_a_random_walk_still_work(rng):
    """IMMEstimator calls ``f.predict(u)`` with ``u = None``; ``Q`` is a keyword."""
    a, b = RecursiveLeastSquares(N_X, lam=0.97), RecursiveLeastSquares(N_X, lam=0.97)
    a.predict(None)
    b.predict()
    assert_array_equal(a.P, b.P)
    a.predict(Q=1e-3)
    assert_array_equal(a.P, b.P / 0.97 + 1e-3 * np.eye(N_X))


# ----------------------------------------------------------------------
# get_update
# ----------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(FILTERS))
def test_get_update_is_update_without_the_change(name, rng):
    Hs, zs = _record(rng, N=30)
    f = FILTERS[name]()
    for H, z in zip(Hs[:-1], zs[:-1]):
        f.predict_update(z, H)
    f.predict()
    before = _state(f)
    f.H = Hs[-1]
    x, P = f.get_update(zs[-1])
    assert_array_equal(f.H, Hs[-1])
    for key, value in before.items():
        if key != "H":
            assert_array_equal(getattr(f, key), value, err_msg=key)
    f.update(zs[-1])
    assert_array_equal(x, f.x)
    assert_array_equal(P, f.P)


def test_get_update_equals_kalman_filter(rng):
    Hs, zs = _record(rng, N=10)
    rls, kf = RecursiveLeastSquares(N_X, Q=1e-3), _kalman(1e-3)
    for f in (rls, kf):
        f.predict()
        f.H = Hs[0].reshape(1, -1)
    x, P = rls.get_update(zs[0])
    x_kf, P_kf = kf.get_update(zs[0])
    assert_allclose(x, x_kf, rtol=0, atol=1e-14 * np.abs(x_kf).max())
    assert_allclose(P, P_kf, rtol=0, atol=1e-14 * np.abs(P_kf).max())   # 2e-16 measured


# ----------------------------------------------------------------------
# the gradient filters: the same filterpy surface
# ----------------------------------------------------------------------
@pytest.mark.parametrize("name", sorted(GRADIENT))
def test_gradient_filters_refuse_filterpys_attributes_by_name(name, rng):
    f = GRADIENT[name]()
    f.predict(None)                             # what IMMEstimator calls
    f.H = rng.standard_normal(N_X)
    f.update(1.0)
    before = _state_gradient(f)
    with pytest.raises(AttributeError, match=rf"`alpha` cannot be assigned: {type(f).__name__} "
                                             r"adapts by its step size `mu`, it has no "
                                             r"fading-memory factor"):
        f.alpha = 1.01
    assert f.alpha == 1.0
    for attribute in ("F", "B", "inv"):
        with pytest.raises(AttributeError, match=rf"`{attribute}` cannot be assigned"):
            setattr(f, attribute, np.eye(N_X))
    for call, arg in [(lambda: f.predict(1e-4), "u"), (lambda: f.predict(B=np.ones((N_X, 1))), "B"),
                      (lambda: f.predict(F=np.eye(N_X)), "F")]:
        with pytest.raises(TypeError, match=rf"(?s)`{arg}` is not an argument "
                                            rf"{type(f).__name__}\.predict\(\) uses: .*; "
                                            rf"got {arg}=.*\.$"):
            call()
    for key, value in before.items():
        assert_array_equal(getattr(f, key), value, err_msg=key)


@pytest.mark.parametrize("name", sorted(set(FILTERS) - {"rls"}))
def test_the_random_walk_hint_only_where_predict_takes_Q(name):
    """``predict(Q=...)`` is named only by the filter whose ``predict`` takes it."""
    with pytest.raises(TypeError) as info:
        FILTERS[name]().predict(1e-4)
    assert "Q" not in str(info.value).split("got u=")[1]
    with pytest.raises(TypeError, match=r"got u=0\.0001\. A random walk is predict\(Q=\.\.\.\)"):
        FILTERS["rls"]().predict(1e-4)


def _state_gradient(f):
    return {name: np.array(getattr(f, name), copy=True)
            for name in ("x", "x_prior", "x_post", "y", "z", "H")}


@pytest.mark.parametrize("m", [1, 2])
@pytest.mark.parametrize("make", [
    lambda m: RecursiveLeastSquares(N_X, m, lam=0.98), lambda m: SquareRootRLS(N_X, m, lam=0.98),
    lambda m: SlidingWindowRLS(N_X, window=20, dim_z=m), lambda m: LMS(N_X, m, mu=0.05),
    lambda m: NLMS(N_X, m, mu=0.5), lambda m: APA(N_X, m, mu=0.5),
], ids=["rls", "square_root", "sliding_window", "lms", "nlms", "apa"])
def test_every_filter_runs_the_saver_loop_with_H_set(make, m, rng):
    """``f.H = row; f.update(z)`` under filterpy's Saver (which reads every property, F,
    B, inv, alpha among them) on every filter, with one output or two sharing the row:
    the bits of ``update(z, row)``, and the Saver's record of them."""
    Hs, Z = rng.standard_normal((40, N_X)), rng.standard_normal((40, m))
    a, b = make(m), make(m)
    saver = Saver(a)
    for H, z in zip(Hs, Z):
        a.predict()
        a.H = H
        a.update(z)
        saver.save()
        b.predict()
        b.update(z, H)
        assert_array_equal(a.x, b.x)
    saver.to_array()
    assert saver.x.shape == (40, N_X, m)
    assert_array_equal(saver.x[-1], b.x)
    assert_array_equal(saver.H[-1], Hs[-1].reshape(1, -1))


# ----------------------------------------------------------------------
# rts_smoother: filterpy's signature
# ----------------------------------------------------------------------
def test_rts_smoother_takes_filterpys_arguments_and_refuses_Fs_and_inv(rng):
    """filterpy's ``rts_smoother(Xs, Ps, Fs=None, Qs=None, inv=...)``: ``Qs`` by keyword
    or in fourth place equals filterpy's; a positional ``Fs`` (third) was taken as ``Qs``
    and is now refused, as is ``inv``."""
    Hs, zs = _record(rng, N=40)
    rls = RecursiveLeastSquares(N_X, Q=1e-3, P0=3.0)        # (P0 = 1e4: P[0] ill-conditioned)
    Xs, Ps, _, _ = rls.batch_filter(zs, Hs)
    Qs = np.broadcast_to(2e-3 * np.eye(N_X), (40, N_X, N_X))
    ref = _kalman(1e-3).rts_smoother(Xs, Ps, None, Qs)        # filterpy's, on our run
    for ours in (rls.rts_smoother(Xs, Ps, None, Qs), rls.rts_smoother(Xs, Ps, Qs=Qs)):
        for a, b, name in zip(ours, ref, ("x", "P", "K", "Pp"), strict=True):
            assert_allclose(a, b, rtol=0, atol=1e-12 * max(1.0, np.abs(b).max()), err_msg=name)
    Fs = [np.eye(N_X)] * 40
    for call, name in [(lambda: rls.rts_smoother(Xs, Ps, Fs), "Fs"),
                       (lambda: rls.rts_smoother(Xs, Ps, Fs=Fs, Qs=Qs), "Fs"),
                       (lambda: rls.rts_smoother(Xs, Ps, inv=np.linalg.inv), "inv")]:
        with pytest.raises(TypeError, match=rf"`{name}` is not an argument "
                                            r"RecursiveLeastSquares\.rts_smoother\(\) uses: "
                                            r"least squares has F = I"):
            call()


@pytest.mark.parametrize("name", sorted(set(FILTERS) - {"rls"}) + sorted(GRADIENT))
def test_Q_of_a_filter_without_a_random_walk_is_zero_and_refused(name, rng):
    """filterpy code sets ``f.Q`` (process noise): on a filter without a random walk it was
    accepted and ignored; it reads as zero and assigning it names the filter."""
    f = {**FILTERS, **GRADIENT}[name]()
    assert_array_equal(f.Q, np.zeros((N_X, N_X)))
    f.predict()
    f.update(1.0, rng.standard_normal(N_X))
    x = np.array(f.x, copy=True)
    with pytest.raises(AttributeError, match=rf"`Q` cannot be assigned: {type(f).__name__} has "
                                             r"no random walk \(filterpy's process noise\); "
                                             r"RecursiveLeastSquares\(Q=\.\.\.\) has one"):
        f.Q = 1e-3 * np.eye(N_X)
    assert_array_equal(f.Q, np.zeros((N_X, N_X)))
    assert_array_equal(f.x, x)
    rls = RecursiveLeastSquares(N_X)
    rls.Q = 1e-3                                # the RLS keeps its settable random walk
    assert_array_equal(rls.Q, 1e-3 * np.eye(N_X))
