r"""Readable NumPy reference of the recursive-IV recursions of
:mod:`rlsfilt.models._recursive_kernels` (``riv_model``, ``riv_rows``), for the tests.

Written for the reader, not for speed: every signal is a full-length array,
every filter is its difference equation. The RPEM/RPLR reference, which calls
the filters' textbook recursion, is ``_reference_rpem.py`` (it shares `_filt`
and `_lag`). `riv_model` and `riv_rows` take the compiled kernels' arguments, so
``recursive_iv(..., kernels=_reference_riv)`` runs the fit on this reference;
the compiled kernels must agree with it to round-off (``tests/test_iv.py``).
Not installed with the package (#26: test-only code out of the package).
"""

from types import SimpleNamespace

import numpy as np

from rlsfilt.models._stability import reflect

__all__ = []


def _lag(x, t, k):
    """``x(t - k)``, zero before the record."""
    return x[t - k] if t - k >= 0 else 0.0


def _filt(num, den, x, out, t):
    r"""Value at ``t`` of ``out = num/den x`` (monic ``den``), from the stored past of `out`."""
    acc = sum(num[k] * _lag(x, t, k) for k in range(len(num)))
    acc -= sum(den[k] * _lag(out, t, k) for k in range(1, len(den)))
    return acc



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


# ----------------------------------------------------------------------
# the compiled kernels' signatures (`recursive_iv_records(..., kernels=...)`)
# ----------------------------------------------------------------------
def _lam_and_Q(il, Qa):
    return 1.0 / il, (Qa if Qa.size else None)


def riv_model(theta, P, buf, U, y, max_lag, na, nb, nk, k0, alpha, beta, refresh, prefilter,
              il, Qa, R, tol, hist, eps_hist, Phi_out, Z_out, Y_out):
    """`riv_model_reference` with the arguments of ``_recursive_kernels.riv_model``."""
    s = SimpleNamespace(na=na, nb=tuple(int(b) for b in nb), nk=tuple(int(k) for k in nk),
                        max_lag=max_lag)
    lam, Q = _lam_and_Q(il, Qa)
    return riv_model_reference(theta, P, U, y, s, k0, alpha, beta, refresh, prefilter, lam, Q,
                               R, tol, hist, eps_hist, Phi_out, Z_out, Y_out)


def riv_rows(theta, P, Phi, Z, Y, il, Qa, R, tol, hist, eps_hist):
    """`riv_rows_reference` with the arguments of ``_recursive_kernels.riv_rows``."""
    lam, Q = _lam_and_Q(il, Qa)
    return riv_rows_reference(theta, P, Phi, Z, Y, lam, Q, R, tol, hist, eps_hist)
