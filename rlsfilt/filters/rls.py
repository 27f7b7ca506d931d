"""Recursive least squares as a filterpy-style filter.

`RecursiveLeastSquares` estimates the parameters ``x`` of the linear
regression ``z_k = H_k x + v_k`` one sample at a time. It is the Kalman
filter of a constant (or random-walk) parameter vector whose measurement
matrix is the regressor row ``H_k``, and it is written so that code written
for :class:`filterpy.kalman.KalmanFilter` runs on it unchanged where the
meaning is the same: ``predict()`` / ``update(z, H)`` / ``batch_filter``,
state ``x`` and ``P``, diagnostics ``y``, ``K``, ``S``, ``SI`` and the lazy
``log_likelihood``, ``likelihood`` and ``mahalanobis``.

Every step runs compiled (:mod:`rlsfilt.filters._kernels`, one compiled call
per ``predict()`` and per ``update()``); the same recursion in textbook NumPy
is ``tests/_reference.py``.
"""

import math

import numpy as np

from .._display import pretty_str
from .._locking import locked as _locked
from .._scale import safe_norm
from .._validation import (
    as_float_array,
    check_covariance,
    check_dimension,
    check_finite,
    check_int,
    check_lam,
    check_scalar,
    check_variance,
)
from ..exceptions import ForgettingSkippedWarning
from . import _health, _streaming
from . import forgetting as _fg
from . import smoother as _smoother
from . import tuning as _tuning
from ._base import MISSING_DIAGNOSTICS, _FilterBase, own_array, refuse_fixed
from .contract import check_state

__all__ = ["RecursiveLeastSquares"]

_EMPTY = np.zeros((0, 0))          # an absent Q or projector, as the kernels take it
_F8 = np.dtype(np.float64)
_BAD_ROW, _BAD_DIAGONAL, _GATED, _CAP = 1, 2, 4, 8   # the flags of _kernels.update_kernel



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
    lam : float or array_like of shape (dim_x,), default 1.0
        Forgetting factor in (0, 1]. ``1`` is ordinary least squares; a
        sample ``j`` steps old is weighted by ``lam**j``, so the memory is
        about ``1 / (1 - lam)`` samples. With ``forgetting="diagonal"``, one
        factor per parameter (a number: the same for every parameter).
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
    forgetting : str, default "exponential"
        One of {"exponential", "directional", "constant_trace", "efra", "variable",
        "diagonal"}: how old data is forgotten (see Notes). ``"exponential"`` divides
        ``P`` by `lam` in :meth:`predict` (filterpy's fading memory), and
        ``"diagonal"`` forgets each parameter with its own factor there,
        :math:`P^- = L^{-1/2} P L^{-1/2} + Q`, ``L = diag(lam)`` (the
        recursion of ``tune(..., "lam_diag")``); the
        others forget inside :meth:`update`, because they need the step's
        regressor or residual, and bound ``P`` when the input stops
        exciting the system (no covariance windup).
    forgetting_params : dict, optional
        Constants of the chosen mode: ``"exponential"``: the windup cap (see
        Notes), ``spread_max`` (1e15) and ``trace_max`` (``1e12 trace(P0)``;
        ``inf`` for both gives the plain recursion), and the same for
        ``"diagonal"``; ``"directional"``: ``eps`` (1e-12,
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
    check_every : int, optional
        Health check period (0 disables it): every `check_every` updates,
        and at the end of :meth:`batch_filter`, ``P`` is tested for positive
        definiteness and its condition number (a Cholesky factor, and
        ``eigvalsh`` when in doubt, O(dim_x^3)); every update also checks
        cheaply (O(dim_x)) that the diagonal of ``P`` is positive and finite,
        and runs the full test at once when it is not. By default
        ``max(250, 32 dim_x)``, which keeps the O(dim_x^3) test under 5 % of
        the O(dim_x^2) updates at every size. A failure issues one
        :class:`~rlsfilt.NumericalWarning` naming the update; a later
        periodic check that finds ``P`` healthy again re-arms it, so a
        problem that recurs warns again.
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
        Regressor row: the one :meth:`update` uses when its `H` is omitted
        (filterpy's convention; assign it, e.g. for filterpy's
        ``IMMEstimator``), and after each update the row that update used.
        Zeros after construction and :meth:`reset`.
    alpha : float
        filterpy's fading-memory factor, ``alpha**2 = 1 / lam``; assigning it
        sets `lam`.
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
    n_capped : int
        Number of updates since :meth:`reset` whose forgetting the windup
        cap restricted to the regressor's direction (exponential and
        diagonal modes; see Notes).
    lam_t : float
        Forgetting factor effectively applied by the last update (`lam` for
        ``"exponential"``, the smallest factor for ``"diagonal"``; the
        directional weight, the variable factor or the constant-trace
        normalization otherwise).
    constraints : EqualityConstraints or None
        Every constraint given to :meth:`constrain`, stacked: ``.A`` of
        shape ``(p, dim_x)`` and ``.b`` of shape ``(p, dim_z)``; unpacks as
        ``A, b = rls.constraints``. Configuration, not state: kept by
        :meth:`reset` and :meth:`initialize`.

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
    (constants in :mod:`rlsfilt.filters.forgetting`) replace the last two
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

    **Diagonal forgetting** (``forgetting="diagonal"``, `lam` one factor per
    parameter; a vector forgetting factor, see Parkum, Poulsen & Holst 1992)
    forgets in :meth:`predict`, like ``"exponential"``, with
    :math:`P^- = L^{-1/2} P L^{-1/2} + Q`, :math:`L = \operatorname{diag}(\lambda_1,
    \dots, \lambda_n)`, i.e. :math:`P^-_{ij} = P_{ij} / \sqrt{\lambda_i\lambda_j} +
    Q_{ij}`; the measurement update is the standard one. A parameter that stays
    constant can keep ``lam_i = 1`` beside one that drifts; equal factors are
    exponential forgetting. It is exactly the recursion whose likelihood
    ``tune(..., "lam_diag")`` maximizes, so ``TuneResult.apply`` runs it. It has
    no weighted least-squares form: :meth:`initialize` does not weight its rows.
    The windup cap below applies with the trace after the time update,
    :math:`\sum_i P_{ii} / \lambda_i`, and held back, the update forgets along
    the regressor by :math:`w = H L^{-1/2} P L^{-1/2} H^T / (H P H^T)` (the growth
    of :math:`H P H^T` the time update would have given; :math:`1/\lambda` for
    equal factors).

    **The windup cap** (exponential and diagonal modes, ``lam < 1``). Plain exponential
    forgetting lets ``P`` grow like ``lam**-k`` in the directions the data
    stop exciting, until it overflows and the estimate is NaN for good. After
    each update the filter therefore decides, in O(dim_x), whether the next
    :meth:`predict` may divide ``P`` by ``lam``: not when
    :math:`\sum_i P_{ii} H_i^2 > \mathtt{spread\_max}\, H P H^T` (``P`` far
    larger off the regressor's direction than along it; the ratio does not
    depend on the units of the regressors) or when
    :math:`\operatorname{tr} P / \lambda` would exceed ``trace_max``. Then
    :meth:`predict` leaves ``P`` (and adds ``Q``) and the next :meth:`update`
    forgets along its regressor only, :math:`P \leftarrow P + (1/\lambda -
    1)\, g g^T / (H g)`, :math:`g = P H^T` (directional forgetting), so
    ``P`` stays finite and positive definite whatever the data, and the
    estimate recovers when excitation returns. Ordinary runs never reach the
    cap: their results are bitwise those of the plain recursion.

    **Constraints.** After :meth:`constrain` the estimate satisfies
    ``A x = b``; plain updates keep it because ``A P = 0``. To hold
    ``A P = 0`` against round-off, and against the modes that add to ``P``
    (``Q``, ``"efra"``, ``"constant_trace"``), ``P`` is projected onto the
    null space of ``A`` (:math:`P \leftarrow \Pi P \Pi`) after each
    predict and update, two small matrix products.

    **Threads.** Each public call that changes the filter's state
    (:meth:`predict`, :meth:`update`, :meth:`predict_update`,
    :meth:`batch_filter`, :meth:`initialize`, :meth:`reset`, :meth:`constrain`,
    ``set_state`` and the assignments of ``x``, ``P`` and the settings) holds
    the filter's own reentrant lock, so a filter shared by threads applies
    every call whole and loses none (about 0.12 us per call,
    ``benchmarks/bench_rls.py --lock-cost``). A sequence of calls is not
    atomic: share :meth:`predict_update`, not a ``predict()``/``update()``
    pair. Copies and pickles get their own lock.

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
    .. [11] R. Parkum, N. K. Poulsen and J. Holst, "Recursive forgetting
       algorithms", *Int. J. Control* 55(1), 1992.

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

    # The filter's own x and P live in slots, outside ``__dict__``: filterpy's Saver
    # deep-copies ``__dict__`` and reads ``x`` and ``P`` through their properties.
    __slots__ = ("_x", "_P", "_cfg")
    _options = _FilterBase._options | {"P", "Q", "lam", "alpha", "gate", "check_every",
                                       "cond_max"}

    _HEALTH_ADVICE = ("The estimate may be unreliable: use a forgetting mode that bounds P "
                      "(forgetting='directional', 'efra', ...), SquareRootRLS, or more "
                      "exciting input.")

    def __init__(self, dim_x, dim_z=1, lam=1.0, *, P0=1e4, x0=None, R=1.0, Q=0.0,
                 forgetting="exponential", forgetting_params=None, gate=None,
                 check_every=None, cond_max=1e12):
        self.dim_x = check_dimension(dim_x, "dim_x")
        self.dim_z = check_int(dim_z, "dim_z", minimum=1)
        self._mode = _fg.mode_code(forgetting)
        self._forgetting_params_in = forgetting_params
        self._gate = None
        self._Pi = _EMPTY            # orthogonal projector onto null(A); empty: no constraints
        self.R = R
        self._P0 = check_covariance(P0, self.dim_x, "P0", definite=True)
        self.lam = lam
        self.Q = Q
        self.gate = gate
        self.check_every = check_every
        self.cond_max = _check_positive(cond_max, "cond_max")
        self._x0 = self._as_state(np.zeros((self.dim_x, self.dim_z)) if x0 is None else x0, "x0")
        self._warned_skip = False
        self._batch_start = None     # n_updates when a step-by-step batch_filter started
        self.constraints = None
        self._null_basis = None      # orthonormal basis of null(A), for the health check
        self.reset()

    # ------------------------------------------------------------------
    # state and configuration (assignments copy and validate)
    # ------------------------------------------------------------------
    @property
    def x(self):
        """Parameter estimate, ``(dim_x, dim_z)``; assigning copies the value."""
        return self._x

    @x.setter
    @_locked
    def x(self, value):
        self._x = own_array(value, "x")
        self._recheck = True

    @property
    def P(self):
        """Covariance of the estimate, ``(dim_x, dim_x)``; assigning copies the value."""
        return self._P

    @P.setter
    @_locked
    def P(self, value):
        self._P = own_array(value, "P")
        self._recheck = True
        self._cap, self._w = False, 1.0     # the windup cap decides again from the new P

    @property
    def R(self):
        """Measurement-noise variance (a positive float). The forgetting mode's constants
        that default to a multiple of it (``forgetting_params['trace']`` of the constant
        trace mode) follow an assignment, as they follow one of `lam`."""
        return self._R

    @R.setter
    @_locked
    def R(self, value):
        r = check_variance(value, "R")
        if "_lam" not in self.__dict__:               # in __init__: configured with lam
            self._R = r
            return
        old, self._R = self._R, r
        try:
            self._set_lam(self._mode, self._lam)     # the defaults that depend on R
        except BaseException:
            self._R = old
            raise

    @property
    def lam(self):
        """Forgetting factor in (0, 1]; with ``forgetting="diagonal"`` the factors of
        the parameters, a read-only array of shape ``(dim_x,)`` (assign a number or an
        array of that shape)."""
        return self._lam

    @lam.setter
    @_locked
    def lam(self, value):
        self._set_lam(self._mode, value)

    def _set_lam(self, mode, value):
        """Validate `value` for forgetting `mode` and configure it (all checks first)."""
        if mode == _fg.DIAGONAL:
            lam = _fg.diagonal_lam(value, self.dim_x)
            lam_min = float(lam.min())
        else:
            if np.ndim(value) and np.size(value) > 1:
                raise ValueError(
                    f"`lam` must be a number for forgetting={_fg.MODES[mode]!r}; got an array "
                    f"of shape {np.shape(value)} (one factor per parameter: "
                    "forgetting='diagonal')")
            lam = lam_min = check_lam(value)
        params = _fg.mode_params(mode, self._forgetting_params_in, self.dim_x, lam_min,
                                 self._R, float(np.trace(self._P0)))
        self._mode, self._lam, self._params = mode, lam, params
        # predict: P / lam (exponential); P / sqrt(lam_i lam_j) (diagonal: 1 / min lam here,
        # not 1 when it forgets: the kernels read the factors from the configuration)
        self._il = 1.0 / lam_min if mode in _fg.TIME_UPDATE_MODES else 1.0
        self._configure()

    @_locked
    def _forget_per_parameter(self, lam):
        """Switch an exponential (or diagonal) filter to ``forgetting="diagonal"`` with the
        factors `lam` (`TuneResult.apply` of ``"lam_diag"``; the state and the windup
        cap's decision are kept: both modes forget in the time update)."""
        if self._mode not in _fg.TIME_UPDATE_MODES:
            raise ValueError("a diagonal forgetting factor applies to a filter with "
                             "forgetting='exponential' or 'diagonal'; got "
                             f"forgetting={self.forgetting!r}")
        self._set_lam(_fg.DIAGONAL, lam)

    @property
    def forgetting(self):
        """Forgetting mode (read-only; chosen at construction)."""
        return _fg.MODES[self._mode]

    @forgetting.setter
    def forgetting(self, value):
        refuse_fixed(self, "forgetting", "construct a new filter with forgetting=...")

    @property
    def forgetting_params(self):
        """The constants of the forgetting mode, defaults filled in (a new dict;
        read-only, chosen at construction)."""
        return dict(zip(_fg._PARAM_NAMES[self._mode], self._params, strict=True))

    @forgetting_params.setter
    def forgetting_params(self, value):
        refuse_fixed(self, "forgetting_params",
                     "construct a new filter with forgetting_params=...")

    @property
    def gate(self):
        """Outlier gate on the normalized residual, or None (off)."""
        return self._gate

    @gate.setter
    @_locked
    def gate(self, value):
        self._gate = None if value is None else _check_positive(value, "gate")
        self._configure()

    @property
    def Q(self):
        """Parameter random-walk covariance, ``(dim_x, dim_x)``."""
        return self._Q

    @Q.setter
    @_locked
    def Q(self, value):
        self._Q = check_covariance(value, self.dim_x, "Q")
        self._Q_kernel = self._Q if self._Q.any() else _EMPTY

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    def predict(self, u=None, B=None, F=None, Q=None):
        r"""Time update :math:`P \leftarrow P / \lambda + Q`.

        The estimate ``x`` is unchanged (constant or random-walk
        parameters). With ``lam = 1`` and ``Q = 0`` this only records
        ``x_prior`` and ``P_prior``. With ``forgetting="diagonal"`` it is
        :math:`P \leftarrow L^{-1/2} P L^{-1/2} + Q`, ``L = diag(lam)``. For
        the other forgetting modes the division by `lam` is not done here (their
        forgetting needs the regressor and happens in :meth:`update`); only
        ``Q`` is added.

        Parameters
        ----------
        u, B, F : None
            filterpy's control input, control matrix and state transition:
            not used by least squares (``F = I``, no control input), so any
            value raises a `TypeError` (a positional argument is `u`, not `Q`).
        Q : float or array_like, optional
            Random-walk covariance for this call only; ``self.Q`` if omitted.
        """
        with self._lock:                                  # one call at a time (threads)
            # validate
            if u is not None or B is not None or F is not None:
                self._refuse_control(u, B, F)             # filterpy's arguments: raise
            Q = self._Q_kernel if Q is None else self._random_walk(Q)
            if self.frozen:                               # adaptation off: x, P unchanged
                return self._frozen_predict()
            x, P = self._state() if self._recheck else (self._x, self._P)
            # one compiled step (_kernels.predict_kernel) into a new array:
            #   x^- = x               (constant, or random-walk, parameters)
            #   P^- = P / lam + Q     (exponential mode: filterpy's fading memory; the windup
            #                          cap holds 1 / lam back, the next update forgets along H)
            #   P^- = L^-1/2 P L^-1/2 + Q   (diagonal mode, L = diag(lam): P_ij / sqrt(lam_i
            #                          lam_j); the cap likewise)
            #   P^- <- Pi P^- Pi      (constraints: keep A P = 0)
            il = 1.0 if self._cap else self._il
            P_prior = np.empty(P.shape)
            _streaming.kernels().predict_kernel(P, il, Q, self._cfg, P_prior)
            self._commit_predict(x, P_prior)

    def _commit_predict(self, x, P_prior):
        """The state change of :meth:`predict`, after its compiled step."""
        self._x, self._P = x, P_prior
        self.x_prior, self.P_prior = x.copy(), P_prior.copy()
        self._w = self._il if self._cap else 1.0          # 1 / lam held back for the update
        self._updates_since_predict = 0
        self._recheck = self._efra_pending = False

    def update(self, z, H=None, R=None):
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
        H : array_like, shape (dim_x,) or (1, dim_x), optional
            Regressor row (the notes' :math:`\phi_k`); ``self.H`` if omitted
            (filterpy's convention). The row used is stored in ``self.H``.
        R : float, optional
            Measurement-noise variance for this call only.
        """
        with self._lock:                                  # one call at a time (threads)
            if self.frozen:                               # adaptation off: only diagnostics
                return self._frozen_update(z, H, R)
            # validate (the row's finiteness: by the compiled step, flag _BAD_ROW)
            H = self._row(H)                              # a new (1, dim_x) row
            z, missing = self._column(z)                  # a new (dim_z, 1) column; NaN: missing
            r = self._R if R is None else check_variance(R, "R")
            x, P = self._state() if self._recheck else (self._x, self._P)
            xn, Pn, y, K, S, SI = _step_arrays(self.dim_x, self.dim_z)
            # one compiled step (_kernels.update_kernel) into those new arrays:
            #   y = z - H x              a-priori residual
            #   S = H P H^T + R          innovation variance
            #   K = P H^T / S            gain
            #   x = x + K y^T            (missing or gated: x unchanged, K = 0)
            #   P = P - K S K^T          (the other forgetting modes: their update)
            #   P <- Pi P Pi             (constraints)
            flags, lam_t = _streaming.kernels().update_kernel(x, P, H, z, r, self._cfg, self._w,
                                                              xn, Pn, y, K, S, SI)
            self._commit_update(H, z, missing, xn, Pn, y, K, S, SI, flags, lam_t)

    def _commit_update(self, H, z, missing, xn, Pn, y, K, S, SI, flags, lam_t):
        """The decisions and the state change of :meth:`update`, after its compiled step."""
        n_updates = self.n_updates + 1
        self._check_step(flags, H, Pn, n_updates)         # raises or warns: nothing changed yet
        # commit
        self._x, self._P = xn, Pn
        self.x_post, self.P_post = xn.copy(), Pn.copy()
        self.H, self.z, self.y, self.K, self.S, self.SI = H, z, y, K, S, SI
        self._lazy = MISSING_DIAGNOSTICS if missing else None
        self.gated = (flags & _GATED) != 0
        self.n_gated += self.gated
        self.n_capped += self._w != 1.0
        self._cap, self._w = (flags & _CAP) != 0, 1.0
        self.lam_t = lam_t
        self.n_updates = n_updates
        self._updates_since_predict += 1
        self._recheck = self._efra_pending = False

    def _vector_step_constants(self):
        """``(il, Q, cfg, R, check_every)`` of `_kernels_vector.vector_step` (copies), or
        None while frozen (a frozen filter's step changes neither ``x`` nor ``P``) and for
        a subclass (whose methods may step otherwise)."""
        if self.frozen or type(self) is not RecursiveLeastSquares:
            return None
        return (float(self._il), self._Q_kernel.copy(), self._cfg.copy(), float(self._R),
                int(self._check_every))

    def _check_step(self, flags, H, P, n_updates):
        """The decisions of `update` before it commits (`flags` of ``update_kernel``,
        `P` the new covariance): raise for a non-finite row, warn for a skipped
        forgetting or a failed health check; all before the state changes (a
        warning turned into an error leaves the filter as it was)."""
        every = self._check_every
        due = every and not n_updates % every
        if not (flags or due or self._updates_since_predict):
            return                                    # the ordinary step: nothing to decide
        if flags & _BAD_ROW:
            check_finite(H[0], "H")                   # raises
        bad = (flags & _BAD_DIAGONAL) != 0
        skipped = (self._updates_since_predict and not self._warned_skip and self._forgets)
        checked = due or (every and bad and not self._warned_health)
        problem = self._health_problem(P, n_updates, bad) if checked else None
        if skipped or (problem is not None and not self._warned_health):
            self._warn(skipped, problem)              # warn before the state changes
        elif due and problem is None:
            self._warned_health = False               # healthy again: the next problem warns

    # ------------------------------------------------------------------
    # batch start and batch runs
    # ------------------------------------------------------------------
    @_locked
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
        from scipy.linalg import solve_triangular  # lazy: keeps `import rlsfilt` light
        Z, Hm = self._as_batch(zs, Hs)
        # (diagonal forgetting has no weighted least-squares form: its batch start does
        # not weight the rows)
        lam = 1.0 if self._mode == _fg.DIAGONAL else self._lam
        w = lam ** (0.5 * np.arange(len(Z) - 1, -1, -1.0))
        keep = ~np.isnan(Z).any(axis=1)
        A = Hm[keep] * w[keep, None]
        B = Z[keep] * w[keep, None]
        # columns scaled to unit norm, so that neither the rank decision nor the
        # QR depends on the units of the regressors (1e-8 beside 1e6 is not rank
        # deficiency); the solution is scaled back exactly: x = D^-1 x_s,
        # (A^T A)^-1 = D^-1 (A_s^T A_s)^-1 D^-1
        norms = safe_norm(A, axis=0) if len(A) else np.ones(self.dim_x)
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
        x = solve_triangular(Rf, Qf.T @ B) / d[:, None]
        Rinv = solve_triangular(Rf, np.eye(self.dim_x)) / d[:, None]   # D^-1 R_s^-1
        with np.errstate(over="ignore", under="ignore"):
            P = self._R * (Rinv @ Rinv.T)
        if not (np.isfinite(P).all() and np.isfinite(x).all() and (np.diag(P) > 0).all()):
            raise ValueError(
                f"`Hs` (largest entry {np.abs(Hm).max():.3g}) gives a covariance "
                "R (Hs^T Hs)^-1 outside the range of double precision; scale the regressors")
        self._x = np.ascontiguousarray(x)
        self._P = np.ascontiguousarray(0.5 * (P + P.T))
        self._efra_pending = self._mode == _fg.EFRA
        self._recheck = True
        if self.constraints is not None:   # keep the constraints given earlier
            self._impose(*self.constraints, *self.constraints, fresh=True)
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self.P_prior, self.P_post = self._P.copy(), self._P.copy()
        self._updates_since_predict = 0
        self._cap, self._w = False, 1.0

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
            returned as ``None``), so memory stays O(N dim_x dim_z): one
            array of estimates, of which `means` and `means_p` are views.

        Returns
        -------
        means : ndarray, shape (N, dim_x, dim_z)
            Estimates after each update.
        covariances : ndarray, shape (N, dim_x, dim_x), or None
            ``P`` after each update.
        means_p : ndarray, shape (N, dim_x, dim_z)
            Estimates after each predict (a predict does not change the
            estimate: a read-only view of the estimate before each update,
            sharing memory with `means`).
        covariances_p : ndarray, shape (N, dim_x, dim_x), or None
            ``P`` after each predict.

        Raises
        ------
        ValueError
            If `zs`, `Hs` (and `Rs`) disagree in length; filterpy's
            ``KalmanFilter`` would silently truncate.

        Notes
        -----
        The loop runs in compiled code (numba, cached on disk after the first
        call): the compiled steps that :meth:`predict` and :meth:`update` call,
        one pair per sample. With exponential forgetting (the default), one
        output and no gate or constraints, one vectorized sweep over ``P`` per
        step applies the update, the next forgetting step and the next gain
        together (the same numbers, bit for bit; with the covariance histories
        in two halves, ``P`` stored after each), and the record is processed
        at tens of nanoseconds per sample for small ``n = dim_x`` (see
        ``docs/performance.md``).

        **Records larger than memory.** Call :meth:`batch_filter` on
        consecutive chunks (for example slices of ``np.load(path,
        mmap_mode="r")``) with ``store_covariances=False``: the filter carries
        its whole state from one call to the next, so the estimates are
        bitwise those of one call over the whole record, and memory is that
        of one chunk.

        Every forgetting mode, the gate and the constraints apply exactly as
        in the step-by-step loop (the results are bitwise equal); gated
        samples are added to ``n_gated``. The health check of ``P`` runs
        every ``check_every`` steps inside the loop and once at the end, so
        a failure is reported with its step in the record.
        """
        return self._batch(zs, Hs, Rs, update_first, saver, store_covariances)

    def _batch_compiled(self, Z, Hm, Rv, update_first, store_covariances):
        """`batch_filter` in one compiled call (`_kernels.run_batch`); leaves the
        filter as the step-by-step loop would, and changes nothing if it raises."""
        out = self._run_batch(Z, Hm, Rv, update_first, store_covariances)
        return out.means, out.covariances, out.means_p, out.covariances_p

    def _run_batch(self, Z, Hm, Rv, update_first, store_covariances, lead=0, residuals=False,
                   scales=None, lags=None):
        """`_batch_compiled` on a validated record ``Z`` (N, dim_z), ``Hm`` (N, dim_x),
        ``Rv`` (N,); returns the kernel's `BatchResult`. `lead`, `residuals`, `scales` and
        `lags` as in `_kernels.run_batch` (``ARX.fit`` runs in scaled units on rows read
        from its signals, ``Hm`` None, and takes the histories and every a-priori
        residual from the result)."""
        P = self._checked_P()
        if self._efra_pending:
            P = self._efra_start(P)
        kern = _streaming.kernels()
        state = (0.0 if self._warned_health else 1.0, 0.0, 0.0, float(self._cap), self._w)
        out = kern.run_batch(
            self._checked_x(), P, Z, Hm, Rv, self._cfg,
            None if self._Q_kernel is _EMPTY else self._Q, self._null_basis, update_first,
            store_covariances, self.check_every, self.n_updates, self.cond_max, state, lead,
            residuals, scales, lags)
        N, problems = len(Z), []
        armed, episodes = out.state[0] == 1.0, int(out.state[1])
        for e, k in enumerate(out.episodes[:min(episodes, kern.MAX_EPISODES)]):
            problems.append((_health.symmetric_problem(out.P_fail[e], self.cond_max,
                                                       self._null_basis)
                             or "`P` failed the health check")
                            + _health.at_step(int(k), self.n_updates + int(k) + 1))
        if episodes > kern.MAX_EPISODES:
            problems.append(f"`P` failed the health check {episodes - kern.MAX_EPISODES} more "
                            "times in this batch_filter (each after a healthy check)")
        if armed and self.check_every:                # the end-of-batch check
            problem = self._health_problem(out.P, self.n_updates + N, False)
            if problem is not None:
                problems.append(problem)
                armed = False
        for problem in problems:                      # before the state changes
            _health.warn(problem, self._HEALTH_ADVICE)
        self._warned_health = not armed
        self._cap, self._w = out.state[3] == 1.0, float(out.state[4])
        self.n_capped += int(out.state[2])
        self._x, self._P = np.ascontiguousarray(out.x), np.ascontiguousarray(out.P)
        self.x_prior, self.P_prior, self.x_post, self.P_post = (out.x_prior, out.P_prior,
                                                                out.x_post, out.P_post)
        self._clear_lazy()
        self.H = out.H_last.reshape(1, -1).copy()
        self.S, self.SI = out.s_last * self._I_z, self._I_z / out.s_last
        self.K = out.K_last
        if np.isnan(Z[-1]).any():
            self.z = np.full((self.dim_z, 1), np.nan)
            self.y = np.full((self.dim_z, 1), np.nan)
            self._lazy = MISSING_DIAGNOSTICS
        else:
            self.z = out.z_last.reshape(-1, 1).copy()
            self.y = out.y_last.reshape(-1, 1).copy()
        self._updates_since_predict = 0 if update_first else 1
        self.n_updates += N
        self.n_gated += int(out.gated.sum())
        self.gated = bool(out.gated[-1])
        self.lam_t = out.lam_t_last
        self._recheck = self._efra_pending = False
        return out

    # ------------------------------------------------------------------
    # equality constraints
    # ------------------------------------------------------------------
    @_locked
    def constrain(self, A, b):
        r"""From now on keep the estimate on the affine set ``A x = b`` as well.

        Constraints accumulate: each call adds its rows to those given
        before (:attr:`constraints` holds them all), and the estimate then
        satisfies every one. The state and covariance are projected once,
        with the new rows only (Zhu & Li 2007):

        .. math::

            W &= P A^T (A P A^T)^{-1} \\
            x &\leftarrow x + W (b - A x), \qquad P \leftarrow P - W A P

        after which :math:`A P = 0` for every row given so far (the earlier
        rows already had it, and :math:`A_{old} W = 0`), so every gain
        satisfies :math:`A K = 0` and plain updates keep all of them.
        Conditioning on the rows one call at a time is conditioning on all
        of them at once, so started from :meth:`initialize` with
        ``lam = 1`` the estimate is, at every later step, the
        equality-constrained least-squares estimate (the KKT solution) on
        all data so far under all constraints given so far, as statsmodels'
        ``RecursiveLS(constraints=...)``. ``P`` is then singular (rank
        ``dim_x - p``); the health check tests it on the null space of the
        constraints. :meth:`reset` and :meth:`initialize` impose them all
        again on their fresh ``x`` and ``P``.

        Parameters
        ----------
        A : array_like, shape (p, dim_x) or (dim_x,)
            Constraint rows, independent of each other and of the rows
            given before, fewer than ``dim_x`` in all.
        b : float or array_like, shape (p,) or (p, dim_z)
            Right-hand side; one column per output when ``dim_z > 1`` (a
            1-D `b` applies to every output).

        Returns
        -------
        self

        Raises
        ------
        ValueError
            When a row is redundant (implied by the others: the same or a
            combination of constraints already given) or conflicting (no
            ``x`` satisfies all of them), or when all constraints together
            would fix every parameter. The filter is left as it was.
        """
        n, m = self.dim_x, self.dim_z
        A = as_float_array(A, "A")
        if A.ndim == 1:
            A = A.reshape(1, -1)
        if A.ndim != 2 or A.shape[1] != n:
            raise ValueError(f"`A` must have shape (p, {n}) (dim_x = {n} columns); got {A.shape}")
        check_finite(A, "A")
        p = A.shape[0]
        rank = _row_rank(A)
        if rank != p or p >= n:
            raise ValueError(f"`A` must have full row rank p < dim_x = {n}; got {p} rows of "
                             f"rank {rank}")
        bb = check_finite(as_float_array(b, "b"), "b")
        if bb.ndim <= 1 and bb.size == p:
            bb = np.repeat(bb.reshape(p, 1), m, axis=1)
        if bb.shape != (p, m):
            raise ValueError(f"`b` must have shape ({p},) or ({p}, {m}); got {bb.shape}")
        A_all, b_all = A, bb
        if self.constraints is not None:
            A_all = np.vstack([self.constraints.A, A])
            b_all = np.vstack([self.constraints.b, bb])
            if A_all.shape[0] >= n:
                raise ValueError(
                    f"`A` adds {p} row(s) to the {A_all.shape[0] - p} constraint(s) given "
                    f"before: {A_all.shape[0]} constraints would fix all dim_x = {n} "
                    "parameters; at most dim_x - 1 can be imposed")
            if _row_rank(A_all) < A_all.shape[0]:
                c = _row_norms(A_all)
                x_ls = np.linalg.lstsq(A_all / c[:, None], b_all / c[:, None], rcond=None)[0]
                A_all, b_all = A_all / c[:, None], b_all / c[:, None]
                gap = np.abs(A_all @ x_ls - b_all).max()
                size = np.abs(b_all).max() + np.abs(A_all).max() * np.abs(x_ls).max()
                if gap <= 1e-9 * max(size, np.finfo(float).tiny):
                    raise ValueError(
                        "`A`, `b` are redundant: the constraint is implied by the ones given "
                        "before (the rows of all constraints are linearly dependent); "
                        "constrain only new directions")
                raise ValueError(
                    "`A`, `b` conflict with the constraints given before: no estimate "
                    "satisfies all of them (a row of `A` is a combination of earlier rows, "
                    "with a different right-hand side)")
        self._impose(A, bb, A_all, b_all)
        return self

    def _impose(self, A, bb, A_all, b_all, fresh=False):
        """Project ``x`` and ``P`` onto ``A x = bb`` (the rows to add) and configure the
        projector onto the null space of all constraints ``A_all``. `fresh`: ``x``
        and ``P`` are new (reset, initialize) and ``A`` is all of them. Computes
        everything first: a failure leaves the filter as it was."""
        # each row scaled to unit norm with its right-hand side (the same constraint), so
        # that A P A^T neither overflows nor underflows for rows in any units
        c = _row_norms(A)
        A, bb = A / c[:, None], bb / c[:, None]
        x, P = self._checked_x(), self._checked_P()
        if self._efra_pending:    # EFRA's start; projected only onto the constraints kept
            lo, hi = _fg.efra_bounds(self._lam, *self._params)
            P = _fg.clip_eigenvalues(P, lo * self._R, hi * self._R)
            if not fresh:
                P = self._projected(P)
        PA = P @ A.T
        M = A @ PA
        try:
            W = np.linalg.solve(M, PA.T).T             # W = P A^T (A P A^T)^-1
        except np.linalg.LinAlgError:
            raise ValueError("`A`: the covariance `P` carries no uncertainty in the "
                             "constrained directions (A P A^T is singular), so the estimate "
                             "cannot be moved onto the constraint; reset() or initialize() "
                             "first") from None
        from scipy.linalg import null_space  # lazy: keeps `import rlsfilt` light
        basis = null_space(A_all / _row_norms(A_all)[:, None])
        Pi = np.ascontiguousarray(basis @ basis.T)
        x_new = x + W @ (bb - A @ x)                   # x <- x + W (b - A x)
        P_new = self._projected(P - W @ PA.T, Pi)      # P <- P - W A P, then Pi P Pi
        self._x, self._P = np.ascontiguousarray(x_new), np.ascontiguousarray(P_new)
        self._Pi = Pi
        self._configure()
        self._null_basis = basis
        self._recheck = True
        self._efra_pending = False                     # P above has EFRA's start
        self.constraints = EqualityConstraints(A_all, b_all)
        self.x_post, self.P_post = self._x.copy(), self._P.copy()

    # ------------------------------------------------------------------
    # filterpy helpers: smoothing and tuning (rlsfilt.filters.smoother, .tuning)
    # ------------------------------------------------------------------
    def rts_smoother(self, Xs, Ps, Fs=None, Qs=None, inv=None):
        """filterpy's ``KalmanFilter.rts_smoother`` with ``F = I``: returns ``(x, P, K, Pp)``.

        `Xs` (N, dim_x) or (N, dim_x, dim_z) and `Ps` (N, dim_x, dim_x) are the
        posteriors of a run (``batch_filter``'s first two results); the priors
        are ``Ps[t] / lam + Qs[t + 1]`` (``self.Q`` when `Qs` is omitted). See
        `rlsfilt.filters.smoother.rts_smoother` for the recursion. The signature
        is filterpy's, ``(Xs, Ps, Fs=None, Qs=None, inv=...)``: `Fs` and `inv`
        (state transitions, matrix inverse) must be None (``F = I``; nothing is
        inverted), else a `TypeError` names them, so that a positional ``Fs``
        is never taken as ``Qs``.
        """
        for name, value in (("Fs", Fs), ("inv", inv)):
            if value is not None:
                raise TypeError(
                    f"`{name}` is not an argument {type(self).__name__}.rts_smoother() uses: "
                    "least squares has F = I and inverts no matrix (filterpy's "
                    f"rts_smoother(Xs, Ps, Fs, Qs, inv)); got {name} of type "
                    f"{type(value).__name__}. A random walk is Qs=...")
        return _smoother.filter_rts_smoother(self, Xs, Ps, Qs)

    def smooth(self, zs, Hs, Rs=None):
        """``batch_filter(zs, Hs, Rs)``, then the Rauch-Tung-Striebel smoother of the run.

        Returns a `rlsfilt.filters.smoother.SmoothedTrajectory` (smoothed and
        filtered estimates and covariances, ``.plot()``); the filter ends where
        ``batch_filter`` leaves it. See `rlsfilt.filters.smoother.rts_smoother`.
        """
        return _smoother.smooth(self, zs, Hs, Rs)

    def tune(self, zs, Hs, param="q", *, bounds=None, burn=0, apply=False):
        """Maximum likelihood of ``lam`` or of the random walk ``Q`` (and ``R``) on a record.

        Returns a `rlsfilt.filters.tuning.TuneResult`; see
        `rlsfilt.filters.tuning.tune` for the parameters and the likelihood.
        """
        return _tuning.tune(self, zs, Hs, param, bounds=bounds, burn=burn, apply=apply)

    # ------------------------------------------------------------------
    # the filter contract (rlsfilt.filters.contract.Filter)
    # ------------------------------------------------------------------
    supports_constraints = True

    @property
    def forgets(self):
        """Whether :meth:`predict` changes ``P`` (``lam < 1`` in the time update, or ``Q``)."""
        return self._forgets

    @_locked
    def get_state(self):
        """Copies of the state a resumed run needs: ``x``, ``P``, the counters, the
        windup cap's decision for the next time update (``cap``, ``w``), EFRA's
        pending start and the health check's memory (see `rlsfilt.filters.contract`).
        A pending :meth:`predict` is included in ``P``."""
        return {"x": self.x.copy(), "P": self.P.copy(), "n_updates": int(self.n_updates),
                "efra_pending": bool(self._efra_pending), "n_capped": int(self.n_capped),
                "cap": bool(self._cap), "w": float(self._w), "n_gated": int(self.n_gated),
                "gated": bool(self.gated), "lam_t": float(self.lam_t),
                "warned_health": bool(self._warned_health),
                "updates_since_predict": int(self._updates_since_predict),
                "recheck": bool(self._recheck)}

    @_locked
    def set_state(self, state):
        """Continue from `state`, a dict from :meth:`get_state` (copied)."""
        s = check_state(self, state)
        self.x, self.P = s["x"], s["P"]
        self.n_updates, self.n_capped, self.n_gated = s["n_updates"], s["n_capped"], s["n_gated"]
        self._efra_pending, self._cap, self._w = s["efra_pending"], s["cap"], s["w"]
        self.gated, self.lam_t = s["gated"], s["lam_t"]
        self._warned_health = s["warned_health"]
        self._updates_since_predict = s["updates_since_predict"]
        self._recheck = s["recheck"]

    @_locked
    def run_record(self, Z, Hm, *, lead=0, residuals=False, scales=None, lags=None):
        """`batch_filter` on a record the caller has validated, for the models.

        ``Z`` (N, dim_z) and ``Hm`` (N, dim_x) (or ``Hm`` None with `lags`: the
        rows read from the signals), the filter's ``R`` for every sample, no
        covariance history; `lead`, `residuals`, `scales` and `lags` as in
        `rlsfilt.filters._kernels.run_batch`. Returns the kernel's
        ``BatchResult`` (the histories ``ARX.fit`` keeps) and leaves the filter
        as ``batch_filter`` would.
        """
        return self._run_batch(Z, Hm, self._as_batch_variances(None, len(Z)), False, False,
                               lead=lead, residuals=residuals, scales=scales, lags=lags)

    def get_prediction(self):
        """Return ``(x, P)`` after a :meth:`predict`, without changing the filter."""
        x, P = self._state()
        P_prior = np.empty_like(P)
        _streaming.kernels().predict_kernel(P, 1.0 if self._cap else self._il, self._Q_kernel,
                                            self._cfg, P_prior)
        return x.copy(), P_prior

    @_locked
    def reset(self):
        """Return to the state given at construction (``x0``, ``P0``).

        ``lam``, ``R``, ``Q``, the forgetting mode and the gate are kept;
        diagnostics and counters are cleared. Constraints given to
        :meth:`constrain` are applied again to ``x0`` and ``P0``.
        """
        self._x, self._P = self._x0.copy(), self._P0.copy()
        self.x_prior, self.P_prior = self._x0.copy(), self._P0.copy()
        self.x_post, self.P_post = self._x0.copy(), self._P0.copy()
        self._reset_diagnostics()
        self._updates_since_predict = 0
        self.gated = False
        self.n_gated = 0
        self.n_updates = 0
        self.n_capped = 0
        self._cap, self._w = False, 1.0     # the windup cap: see predict()
        self.lam_t = float(np.min(self._lam))
        self._warned_health = False
        self._efra_pending = self._mode == _fg.EFRA
        self._recheck = True          # check the state (and start EFRA) at the next step
        if self.constraints is not None:
            self._impose(*self.constraints, *self.constraints, fresh=True)

    def __repr__(self):
        return "\n".join([
            "RecursiveLeastSquares object",
            pretty_str("dim_x", self.dim_x),
            pretty_str("dim_z", self.dim_z),
            pretty_str("lam", self._lam),
            pretty_str("forgetting", self.forgetting),
            pretty_str("gate", self._gate),
            pretty_str("n_gated", self.n_gated),
            pretty_str("x", self._x),
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
    def _row(self, H):
        """`H` (``self.H`` when None) as a new C-contiguous float64 row ``(1, dim_x)``,
        the layout the compiled step is typed for. Its finiteness is tested by the
        compiled step (cheaper than ``np.isfinite`` here)."""
        H = self.H if H is None else H
        if type(H) is np.ndarray and H.dtype is _F8 and H.shape == (self.dim_x,):
            return np.array(H, ndmin=2)        # a copy: C-contiguous whatever H's strides
        return self._as_regressor(H, "H")

    def _column(self, z):
        """`z` as a new float64 column ``(dim_z, 1)`` and whether it is missing (then
        all NaN). The common case, one finite float, skips the general validation."""
        if isinstance(z, float) and self.dim_z == 1 and math.isfinite(z):
            return np.array(z, ndmin=2), False
        z = self._as_measurement(z, "z")
        if z is None:
            return np.full((self.dim_z, 1), np.nan), True
        return z, False

    def _state(self):
        """``(x, P)`` after an assignment or a (re)start: checked for their shapes,
        ``P`` clipped for EFRA's first step (a new array)."""
        # C order: the layout the kernels are compiled (and cached) for
        x, P = self._checked_x(), self._checked_P()
        P = self._efra_start(P) if self._efra_pending else P
        return np.ascontiguousarray(x), np.ascontiguousarray(P)

    def _configure(self):
        """The configuration array the kernels take (mode, lam, gate, constants, Pi)."""
        self._cfg = _fg.kernel_config(self._mode, self._lam, self._params, self._gate,
                                      self._Pi if self._Pi.size else None)

    def _random_walk(self, Q):
        """`Q` of one predict, as the kernels take it ((0, 0) when zero)."""
        Q = check_covariance(Q, self.dim_x, "Q")
        return Q if Q.any() else _EMPTY

    @property
    def _forgets(self):
        """Whether the time update changes ``P`` (forgetting in predict, or ``Q``)."""
        return self._il != 1.0 or self._Q_kernel is not _EMPTY

    def _health_problem(self, P, n_updates, diagonal_bad):
        """The health problem of ``P`` after update `n_updates` (the check is due;
        `diagonal_bad`: the kernel's cheap check failed), or None."""
        kern = _streaming.kernels()
        armed = not self._warned_health              # warned: only the bound re-arms
        # without constraints `unhealthy` itself (`unhealthy_on` with an empty basis is not
        # compiled for it), or `unhealthy_sym` (which the batch loops' check compiled
        # already) when ``P`` is exactly symmetric and ``(P + P^T) / 2`` is ``P`` (no
        # entry whose double overflows): the same decision
        if diagonal_bad:
            bad = True
        elif self._null_basis is not None:
            bad = kern.unhealthy_on(P, self._null_basis, self.cond_max, armed)
        else:
            Pc = np.ascontiguousarray(P, dtype=np.float64)
            if np.array_equal(Pc, Pc.T) and np.all(np.abs(Pc) < 2.0 ** 1023):
                n = len(Pc)
                bad = kern.unhealthy_sym(Pc, float(self.cond_max), np.empty((n, n)),
                                         np.empty((n, n)), armed)
            else:
                bad = kern.unhealthy(Pc, float(self.cond_max), armed)
        if not bad:
            return None
        if not armed:
            return "`P` is not certified healthy"
        problem = _health.symmetric_problem(P, self.cond_max, self._null_basis)
        return None if problem is None else problem + _health.at_update(n_updates,
                                                                        self._batch_start)

    def _final_health_check(self):
        """The full check at the end of a step-by-step `batch_filter`."""
        if self._warned_health or not self.check_every:
            return
        problem = _health.symmetric_problem(self._checked_P(), self.cond_max, self._null_basis)
        if problem is not None:
            self._warn(False, problem + _health.at_update(self.n_updates))

    def _warn(self, skipped, problem):
        """Issue the warnings of a step, before it changes the state (a warning turned
        into an error then leaves the filter as it was)."""
        if skipped:
            _health.warn_at_caller(_health.SKIPPED_FORGETTING, ForgettingSkippedWarning)
            self._warned_skip = True
        self._warn_health(problem)

    def _efra_start(self, P):
        """``P`` clipped into EFRA's invariant interval before its first step (a new array)."""
        lo, hi = _fg.efra_bounds(self._lam, *self._params)
        return self._projected(_fg.clip_eigenvalues(P, lo * self._R, hi * self._R))

    def _projected(self, P, Pi=None):
        """``Pi P Pi`` (a new array; ``P`` itself without constraints). `Pi` is the
        filter's projector unless given."""
        Pi = self._Pi if Pi is None else Pi
        P = np.array(P, dtype=np.float64, order="C")
        if Pi.size:
            _streaming.kernels().project(P, Pi, np.empty(P.shape))
        return P


class EqualityConstraints:
    """The equality constraints ``A x = b`` a filter keeps: every row given to
    `RecursiveLeastSquares.constrain`, stacked.

    Attributes
    ----------
    A : ndarray, shape (p, dim_x)
    b : ndarray, shape (p, dim_z)

    Unpacks as ``A, b = rls.constraints``. (Not a tuple: filterpy's
    ``Saver.to_array`` makes an array of the saved values, which a tuple of
    two arrays of different shapes cannot be.)
    """

    __slots__ = ("A", "b")

    def __init__(self, A, b):
        self.A, self.b = A.copy(), b.copy()

    def __iter__(self):
        return iter((self.A, self.b))

    def __repr__(self):
        return f"EqualityConstraints(A={self.A.tolist()}, b={self.b.tolist()})"


def _step_arrays(n, m):
    """New arrays for the outputs of one ``update_kernel`` call: ``x`` (n, m), ``P``
    (n, n), ``y`` (m, 1), ``K`` (n, 1), ``S`` and ``SI`` (m, m), all C-contiguous
    float64 (the layout the kernel is compiled for). Each step writes into new
    arrays, so an array the filter handed out is never changed afterwards."""
    return (np.empty((n, m)), np.empty((n, n)), np.empty((m, 1)), np.empty((n, 1)),
            np.empty((m, m)), np.empty((m, m)))


def _row_norms(A):
    """2-norms of the rows of `A`, without overflow or underflow (1 for a zero row)."""
    norms = safe_norm(A.T, axis=0)
    return np.where(norms > 0, norms, 1.0)


def _row_rank(A):
    """Numerical rank of the rows of `A` after scaling each to unit norm (a constraint's
    units do not decide whether it is independent)."""
    Au = A / _row_norms(A)[:, None]
    sv = np.linalg.svd(Au, compute_uv=False)
    return int(np.sum(sv > 1e-10 * max(sv[0], np.finfo(float).tiny))) if len(sv) else 0


def _check_positive(value, name):
    value = check_scalar(value, name)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"`{name}` must be a positive finite number; got {value}")
    return value
