"""Anti-windup forgetting modes of RecursiveLeastSquares."""

import warnings

import numpy as np
import pytest
from conftest import arx_record
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import NumericalWarning, RecursiveLeastSquares

ANTI_WINDUP = ["directional", "constant_trace", "efra", "variable"]
THETA1 = np.array([1.0, 0.5, 0.25])
THETA2 = np.array([0.5, -0.3, 0.8])
SIGMA = 0.05


def windup_record(rng, n1=500, n2=2000, n3=1000):
    """FIR plant: rich input (n1), input held at 1 (n2), parameter jump and rich input (n3).

    While the input is constant every regressor row is [1, 1, 1]: two of the
    three parameter directions get no information at all.
    """
    N = n1 + n2 + n3 + 3
    u = np.sign(rng.standard_normal(N))
    u[n1 + 3:n1 + n2 + 3] = 1.0
    Hs = np.column_stack([u[2:-1], u[1:-2], u[:-3]])
    theta = np.where(np.arange(len(Hs))[:, None] < n1 + n2, THETA1, THETA2)
    zs = (Hs * theta).sum(axis=1) + SIGMA * rng.standard_normal(len(Hs))
    return Hs, zs, n1, n2


# ----------------------------------------------------------------------
# the windup scenario of the issue: lam = 0.98, 2000 samples of constant input
# ----------------------------------------------------------------------
def test_exponential_forgetting_winds_up_and_warns(rng):
    Hs, zs, n1, n2 = windup_record(rng)
    rls = RecursiveLeastSquares(3, lam=0.98, R=SIGMA**2)
    with pytest.warns(NumericalWarning, match=r"ill-conditioned.*at step \d+ of batch_filter"):
        _, P, _, _ = rls.batch_filter(zs, Hs)
    assert np.trace(P[n1:n1 + n2], axis1=1, axis2=2).max() > 1e10


@pytest.mark.parametrize("mode", ANTI_WINDUP)
def test_anti_windup_bounded_and_tracks_jump(rng, mode):
    Hs, zs, n1, n2 = windup_record(rng)
    rls = RecursiveLeastSquares(3, lam=0.98, R=SIGMA**2, forgetting=mode)  # default P0 = 1e4 I
    means, P, _, _ = rls.batch_filter(zs, Hs)
    trace = np.trace(P, axis1=1, axis2=2)
    assert trace[n1:].max() < 1e2                   # plain forgetting: > 1e10
    assert np.all(np.linalg.eigvalsh(P[n1:])[:, 0] > 0)
    j = n1 + n2
    # identified before the input stopped, and still there when it returns
    assert_allclose(means[n1 - 1, :, 0], THETA1, atol=0.05)
    assert_allclose(means[j - 1, :, 0], THETA1, atol=0.05)
    # tracks the jump once the input is rich again
    err = np.abs(means[j:, :, 0] - THETA2).max(axis=1)
    assert err[:10].max() > 0.2                     # the jump is real
    assert err[-300:].max() < 0.05


def test_constant_input_with_noisy_output_alone_is_not_windup(rng):
    """Contrast: the exponential mode is fine as long as the data excite every direction."""
    Hs, zs = arx_record(rng, n_samples=3000)
    rls = RecursiveLeastSquares(4, lam=0.98, R=0.01)
    _, P, _, _ = rls.batch_filter(zs, Hs)
    assert np.trace(P[100:], axis1=1, axis2=2).max() < 1.0


# ----------------------------------------------------------------------
# each mode against its defining equations
# ----------------------------------------------------------------------
def _one_step(rls, phi, z):
    x0, P0 = rls.x.copy(), rls.P.copy()
    rls.predict_update(z, phi)
    return x0, P0


def test_directional_is_information_update_along_regressor(rng):
    rls = RecursiveLeastSquares(3, lam=0.9, R=0.5, forgetting="directional", P0=2.0)
    Hs, zs, *_ = windup_record(rng, 30, 5, 5)
    for phi, z in zip(Hs, zs):
        x0, P0 = _one_step(rls, phi, z)
        rho = phi @ P0 @ phi / 0.5
        eps = 0.9 - 0.1 / rho
        info = np.linalg.inv(P0) + eps * np.outer(phi, phi) / 0.5
        assert_allclose(np.linalg.inv(rls.P), info, rtol=1e-8, atol=1e-8 * np.abs(info).max())
        # x = x0 + P phi' (z - phi x0) / R with the updated P
        assert_allclose(rls.x[:, 0], x0[:, 0] + rls.P @ phi * (z - phi @ x0[:, 0]) / 0.5,
                        rtol=1e-9, atol=1e-12)
        assert rls.lam_t == pytest.approx(eps)


def test_directional_leaves_unexcited_directions_alone():
    rls = RecursiveLeastSquares(2, lam=0.9, forgetting="directional", P0=1.0)
    for _ in range(500):
        rls.predict_update(1.0, [1.0, 0.0])
    # only the excited direction is forgotten; phi P phi' settles at R (1 - lam) / lam
    assert_allclose(rls.P[0, 0], 0.1 / 0.9, rtol=1e-9)
    assert_allclose(rls.P[1, 1], 1.0, rtol=1e-12)
    assert rls.P[0, 1] == 0.0


@pytest.mark.parametrize("mode", ["directional", "variable"])
def test_modes_reduce_to_plain_rls_without_forgetting(rng, mode):
    Hs, zs = arx_record(rng, n_samples=200)
    plain = RecursiveLeastSquares(4, P0=10.0, R=0.3)
    other = RecursiveLeastSquares(4, P0=10.0, R=0.3, forgetting=mode)
    m1, P1, _, _ = plain.batch_filter(zs, Hs)
    m2, P2, _, _ = other.batch_filter(zs, Hs)
    assert_allclose(m2, m1, rtol=1e-12, atol=1e-14)
    assert_allclose(P2, P1, rtol=1e-12, atol=1e-16)


def test_constant_trace_formula(rng):
    rls = RecursiveLeastSquares(4, lam=0.95, forgetting="constant_trace",
                                forgetting_params={"trace": 2.0, "ratio": 100.0})
    assert rls.forgetting_params == {"trace": 2.0, "ratio": 100.0}
    Hs, zs = arx_record(rng, n_samples=50)
    c2 = 2.0 / (100.0 + 4)
    c1 = 2.0 - 4 * c2
    for phi, z in zip(Hs, zs):
        x0, P0 = _one_step(rls, phi, z)
        Pb = P0 - np.outer(P0 @ phi, P0 @ phi) / (1.0 + phi @ P0 @ phi)
        assert_allclose(rls.P, c1 * Pb / np.trace(Pb) + c2 * np.eye(4), rtol=1e-10, atol=1e-14)
        assert np.trace(rls.P) == pytest.approx(2.0, rel=1e-13)
        assert_allclose(rls.x[:, 0], x0[:, 0] + P0 @ phi * (z - phi @ x0[:, 0])
                        / (1.0 + phi @ P0 @ phi), rtol=1e-10, atol=1e-13)
    w = np.linalg.eigvalsh(rls.P)
    assert w[-1] / w[0] < 100.0 + 4


def test_constant_trace_default_trace():
    rls = RecursiveLeastSquares(3, lam=0.98, R=0.5, forgetting="constant_trace")
    assert rls.forgetting_params["trace"] == pytest.approx(3 * 0.5 * 0.02)


def test_efra_formula_and_bounds(rng):
    R = 0.04
    rls = RecursiveLeastSquares(3, lam=0.95, R=R, forgetting="efra")
    assert rls.forgetting_params == {"alpha": 0.5, "beta": 0.005, "delta": 0.005}
    eta = 0.05 / 0.95
    hi = (eta + np.sqrt(eta**2 + 4 * 0.005**2)) / 0.01
    lo = (eta - 0.5 + np.sqrt((0.5 - eta) ** 2 + 4 * 0.005**2)) / 0.01
    assert hi == pytest.approx(eta / 0.005 + 0.005 / eta, rel=0.01)   # the paper's estimate
    Hs, zs, *_ = windup_record(rng, 200, 300, 200)
    first = True
    for phi, z in zip(Hs, zs):
        x0, P0 = _one_step(rls, phi, z)
        if first:   # P0 = 1e4 I was brought into the invariant set before the step
            P0 = hi * R * np.eye(3)
            first = False
        s = R + phi @ P0 @ phi
        P = P0 / 0.95 - 0.5 * np.outer(P0 @ phi, P0 @ phi) / s + 0.005 * R * np.eye(3) \
            - 0.005 / R * P0 @ P0
        assert_allclose(rls.P, P, rtol=1e-9, atol=1e-15)
        assert_allclose(rls.x[:, 0], x0[:, 0] + 0.5 * P0 @ phi * (z - phi @ x0[:, 0]) / s,
                        rtol=1e-9, atol=1e-13)
        w = np.linalg.eigvalsh(rls.P / R)
        assert lo * (1 - 1e-9) <= w[0] and w[-1] <= hi * (1 + 1e-9)


def test_variable_forgetting_factor(rng):
    R = SIGMA**2
    rls = RecursiveLeastSquares(3, lam=0.98, R=R, forgetting="variable", P0=0.01)
    assert rls.forgetting_params == {"lam_min": pytest.approx(0.8), "trace_max": 30.0}
    Hs, zs, *_ = windup_record(rng, 300, 10, 50)
    seen = set()
    for phi, z in zip(Hs, zs):
        x0, P0 = _one_step(rls, phi, z)
        s = R + phi @ P0 @ phi
        e = z - phi @ x0[:, 0]
        lam_t = min(1.0, max(0.8, 1 - 0.02 * e**2 / s))
        assert rls.lam_t == pytest.approx(lam_t, rel=1e-12)
        Pb = P0 - np.outer(P0 @ phi, P0 @ phi) / s
        assert_allclose(rls.P, Pb / lam_t, rtol=1e-10, atol=1e-16)
        seen.add(round(lam_t, 1))
    assert {0.8, 1.0} <= seen          # the floor and the ceiling were both hit
    assert rls.lam_t <= 1.0


def test_variable_trace_cap():
    rls = RecursiveLeastSquares(2, lam=0.9, forgetting="variable",
                                forgetting_params={"trace_max": 5.0, "lam_min": 0.5}, P0=1.0)
    for k in range(300):
        rls.predict_update(10.0 * (-1) ** k, [1.0, 1.0])   # big residuals, one direction
    assert np.trace(rls.P) <= 5.0 * (1 + 1e-12)


# ----------------------------------------------------------------------
# how the modes fit the predict/update split
# ----------------------------------------------------------------------
@pytest.mark.parametrize("mode", ANTI_WINDUP)
def test_predict_only_records_priors_for_regressor_modes(mode):
    rls = RecursiveLeastSquares(2, lam=0.9, forgetting=mode, P0=3.0)
    rls.predict()
    assert_array_equal(rls.P, 3.0 * np.eye(2))
    assert_array_equal(rls.P_prior, rls.P)
    with warnings.catch_warnings():
        warnings.simplefilter("error")     # no ForgettingSkippedWarning: update is a full step
        rls.update(1.0, [1.0, 0.5])
        rls.update(2.0, [0.5, 1.0])
    rls2 = RecursiveLeastSquares(2, lam=0.9, forgetting=mode, P0=3.0)
    rls2.predict_update(1.0, [1.0, 0.5])
    rls2.predict_update(2.0, [0.5, 1.0])
    assert_array_equal(rls.x, rls2.x)
    assert_array_equal(rls.P, rls2.P)


@pytest.mark.parametrize("mode", ["exponential"] + ANTI_WINDUP)
@pytest.mark.parametrize("update_first", [False, True])
def test_batch_filter_equals_stepwise_loop_for_every_mode(rng, mode, update_first):
    Hs, zs, *_ = windup_record(rng, 100, 100, 100)
    zs[[50, 150, 250]] += 5.0                       # outliers for the gate
    zs[[60, 299]] = np.nan                          # missing samples
    kw = dict(lam=0.95, R=SIGMA**2, Q=1e-6, forgetting=mode, gate=4.0)
    batch = RecursiveLeastSquares(3, **kw)
    means, covs, means_p, covs_p = batch.batch_filter(zs, Hs, update_first=update_first)
    loop = RecursiveLeastSquares(3, **kw)
    for k in range(len(zs)):
        if not update_first:
            loop.predict()
            assert_allclose(means_p[k], loop.x, rtol=0, atol=0)
            assert_allclose(covs_p[k], loop.P, rtol=0, atol=0)
        loop.update(zs[k], Hs[k])
        assert_array_equal(means[k], loop.x)
        assert_array_equal(covs[k], loop.P)
        if update_first:
            loop.predict()
    for name in ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "z", "H"):
        assert_array_equal(getattr(batch, name), getattr(loop, name), err_msg=name)
    assert batch.n_gated == loop.n_gated >= 3
    assert batch.n_updates == loop.n_updates == len(zs)
    assert batch.lam_t == loop.lam_t


def test_repr_and_properties():
    rls = RecursiveLeastSquares(2, lam=0.9, forgetting="efra")
    assert rls.forgetting == "efra"
    assert "efra" in repr(rls)
    params = rls.forgetting_params
    params["alpha"] = 2.0                            # a copy: the filter is unchanged
    assert rls.forgetting_params["alpha"] == 0.5


# ----------------------------------------------------------------------
# bad arguments
# ----------------------------------------------------------------------
def test_bad_forgetting_arguments():
    with pytest.raises(ValueError, match=r"`forgetting` must be one of 'exponential', "
                                         r"'directional'.*got 'kalman'"):
        RecursiveLeastSquares(2, forgetting="kalman")
    with pytest.raises(TypeError, match=r"`forgetting_params` has unknown keys \['trace'\] for "
                                        r"forgetting='efra'; allowed: alpha, beta, delta"):
        RecursiveLeastSquares(2, lam=0.9, forgetting="efra", forgetting_params={"trace": 1})
    with pytest.raises(TypeError, match=r"unknown keys \['eps'\] for forgetting='exponential'; "
                                        r"allowed: spread_max, trace_max"):
        RecursiveLeastSquares(2, forgetting_params={"eps": 1})
    for name in ("spread_max", "trace_max"):           # the windup cap of the exponential mode
        for bad in (0.0, -1.0, np.nan):
            with pytest.raises(ValueError, match=rf"`forgetting_params\['{name}'\]` must be a "
                                                 r"positive number \(inf turns the cap off\)"):
                RecursiveLeastSquares(2, lam=0.9, forgetting_params={name: bad})
    with pytest.raises(TypeError, match=r"`forgetting_params` must be a dict or None; got list"):
        RecursiveLeastSquares(2, forgetting="efra", forgetting_params=[1])
    with pytest.raises(ValueError, match=r"`forgetting_params\['beta'\]` must be a positive"):
        RecursiveLeastSquares(2, lam=0.9, forgetting="efra", forgetting_params={"beta": -1})
    with pytest.raises(ValueError, match=r"`forgetting_params\['alpha'\]` must be in \(0, 1\]"):
        RecursiveLeastSquares(2, lam=0.9, forgetting="efra", forgetting_params={"alpha": 1.5})
    with pytest.raises(ValueError, match=r"EFRA constants give an unstable recursion"):
        RecursiveLeastSquares(2, lam=0.5, forgetting="efra", forgetting_params={"delta": 0.5})
    with pytest.raises(ValueError, match=r"`forgetting_params\['lam_min'\]` must be in "
                                         r"\(0, lam\] = \(0, 0.9\]; got 0.95"):
        RecursiveLeastSquares(2, lam=0.9, forgetting="variable",
                              forgetting_params={"lam_min": 0.95})
    with pytest.raises(ValueError, match=r"constant_trace' with lam = 1 needs an explicit"):
        RecursiveLeastSquares(2, forgetting="constant_trace")
    with pytest.raises(ValueError, match=r"`gate` must be a positive finite number; got 0.0"):
        RecursiveLeastSquares(2, gate=0)


# ----------------------------------------------------------------------
# diagonal (per-parameter) forgetting (#30)
# ----------------------------------------------------------------------
def test_diagonal_forgetting_on_separate_regressors_is_each_parameters_ewls(rng):
    """Rows that excite one parameter each keep P diagonal, so each parameter is its own
    scalar recursion forgetting with its own factor at every step: the estimate equals
    exponentially weighted least squares of its samples, sample k weighted by
    lam_i**(t - k) and the prior by lam_i**t / P0 (closed form, 1e-12)."""
    N, lam, P0 = 300, np.array([0.9, 0.97, 1.0]), 4.0
    axis = rng.integers(0, 3, N)
    h = rng.uniform(0.5, 2.0, N)
    Hs = np.zeros((N, 3))
    Hs[np.arange(N), axis] = h
    zs = h * np.array([1.0, -2.0, 0.5])[axis] + 0.1 * rng.standard_normal(N)
    zs[[17, 150]] = np.nan
    rls = RecursiveLeastSquares(3, lam=lam, forgetting="diagonal", P0=P0)
    means = rls.batch_filter(zs, Hs)[0][:, :, 0]
    for t in (0, 5, 40, 149, 150, N - 1):
        age = t - np.arange(t + 1)                       # the prior is t + 1 steps old
        for i in range(3):
            on = (axis[:t + 1] == i) & ~np.isnan(zs[:t + 1])
            w = lam[i] ** age[on]
            info = lam[i] ** (t + 1) / P0 + np.sum(w * h[:t + 1][on] ** 2)
            ewls = np.sum(w * h[:t + 1][on] * zs[:t + 1][on]) / info
            assert_allclose(means[t, i], ewls, rtol=1e-12, atol=1e-14)
    assert_allclose(rls.P, np.diag(np.diag(rls.P)), rtol=0, atol=0)


def test_diagonal_forgetting_with_equal_factors_is_exponential(rng):
    """Equal factors: P / sqrt(lam lam) is P / lam up to round-off (1e-12), and all factors
    1 gives the plain recursion bit for bit (no time update runs)."""
    Hs, zs = arx_record(rng, n_samples=300)
    zs = zs.astype(float)
    zs[[3, 100]] = np.nan
    for lam in (0.95, 1.0):
        a = RecursiveLeastSquares(4, lam=lam, Q=1e-5, P0=100.0)
        b = RecursiveLeastSquares(4, lam=lam, Q=1e-5, P0=100.0, forgetting="diagonal")
        ma, Pa, _, _ = a.batch_filter(zs, Hs)
        mb, Pb, _, _ = b.batch_filter(zs, Hs)
        if lam == 1.0:
            assert_array_equal(mb, ma)
            assert_array_equal(Pb, Pa)
        else:
            assert_allclose(mb, ma, rtol=1e-12, atol=1e-12 * np.abs(ma).max())
            assert_allclose(Pb, Pa, rtol=1e-12, atol=1e-12 * np.abs(Pa).max())
        assert b.lam_t == lam and np.array_equal(b.lam, np.full(4, lam))


def test_diagonal_forgetting_tracks_the_drifting_parameter_only(rng):
    """A constant parameter beside a drifting one: forgetting only the drifting one
    tracks it as well as forgetting both, and estimates the constant one better."""
    N = 4000
    Hs = rng.standard_normal((N, 2))
    drift = 1.0 + np.cumsum(0.01 * rng.standard_normal(N))
    zs = Hs[:, 0] * 2.0 + Hs[:, 1] * drift + 0.3 * rng.standard_normal(N)
    both = RecursiveLeastSquares(2, lam=0.97, R=0.09).batch_filter(zs, Hs)[0][:, :, 0]
    one = RecursiveLeastSquares(2, lam=[1.0, 0.97], forgetting="diagonal",
                                R=0.09).batch_filter(zs, Hs)[0][:, :, 0]
    err = lambda m, i, truth: np.sqrt(np.mean((m[500:, i] - truth[500:]) ** 2))  # noqa: E731
    const = np.full(N, 2.0)
    assert err(one, 0, const) < 0.5 * err(both, 0, const)
    assert err(one, 1, drift) < 1.1 * err(both, 1, drift)


def test_diagonal_lam_is_validated_and_read_only():
    rls = RecursiveLeastSquares(3, lam=[0.9, 0.99, 1.0], forgetting="diagonal")
    assert rls.forgetting == "diagonal" and rls.lam_t == 0.9
    assert rls.forgetting_params == {"spread_max": 1e15, "trace_max": 1e12 * 3e4}
    with pytest.raises(ValueError, match="read-only"):
        rls.lam[0] = 0.5
    given = np.array([0.95, 0.9, 0.8])
    rls.lam = given
    given[0] = 0.1                                       # the filter keeps its own copy
    assert_array_equal(rls.lam, [0.95, 0.9, 0.8])
    rls.lam = 0.97                                       # a number: every parameter
    assert_array_equal(rls.lam, np.full(3, 0.97))
    assert_allclose(rls.alpha, np.full(3, 1 / np.sqrt(0.97)), rtol=1e-15)
    before = rls.lam
    with pytest.raises(ValueError, match=r"`lam` must be a number or have shape \(3,\) \(one "
                                         r"forgetting factor per parameter, dim_x = 3\); got "
                                         r"shape \(2,\)"):
        rls.lam = [0.9, 0.9]
    with pytest.raises(ValueError, match=r"`lam` must be in \(0, 1\]; got lam\[1\] = 1.5"):
        rls.lam = [0.9, 1.5, 0.9]
    with pytest.raises(ValueError, match=r"`lam` must be in \(0, 1\]; got lam\[2\] = nan"):
        RecursiveLeastSquares(3, lam=[0.9, 0.9, np.nan], forgetting="diagonal")
    with pytest.raises(TypeError, match="`lam` must be real"):
        RecursiveLeastSquares(3, lam=[0.9j, 0.9, 0.9], forgetting="diagonal")
    assert rls.lam is before                             # a rejected value changes nothing
    with pytest.raises(ValueError, match=r"`lam` must be a number for "
                                         r"forgetting='exponential'; got an array of shape "
                                         r"\(3,\) \(one factor per parameter: "
                                         r"forgetting='diagonal'\)"):
        RecursiveLeastSquares(3, lam=[0.9, 0.99, 1.0])
    with pytest.raises(TypeError, match=r"unknown keys \['eps'\] for forgetting='diagonal'; "
                                        r"allowed: spread_max, trace_max"):
        RecursiveLeastSquares(3, forgetting="diagonal", forgetting_params={"eps": 1})
    from rlsfilt import ARMAX, RLSBank

    with pytest.raises(ValueError, match=r"`forgetting` must be one of 'exponential', "
                                         r"'directional', 'constant_trace' for RLSBank; got "
                                         r"'diagonal'"):
        RLSBank(2, 3, forgetting="diagonal")
    u = np.sin(np.arange(100.0))
    with pytest.raises(ValueError, match="`forgetting` must not be 'diagonal' for the recursive "
                                         "prediction-error fits"):
        ARMAX(1, 1, 1).fit(u, np.roll(u, 1), method="rpem", forgetting="diagonal")


def test_diagonal_batch_start_does_not_weight_the_rows(rng):
    """``initialize`` under diagonal forgetting is ordinary least squares on the rows
    (diagonal forgetting has no weighted least-squares form)."""
    Hs, zs = arx_record(rng, n_samples=30)
    rls = RecursiveLeastSquares(4, lam=[0.9, 0.95, 0.99, 1.0], forgetting="diagonal", R=0.5)
    rls.initialize(zs, Hs)
    ls = np.linalg.lstsq(Hs, zs, rcond=None)[0]
    assert_allclose(rls.x[:, 0], ls, rtol=1e-10)
    assert_allclose(rls.P, 0.5 * np.linalg.inv(Hs.T @ Hs), rtol=1e-10)


def test_diagonal_smoother_uses_its_time_update(rng):
    """``rts_smoother`` builds the priors of the diagonal mode, L^-1/2 P L^-1/2 + Q: the
    same smoothed trajectory as ``smooth`` (which reads the priors the filter stored)."""
    Hs, zs = arx_record(rng, n_samples=200)
    kw = dict(lam=[0.9, 0.95, 0.99, 1.0], forgetting="diagonal", Q=1e-6, P0=10.0)
    run = RecursiveLeastSquares(4, **kw)
    means, covs, _, _ = run.batch_filter(zs, Hs)
    xs, Ps, _, _ = run.rts_smoother(means, covs)
    smoothed = RecursiveLeastSquares(4, **kw).smooth(zs, Hs)
    assert_allclose(xs, smoothed.means, rtol=1e-12, atol=1e-13)
    assert_allclose(Ps, smoothed.covariances, rtol=1e-12, atol=1e-15)


def test_saver_records_gate_and_forgetting_state(rng):
    from filterpy.common import Saver

    Hs, zs, *_ = windup_record(rng, 50, 0, 0)
    zs[20] += 10.0
    rls = RecursiveLeastSquares(3, lam=0.95, R=SIGMA**2, forgetting="variable", gate=5.0)
    saver = Saver(rls)
    rls.batch_filter(zs, Hs, saver=saver)
    saver.to_array()
    assert saver.gated.sum() == 1 and saver.gated[20]
    assert_array_equal(saver.n_gated[-1], 1)
    lam_min = rls.forgetting_params["lam_min"]
    assert lam_min == 0.5
    assert np.all((saver.lam_t >= lam_min) & (saver.lam_t <= 1.0))
