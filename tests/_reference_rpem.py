r"""Readable NumPy reference of the RPEM/RPLR recursion of
:mod:`rlsfilt.models._recursive_kernels` (for the tests).

Every signal is a full-length array, every filter its difference equation, and
the covariance update is the filters' own textbook recursion
(``_reference.UPDATES``), called with the prediction error as the residual.
"""

import _reference as _rls_reference
import numpy as np
from _reference_riv import _filt, _lag

from rlsfilt.filters import forgetting as _fg
from rlsfilt.models._family import split_theta
from rlsfilt.models._stability import stabilize_theta

__all__ = ["rpem_reference"]

def rpem_reference(theta, P, y, U, s, method="rpem", mode=0, params=(), lam=1.0, Q=None,
                   R=1.0, gate=None, project=True, lam_now=None, lam_rate=0.99):
    """RPEM (``method="rpem"``) or RPLR over a record from rest; returns histories.

    The forgetting factor starts at `lam_now` (default `lam`) and follows
    ``lam(t+1) = lam - (lam - lam(t)) lam_rate``.

    ``theta`` (n,) and ``P`` (n, n) are the start (not modified). Returns
    ``(theta, P, theta_history (N, n), yhat (N,), eps (N,))``.
    """
    theta = np.array(theta, dtype=float)
    P = np.array(P, dtype=float)
    N, n, nu = len(y), s.n_params, s.n_inputs
    sig = {name: np.zeros(N) for name in ("yf", "e", "ef", "v", "vf")}
    per = [{name: np.zeros(N) for name in ("p", "uf", "w", "s", "wf")} for _ in range(nu)]
    hist, yhat, eps_out = np.zeros((N, n)), np.zeros(N), np.zeros(N)
    lam_t = lam if lam_now is None else lam_now
    for t in range(N):
        A, B, C, D, F = split_theta(theta, s)              # theta(t-1)
        if method == "rpem":                               # measured signals through D/C, D/(C F)
            sig["yf"][t] = _filt(D, C, y, sig["yf"], t)
            for i in range(nu):
                per[i]["p"][t] = _filt([1.0], F[i], U[:, i], per[i]["p"], t)
                per[i]["uf"][t] = _filt(D, C, per[i]["p"], per[i]["uf"], t)
        phi, psi = [], []
        phi += [-_lag(y, t, k) for k in range(1, s.na + 1)]
        psi += [-_lag(sig["yf"], t, k) for k in range(1, s.na + 1)]
        for i in range(nu):
            lags = range(s.nk[i], s.nk[i] + s.nb[i])
            phi += [_lag(U[:, i], t, k) for k in lags]
            psi += [_lag(per[i]["uf"], t, k) for k in lags]
        phi += [_lag(sig["e"], t, k) for k in range(1, s.nc + 1)]
        psi += [_lag(sig["ef"], t, k) for k in range(1, s.nc + 1)]
        phi += [-_lag(sig["v"], t, k) for k in range(1, s.nd + 1)]
        psi += [-_lag(sig["vf"], t, k) for k in range(1, s.nd + 1)]
        for i in range(nu):
            phi += [-_lag(per[i]["w"], t, k) for k in range(1, s.nf[i] + 1)]
            psi += [-_lag(per[i]["wf"], t, k) for k in range(1, s.nf[i] + 1)]
        phi = np.array(phi)
        psi = phi.copy() if method == "rplr" else np.array(psi)
        yhat[t] = phi @ theta                              # yhat = phi^T theta(t-1)
        eps = y[t] - yhat[t]
        eps_out[t] = eps
        # time update, then the measurement update of the filters (RLS with regressor psi)
        P = P / lam_t if mode == _fg.EXPONENTIAL else P
        if Q is not None:
            P = P + Q
        g = P @ psi[:, None]                               # g = P psi
        s_var = float(psi @ g[:, 0]) + R                   # s = psi^T P psi + R
        if gate is None or eps * eps <= gate * gate * s_var:
            x, P, _, _ = _rls_reference.UPDATES[mode](theta[:, None], P, np.array([[eps]]), g,
                                                      s_var, R, lam_t, tuple(params))
            theta = x[:, 0]
        lam_t = lam - (lam - lam_t) * lam_rate
        if project:
            theta, _ = stabilize_theta(theta, s)
        hist[t] = theta
        A, B, C, D, F = split_theta(theta, s)              # theta(t)
        wsum = 0.0
        for i in range(nu):
            per[i]["w"][t] = _filt(B[i], F[i], U[:, i], per[i]["w"], t)   # w = B/F u
            wsum += per[i]["w"][t]
        sig["v"][t] = _filt(A, [1.0], y, sig["v"], t) - wsum              # v = A y - sum w
        sig["e"][t] = _filt(D, C, sig["v"], sig["e"], t)                  # e = D/C v
        if method == "rpem":
            sig["ef"][t] = _filt([1.0], C, sig["e"], sig["ef"], t)        # 1/C e
            sig["vf"][t] = _filt([1.0], C, sig["v"], sig["vf"], t)        # 1/C v
            for i in range(nu):
                per[i]["s"][t] = _filt([1.0], F[i], per[i]["w"], per[i]["s"], t)
                per[i]["wf"][t] = _filt(D, C, per[i]["s"], per[i]["wf"], t)
    return theta, P, hist, yhat, eps_out
