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

import functools
import math
import sys
import sysconfig
import warnings

import numpy as np
from filterpy.common import pretty_str
from scipy.linalg import null_space, solve_triangular

from .._validation import (
    as_float_array,
    check_covariance,
    check_finite,
    check_int,
    check_lam,
    check_scalar,
    check_variance,
)
from ..exceptions import ForgettingSkippedWarning, NumericalWarning
from . import forgetting as _fg
from ._base import _FilterBase, _innovation

__all__ = ["RecursiveLeastSquares"]

_F8 = np.dtype(np.float64)
# (without getrefcount, or with _FREE None, no array compares equal: no recycling)
_getrefcount = getattr(sys, "getrefcount", lambda obj: -1)

# Run batch_filter, predict and update through the compiled kernels of
# `_kernels` (numba), for every mode and option. The tests switch this off to
# compare with the pure-NumPy reference (`_batch_reference`,
# `_measurement_step`, `forgetting.update_<mode>`).
_COMPILED = True
_kernels = None
_EXPONENTIAL = _fg.EXPONENTIAL    # the mode of the fused fast paths
_EMPTY2 = np.zeros((0, 0))        # stands for an absent Q or projector in kernel calls


def _get_kernels():
    """Import the numba kernels on first use, so ``import rlsfilt`` stays light."""
    global _kernels
    if _kernels is None:
        from . import _kernels as k
        _kernels = k
    return _kernels


# Compiled entry points of `predict_kernel` and `update_kernel` for the
# argument types of the recycling fast path (see `_entry_point`).
_predict_entry = None
_update_entry = None


def _entry_point(dispatcher, args):
    """The compiled function of `dispatcher` for exactly the types of `args`, or None.

    Calling a numba dispatcher first types every argument to choose the
    compiled overload, about 70 ns per argument: most of the cost of a
    streaming step at small ``dim_x``. The streaming fast path calls the
    overload's entry point directly instead, and only with arguments whose
    types cannot differ from the ones it was resolved for: the filter's own
    C-contiguous float64 arrays and a regressor checked with
    ``flags.carray``. None (use the dispatcher) when numba does not expose
    the overload.
    """
    try:
        from numba import typeof

        sig = tuple(typeof(a) for a in args)
        return dispatcher.overloads[sig].entry_point
    except Exception:       # pragma: no cover - numba internals changed
        return None


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


def _set_entries(predict=None, update=None):
    global _predict_entry, _update_entry
    if predict is not None:
        _predict_entry = predict
    if update is not None:
        _update_entry = update


class RecursiveLeastSquares(_FilterBase):
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
    forgetting : {"exponential", "directional", "constant_trace", "efra", "variable"}, optional
        How old data is forgotten (see Notes); ``"exponential"`` by
        default. ``"exponential"`` divides
        ``P`` by `lam` in :meth:`predict` (filterpy's fading memory); the
        others forget inside :meth:`update`, because they need the step's
        regressor or residual, and bound ``P`` when the input stops
        exciting the system (no covariance windup).
    forgetting_params : dict, optional
        Constants of the chosen mode: ``"directional"``: ``eps`` (1e-12,
        smallest ``phi P phi^T / R`` that triggers forgetting);
        ``"constant_trace"``: ``trace`` (``dim_x * R * (1 - lam)`` with the
        `R` and `lam` given at construction: the trace plain forgetting
        settles at for white unit-power regressors; scale it by the inverse
        regressor power) and
        ``ratio`` (1e4, ``c1 / c2`` and so about the largest ``cond(P)``);
        ``"efra"``: ``alpha`` (0.5), ``beta`` (0.005), ``delta`` (0.005);
        ``"variable"``: ``lam_min`` (``max(0.5, 1 - 10 (1 - lam))``, the
        floor of the variable factor) and ``trace_max`` (``10 dim_x``).
    gate : float, optional
        Outlier gate: a measurement whose normalized residual
        :math:`\sqrt{y^T y / S}` (``|y| / sqrt(S)`` for one output,
        :math:`S = H P^- H^T + R`) exceeds `gate` is not applied; it is
        counted in ``n_gated`` and flagged by ``gated``. ``R`` must describe
        the real measurement noise, or good samples are rejected (``R`` too
        small) or outliers pass (``R`` too large). Typical values are 3-5.
        Off by default. Early samples pass easily while ``P`` is still
        large; and an abrupt parameter change also makes large residuals,
        so a gate delays (a tight gate can block) tracking of jumps: watch
        ``n_gated`` or ``gated`` for runs of rejections.
    check_every : int, default 100
        Health check period (0 disables it): every `check_every` updates,
        and at the end of :meth:`batch_filter`, ``P`` is tested for positive
        definiteness and its condition number (one ``eigvalsh``, O(dim_x^3));
        every update also checks cheaply (O(dim_x)) that the diagonal of
        ``P`` is positive and finite. A failure issues one
        :class:`~rlsfilt.NumericalWarning` naming the update.
    cond_max : float, default 1e12
        Condition number of ``P`` beyond which the health check warns.

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
    gated : bool
        Whether the gate rejected the last measurement.
    n_gated : int
        Number of measurements rejected by the gate since :meth:`reset`.
    n_updates : int
        Number of measurement updates since :meth:`reset`.
    lam_t : float
        Forgetting factor effectively applied by the last update (`lam` for
        ``"exponential"``; the directional weight, the variable factor or
        the constant-trace normalization otherwise).
    constraints : tuple of ndarray or None
        ``(A, b)`` given to :meth:`constrain`.

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

    **Forgetting modes.** Plain exponential forgetting winds up: while the
    input does not excite a direction, ``P`` grows like ``lam**-k`` in it
    and the next disturbance throws the estimate away. The other modes
    (functions in :mod:`rlsfilt.filters.forgetting`) replace the last two
    lines above; for them :meth:`predict` adds ``Q`` and records the priors
    only, and the forgetting happens in :meth:`update` (so ``update`` alone
    is a complete step; :meth:`predict_update` is the one-call textbook
    step for every mode):

    * ``"directional"`` (Kulhavy & Karny 1984; Bittanti, Bolzern & Campi
      1990): forget only along the regressor, :math:`P^{-1} \leftarrow
      P^{-1} + \varepsilon H^T H / R`, :math:`\varepsilon = \lambda -
      (1 - \lambda) R / (H P H^T)`.
    * ``"constant_trace"`` (Goodwin & Sin 1984; Astrom & Wittenmark 1995):
      :math:`P \leftarrow c_1 \bar P / \operatorname{tr} \bar P + c_2 I`
      after the plain update :math:`\bar P`; `lam` only sets the default ``trace``.
    * ``"efra"`` (Salgado, Goodwin & Middleton 1988): :math:`P \leftarrow
      P/\lambda - \alpha g g^T / S + \beta R I - (\delta / R) P^2`
      (the paper's recursion for ``P / R``), gain :math:`\alpha g / S`; the
      eigenvalues of ``P / R`` are clipped into EFRA's invariant interval
      once, by the first :meth:`predict` or :meth:`update` after
      construction, :meth:`reset` or :meth:`initialize` (so the default
      ``P0`` works).
    * ``"variable"`` (Fortescue, Kershenbaum & Ydstie 1981):
      :math:`\lambda_t = 1 - (1 - \lambda)\, y^T y / (m S)`, clipped to
      ``[lam_min, 1]`` and raised so that ``trace(P) <= trace_max``.

    **Constraints.** After :meth:`constrain` the estimate satisfies
    ``A x = b``; plain updates keep it because ``A P = 0``. To hold
    ``A P = 0`` against round-off, and against the modes that add to ``P``
    (``Q``, ``"efra"``, ``"constant_trace"``), ``P`` is projected onto the
    null space of ``A`` (:math:`P \leftarrow \Pi P \Pi`) after each
    predict and update, two small matrix products.

    Missing measurements (``z is None`` or any NaN in ``z``) keep the
    estimate (posterior = prior), as filterpy and statsmodels do. Then ``y``
    and ``z`` are NaN, ``K`` is zero, ``S`` is the predictive variance of the
    missing measurement, ``log_likelihood`` is 0 and ``likelihood`` 1 (a
    missing sample adds nothing to the log-likelihood), and ``mahalanobis``
    is NaN (there is no residual to measure). Because the outputs share ``P``, one NaN
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
    .. [5] R. Kulhavy and M. Karny, "Tracking of slowly varying parameters by
       directional forgetting", *Proc. 9th IFAC World Congress*, 1984.
    .. [6] S. Bittanti, P. Bolzern and M. Campi, "Convergence and exponential
       convergence of identification algorithms with directional forgetting
       factor", *Automatica* 26(5), 1990.
    .. [7] G. C. Goodwin and K. S. Sin, *Adaptive Filtering, Prediction and
       Control*, Prentice Hall, 1984.
    .. [8] M. E. Salgado, G. C. Goodwin and R. H. Middleton, "Modified least
       squares algorithm incorporating exponential resetting and
       forgetting", *Int. J. Control* 47(2), 1988.
    .. [9] T. R. Fortescue, L. S. Kershenbaum and B. E. Ydstie,
       "Implementation of self-tuning regulators with variable forgetting
       factors", *Automatica* 17(6), 1981.
    .. [10] Y. Zhu and X. R. Li, "Recursive least squares with linear
       constraints", *Communications in Information and Systems* 7(3), 2007.

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
    # (_FilterBase has no __slots__, so instances keep their __dict__.)
    __slots__ = ("_x_own", "_P_own", "_spare_prior", "_spare_update", "_row", "_row2",
                 "_params_arr", "_general")

    def __init__(self, dim_x, dim_z=1, lam=1.0, *, P0=1e4, x0=None, R=1.0, Q=0.0,
                 forgetting="exponential", forgetting_params=None, gate=None,
                 check_every=100, cond_max=1e12):
        self.dim_x = check_int(dim_x, "dim_x", minimum=1)
        self.dim_z = check_int(dim_z, "dim_z", minimum=1)
        self._mode = _fg.mode_code(forgetting)
        self._forgetting_params_in = forgetting_params
        self.R = R
        self.lam = lam
        self.Q = Q
        self.gate = gate
        self.check_every = check_int(check_every, "check_every", minimum=0)
        self.cond_max = _check_positive(cond_max, "cond_max")
        self._P0 = check_covariance(P0, self.dim_x, "P0", definite=True)
        self._x0 = self._as_state(np.zeros((self.dim_x, self.dim_z)) if x0 is None else x0, "x0")
        self._warned_skip = False
        self._row, self._row2 = (self.dim_x,), (1, self.dim_x)   # regressor shapes
        self.constraints = None
        self._Pi = None          # orthogonal projector onto null(A)
        self._set_path()
        self._null_basis = None  # orthonormal basis of null(A), for the health check
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
        lam = check_lam(value)
        params = _fg.mode_params(self._mode, self._forgetting_params_in, self.dim_x, lam,
                                 self._R)
        self._lam, self._params = lam, params
        self._params_arr = np.array(params, dtype=np.float64)

    @property
    def forgetting(self):
        """Forgetting mode (read-only; chosen at construction)."""
        return _fg.MODES[self._mode]

    @property
    def forgetting_params(self):
        """The constants of the forgetting mode, defaults filled in (a new dict)."""
        return dict(zip(_fg._PARAM_NAMES[self._mode], self._params, strict=True))

    @property
    def gate(self):
        """Outlier gate on the normalized residual, or None (off)."""
        return self._gate

    @gate.setter
    def gate(self, value):
        self._gate = None if value is None else _check_positive(value, "gate")
        self._set_path()

    def _set_path(self):
        """Choose the streaming path: the fused fast path, or the general step."""
        self._general = (self._mode != _EXPONENTIAL or self._gate is not None
                         or getattr(self, "_Pi", None) is not None)

    @property
    def Q(self):
        """Parameter random-walk covariance, ``(dim_x, dim_x)``."""
        return self._Q

    @Q.setter
    def Q(self, value):
        # C-contiguous float64: the streaming fast path passes it to compiled code
        self._Q = np.ascontiguousarray(check_covariance(value, self.dim_x, "Q"),
                                       dtype=np.float64)
        self._Q_is_zero = not self._Q.any()

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    def predict(self, Q=None):
        r"""Time update :math:`P \leftarrow P / \lambda + Q`.

        The estimate ``x`` is unchanged (constant or random-walk
        parameters). With ``lam = 1`` and ``Q = 0`` this only records
        ``x_prior`` and ``P_prior``. For the forgetting modes other than
        ``"exponential"`` the division by `lam` is not done here (their
        forgetting needs the regressor and happens in :meth:`update`); only
        ``Q`` is added.

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
        if self._general or not _COMPILED:
            P = self._checked_P()
            if self._efra_pending:
                P = self._efra_start(P)
            if _COMPILED:        # the compiled step that batch_filter runs
                P = np.array(P, dtype=np.float64, order="C")
                Pi = self._Pi
                n = self.dim_x
                (_kernels or _get_kernels()).general_predict(
                    P, 1.0 / self._time_lam(), Q, q_zero, Pi is not None,
                    _EMPTY2 if Pi is None else Pi, np.empty((n, n)))
                self.P = P
            else:
                P = _predict_covariance(P, self._time_lam(), None if q_zero else Q)
                self.P = P if self._Pi is None else _project(P, self._Pi)
            self.x_prior = self.x.copy()
            self.P_prior = self.P.copy()
            self._updates_since_predict = 0
            return
        x, P = self.x, self.P
        rc = _getrefcount
        x_prior, P_prior = self._spare_prior
        # Nobody else holds P or the last priors (the usual case, see
        # _free_refcount): P^- overwrites P, the priors are rewritten in place.
        recycled = (x is self._x_own and P is self._P_own and rc(P) == _FREE
                    and rc(x_prior) == _FREE and rc(P_prior) == _FREE
                    and self.x_prior is x_prior and self.P_prior is P_prior)
        if recycled:
            ep = _predict_entry
            if ep is not None and Q is self._Q:
                ep(x, P, 1.0 / self._lam, Q, q_zero, P, x_prior, P_prior)
                self._updates_since_predict = 0
                return
            Pn = P
        else:
            n = self.dim_x
            x = np.ascontiguousarray(self._checked_x(), dtype=float)
            P = np.ascontiguousarray(self._checked_P(), dtype=float)
            Pn, x_prior, P_prior = np.empty((n, n)), np.empty((n, self.dim_z)), np.empty((n, n))
        args = (x, P, 1.0 / self._lam, Q, q_zero, Pn, x_prior, P_prior)
        (_kernels or _get_kernels()).predict_kernel(*args)
        if recycled and Q is self._Q:       # the types of the fast path: resolve its entry
            _set_entries(predict=_entry_point(_kernels.predict_kernel, args))
        if not recycled:
            self.x = self._x_own = x
            self.P = self._P_own = Pn
            self.x_prior, self.P_prior = self._spare_prior = x_prior, P_prior
        self._updates_since_predict = 0

    def update(self, z, H, R=None):
        r"""Measurement update with regressor row `H`.

        For the forgetting modes other than ``"exponential"`` this includes
        the step's forgetting. A measurement rejected by the gate leaves
        ``x`` and ``P`` unchanged (``gated`` is True, ``y`` and ``S`` are
        those of the rejected sample, ``K`` is zero).

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
        if self._general or not _COMPILED:
            self._update_general(z, H, R)
            return
        # The common case (a float64 row, a float measurement, the filter's
        # own x and P) skips the conversions; the arithmetic is the compiled
        # step that batch_filter runs, so both agree bit for bit.
        if type(H) is np.ndarray and H.dtype is _F8 and H.shape == self._row:
            phi = H
        elif type(H) is np.ndarray and H.dtype is _F8 and H.shape == self._row2:
            phi = H.reshape(self.dim_x)
        else:
            phi = self._as_regressor(H, "H").reshape(self.dim_x)
        r = self._R if R is None else check_variance(R, "R")
        zf = isinstance(z, float) and self.dim_z == 1
        if zf:
            missing = z != z
            if not missing and z - z != 0.0:
                self._as_measurement(z, "z")            # raises: z is inf
        else:
            zvalue = self._as_measurement(z, "z")
            missing = zvalue is None
        x, P = self.x, self.P
        rc = _getrefcount
        y, K, S, SI, Hc, zc, x_post, P_post = self._spare_update
        # Nobody else holds x, P or the last step's diagnostics (the usual
        # case, see _free_refcount): update them in place, no allocations.
        recycled = (x is self._x_own and P is self._P_own and (zf or missing)
                    and rc(x) == _FREE and rc(P) == _FREE and rc(y) == _FREE
                    and rc(K) == _FREE and rc(S) == _FREE and rc(SI) == _FREE
                    and rc(Hc) == _FREE and rc(zc) == _FREE and rc(x_post) == _FREE
                    and rc(P_post) == _FREE
                    # the attributes still are the spare arrays (an attribute the
                    # user replaced while keeping the old array keeps the count)
                    and self.y is y and self.K is K and self.S is S and self.SI is SI
                    and self.H is Hc and self.z is zc and self.x_post is x_post
                    and self.P_post is P_post)
        if recycled:
            xn, Pn = x, P
        else:
            n, m = self.dim_x, self.dim_z
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
        ep = _update_entry
        if recycled and ep is not None and phi.flags.carray:
            code = ep(x, P, phi, zc, z0, zmode, r, x, P, y, K, S, SI, Hc, x_post, P_post)
        else:
            args = (x, P, phi, zc, float(z0), zmode, float(r), xn, Pn, y, K, S, SI, Hc,
                    x_post, P_post)
            code = (_kernels or _get_kernels()).update_kernel(*args)
            if recycled and ep is None and phi.flags.carray:   # resolve the fast entry
                _set_entries(update=_entry_point(_kernels.update_kernel, args))
        if code == 1:
            check_finite(phi, "H")                   # raises: H is not finite
        if self._updates_since_predict:
            self._note_update()
        else:
            self._updates_since_predict = 1
        if missing:
            self._log_likelihood, self._likelihood, self._mahalanobis = 0.0, 1.0, math.nan
        else:
            self._log_likelihood = self._likelihood = self._mahalanobis = None
        if not recycled:
            self._spare_update = (y, K, S, SI, Hc, zc, x_post, P_post)
            self.H, self.z, self.S, self.SI, self.y, self.K = Hc, zc, S, SI, y, K
            self.x = self._x_own = xn
            self.P = self._P_own = Pn
            self.x_post, self.P_post = x_post, P_post
        if self.gated:
            self.gated = False
        self.lam_t = self._lam
        self.n_updates = nu = self.n_updates + 1
        # the cheap health check of _check_health: the kernel tested the
        # diagonal (code 2); the periodic full check runs compiled, and the
        # NumPy check only words the warning
        every = self.check_every
        if every and (code == 2 or not nu % every) and not self._warned_health:
            if code == 2 or _kernels._unhealthy(self.P, self.cond_max):
                self._check_health(cheap=False)

    def predict_update(self, z, H, R=None):
        """One textbook RLS step: :meth:`predict` then :meth:`update`."""
        self.predict()
        self.update(z, H, R)

    def _update_general(self, z, H, R):
        """:meth:`update` for the forgetting modes other than exponential, the gate
        and the constraints: the compiled step that batch_filter runs (so the
        two agree bit for bit), or the NumPy reference when ``_COMPILED`` is off."""
        if not _COMPILED:
            self._update_reference(z, H, R)
            return
        n, m = self.dim_x, self.dim_z
        if type(H) is np.ndarray and H.dtype is _F8 and (H.shape == self._row
                                                          or H.shape == self._row2):
            phi = H.reshape(n)                 # finiteness: tested by the kernel
        else:
            phi = self._as_regressor(H, "H").reshape(n)
        r = self._R if R is None else check_variance(R, "R")
        zc = np.empty(m)
        if isinstance(z, float) and m == 1:
            zmode, z0 = (2, 0.0) if z != z else (1, z)
            if zmode == 1 and z - z != 0.0:
                self._as_measurement(z, "z")            # raises: z is inf
        else:
            zvalue = self._as_measurement(z, "z")
            zmode, z0 = (2, 0.0) if zvalue is None else (0, 0.0)
            if zvalue is not None:
                zc[:] = zvalue[:, 0]
        x, P = self._checked_x(), self._checked_P()
        if self._efra_pending:
            check_finite(phi, "H")                    # before the state changes
            P = self._efra_start(P)
        x = np.array(x, dtype=np.float64, order="C")
        P = np.array(P, dtype=np.float64, order="C")
        y, K = np.empty(m), np.empty(n)
        S, SI, Hc = np.empty((m, m)), np.empty((m, m)), np.empty((1, n))
        x_post, P_post = np.empty((n, m)), np.empty((n, n))
        Pi, gate = self._Pi, self._gate
        code, s, lam_t, gated = (_kernels or _get_kernels()).general_update_kernel(
            x, P, phi, zc, float(z0), zmode, r, self._mode, self._params_arr, self._lam,
            gate is not None, 0.0 if gate is None else gate, Pi is not None,
            _EMPTY2 if Pi is None else Pi, y, K, S, SI, Hc, x_post, P_post)
        if code == 1:
            check_finite(phi, "H")                    # raises: H is not finite
        self._note_update()
        if zmode == 2:
            self._log_likelihood, self._likelihood, self._mahalanobis = 0.0, 1.0, math.nan
        else:
            self._log_likelihood = self._likelihood = self._mahalanobis = None
        self.H, self.S, self.SI = Hc, S, SI
        self.z, self.y, self.K = zc.reshape(m, 1), y.reshape(m, 1), K.reshape(n, 1)
        self.x, self.P = x, P
        self.x_post, self.P_post = x_post, P_post
        self.gated = gated
        self.n_gated += gated
        self.lam_t = lam_t
        self.n_updates = nu = self.n_updates + 1
        # the cheap health check: the kernel tested the diagonal (code 2)
        every = self.check_every
        if every and (code == 2 or not nu % every) and not self._warned_health:
            self._check_health(cheap=False)

    def _update_reference(self, z, H, R):
        """:meth:`update` in NumPy (the reference path)."""
        phi = self._as_regressor(H, "H")
        r = self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        x, P = self._checked_x(), self._checked_P()
        self._note_update()
        self._clear_lazy()
        if self._efra_pending:
            P = self._efra_start(P)
        self.H = phi
        x, P, y, K, g, s, lam_t, gated = _measurement_step(
            self._mode, self._params, self._lam, x, P, phi, zc, r, self._gate, self._Pi)
        self.S = s * self._I_z
        self.SI = self._I_z / s
        self.gated = gated
        self.n_gated += gated
        self.lam_t = lam_t
        self.x, self.P, self.K = x, P, K
        if zc is None:
            self.z = np.full((self.dim_z, 1), np.nan)
            self.y = np.full((self.dim_z, 1), np.nan)
            self._log_likelihood, self._likelihood, self._mahalanobis = 0.0, 1.0, math.nan
        else:
            self.z, self.y = zc, y
        self.x_post = self.x.copy()
        self.P_post = self.P.copy()
        self.n_updates += 1
        self._check_health(cheap=True)

    # ------------------------------------------------------------------
    # batch start and batch runs
    # ------------------------------------------------------------------
    def initialize(self, zs, Hs):
        r"""Start the filter from batch least squares on the first samples.

        This is step 1 of the lecture notes: with the first ``k0`` samples
        stacked as :math:`Z = \Phi x + V`, set

        .. math::

            x = (\Phi^T \Phi)^{-1} \Phi^T Z, \qquad P = R\,(\Phi^T \Phi)^{-1},

        both computed from the QR factorization :math:`\Phi D^{-1} = Q_1 R_1`
        of the regressors with their columns scaled to unit norm
        (:math:`D` the diagonal of the column norms; :math:`x = D^{-1} R_1^{-1}
        Q_1^T Z`, :math:`P = R\,D^{-1} R_1^{-1} R_1^{-T} D^{-1}`), never from the
        normal equations, which square the condition number. The scaling
        makes the rank decision independent of the units of the regressors
        (a column in 1e-8 beside one in 1e6 is not mistaken for a zero
        column), as in ``ARX.fit(method="ls")``; the result is the same exact
        least-squares solution.
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
        # columns scaled to unit norm, so that neither the rank decision nor the
        # QR depends on the units of the regressors (1e-8 beside 1e6 is not rank
        # deficiency); the solution is scaled back exactly: x = D^-1 x_s,
        # (A^T A)^-1 = D^-1 (A_s^T A_s)^-1 D^-1
        norms = np.linalg.norm(A, axis=0) if len(A) else np.ones(self.dim_x)
        d = np.where(norms > 0.0, norms, 1.0)
        As = A / d
        rank = int(np.linalg.matrix_rank(As)) if len(A) else 0
        if rank < self.dim_x:
            raise ValueError(
                f"`Hs` is rank-deficient: found {rank} linearly independent rows in "
                f"{len(A)} usable samples; need {self.dim_x} (one per parameter). Use more "
                "samples or a more exciting input."
            )
        Qf, Rf = np.linalg.qr(As)
        self.x = solve_triangular(Rf, Qf.T @ B) / d[:, None]
        Rinv = solve_triangular(Rf, np.eye(self.dim_x)) / d[:, None]   # D^-1 R_s^-1
        P = self._R * (Rinv @ Rinv.T)
        self.P = 0.5 * (P + P.T)
        self._efra_pending = self._mode == _fg.EFRA
        if self.constraints is not None:   # keep the constraints given earlier
            self.constrain(*self.constraints)
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
        With exponential forgetting (the default) and no gate or constraints
        the loop runs in compiled code (numba, cached on disk after the first
        call): one sweep over ``P`` per step applies the update, the next
        forgetting step and the next gain together, so a step costs about
        :math:`6\,n^2` floating-point operations for ``n = dim_x`` and the
        record is processed at tens of nanoseconds per sample for small ``n``
        (see ``docs/performance.md``). The other modes, the gate and the
        constraints run a compiled loop of one step per sample, the same
        compiled step that :meth:`predict` and :meth:`update` call.

        Every forgetting mode, the gate and the constraints apply exactly as
        in the step-by-step loop (the results are bitwise equal); gated
        samples are added to ``n_gated``. The health check of ``P`` runs
        every ``check_every`` steps inside the loop and once at the end, so
        a failure is reported with its step in the record.
        """
        Z, Hm = self._as_batch(zs, Hs)
        Rv = self._as_batch_variances(Rs, len(Z))
        if saver is not None:
            return self._batch_stepwise(Z, Hm, Rv, update_first, saver, store_covariances)
        P = self._checked_P()
        if self._efra_pending and len(Z):
            P = self._efra_start(P)
        if not _COMPILED:
            run = _batch_reference
        elif self._mode == _EXPONENTIAL and self._gate is None and self._Pi is None:
            # the fused fast path; the residual histories are not needed: last step only
            run = functools.partial(_get_kernels().batch_compiled, histories=False)
        else:
            run = _get_kernels().batch_general
        out = run(self._checked_x(), P, Z, Hm, Rv, self._lam,
                  None if self._Q_is_zero else self._Q, update_first,
                  store_covariances, mode=self._mode, params=self._params,
                  gate=self._gate, Pi=self._Pi, check_every=self.check_every,
                  basis=self._null_basis, cond_max=self.cond_max, step0=self.n_updates)
        self._adopt_last_step(out, Hm, Z, Rv, update_first)
        if out.problem is not None and not self._warned_health:
            self._warn_health(out.problem)
        self._check_health(cheap=False)
        return out.means, out.covariances, out.means_p, out.covariances_p

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
            self._log_likelihood, self._likelihood, self._mahalanobis = 0.0, 1.0, math.nan
        else:
            self.z = Z[-1].reshape(-1, 1).copy()
            self.y = out.y_last.reshape(-1, 1)
            self.K = out.K_last.reshape(-1, 1)
        self.x_post = out.x_post
        self.P_post = out.P_post
        self.x_prior = out.x_prior
        self.P_prior = out.P_prior
        self._updates_since_predict = 0 if update_first else 1
        self.n_updates += len(Z)
        self.n_gated += int(out.gated.sum())
        self.gated = bool(out.gated[-1])
        self.lam_t = out.lam_t_last
        if self.gated:
            self.K = np.zeros((self.dim_x, 1))

    # ------------------------------------------------------------------
    # equality constraints
    # ------------------------------------------------------------------
    def constrain(self, A, b):
        r"""From now on keep the estimate on the affine set ``A x = b``.

        The state and covariance are projected once (Zhu & Li 2007):

        .. math::

            W &= P A^T (A P A^T)^{-1} \\
            x &\leftarrow x + W (b - A x), \qquad P \leftarrow P - W A P

        after which :math:`A P = 0`, so every gain satisfies :math:`A K = 0`
        and plain updates keep :math:`A x = b`. Started from
        :meth:`initialize` with ``lam = 1`` this gives, at every later step,
        the equality-constrained least-squares estimate (the KKT solution)
        on all data so far, as statsmodels' ``RecursiveLS(constraints=...)``.
        ``P`` is then singular (rank ``dim_x - rank(A)``); the health check
        tests it on the null space of ``A``.

        Parameters
        ----------
        A : array_like, shape (p, dim_x) or (dim_x,)
            Constraint matrix of full row rank ``p < dim_x``.
        b : float or array_like, shape (p,) or (p, dim_z)
            Right-hand side; one column per output when ``dim_z > 1`` (a
            1-D `b` applies to every output).

        Returns
        -------
        self
        """
        n, m = self.dim_x, self.dim_z
        A = as_float_array(A, "A")
        if A.ndim == 1:
            A = A.reshape(1, -1)
        if A.ndim != 2 or A.shape[1] != n:
            raise ValueError(f"`A` must have shape (p, {n}) (dim_x = {n} columns); got {A.shape}")
        check_finite(A, "A")
        p = A.shape[0]
        rank = np.linalg.matrix_rank(A)
        if rank != p or p >= n:
            raise ValueError(f"`A` must have full row rank p < dim_x = {n}; got {p} rows of "
                             f"rank {rank}")
        bb = check_finite(as_float_array(b, "b"), "b")
        if bb.ndim <= 1 and bb.size == p:
            bb = np.repeat(bb.reshape(p, 1), m, axis=1)
        if bb.shape != (p, m):
            raise ValueError(f"`b` must have shape ({p},) or ({p}, {m}); got {bb.shape}")
        x, P = self._checked_x(), self._checked_P()
        if self._efra_pending:
            P = self._efra_start(P)
        PA = P @ A.T
        W = np.linalg.solve(A @ PA, PA.T).T            # W = P A^T (A P A^T)^-1
        self.x = x + W @ (bb - A @ x)                  # x <- x + W (b - A x)
        P = P - W @ PA.T                               # P <- P - W A P
        basis = null_space(A)
        self._Pi = basis @ basis.T
        self._set_path()
        self.P = _project(P, self._Pi)
        self._null_basis = basis
        self.constraints = (A.copy(), bb.copy())
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        return self

    # ------------------------------------------------------------------
    # health of P
    # ------------------------------------------------------------------
    def _check_health(self, cheap):
        """Warn once if ``P`` is not positive definite or too ill-conditioned.

        With `cheap`, only the diagonal is looked at (O(dim_x)) unless this
        update is a multiple of ``check_every``; a suspicious diagonal
        triggers the full check (``eigvalsh`` on ``P`` restricted to the
        null space of the constraints, if any).
        """
        if self._warned_health or not self.check_every:
            return
        P = self.P
        if cheap:
            d = np.diagonal(P)
            if (self.n_updates % self.check_every and np.isfinite(d).all()
                    and (d > 0).all()):
                return
        problem = _health_problem(P, self._null_basis, self.cond_max)
        if problem is not None:
            self._warn_health(problem + f" at update {self.n_updates} since reset")

    def _warn_health(self, message):
        self._warned_health = True
        warnings.warn(message + ". The estimate may be unreliable: use a forgetting mode that "
                      "bounds P (forgetting='directional', 'efra', ...), SquareRootRLS, or more "
                      "exciting input.", NumericalWarning, stacklevel=3)

    def _efra_start(self, P):
        """Clip ``P`` into EFRA's invariant interval before its first step."""
        self._efra_pending = False
        lo, hi = _fg.efra_bounds(self._lam, *self._params)
        P = _fg.clip_eigenvalues(P, lo * self._R, hi * self._R)
        return P if self._Pi is None else _project(P, self._Pi)

    def _time_lam(self):
        """Forgetting applied by predict(): `lam` only in the exponential mode."""
        return self._lam if self._mode == _fg.EXPONENTIAL else 1.0

    # ------------------------------------------------------------------
    # filterpy helpers
    # ------------------------------------------------------------------
    def get_prediction(self):
        """Return ``(x, P)`` after a :meth:`predict`, without changing the filter."""
        P = _predict_covariance(self._checked_P(), self._time_lam(),
                                None if self._Q_is_zero else self._Q)
        return self._checked_x().copy(), P.copy()

    def reset(self):
        """Return to the state given at construction (``x0``, ``P0``).

        ``lam``, ``R``, ``Q``, the forgetting mode and the gate are kept;
        diagnostics and counters are cleared. Constraints given to
        :meth:`constrain` are applied again to ``x0`` and ``P0``.
        """
        self.x = self._x_own = self._x0.copy()
        self.P = self._P_own = self._P0.copy()
        self.x_prior, self.P_prior = self.x.copy(), self.P.copy()
        self.x_post, self.P_post = self.x.copy(), self.P.copy()
        self._reset_diagnostics()
        # arrays the streaming methods may overwrite when nobody else holds them
        self._spare_prior = (self.x_prior, self.P_prior)
        self._spare_update = (self.y, self.K, self.S, self.SI, self.H, self.z, self.x_post,
                              self.P_post)
        self._updates_since_predict = 0
        self.gated = False
        self.n_gated = 0
        self.n_updates = 0
        self.lam_t = self._lam
        self._warned_health = False
        self._efra_pending = self._mode == _fg.EFRA
        if self.constraints is not None:
            self.constrain(*self.constraints)

    def __repr__(self):
        return "\n".join([
            "RecursiveLeastSquares object",
            pretty_str("dim_x", self.dim_x),
            pretty_str("dim_z", self.dim_z),
            pretty_str("lam", self._lam),
            pretty_str("forgetting", self.forgetting),
            pretty_str("gate", self._gate),
            pretty_str("n_gated", self.n_gated),
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
    def _note_update(self):
        """Warn once when forgetting is skipped by two updates in a row."""
        if (self._updates_since_predict and not self._warned_skip
                and (self._time_lam() < 1.0 or not self._Q_is_zero)):
            self._warned_skip = True
            warnings.warn(
                "update() was called twice without predict() in between, so the forgetting "
                "(lam < 1) or random walk (Q > 0) of this step was skipped; call predict() "
                "before each update() or use predict_update().",
                ForgettingSkippedWarning, stacklevel=3)
        self._updates_since_predict += 1

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


def _project(P, Pi):
    """``Pi P Pi`` made exactly symmetric (projection onto null(A))."""
    P = Pi @ P @ Pi
    return 0.5 * (P + P.T)


def _measurement_step(mode, params, lam, x, P, phi, z, r, gate, Pi):
    """One measurement update of any mode, with the gate and the constraints.

    `z` is a ``(dim_z, 1)`` column or None (missing). Returns ``x, P, y, K,
    g, s, lam_t, gated``; for a missing or gated sample ``x`` and ``P`` are
    the inputs, ``K`` is zero and ``lam_t`` is 1 (nothing is forgotten),
    or `lam` in the exponential mode (its predict forgot anyway).
    """
    g, s = _innovation(P, phi, r)          # g = P H^T, S = H P H^T + R
    lam_skip = lam if mode == _fg.EXPONENTIAL else 1.0
    if z is None:
        return x, P, None, np.zeros_like(g), g, s, lam_skip, False
    if gate is not None:
        y = z - (phi @ x).T
        if float(np.vdot(y, y)) > gate * gate * s:   # sqrt(y'y / S) > gate
            return x, P, y, np.zeros_like(g), g, s, lam_skip, True
    x, P, y, K, lam_t = _fg.UPDATES[mode](x, P, phi, z, g, s, r, lam, params)
    if Pi is not None:   # keep A P = 0 against round-off (and the I terms of some modes)
        P = _project(P, Pi)
    return x, P, y, K, g, s, lam_t, False


def _health_problem(P, basis, cond_max):
    """None if ``P`` (on the null space `basis` of the constraints) is healthy,
    else a description."""
    if not np.isfinite(P).all():
        return "`P` has non-finite entries"
    Pr = P if basis is None else basis.T @ P @ basis
    if Pr.size == 0:
        return None
    asym = float(np.max(np.abs(Pr - Pr.T)))
    scale = float(np.max(np.abs(Pr)))
    w = np.linalg.eigvalsh(0.5 * (Pr + Pr.T))
    if w[0] <= 0.0:
        return f"`P` is not positive definite (smallest eigenvalue {w[0]:.3g})"
    if asym > 1e-8 * scale:
        return f"`P` is not symmetric (max |P - P^T| = {asym:.3g})"
    if w[-1] > cond_max * w[0]:
        return f"`P` is ill-conditioned (condition number {w[-1] / w[0]:.3g} > {cond_max:.3g})"
    return None


def _check_positive(value, name):
    value = check_scalar(value, name)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"`{name}` must be a positive finite number; got {value}")
    return value


class _BatchResult:
    __slots__ = ("means", "covariances", "means_p", "covariances_p", "ys", "ss",
                 "x", "P", "x_prior", "P_prior", "x_post", "P_post", "y_last", "K_last",
                 "s_last", "gated", "lam_t_last", "problem")


def _batch_reference(x, P, Z, Hm, Rv, lam, Q, update_first, store_covariances, *,
                     mode=_fg.EXPONENTIAL, params=(), gate=None, Pi=None, check_every=0,
                     basis=None, cond_max=np.inf, step0=0):
    """Pure-NumPy batch recursion (the reference path for compiled kernels).

    Returns a `_BatchResult` with the histories, the recursive residuals
    ``ys`` (N, dim_z; NaN where missing, the rejected residual where gated),
    innovation variances ``ss`` (N,), the gate decisions ``gated`` (N,),
    the last step's state and ``problem``: None, or the first health
    failure found by a full check every `check_every` steps (message with
    the update number ``step0 + k + 1``). The cheap per-step diagonal check
    of the streaming path is not done here; the caller checks once more at
    the end.
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
    out.gated = np.zeros(N, dtype=bool)
    out.problem = None
    tlam = lam if mode == _fg.EXPONENTIAL else 1.0
    constrained = Pi is not None
    x_prior, P_prior = x, P
    K = np.zeros((n, 1))
    s = np.nan
    lam_t = lam
    missing = np.isnan(Z).any(axis=1)
    for k in range(N):
        if not update_first:
            P = _predict_covariance(P, tlam, Q)
            if constrained:
                P = _project(P, Pi)
            x_prior, P_prior = x, P
            out.means_p[k] = x
            if store_covariances:
                out.covariances_p[k] = P
        zc = None if missing[k] else Z[k].reshape(m, 1)
        x, P, y, K, _, s, lam_t, gated = _measurement_step(
            mode, params, lam, x, P, Hm[k:k + 1], zc, Rv[k], gate, Pi)
        out.ss[k] = s
        out.gated[k] = gated
        if y is not None:
            out.ys[k] = y[:, 0]
        x_post, P_post = x, P
        out.means[k] = x
        if store_covariances:
            out.covariances[k] = P
        if update_first:
            P = _predict_covariance(P, tlam, Q)
            if constrained:
                P = _project(P, Pi)
            x_prior, P_prior = x, P
            out.means_p[k] = x
            if store_covariances:
                out.covariances_p[k] = P
        if check_every and out.problem is None and (step0 + k + 1) % check_every == 0:
            problem = _health_problem(P, basis, cond_max)
            if problem is not None:
                out.problem = (f"{problem} at step {k} of batch_filter (update "
                               f"{step0 + k + 1} since reset)")
    out.x, out.P = x.copy(), P.copy()
    if N:
        out.x_prior, out.P_prior = x_prior.copy(), P_prior.copy()
        out.x_post, out.P_post = x_post.copy(), P_post.copy()
        out.y_last, out.K_last, out.s_last = out.ys[-1].copy(), K.copy(), s
        out.lam_t_last = lam_t
    return out
