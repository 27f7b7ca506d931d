r"""Identified models as filterpy Kalman filters in innovations form.

A model :math:`A(q^{-1}) y(t) = B(q^{-1}) u(t) + C(q^{-1}) e(t)` (ARX: ``C = 1``)
has the *innovations form*

.. math::

    x(t+1) = F x(t) + G u(t) + K e(t), \qquad y(t) = H x(t) + D u(t) + e(t),

with ``F, G, H, D`` an observer-canonical realization of ``B/A`` and ``K``
that of ``(C - A)/A``; :math:`e(t) = y(t) - \hat y(t|t-1)` is the
innovation. `to_kalman` hands this to `filterpy.kalman.KalmanFilter`;
`rlsfilt.adaptive.from_kalman` (module ``innovations``) goes back.
"""

import functools
import warnings

import numpy as np

from .._validation import as_float_array
from ..exceptions import OperatingPointWarning
from ._polynomials import model_dt, observer_form, trim

__all__ = ["to_kalman"]


def to_kalman(model, noise_variance=None):
    r"""A `filterpy.kalman.KalmanFilter` whose predictions are the model's.

    The filter's one-step predictions equal ``model.predict(u, y,
    horizon=1)`` and its ``k``-step predictions (``k`` calls of ``predict``
    from a posterior) equal ``model.predict(u, y, horizon=k)``.

    Parameters
    ----------
    model : ARX, another rlsfilt model, or an object with ``polynomials()``
        A fitted `~rlsfilt.ARX` (any numbers of inputs and outputs) or any
        rlsfilt model through ``polydata()``: ARMAX, and for one output OE
        and BJ too (over the common denominator ``A D F``), AR and ARMA
        (``dim_u = 0``: call ``kf.predict()`` without `u`); or an object
        whose ``polynomials()`` gives ``(A, B)`` or ``(A, B, C)`` in
        ascending powers of :math:`q^{-1}`, such as an `InnovationsModel`,
        or ``(A, B, C, D, F)`` (``B``, ``F`` one per input), as the
        streaming estimators `RecursiveARMAX`, `RecursiveOE`,
        `RecursiveBJ` give (one output, over ``A D F``).
    noise_variance : float or array_like, optional
        Covariance :math:`\Sigma` of the innovations: a positive variance,
        ``ny`` of them, or a symmetric positive definite ``(ny, ny)`` matrix;
        the model's ``noise_covariance_`` or ``noise_variance_``, or 1 by
        default (it only scales ``P`` and ``S``, never the predictions).

    Returns
    -------
    filterpy.kalman.KalmanFilter
        ``dim_x = n + ny`` (the realization's ``n`` states, then the
        innovation), ``dim_z = ny``, ``dim_u = nu``, with ``x = 0`` and
        ``P = 0``: the posterior at ``t = -1`` with everything before
        ``t = 0`` zero (the model's convention). Also an attribute ``D``
        (``ny x nu``), the feed-through, nonzero only for ``nk = 0``.

    Warns
    -----
    OperatingPointWarning
        For a model with an operating point (``ARX(offset=True)`` or
        ``offset="mean"``): the filter is its model of the deviations, so
        feed it ``u - model.input_offset_`` and ``y - model.output_offset_``
        and add ``model.output_offset_`` to its predictions (fed the data
        themselves, its predictions are off by a constant).

    Notes
    -----
    The state is :math:`s(t) = [x(t); \varepsilon(t)]` with

    .. math::

        F_s = \begin{bmatrix} F & K \\ 0 & 0 \end{bmatrix},\quad
        B_s = \begin{bmatrix} G \\ 0 \end{bmatrix},\quad
        H_s = \begin{bmatrix} H & I \end{bmatrix},\quad
        Q_s = \begin{bmatrix} 0 & 0 \\ 0 & \Sigma \end{bmatrix},\quad
        R_s = 0.

    The innovation is part of the state because it drives both the state
    and the output (correlated process and measurement noise, which
    `KalmanFilter` does not otherwise take). From ``P = 0`` the filter is
    in steady state from the first step: the prior covariance is
    :math:`Q_s`, the gain :math:`[0; I]`, so ``update`` sets
    :math:`\varepsilon` to the innovation :math:`y - H_s s^-` and
    ``predict`` propagates it through ``K``. One sample is

    .. code-block:: python

        kf.predict(u=u_prev)          # u(t-1): a scalar, or a column (nu, 1)
        yhat = kf.H @ kf.x + kf.D @ u_now           # = model.predict(...)[t]
        kf.update(y_now - kf.D @ u_now)             # D = 0 unless nk = 0

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import ARX
    >>> from rlsfilt.adaptive import to_kalman
    >>> model = ARX.from_polynomials([-0.9], [1.0])      # y(t) = 0.9 y(t-1) + u(t-1)
    >>> u = np.array([1.0, 0.0, 0.0, 0.0])
    >>> y = np.array([0.0, 1.0, 1.0, 0.5])
    >>> kf = to_kalman(model)
    >>> yhat = []
    >>> for t in range(4):
    ...     kf.predict(u=u[t - 1] if t else 0.0)
    ...     yhat.append((kf.H @ kf.x).item())
    ...     kf.update(y[t])
    >>> np.allclose(yhat, model.predict(u, y, horizon=1))
    True
    """
    from filterpy.kalman import KalmanFilter

    _warn_operating_point(model)
    A, B, C = _matrix_polynomials(model)
    ny, nu = B.shape[0], B.shape[1]
    Sigma = _noise_covariance(model, noise_variance, ny)
    # one realization of [B, C]: inputs u and e share F and H
    L = max(B.shape[2], C.shape[2])
    F, G_all, H, D_all = observer_form(A, np.concatenate([_pad3(B, L), _pad3(C, L)], axis=1))
    G, K = G_all[:, :nu], G_all[:, nu:]
    D = D_all[:, :nu]
    n = F.shape[0]
    kf = KalmanFilter(dim_x=n + ny, dim_z=ny, dim_u=nu)
    Fs = np.zeros((n + ny, n + ny))
    Fs[:n, :n], Fs[:n, n:] = F, K
    kf.F = Fs
    kf.B = np.vstack([G, np.zeros((ny, nu))])
    kf.H = np.hstack([H, np.eye(ny)])
    Qs = np.zeros((n + ny, n + ny))
    Qs[n:, n:] = Sigma
    kf.Q = Qs
    kf.R = np.zeros((ny, ny))
    kf.x = np.zeros((n + ny, 1))
    kf.P = np.zeros((n + ny, n + ny))
    kf.D = D
    kf.dt = model_dt(model)
    return kf


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _warn_operating_point(model):
    """`OperatingPointWarning` when the model's dynamics are about a nonzero operating point
    (the filter, like `polydata`, is the model of the deviations from it)."""
    u_op = np.asarray(getattr(model, "input_offset_", 0.0), dtype=float)
    y_op = np.asarray(getattr(model, "output_offset_", 0.0), dtype=float)
    if np.any(u_op != 0.0) or np.any(y_op != 0.0):
        warnings.warn(
            f"the {type(model).__name__} model has an operating point (input_offset_ = "
            f"{np.round(u_op, 6).tolist()}, output_offset_ = {np.round(y_op, 6).tolist()}): the "
            f"Kalman filter is its model of the deviations; feed it u - input_offset_ and "
            f"y - output_offset_ and add output_offset_ to its predictions",
            OperatingPointWarning, stacklevel=3)


def _matrix_polynomials(model):
    r"""``A (ny, ny, *)``, ``B (ny, nu, *)``, ``C (ny, ny, *)`` of the model's ARMAX form.

    From ``polydata()`` (every rlsfilt model): one output over the common
    denominator, :math:`A D \prod_j F_j\, y = \sum_j B_j D \prod_{k \ne j} F_k\,
    u_j + C \prod_j F_j\, e`; several outputs need ``D = F = 1``. Otherwise
    from ``polynomials()``: ``(A, B)`` or ``(A, B, C)``.
    """
    if hasattr(model, "polydata"):
        p = model.polydata()
        A, B = np.asarray(p.A, dtype=float), np.asarray(p.B, dtype=float)
        C, D, F = (np.asarray(x, dtype=float) for x in (p.C, p.D, p.F))
        ny, nu = A.shape[0], B.shape[1]
        if ny == 1:
            A, B, C = _common_denominator(A[0, 0], [B[0, j] for j in range(nu)], C[0], D[0],
                                          [F[0, j] for j in range(nu)])
        else:
            if np.any(D[:, 1:]) or np.any(F[:, :, 1:]):
                raise ValueError("`model` with several outputs must have D = F = 1 (ARX or "
                                 "ARMAX) to become a Kalman filter")
            Cm = np.zeros((ny, ny, C.shape[1]))
            for i in range(ny):
                Cm[i, i] = C[i]
            C = Cm
        return _check_monic(A, B, C)
    if not hasattr(model, "polynomials"):
        raise TypeError(f"`model` must have polydata() or polynomials() (a fitted ARX, an "
                        f"InnovationsModel); got {type(model).__name__}")
    polys = model.polynomials()
    if isinstance(polys, dict):
        polys = tuple(polys.get(k, polys.get(k.upper())) for k in "abc")
    if len(polys) == 5:   # (A, B, C, D, F) of the streaming estimators (RecursiveOE, ...)
        a, b, c, d, f = polys
        bs = [b] if np.ndim(b) == 1 and not isinstance(b, (list, tuple)) else list(b)
        fs = [f] if np.ndim(f) == 1 and not isinstance(f, (list, tuple)) else list(f)
        return _check_monic(*_common_denominator(a, bs, c, d, fs))
    if len(polys) not in (2, 3):
        raise ValueError(f"`model.polynomials()` must give (A, B), (A, B, C) or (A, B, C, D, F); "
                         f"got {len(polys)} polynomials")
    A, B = (np.asarray(p, dtype=float) for p in polys[:2])
    C = np.asarray(polys[2], dtype=float) if len(polys) > 2 and polys[2] is not None else None
    if A.ndim == 1:
        A = A.reshape(1, 1, -1)
        B = B.reshape(-1, B.shape[-1])[None] if B.ndim <= 2 else B
        C = np.ones((1, 1, 1)) if C is None else C.reshape(1, 1, -1)
    else:
        C = np.eye(A.shape[0])[:, :, None] if C is None else C
    return _check_monic(A, B, C)


def _common_denominator(a, bs, c, d, fs):
    r"""One output over the common denominator: :math:`A D \prod_j F_j\, y = \sum_j B_j D
    \prod_{k \ne j} F_k\, u_j + C \prod_j F_j\, e` as ``A (1, 1, *)``, ``B (1, nu, *)``,
    ``C (1, 1, *)`` (no input, AR or ARMA: ``B`` of shape ``(1, 0, 1)``)."""
    Fs = [trim(np.asarray(f, dtype=float)) for f in fs]
    prodF = functools.reduce(np.convolve, Fs, np.ones(1))
    d = trim(np.asarray(d, dtype=float))
    Anew = np.convolve(np.convolve(trim(np.asarray(a, dtype=float)), d), prodF)
    Bs = [np.convolve(np.convolve(trim(np.asarray(b, dtype=float)), d),
                      functools.reduce(np.convolve, Fs[:j] + Fs[j + 1:], np.ones(1)))
          for j, b in enumerate(bs)]
    nu = len(Bs)
    L = max((len(b) for b in Bs), default=1)
    B = np.array([[np.pad(b, (0, L - len(b))) for b in Bs]]).reshape(1, nu, L)
    C = np.convolve(trim(np.asarray(c, dtype=float)), prodF).reshape(1, 1, -1)
    return Anew.reshape(1, 1, -1), B, C


def _check_monic(A, B, C):
    ny = A.shape[0]
    if not np.array_equal(A[:, :, 0], np.eye(ny)):
        raise ValueError("`model`: A(0) must be the identity (a monic A)")
    if not np.array_equal(C[:, :, 0], np.eye(ny)):
        raise ValueError("`model`: C(0) must be the identity (a monic C)")
    return A, B, C


def _pad3(P, n):
    out = np.zeros(P.shape[:2] + (n,))
    out[:, :, :P.shape[2]] = P
    return out


def _noise_covariance(model, noise_variance, ny):
    if noise_variance is None:
        value = getattr(model, "noise_covariance_", None)
        if value is None or ny == 1:
            value = getattr(model, "noise_variance_", None)
        if value is None:
            value = 1.0
    else:
        value = as_float_array(noise_variance, "noise_variance")
    S = np.asarray(value, dtype=float)
    if S.ndim == 0 or S.size == 1:
        S = float(S.reshape(())) * np.eye(ny)
    elif S.shape == (ny,):
        S = np.diag(S)
    if S.shape != (ny, ny) or not np.all(np.isfinite(S)):
        raise ValueError(f"`noise_variance` must be a finite scalar or a ({ny}, {ny}) "
                         f"covariance; got shape {S.shape}")
    if noise_variance is None:
        if not np.any(S):
            S = np.eye(ny)        # a noise-free model: any positive scale gives the same filter
        return S
    # given: a variance is positive, a covariance symmetric positive definite (S, the
    # innovations' covariance the filter inverts, is this matrix)
    scale = float(np.max(np.abs(S)))
    if np.max(np.abs(S - S.T)) > 1e-10 * scale:
        raise ValueError(f"`noise_variance` must be a symmetric ({ny}, {ny}) covariance; got "
                         f"max |S - S^T| = {np.max(np.abs(S - S.T)):.3g}")
    smallest = float(S[0, 0] if ny == 1 else np.linalg.eigvalsh(0.5 * (S + S.T))[0])
    if not smallest > 0.0:
        got = f"{smallest:.6g}" if ny == 1 else f"smallest eigenvalue {smallest:.3g}"
        raise ValueError(f"`noise_variance` must be "
                         f"{'a positive variance' if ny == 1 else 'positive definite'}; got {got}")
    return S
