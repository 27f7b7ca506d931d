"""Run the textbook recursions of ``tests/_reference.py`` over a record.

Each runner starts from the state of a filter (which it does not modify) and
returns what ``batch_filter`` returns, step by step, computed by the plain
NumPy reference: the histories ``means``, ``covs`` (after each update),
``means_p``, ``covs_p`` (after each predict), the residuals ``ys`` (N, m;
NaN where missing), the innovation variances ``ss`` and, for
`RecursiveLeastSquares`, the gate decisions, the forgetting factors and
whether the windup cap held each step's forgetting back (``capped``). The
kernel tests hold the compiled filters equal to these step by step.
"""

import _reference as ref
import numpy as np

from rlsfilt.filters.forgetting import TIME_UPDATE_MODES, clip_eigenvalues, efra_bounds


def _record(zs, Hs, Rs, R, m):
    Hm = np.asarray(Hs, dtype=float)
    Hm = Hm.reshape(len(Hm), Hm.shape[-1])
    Z = np.array([np.full(m, np.nan) if z is None else np.ravel(z) for z in zs], dtype=float)
    Z = Z.reshape(len(Hm), m)
    Rv = np.full(len(Z), R) if Rs is None else np.asarray(Rs, dtype=float)
    return Z, Hm, Rv


def _column(z):
    return None if np.isnan(z).any() else z.reshape(-1, 1)


class _History:
    def __init__(self):
        self.means, self.covs, self.means_p, self.covs_p = [], [], [], []
        self.ys, self.ss, self.gated, self.lam_t, self.K = [], [], [], [], []
        self.capped = []

    def finish(self):
        for name in ("means", "covs", "means_p", "covs_p", "ys", "ss", "gated", "lam_t",
                     "capped"):
            setattr(self, name, np.array(getattr(self, name)))
        return self


def rls_run(f, zs, Hs, Rs=None, update_first=False):
    """`RecursiveLeastSquares` (every mode, the gate, the constraints, ``Q``)."""
    Z, Hm, Rv = _record(zs, Hs, Rs, f.R, f.dim_z)
    mode, params, lam, gate = f._mode, f._params, f.lam, f.gate
    Pi = f._Pi if f._Pi.size else None
    Q = f.Q if f.Q.any() else None
    lam_time = lam if mode in TIME_UPDATE_MODES else 1.0   # the others forget in the update
    x, P = f.x.copy(), f.P.copy()
    if f._efra_pending:                                 # EFRA's start: clip into its interval
        lo, hi = efra_bounds(lam, *params)
        P = clip_eigenvalues(P, lo * f.R, hi * f.R)
        P = P if Pi is None else ref.project(P, Pi)
    h = _History()
    cap, held_back = f._cap, f._w != 1.0                # the windup cap's state

    def predict(P):
        P = ref.rls_predict(P, lam_time, Q, Pi, cap)
        h.means_p.append(x)
        h.covs_p.append(P)
        return P

    for k in range(len(Z)):
        if not update_first:
            P = predict(P)
            held_back = cap
        x, P, y, K, s, lam_t, gated, cap = ref.rls_update(
            x, P, Hm[k:k + 1], _column(Z[k]), Rv[k], mode, params, lam, gate, Pi, held_back)
        h.capped.append(held_back)
        held_back = False
        h.means.append(x)
        h.covs.append(P)
        h.ys.append(np.full(Z.shape[1], np.nan) if y is None else y[:, 0])
        h.ss.append(s)
        h.gated.append(gated)
        h.lam_t.append(lam_t)
        h.K = K
        if update_first:
            P = predict(P)
            held_back = cap
    return h.finish()


def square_root_run(f, zs, Hs, Rs=None, update_first=False):
    """`SquareRootRLS`: Givens rotations on the information square root."""
    Z, Hm, Rv = _record(zs, Hs, Rs, f.R, f.dim_z)
    U, x = f.U, f.x.copy()
    d = U @ x                                         # d = U x
    h = _History()

    def predict(U, d):
        U, d = ref.square_root_predict(U, d, f.lam)
        h.means_p.append(x)                           # x is unchanged by a predict
        h.covs_p.append(ref.square_root_covariance(U))
        return U, d

    for k in range(len(Z)):
        if not update_first:
            U, d = predict(U, d)
        U, d, x, y, K, s = ref.square_root_update(U, d, Hm[k:k + 1], _column(Z[k]), Rv[k])
        h.means.append(x)
        h.covs.append(ref.square_root_covariance(U))
        h.ys.append(np.full(Z.shape[1], np.nan) if y is None else y[:, 0])
        h.ss.append(s)
        h.K = K
        if update_first:
            U, d = predict(U, d)
    h.U = U
    return h.finish()


def sliding_window_run(f, zs, Hs, Rs=None, update_first=False):
    """`SlidingWindowRLS`: update, downdate and refit of the stored window."""
    Z, Hm, Rv = _record(zs, Hs, Rs, f.R, f.dim_z)
    w = ref.SlidingWindow(f.x, f.P, f.window, f.refresh, f._x0, f._P0)
    w.wH, w.wZ, w.wR = f._wH.copy(), f._wZ.copy(), f._wR.copy()
    w.head, w.nw, w.count = f._head, f._nw, f._count
    w.next_exact_try, w.exact = f._next_exact_try, f.exact
    h = _History()
    for k in range(len(Z)):
        if not update_first:
            h.means_p.append(w.x)
            h.covs_p.append(w.P)
        y, K, s = w.update(Hm[k:k + 1], _column(Z[k]), Rv[k])
        h.means.append(w.x)
        h.covs.append(w.P)
        h.ys.append(np.full(Z.shape[1], np.nan) if y is None else y[:, 0])
        h.ss.append(s)
        h.K = K
        if update_first:
            h.means_p.append(w.x)
            h.covs_p.append(w.P)
    h.window = w
    return h.finish()
