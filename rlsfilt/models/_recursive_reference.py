r"""Readable NumPy reference of the recursions of :mod:`._recursive_kernels` (for the tests).

Written for the reader, not for speed: every signal is a full-length array,
every filter is its difference equation, and the covariance update is the
filters' own textbook recursion, :data:`rlsfilt.filters._reference.UPDATES`,
called with the prediction error as the residual. The compiled kernels must agree
with these functions to round-off; production code never calls them, except
``compiled=False`` paths that exist for the tests.
"""

import numpy as np

from ..filters import _reference as _rls_reference
from ..filters import forgetting as _fg
from ._family import split_theta
from ._stability import reflect, stabilize_theta

__all__ = []


def _lag(x, t, k):
    """``x(t - k)``, zero before the record."""
    return x[t - k] if t - k >= 0 else 0.0


def _filt(num, den, x, out, t):
    r"""Value at ``t`` of ``out = num/den x`` (monic ``den``), from the stored past of `out`."""
    acc = sum(num[k] * _lag(x, t, k) for k in range(len(num)))
    acc -= sum(den[k] * _lag(out, t, k) for k in range(1, len(den)))
    return acc


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


def _riv_step(theta, P, phi, z, y, lam, Q, R, tol):
    """One RIV step: ``P <- P/lam + Q``; ``K = P z / (R + phi^T P z)``; ``P <- P - K phi^T P``.

    Skipped (``theta``, ``P`` after the time update kept) when the
    denominator fails the conditioning check. Returns ``(theta, P, eps, skipped)``.
    """
    P = P / lam
    if Q is not None:
        P = P + Q
    g = P @ z                                   # P z
    h = phi @ P                                 # phi^T P
    d = R + phi @ g
    eps = y - phi @ theta
    if not abs(d) > tol * (R + np.linalg.norm(phi) * np.linalg.norm(g)):
        return theta, P, eps, True
    K = g / d
    theta = theta + np.outer(K, eps)
    P = P - np.outer(K, h)
    return theta, P, eps, False


def riv_rows_reference(theta, P, Phi, Z, Y, lam, Q, R, tol, hist, eps_hist):
    """`_recursive_kernels.riv_rows` in NumPy (in place on ``theta``, ``P`` and the histories)."""
    bad = -1
    th, Pm = theta.copy(), P.copy()
    for t in range(len(Phi)):
        th, Pm, eps, skipped = _riv_step(th, Pm, Phi[t], Z[t], Y[t], lam, Q, R, tol)
        if bad < 0 and skipped:
            bad = t
        hist[t] = th
        eps_hist[t] = eps
    theta[:] = th
    P[:] = Pm
    return bad


def riv_model_reference(theta, P, U, y, s, k0, alpha, beta, refresh, prefilter, lam, Q, R,
                        tol, hist, eps_hist, Phi_out, Z_out, Y_out):
    """`_recursive_kernels.riv_model` in NumPy (same arguments, in place)."""
    N, nu = U.shape
    na = s.na
    yf, uf, x, xf = np.zeros(N), np.zeros((N, nu)), np.zeros(N), np.zeros(N)
    th, Pm = theta.copy(), P.copy()
    bad, t0 = -1, s.max_lag
    for t in range(N):
        a = np.concatenate([[1.0], alpha])
        ident = np.ones(1)
        L = a if prefilter else ident                       # prefilter 1/A_aux
        yf[t] = _filt([1.0], L, y, yf, t)
        for i in range(nu):
            uf[t, i] = _filt([1.0], L, U[:, i], uf[:, i], t)
        xb, start = 0.0, 0
        for i in range(nu):
            b = np.concatenate([np.zeros(s.nk[i]), beta[start:start + s.nb[i]]])
            start += s.nb[i]
            xb += sum(b[k] * _lag(U[:, i], t, k) for k in range(len(b)))
        x[t] = xb - sum(a[k] * _lag(x, t, k) for k in range(1, na + 1))   # A_aux x = B_aux u
        xf[t] = _filt([1.0], L, x, xf, t)
        if t < t0:
            continue
        row = t - t0
        phi = np.array([-yf[t - k] for k in range(1, na + 1)]
                       + [uf[t - s.nk[i] - k, i] for i in range(nu) for k in range(s.nb[i])])
        z = np.array([-xf[t - k] for k in range(1, na + 1)]
                     + [uf[t - s.nk[i] - k, i] for i in range(nu) for k in range(s.nb[i])])
        Phi_out[row], Z_out[row], Y_out[row] = phi, z, yf[t]
        if row < k0:
            hist[row] = np.nan
            eps_hist[row] = np.nan
            if row == k0 - 1:
                M = Z_out[:k0].T @ Phi_out[:k0]
                if not np.linalg.cond(M) < 1e15:
                    return bad, True
                Pm = np.linalg.inv(M)
                th = (Pm @ (Z_out[:k0].T @ yf[t0:t0 + k0]))[:, None]
                hist[row] = th
        else:
            th, Pm, eps, skipped = _riv_step(th, Pm, phi, z, np.array([yf[t]]), lam, Q, R, tol)
            if bad < 0 and skipped:
                bad = row
            hist[row] = th
            eps_hist[row] = eps
        if refresh > 0 and (row + 1) % refresh == 0 and row + 1 >= k0:
            alpha[:] = reflect(np.concatenate([[1.0], th[:na, 0]]))[1:]
            beta[:] = th[na:, 0]
    theta[:] = th
    P[:] = Pm
    return bad, False
