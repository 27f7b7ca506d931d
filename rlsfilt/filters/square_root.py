"""Square-root (QR, information form) recursive least squares."""

import math
import warnings

import numpy as np
from filterpy.common import pretty_str
from scipy.linalg import cho_factor, cho_solve

from .._validation import check_covariance, check_int, check_lam, check_real, check_variance
from ..exceptions import NumericalWarning
from ._base import _FilterBase, _tri_inv, _tri_solve, _window_kernels

__all__ = ["SquareRootRLS"]

# Run update, batch_filter and the P property through the compiled kernels of
# `_kernels_window` (numba). The tests switch this off to compare with the
# pure-NumPy reference (the Householder QR step below).
_COMPILED = True
_FLOATS = (float, np.float64)


class SquareRootRLS(_FilterBase):
    r"""QR recursive least squares: the information square root, updated by QR.

    Same estimates as :class:`~rlsfilt.RecursiveLeastSquares` with
    exponential forgetting, computed without ever forming ``P`` or its
    inverse: the filter keeps the upper-triangular square root ``U`` of the
    information matrix (:math:`U^T U = P^{-1}`) and ``d = U x``, and folds
    each new row in with orthogonal (Givens) rotations. Its
    round-off grows with ``cond(U) = sqrt(cond(P))`` where the covariance
    form's grows with ``cond(P)``, and ``P`` is positive definite by
    construction (it still loses accuracy, and the filter warns, when
    forgetting without excitation winds ``cond(P)`` up: see
    `check_every`); on ill-conditioned regressions (NIST StRD Longley,
    condition number 5e9) it keeps about as many digits as a batch QR
    solve. The interface is filterpy's: ``predict``/``update(z, H)``/
    ``initialize``/``batch_filter``, ``x``, ``P`` (computed on access),
    ``y``, ``K``, ``S``.

    Parameters
    ----------
    dim_x : int
        Number of parameters.
    dim_z : int, default 1
        Number of outputs sharing the regressor.
    lam : float, default 1.0
        Forgetting factor in (0, 1], applied by :meth:`predict`
        (:math:`U \leftarrow \sqrt{\lambda} U`, i.e. :math:`P \leftarrow
        P / \lambda`).
    P0 : float or array_like, default 1e4
        Initial covariance (symmetric positive definite).
    x0 : array_like, optional
        Initial estimate; zeros by default.
    R : float, default 1.0
        Measurement-noise variance.
    check_every : int, default 100
        Health check period (0 disables it), with the semantics of
        :class:`~rlsfilt.RecursiveLeastSquares`: every `check_every`
        updates, and at the end of :meth:`batch_filter`, the condition
        number of ``P`` is computed from the triangular factor,
        :math:`\operatorname{cond}(P) = \operatorname{cond}(U)^2` (its
        singular values, O(dim_x^3), without forming ``P``); every update
        also checks cheaply (O(dim_x)) that the diagonal of ``U`` is positive
        and finite, which is what positive definiteness of ``P`` comes down
        to in the square-root form. A failure issues one
        :class:`~rlsfilt.NumericalWarning` naming the update (and, in
        :meth:`batch_filter`, the step of the record).
    cond_max : float, default 1e12
        Condition number of ``P`` beyond which the health check warns.

    Attributes
    ----------
    x : ndarray, shape (dim_x, dim_z)
        Estimate (assigning it sets ``d = U x``).
    P : ndarray, shape (dim_x, dim_x)
        Covariance :math:`U^{-1} U^{-T}`, computed on access; assigning it
        refactors.
    U : ndarray, shape (dim_x, dim_x)
        Upper-triangular information square root (a copy).
    n_updates : int
        Measurement updates since the last :meth:`reset` (the count the
        health warning names).
    x_prior, P_prior, x_post, P_post, H, z, y, K, S, SI
        As in :class:`~rlsfilt.RecursiveLeastSquares`.

    Notes
    -----
    The update solves, in the least-squares sense, the stacked system of the
    old information and the new row (scaled by :math:`1/\sqrt{R}`):

    .. math::

        \begin{bmatrix} U & d \\ H/\sqrt{R} & z^T/\sqrt{R} \end{bmatrix}
        = Q \begin{bmatrix} U' & d' \\ 0 & e \end{bmatrix}, \qquad
        x = U'^{-1} d'

    which is the recursive form of least squares by orthogonal
    transformations (Gentleman 1973; McWhirter 1983; Haykin 2002, ch. 13).
    ``y``, ``S`` and ``K`` are reported as in the covariance form
    (:math:`S = \lVert U^{-T} H^T \rVert^2 + R`, :math:`K = U^{-1} U^{-T} H^T
    / S`). A parameter random walk ``Q`` has no cheap information-form
    update and is not offered; use :class:`~rlsfilt.RecursiveLeastSquares`
    for it. The cost per step is ``dim_x`` Givens rotations (one per row
    of ``U``, each keeping its diagonal entry positive) and three triangular
    solves, :math:`O(n^2)`; ``P`` costs :math:`O(n^3)` and is formed only
    when it is read or stored. :meth:`update` and :meth:`batch_filter` run
    compiled (numba) and give the same numbers bit for bit; the pure-NumPy
    reference path (one Householder QR of the stacked
    ``(dim_x + 1, dim_x + dim_z)`` matrix per step) agrees with them to
    round-off.

    References
    ----------
    .. [1] W. M. Gentleman, "Least squares computations by Givens
       transformations without square roots", *J. Inst. Maths Applics* 12,
       329-336, 1973.
    .. [2] J. G. McWhirter, "Recursive least-squares minimization using a
       systolic array", *Proc. SPIE* 431, 105-112, 1983.
    .. [3] S. Haykin, *Adaptive Filter Theory*, 4th ed., Prentice Hall,
       2002, ch. 13.
    .. [4] G. J. Bierman, *Factorization Methods for Discrete Sequential
       Estimation*, Academic Press, 1977.
    .. [5] J. W. Longley, "An appraisal of least squares programs for the
       electronic computer from the point of view of the user", *JASA* 62,
       819-841, 1967 (the ill-conditioned benchmark of NIST StRD).

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import SquareRootRLS
    >>> rng = np.random.default_rng(0)
    >>> Hs = rng.standard_normal((200, 2))
    >>> zs = Hs @ [0.8, -0.5] + 0.01 * rng.standard_normal(200)
    >>> srls = SquareRootRLS(dim_x=2)
    >>> means, *_ = srls.batch_filter(zs, Hs)
    >>> np.round(srls.x.ravel(), 2)
    array([ 0.8, -0.5])
    """

    def __init__(self, dim_x, dim_z=1, lam=1.0, *, P0=1e4, x0=None, R=1.0,
                 check_every=100, cond_max=1e12):
        self.dim_x = check_int(dim_x, "dim_x", minimum=1)
        self.dim_z = check_int(dim_z, "dim_z", minimum=1)
        self.lam = lam
        self.R = R
        self.check_every = check_int(check_every, "check_every", minimum=0)
        self.cond_max = check_real(cond_max, "cond_max", minimum=0, strict=True)
        self._batch_start = None      # n_updates at the start of a stepwise batch_filter
        self._P0 = check_covariance(P0, self.dim_x, "P0", definite=True)
        self._x0 = self._as_state(np.zeros((self.dim_x, self.dim_z)) if x0 is None else x0, "x0")
        self.reset()

    # ------------------------------------------------------------------
    # state: the factor is primary, x and P are views of it
    # ------------------------------------------------------------------
    @property
    def lam(self):
        """Forgetting factor in (0, 1]."""
        return self._lam

    @lam.setter
    def lam(self, value):
        self._lam = check_lam(value)

    @property
    def x(self):
        """Estimate ``U^-1 d``, shape ``(dim_x, dim_z)``."""
        return self._x

    @x.setter
    def x(self, value):
        self._x = self._as_state(value, "x")
        self._d = self._U @ self._x

    @property
    def P(self):
        """Covariance ``U^-1 U^-T`` (a new array on every access)."""
        if _COMPILED:
            P = np.empty((self.dim_x, self.dim_x))
            kern = _window_kernels()
            kern.sr_covariance(kern.c_array(self._U), P)
            return P
        Ui = _tri_inv(self._U)
        P = Ui @ Ui.T
        return 0.5 * (P + P.T)

    @P.setter
    def P(self, value):
        P = check_covariance(value, self.dim_x, "P", definite=True)
        info = cho_solve(cho_factor(P, lower=True), np.eye(self.dim_x))
        self._U = np.linalg.cholesky(0.5 * (info + info.T)).T
        self._d = self._U @ self._x

    @property
    def U(self):
        """Upper-triangular information square root, ``U^T U = P^-1`` (a copy)."""
        return self._U.copy()

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    def predict(self):
        r"""Time update :math:`U \leftarrow \sqrt{\lambda} U` (:math:`P \leftarrow P/\lambda`)."""
        if self._lam != 1.0:
            c = math.sqrt(self._lam)
            self._U = c * self._U
            self._d = c * self._d
        self.x_prior = self._x.copy()
        self.P_prior = self.P

    def update(self, z, H, R=None):
        """Measurement update with regressor row `H` (see
        :meth:`RecursiveLeastSquares.update`; missing `z` keeps the estimate)."""
        phi = self._as_regressor(H, "H")
        r = self._R if R is None else check_variance(R, "R")
        if type(z) in _FLOATS and self.dim_z == 1 and z - z == 0.0:   # a finite float
            zc = np.array([[z]], dtype=np.float64)
        else:
            zc = self._as_measurement(z, "z")
        self._clear_lazy()
        self.H = phi
        if _COMPILED:
            self._update_compiled(zc, phi, r)
            return
        w = _tri_solve(self._U, phi.ravel(), trans=1)          # w = U^-T H^T
        s = float(w @ w) + r                                    # S = H P H^T + R
        self.S, self.SI = s * self._I_z, self._I_z / s
        if zc is None:
            self.z = np.full((self.dim_z, 1), np.nan)
            self.y = np.full((self.dim_z, 1), np.nan)
            self.K = np.zeros((self.dim_x, 1))
            self._log_likelihood, self._likelihood = 0.0, 1.0
        else:
            self.z = zc
            self.y = zc - (phi @ self._x).T                     # y = z - H x
            self.K = _tri_solve(self._U, w).reshape(-1, 1) / s   # K = P H^T / S
            self._U, self._d = _qr_update(self._U, self._d, phi, zc, r)
            self._x = _tri_solve(self._U, self._d)
        self.n_updates = nu = self.n_updates + 1
        every = self.check_every
        if every and not self._warned_health:
            dg = np.diagonal(self._U)
            if not nu % every or not (np.isfinite(dg).all() and (dg > 0.0).all()):
                problem = _health_problem(self._U, self.cond_max)
                if problem is not None:
                    self._warn_health(problem + self._where(), self._user_level(3))
        self.x_post = self._x.copy()
        self.P_post = self.P

    def _update_compiled(self, zc, phi, r):
        """:meth:`update` by the compiled step (the one `batch_filter` runs)."""
        n, m = self.dim_x, self.dim_z
        U, d = self._U.copy(), self._d.copy()
        x = self._x.copy()
        y, K = np.empty((m, 1)), np.empty((n, 1))
        zrow = np.full(m, np.nan) if zc is None else zc[:, 0]
        kern = _window_kernels()
        s, bad = kern.sr_update_kernel(U, d, x, phi[0], zrow, r, y[:, 0], K[:, 0])
        self.S, self.SI = s * self._I_z, self._I_z / s
        self.z, self.y, self.K = zrow.reshape(m, 1), y, K
        if zc is None:
            self._log_likelihood, self._likelihood = 0.0, 1.0
        self._U, self._d, self._x = U, d, x
        # the health check: the kernel tested the diagonal (`bad`); the
        # periodic full check runs compiled, the NumPy check only words it
        self.n_updates = nu = self.n_updates + 1
        every = self.check_every
        if every and (bad or not nu % every) and not self._warned_health:
            if bad or kern.sr_unhealthy(U, self.cond_max):
                problem = _health_problem(U, self.cond_max) or "`P` failed the health check"
                self._warn_health(problem + self._where(), self._user_level(4))
        self.x_post = x.copy()
        self.P_post = self.P

    def predict_update(self, z, H, R=None):
        """:meth:`predict` then :meth:`update`."""
        self.predict()
        self.update(z, H, R)

    def initialize(self, zs, Hs):
        """Start from batch least squares on the first samples (QR of the rows).

        Row ``i`` of ``k0`` is weighted by ``lam**(k0 - 1 - i)`` as in
        :meth:`RecursiveLeastSquares.initialize`; rows with missing
        measurements are dropped.

        Raises
        ------
        ValueError
            If the rows do not determine every parameter.
        """
        Z, Hm = self._as_batch(zs, Hs)
        keep = ~np.isnan(Z).any(axis=1)
        w = self._lam ** (0.5 * np.arange(len(Z) - 1, -1, -1.0)) / math.sqrt(self._R)
        A = Hm[keep] * w[keep, None]
        B = Z[keep] * w[keep, None]
        rank = np.linalg.matrix_rank(A) if len(A) else 0
        if rank < self.dim_x:
            raise ValueError(
                f"`Hs` is rank-deficient: found {rank} linearly independent rows in "
                f"{len(A)} usable samples; need {self.dim_x} (one per parameter)")
        Rf = np.linalg.qr(np.hstack([A, B]), mode="r")
        self._U, self._d = _positive_diagonal(Rf[:self.dim_x, :self.dim_x],
                                              Rf[:self.dim_x, self.dim_x:])
        self._x = _tri_solve(self._U, self._d)
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self.P_prior = self.P_post = self.P

    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True):
        """Run the filter over a record; same arguments and returns as
        :meth:`RecursiveLeastSquares.batch_filter`."""
        return self._batch_dispatch(zs, Hs, Rs, update_first, saver, store_covariances,
                                    _COMPILED)

    def _batch_compiled(self, Z, Hm, Rv, update_first, store_covariances):
        """`batch_filter` in one compiled call; leaves the filter as the
        step-by-step loop would (the same compiled step, bit for bit, and
        the same health check, reported with its step)."""
        N, n, m = len(Z), self.dim_x, self.dim_z
        U = np.array(self._U, dtype=np.float64, order="C")
        d = np.array(self._d, dtype=np.float64, order="C")
        x = np.array(self._x, dtype=np.float64, order="C")
        x_start = self._x.copy()
        means = np.empty((N, n, m))
        if store_covariances:
            covs, covs_p = np.empty((N, n, n)), np.empty((N, n, n))
        else:
            covs = covs_p = np.empty((0, n, n))
        x_prior, P_prior, P_post = np.empty((n, m)), np.empty((n, n)), np.empty((n, n))
        y, K = np.empty(m), np.empty(n)
        # one variance for every step: a length-1 array (copies: the kernels
        # are compiled for writable C arrays only)
        kern = _window_kernels()
        Rv = kern.c_array(Rv[:1] if Rv.strides[0] == 0 else Rv)
        c = math.sqrt(self._lam) if self._lam != 1.0 else 1.0
        step0 = self.n_updates
        U_fail = np.empty((n, n))
        s, k_fail = kern.sr_batch_kernel(
            U, d, x, kern.c_array(Z),
            kern.c_array(Hm), Rv, c, bool(update_first),
            means, covs, covs_p, x_prior, P_prior, P_post, y, K,
            0 if self._warned_health else self.check_every, step0, float(self.cond_max),
            U_fail)
        self.n_updates = step0 + N
        if k_fail >= 0:
            problem = (_health_problem(U_fail, self.cond_max)
                       or "`P` failed the health check")
            self._warn_health(f"{problem} at step {k_fail} of batch_filter (update "
                              f"{step0 + k_fail + 1} since reset)", 5)
        # the estimate is unchanged by a time update
        if update_first:
            means_p = means.copy()
        else:
            means_p = np.empty((N, n, m))
            means_p[0] = x_start
            means_p[1:] = means[:-1]
        self._U, self._d, self._x = U, d, x
        self._clear_lazy()
        self.H = Hm[-1].reshape(1, n).copy()
        self.S, self.SI = s * self._I_z, self._I_z / s
        self.z = Z[-1].reshape(m, 1).copy()
        self.y, self.K = y.reshape(m, 1), K.reshape(n, 1)
        if np.isnan(self.z).any():
            self.z[:] = np.nan
            self._log_likelihood, self._likelihood = 0.0, 1.0
        self.x_prior, self.P_prior = x_prior, P_prior
        self.x_post, self.P_post = x.copy(), P_post
        if not store_covariances:
            covs = covs_p = None
        return means, covs, means_p, covs_p

    # ------------------------------------------------------------------
    # helpers
    # ------------------------------------------------------------------
    def get_prediction(self):
        """Return ``(x, P)`` after a :meth:`predict`, without changing the filter."""
        return self._x.copy(), self.P / self._lam

    # ------------------------------------------------------------------
    # health of P
    # ------------------------------------------------------------------
    def _check_health(self):
        """Warn once if ``P`` is not positive definite or too ill-conditioned
        (the full check, on the factor ``U``).
        Called at the end of ``batch_filter`` (through ``_batch_dispatch``): the
        warning points at the caller of ``batch_filter``."""
        if self._warned_health or not self.check_every:
            return
        problem = _health_problem(self._U, self.cond_max)
        if problem is not None:
            self._warn_health(problem + f" at update {self.n_updates} since reset", 5)

    def _user_level(self, level):
        """`stacklevel` of the caller of :meth:`update` (deeper inside a
        stepwise :meth:`batch_filter`, below ``_batch_dispatch`` and
        ``_batch_stepwise``)."""
        return level if self._batch_start is None else level + 3

    def _where(self):
        """Where the health check failed: the update, and the step of a
        running `batch_filter`."""
        nu = self.n_updates
        if self._batch_start is None:
            return f" at update {nu} since reset"
        return (f" at step {nu - self._batch_start - 1} of batch_filter (update {nu} "
                f"since reset)")

    def _warn_health(self, message, stacklevel):
        self._warned_health = True
        warnings.warn(message + ". The estimate may be unreliable: the input has stopped "
                      "exciting some direction of the parameters (covariance windup under "
                      "forgetting); use more exciting input, lam closer to 1, or "
                      "RecursiveLeastSquares with an anti-windup forgetting mode "
                      "(forgetting='directional', 'efra', ...).", NumericalWarning,
                      stacklevel=stacklevel)

    def reset(self):
        """Return to ``x0``, ``P0``; ``lam`` and ``R`` are kept. Re-arms the
        health warning."""
        n = self.dim_x
        self.n_updates = 0
        self._warned_health = False
        self._x = self._x0.copy()
        self._U = np.eye(n)
        self.P = self._P0
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self.P_prior, self.P_post = self._P0.copy(), self._P0.copy()
        self._reset_diagnostics()

    def __repr__(self):
        return "\n".join([
            "SquareRootRLS object",
            pretty_str("dim_x", self.dim_x),
            pretty_str("dim_z", self.dim_z),
            pretty_str("lam", self._lam),
            pretty_str("x", self._x),
            pretty_str("U", self._U),
            pretty_str("P", self.P),
            pretty_str("R", self._R),
            pretty_str("y", self.y),
            pretty_str("K", self.K),
            pretty_str("S", self.S),
        ])


def _health_problem(U, cond_max):
    """None if ``P = U^-1 U^-T`` is healthy, else a description (the wording
    of ``rls._health_problem``).

    ``P`` is positive definite exactly when the triangular ``U`` has a
    positive, finite diagonal, and ``cond(P) = cond(U)^2`` (singular values
    of ``U``), so ``P`` is never formed.
    """
    if not np.isfinite(U).all():
        return "`P` has non-finite entries"
    dmin = float(np.min(np.diagonal(U)))
    if not dmin > 0.0:
        return (f"`P` is not positive definite (smallest diagonal entry of its square root "
                f"U is {dmin:.3g})")
    sv = np.linalg.svd(U, compute_uv=False)
    ratio = float(sv[0] / sv[-1]) if sv[-1] > 0.0 else math.inf
    cond = ratio * ratio if ratio < 1e150 else math.inf
    if cond > cond_max:
        return f"`P` is ill-conditioned (condition number {cond:.3g} > {cond_max:.3g})"
    return None


def _qr_update(U, d, phi, z, r):
    """Fold the row ``[phi, z^T] / sqrt(r)`` into ``[U, d]`` by one QR."""
    n = U.shape[0]
    c = 1.0 / math.sqrt(r)
    M = np.vstack([np.hstack([U, d]), np.hstack([phi * c, z.T * c])])
    Rf = np.linalg.qr(M, mode="r")
    return _positive_diagonal(Rf[:n, :n], Rf[:n, n:])


def _positive_diagonal(U, d):
    """Flip row signs so that ``diag(U) > 0`` (the unique factor)."""
    sg = np.where(np.diag(U) < 0.0, -1.0, 1.0)
    return U * sg[:, None], d * sg[:, None]
