r"""The textbook recursions of the three filters, in plain NumPy.

This module is the readable statement of every algorithm rlsfilt runs, one
short function per step and per forgetting mode, written as the equations
read. It is **not** used by the filters: their public methods run the
compiled kernels (:mod:`rlsfilt.filters._kernels` and
:mod:`rlsfilt.filters._kernels_window`). The tests import it and hold the
kernels equal to it step by step, to 1e-12, for every mode and option
(``tests/test_kernels.py``, ``tests/test_kernels_window.py``). It is the
same algorithm, not merely the same answer: the square-root filter here
folds each row in with the same Givens rotations as its kernel.

Shapes: ``x`` (n, m) estimate (one column per output), ``P`` (n, n),
``phi`` (1, n) regressor row, ``z`` (m, 1) measurement, ``r`` the noise
variance; ``g = P phi^T`` and ``s = phi P phi^T + r``.
"""

import math

import numpy as np
from scipy.linalg import solve_triangular
from scipy.linalg.lapack import dtrtri

from rlsfilt.filters.forgetting import (
    CONSTANT_TRACE,
    DIAGONAL,
    DIRECTIONAL,
    EFRA,
    EXPONENTIAL,
    VARIABLE,
)

__all__ = []


# ----------------------------------------------------------------------
# RecursiveLeastSquares
# ----------------------------------------------------------------------
def rls_predict(P, lam, Q=None, Pi=None, cap=False):
    """Time update ``P^- = P / lam + Q`` (then ``Pi P^- Pi`` with constraints).

    `lam` an array (the diagonal mode): ``P^- = L^-1/2 P L^-1/2 + Q`` with
    ``L = diag(lam)`` (`diagonal_predict`). With `cap` (the windup cap of the
    last update, `windup_cap`) the forgetting is held back: the next
    `rls_update` forgets along its regressor.
    """
    if not cap:
        P = diagonal_predict(P, lam) if np.ndim(lam) else P / lam
    if Q is not None:
        P = P + Q
    return P if Pi is None else project(P, Pi)


def rls_update(x, P, phi, z, r, mode=EXPONENTIAL, params=(), lam=1.0, gate=None, Pi=None,
               held_back=False):
    """One measurement update of any mode, with the gate and the constraints.

    `z` is a column or None (missing). `held_back` says that the last
    `rls_predict` held the forgetting back (the windup cap, exponential
    mode): the update then first forgets along its regressor
    (`forget_along`). Returns ``x, P, y, K, s, lam_t, gated, cap``; a
    missing or gated sample leaves ``x`` and ``P`` (but for that
    forgetting), ``K`` is zero and ``lam_t`` is `lam` in the exponential
    mode (its predict forgot) and 1 otherwise; ``cap`` is `windup_cap` of
    the new ``P``: whether the next `rls_predict` holds the forgetting back.
    """
    if held_back:
        P = forget_along(P, phi, lam)
    g = P @ phi.T                                   # g = P H^T
    s = (phi @ g).item() + r                        # S = H P H^T + R
    lam_skip = np.min(lam) if mode in (EXPONENTIAL, DIAGONAL) else 1.0
    gated = False
    if z is None:
        y = None
    else:
        y = z - (phi @ x).T                         # y = z - H x
        gated = gate is not None and float(np.vdot(y, y)) > gate * gate * s  # sqrt(y'y/S) > gate
    if z is None or gated:
        x, K, lam_t, hph = x, np.zeros_like(g), lam_skip, s - r
    else:
        x, P, K, lam_t = UPDATES[mode](x, P, y, g, s, r, lam, params)
        if Pi is not None:                          # keep A P = 0
            P = project(P, Pi)
        hph = (s - r) * r / s                       # phi P phi^T after the update
    cap = (mode in (EXPONENTIAL, DIAGONAL)
           and windup_cap(P, phi, hph, lam, params, Pi is not None))
    return x, P, y, K, s, lam_t, gated, cap


def diagonal_predict(P, lam):
    r"""The time update of diagonal (per-parameter) forgetting, without ``Q``:

    .. math:: P^- = L^{-1/2} P L^{-1/2},\qquad L = \operatorname{diag}(\lambda_1,
              \dots, \lambda_n),

    i.e. :math:`P^-_{ij} = P_{ij} / \sqrt{\lambda_i \lambda_j}`: parameter ``i``
    forgets with its own factor (a memory of about :math:`1/(1 - \lambda_i)`
    samples); equal factors are exponential forgetting, ``P / lam``.
    """
    w = 1.0 / np.sqrt(lam)
    return P * np.outer(w, w)       # (elementwise: exactly symmetric, as P; L^-1/2 P L^-1/2
    #                                 as two products is not, and its asymmetry grows)


def forget_along(P, phi, lam):
    r"""The forgetting of one step along the regressor only (directional forgetting).

    .. math:: g = P \phi^T,\quad q = \phi g,\qquad
              P \leftarrow P + (w - 1)\, g g^T / q

    with :math:`w = 1/\lambda` (exponential), so that :math:`\phi P \phi^T` grows by
    :math:`1/\lambda` as under exponential forgetting, while every direction the
    regressor does not excite keeps its ``P`` (a zero regressor changes nothing).
    With a vector `lam` (diagonal forgetting) :math:`w = \phi L^{-1/2} P L^{-1/2}
    \phi^T / q`, the growth the diagonal time update would give
    :math:`\phi P \phi^T` (``1 / lam`` again when the factors are equal).
    """
    g = P @ phi.T
    q = (phi @ g).item()
    if not q > 0.0:
        return P
    w = (phi @ diagonal_predict(P, lam) @ phi.T).item() / q if np.ndim(lam) else 1.0 / lam
    return P + ((w - 1.0) / q) * (g * g.T)


def windup_cap(P, phi, hph, lam, params, constrained=False):
    r"""Whether the next time update holds the forgetting back (exponential mode).

    With ``params = (spread_max, trace_max)``: when dividing ``P`` by `lam`
    would make :math:`\operatorname{tr} P / \lambda` exceed ``trace_max``, or
    when ``P`` is far larger off the regressor's direction than along it,

    .. math:: \sum_i P_{ii} \phi_i^2 > \text{spread\_max}\; \phi P \phi^T

    (`hph` is :math:`\phi P \phi^T`, from the update's identity
    :math:`\phi P^+ \phi^T = q r / (q + r)`). The left side is invariant to the
    units of each regressor; the ratio is at most ``dim_x`` times the
    condition number of the correlation matrix of ``P``. Never with ``lam =
    1``; the spread test is off under constraints (``P`` is singular there).
    With a vector `lam` (diagonal forgetting) the trace after its time update,
    :math:`\sum_i P_{ii} / \lambda_i`, and never when every factor is 1.
    """
    if np.all(lam == 1.0):
        return False
    spread_max, trace_max = params
    d = np.diagonal(P)
    if np.sum(d / lam) > trace_max:
        return True
    return (not constrained and spread_max < np.inf
            and float(d @ (phi[0] * phi[0])) > spread_max * hph)


def update_exponential(x, P, y, g, s, r, lam, params):
    r"""Standard update; the forgetting ``P / lam`` happened in the predict.

    .. math:: K = g / s,\quad x \leftarrow x + K y^T,\quad P \leftarrow P - g g^T / s
    """
    K = g / s                                       # K = P H^T / S
    return x + K * y.T, P - (g * g.T) / s, K, lam   # x + K y^T,  P - K S K^T


def update_directional(x, P, y, g, s, r, lam, params):
    r"""Directional forgetting (Kulhavy & Karny 1984; Bittanti et al. 1990).

    With :math:`\rho = \phi P \phi^T / r`, :math:`\varepsilon = \lambda -
    (1 - \lambda)/\rho` when :math:`\rho >` ``eps`` (else 1), the
    information update :math:`P^{-1} \leftarrow P^{-1} + \varepsilon
    \phi^T\phi / r` reads

    .. math:: K = \frac{g}{r (1 + \varepsilon\rho)},\quad
              P \leftarrow P - \frac{\varepsilon\, g g^T}{r (1 + \varepsilon\rho)}

    Only the excited direction is forgotten, so ``P`` cannot wind up.
    """
    (eps,) = params
    rho = (s - r) / r                               # phi P phi^T / r
    e = lam - (1.0 - lam) / rho if rho > eps else 1.0
    d = r * (1.0 + e * rho)
    K = g / d
    return x + K * y.T, P - (e / d) * (g * g.T), K, e


def update_constant_trace(x, P, y, g, s, r, lam, params):
    r"""Constant trace (Goodwin & Sin 1984; Astrom & Wittenmark 1995).

    .. math:: \bar P = P - g g^T / s,\qquad
              P \leftarrow c_1 \bar P / \operatorname{tr}\bar P + c_2 I

    with :math:`c_1 + n c_2 =` ``trace`` and :math:`c_1 / c_2 =` ``ratio``;
    ``lam_t = tr(P_bar) / c_1``.
    """
    trace, ratio = params
    n = P.shape[0]
    c2 = trace / (ratio + n)
    c1 = trace - n * c2
    x, Pb, K, _ = update_exponential(x, P, y, g, s, r, lam, ())
    tb = np.trace(Pb)
    return x, (c1 / tb) * Pb + c2 * np.eye(n), K, tb / c1


def update_efra(x, P, y, g, s, r, lam, params):
    r"""Exponential forgetting and resetting (Salgado, Goodwin & Middleton 1988).

    .. math:: K = \alpha g / s,\quad
              P \leftarrow P / \lambda - \alpha g g^T / s + \beta r I - (\delta / r) P^2

    (the paper's recursion for ``P / r``).
    """
    alpha, beta, delta = params
    K = (alpha / s) * g
    Pn = P / lam - (alpha / s) * (g * g.T) - (delta / r) * (P @ P)
    return x + K * y.T, 0.5 * (Pn + Pn.T) + beta * r * np.eye(P.shape[0]), K, lam


def update_variable(x, P, y, g, s, r, lam, params):
    r"""Variable forgetting factor (Fortescue, Kershenbaum & Ydstie 1981).

    .. math:: \lambda_t = 1 - (1 - \lambda)\, \frac{y^T y}{m\, s},\qquad
              \bar P = P - g g^T / s,\qquad P \leftarrow \bar P / \lambda_t

    with :math:`\lambda_t` clipped to ``[lam_min, 1]`` and raised so that
    ``trace(P) <= trace_max``.
    """
    lam_min, trace_max = params
    x, Pb, K, _ = update_exponential(x, P, y, g, s, r, lam, ())
    lt = 1.0 - (1.0 - lam) * float(np.vdot(y, y)) / (y.shape[0] * s)
    lt = min(1.0, max(lam_min, lt))
    lt = max(lt, min(1.0, np.trace(Pb) / trace_max))
    return x, Pb / lt, K, lt


def update_diagonal(x, P, y, g, s, r, lam, params):
    r"""Diagonal forgetting: the standard update (`update_exponential`); the forgetting
    ``P^- = L^{-1/2} P L^{-1/2}`` happened in the predict (`diagonal_predict`).
    ``lam_t`` is the smallest factor."""
    x, P, K, _ = update_exponential(x, P, y, g, s, r, lam, params)
    return x, P, K, np.min(lam)


#: The measurement update of each mode, indexed by its code.
UPDATES = {EXPONENTIAL: update_exponential, DIRECTIONAL: update_directional,
           CONSTANT_TRACE: update_constant_trace, EFRA: update_efra, VARIABLE: update_variable,
           DIAGONAL: update_diagonal}


def project(P, Pi):
    """``Pi P Pi``, made exactly symmetric (``P`` on the null space of the constraints)."""
    P = Pi @ P @ Pi
    return 0.5 * (P + P.T)


# ----------------------------------------------------------------------
# SquareRootRLS: the information square root U (U^T U = P^-1), d = U x
# ----------------------------------------------------------------------
def square_root_predict(U, d, lam):
    r"""Time update :math:`U \leftarrow \sqrt\lambda U,\ d \leftarrow \sqrt\lambda d`."""
    c = math.sqrt(lam)
    return c * U, c * d


def square_root_update(U, d, phi, z, r):
    r"""Fold the row ``[phi, z^T] / sqrt(r)`` into ``[U, d]`` by Givens rotations.

    .. math::

        \begin{bmatrix} U & d \\ \phi/\sqrt r & z^T/\sqrt r \end{bmatrix}
        \to \begin{bmatrix} U' & d' \\ 0 & e \end{bmatrix},\qquad x = U'^{-1} d'

    One rotation per row ``i`` of ``U`` zeroes entry ``i`` of the new row and
    keeps ``U_ii`` positive. Returns ``U, d, x, y, K, s`` with the residual
    ``y = z - phi x``, ``s = |U^-T phi^T|^2 + r`` and the gain
    ``K = U^-1 U^-T phi^T / s`` of the old factor; a missing `z` (None)
    changes nothing (``y`` None, ``K`` zero).
    """
    n = U.shape[0]
    w = solve_triangular(U, phi[0], trans="T")        # w = U^-T H^T
    s = float(w @ w) + r                              # S = H P H^T + R
    x = solve_triangular(U, d)
    if z is None:
        return U, d, x, None, np.zeros((n, 1)), s
    K = solve_triangular(U, w).reshape(n, 1) / s      # K = P H^T / S
    y = z - (phi @ x).T                               # y = z - H x
    U, d = U.copy(), d.copy()
    a = phi[0] / math.sqrt(r)                         # the new row [a | b]
    b = z[:, 0] / math.sqrt(r)
    for i in range(n):
        if a[i] == 0.0:
            continue
        rho = math.hypot(U[i, i], a[i])
        c, sn = U[i, i] / rho, a[i] / rho             # rotation zeroing a[i]
        Ui, ai = U[i, i + 1:].copy(), a[i + 1:].copy()
        U[i, i] = rho
        U[i, i + 1:] = c * Ui + sn * ai
        a[i + 1:] = c * ai - sn * Ui
        di = d[i].copy()
        d[i] = c * di + sn * b
        b = c * b - sn * di
    return U, d, solve_triangular(U, d), y, K, s


def square_root_covariance(U):
    """``P = U^-1 U^-T`` (LAPACK ``trtri`` for ``U^-1``)."""
    Ui = dtrtri(U, lower=0)[0]
    P = Ui @ Ui.T
    return 0.5 * (P + P.T)


# ----------------------------------------------------------------------
# SlidingWindowRLS
# ----------------------------------------------------------------------
class SlidingWindow:
    """The state of `SlidingWindowRLS` and its textbook step.

    ``x``, ``P``; the ring buffer ``wH`` (window, n), ``wZ`` (window, m; NaN
    marks a missing sample), ``wR`` (window,); ``head`` (the oldest slot once
    full), ``nw`` (samples held), ``count`` (updates), ``exact`` (the prior
    has been dropped) and ``next_exact_try``; the prior ``x0``, ``P0``.
    """

    def __init__(self, x, P, window, refresh, x0, P0):
        n, m = x.shape
        self.x, self.P = x.copy(), P.copy()
        self.window, self.refresh = window, refresh
        self.x0, self.P0 = x0.copy(), P0.copy()
        self.wH, self.wZ = np.zeros((window, n)), np.full((window, m), np.nan)
        self.wR = np.ones(window)
        self.head = self.nw = self.count = self.next_exact_try = 0
        self.exact = False

    def update(self, phi, z, r):
        """Add ``(phi, z, r)``, drop the oldest sample; returns ``y, K, s``."""
        x, P = self.x, self.P
        g = P @ phi.T                                 # g = P H^T
        s = (phi @ g).item() + r                      # S = H P H^T + R
        y, K = None, np.zeros_like(g)
        if z is not None:
            c = 1.0 / s
            y = z - (phi @ x).T                       # y = z - H x
            K = g * c                                 # K = P H^T / S
            x = x + K * y.T                           # x = x + K y^T
            P = P - (g * g.T) * c                     # P = P - g g^T / S
        h = self.head                                 # the slot of the oldest sample
        refit = False
        if self.nw == self.window and not np.isnan(self.wZ[h]).any():
            ok, x, P = downdate(x, P, self.wH[h:h + 1], self.wZ[h].reshape(-1, 1), self.wR[h])
            refit = not ok
        self.wH[h], self.wR[h] = phi[0], r
        self.wZ[h] = np.nan if z is None else z[:, 0]
        self.head = (h + 1) % self.window
        self.nw = min(self.nw + 1, self.window)
        self.count += 1
        if self.nw == self.window and not self.exact:
            refit = refit or self.count >= self.next_exact_try
        if self.refresh and self.count % self.refresh == 0:
            refit = True
        if refit:                                     # exact least squares on the window, or
            sol = window_lstsq(self.wH[:self.nw], self.wZ[:self.nw], self.wR[:self.nw])
            self.exact = sol is not None
            if sol is None:                           # with the prior, tried again later
                self.next_exact_try = self.count + self.window
                sol = window_lstsq(self.wH[:self.nw], self.wZ[:self.nw], self.wR[:self.nw],
                                   self.x0, self.P0)
            x, P = sol
        self.x, self.P = x, P
        return y, K, s


def downdate(x, P, phi, z, r):
    r"""Remove the sample ``(phi, z, r)``: the inverse of an update.

    .. math:: g = P \phi^T,\quad d = r - \phi g,\quad
              x \leftarrow x - g (z - \phi x)^T / d,\quad P \leftarrow P + g g^T / d

    Returns ``ok, x, P``; not ok (nothing done) when ``d`` is not clearly
    positive, i.e. the remaining samples may not determine every parameter.
    """
    g = P @ phi.T
    d = r - (phi @ g).item()
    if not d > 1e-8 * r:
        return False, x, P
    e = z - (phi @ x).T                               # residual of the leaving sample
    c = 1.0 / d
    return True, x - (g * c) * e.T, P + (g * g.T) * c


def window_lstsq(Hw, Zw, Rw, x0=None, P0=None):
    """Weighted least squares on the window rows by QR; ridge towards `x0` with `P0`.

    Returns ``(x, P)``, or None when the rows do not determine every
    parameter (without a prior).
    """
    n = Hw.shape[1]
    keep = ~np.isnan(Zw).any(axis=1)
    w = 1.0 / np.sqrt(Rw[keep])
    A, B = Hw[keep] * w[:, None], Zw[keep] * w[:, None]
    if P0 is not None:                                # prior rows: L^T (x - x0), L L^T = P0^-1
        Lt = np.linalg.cholesky(np.linalg.inv(P0)).T
        A, B = np.concatenate([Lt, A]), np.concatenate([Lt @ x0, B])
    if len(A) < n or (P0 is None and np.linalg.matrix_rank(A) < n):
        return None
    Qf, Rf = np.linalg.qr(A)
    x = solve_triangular(Rf, Qf.T @ B)
    return x, square_root_covariance(Rf)


# ----------------------------------------------------------------------
# diagonal (per-parameter) forgetting, for the likelihood of `tune`
# ----------------------------------------------------------------------
def diagonal_forgetting_profile_loglik(z, H, lam, Q, P0, x0):
    r"""Profile log-likelihood (``R`` concentrated out) of the recursion with a diagonal
    forgetting ``P^- = L^{-1/2} P L^{-1/2} + Q``, ``L = diag(lam)``, ``R = 1``; `lam` a
    vector (a scalar: exponential forgetting). Missing samples (NaN) are skipped."""
    n = H.shape[1]
    Li = np.diag(1.0 / np.sqrt(np.broadcast_to(lam, (n,))))
    x, P = np.array(x0, dtype=float).reshape(n), np.array(P0, dtype=float)
    ys, ss = [], []
    for zt, h in zip(z, H, strict=True):
        P = Li @ P @ Li + Q                       # time update
        s = h @ P @ h + 1.0                       # innovation variance
        y = zt - h @ x                            # innovation
        if np.isnan(y):
            continue
        K = P @ h / s
        x = x + K * y
        P = P - np.outer(K, h @ P)
        P = 0.5 * (P + P.T)
        ys.append(y)
        ss.append(s)
    y, s = np.array(ys), np.array(ss)
    N = len(y)
    sigma2 = np.mean(y * y / s)
    return -0.5 * (N * (math.log(2 * math.pi) + math.log(sigma2) + 1) + np.log(s).sum())


# ----------------------------------------------------------------------
# the gradient family (LMS, NLMS, the sign variants, affine projection)
# ----------------------------------------------------------------------
def lms_step(x, h, z, mu, method, eps=0.0, leak=0.0):
    r"""One step of the LMS family (Haykin 2002, ch. 5, 6, 13): ``y = z - x^T h``,
    ``K = mu f(h) / n``, ``x <- (1 - mu a) x + K g(y)^T``, with ``f``, ``g`` the
    identity or the sign (``"sign_data"``, ``"sign_error"``, ``"sign_sign"``) and
    ``n = eps + h^T h`` for ``"nlms"`` (1 otherwise). `h` (n,), `z` (m,); returns
    ``(x, y, K)`` with ``y`` (m, 1) and ``K`` (n, 1)."""
    y = z - h @ x                                            # a-priori residual
    f = np.sign(h) if method in ("sign_data", "sign_sign") else h
    g = np.sign(y) if method in ("sign_error", "sign_sign") else y
    norm = eps + h @ h if method == "nlms" else 1.0
    K = mu * f / norm
    return (1.0 - mu * leak) * x + np.outer(K, g), y.reshape(-1, 1), K.reshape(-1, 1)


def apa_step(x, X, D, h, z, mu, eps):
    r"""One affine-projection step (Ozeki & Umeda 1984; Haykin 2002, ch. 6): the
    newest row and measurement enter the buffers ``X`` (order, n) and ``D``
    (order, m) first, ``E = D - X x``, ``K = mu X^T (X X^T + eps I)^-1``,
    ``x <- x + K E``. Returns ``(x, X, D, y, K)``, ``y = E[0]`` as (m, 1)."""
    X, D = np.vstack([h, X[:-1]]), np.vstack([z, D[:-1]])
    E = D - X @ x
    K = mu * np.linalg.solve(X @ X.T + eps * np.eye(len(X)), X).T   # (G symmetric)
    return x + K @ E, X, D, E[0].reshape(-1, 1), K
