"""SelfTuningRegulator: convergence to the true design, the step equations, safeguards."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import (
    ExcitationWarning,
    RecursiveLeastSquares,
    RegulatorWarning,
    SlidingWindowRLS,
    SquareRootRLS,
)
from rlsfilt.adaptive import RSTController, SelfTuningRegulator, STRHistory, rst_design

A = np.array([1.0, -1.5, 0.7])
B = np.array([0.0, 1.0, 0.5])
THETA = np.array([-1.5, 0.7, 1.0, 0.5])
AM, AO = np.poly([0.5, 0.6]), np.poly([0.2, 0.3])
DESIGN = dict(Am=AM, Ao=AO)


def _run(stre, N, noise=1e-3, seed=0, dither=0.1, period=100, plant=(A, B), r=None):
    """Close the loop around A y = B u + e (zero before t = 0); returns y, u, r."""
    Ap, Bp = plant
    rng = np.random.default_rng(seed)
    r = np.where(np.arange(N) % period < period // 2, 1.0, -1.0) if r is None else r
    d = dither * rng.choice([-1.0, 1.0], N)
    e = noise * rng.standard_normal(N)
    L = max(len(Ap), len(Bp))
    y, u = np.zeros(N + L), np.zeros(N + L)
    for k in range(L, N + L):
        y[k] = (-Ap[1:] @ y[k - 1:k - len(Ap):-1] + Bp[1:] @ u[k - 1:k - len(Bp):-1]
                + e[k - L])
        u[k] = stre.step(y[k], r[k - L], dither=d[k - L])
    return y[L:], u[L:], r


def _max_diff(c1, c2):
    return max(np.abs(np.trim_zeros(getattr(c1, n), "b") - np.trim_zeros(getattr(c2, n), "b"))
               .max() for n in "RST")


@pytest.mark.parametrize("make", [
    lambda: RecursiveLeastSquares(4, lam=1.0, P0=1e4),
    lambda: SquareRootRLS(4, lam=1.0, P0=1e4),
    lambda: SlidingWindowRLS(4, window=1500, P0=1e4),
], ids=["RecursiveLeastSquares", "SquareRootRLS", "SlidingWindowRLS"])
def test_converged_controller_equals_the_design_on_the_true_plant(make):
    stre = SelfTuningRegulator(make(), DESIGN, na=2, nb=2, nk=1)
    _run(stre, 2000)
    assert np.abs(stre.theta - THETA).max() < 1e-3
    assert _max_diff(stre.controller, rst_design(A, B, AM, AO)) < 1e-3


def test_one_step_is_the_estimator_update_then_the_control_law():
    """The history equals an independent replay: RLS on the logged ARX regressors, then
    R u = T r - S y with the logged controller."""
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), DESIGN, na=2, nb=2)
    N = 300
    y, u, r = _run(stre, N, noise=0.01, seed=3)
    h = stre.history
    assert isinstance(h, STRHistory) and len(h) == N
    assert_array_equal(h.y, y)
    assert_array_equal(h.u, u)
    ref = RecursiveLeastSquares(4, P0=100.0)
    yp, up = np.r_[0.0, 0.0, y], np.r_[0.0, 0.0, u]
    dither = np.zeros(N)
    for t in range(N):
        phi = np.array([-yp[t + 1], -yp[t], up[t + 1], up[t]])
        assert abs(h.e[t] - (y[t] - phi @ ref.x[:, 0])) < 1e-12
        ref.predict_update(y[t], phi)
        assert_allclose(h.theta[t], ref.x[:, 0], rtol=0, atol=1e-12)
        R, S, T = h.R[t], h.S[t], h.T[t]
        law = 0.0                       # no controller before the first accepted design
        if R[0] != 0.0:
            def past(x, k, t=t):
                return x[t - k] if t - k >= 0 else 0.0

            Lc = len(R)
            law = (sum(T[k] * past(r, k) for k in range(Lc))
                   - sum(S[k] * past(y, k) for k in range(Lc))
                   - sum(R[k] * past(u, k) for k in range(1, Lc))) / R[0]
        dither[t] = u[t] - law
        # the controller in use is the design from the step's estimate (when accepted)
        if not h.rejected[t]:
            want = rst_design(A=np.r_[1.0, h.theta[t, :2]], B=np.r_[0.0, h.theta[t, 2:]],
                              Am=AM, Ao=AO)
            assert _max_diff(RSTController(R, S, T), want) < 1e-12
    assert_allclose(np.abs(dither), 0.1, rtol=0, atol=1e-9)     # what is left is the dither


def test_dead_zone_skips_small_prediction_errors():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2,
                               dead_zone=0.02)
    _run(stre, 600, noise=0.01)
    h = stre.history
    assert_array_equal(h.updated, np.abs(h.e) > 0.02)
    assert 0 < (~h.updated).sum() < len(h)
    skipped = np.flatnonzero(~h.updated[1:]) + 1
    assert_array_equal(h.theta[skipped], h.theta[skipped - 1])
    assert_array_equal(h.trace_P[skipped], h.trace_P[skipped - 1])


def test_projection_keeps_the_estimate_in_the_box():
    lower = np.array([-np.inf, -np.inf, 1.2, -np.inf])
    upper = np.full(4, np.inf)
    saved = lower.copy()
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2,
                               bounds=(lower, upper))
    _run(stre, 400)
    h = stre.history
    assert np.all(h.theta[:, 2] >= 1.2)
    assert (h.theta[:, 2] == 1.2).sum() > 10                  # true b1 = 1 is outside
    assert_array_equal(stre.estimator.x[:, 0], h.theta[-1])  # written back into the filter
    assert_array_equal(lower, saved)
    free = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2)
    _run(free, 400)
    assert free.history.theta[:, 2].min() < 1.1                # without the box: below


def test_a_near_common_factor_keeps_the_last_controller():
    # initial estimate A = 1 - 0.5 q^-1, B = q^-1 (1 - 0.5 q^-1): a common factor
    x0 = np.array([-0.5, 0.0, 1.0, -0.5])
    initial = rst_design(A, B, AM, AO)
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e-6, x0=x0), DESIGN, na=2, nb=2,
                               initial=initial)
    u0 = stre.step(0.0, 1.0)              # phi = 0: the estimate stays, the design is refused
    h = stre.history
    assert h.rejected[0] and h.redesigned[0]
    assert_array_equal(np.trim_zeros(h.R[0], "b"), initial.R)
    assert abs(u0 - initial.T[0] / initial.R[0]) < 1e-15
    # without an initial controller there is none: u is the dither alone
    bare = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e-6, x0=x0), DESIGN, na=2, nb=2)
    assert bare.controller is None
    assert bare.step(0.0, 1.0, dither=0.25) == 0.25


def test_a_design_that_fails_is_skipped():
    def fussy(A_, B_):
        if B_[1] < 0.9:
            raise ValueError("no")
        return rst_design(A_, B_, AM, AO)

    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), fussy, na=2, nb=2)
    _run(stre, 300)
    assert stre.history.rejected.any()
    assert _max_diff(stre.controller, rst_design(A, B, AM, AO)) < 0.05


def test_redesign_every_k_samples():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2,
                               redesign_every=5)
    _run(stre, 200)
    h = stre.history
    assert_array_equal(h.redesigned, np.arange(200) % 5 == 0)
    for t in range(1, 200):
        if t % 5:
            assert_array_equal(h.R[t], h.R[t - 1])


def test_saturation_limits_the_applied_control():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2,
                               u_limits=(-0.15, 0.15))
    y, u, r = _run(stre, 300)
    assert u.min() >= -0.15 and u.max() <= 0.15 and (np.abs(u) == 0.15).sum() > 5
    # the saturated control enters the regressor: the estimate still converges
    assert np.abs(stre.theta - THETA).max() < 0.05


def test_excitation_monitor_warns_once_when_the_data_stop_carrying_information():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2,
                               monitor_every=50)
    zero = np.zeros(160)
    with pytest.warns(ExcitationWarning, match=r"steps 0\.\.49 do not excite every parameter") \
            as caught, pytest.warns(RegulatorWarning, match=r"the loop is open"):
        _run(stre, 160, noise=0.0, dither=0.0, r=zero)
    assert len([w for w in caught if issubclass(w.category, ExcitationWarning)]) == 1
    assert stre.history.excitation[49] == 0.0 and np.isnan(stre.history.excitation[48])


def test_a_well_excited_loop_does_not_warn():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, lam=0.99, P0=1e4), DESIGN, na=2, nb=2,
                               monitor_every=100)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _run(stre, 400)
    assert np.nanmin(stre.history.excitation) > 1e-8


def test_windup_warning_under_forgetting_without_excitation():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, lam=0.9, P0=1.0), DESIGN, na=2, nb=2,
                               monitor_every=0)
    with pytest.warns(ExcitationWarning, match=r"at step 65 is more than windup_ratio = 1000 "
                                                r"times its value 4 .* winding up"), \
            pytest.warns(RegulatorWarning, match=r"the loop is open"):
        _run(stre, 100, noise=0.0, dither=0.0, r=np.zeros(100))
    # phi = 0: P / lam each step, trace(P) after step k is 4 / 0.9^(k+1); no block was excited,
    # so the reference is trace(P0) = 4, exceeded 1e3-fold first at k + 1 = 66
    h = stre.history
    assert_allclose(h.trace_P, 4.0 / 0.9 ** np.arange(1, 101), rtol=1e-13)
    assert int(np.argmax(h.trace_P > 4e3)) == 65


def test_windup_is_measured_from_the_last_well_excited_block():
    """A tight prior does not count as windup: the reference is the excited data's level."""
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, lam=0.98, P0=1e-6, x0=THETA), DESIGN,
                               na=2, nb=2, monitor_every=100)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        _run(stre, 400, noise=0.01)
    h = stre.history
    assert h.trace_P[-1] > 1e3 * h.trace_P[0]          # far above the prior, and no warning
    # then the excitation stops: both warnings come
    with pytest.warns(ExcitationWarning) as caught:
        _run(stre, 800, noise=0.0, dither=0.0, r=np.zeros(800))
    messages = [str(w.message) for w in caught]
    assert any("winding up" in m for m in messages)
    assert any("do not excite every parameter" in m for m in messages)


def test_a_failing_step_leaves_the_regulator_as_it_was():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2)
    _run(stre, 50)
    before = stre.state
    with pytest.raises(ValueError, match=r"`y` must be finite; got nan"):
        stre.step(np.nan, 1.0)
    assert_array_equal(stre.state, before)

    def too_big(A_, B_):
        return RSTController(np.r_[1.0, np.zeros(8), 0.1], [1.0], [1.0])

    stre.design = too_big
    with pytest.raises(ValueError, match=r"deg R = 9 > max_order = 5; pass a larger max_order"):
        stre.step(0.3, 1.0)
    assert_array_equal(stre.state, before)
    assert len(stre.history) == 50


@pytest.mark.parametrize("kwargs, exc, match", [
    (dict(estimator=RecursiveLeastSquares(3)), ValueError, r"`estimator` must have dim_x = na "
                                                           r"\+ nb = 4 and dim_z = 1; got dim_x "
                                                           r"= 3"),
    (dict(estimator=object()), TypeError, r"`estimator` must be an rlsfilt filter"),
    (dict(design=3), TypeError, r"`design` must be a callable"),
    (dict(nk=0), ValueError, r"`nk` must be >= 1"),
    (dict(bounds=(0.0,)), TypeError, r"`bounds` must be a pair"),
    (dict(bounds=(1.0, 0.0)), ValueError, r"`bounds` must have lower <= upper"),
    (dict(bounds=(np.zeros(3), 1.0)), ValueError, r"`bounds` lower must be a scalar or have "
                                                  r"shape \(4,\)"),
    (dict(u_limits=(1.0, -1.0)), ValueError, r"`u_limits` must have u_min < u_max"),
    (dict(dead_zone=-1.0), ValueError, r"`dead_zone` must be a finite value >= 0"),
    (dict(windup_ratio=1.0), ValueError, r"`windup_ratio` must be a finite number > 1"),
    (dict(redesign_every=0), ValueError, r"`redesign_every` must be >= 1"),
])
def test_bad_arguments_name_the_argument(kwargs, exc, match):
    args = dict(estimator=RecursiveLeastSquares(4), design=DESIGN, na=2, nb=2)
    args.update(kwargs)
    with pytest.raises(exc, match=match):
        SelfTuningRegulator(**args)


def test_history_plot_and_repr():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=1e4), DESIGN, na=2, nb=2, dt=0.1)
    _run(stre, 120)
    h = stre.history
    assert_allclose(h.t, 0.1 * np.arange(120))
    fig = h.plot(true_theta=THETA)
    assert len(fig.axes) == 5
    assert fig.axes[-1].get_xlabel() == "time (s)"
    plt.close(fig)
    assert "120 steps" in repr(h)
    assert "SelfTuningRegulator(na=2, nb=2, nk=1" in repr(stre) and "u(t) =" in repr(stre)
