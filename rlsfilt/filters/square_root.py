"""Square-root (QR, information form) recursive least squares."""

import math

import numpy as np

from .._display import pretty_str
from .._validation import (
    check_covariance,
    check_dimension,
    check_int,
    check_lam,
    check_real,
    check_variance,
)
from . import _health, _streaming
from ._base import MISSING_DIAGNOSTICS, _FilterBase
from ._streaming import c_array

__all__ = ["SquareRootRLS"]

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
    check_every : int, optional
        Health check period (0 disables it; by default ``max(250, 32
        dim_x)``), with the semantics of
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
    when it is read or stored. :meth:`predict`, :meth:`update` and
    :meth:`batch_filter` run compiled (numba) and give the same numbers bit
    for bit.

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

    _HEALTH_ADVICE = ("The estimate may be unreliable: the input has stopped exciting some "
                      "direction of the parameters (covariance windup under forgetting); use "
                      "more exciting input, lam closer to 1, or RecursiveLeastSquares with an "
                      "anti-windup forgetting mode (forgetting='directional', 'efra', ...).")

    def __init__(self, dim_x, dim_z=1, lam=1.0, *, P0=1e4, x0=None, R=1.0,
                 check_every=None, cond_max=1e12):
        self.dim_x = check_dimension(dim_x, "dim_x")
        self.dim_z = check_int(dim_z, "dim_z", minimum=1)
        self.lam = lam
        self.R = R
        self.check_every = check_every
        self.cond_max = check_real(cond_max, "cond_max", minimum=0, strict=True)
        self._batch_start = None      # n_updates when a step-by-step batch_filter started
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
        P = np.empty((self.dim_x, self.dim_x))
        _streaming.window_kernels().upper_inverse_gram(c_array(self._U), P)
        return P

    @P.setter
    def P(self, value):
        from scipy.linalg import cho_factor, cho_solve  # lazy: keeps `import rlsfilt` light
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
        U, d = np.array(self._U, order="C"), np.array(self._d, order="C")
        if self._lam != 1.0:
            # U <- sqrt(lam) U,  d <- sqrt(lam) d     (P <- P / lam, x unchanged)
            _streaming.window_kernels().sr_predict(U, d, math.sqrt(self._lam))
        self._U, self._d = U, d
        self.x_prior = self._x.copy()
        self.P_prior = self.P

    def update(self, z, H, R=None):
        """Measurement update with regressor row `H` (see
        :meth:`RecursiveLeastSquares.update`; missing `z` keeps the estimate)."""
        phi = self._as_regressor(H, "H")
        r = self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        n, m = self.dim_x, self.dim_z
        U, d, x = c_array(self._U.copy()), c_array(self._d.copy()), c_array(self._x.copy())
        y, K = np.empty((m, 1)), np.empty((n, 1))
        zrow = np.full(m, np.nan) if zc is None else zc[:, 0]
        # one compiled step (sr_update_kernel), on copies of the state:
        #   w = U^-T H^T,  S = w^T w + R,  K = U^-1 w / S     (K = P H^T / S)
        #   y = z - H x
        #   [U d; H/sqrt(R) z^T/sqrt(R)] -> [U' d'; 0 e]      Givens rotations, one per row
        #   x = U'^-1 d'
        kern = _streaming.window_kernels()
        s, bad = kern.sr_update_kernel(U, d, x, phi[0], zrow, r, y[:, 0], K[:, 0])
        n_updates = self.n_updates + 1
        problem = None
        if self._health_due(n_updates, bad) and (bad or kern.factor_unhealthy(U, self.cond_max)):
            problem = ((_health.factor_problem(U, self.cond_max) or "`P` failed the health check")
                       + _health.at_update(n_updates, self._batch_start))
        self._warn_health(problem)                           # before the state changes
        self._clear_lazy()
        self.H = phi
        self.S, self.SI = s * self._I_z, self._I_z / s
        self.z, self.y, self.K = zrow.reshape(m, 1), y, K
        if zc is None:
            self._lazy = MISSING_DIAGNOSTICS
        self._U, self._d, self._x = U, d, x
        self.n_updates = n_updates
        self.x_post = x.copy()
        self.P_post = self.P

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
        from scipy.linalg import solve_triangular  # lazy: keeps `import rlsfilt` light
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
        self._x = solve_triangular(self._U, self._d)
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self.P_prior = self.P_post = self.P

    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True):
        """Run the filter over a record; same arguments and returns as
        :meth:`RecursiveLeastSquares.batch_filter`."""
        return self._batch(zs, Hs, Rs, update_first, saver, store_covariances)

    def _batch_compiled(self, Z, Hm, Rv, update_first, store_covariances):
        """`batch_filter` in one compiled call; leaves the filter as the
        step-by-step loop would (the same compiled step, bit for bit, and
        the same health check, reported with its step), and changes nothing
        if it raises."""
        N, n, m = len(Z), self.dim_x, self.dim_z
        U = np.array(self._U, dtype=np.float64, order="C")
        d = np.array(self._d, dtype=np.float64, order="C")
        x = np.array(self._x, dtype=np.float64, order="C")
        means = np.empty((N, n, m))
        if store_covariances:
            covs, covs_p = np.empty((N, n, n)), np.empty((N, n, n))
        else:
            covs = covs_p = np.empty((0, n, n))
        x_prior, P_prior, P_post = np.empty((n, m)), np.empty((n, n)), np.empty((n, n))
        y, K = np.empty(m), np.empty(n)
        kern = _streaming.window_kernels()
        Rv = c_array(Rv[:1] if Rv.strides[0] == 0 else Rv)   # one variance: a length-1 array
        step0 = self.n_updates
        U_fail = np.empty((n, n))
        s, k_fail = kern.sr_batch_kernel(
            U, d, x, c_array(Z), c_array(Hm), Rv, math.sqrt(self._lam), bool(update_first),
            means, covs, covs_p, x_prior, P_prior, P_post, y, K,
            0 if self._warned_health else self.check_every, step0, float(self.cond_max),
            U_fail)
        problem = None
        if k_fail >= 0:
            problem = ((_health.factor_problem(U_fail, self.cond_max)
                        or "`P` failed the health check")
                       + _health.at_step(k_fail, step0 + k_fail + 1))
        elif not self._warned_health and self.check_every:    # the end-of-batch check
            problem = _health.factor_problem(U, self.cond_max)
            if problem is not None:
                problem += _health.at_update(step0 + N)
        self._warn_health(problem)                           # before the state changes
        # the estimate is unchanged by a time update
        if update_first:
            means_p = means.copy()
        else:
            means_p = np.empty((N, n, m))
            means_p[0] = self._x
            means_p[1:] = means[:-1]
        self.n_updates = step0 + N
        self._U, self._d, self._x = U, d, x
        self._clear_lazy()
        self.H = Hm[-1].reshape(1, n).copy()
        self.S, self.SI = s * self._I_z, self._I_z / s
        self.z = Z[-1].reshape(m, 1).copy()
        self.y, self.K = y.reshape(m, 1), K.reshape(n, 1)
        if np.isnan(self.z).any():
            self.z[:] = np.nan
            self._lazy = MISSING_DIAGNOSTICS
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
    def _final_health_check(self):
        """The full check at the end of a step-by-step `batch_filter`."""
        if self._warned_health or not self.check_every:
            return
        problem = _health.factor_problem(self._U, self.cond_max)
        if problem is not None:
            self._warn_health(problem + _health.at_update(self.n_updates))

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


def _positive_diagonal(U, d):
    """Flip row signs so that ``diag(U) > 0`` (the unique factor)."""
    sg = np.where(np.diag(U) < 0.0, -1.0, 1.0)
    return U * sg[:, None], d * sg[:, None]
