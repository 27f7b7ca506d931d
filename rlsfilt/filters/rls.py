"""Recursive least squares as a filterpy-style filter.

`RecursiveLeastSquares` estimates the parameters ``x`` of the linear
regression ``z_k = H_k x + v_k`` one sample at a time. It is the Kalman
filter of a constant (or random-walk) parameter vector whose measurement
matrix is the regressor row ``H_k``, and it is written so that code written
for :class:`filterpy.kalman.KalmanFilter` runs on it unchanged where the
meaning is the same: ``predict()`` / ``update(z, H)`` / ``batch_filter``,
state ``x`` and ``P``, diagnostics ``y``, ``K``, ``S``, ``SI`` and the lazy
``log_likelihood``, ``likelihood`` and ``mahalanobis``.
"""

import copy
import math
import sys
import sysconfig
import warnings

import numpy as np
from filterpy.common import pretty_str
from scipy.linalg import solve_triangular

from .._validation import (
    as_float_array,
    check_covariance,
    check_finite,
    check_int,
    check_lam,
    check_variance,
)
from ..exceptions import ForgettingSkippedWarning

__all__ = ["RecursiveLeastSquares"]

_LOG_2PI = math.log(2.0 * math.pi)
_F8 = np.dtype(np.float64)

# Run batch_filter through the compiled kernels of `_kernels` (numba). The
# tests switch this off to compare with the pure-NumPy `_batch_reference`.
_COMPILED = True
_kernels = None


def _get_kernels():
    """Import the numba kernels on first use, so ``import rlsfilt`` stays light."""
    global _kernels
    if _kernels is None:
        from . import _kernels as k
        _kernels = k
    return _kernels


def _free_refcount():
    """What ``sys.getrefcount`` reports for an array nobody else can see.

    The streaming methods recycle the arrays of the previous step (``y``,
    ``K``, ``S``, ``x_prior``, ...) instead of allocating new ones, but only
    when the filter holds the sole references: one attribute, one private
    reference (a tuple or a second attribute) and the local variable. Any
    reference held elsewhere (a list of past estimates, a view, a Saver)
    raises the count and a fresh array is made, so no array a user can see
    ever changes. The count is measured here rather than assumed; recycling
    is off where it cannot be measured reliably (no ``getrefcount``, or a
    free-threaded build).
    """
    if not hasattr(sys, "getrefcount") or sysconfig.get_config_var("Py_GIL_DISABLED"):
        return None

    class _Holder:
        pass

    h = _Holder()
    h.y = np.empty(1)
    h.spare = (h.y,)
    (y,) = h.spare
    via_tuple = sys.getrefcount(y)
    h.P = np.empty(1)
    h.P_own = h.P
    P = h.P
    via_attribute = sys.getrefcount(P)
    return via_tuple if via_tuple == via_attribute else None


_FREE = _free_refcount()


class RecursiveLeastSquares:
    r"""Recursive least-squares estimator with a filterpy ``KalmanFilter`` API.

    Estimates ``x`` in the regression :math:`z_k = H_k x + v_k` where
    :math:`H_k` is the regressor row (the lecture notes' :math:`\phi_k`) and
    :math:`v_k` white noise of variance ``R``. With several outputs that
    share one regressor, ``x`` has one column per output and all columns
    share one covariance ``P``.

    Parameters
    ----------
    dim_x : int
        Number of parameters (length of the regressor row).
    dim_z : int, default 1
        Number of outputs sharing the regressor.
    lam : float, default 1.0
        Forgetting factor in (0, 1]. ``1`` is ordinary least squares; a
        sample ``j`` steps old is weighted by ``lam**j``, so the memory is
        about ``1 / (1 - lam)`` samples.
    P0 : float or array_like, default 1e4
        Initial covariance; a scalar means ``P0 * I`` (the broad prior of
        MATLAB's ``rarx``). Must be symmetric positive definite.
    x0 : array_like, optional
        Initial estimate, shape ``(dim_x,)`` or ``(dim_x, dim_z)``; zeros by
        default.
    R : float, default 1.0
        Measurement-noise variance, shared by all outputs.
    Q : float or array_like, default 0.0
        Covariance of the parameter random walk added in :meth:`predict`; a
        scalar means ``Q * I``.

    Attributes
    ----------
    x : ndarray, shape (dim_x, dim_z)
        Parameter estimate (one column per output).
    P : ndarray, shape (dim_x, dim_x)
        Covariance of the estimate (the notes' scaled inverse data matrix).
    x_prior, P_prior : ndarray
        Copies of ``x`` and ``P`` after the last :meth:`predict`.
    x_post, P_post : ndarray
        Copies of ``x`` and ``P`` after the last :meth:`update`.
    H : ndarray, shape (1, dim_x)
        Regressor row used by the last update.
    z : ndarray, shape (dim_z, 1)
        Last measurement (NaN when it was missing).
    y : ndarray, shape (dim_z, 1)
        A-priori residual :math:`z - H x^-` of the last update (NaN when the
        measurement was missing).
    K : ndarray, shape (dim_x, 1)
        Gain of the last update (zeros when the measurement was missing).
    S, SI : ndarray, shape (dim_z, dim_z)
        Innovation covariance :math:`(H P^- H^T + R) I` and its inverse.
    dim_x, dim_z : int
        Dimensions given at construction.

    Notes
    -----
    One step of the recursion (Ljung 1999, sec. 11.2; Astrom & Wittenmark
    1995, sec. 2.2), with :math:`\lambda` the forgetting factor and ``Q`` the
    random walk, split as in a Kalman filter into a time update
    (:meth:`predict`) and a measurement update (:meth:`update`):

    .. math::

        P^- &= P / \lambda + Q \\
        y &= z - H x^- \\
        S &= H P^- H^T + R \\
        K &= P^- H^T / S \\
        x &= x^- + K y^T \\
        P &= P^- - (P^- H^T)(P^- H^T)^T / S

    The last line is the matrix inversion lemma applied to
    :math:`P^{-1} = (P^-)^{-1} + H^T H / R` (the notes' formula (1)); it is
    evaluated as a symmetric outer product, so ``P`` stays exactly symmetric
    and no inverse of ``P`` is ever formed. With ``R = 1``, ``lam = 1``,
    ``Q = 0`` and the batch start of :meth:`initialize`, the estimate equals
    ordinary least squares on all data so far at every step; with
    ``lam < 1`` it is exponentially weighted least squares, and
    ``y / sqrt(S)`` is the recursive residual of Brown, Durbin & Evans (1975).

    Missing measurements (``z is None`` or any NaN in ``z``) keep the
    estimate (posterior = prior), as filterpy and statsmodels do. Then ``y``
    and ``z`` are NaN, ``K`` is zero, ``S`` is the predictive variance of the
    missing measurement, and ``log_likelihood`` is 0 (a missing sample adds
    nothing to the log-likelihood). Because the outputs share ``P``, one NaN
    in a multi-output ``z`` makes the whole sample missing.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, ch. 11.
    .. [2] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 2.
    .. [3] S. Haykin, *Adaptive Filter Theory*, 4th ed., Prentice Hall, 2002,
       ch. 9.
    .. [4] R. L. Brown, J. Durbin and J. M. Evans, "Techniques for testing the
       constancy of regression relationships over time", *J. R. Stat. Soc.
       B* 37(2), 1975.

    Examples
    --------
    Identify ``y[k] = 0.8 y[k-1] + 0.5 u[k-1]`` from noisy data:

    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(500)
    >>> y = np.zeros(500)
    >>> for k in range(1, 500):
    ...     y[k] = 0.8 * y[k - 1] + 0.5 * u[k - 1] + 0.01 * rng.standard_normal()
    >>> rls = RecursiveLeastSquares(dim_x=2)
    >>> for k in range(1, 500):
    ...     rls.predict_update(y[k], H=[y[k - 1], u[k - 1]])
    >>> np.round(rls.x.ravel(), 2)
    array([0.8, 0.5])
    """

    # Bookkeeping of the streaming fast path lives in slots, outside
    # ``__dict__``, so that filterpy's Saver (which records every entry of
    # ``__dict__``) sees only the filter's state.
    __slots__ = ("__dict__", "__weakref__", "_x_own", "_P_own", "_spare_prior", "_spare_update",
                 "_row", "_row2")

    def __init__(self, dim_x, dim_z=1, lam=1.0, *, P0=1e4, x0=None, R=1.0, Q=0.0):
        self.dim_x = check_int(dim_x, "dim_x", minimum=1)
        self.dim_z = check_int(dim_z, "dim_z", minimum=1)
        self.lam = lam
        self.R = R
        self.Q = Q
        self._P0 = check_covariance(P0, self.dim_x, "P0", definite=True)
        self._x0 = self._as_state(np.zeros((self.dim_x, self.dim_z)) if x0 is None else x0, "x0")
        self._warned_skip = False
        self._row, self._row2 = (self.dim_x,), (1, self.dim_x)   # regressor shapes
        self.reset()

    # ------------------------------------------------------------------
    # configuration, validated once on assignment
    # ------------------------------------------------------------------
    @property
    def lam(self):
        """Forgetting factor in (0, 1]."""
        return self._lam

    @lam.setter
    def lam(self, value):
        self._lam = check_lam(value)

    @property
    def R(self):
        """Measurement-noise variance (a positive float)."""
        return self._R

    @R.setter
    def R(self, value):
        self._R = check_variance(value, "R")

    @property
    def Q(self):
        """Parameter random-walk covariance, ``(dim_x, dim_x)``."""
        return self._Q

    @Q.setter
    def Q(self, value):
        self._Q = check_covariance(value, self.dim_x, "Q")
        self._Q_is_zero = not self._Q.any()

    # ------------------------------------------------------------------
    # lazily computed diagnostics, as in filterpy
    # ------------------------------------------------------------------
    @property
    def log_likelihood(self):
        """Log-likelihood of the last measurement, ``log N(y; 0, S)``."""
        if self._log_likelihood is None:
            self._log_likelihood = _gaussian_logpdf(self.y, self.S[0, 0])
        return self._log_likelihood

    @property
    def likelihood(self):
        """``exp(log_likelihood)``, floored at the smallest positive float."""
        if self._likelihood is None:
            self._likelihood = max(math.exp(self.log_likelihood), np.finfo(float).tiny)
        return self._likelihood

    @property
    def mahalanobis(self):
        """Mahalanobis distance ``sqrt(y^T S^-1 y)`` of the last residual."""
        if self._mahalanobis is None:
            self._mahalanobis = math.sqrt(float(np.vdot(self.y, self.y)) / self.S[0, 0])
        return self._mahalanobis

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    def predict(self, Q=None):
        r"""Time update :math:`P \leftarrow P / \lambda + Q`.

        The estimate ``x`` is unchanged (constant or random-walk
        parameters). With ``lam = 1`` and ``Q = 0`` this only records
        ``x_prior`` and ``P_prior``.

        Parameters
        ----------
        Q : float or array_like, optional
            Random-walk covariance for this call only; ``self.Q`` if omitted.
        """
        if Q is None:
            Q, q_zero = self._Q, self._Q_is_zero
        else:
            Q = check_covariance(Q, self.dim_x, "Q")
            q_zero = not Q.any()
        x, P = self.x, self.P
        rc = sys.getrefcount
        x_prior, P_prior = self._spare_prior
        # Nobody else holds P or the last priors (the usual case, see
        # _free_refcount): P^- overwrites P, the priors are rewritten in place.
        recycled = (x is self._x_own and P is self._P_own and rc(P) == _FREE
                    and rc(x_prior) == _FREE and rc(P_prior) == _FREE)
        if recycled:
            Pn = P
        else:
            n = self.dim_x
            x = np.ascontiguousarray(self._checked_x(), dtype=float)
            P = np.ascontiguousarray(self._checked_P(), dtype=float)
            Pn, x_prior, P_prior = np.empty((n, n)), np.empty((n, self.dim_z)), np.empty((n, n))
        (_kernels or _get_kernels()).predict_kernel(
            x, P, 1.0 / self._lam, Q, q_zero, Pn, x_prior, P_prior)
        if not recycled:
            self.x = self._x_own = x
            self.P = self._P_own = Pn
            self.x_prior, self.P_prior = self._spare_prior = x_prior, P_prior
        self._updates_since_predict = 0

    def update(self, z, H, R=None):
        r"""Measurement update with regressor row `H`.

        Parameters
        ----------
        z : float, array_like of shape (dim_z,), or None
            Measurement. ``None`` or any NaN marks it missing: the estimate
            is kept (posterior = prior).
        H : array_like, shape (dim_x,) or (1, dim_x)
            Regressor row (the notes' :math:`\phi_k`).
        R : float, optional
            Measurement-noise variance for this call only.
        """
        # The common case (a float64 row, a float measurement, the filter's
        # own x and P) skips the conversions; the arithmetic is the compiled
        # step that batch_filter runs, so both agree bit for bit.
        n, m = self.dim_x, self.dim_z
        if type(H) is np.ndarray and H.dtype is _F8 and H.shape == self._row:
            phi = H
        elif type(H) is np.ndarray and H.dtype is _F8 and H.shape == self._row2:
            phi = H.reshape(n)
        else:
            phi = self._as_regressor(H, "H").reshape(n)
        r = self._R if R is None else check_variance(R, "R")
        zf = m == 1 and isinstance(z, float)
        if zf:
            missing = z != z
            if not missing and z - z != 0.0:
                self._as_measurement(z, "z")            # raises: z is inf
        else:
            zvalue = self._as_measurement(z, "z")
            missing = zvalue is None
        x, P = self.x, self.P
        rc = sys.getrefcount
        y, K, S, SI, Hc, zc, x_post, P_post = self._spare_update
        # Nobody else holds x, P or the last step's diagnostics (the usual
        # case, see _free_refcount): update them in place, no allocations.
        recycled = (x is self._x_own and P is self._P_own and (zf or missing)
                    and rc(x) == _FREE and rc(P) == _FREE and rc(y) == _FREE
                    and rc(K) == _FREE and rc(S) == _FREE and rc(SI) == _FREE
                    and rc(Hc) == _FREE and rc(zc) == _FREE and rc(x_post) == _FREE
                    and rc(P_post) == _FREE)
        if recycled:
            xn, Pn = x, P
        else:
            if x is not self._x_own:
                x = np.ascontiguousarray(self._checked_x(), dtype=float)
            if P is not self._P_own:
                P = np.ascontiguousarray(self._checked_P(), dtype=float)
            xn, Pn = np.empty((n, m)), np.empty((n, n))
            y, K, S, SI = np.empty((m, 1)), np.empty((n, 1)), np.empty((m, m)), np.empty((m, m))
            Hc, x_post, P_post = np.empty((1, n)), np.empty((n, m)), np.empty((n, n))
            if zf or missing:                # the kernel writes z (or NaN) into zc
                zc = np.empty((m, 1))
            else:
                zc = zvalue
        zmode, z0 = (2, 0.0) if missing else ((1, z) if zf else (0, 0.0))
        s = (_kernels or _get_kernels()).update_kernel(
            x, P, phi, zc, z0, zmode, r, xn, Pn, y, K, S, SI, Hc, x_post, P_post)
        if s != s:
            check_finite(phi, "H")                   # raises: H is not finite
        if self._updates_since_predict:
            self._note_update()
        else:
            self._updates_since_predict = 1
        if missing:
            self._log_likelihood, self._likelihood, self._mahalanobis = 0.0, 1.0, None
        else:
            self._log_likelihood = self._likelihood = self._mahalanobis = None
        if not recycled:
            self._spare_update = (y, K, S, SI, Hc, zc, x_post, P_post)
            self.H, self.z, self.S, self.SI, self.y, self.K = Hc, zc, S, SI, y, K
            self.x = self._x_own = xn
            self.P = self._P_own = Pn
            self.x_post, self.P_post = x_post, P_post

    def predict_update(self, z, H, R=None):
        """One textbook RLS step: :meth:`predict` then :meth:`update`."""
        self.predict()
        self.update(z, H, R)

    # ------------------------------------------------------------------
    # batch start and batch runs
    # ------------------------------------------------------------------
    def initialize(self, zs, Hs):
        r"""Start the filter from batch least squares on the first samples.

        This is step 1 of the lecture notes: with the first ``k0`` samples
        stacked as :math:`Z = \Phi x + V`, set

        .. math::

            x = (\Phi^T \Phi)^{-1} \Phi^T Z, \qquad P = R\,(\Phi^T \Phi)^{-1},

        both computed from the QR factorization :math:`\Phi = Q_1 R_1`
        (:math:`x = R_1^{-1} Q_1^T Z`, :math:`P = R\,R_1^{-1} R_1^{-T}`),
        never from the normal equations, which square the condition number.
        After it, updates with ``lam = 1`` reproduce batch least squares on
        all data so far at every step. With ``lam < 1`` row ``i`` of
        ``k0`` is weighted by ``lam**(k0 - 1 - i)``, so later steps reproduce
        exponentially weighted least squares. Rows whose measurement is
        missing (NaN) are dropped.

        Parameters
        ----------
        zs : array_like, shape (k0,) or (k0, dim_z)
            Measurements.
        Hs : array_like, shape (k0, dim_x)
            Regressor rows.

        Raises
        ------
        ValueError
            If the regressor rows do not determine every parameter (fewer
            independent rows than ``dim_x``).
        """
        Z, Hm = self._as_batch(zs, Hs)
        w = self._lam ** (0.5 * np.arange(len(Z) - 1, -1, -1.0))
        keep = ~np.isnan(Z).any(axis=1)
        A = Hm[keep] * w[keep, None]
        B = Z[keep] * w[keep, None]
        rank = np.linalg.matrix_rank(A) if len(A) else 0
        if rank < self.dim_x:
            raise ValueError(
                f"`Hs` is rank-deficient: found {rank} linearly independent rows in "
                f"{len(A)} usable samples; need {self.dim_x} (one per parameter). Use more "
                "samples or a more exciting input."
            )
        Qf, Rf = np.linalg.qr(A)
        self.x = solve_triangular(Rf, Qf.T @ B)
        Rinv = solve_triangular(Rf, np.eye(self.dim_x))
        P = self._R * (Rinv @ Rinv.T)
        self.P = 0.5 * (P + P.T)
        self.x_prior = self.x_post = self.x.copy()
        self.P_prior = self.P_post = self.P.copy()
        self._updates_since_predict = 0

    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True):
        r"""Run the filter over a whole record.

        Parameters
        ----------
        zs : array_like, shape (N,) or (N, dim_z), or a list with None
            Measurements; ``None`` or NaN marks a missing sample.
        Hs : array_like, shape (N, dim_x) or (N, 1, dim_x)
            Regressor rows, one per measurement.
        Rs : float or array_like of shape (N,), optional
            Measurement-noise variance per step (``self.R`` if omitted).
        update_first : bool, default False
            Update then predict in each step instead of predict then update.
        saver : filterpy.common.Saver, optional
            Its ``save()`` is called after each step.
        store_covariances : bool, default True
            With ``False`` the covariance histories are not stored (they are
            returned as ``None``), so memory stays O(N dim_x dim_z).

        Returns
        -------
        means : ndarray, shape (N, dim_x, dim_z)
            Estimates after each update.
        covariances : ndarray, shape (N, dim_x, dim_x), or None
            ``P`` after each update.
        means_p : ndarray, shape (N, dim_x, dim_z)
            Estimates after each predict.
        covariances_p : ndarray, shape (N, dim_x, dim_x), or None
            ``P`` after each predict.

        Raises
        ------
        ValueError
            If `zs`, `Hs` (and `Rs`) disagree in length; filterpy's
            ``KalmanFilter`` would silently truncate.

        Notes
        -----
        The loop runs in compiled code (numba, cached on disk after the
        first call): one sweep over ``P`` per step applies the update, the
        next forgetting step and the next gain together, so a step costs
        about :math:`6\,n^2` floating-point operations for ``n = dim_x`` and
        the record is processed at tens of nanoseconds per sample for small
        ``n`` (see ``docs/performance.md``). The results equal the
        step-by-step :meth:`predict`/:meth:`update` loop bit for bit.
        """
        Z, Hm = self._as_batch(zs, Hs)
        Rv = self._as_batch_variances(Rs, len(Z))
        if saver is not None:
            return self._batch_stepwise(Z, Hm, Rv, update_first, saver, store_covariances)
        run = _get_kernels().batch_compiled if _COMPILED else _batch_reference
        out = run(self._checked_x(), self._checked_P(), Z, Hm, Rv, self._lam,
                  None if self._Q_is_zero else self._Q, update_first, store_covariances)
        self._adopt_last_step(out, Hm, Z, Rv, update_first)
        return out.means, out.covariances, out.means_p, out.covariances_p

    def _batch_stepwise(self, Z, Hm, Rv, update_first, saver, store_covariances):
        N = len(Z)
        means = np.empty((N, self.dim_x, self.dim_z))
        means_p = np.empty_like(means)
        covs = np.empty((N, self.dim_x, self.dim_x)) if store_covariances else None
        covs_p = np.empty_like(covs) if store_covariances else None
        for k in range(N):
            if not update_first:
                self.predict()
                means_p[k] = self.x
                if store_covariances:
                    covs_p[k] = self.P
            self.update(Z[k], Hm[k], Rv[k])
            means[k] = self.x
            if store_covariances:
                covs[k] = self.P
            if update_first:
                self.predict()
                means_p[k] = self.x
                if store_covariances:
                    covs_p[k] = self.P
            saver.save()
        return means, covs, means_p, covs_p

    def _adopt_last_step(self, out, Hm, Z, Rv, update_first):
        """Leave the filter as the step-by-step loop would have left it."""
        self.x, self.P = self._x_own, self._P_own = out.x, out.P
        if len(Z) == 0:
            return
        self._clear_lazy()
        self.H = Hm[-1].reshape(1, -1).copy()
        s = out.s_last
        self.S, self.SI = s * self._I_z, self._I_z / s
        if np.isnan(Z[-1]).any():
            self.z = np.full((self.dim_z, 1), np.nan)
            self.y = np.full((self.dim_z, 1), np.nan)
            self.K = np.zeros((self.dim_x, 1))
            self._log_likelihood, self._likelihood = 0.0, 1.0
        else:
            self.z = Z[-1].reshape(-1, 1).copy()
            self.y = out.y_last.reshape(-1, 1)
            self.K = out.K_last.reshape(-1, 1)
        self.x_post = out.x_post
        self.P_post = out.P_post
        self.x_prior = out.x_prior
        self.P_prior = out.P_prior
        self._updates_since_predict = 0 if update_first else 1

    # ------------------------------------------------------------------
    # filterpy helpers
    # ------------------------------------------------------------------
    def get_prediction(self):
        """Return ``(x, P)`` after a :meth:`predict`, without changing the filter."""
        P = _predict_covariance(self._checked_P(), self._lam,
                                None if self._Q_is_zero else self._Q)
        return self._checked_x().copy(), P.copy()

    def residual_of(self, z, H):
        """A-priori residual ``z - H x`` for `z` and regressor `H`, shape ``(dim_z, 1)``."""
        zc = self._as_measurement(z, "z")
        if zc is None:
            raise ValueError("`z` must be a measurement to form a residual; got a missing value")
        return zc - self.measurement_of_state(self.x, H)

    def measurement_of_state(self, x, H):
        """Predicted measurement ``H x`` as a column ``(dim_z, 1)``."""
        phi = self._as_regressor(H, "H")
        return (phi @ self._as_state(x, "x")).T

    def log_likelihood_of(self, z, H, R=None):
        """Log-likelihood of measurement `z` with regressor `H` under the current state."""
        phi = self._as_regressor(H, "H")
        r = self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        if zc is None:
            return 0.0
        _, s = _innovation(self._checked_P(), phi, r)
        return _gaussian_logpdf(zc - (phi @ self._checked_x()).T, s)

    def copy(self):
        """Return an independent deep copy of the filter."""
        return copy.deepcopy(self)

    def reset(self):
        """Return to the state given at construction (``x0``, ``P0``).

        ``lam``, ``R`` and ``Q`` are kept; diagnostics are cleared.
        """
        n, m = self.dim_x, self.dim_z
        self.x = self._x_own = self._x0.copy()
        self.P = self._P_own = self._P0.copy()
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        self.H = np.zeros((1, n))
        self.z = np.zeros((m, 1))
        self.y = np.zeros((m, 1))
        self.K = np.zeros((n, 1))
        self._I_z = np.eye(m)
        self.S = np.zeros((m, m))
        self.SI = np.zeros((m, m))
        # arrays the streaming methods may overwrite when nobody else holds them
        self._spare_prior = (self.x_prior, self.P_prior)
        self._spare_update = (self.y, self.K, self.S, self.SI, self.H, self.z, self.x_post,
                              self.P_post)
        self._updates_since_predict = 0
        # before any update, as filterpy: nothing observed yet
        self._log_likelihood = math.log(np.finfo(float).tiny)
        self._likelihood = np.finfo(float).tiny
        self._mahalanobis = 0.0

    def __repr__(self):
        return "\n".join([
            "RecursiveLeastSquares object",
            pretty_str("dim_x", self.dim_x),
            pretty_str("dim_z", self.dim_z),
            pretty_str("lam", self._lam),
            pretty_str("x", self.x),
            pretty_str("P", self.P),
            pretty_str("x_prior", self.x_prior),
            pretty_str("P_prior", self.P_prior),
            pretty_str("x_post", self.x_post),
            pretty_str("P_post", self.P_post),
            pretty_str("Q", self._Q),
            pretty_str("R", self._R),
            pretty_str("H", self.H),
            pretty_str("K", self.K),
            pretty_str("y", self.y),
            pretty_str("S", self.S),
            pretty_str("SI", self.SI),
            pretty_str("log-likelihood", self.log_likelihood),
            pretty_str("likelihood", self.likelihood),
            pretty_str("mahalanobis", self.mahalanobis),
        ])

    # ------------------------------------------------------------------
    # private helpers
    # ------------------------------------------------------------------
    def _clear_lazy(self):
        self._log_likelihood = None
        self._likelihood = None
        self._mahalanobis = None

    def _note_update(self):
        """Warn once when forgetting is skipped by two updates in a row."""
        if (self._updates_since_predict and not self._warned_skip
                and (self._lam < 1.0 or not self._Q_is_zero)):
            self._warned_skip = True
            warnings.warn(
                "update() was called twice without predict() in between, so the forgetting "
                "(lam < 1) or random walk (Q > 0) of this step was skipped; call predict() "
                "before each update() or use predict_update().",
                ForgettingSkippedWarning, stacklevel=3)
        self._updates_since_predict += 1

    def _as_regressor(self, H, name):
        if type(H) is np.ndarray and H.dtype == np.float64:
            phi = H
        else:
            phi = as_float_array(H, name)
        n = self.dim_x
        if phi.shape == (n,) or phi.shape == (1, n) or (n == 1 and phi.ndim == 0):
            phi = phi.reshape(1, n)
        else:
            raise ValueError(f"`{name}` must have shape ({n},) or (1, {n}) (one regressor row of "
                             f"dim_x = {n} entries); got shape {phi.shape}")
        if not np.isfinite(phi).all():
            check_finite(phi.ravel(), name)
        return phi.copy()

    def _as_measurement(self, z, name):
        """Return `z` as a new ``(dim_z, 1)`` column, or None when missing."""
        if z is None:
            return None
        zz = as_float_array(z, name)
        m = self.dim_z
        if zz.size != m or not (zz.ndim == 0 or zz.shape in ((m,), (m, 1), (1, 1))):
            raise ValueError(f"`{name}` must be a scalar or have shape ({m},) (dim_z = {m}); "
                             f"got shape {zz.shape}")
        if np.isnan(zz).any():
            return None
        if np.isinf(zz).any():
            raise ValueError(f"`{name}` must be finite or NaN (missing); got {zz.ravel()}")
        return zz.reshape(m, 1).copy()

    def _as_state(self, x, name):
        arr = as_float_array(x, name)
        n, m = self.dim_x, self.dim_z
        if m == 1 and arr.shape == (n,):
            arr = arr.reshape(n, 1)
        if arr.shape != (n, m):
            raise ValueError(f"`{name}` must have shape ({n}, {m}); got {arr.shape}")
        return check_finite(arr.copy(), name)

    def _checked_x(self):
        x = self.x
        if not isinstance(x, np.ndarray) or x.shape != (self.dim_x, self.dim_z):
            raise ValueError(
                f"`x` must be an array of shape ({self.dim_x}, {self.dim_z}); got "
                f"{getattr(x, 'shape', type(x).__name__)}. Assign the estimate as a column, "
                "e.g. rls.x = x.reshape(-1, 1).")
        return x

    def _checked_P(self):
        P = self.P
        if not isinstance(P, np.ndarray) or P.shape != (self.dim_x, self.dim_x):
            raise ValueError(f"`P` must be an array of shape ({self.dim_x}, {self.dim_x}); got "
                             f"{getattr(P, 'shape', type(P).__name__)}")
        return P

    def _as_batch(self, zs, Hs):
        """Validate a record: ``Z`` (N, dim_z) with NaN for missing, ``H`` (N, dim_x)."""
        n, m = self.dim_x, self.dim_z
        if isinstance(zs, np.ndarray) or not any(v is None for v in zs):
            Z = as_float_array(zs, "zs")
        else:  # a list with None entries for missing samples
            Z = np.array([np.full(m, np.nan) if v is None
                          else as_float_array(v, "zs").reshape(-1) for v in zs])
        if Z.ndim == 1 and m == 1:
            Z = Z.reshape(-1, 1)
        elif Z.ndim == 3 and Z.shape[2] == 1:
            Z = Z[:, :, 0]
        if Z.ndim != 2 or Z.shape[1] != m:
            raise ValueError(f"`zs` must have shape (N,) or (N, {m}) (dim_z = {m}); got {Z.shape}")
        Hm = as_float_array(Hs, "Hs")
        if Hm.ndim == 3 and Hm.shape[1] == 1:
            Hm = Hm[:, 0, :]
        if Hm.ndim != 2 or Hm.shape[1] != n:
            raise ValueError(f"`Hs` must have shape (N, {n}) (dim_x = {n}); got {Hm.shape}")
        if len(Hm) != len(Z):
            raise ValueError(f"`zs` and `Hs` must have the same length; got {len(Z)} measurements "
                             f"and {len(Hm)} regressor rows")
        # one summation pass screens long records; the exact checks run only
        # when the sum is not finite (a bad entry, or an overflow)
        if not np.isfinite(Hm.sum()):
            check_finite(Hm, "Hs")
        if not np.isfinite(Z.sum()) and np.isinf(Z).any():
            check_finite(np.where(np.isnan(Z), 0.0, Z), "zs")
        return Z, Hm                    # read only below: no copies of long records

    def _as_batch_variances(self, Rs, N):
        # one shared variance is a read-only broadcast view: no O(N) array
        if Rs is None:
            return np.broadcast_to(self._R, (N,))
        arr = as_float_array(Rs, "Rs")
        if arr.ndim == 0:
            return np.broadcast_to(check_variance(arr, "Rs"), (N,))
        if arr.ndim == 3 and arr.shape[1:] == (1, 1):
            arr = arr.reshape(-1)
        if arr.ndim != 1 or len(arr) != N:
            raise ValueError(f"`Rs` must be a scalar or have shape ({N},) (one variance per "
                             f"measurement); got {arr.shape}")
        bad = ~(np.isfinite(arr) & (arr > 0))
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"`Rs` must hold positive finite variances; got {arr[i]} at index {i}")
        return arr.copy()


# ----------------------------------------------------------------------
# The arithmetic of one step, shared by the methods and the batch loop so
# that the two cannot drift apart.
# ----------------------------------------------------------------------
def _predict_covariance(P, lam, Q):
    """``P / lam + Q`` as a new array (Q None means zero)."""
    P = P * (1.0 / lam) if lam != 1.0 else P.copy()
    if Q is not None:
        P += Q
    return P


def _innovation(P, phi, r):
    """``g = P phi^T`` (dim_x, 1) and the scalar ``s = phi P phi^T + r``."""
    g = P @ phi.T
    return g, (phi @ g).item() + r


def _apply_update(x, P, phi, z, g, s):
    """Measurement update; returns new ``x, P, y, K``."""
    y = z - (phi @ x).T                    # y = z - H x          (dim_z, 1)
    K = g / s                              # K = P H^T / S         (dim_x, 1)
    x = x + K * y.T                        # x = x + K y^T         (dim_x, dim_z)
    P = P - np.outer(g, g) / s             # P = P - g g^T / S     exactly symmetric
    return x, P, y, K


def _gaussian_logpdf(y, s):
    """``log N(y; 0, s I)`` for a residual column `y` and scalar variance `s`."""
    m = y.size
    return -0.5 * (m * (_LOG_2PI + math.log(s)) + float(np.vdot(y, y)) / s)


class _BatchResult:
    __slots__ = ("means", "covariances", "means_p", "covariances_p", "ys", "ss",
                 "x", "P", "x_prior", "P_prior", "x_post", "P_post", "y_last", "K_last",
                 "s_last")


def _batch_reference(x, P, Z, Hm, Rv, lam, Q, update_first, store_covariances):
    """Pure-NumPy batch recursion (the reference path for compiled kernels).

    Returns a `_BatchResult` with the histories, the recursive residuals
    ``ys`` (N, dim_z) and innovation variances ``ss`` (N,), and the last
    step's state.
    """
    N = len(Z)
    n, m = x.shape
    out = _BatchResult()
    out.means = np.empty((N, n, m))
    out.means_p = np.empty((N, n, m))
    out.covariances = np.empty((N, n, n)) if store_covariances else None
    out.covariances_p = np.empty((N, n, n)) if store_covariances else None
    out.ys = np.full((N, m), np.nan)
    out.ss = np.empty(N)
    x_prior, P_prior = x, P
    K = np.zeros((n, 1))
    s = np.nan
    for k in range(N):
        if not update_first:
            P = _predict_covariance(P, lam, Q)
            x_prior, P_prior = x, P
            out.means_p[k] = x
            if store_covariances:
                out.covariances_p[k] = P
        phi = Hm[k:k + 1]
        g, s = _innovation(P, phi, Rv[k])
        out.ss[k] = s
        z = Z[k]
        if not np.isnan(z).any():
            x, P, y, K = _apply_update(x, P, phi, z.reshape(m, 1), g, s)
            out.ys[k] = y[:, 0]
        x_post, P_post = x, P
        out.means[k] = x
        if store_covariances:
            out.covariances[k] = P
        if update_first:
            P = _predict_covariance(P, lam, Q)
            x_prior, P_prior = x, P
            out.means_p[k] = x
            if store_covariances:
                out.covariances_p[k] = P
    out.x, out.P = x.copy(), P.copy()
    if N:
        out.x_prior, out.P_prior = x_prior.copy(), P_prior.copy()
        out.x_post, out.P_post = x_post.copy(), P_post.copy()
        out.y_last, out.K_last, out.s_last = out.ys[-1].copy(), K.copy(), s
    return out
