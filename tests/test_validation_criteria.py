"""Information criteria: MATLAB's published numbers, statsmodels OLS as oracle."""

import math

import numpy as np
import pytest
import statsmodels.api as sm

from rlsfilt import ARX, datasets
from rlsfilt.exceptions import NotFittedError
from rlsfilt.validation import InformationCriteria, criteria_from_loss, information_criteria


def test_matlab_documented_example():
    """MATLAB's ``aic`` page: LossFcn 1.6575, N = 300 (iddata1), np = 6."""
    ic = criteria_from_loss(1.6575, n_samples=300, n_params=6)
    assert isinstance(ic, InformationCriteria)
    assert ic.aic == pytest.approx(1.0150e3, abs=0.05)
    assert ic.aicc == pytest.approx(1.0153e3, abs=0.06)
    assert ic.bic == pytest.approx(1.0372e3, abs=0.05)
    assert ic.naic == pytest.approx(0.5453, abs=5e-5)
    assert ic.fpe == pytest.approx(1.7252, abs=5e-5)


def test_formulas():
    V, N, d = 0.37, 812, 7
    ic = criteria_from_loss(V, N, d)
    c = N * (math.log(2 * math.pi) + 1)
    assert ic.aic == pytest.approx(N * math.log(V) + 2 * d + c, rel=1e-15)
    assert ic.aicc == pytest.approx(ic.aic + 2 * d * (d + 1) / (N - d - 1), rel=1e-15)
    assert ic.bic == pytest.approx(N * math.log(V) + d * math.log(N) + c, rel=1e-15)
    assert ic.naic == pytest.approx(math.log(V) + 2 * d / N, rel=1e-15)
    assert ic.fpe == pytest.approx(V * (N + d) / (N - d), rel=1e-15)
    assert ic.mdl == pytest.approx(V * (1 + d * math.log(N) / N), rel=1e-15)
    assert ic.as_dict()["n_params"] == d
    assert "aic=" in repr(ic)
    two = criteria_from_loss(V, N, d, n_outputs=2)
    assert two.aic - ic.aic == pytest.approx(c, rel=1e-14)
    assert math.isinf(criteria_from_loss(V, 8, 7).aicc)
    assert math.isinf(criteria_from_loss(V, 7, 7).fpe)


def test_model_criteria_match_statsmodels_ols():
    d = datasets.mass_spring_damper()
    model = ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y)
    Phi, target = model.regressors(d.u, d.y)
    ols = sm.OLS(target, Phi).fit()
    ic = information_criteria(model, d.u, d.y)
    assert ic.n_samples == len(target) == model.n_samples_
    assert ic.n_params == 4
    assert ic.loss == pytest.approx(ols.ssr / len(target), rel=1e-10)
    assert ic.aic == pytest.approx(ols.aic, rel=1e-10)
    assert ic.bic == pytest.approx(ols.bic, rel=1e-10)


def test_criteria_prefer_true_order():
    d = datasets.dc_motor()
    scores = {}
    for na in (1, 2, 3, 4):
        m = ARX(na, na, d.nk).fit(d.u, d.y)
        scores[na] = information_criteria(m, d.u, d.y)
    assert min(scores, key=lambda k: scores[k].bic) == d.na == 2
    assert min(scores, key=lambda k: scores[k].mdl) == 2


def test_validation_data_and_several_outputs(rng):
    d = datasets.thermal_process()
    m = ARX(d.na, d.nb, d.nk).fit(d.u[:600], d.y[:600])
    ic_val = information_criteria(m, d.u[600:], d.y[600:])
    Phi, target = m.regressors(d.u[600:], d.y[600:])
    e = target - Phi @ m.theta_
    assert ic_val.loss == pytest.approx(np.mean(e ** 2), rel=1e-12)
    # two outputs: V is the determinant of the residual covariance
    u = rng.standard_normal(400)
    Y = np.column_stack([np.convolve(u, [0, 1.0, 0.3])[:400], np.convolve(u, [0, 0.5])[:400]])
    Y += 0.1 * rng.standard_normal((400, 2))
    m2 = ARX(1, 2).fit(u, Y)
    ic2 = information_criteria(m2, u, Y)
    Phi, T = m2.regressors(u, Y)
    E = T - Phi @ m2.theta_
    assert ic2.n_outputs == 2
    assert ic2.n_params == 2 * 4                    # [a11 a12 b1 b2] per output (na=1, nb=2)
    assert ic2.loss == pytest.approx(np.linalg.det(E.T @ E / len(E)), rel=1e-10)


def test_criteria_errors():
    with pytest.raises(ValueError, match="`loss` must be a positive finite number; got 0.0"):
        criteria_from_loss(0.0, 10, 2)
    with pytest.raises(ValueError, match="`n_samples` must be >= 1; got 0"):
        criteria_from_loss(1.0, 0, 2)
    with pytest.raises(TypeError, match="`n_params` must be an integer; got 2.5"):
        criteria_from_loss(1.0, 10, 2.5)
    with pytest.raises(NotFittedError, match="not fitted yet; call `fit"):
        information_criteria(ARX(1, 1), np.zeros(10), np.zeros(10))
    with pytest.raises(TypeError, match="`model` must be a fitted ARX model"):
        information_criteria(object(), np.zeros(10), np.zeros(10))
