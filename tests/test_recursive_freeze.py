"""freeze()/unfreeze()/adapt on the streaming Recursive* estimators (#31, MATLAB's
``EnableAdaptation = false``).

For every class and estimation method: while frozen, ``theta`` and ``P`` stay
bit-equal and each output is the prediction of the held estimate (computed by
hand from the lagged data for ARX/AR, from the step's regressor for the
others); after :meth:`unfreeze` the estimator continues bit for bit as a
reference fed the same data with adaptation off for those samples: the filter
run by hand on the regressor rows with the filter-level :meth:`freeze` (the
gradient and window methods, ARX/AR), or, for the compiled RPEM/RPLR step, the
same recursion with an all-rejecting gate over those samples (with ``lam = 1``,
no profile and no random walk a gated step changes neither ``theta`` nor ``P``).
"""

import copy
import pickle

import numpy as np
import pytest
from numpy.testing import assert_array_equal
from scipy.signal import lfilter

from rlsfilt import (
    LMS,
    NLMS,
    RecursiveAR,
    RecursiveARMA,
    RecursiveARMAX,
    RecursiveARX,
    RecursiveBJ,
    RecursiveLeastSquares,
    RecursiveOE,
    SlidingWindowRLS,
)
from rlsfilt.filters.forgetting import CFG_GATE

N, F0, F1 = 300, 120, 190          # record length, first frozen sample, first after


def _record(seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    e = 0.1 * rng.standard_normal(N)
    y = lfilter([0, 1.0, 0.5], [1, -1.2, 0.5], u) + lfilter([1, 0.3], [1, -0.5], e)
    return u, y


# (class, orders, options, has an input, hand-built ARX/AR rows (na, nb, nk) or None)
CASES = {
    "arx-rls": (RecursiveARX, (2, 2, 1), {}, True, (2, 2, 1)),
    "arx-nlms": (RecursiveARX, (2, 2, 1), {"method": "nlms", "mu": 0.5}, True, (2, 2, 1)),
    "arx-lms": (RecursiveARX, (2, 2, 1), {"method": "lms", "mu": 0.02}, True, (2, 2, 1)),
    "arx-window": (RecursiveARX, (2, 2, 1), {"window": 40}, True, (2, 2, 1)),
    "ar-rls": (RecursiveAR, (2,), {}, False, (2, 0, 1)),
    "ar-nlms": (RecursiveAR, (2,), {"method": "nlms", "mu": 0.5}, False, (2, 0, 1)),
    "ar-lms": (RecursiveAR, (2,), {"method": "lms", "mu": 0.02}, False, (2, 0, 1)),
    "ar-window": (RecursiveAR, (2,), {"window": 30}, False, (2, 0, 1)),
    "oe-rpem": (RecursiveOE, (2, 2, 1), {}, True, None),
    "oe-rplr": (RecursiveOE, (2, 2, 1), {"method": "rplr"}, True, None),
    "oe-window": (RecursiveOE, (2, 2, 1), {"window": 50}, True, None),
    "armax-rpem": (RecursiveARMAX, (2, 2, 1, 1), {}, True, None),
    "armax-rplr": (RecursiveARMAX, (2, 2, 1, 1), {"method": "rplr"}, True, None),
    "bj-rpem": (RecursiveBJ, (2, 1, 1, 2, 1), {}, True, None),
    "bj-rplr": (RecursiveBJ, (2, 1, 1, 2, 1), {"method": "rplr"}, True, None),
    "arma-rpem": (RecursiveARMA, (2, 1), {}, False, None),
    "arma-rplr": (RecursiveARMA, (2, 1), {"method": "rplr"}, False, None),
}
FILTER_METHODS = ("nlms", "lms")


def _make(name, **extra):
    cls, orders, options, _, _ = CASES[name]
    return cls(*orders, **{**options, **extra})


def _has_P(est):
    return est.method not in FILTER_METHODS


def _steps(est, name, u, y, lo, hi):
    has_u = CASES[name][3]
    return [est.step(y[t], u[t]) if has_u else est.step(y[t]) for t in range(lo, hi)]


def _rows(y, u, na, nb, nk):
    """[-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1)], lags before the start zero."""
    rows = np.zeros((len(y), na + nb))
    for t in range(len(y)):
        for i in range(na):
            rows[t, i] = -y[t - 1 - i] if t - 1 - i >= 0 else 0.0
        for i in range(nb):
            rows[t, na + i] = u[t - nk - i] if t - nk - i >= 0 else 0.0
    return rows


def _phi(est):
    """The regressor of the estimator's last step."""
    return est._state.phi


@pytest.mark.parametrize("name", sorted(CASES))
def test_frozen_steps_hold_the_estimate_and_predict_with_it(name):
    u, y = _record()
    est = _make(name)
    _steps(est, name, u, y, 0, F0)
    theta = est.theta
    P = est.P if _has_P(est) else None
    assert est.freeze() is est and est.frozen and not est.adapt
    assert "frozen" in repr(est)
    rows = None if CASES[name][4] is None else _rows(y, u, *CASES[name][4])
    for t in range(F0, F1):
        yhat, th = _steps(est, name, u, y, t, t + 1)[0]
        assert_array_equal(th, theta)
        assert_array_equal(est.theta, theta)
        if P is not None:
            assert_array_equal(est.P, P)
        phi = _phi(est) if rows is None else rows[t]
        if rows is not None:
            assert_array_equal(_phi(est), rows[t])       # the lags moved on
        assert yhat == pytest.approx(float(phi @ theta), rel=1e-13, abs=1e-13)
        assert est.last_error == pytest.approx(y[t] - yhat, rel=1e-13, abs=1e-13)
    assert est.n_steps == F1
    # batch while frozen: the same as the steps, the estimate still held
    twin = copy.deepcopy(est)
    steps = _steps(twin, name, u, y, F1, N)
    has_u = CASES[name][3]
    yh, hist = est.batch(y[F1:], u[F1:]) if has_u else est.batch(y[F1:])
    assert_array_equal(yh, [s[0] for s in steps])
    assert_array_equal(hist, np.tile(theta, (N - F1, 1)))
    assert_array_equal(est.theta, theta)
    est.unfreeze()
    assert not est.frozen and est.adapt and "frozen" not in repr(est)


def _hand_filter(name, n):
    _, _, options, _, _ = CASES[name]
    opts = {k: v for k, v in options.items() if k not in ("method", "window")}
    if "window" in options:
        return SlidingWindowRLS(n, options["window"], 1, **opts)
    return {"nlms": NLMS, "lms": LMS}[options["method"]](n, 1, **opts)


@pytest.mark.parametrize("name", [k for k in CASES if k.endswith(("nlms", "lms", "window"))
                                  and CASES[k][4] is not None])
def test_unfreeze_continues_as_the_filter_frozen_on_the_rows(name):
    """Gradient and window methods of ARX/AR: the filter run by hand on the rows,
    frozen with the filter's own freeze() over the same samples (bit for bit)."""
    u, y = _record(1)
    rows = _rows(y, u, *CASES[name][4])
    est = _make(name)
    filt = _hand_filter(name, rows.shape[1])
    for t in range(N):
        if t == F0:
            est.freeze()
            filt.freeze()
        if t == F1:
            est.unfreeze()
            filt.unfreeze()
        yhat, th = _steps(est, name, u, y, t, t + 1)[0]
        filt.predict()
        assert yhat == float(rows[t] @ filt.x[:, 0])
        filt.update(y[t], rows[t])
        assert_array_equal(th, filt.x[:, 0])
    if "window" in CASES[name][2]:
        assert_array_equal(est.P, filt.P)


def _gated(est, on):
    est._state._cfg[CFG_GATE] = 0.0 if on else np.inf


@pytest.mark.parametrize("name", [k for k in CASES
                                  if not k.endswith(("nlms", "lms", "window"))])
def test_unfreeze_continues_as_a_recursion_that_skipped_those_updates(name):
    """The compiled RPEM/RPLR step (ARX/AR rls, OE, ARMAX, BJ, ARMA): bit for bit the
    same recursion with every update of the frozen samples rejected by its gate."""
    u, y = _record(2)
    est, ref = _make(name, lam_start=1.0), _make(name, lam_start=1.0)
    out, expected = [], []
    for t in range(N):
        if t == F0:
            est.freeze()
            _gated(ref, True)
        if t == F1:
            est.unfreeze()
            _gated(ref, False)
        out.append(_steps(est, name, u, y, t, t + 1)[0])
        expected.append(_steps(ref, name, u, y, t, t + 1)[0])
        if t == F0 + 5:                   # the held estimate differs from the start's
            assert not np.array_equal(est.theta, np.zeros_like(est.theta))
    for (a, ta), (b, tb) in zip(out, expected):
        assert a == b
        assert_array_equal(ta, tb)
    assert_array_equal(est.P, ref.P)
    # and the frozen span changed the outcome (a test that can fail)
    plain = _make(name, lam_start=1.0)
    _steps(plain, name, u, y, 0, N)
    assert not np.array_equal(plain.theta, est.theta)


def test_frozen_profile_waits_and_arx_rls_is_the_frozen_filter():
    """The forgetting profile does not advance while frozen; RecursiveARX's least
    squares equals RecursiveLeastSquares frozen by hand over the same rows (1e-12)."""
    u, y = _record(3)
    est = RecursiveARX(2, 2, 1, lam=0.99, lam_start=0.9)
    rows = _rows(y, u, 2, 2, 1)
    _steps(est, "arx-rls", u, y, 0, F0)
    lam_now = est._state.lam_now
    est.freeze()
    _steps(est, "arx-rls", u, y, F0, F1)
    assert est._state.lam_now == lam_now
    # against the filter (profile off so the filter's constant factor applies)
    est = RecursiveARX(2, 2, 1, lam=0.995, lam_start=1.0)
    filt = RecursiveLeastSquares(4, 1, lam=0.995, P0=1e4)
    for t in range(N):
        if t == F0:
            est.freeze()
            filt.freeze()
        if t == F1:
            est.unfreeze()
            filt.unfreeze()
        yhat, th = est.step(y[t], u[t])
        filt.predict()
        filt.update(y[t], rows[t])
        np.testing.assert_allclose(th, filt.x[:, 0], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(est.P, filt.P, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("name", ["arx-rls", "arx-nlms", "oe-window", "armax-rpem"])
def test_switch_survives_reset_copies_and_pickles_and_rejects_bad_values(name):
    u, y = _record(4)
    est = _make(name)
    _steps(est, name, u, y, 0, 50)
    est.adapt = False
    for twin in (copy.copy(est), copy.deepcopy(est), pickle.loads(pickle.dumps(est))):
        assert twin.frozen
        theta = twin.theta
        _steps(twin, name, u, y, 50, 60)
        assert_array_equal(twin.theta, theta)
    assert est.n_steps == 50              # the copies did not move the original
    est.reset()
    assert est.frozen and est.n_steps == 0
    theta = est.theta
    _steps(est, name, u, y, 0, 20)
    assert_array_equal(est.theta, theta)
    for bad in ("no", 2, None, np.array([True, False])):
        with pytest.raises((TypeError, ValueError), match="adapt"):
            est.adapt = bad
        assert est.frozen
    est.adapt = True
    assert not est.frozen
    _steps(est, name, u, y, 20, 60)
    assert not np.array_equal(est.theta, theta)


# ----------------------------------------------------------------------
# RecursiveIV
# ----------------------------------------------------------------------
def _riv(instruments, **kw):
    from rlsfilt import RecursiveIV

    return RecursiveIV(2, 2, 1, instruments=instruments, **kw)


def _riv_step(est, t, u, y):
    if est.instruments == "given":
        return est.step(y[t], u[t], z=[u[t - 3], u[t - 4], u[t - 1], u[t - 2]])
    return est.step(y[t], u[t])


@pytest.mark.parametrize("instruments", ["model", "delayed", "given"])
def test_riv_frozen_steps_hold_the_estimate_and_predict_with_it(instruments):
    u, y = _record(5)
    est = _riv(instruments, theta_aux=[-1.0, 0.3, 1.0, 0.0], refresh=25)
    for t in range(4, F0):
        _riv_step(est, t, u, y)
    theta, P = est.theta, est.P
    aux = (est._alpha.copy(), est._beta.copy())
    est.freeze()
    assert est.frozen and not est.adapt and repr(est).endswith("frozen")
    for t in range(F0, F1):
        yhat, th = _riv_step(est, t, u, y)
        assert_array_equal(th, theta)
        assert_array_equal(est.P, P)
        assert yhat == pytest.approx(float(est.phi @ theta), rel=1e-13, abs=1e-13)
    assert_array_equal(est._alpha, aux[0])             # the auxiliary model held
    assert_array_equal(est._beta, aux[1])
    est.unfreeze()
    _riv_step(est, F1, u, y)
    assert not np.array_equal(est.theta, theta)
    with pytest.raises(TypeError, match="adapt"):
        est.adapt = "no"


@pytest.mark.parametrize("instruments, options", [("delayed", {}),
                                                   ("model", {"refresh": 0})])
def test_riv_unfreeze_continues_as_a_recursion_that_skipped_those_updates(instruments,
                                                                          options):
    """Bit for bit the same recursion whose updates of those samples its conditioning
    check rejected (tol = inf: theta and P untouched with lam = 1 and no random walk)."""
    import warnings

    from rlsfilt.models._recursive_kernels import RF_TOL

    u, y = _record(6)
    est = _riv(instruments, theta_aux=[-1.0, 0.3, 1.0, 0.0], **options)
    ref = _riv(instruments, theta_aux=[-1.0, 0.3, 1.0, 0.0], **options)
    tol = ref._fpar[RF_TOL]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # the reference's skipped updates
        for t in range(4, N):
            if t == F0:
                est.freeze()
                ref._fpar[RF_TOL] = np.inf
            if t == F1:
                est.unfreeze()
                ref._fpar[RF_TOL] = tol
            a, b = _riv_step(est, t, u, y), _riv_step(ref, t, u, y)
            assert a[0] == b[0]
            assert_array_equal(a[1], b[1])
    assert_array_equal(est.P, ref.P)
    assert ref.n_skipped == F1 - F0 and est.n_skipped == 0


def test_riv_rows_taken_while_frozen_do_not_count_towards_the_exact_start():
    """Frozen from the first sample: the exact start after unfreeze() is the IV solution
    of the next k0 rows (numpy), not of rows seen while frozen."""
    u, y = _record(7)
    k0 = 20
    est = _riv("delayed", k0=k0).freeze()
    for t in range(0, 40):
        yhat, _ = _riv_step(est, t, u, y)
    assert_array_equal(est.theta, np.zeros(4))
    est.unfreeze()
    Phi, Z, target = [], [], []
    for t in range(40, 40 + k0):
        _riv_step(est, t, u, y)
        Phi.append(est.phi)
        Z.append(est.z)
        target.append(y[t])
    Phi, Z = np.array(Phi), np.array(Z)
    expected = np.linalg.solve(Z.T @ Phi, Z.T @ np.array(target))
    np.testing.assert_allclose(est.theta, expected, rtol=1e-9)
