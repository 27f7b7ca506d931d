r"""Innovations models as polynomials: from a Kalman filter back to :math:`A y = B u + C e`.

`from_kalman` takes a `filterpy.kalman.KalmanFilter` (its steady-state
predictor gain from ``F, H, Q, R``) or an innovations form
:math:`x(t+1) = F x + G u + K e`, :math:`y = H x + D u + e` and returns an
`InnovationsModel`, the converse of `rlsfilt.adaptive.to_kalman`.
"""

import numpy as np

from .._validation import as_float_array, check_dt, check_finite, check_real
from ._polynomials import trim

__all__ = ["from_kalman", "InnovationsModel"]

class InnovationsModel:
    r"""A single-output model :math:`A y = B u + C e` from an innovations form.

    Made by `from_kalman`. It has ``polynomials()``, so it can go straight
    to `minimum_variance`, `rst_design` or back to `to_kalman`.

    Attributes
    ----------
    A, C : ndarray
        Monic, ascending powers of :math:`q^{-1}`.
    B : ndarray, shape (nu, nb) or (nb,)
        One row per input (1-D for one input), with the delay's leading
        zeros.
    noise_variance : float
        Variance of the innovations :math:`e`.
    dt : True or float
    """

    def __init__(self, A, B, C, noise_variance, dt=True):
        self.A, self.B, self.C = A, B, C
        self.noise_variance = float(noise_variance)
        self.noise_variance_ = self.noise_variance
        self.dt = dt

    def polynomials(self):
        """``(A, B, C)`` (copies)."""
        return self.A.copy(), self.B.copy(), self.C.copy()

    def to_arx(self, tol=1e-9):
        """The same model as an `~rlsfilt.ARX` (``C`` must be 1 to `tol`).

        Parameters
        ----------
        tol : float, default 1e-9
            Largest ``|c_i|``, ``i >= 1``, counted as zero.

        Returns
        -------
        ARX
        """
        from ..models import ARX

        tol = check_real(tol, "tol", minimum=0)
        if len(self.C) > 1 and np.max(np.abs(self.C[1:])) > tol:
            raise ValueError(f"the noise polynomial C = {self.C.tolist()} is not 1 (largest "
                             f"|c_i| = {np.max(np.abs(self.C[1:])):.3g} > tol = {tol:.3g}): "
                             "this is an ARMAX model, not ARX")
        rows = np.atleast_2d(self.B)
        bs, nks = [], []
        for row in rows:
            nz = np.flatnonzero(row)
            if not len(nz):
                raise ValueError("an input has B = 0; an ARX model needs nb >= 1 per input")
            nks.append(int(nz[0]))
            bs.append(row[nz[0]:nz[-1] + 1].copy())
        multi = rows.shape[0] > 1
        return ARX.from_polynomials(self.A[1:], bs if multi else bs[0],
                                    nk=nks if multi else nks[0], dt=self.dt,
                                    noise_variance=self.noise_variance)

    def __repr__(self):
        return (f"InnovationsModel(A={self.A.tolist()}, B={self.B.tolist()}, "
                f"C={self.C.tolist()}, noise_variance={self.noise_variance:.6g}, dt={self.dt!r})")


def from_kalman(kf=None, *, F=None, H=None, G=None, K=None, D=None, noise_variance=1.0,
                dt=True, max_iter=100000):
    r"""The polynomials :math:`A y = B u + C e` of an innovations model or a Kalman filter.

    Either a `filterpy.kalman.KalmanFilter` (its steady-state predictor gain
    is computed from ``F, H, Q, R``), or the innovations form
    :math:`x(t+1) = F x + G u + K e`, :math:`y = H x + D u + e` given by
    keyword. One output.

    Parameters
    ----------
    kf : filterpy.kalman.KalmanFilter, optional
        Uses ``kf.F``, ``kf.H``, ``kf.B`` (may be None), ``kf.Q``, ``kf.R``
        and, if present, ``kf.D`` (as set by `to_kalman`) and ``kf.dt``.
    F, H, G, K, D : array_like, optional
        Innovations form (without `kf`): ``F`` (n, n), ``H`` (1, n), ``G``
        (n, nu), ``K`` (n,) or (n, 1), ``D`` (1, nu). ``G`` and ``K``
        default to zero, ``D`` to zero.
    noise_variance : float, default 1.0
        Variance of ``e`` (without `kf`; with `kf` it is the innovation
        variance :math:`H P H^T + R`).
    dt : True or float, default True
        Sampling period (without `kf`).
    max_iter : int, default 100000
        Iterations of the Riccati recursion when the algebraic Riccati
        equation cannot be solved directly (a singular ``R``).

    Returns
    -------
    InnovationsModel

    Notes
    -----
    With :math:`\det(zI - F)` read as a polynomial in :math:`q^{-1}`
    (``np.poly(F)``, ascending powers of :math:`q^{-1}`):

    .. math::

        A = \det(I - F q^{-1}), \quad
        C = \det(I - (F - K H) q^{-1}), \quad
        B_j = \det(I - (F - G_j H) q^{-1}) - A + D_j A,

    from :math:`1 + H (zI - F)^{-1} v = \det(zI - F + v H) / \det(zI - F)`
    (the matrix determinant lemma). For a Kalman filter the predictor gain
    is :math:`K = F P H^T (H P H^T + R)^{-1}` with ``P`` the stabilizing
    solution of the filter Riccati equation. Common trailing zeros (poles
    and zeros at ``z = 0``) are removed; no other cancellation is made.

    Examples
    --------
    The round trip through filterpy gives the ARX model back:

    >>> import numpy as np
    >>> from rlsfilt import ARX
    >>> from rlsfilt.adaptive import from_kalman, to_kalman
    >>> model = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], noise_variance=0.01)
    >>> back = from_kalman(to_kalman(model))
    >>> np.round(back.A, 12), np.round(back.B, 12), np.round(back.C, 12)
    (array([ 1. , -1.5,  0.7]), array([0. , 1. , 0.5]), array([1.]))
    >>> np.round(back.to_arx().a_, 12), round(back.noise_variance, 12)
    (array([-1.5,  0.7]), 0.01)
    """
    if kf is not None:
        if any(v is not None for v in (F, H, G, K, D)):
            raise TypeError("give either `kf` or the innovations form (F, H, G, K, D), not both")
        F, H = _mat(kf.F, "kf.F"), _mat(kf.H, "kf.H")
        G = None if getattr(kf, "B", None) is None else _mat(kf.B, "kf.B")
        D = getattr(kf, "D", None)
        Q, R = _mat(kf.Q, "kf.Q"), _mat(kf.R, "kf.R")
        P = _riccati(F, H, Q, R, _mat(kf.P, "kf.P"), max_iter)
        S = H @ P @ H.T + R
        K = F @ P @ H.T @ np.linalg.inv(S)
        noise_variance = float(S[0, 0]) if S.shape == (1, 1) else S
        dt = getattr(kf, "dt", True)
    elif F is None or H is None:
        raise TypeError("`F` and `H` are required without `kf`")
    F = _mat(F, "F")
    n = F.shape[0]
    if F.shape != (n, n):
        raise ValueError(f"`F` must be square; got shape {F.shape}")
    H = _mat(H, "H")
    if H.shape != (1, n):
        raise ValueError(f"`H` must have shape (1, {n}) (one output); got {H.shape}")
    G = np.zeros((n, 1)) if G is None else _mat(G, "G").reshape(n, -1)
    nu = G.shape[1]
    K = np.zeros((n, 1)) if K is None else _mat(K, "K").reshape(n, 1)
    D = np.zeros((1, nu)) if D is None else _mat(D, "D").reshape(1, nu)
    sigma2 = check_real(np.asarray(noise_variance, dtype=float).reshape(-1)[0],
                        "noise_variance", minimum=0)
    A = np.poly(F) if n else np.ones(1)
    C = np.poly(F - K @ H) if n else np.ones(1)
    Bs = [(np.poly(F - G[:, [j]] @ H) - A if n else np.zeros(1)) + D[0, j] * A
          for j in range(nu)]
    # remove common trailing zeros (poles and zeros at z = 0) from A, B, C
    while len(A) > 1 and A[-1] == 0.0 and C[-1] == 0.0 and all(b[-1] == 0.0 for b in Bs):
        A, C, Bs = A[:-1], C[:-1], [b[:-1] for b in Bs]
    A, C = _clean(A), _clean(C)
    Bs = [_clean(b, keep_length=True) for b in Bs]
    lb = max(len(trim(b)) for b in Bs)
    B = np.array([b[:lb] for b in Bs])
    return InnovationsModel(A, B[0] if nu == 1 else B, C, sigma2, check_dt(dt))


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _mat(value, name):
    arr = np.atleast_2d(as_float_array(value, name)).astype(float)
    return check_finite(arr, name)


def _riccati(F, H, Q, R, P0, max_iter):
    """Stabilizing solution of ``P = F P F' - F P H' (H P H' + R)^-1 H P F' + Q`` (prior form)."""
    from scipy.linalg import solve_discrete_are

    try:
        if np.linalg.matrix_rank(R) == R.shape[0]:
            P = solve_discrete_are(F.T, H.T, Q, R)
            if np.all(np.isfinite(P)):
                return 0.5 * (P + P.T)
    except (np.linalg.LinAlgError, ValueError):
        pass
    P = F @ P0 @ F.T + Q                  # iterate the Riccati recursion from the filter's P
    for _ in range(max_iter):
        S = H @ P @ H.T + R
        Kp = F @ P @ H.T @ np.linalg.pinv(S)
        Pn = F @ P @ F.T - Kp @ S @ Kp.T + Q
        Pn = 0.5 * (Pn + Pn.T)
        if np.max(np.abs(Pn - P)) <= 1e-14 * max(1.0, np.max(np.abs(Pn))):
            return Pn
        P = Pn
    raise ValueError(f"`kf`: the Riccati recursion did not converge in max_iter = {max_iter} "
                     "iterations (is (F, H) detectable?)")


def _clean(p, keep_length=False):
    """Round-off-level coefficients to zero (relative to the largest), then trim."""
    p = np.where(np.abs(p) <= 64 * np.finfo(float).eps * max(np.max(np.abs(p)), 1.0), 0.0, p)
    return p if keep_length else trim(p)
