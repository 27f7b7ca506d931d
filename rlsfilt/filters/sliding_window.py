"""Exact least squares over a sliding window of the most recent samples."""

import numpy as np

from .._display import pretty_str
from .._locking import locked as _locked
from .._validation import (
    check_covariance,
    check_dimension,
    check_int,
    check_length,
    check_real,
    check_variance,
)
from . import _health, _streaming
from ._base import MISSING_DIAGNOSTICS, _FilterBase, own_array, refuse_fixed
from ._streaming import c_array
from .contract import check_state

__all__ = ["SlidingWindowRLS"]

class SlidingWindowRLS(_FilterBase):
    r"""Recursive least squares over the last `window` samples (update + downdate).

    Where exponential forgetting weights old data by ``lam**age`` forever, a
    sliding window gives the *exact* least-squares estimate on the last
    `window` samples and none before: each :meth:`update` adds the new
    sample and removes the one that leaves the window (a downdate with the
    matrix inversion lemma). The interface is that of
    :class:`~rlsfilt.RecursiveLeastSquares` (``predict``/``update(z, H)``/
    ``initialize``/``batch_filter``, ``x``, ``P``, ``y``, ``K``, ``S``).

    Parameters
    ----------
    dim_x : int
        Number of parameters.
    window : int
        Number of samples in the window (at least `dim_x`; missing samples
        occupy a slot but carry no information).
    dim_z : int, default 1
        Number of outputs sharing the regressor.
    P0 : float or array_like, default 1e4
        Prior covariance used only until the window holds enough data to
        determine every parameter (see Notes).
    x0 : array_like, optional
        Prior estimate, shape ``(dim_x,)`` or ``(dim_x, dim_z)``; zeros by
        default.
    R : float, default 1.0
        Measurement-noise variance (per-call values given to :meth:`update`
        are remembered for the downdate).
    refresh : int or None, default ``10 * window``
        Recompute the estimate from the stored window by QR every `refresh`
        updates, which removes the round-off that downdating accumulates;
        ``0`` never refreshes.
    check_every : int, optional
        Health check period (0 disables it; by default ``max(250, 32
        dim_x)``), with the semantics of
        :class:`~rlsfilt.RecursiveLeastSquares`: every `check_every`
        updates, and at the end of :meth:`batch_filter`, ``P`` is tested for
        symmetry, positive definiteness and its condition number (O(dim_x^3));
        every update also checks cheaply (O(dim_x)) that the diagonal of
        ``P`` is positive and finite. ``P`` becomes ill-conditioned when the
        rows in the window stop exciting some direction of the parameters
        (nearly collinear regressors), and downdating can cost it its
        definiteness. A failure issues one :class:`~rlsfilt.NumericalWarning`
        naming the update (and, in :meth:`batch_filter`, the step of the
        record).
    cond_max : float, default 1e12
        Condition number of ``P`` beyond which the health check warns.

    Attributes
    ----------
    x, P : ndarray
        Estimate ``(dim_x, dim_z)`` and covariance ``(dim_x, dim_x)``:
        :math:`P = (\sum_{k \in W} H_k^T H_k / R_k)^{-1}`.
    x_prior, P_prior, x_post, P_post, H, z, y, K, S, SI
        As in :class:`~rlsfilt.RecursiveLeastSquares`.
    exact : bool
        True once ``x`` is least squares on the window alone (the prior has
        been dropped).
    n_samples : int
        Number of samples currently in the window.
    n_updates : int
        Measurement updates since the last :meth:`reset` (the count the
        health warning names).

    Notes
    -----
    Adding a sample is the RLS update; removing the sample :math:`(H, z,
    R)` that leaves the window is its inverse, the downdate

    .. math::

        g &= P H^T, \qquad d = R - H g \\
        x &\leftarrow x - g (z - H x)^T / d \\
        P &\leftarrow P + g g^T / d

    (:math:`P^{-1} \leftarrow P^{-1} - H^T H / R`). :math:`d > 0` exactly
    when the remaining samples still determine every parameter; when it
    is not (clearly) positive the estimate is recomputed from the stored
    window instead. Until the window first holds `window` samples (or after
    :meth:`initialize`), the prior ``x0``, ``P0`` is part of the estimate
    (ridge regression); when it fills, the estimate is recomputed by QR
    from the window alone and is exact from then on (``exact`` is True). If
    the window then does not determine every parameter, the prior is kept
    and the exact start is tried again one window later. Downdating is the
    numerically delicate half (Haykin 2002, sec. 9; Alexander, Pan &
    Plemmons 1988), hence the periodic `refresh`. A step costs
    :math:`O(n^2)` (:math:`O(\text{window}\, n^2)` for a refit);
    :meth:`update`, :meth:`initialize` and :meth:`batch_filter` run
    compiled (numba) and give the same numbers bit for bit.

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
    .. [1] S. Haykin, *Adaptive Filter Theory*, 4th ed., Prentice Hall, 2002.
    .. [2] S. T. Alexander, C.-T. Pan and R. J. Plemmons, "Analysis of a
       recursive least squares hyperbolic rotation algorithm for signal
       processing", *Linear Algebra Appl.* 98, 3-40, 1988.
    .. [3] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 11.2.

    Examples
    --------
    A gain that changes halfway is tracked with a 50-sample memory:

    >>> import numpy as np
    >>> from rlsfilt import SlidingWindowRLS
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(400)
    >>> y = np.where(np.arange(400) < 200, 2.0, -1.0) * u + 0.01 * rng.standard_normal(400)
    >>> sw = SlidingWindowRLS(dim_x=1, window=50)
    >>> means, *_ = sw.batch_filter(y, u.reshape(-1, 1))
    >>> np.round([means[199, 0, 0], means[399, 0, 0]], 2)
    array([ 2., -1.])
    """

    _NO_FADING_MEMORY = "forgets by its window, not by a fading-memory factor"
    _HEALTH_ADVICE = ("The estimate may be unreliable: the samples in the window do not "
                      "excite every direction of the parameters; use a longer window or more "
                      "exciting input.")

    _options = _FilterBase._options | {"P", "refresh", "check_every", "cond_max"}

    # the ring buffer is written in place (a snapshot of the attributes copies it)
    _written_in_place = ("_wH", "_wZ", "_wR")

    def __init__(self, dim_x, window, dim_z=1, *, P0=1e4, x0=None, R=1.0, refresh=None,
                 check_every=None, cond_max=1e12):
        self.dim_x = check_dimension(dim_x, "dim_x")
        self.dim_z = check_int(dim_z, "dim_z", minimum=1)
        # the ring buffer: rows, measurements and variances, and the batch's copies of them
        self._window = check_length(window, "window", minimum=self.dim_x,
                                    bytes_per_item=16 * (self.dim_x + self.dim_z + 1))
        self.refresh = (10 * self.window if refresh is None
                        else check_int(refresh, "refresh", minimum=0))
        self.R = R
        self.check_every = check_every
        self.cond_max = check_real(cond_max, "cond_max", minimum=0, strict=True)
        self._batch_start = None      # n_updates at the start of a stepwise batch_filter
        self._P0 = check_covariance(P0, self.dim_x, "P0", definite=True)
        self._x0 = self._as_state(np.zeros((self.dim_x, self.dim_z)) if x0 is None else x0, "x0")
        # the prior rows of the refit (window_lstsq): L^T (x - x0) with L L^T = P0^-1
        self._Lt = np.ascontiguousarray(np.linalg.cholesky(np.linalg.inv(self._P0)).T)
        self._Ltx0 = self._Lt @ self._x0
        self.reset()

    # ------------------------------------------------------------------
    # state (assignments copy: the filter owns its arrays)
    # ------------------------------------------------------------------
    @property
    def x(self):
        """Estimate ``(dim_x, dim_z)``; assigning copies the value."""
        return self._x

    @x.setter
    @_locked
    def x(self, value):
        self._x = own_array(value, "x")

    @property
    def P(self):
        """Covariance ``(dim_x, dim_x)``; assigning copies the value."""
        return self._P

    @P.setter
    @_locked
    def P(self, value):
        self._P = own_array(value, "P")

    @property
    def window(self):
        """Number of samples in the window (read-only: the ring buffer's size, chosen
        at construction)."""
        return self._window

    @window.setter
    def window(self, value):
        refuse_fixed(self, "window", "it is the size of the ring buffer; construct a "
                                     "new SlidingWindowRLS(dim_x, window)")

    def __copy__(self):
        """A shallow copy with its own window: the compiled step writes the ring
        buffer in place, so two filters must never share it."""
        new = type(self).__new__(type(self))
        new.__dict__.update(self.__dict__)
        new._wH, new._wZ, new._wR = self._wH.copy(), self._wZ.copy(), self._wR.copy()
        return new

    @property
    def n_samples(self):
        """Number of samples currently in the window."""
        return self._nw

    @property
    def n_updates(self):
        """Measurement updates since the last :meth:`reset`."""
        return self._count

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    @_locked
    def predict(self, u=None, B=None, F=None):
        """Record ``x_prior`` and ``P_prior`` (the window has no time update).

        `u`, `B`, `F` are filterpy's control input, control matrix and state
        transition: any value but None raises a `TypeError` (``F = I``, no
        control input).
        """
        if u is not None or B is not None or F is not None:
            self._refuse_control(u, B, F)
        if self.frozen:                               # adaptation off: x, P unchanged
            return self._frozen_predict()
        self._checked_P()
        self.x_prior = self._checked_x().copy()
        self.P_prior = self.P.copy()

    @_locked
    def update(self, z, H=None, R=None):
        """Add sample ``(z, H)`` to the window and drop the oldest one.

        Parameters
        ----------
        z : float, array_like of shape (dim_z,), or None
            Measurement; ``None`` or NaN marks it missing: it takes a slot in
            the window and adds no information. Once the window is full the
            oldest sample still leaves it, so ``x`` and ``P`` change: they
            become least squares on the samples left in the window (a
            window one valid sample shorter).
        H : array_like, shape (dim_x,) or (1, dim_x), optional
            Regressor row; ``self.H`` if omitted (filterpy's convention). The
            row used is stored in ``self.H``.
        R : float, optional
            Noise variance of this sample.
        """
        if self.frozen:                               # adaptation off: only diagnostics
            return self._frozen_update(z, H, R)
        phi = self._as_regressor(self.H if H is None else H, "H")   # filterpy: self.H
        r = self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        n, m = self.dim_x, self.dim_z
        x = np.array(self._checked_x(), dtype=np.float64, order="C")
        P = np.array(self._checked_P(), dtype=np.float64, order="C")
        y, K = np.empty((m, 1)), np.empty((n, 1))
        zrow = np.full(m, np.nan) if zc is None else zc[:, 0]
        h = self._head                    # the slot the new sample overwrites
        leaving = (self._wH[h].copy(), self._wZ[h].copy(), self._wR[h])
        ist = self._int_state()
        # one compiled step (sw_update_kernel), on copies of x and P:
        #   y = z - H x,  S = H P H^T + R,  K = P H^T / S      update with the new sample
        #   x = x + K y^T,  P = P - K S K^T
        #   g = P H_old^T,  d = R_old - H_old g                 downdate with the leaving one
        #   x = x - g (z_old - H_old x)^T / d,  P = P + g g^T / d
        #   refit by QR of the window: d not clearly positive, window first full, `refresh`
        kern = _streaming.window_kernels()
        s, bad = kern.sw_update_kernel(x, P, phi[0], zrow, r, self._wH, self._wZ, self._wR, ist,
                                       int(self.refresh or 0), self._Lt, self._Ltx0,
                                       y[:, 0], K[:, 0])
        n_updates = int(ist[kern.COUNT])
        problem = None
        if self._health_due(n_updates, bad) and (bad or kern.unhealthy(P, self.cond_max)):
            problem = ((_health.symmetric_problem(P, self.cond_max) or "`P` failed the health "
                        "check") + _health.at_update(n_updates, self._batch_start))
        try:
            self._warn_health(problem)                # before the state changes
        except BaseException:
            self._wH[h], self._wZ[h], self._wR[h] = leaving   # the ring buffer as it was
            raise
        self._set_int_state(ist)
        self._clear_lazy()
        self.H = phi
        self.S, self.SI = s * self._I_z, self._I_z / s
        self.z, self.y, self.K = zrow.reshape(m, 1), y, K
        if zc is None:
            self._lazy = MISSING_DIAGNOSTICS
        self._x, self._P = x, P
        self.x_post, self.P_post = x.copy(), P.copy()

    def _int_state(self):
        """The ring-buffer counters as the kernels' ``ist`` array."""
        return np.array((self._head, self._nw, self._count, self._next_exact_try,
                         1 if self.exact else 0), dtype=np.int64)

    def _set_int_state(self, ist):
        self._head, self._nw, self._count, self._next_exact_try, exact = ist.tolist()
        self.exact = exact == 1

    @_locked
    def initialize(self, zs, Hs, Rs=None):
        """Start from exact least squares on the given samples.

        The last ``min(len(zs), window)`` samples become the window.

        Parameters
        ----------
        zs : array_like, shape (k0,) or (k0, dim_z)
            Measurements (NaN marks missing ones).
        Hs : array_like, shape (k0, dim_x)
            Regressor rows.
        Rs : float or array_like of shape (k0,), optional
            Noise variances (``R`` if omitted).

        Raises
        ------
        ValueError
            If the samples kept do not determine every parameter.
        """
        Z, Hm = self._as_batch(zs, Hs)
        Rv = self._as_batch_variances(Rs, len(Z))
        keep = slice(max(0, len(Z) - self.window), len(Z))
        k = len(Z[keep])
        n, m, w = self.dim_x, self.dim_z, self.window
        wH, wZ, wR = np.zeros((w, n)), np.full((w, m), np.nan), np.ones(w)
        wH[:k], wZ[:k], wR[:k] = Hm[keep], Z[keep], Rv[keep]
        x, P = np.empty((n, m)), np.empty((n, n))
        # exact least squares on the window by QR (the compiled refit of update)
        if not _streaming.window_kernels().window_lstsq(wH, wZ, wR, k, self._Lt, self._Ltx0, 0,
                                                        x, P):
            rank = np.linalg.matrix_rank(Hm[keep][~np.isnan(Z[keep]).any(axis=1)])
            raise ValueError(f"`Hs` is rank-deficient: the last {k} samples have "
                             f"rank {rank}; need {self.dim_x} (one per parameter)")
        self._wH, self._wZ, self._wR = wH, wZ, wR
        self._nw, self._head = k, k % w
        self._x, self._P = x, P
        self.exact = True
        self.x_prior, self.x_post = x.copy(), x.copy()
        self.P_prior, self.P_post = P.copy(), P.copy()

    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True):
        """Run the filter over a record; same arguments and returns as
        :meth:`RecursiveLeastSquares.batch_filter`.

        The window has no time update, so the predicted histories are the
        updated ones shifted by one step (equal to them with `update_first`):
        `means_p` and `covariances_p` are read-only views of the arrays
        `means` and `covariances` share, not copies."""
        return self._batch(zs, Hs, Rs, update_first, saver, store_covariances)

    def _batch_compiled(self, Z, Hm, Rv, update_first, store_covariances):
        """`batch_filter` in one compiled call, on copies of the state; leaves the
        filter as the step-by-step loop would (the same compiled step, bit for
        bit), and changes nothing if it raises."""
        N, n, m = len(Z), self.dim_x, self.dim_z
        x_start = np.array(self._checked_x(), dtype=np.float64, order="C")
        P_start = np.array(self._checked_P(), dtype=np.float64, order="C")
        x, P = x_start.copy(), P_start.copy()
        wH, wZ, wR = self._wH.copy(), self._wZ.copy(), self._wR.copy()
        # one buffer per history: row 0 the state before the record, row k + 1 the
        # state after update k; the window has no time update, so the predicted
        # histories are read-only views of the same buffers (shifted by one step
        # unless update_first): no copies of the record's histories
        means_buf = np.empty((N + 1, n, m))
        means_buf[0] = x_start
        means = means_buf[1:]
        covs_buf = np.empty((N + 1 if store_covariances else 1, n, n))
        covs_buf[0] = P_start
        covs = covs_buf[1:]
        y, K, P_last = np.empty(m), np.empty(n), np.empty((n, n))
        kern = _streaming.window_kernels()
        Rv = c_array(Rv[:1] if Rv.strides[0] == 0 else Rv)   # one variance: a length-1 array
        ist = self._int_state()
        step0 = self._count
        P_fail = np.empty((n, n))
        s, k_fail = kern.sw_batch_kernel(
            x, P, c_array(Z), c_array(Hm), Rv, wH, wZ, wR,
            ist, int(self.refresh or 0), self._Lt, self._Ltx0, means, covs, y, K, P_last,
            0 if self._warned_health else self.check_every, step0, float(self.cond_max),
            P_fail)
        problem = None
        if k_fail >= 0:
            problem = ((_health.symmetric_problem(P_fail, self.cond_max)
                        or "`P` failed the health check")
                       + _health.at_step(k_fail, step0 + k_fail + 1))
        elif not self._warned_health and self.check_every:    # the end-of-batch check
            problem = _health.symmetric_problem(P, self.cond_max)
            if problem is not None:
                problem += _health.at_update(step0 + N)
        self._warn_health(problem)                    # before the state changes
        self._wH, self._wZ, self._wR = wH, wZ, wR
        self._set_int_state(ist)
        # the window has no time update: the priors are the previous posteriors
        means_p = (means if update_first else means_buf[:-1]).view()
        means_p.flags.writeable = False
        covs_p = None
        if store_covariances:
            covs_p = (covs if update_first else covs_buf[:-1]).view()
            covs_p.flags.writeable = False
        if update_first:
            self.x_prior, self.P_prior = x.copy(), P.copy()
        else:
            self.x_prior = means_p[-1].copy()
            self.P_prior = covs_p[-1].copy() if store_covariances else P_last
        self._clear_lazy()
        self.H = Hm[-1].reshape(1, n).copy()
        self.S, self.SI = s * self._I_z, self._I_z / s
        self.z = Z[-1].reshape(m, 1).copy()
        self.y, self.K = y.reshape(m, 1), K.reshape(n, 1)
        if np.isnan(self.z).any():
            self.z[:] = np.nan
            self._lazy = MISSING_DIAGNOSTICS
        self._x, self._P = x, P
        self.x_post, self.P_post = x.copy(), P.copy()
        return means, (covs if store_covariances else None), means_p, covs_p

    # ------------------------------------------------------------------
    # helpers
    # ------------------------------------------------------------------
    def get_prediction(self):
        """Return ``(x, P)`` after a :meth:`predict` (unchanged: no time update)."""
        return self._checked_x().copy(), self._checked_P().copy()

    # ------------------------------------------------------------------
    # the filter contract (rlsfilt.filters.contract.Filter)
    # ------------------------------------------------------------------
    @_locked
    def get_state(self):
        """Copies of the state a resumed run needs: ``x``, ``P``, the window (rows,
        measurements, variances, oldest not first: a ring buffer from ``head``), its
        counters and the health check's memory (see `rlsfilt.filters.contract`)."""
        return {"x": self.x.copy(), "P": self.P.copy(), "window_H": self._wH.copy(),
                "window_z": self._wZ.copy(), "window_R": self._wR.copy(),
                "head": int(self._head), "n_samples": int(self._nw),
                "n_updates": int(self._count), "next_exact_try": int(self._next_exact_try),
                "exact": bool(self.exact), "warned_health": bool(self._warned_health)}

    @_locked
    def set_state(self, state):
        """Continue from `state`, a dict from :meth:`get_state` (copied)."""
        s = check_state(self, state)
        self.x, self.P = s["x"], s["P"]
        self._wH, self._wZ, self._wR = s["window_H"], s["window_z"], s["window_R"]
        self._head, self._nw, self._count = s["head"], s["n_samples"], s["n_updates"]
        self._next_exact_try, self.exact = s["next_exact_try"], s["exact"]
        self._warned_health = s["warned_health"]

    # ------------------------------------------------------------------
    # health of P
    # ------------------------------------------------------------------
    def _final_health_check(self):
        """The full check at the end of a step-by-step `batch_filter`."""
        if self._warned_health or not self.check_every:
            return
        problem = _health.symmetric_problem(self._checked_P(), self.cond_max)
        if problem is not None:
            self._warn_health(problem + _health.at_update(self._count))

    @_locked
    def reset(self):
        """Empty the window and return to ``x0``, ``P0``. Re-arms the health
        warning."""
        self._x = self._x0.copy()
        self._P = self._P0.copy()
        self.x_prior, self.P_prior = self._x.copy(), self._P.copy()
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        self._reset_diagnostics()
        self._clear_window()
        self._count = 0
        self._warned_health = False
        self._next_exact_try = 0
        self.exact = False

    def _clear_window(self):
        """Empty ring buffer: rows ``_wH``, measurements ``_wZ`` (NaN = missing), ``_wR``."""
        self._wH = np.zeros((self.window, self.dim_x))
        self._wZ = np.full((self.window, self.dim_z), np.nan)
        self._wR = np.ones(self.window)
        self._nw = 0
        self._head = 0

    def __repr__(self):
        return "\n".join([
            "SlidingWindowRLS object",
            pretty_str("dim_x", self.dim_x),
            pretty_str("dim_z", self.dim_z),
            pretty_str("window", self.window),
            pretty_str("n_samples", self.n_samples),
            pretty_str("exact", self.exact),
            pretty_str("x", self.x),
            pretty_str("P", self.P),
            pretty_str("R", self._R),
            pretty_str("y", self.y),
            pretty_str("K", self.K),
            pretty_str("S", self.S),
        ])
