"""Square-root (QR, information form) recursive least squares."""

import math

import numpy as np

from .._display import pretty_str
from .._locking import locked as _locked
from .._validation import (
    check_covariance,
    check_dimension,
    check_int,
    check_lam,
    check_real,
    check_variance,
)
from ..exceptions import ForgettingSkippedWarning
from . import _health, _streaming
from ._base import MISSING_DIAGNOSTICS, _FilterBase
from ._streaming import c_array
from .contract import check_state

__all__ = ["SquareRootRLS"]

class SquareRootRLS(_FilterBase):
    r"""QR recursive least squares: the information square root, updated by QR.

    Same estimates as :class:`~rlsfilt.RecursiveLeastSquares` with
    exponential forgetting, computed without ever forming ``P`` or its
    inverse: the filter keeps the upper-triangular square root ``U`` of the
    information matrix (:math:`U^T U = P^{-1}`), in the square-root-free
    form :math:`U = \Delta^{-1/2} W` (``W`` unit upper triangular,
    :math:`\Delta` diagonal), and folds each new row in with orthogonal
    (Givens) rotations, computed without square roots. Its
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
        P / \lambda`: :math:`\Delta \leftarrow \Delta / \lambda`).
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
        Estimate (assigning it sets ``v = W x``).
    P : ndarray, shape (dim_x, dim_x)
        Covariance :math:`U^{-1} U^{-T}`, computed on access; assigning it
        refactors.
    U : ndarray, shape (dim_x, dim_x)
        Upper-triangular information square root
        :math:`\Delta^{-1/2} W`, computed on access.
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
    The filter stores the factors of :math:`U = \Delta^{-1/2} W` and
    :math:`v = W x` (so :math:`d = \Delta^{-1/2} v`, :math:`P = W^{-1}
    \Delta W^{-T}`) and applies Gentleman's rotations without square roots:
    the same rotations, one division and two multiply-adds per entry of
    ``W`` (row ``i``: :math:`\eta_{i+1} = \eta_i + a_i^2 \delta_i`,
    :math:`\delta_i \leftarrow \delta_i \eta_i / \eta_{i+1}`,
    :math:`a_j \leftarrow a_j - a_i W_{ij}`, :math:`W_{ij} \leftarrow
    W_{ij} + a_i \delta_i a_j / \eta_{i+1}`, from :math:`\eta_0 = R` and
    the new row :math:`a = H`; then :math:`S = \eta_n`). The time update
    scales :math:`\Delta` only.
    ``y``, ``S`` and ``K`` are reported as in the covariance form
    (:math:`S = \lVert U^{-T} H^T \rVert^2 + R`, :math:`K = U^{-1} U^{-T} H^T
    / S`). A parameter random walk ``Q`` has no cheap information-form
    update and is not offered; use :class:`~rlsfilt.RecursiveLeastSquares`
    for it. The cost per step is ``dim_x`` rotations (one per row of
    ``U``; about :math:`2 n^2` flops, ``n`` divisions and no square root)
    and a unit triangular solve for ``x`` (:math:`n^2` flops); the gain, when
    it is reported, costs two more triangular solves. ``P`` costs
    :math:`O(n^3)` and is formed only when it is read or stored. :meth:`predict`, :meth:`update` and
    :meth:`batch_filter` run compiled (numba) and give the same numbers bit
    for bit.

    **Threads.** Each public call that changes the filter's state
    (:meth:`predict`, :meth:`update`, :meth:`predict_update`,
    :meth:`batch_filter`, :meth:`initialize`, :meth:`reset`,
    ``set_state`` and the assignments of ``x``, ``P`` and the settings) holds
    the filter's own reentrant lock, so a filter shared by threads applies
    every call whole and loses none (about 0.12 us per call,
    ``benchmarks/bench_rls.py --lock-cost``). A sequence of calls is not
    atomic: share :meth:`predict_update`, not a ``predict()``/``update()``
    pair. Copies and pickles get their own lock.

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

    _options = _FilterBase._options | {"P", "lam", "alpha", "check_every", "cond_max"}

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
    @_locked
    def lam(self, value):
        self._lam = check_lam(value)

    @property
    def x(self):
        """Estimate ``U^-1 d``, shape ``(dim_x, dim_z)``."""
        return self._x

    @x.setter
    @_locked
    def x(self, value):
        x = self._as_state(value, "x")
        self._set_factors(self._Wv[:, :self.dim_x], self._delta, x=x)

    @property
    def P(self):
        """Covariance ``U^-1 U^-T = W^-1 Delta W^-T`` (a new array on every access)."""
        P = np.empty((self.dim_x, self.dim_x))
        _streaming.window_kernels().sr_covariance(self._Wv, self._delta, P)
        return P

    @P.setter
    @_locked
    def P(self, value):
        from scipy.linalg import cho_factor, cho_solve  # lazy: keeps `import rlsfilt` light
        P = check_covariance(value, self.dim_x, "P", definite=True)
        info = cho_solve(cho_factor(P, lower=True), np.eye(self.dim_x))
        # P^-1 = U^T U (Cholesky), U = Delta^-1/2 W
        self._set_factors(*_unit_factor(np.linalg.cholesky(0.5 * (info + info.T)).T), x=self._x)

    @property
    def U(self):
        """Upper-triangular information square root ``Delta^-1/2 W``, ``U^T U = P^-1``
        (a new array on every access)."""
        U = np.empty((self.dim_x, self.dim_x))
        _streaming.window_kernels().sr_factor(self._Wv, self._delta, U)
        return U

    def _set_factors(self, W, delta, v=None, x=None):
        """Set the state ``W``, ``delta`` and ``v = W x`` (from `v`, or from `x`) and
        ``x = W^-1 v``; ``[W | v]`` is kept as one C-ordered array."""
        from scipy.linalg import solve_triangular  # lazy: keeps `import rlsfilt` light
        W = np.asarray(W, dtype=np.float64)
        if v is None:
            v = W @ x
        n, m = v.shape
        # [W | v] in one C-ordered array, its rows padded with zeros (see the kernels)
        self._Wv = np.zeros((n, _streaming.window_kernels().padded_width(n, m)))
        self._Wv[:, :n], self._Wv[:, n:n + m] = W, v
        self._delta = np.array(delta, dtype=np.float64)
        self._x = (np.array(x, dtype=np.float64) if x is not None
                   else solve_triangular(W, v, unit_diagonal=True))

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    @_locked
    def predict(self, u=None, B=None, F=None):
        r"""Time update :math:`U \leftarrow \sqrt{\lambda} U` (:math:`P \leftarrow P/\lambda`).

        `u`, `B`, `F` are filterpy's control input, control matrix and state
        transition: any value but None raises a `TypeError` (``F = I``, no
        control input).
        """
        if u is not None or B is not None or F is not None:
            self._refuse_control(u, B, F)
        if self.frozen:                               # adaptation off: x, P unchanged
            return self._frozen_predict()
        delta = self._delta.copy()
        if self._lam != 1.0:
            # Delta <- Delta / lam     (U <- sqrt(lam) U, P <- P / lam; W, v and x unchanged)
            _streaming.window_kernels().sr_predict(delta, 1.0 / self._lam)
        self._delta = delta
        self._updates_since_predict = 0
        self.x_prior = self._x.copy()
        self.P_prior = self.P

    @_locked
    def update(self, z, H=None, R=None):
        """Measurement update with regressor row `H` (``self.H`` if omitted, as in
        filterpy; see :meth:`RecursiveLeastSquares.update`; missing `z` keeps the
        estimate)."""
        if self.frozen:                               # adaptation off: only diagnostics
            return self._frozen_update(z, H, R)
        phi = self._as_regressor(self.H if H is None else H, "H")   # filterpy: self.H
        r = self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        n, m = self.dim_x, self.dim_z
        Wv, delta, x = self._Wv.copy(), self._delta.copy(), self._x.copy()
        y, K = np.empty((m, 1)), np.empty((n, 1))
        zrow = np.full(m, np.nan) if zc is None else zc[:, 0]
        # one compiled step (sr_update_kernel), on copies of the state:
        #   a = W^-T H^T,  S = R + sum_i a_i^2 delta_i,  K = W^-1 Delta a / S   (= P H^T / S)
        #   y = z - H x
        #   [U d; H/sqrt(R) z^T/sqrt(R)] -> [U' d'; 0 e]   Givens rotations, one per row,
        #                                                   without square roots (W, Delta, v)
        #   x = W'^-1 v'
        kern = _streaming.window_kernels()
        s, bad = kern.sr_update_kernel(Wv, delta, x, phi[0], zrow, r, y[:, 0], K[:, 0])
        n_updates = self.n_updates + 1
        problem = None
        if self._health_due(n_updates, bad):
            U = np.empty((n, n))                         # U = Delta^-1/2 W, for the check
            if bad or kern.sr_unhealthy(Wv, delta, self.cond_max, U):
                kern.sr_factor(Wv, delta, U)
                problem = ((_health.factor_problem(U, self.cond_max)
                            or "`P` failed the health check")
                           + _health.at_update(n_updates, self._batch_start))
        # an update after an update: the forgetting of this step was skipped (once)
        skipped = self._lam != 1.0 and self._updates_since_predict and not self._warned_skip
        if skipped:
            _health.warn_at_caller(_health.SKIPPED_FORGETTING, ForgettingSkippedWarning)
        self._warn_health(problem)                           # before the state changes
        self._warned_skip = self._warned_skip or bool(skipped)
        self._updates_since_predict += 1
        self._clear_lazy()
        self.H = phi
        self.S, self.SI = s * self._I_z, self._I_z / s
        self.z, self.y, self.K = zrow.reshape(m, 1), y, K
        if zc is None:
            self._lazy = MISSING_DIAGNOSTICS
        self._Wv, self._delta, self._x = Wv, delta, x
        self.n_updates = n_updates
        self.x_post = x.copy()
        self.P_post = self.P

    @_locked
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
        U, d = Rf[:self.dim_x, :self.dim_x], Rf[:self.dim_x, self.dim_x:]
        # U = Delta^-1/2 W, d = U x = Delta^-1/2 v  (the signs of Q's rows: diag(U) > 0)
        self._set_factors(*_unit_factor(U), v=d / np.diagonal(U)[:, None])
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self.P_prior = self.P_post = self.P
        self._updates_since_predict = 0

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
        Wv, delta, x = self._Wv.copy(), self._delta.copy(), self._x.copy()
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
            Wv, delta, x, c_array(Z), c_array(Hm), Rv, 1.0 / self._lam, bool(update_first),
            means, covs, covs_p, x_prior, P_prior, P_post, y, K,
            0 if self._warned_health else self.check_every, step0, float(self.cond_max),
            U_fail)
        problem = None
        if k_fail >= 0:
            problem = ((_health.factor_problem(U_fail, self.cond_max)
                        or "`P` failed the health check")
                       + _health.at_step(k_fail, step0 + k_fail + 1))
        elif not self._warned_health and self.check_every:    # the end-of-batch check
            U = np.empty((n, n))
            kern.sr_factor(Wv, delta, U)
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
        self._updates_since_predict = 0 if update_first else 1   # last: a predict, an update
        self._Wv, self._delta, self._x = Wv, delta, x
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
    # the filter contract (rlsfilt.filters.contract.Filter)
    # ------------------------------------------------------------------
    @property
    def forgets(self):
        """Whether :meth:`predict` changes the factor (``lam < 1``)."""
        return self._lam != 1.0

    @_locked
    def get_state(self):
        """Copies of the state a resumed run needs: ``x`` and the square-root-free
        factors as the filter keeps them (``U = Delta^-1/2 W``, ``v = W x``), the
        update count and the health check's memory (see `rlsfilt.filters.contract`)."""
        n, m = self.dim_x, self.dim_z
        return {"x": self._x.copy(), "W": self._Wv[:, :n].copy(), "delta": self._delta.copy(),
                "v": self._Wv[:, n:n + m].copy(), "n_updates": int(self.n_updates),
                "warned_health": bool(self._warned_health)}

    @_locked
    def set_state(self, state):
        """Continue from `state`, a dict from :meth:`get_state` (copied)."""
        s = check_state(self, state)
        self._set_factors(s["W"], s["delta"], v=s["v"], x=s["x"])
        self.n_updates, self._warned_health = s["n_updates"], s["warned_health"]

    # ------------------------------------------------------------------
    # health of P
    # ------------------------------------------------------------------
    def _final_health_check(self):
        """The full check at the end of a step-by-step `batch_filter`."""
        if self._warned_health or not self.check_every:
            return
        problem = _health.factor_problem(self.U, self.cond_max)
        if problem is not None:
            self._warn_health(problem + _health.at_update(self.n_updates))

    @_locked
    def reset(self):
        """Return to ``x0``, ``P0``; ``lam`` and ``R`` are kept. Re-arms the
        health warning."""
        self.n_updates = 0
        self._warned_health = False
        self._updates_since_predict, self._warned_skip = 0, False
        self._x = self._x0.copy()
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
            pretty_str("U", self.U),
            pretty_str("P", self.P),
            pretty_str("R", self._R),
            pretty_str("y", self.y),
            pretty_str("K", self.K),
            pretty_str("S", self.S),
        ])


def _unit_factor(U):
    """``W``, ``delta`` of ``U = Delta^-1/2 W`` (``W`` unit upper triangular) for an
    upper-triangular ``U`` with a nonzero diagonal: ``delta_i = 1 / U_ii^2``,
    ``W = diag(U)^-1 U``, both independent of the signs of ``U``'s rows."""
    u = np.diagonal(U).copy()
    W = np.triu(U / u[:, None])
    np.fill_diagonal(W, 1.0)
    with np.errstate(over="ignore", under="ignore"):
        # beyond the double range (|u| outside about 1e-154...1e154) delta is 0 or inf,
        # and the health check reports P as it is: not representable
        r = 1.0 / u
        return W, r * r
