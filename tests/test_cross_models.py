"""Every model class x inputs/outputs x several experiments x offsets x every consumer.

Each registered case is fitted on an `IOData` of three experiments of uneven lengths (one
shorter than a 3-step horizon, one shorter than the model's lags in the consumers) and its
consumers are checked against oracles that share no code with them:

- ``predict(horizon=k)`` for k = 1, 3 and inf on every experiment against filterpy: the
  Kalman filter of `to_kalman` run on the deviations from the operating point, ``k``
  predicts from the posterior at ``t - k`` (the filter's machinery, not the predictor's
  polynomial formula); ``k >= N`` and ``np.inf`` against ``simulate``, which is checked
  against python-control's ``forced_response`` of ``to_ss()``;
- ``compare(initial="zero", horizon=k)`` fit against MATLAB's fit written here from those
  predictions over the rows of every experiment;
- ``residual_analysis`` against statsmodels' Ljung-Box statistic of the concatenated
  one-step errors, and ``information_criteria`` loss against their mean square (the
  determinant of their covariance for two outputs).

A new model class or option joins every check with one line in `CASES`.
"""

from dataclasses import dataclass, field

import control
import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.signal import lfilter
from statsmodels.stats.diagnostic import acorr_ljungbox
from test_adaptive_kalman import kalman_predictions

from rlsfilt import AR, ARMA, ARMAX, ARX, BJ, OE, IOData, OperatingPointWarning, compare
from rlsfilt.adaptive import to_kalman
from rlsfilt.validation import information_criteria, residual_analysis

LENGTHS = (160, 90, 2)        # the last experiment: shorter than the 3-step horizon


def _plant(gen, N, nu, ny, level):
    """Two inputs with delays 1 and 3 (or 0 and 2 for a feed-through), coloured noise,
    around an operating point `level` (0: none)."""
    U = gen.standard_normal((N, max(nu, 1)))
    e = gen.standard_normal((N, ny))
    Y = np.zeros((N, ny))
    for i in range(ny):
        Y[:, i] = lfilter([1, 0.4], [1, -1.2, 0.5], 0.3 * e[:, i])
        if nu:
            Y[:, i] += lfilter([0, 1.0, 0.5], [1, -1.2, 0.5], U[:, 0]) * (1 + i)
        if nu > 1:
            Y[:, i] += lfilter([0, 0, 0, 0.7], [1, -0.6], U[:, 1])
        if i:
            Y[:, i] += 0.5 * Y[:, 0]
    return U[:, :nu] + level, Y + 3 * level


@dataclass
class CrossCase:
    """``make()`` an unfitted model of `nu` inputs and `ny` outputs, fitted on data around
    `level`; ``fit_kwargs`` go to ``fit``."""

    name: str
    make: object
    nu: int
    ny: int = 1
    level: float = 0.0
    fit_kwargs: dict = field(default_factory=dict)

    def records(self, seed=0):
        gen = np.random.default_rng(seed)
        out = []
        for N in LENGTHS:
            U, Y = _plant(gen, N, self.nu, self.ny, self.level)
            u = None if self.nu == 0 else (U if self.nu > 1 else U[:, 0])
            out.append((u, Y if self.ny > 1 else Y[:, 0]))
        return out

    def data(self, records):
        if self.nu == 0:
            return None, [y for _, y in records]
        return IOData([u for u, _ in records], [y for _, y in records]), None

    def fitted(self):
        recs = self.records()
        d, ys = self.data(recs)
        model = self.make()
        model = model.fit(ys, **self.fit_kwargs) if self.nu == 0 else \
            model.fit(d, **self.fit_kwargs)
        return model, recs


CASES = [
    CrossCase("ARX-siso", lambda: ARX(2, 2, 1), 1),
    CrossCase("ARX-2-inputs-delays-1-3", lambda: ARX(2, [2, 1], [1, 3]), 2),
    CrossCase("ARX-2-inputs-feedthrough", lambda: ARX(2, [2, 1], [0, 2]), 2),
    CrossCase("ARX-2-outputs", lambda: ARX(2, [2, 1], [1, 3]), 2, ny=2),
    CrossCase("ARX-offset", lambda: ARX(2, [2, 1], [1, 3], offset=True), 2, level=5.0),
    CrossCase("ARX-offset-mean", lambda: ARX(2, [2, 1], [1, 3], offset="mean"), 2, level=5.0),
    CrossCase("ARX-offset-2-outputs", lambda: ARX(2, [2, 1], [1, 3], offset=True), 2, ny=2,
              level=5.0),
    CrossCase("ARX-iv-offset", lambda: ARX(2, [2, 1], [1, 3], offset=True), 2, level=5.0,
              fit_kwargs={"method": "iv"}),
    CrossCase("ARX-rls", lambda: ARX(2, [2, 1], [1, 3]), 2, fit_kwargs={"method": "rls"}),
    CrossCase("ARMAX", lambda: ARMAX(2, [2, 1], 1, [1, 3]), 2),
    CrossCase("ARMAX-feedthrough", lambda: ARMAX(2, [2, 1], 1, [0, 2]), 2),
    CrossCase("ARMAX-rpem", lambda: ARMAX(2, 2, 1, 1), 1, fit_kwargs={"method": "rpem"}),
    CrossCase("OE", lambda: OE([2, 1], [2, 1], [1, 3]), 2),
    CrossCase("OE-feedthrough", lambda: OE([2, 1], [2, 1], [0, 2]), 2),
    CrossCase("BJ", lambda: BJ([2, 1], 1, 1, [2, 1], [1, 3]), 2),
    CrossCase("BJ-feedthrough-nd2", lambda: BJ([2, 1], 1, 2, [2, 1], [0, 2]), 2),
    CrossCase("AR", lambda: AR(2), 0),
    CrossCase("ARMA", lambda: ARMA(2, 1), 0),
]

cases = pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
INPUT_CASES = [c for c in CASES if c.nu]
input_cases = pytest.mark.parametrize("case", INPUT_CASES, ids=[c.name for c in INPUT_CASES])


_FITTED = {}     # one fit per case for the whole module (the checks never modify a model)


def _fitted(case):
    if case.name not in _FITTED:
        _FITTED[case.name] = case.fitted()
    return _FITTED[case.name]


def _ops(model, nu, ny):
    u_op = np.asarray(getattr(model, "input_offset_", np.zeros(nu)), float).reshape(nu)
    y_op = np.asarray(getattr(model, "output_offset_", np.zeros(ny)), float).reshape(ny)
    return u_op, y_op


def _filter(model):
    if np.any(_ops(model, model.n_inputs_, model.n_outputs_)[1] != 0):
        with pytest.warns(OperatingPointWarning):
            return to_kalman(model)
    return to_kalman(model)


def _arrays(case, u, y):
    N = len(y)
    U = np.zeros((N, 0)) if u is None else np.asarray(u, float).reshape(N, -1)
    return U, np.asarray(y, float).reshape(N, -1)


def _predict(model, u, y, horizon):
    return np.asarray(model.predict(u, y, horizon=horizon), float).reshape(len(y), -1)


def _oracle(case, model, kf, u, y, horizon):
    """The k-step prediction by filterpy (k finite, < N), else the simulation of to_ss."""
    U, Y = _arrays(case, u, y)
    u_op, y_op = _ops(model, U.shape[1], Y.shape[1])
    N = len(Y)
    if np.isfinite(horizon) and horizon < N:
        return kalman_predictions(kf, U - u_op, Y - y_op, int(horizon)) + y_op
    if case.nu == 0:                                   # no input: the free response is zero
        return np.zeros_like(Y) + y_op
    ss = control.forced_response(model.to_ss(), np.arange(N), (U - u_op).T).outputs
    return np.atleast_2d(ss).T.reshape(N, -1) + y_op


def _fit_percent(Y, Yhat):
    return 100 * (1 - np.linalg.norm(Y - Yhat, axis=0) / np.linalg.norm(Y - Y.mean(0), axis=0))


@cases
@pytest.mark.parametrize("horizon", [1, 3, np.inf])
def test_predict_and_compare_on_several_experiments_equal_the_oracles(case, horizon):
    model, recs = _fitted(case)
    kf = _filter(model)
    d, ys = case.data(recs)
    got = (model.predict(None, ys, horizon=horizon) if case.nu == 0
           else model.predict(d, horizon=horizon))
    assert isinstance(got, list) and len(got) == len(recs)
    wants = []
    for (u, y), g in zip(recs, got):
        want = _oracle(case, model, kf, u, y, horizon)
        scale = max(np.abs(want).max(), 1.0)
        assert_allclose(np.asarray(g, float).reshape(want.shape), want, rtol=0,
                        atol=1e-9 * scale)
        # one experiment on its own gives the same as within the list
        assert_allclose(_predict(model, u, y, horizon), want, rtol=0, atol=1e-9 * scale)
        wants.append(want)
    # MATLAB's fit over every sample of every experiment (from rest: initial="zero")
    c = compare(model, d, ys, initial="zero", horizon=horizon)
    Y = np.vstack([_arrays(case, u, y)[1] for u, y in recs])
    assert_allclose(np.atleast_1d(c.fit), _fit_percent(Y, np.vstack(wants)), rtol=1e-10)


@input_cases
def test_simulate_from_rest_is_the_state_space_response(case):
    model, recs = _fitted(case)
    for u, y in recs:
        U, Y = _arrays(case, u, y)
        u_op, y_op = _ops(model, U.shape[1], Y.shape[1])
        ss = control.forced_response(model.to_ss(), np.arange(len(U)), (U - u_op).T).outputs
        want = np.atleast_2d(ss).T.reshape(len(U), -1) + y_op
        got = np.asarray(model.simulate(u), float).reshape(want.shape)
        assert_allclose(got, want, rtol=0, atol=1e-9 * max(np.abs(want).max(), 1.0))


@cases
def test_residual_statistics_on_several_experiments_equal_statsmodels(case):
    model, recs = _fitted(case)
    kf = _filter(model)
    E = np.vstack([(_arrays(case, u, y)[1] - _oracle(case, model, kf, u, y, 1))[model.max_lag:]
                   for u, y in recs])
    d, ys = case.data(recs)
    for i in range(case.ny):
        r = residual_analysis(model, d, ys, max_lag=8, output=i)
        assert_allclose(r.residuals, E[:, i], rtol=0, atol=1e-9 * np.abs(E).max())
        q = acorr_ljungbox(E[:, i], lags=[8])["lb_stat"].iloc[0]
        assert r.q_statistic == pytest.approx(q, rel=1e-9)
    ic = information_criteria(model, d, ys) if case.nu else information_criteria(model, None, ys)
    V = np.mean(E[:, 0] ** 2) if case.ny == 1 else np.linalg.det(E.T @ E / len(E))
    assert ic.loss == pytest.approx(V, rel=1e-9)
    assert ic.n_samples == sum(max(len(y) - model.max_lag, 0) for _, y in recs)


OE_CASES = [c for c in CASES if c.name.startswith("OE")]


@pytest.mark.parametrize("case", OE_CASES, ids=[c.name for c in OE_CASES])
@pytest.mark.parametrize("horizon", [2, 3])
def test_a_model_without_noise_model_has_the_same_fit_at_every_horizon(case, horizon):
    # H = 1 (OE): every k-step prediction is the simulation, from the estimated state too
    model, recs = _fitted(case)
    p = model.polydata()
    assert not (np.any(p.A[..., 1:]) or np.any(p.C[..., 1:]) or np.any(p.D[..., 1:]))
    d, _ = case.data(recs)
    sim = compare(model, d)
    pred = compare(model, d, horizon=horizon)
    assert_allclose(pred.y_hat, sim.y_hat, rtol=1e-9, atol=1e-9)
    assert pred.fit == pytest.approx(sim.fit, abs=1e-9)
