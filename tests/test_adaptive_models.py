"""Every model class through the model interface (polydata: A, B, C, D, F), not only ARX.

The ARMAX, OE and BJ classes are written elsewhere; a minimal object with
``polydata()`` stands for them here, with the textbook one-step predictors as
oracles (Ljung 1999, sec. 3.2).
"""

import copy

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.signal import lfilter

from rlsfilt.adaptive import minimum_variance, rst_design, to_kalman
from rlsfilt.models import Polynomials


class _PolyModel:
    """One input, one output: A y = B/F u + C/D e."""

    def __init__(self, A=(1.0,), B=(0.0, 1.0), C=(1.0,), D=(1.0,), F=(1.0,), dt=True):
        self.dt = dt
        self.noise_variance_ = 0.1
        self._p = Polynomials(np.array(A, float).reshape(1, 1, -1),
                              np.array(B, float).reshape(1, 1, -1),
                              np.array(C, float).reshape(1, -1),
                              np.array(D, float).reshape(1, -1),
                              np.array(F, float).reshape(1, 1, -1))

    def polydata(self):
        return self._p


A = [1.0, -1.2, 0.5]
B = [0.0, 0.8, 0.3]
C = [1.0, 0.4, 0.2]
D = [1.0, -0.6]
F = [1.0, -0.7, 0.1]


def _one_step(kf, u, y):
    f = copy.deepcopy(kf)
    out = np.zeros(len(y))
    for t in range(len(y)):
        f.predict(u=u[t - 1] if t else 0.0)
        out[t] = (f.H @ f.x).item()
        f.update(y[t])
    return out


def _data(N=80, seed=0):
    rng = np.random.default_rng(seed)
    return rng.standard_normal(N), rng.standard_normal(N)


@pytest.mark.parametrize("kind", ["ARMAX", "OE", "BJ"])
def test_kalman_predictions_of_armax_oe_bj_equal_their_predictors(kind):
    u, y = _data()
    if kind == "ARMAX":       # C yhat = (C - A) y + B u
        model = _PolyModel(A=A, B=B, C=C)
        want = lfilter(np.subtract(C, A), C, y) + lfilter(B, C, u)
    elif kind == "OE":        # yhat = B/F u
        model = _PolyModel(B=B, F=F)
        want = lfilter(B, F, u)
    else:                     # yhat = (D/C)(B/F) u + (1 - D/C) y
        model = _PolyModel(B=B, C=C, D=D, F=F)
        want = lfilter(np.convolve(D, B), np.convolve(C, F), u) + y - lfilter(D, C, y)
    got = _one_step(to_kalman(model), u, y)
    assert_allclose(got, want, rtol=0, atol=1e-10 * np.abs(want).max())


def test_designs_read_the_plant_and_the_noise_model_from_polydata():
    oe = _PolyModel(B=B, F=F, dt=0.2)
    Am, Ao = np.poly([0.5, 0.6]), np.poly([0.2, 0.3])
    ctrl = rst_design(oe, Am=Am, Ao=Ao)              # plant B / (A F) = B / F
    ref = rst_design(np.convolve([1.0], F), B, Am, Ao)
    assert_allclose(ctrl.S, ref.S, rtol=0, atol=0)
    assert ctrl.dt == 0.2
    armax = _PolyModel(A=A, B=[0.0, 0.0, 1.0, 0.5], C=C)
    mv = minimum_variance(armax)
    ref = minimum_variance(A, [0.0, 0.0, 1.0, 0.5], C)
    assert_allclose(mv.R, ref.R, rtol=0, atol=0)
    assert_allclose(mv.F, lfilter(C, A, [1.0, 0.0]), rtol=0, atol=1e-15)
    with pytest.raises(ValueError, match=r"`A` must be a model with one input and one output"):
        two = _PolyModel()
        two._p = two._p._replace(B=np.zeros((1, 2, 2)))
        rst_design(two, Am=Am)


@pytest.mark.parametrize("kind", ["OE", "BJ", "ARMAX"])
def test_streaming_estimators_design_as_their_polynomials_over_a_common_denominator(kind):
    # their polynomials() are (A, B, C, D, F) with B and F lists per input: refused before
    # ("`B` must be a 1-D array ... got shape (1, 3)"); D and F must not be dropped
    from rlsfilt import RecursiveARMAX, RecursiveBJ, RecursiveOE
    gen = np.random.default_rng(0)
    u = gen.standard_normal(500)
    y = (lfilter([0, 1, 0.5], [1, -0.8], u)
         + lfilter([1, 0.3], [1, -0.6], 0.1 * gen.standard_normal(500)))
    est = {"OE": lambda: RecursiveOE(2, 1, 1), "BJ": lambda: RecursiveBJ(2, 1, 1, 1, 1),
           "ARMAX": lambda: RecursiveARMAX(1, 2, 1, 1)}[kind]()
    for t in range(len(y)):
        est.step(y[t], u[t])
    A, B, C, D, F = est.polynomials()
    AF = np.convolve(A, F[0])
    pairs = [(minimum_variance(est),
              minimum_variance(np.convolve(AF, D), np.convolve(B[0], D), np.convolve(C, F[0]))),
             (rst_design(est, Am=[1, -0.5]), rst_design(AF, B[0], Am=[1, -0.5]))]
    for got, want in pairs:
        for key in ("R", "S", "T"):
            assert_allclose(getattr(got, key), getattr(want, key), rtol=1e-12, atol=1e-14)
