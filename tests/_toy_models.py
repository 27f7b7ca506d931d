"""A small non-ARX model written only against `IdentifiedModel`, for the interface tests.

`FirstOrderOE` is the output-error model ``y(t) = b1 / (1 + f1 q^-1) u(t-1) + e(t)``:
its one-step predictor is the simulated output, not a regression on measured
outputs, so validation code that quietly assumed ARX would fail on it. Its
regressors are the pseudo-linear ones ``[-yhat(t-1), u(t-1)]`` (``yhat`` the
simulated output), and it is fitted by the prediction-error method with
Gauss-Newton steps (Ljung 1999, sec. 10.2): the gradient of ``yhat`` is the
regressor row filtered by ``1 / F(q)``.
"""

import numpy as np
from scipy.signal import lfilter

from rlsfilt.models import IdentifiedModel, Polynomials
from rlsfilt.models.regressors import as_io_data


class FirstOrderOE(IdentifiedModel):
    """``y(t) = b1 u(t-1) / (1 + f1 q^-1) + e(t)``, one input, one output."""

    def __init__(self, n_iter=50, dt=True):
        self.n_iter = n_iter
        self.dt = dt

    # --- what IdentifiedModel asks for ---------------------------------
    def fit(self, u, y):
        U, Y, info = as_io_data(u, y)
        if U.shape[1] != 1 or Y.shape[1] != 1:
            raise ValueError(f"`u` and `y` must be single signals; got {U.shape[1]} input(s) "
                             f"and {Y.shape[1]} output(s)")
        if len(U) < 4:
            raise ValueError(f"`y` must have at least 4 samples; got {len(U)}")
        self._check_dt()
        u1, y1 = U[:, 0], Y[:, 0]
        # start: the ARX(1, 1) estimate, then Gauss-Newton on sum (y - yhat(theta))^2
        Phi = np.column_stack([-y1[:-1], u1[:-1]])
        theta = np.linalg.lstsq(Phi, y1[1:], rcond=None)[0]
        for _ in range(self.n_iter):
            psi = _gradient(theta, u1)
            e = y1[1:] - _rows(theta, u1) @ theta
            step = np.linalg.lstsq(psi, e, rcond=None)[0]
            theta = theta + step
            if np.max(np.abs(step)) <= 1e-13 * max(1.0, np.max(np.abs(theta))):
                break
        Phi = _rows(theta, u1)
        resid = y1[1:] - Phi @ theta
        dof = len(resid) - 2
        sigma2 = float(resid @ resid) / dof
        self._info = dict(info)
        self.theta_ = theta
        psi = _gradient(theta, u1)
        self.theta_cov_ = sigma2 * np.linalg.inv(psi.T @ psi)     # Ljung (1999), eq. 9.18
        self.noise_variance_ = sigma2
        self.residuals_ = resid
        self.n_samples_ = len(resid)
        self.n_params_ = 2
        self.n_inputs_ = self.n_outputs_ = 1
        return self

    def regressors(self, u, y):
        self._check_fitted("regressors")
        U, Y = self._data(u, y)
        return _rows(self.theta_, U[:, 0]), Y[1:, 0].copy()

    def predict(self, u, y, horizon=1):
        self._check_fitted("predict")
        self._data(u, y)
        return self.simulate(u)     # the OE predictor ignores the measured outputs

    def simulate(self, u, y0=None):
        self._check_fitted("simulate")
        U, _ = self._data(u)
        f, b = self.theta_
        y = lfilter([0.0, b], [1.0, f], U[:, 0])
        if y0 is not None:
            y0 = np.atleast_1d(np.asarray(y0, dtype=float)).ravel()
            y[:len(y0)] = y0
            for t in range(max(len(y0), 1), len(y)):
                y[t] = -f * y[t - 1] + b * U[t - 1, 0]
        return y

    def polydata(self, theta=None):
        self._check_fitted("polydata")
        f, b = self.theta_ if theta is None else np.asarray(theta, dtype=float).ravel()
        return Polynomials(A=np.ones((1, 1, 1)), B=np.array([[[0.0, b]]]), C=np.ones((1, 1)),
                           D=np.ones((1, 1)), F=np.array([[[1.0, f]]]))

    @property
    def param_names_(self):
        self._check_fitted("param_names_")
        return ["f1", "b1"]

    @property
    def orders_(self):
        self._check_fitted("orders_")
        return {"nb": 1, "nf": 1, "nk": 1}

    @property
    def max_lag(self):
        self._check_fitted("max_lag")
        return 1


def _rows(theta, u):
    """Pseudo-linear regressors ``[-yhat(t-1), u(t-1)]`` for t = 1 .. N-1, ``yhat`` from `theta`."""
    f, b = theta
    yhat = lfilter([0.0, b], [1.0, f], u)
    return np.column_stack([-yhat[:-1], u[:-1]])


def _gradient(theta, u):
    """``d yhat / d theta`` on rows t = 1 .. N-1: the regressors filtered by ``1 / F(q)``."""
    f = theta[0]
    return lfilter([1.0], [1.0, f], _rows(theta, u), axis=0)
