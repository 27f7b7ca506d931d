r"""A bank of independent recursive least-squares filters, one per channel.

`RLSBank` runs ``n_channels`` single-output `RecursiveLeastSquares` filters
of the same size side by side: the state has a leading channel axis
(``x`` is ``(C, dim_x)``, ``P`` is ``(C, dim_x, dim_x)``), and one compiled
call updates every channel (:mod:`rlsfilt.filters._kernels_bank`). Each
channel follows the arithmetic of its own `RecursiveLeastSquares` (the same
bits in the exponential and directional modes; the constant-trace rescaling
agrees to round-off, a few units in the last place), so ``bank.channel(i)``
is an ordinary filter that continues where channel ``i`` of the bank stands.

The state arrays the bank makes (``x``, ``P``, their priors and
posteriors, ``K``, ``Q``) are stored in Fortran order, the channel index
varying fastest: their transposes (``x.T`` is ``(dim_x, C)``) are the
C-contiguous arrays the kernels read and write along the channels, with no
copy or transposition per call. An array assigned in another layout is
copied into this one once, at its next use.

A streaming step does no work it need not do. :meth:`RLSBank.predict`
only records the time update (``_pending``); the next
:meth:`RLSBank.update` applies it as its compiled call loads the state
(one pass instead of two), and reading ``P`` or ``P_prior``, assigning
the state, :meth:`RLSBank.batch_filter`, a second ``predict()`` or
:meth:`RLSBank.channel` runs it before, exactly as an immediate time update
would. The copies ``x_prior``, ``P_prior``, ``x_post``, ``P_post`` are
made when they are first read (`_Lazy`), from arrays the bank never
writes into; an array the bank has handed out (through ``x`` or ``P``)
may be written into by its holder, so every copy still pending on it is
made first. Every attribute read has the bits of the eager recursion.
"""

import copy
import math
import threading

import numpy as np

from .._display import bank_html, edge_indices, pretty_str
from .._lazy import lazy_module
from .._locking import atomic as _atomic
from .._locking import init_signature
from .._locking import locked as _locked
from .._validation import (
    COVARIANCE_MAX,
    VARIANCE_RANGE,
    as_float_array,
    check_bool,
    check_covariance,
    check_dimension,
    check_int,
    check_length,
    check_scalar,
)
from ..exceptions import ForgettingSkippedWarning, NumericalWarning
from . import _health
from . import forgetting as _fg
from ._base import refuse_fixed, register_filter_class

__all__ = ["RLSBank", "BankHistory"]

#: The forgetting modes `RLSBank` runs (the command line offers these).
MODES = ("exponential", "directional", "constant_trace")
# the keys of `forgetting_params` each mode of the bank reads (its kernels know no others)
_SUPPORTED_PARAMS = {"exponential": ("spread_max", "trace_max"), "directional": ("eps",),
                     "constant_trace": ("trace", "ratio")}
_LOG_2PI = math.log(2.0 * math.pi)
_TINY = np.finfo(float).tiny
_get_kernels = lazy_module("rlsfilt.filters._kernels_bank")


class _Lazy:
    """A state copy of the bank (``x_prior``, ``P_prior``, ``x_post``,
    ``P_post``) made when it is first read: the attribute ``_<name>`` holds
    either the array or the ``(source, il, Qt, q_zero)`` it is made from, the
    source an array of the bank's layout that nobody writes into; the copy
    is ``source`` itself (``il`` None) or its time update ``source * il +
    Q`` (by `bank_predict`, as :meth:`RLSBank.predict` makes it)."""

    def __init__(self, doc):
        self.__doc__ = doc

    def __set_name__(self, owner, name):
        self.key = "_" + name

    def __get__(self, bank, owner=None):
        if bank is None:
            return self
        with bank._lock:
            value = bank.__dict__[self.key]
            if type(value) is tuple:
                value = _made(value)
                bank.__dict__[self.key] = value
            return value

    def __set__(self, bank, value):
        with bank._lock:
            bank._settle_pending()   # the predict before keeps its P_prior, as if it had run
            bank.__dict__[self.key] = value


def _made(lazy):
    """The array a `_Lazy` entry ``(source, il, Qt, q_zero)`` stands for."""
    src, il, Qt, q_zero = lazy
    if il is None:
        return src.copy(order="F")
    Pt = _t(src)
    Pn, P_prior = np.empty_like(Pt), np.empty_like(Pt)
    _get_kernels().bank_predict(Pt, il, Qt, q_zero, Pn, P_prior)
    return P_prior.T


def _supported_params(forgetting, params):
    """A copy of the user's `forgetting_params`, holding only keys that the bank's
    `forgetting` mode reads (a key only `RecursiveLeastSquares` reads is refused
    here rather than silently ignored by the bank's kernels)."""
    if params is None:
        return None
    if not isinstance(params, dict):
        raise TypeError(f"`forgetting_params` must be a dict or None; got "
                        f"{type(params).__name__}")
    supported = _SUPPORTED_PARAMS[forgetting]
    for key in params:
        if key not in supported:
            raise ValueError(
                f"`forgetting_params` key {key!r} is not supported by RLSBank (mode "
                f"{forgetting!r}); supported: {', '.join(map(repr, supported)) or 'none'}")
    return dict(params)


class BankHistory:
    """What :meth:`RLSBank.batch_filter` returns.

    It unpacks like filterpy's ``batch_filter`` result, ``means,
    covariances, means_p, covariances_p = bank.batch_filter(zs, Hs)``, and
    also holds the residual histories.

    Attributes
    ----------
    means, means_p : ndarray, shape (N, C, dim_x), or None
        Estimates after each update and after each predict (None with
        ``store_means=False``).
    covariances, covariances_p : ndarray, shape (N, C, dim_x, dim_x), or None
        ``P`` after each update and after each predict (None with
        ``store_covariances=False``).
    residuals : ndarray, shape (N, C), or None
        A-priori residuals :math:`z - H x^-` of each step and channel (NaN
        where the channel skipped the step; None with
        ``store_residuals=False``).
    innovation_variances : ndarray, shape (N, C), or None
        :math:`S = H P^- H^T + R` (NaN where the regressor held NaN), so
        that ``residuals / sqrt(innovation_variances)`` are the recursive
        residuals of each channel (None with ``store_residuals=False``).
    """

    def __init__(self, means, covariances, means_p, covariances_p, residuals,
                 innovation_variances, shape=None):
        self.means = means
        self.covariances = covariances
        self.means_p = means_p
        self.covariances_p = covariances_p
        self.residuals = residuals
        self.innovation_variances = innovation_variances
        self._shape = residuals.shape if shape is None else tuple(shape)

    def __iter__(self):
        return iter((self.means, self.covariances, self.means_p, self.covariances_p))

    def __len__(self):
        return 4

    def __getitem__(self, index):
        return (self.means, self.covariances, self.means_p, self.covariances_p)[index]

    def __repr__(self):
        N, C = self._shape
        return f"<BankHistory: {N} steps of {C} channels>"


class BankBase:
    """What every bank of filters shares: its lock (in a slot, outside ``__dict__``,
    which filterpy's Saver deep-copies and `_atomic` restores; made in ``__new__``,
    so copies and unpickled banks get their own), ``copy`` and filterpy's
    diagnostics per channel from the last residuals ``y`` and their variances
    ``S`` (``(C,)`` each; ``_fresh`` before any update). `RLSBank` and
    `rlsfilt.filters.gradient_bank.GradientBank` derive from it."""

    __slots__ = ("_lock", "__dict__", "__weakref__")
    #: The settings whose assignment the bank honours; every other setting of a filter
    #: (`rlsfilt.filters._base.option_names`) is refused by name, as by the filters.
    _options = frozenset({"x", "R"})

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        register_filter_class(cls)

    def __new__(cls, *args, **kwargs):
        self = super().__new__(cls)
        self._lock = threading.RLock()
        return self

    def __getstate__(self):
        """The attributes without the lock, read under it (pickle, copy, deepcopy)."""
        with self._lock:
            return self.__dict__.copy()

    def __setstate__(self, state):
        self._lock = threading.RLock()      # (made by __new__ too; not by pickle protocol 0, 1)
        self.__dict__.update(state)

    def copy(self):
        """An independent deep copy of the bank."""
        return copy.deepcopy(self)

    @property
    def log_likelihood(self):
        """``log N(y; 0, S)`` of each channel's last measurement, shape (C,)
        (0 where the channel skipped it; ``log(tiny)`` before any update)."""
        if self._fresh:
            return np.full(self.n_channels, math.log(_TINY))
        with np.errstate(invalid="ignore", divide="ignore"):
            ll = -0.5 * (_LOG_2PI + np.log(self.S) + self.y * self.y / self.S)
        return np.where(np.isnan(self.y), 0.0, ll)

    @property
    def likelihood(self):
        """``exp(log_likelihood)``, floored at the smallest positive float, shape (C,)."""
        return np.maximum(np.exp(self.log_likelihood), _TINY)

    @property
    def mahalanobis(self):
        """``|y| / sqrt(S)`` of each channel's last residual, shape (C,) (NaN where skipped)."""
        if self._fresh:
            return np.zeros(self.n_channels)
        with np.errstate(invalid="ignore"):
            return np.abs(self.y) / np.sqrt(self.S)


class RLSBank(BankBase):
    r"""``n_channels`` independent recursive least-squares filters updated together.

    Channel ``c`` estimates ``x[c]`` in its own regression
    :math:`z_{k,c} = H_{k,c}\, x_c + v_{k,c}`, with its own forgetting
    factor, noise variance and random walk, as a
    :class:`~rlsfilt.RecursiveLeastSquares` with ``dim_z = 1`` would (bit for
    bit, except the constant-trace mode: to round-off); the
    bank runs all channels in one compiled call per :meth:`update` and per
    :meth:`batch_filter`, which for thousands of small filters is one to
    two orders of magnitude faster than a Python loop over filters (see
    ``docs/performance.md``).

    A bank shared by threads applies each call whole: every public call that
    changes its state (and every read that settles a deferred
    :meth:`predict`) holds the bank's own reentrant lock; copies and pickles
    get their own.

    Parameters
    ----------
    n_channels : int
        Number of channels ``C``.
    dim_x : int
        Number of parameters of every channel.
    lam : float or array_like of shape (C,), default 1.0
        Forgetting factor in (0, 1], shared or one per channel.
    Q : float or array_like, default 0.0
        Random walk added to ``P`` by :meth:`predict`: a scalar ``q``
        (``q I`` for every channel), one scalar per channel (shape
        ``(C,)``), one matrix for all channels ``(dim_x, dim_x)``, or one
        matrix per channel ``(C, dim_x, dim_x)``.
    R : float or array_like of shape (C,), default 1.0
        Measurement-noise variance, shared or one per channel.
    P0 : float or array_like, default 1e4
        Initial covariance, in the forms of `Q` (positive definite).
    x0 : array_like of shape (dim_x,) or (C, dim_x), optional
        Initial estimate, shared or one per channel; zeros by default.
    forgetting : {"exponential", "directional", "constant_trace"}, default "exponential"
        Forgetting mode, as in :class:`~rlsfilt.RecursiveLeastSquares`.
        ``"efra"``, ``"variable"``, ``"diagonal"`` (a forgetting factor
        per parameter), the outlier gate and equality constraints are not
        available in the bank (use one `RecursiveLeastSquares` per channel
        for them; `BankTuneResult.apply` refuses a tuned ``"lam_diag"``
        likewise).
    forgetting_params : dict, optional
        Constants of the mode, as in `RecursiveLeastSquares` (defaults
        computed per channel from its `lam`, `R` and `P0`): ``eps`` for
        ``"directional"``, ``trace`` and ``ratio`` for ``"constant_trace"``,
        the windup cap's ``spread_max`` (1e15) and ``trace_max`` (1e12
        ``trace(P0)``) for ``"exponential"``. Any other key (one that only
        `RecursiveLeastSquares` reads) is a ValueError naming it.
    check_every : int, default 100
        Health check period (0 disables it): every `check_every` updates,
        and at the end of :meth:`batch_filter`, each channel's ``P`` is
        tested as `RecursiveLeastSquares` tests it; every :meth:`update`
        also tests the diagonals. Channels that fail are named in one
        :class:`~rlsfilt.NumericalWarning` and listed in
        ``failed_channels``.
    cond_max : float, default 1e12
        Condition number of ``P`` beyond which the health check fails.
    parallel : bool, default False
        Run :meth:`batch_filter`'s blocks of channels on numba's threads
        (``numba.set_num_threads``). Off by default: on the shared 2-core
        machine of ``docs/performance.md`` two threads gained little, and
        under Dask or a process pool the cores are already busy. The
        results are the same bits either way.

    Attributes
    ----------
    x : ndarray, shape (C, dim_x)
        Estimates, one row per channel.
    P : ndarray, shape (C, dim_x, dim_x)
        Covariances.
    x_prior, P_prior, x_post, P_post : ndarray
        Copies of ``x`` and ``P`` after the last predict and update.
    H : ndarray, shape (C, dim_x)
        Regressors of the last update.
    z, y : ndarray, shape (C,)
        Last measurements and a-priori residuals :math:`z - H x^-` (NaN
        where a channel skipped the update).
    S, SI : ndarray, shape (C,)
        Innovation variances :math:`H P^- H^T + R` and their inverses (NaN
        where the regressor held NaN).
    K : ndarray, shape (C, dim_x)
        Gains of the last update (zero where a channel skipped it).
    lam_t : ndarray, shape (C,)
        Forgetting factor each channel's last update applied.
    n_updates : int
        Measurement updates since :meth:`reset`.
    n_capped : ndarray of int, shape (C,)
        Updates of each channel whose forgetting the windup cap restricted
        to the regressor's direction (exponential mode), as
        ``RecursiveLeastSquares.n_capped``.
    failed_channels : ndarray of int
        Channels whose ``P`` failed a health check since :meth:`reset`.
    n_channels, dim_x : int
        Sizes given at construction.

    Notes
    -----
    Each channel runs the recursion of `RecursiveLeastSquares` (Ljung
    1999, sec. 11.2; Astrom & Wittenmark 1995, sec. 2.2):

    .. math::

        P_c^- &= P_c / \lambda_c + Q_c \\
        y_c &= z_c - H_c x_c^- ,\qquad S_c = H_c P_c^- H_c^T + R_c \\
        K_c &= P_c^- H_c^T / S_c ,\qquad x_c = x_c^- + K_c y_c \\
        P_c &= P_c^- - (P_c^- H_c^T)(P_c^- H_c^T)^T / S_c

    with the same operations in the same order, so every channel agrees
    with a separate filter bit for bit in the exponential and directional
    modes; the directional and constant-trace modes replace the last two
    lines as in :mod:`rlsfilt.filters.forgetting`, and the constant-trace
    rescaling agrees to round-off only (a few units in the last place: the
    tests hold it to 1e-12). ``P`` is kept exactly symmetric.

    **The windup cap** (exponential mode, ``lam < 1``) is that of
    `RecursiveLeastSquares`, channel by channel and with the same
    arithmetic: after each update a channel whose ``P`` spread far off its
    regressor's direction (:math:`\sum_i P_{ii} H_i^2 > \mathtt{spread\_max}\,
    H P H^T`) or whose ``trace(P) / lam`` would exceed ``trace_max`` holds
    its next time update's forgetting back, and its next update forgets
    along its regressor only. A channel whose regressor stops exciting
    therefore stays finite and recovers when excitation returns (without
    the cap ``P`` grew like ``lam**-k`` until the channel was NaN for good),
    and ordinary runs give the bits of the plain recursion. The state of the
    cap is carried across calls and into :meth:`channel`.

    **Missing data per channel.** A NaN in ``z[c]``, or any NaN in the
    regressor ``H[c]``, skips the measurement update of channel ``c`` only
    (its estimate and covariance are kept, its ``K`` is zero and its ``y``
    NaN); the other channels update. Infinite values are errors.

    **Memory layout.** The arrays the bank makes for its state (``x``,
    ``P``, their priors and posteriors, ``K``) have the documented shapes
    but Fortran order: the channel index varies fastest, so that the
    compiled kernels run along the channels with no transposition (NumPy
    handles them as any array; ``np.ascontiguousarray`` gives a C-ordered
    copy). An array assigned to ``x`` or ``P`` is stored as a Fortran-ordered
    copy.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, ch. 11.
    .. [2] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 2.

    Examples
    --------
    Three first-order plants ``y(t) = a y(t-1) + b u(t-1)`` identified at once:

    >>> import numpy as np
    >>> from rlsfilt import RLSBank
    >>> rng = np.random.default_rng(0)
    >>> a, b = np.array([0.5, 0.8, -0.3]), np.array([1.0, 2.0, 0.5])
    >>> u = rng.standard_normal((300, 3))
    >>> y = np.zeros((300, 3))
    >>> for t in range(1, 300):
    ...     y[t] = a * y[t - 1] + b * u[t - 1]
    >>> Hs = np.stack([y[:-1], u[:-1]], axis=-1)      # (N, C, dim_x)
    >>> bank = RLSBank(3, 2)
    >>> _ = bank.batch_filter(y[1:], Hs)
    >>> np.round(bank.x, 3)
    array([[ 0.5,  1. ],
           [ 0.8,  2. ],
           [-0.3,  0.5]])
    """

    x_prior = _Lazy("Estimates after the last :meth:`predict`, ``(C, dim_x)``.")
    P_prior = _Lazy("Covariances after the last :meth:`predict`, ``(C, dim_x, dim_x)``.")
    x_post = _Lazy("Estimates after the last :meth:`update`, ``(C, dim_x)``.")
    P_post = _Lazy("Covariances after the last :meth:`update`, ``(C, dim_x, dim_x)``.")


    _options = BankBase._options | {"P", "Q", "lam", "check_every", "cond_max", "parallel"}

    def __init__(self, n_channels, dim_x, lam=1.0, *, Q=0.0, R=1.0, P0=1e4, x0=None,
                 forgetting="exponential", forgetting_params=None, check_every=100,
                 cond_max=1e12, parallel=False):
        self._pending = None
        self.dim_x = check_dimension(dim_x, "dim_x")
        # per channel: x, P and their priors, posteriors and the batch's work arrays
        self.n_channels = check_length(n_channels, "n_channels",
                                       bytes_per_item=64 * self.dim_x * (self.dim_x + 1))
        if not isinstance(forgetting, str) or forgetting not in MODES:
            raise ValueError(
                f"`forgetting` must be one of {', '.join(map(repr, MODES))} for RLSBank; got "
                f"{forgetting!r} (use one RecursiveLeastSquares per channel for the others)")
        self._mode = MODES.index(forgetting)
        self._forgetting_params_in = _supported_params(forgetting, forgetting_params)
        self._R = self._per_channel_positive(R, "R")
        # (P0 first: the windup cap's default trace_max is 1e12 trace(P0), per channel)
        self._P0 = np.asfortranarray(self._covariances(P0, "P0", definite=True))
        self.lam = lam
        self.Q = Q
        self.check_every = check_int(check_every, "check_every", minimum=0)
        cond_max = check_scalar(cond_max, "cond_max")
        if not (math.isfinite(cond_max) and cond_max > 0.0):
            raise ValueError(f"`cond_max` must be a positive finite number; got {cond_max}")
        self.cond_max = cond_max
        if not isinstance(parallel, (bool, np.bool_)):
            raise TypeError(f"`parallel` must be True or False; got {parallel!r}")
        self.parallel = bool(parallel)
        self._x0 = np.asfortranarray(
            self._estimates(np.zeros(self.dim_x) if x0 is None else x0, "x0"))
        self.reset()

    # ------------------------------------------------------------------
    # state and configuration; assigning stores a copy
    # ------------------------------------------------------------------
    @property
    @_locked
    def x(self):
        """Estimates, ``(C, dim_x)``; assigning stores a copy (the shape is checked
        where it is used, so that the error names the method)."""
        self._hand_out(self._x)
        return self._x

    @x.setter
    @_locked
    def x(self, value):
        x = np.array(as_float_array(value, "x"), dtype=np.float64, order="F")
        self._settle_pending()
        self._x, self._x_out = x, False

    @property
    @_locked
    def P(self):
        """Covariances, ``(C, dim_x, dim_x)``; assigning stores a copy (the shape is
        checked where it is used)."""
        self._settle_pending()
        self._hand_out(self._P)
        return self._P

    @P.setter
    @_locked
    def P(self, value):
        P = np.array(as_float_array(value, "P"), dtype=np.float64, order="F")
        self._settle_pending()
        old = self._P
        # the windup cap decides again from the new P, in the channels whose P changed
        # (as assigning P to each channel's own filter would)
        changed = (np.any(old != P, axis=(1, 2)) if old.shape == P.shape == (
            self.n_channels, self.dim_x, self.dim_x) else None)
        self._P, self._P_out = P, False
        self._uncap(changed)

    # ------------------------------------------------------------------
    # the deferred time update and the lazy copies (see the module docstring)
    # ------------------------------------------------------------------
    def _settle_pending(self):
        """Run the time update a :meth:`predict` deferred, as it would have run."""
        pending = self._pending
        if pending is None:
            return
        il, Qt, q_zero = pending
        Pt = self._checked_P()
        Pn, P_prior = np.empty_like(Pt), np.empty_like(Pt)
        _get_kernels().bank_predict(Pt, il, Qt, q_zero, Pn, P_prior)
        self._P, self._P_out = Pn.T, False
        self.__dict__["_P_prior"] = P_prior.T
        self._pending = None

    def _hand_out(self, arr):
        """Before `arr` (the bank's ``x`` or ``P``) is handed out, where its holder
        may write into it: make the lazy copies still pending on it."""
        d = self.__dict__
        for key in ("_x_prior", "_P_prior", "_x_post", "_P_post"):
            lazy = d[key]
            if type(lazy) is tuple and lazy[0] is arr:
                d[key] = _made(lazy)
        if arr is self._x:
            self._x_out = True
        else:
            self._P_out = True

    @property
    def lam(self):
        """Forgetting factors, shape (C,) (a copy; assign to change them)."""
        return self._lam.copy()

    @lam.setter
    @_locked
    def lam(self, value):
        lam = self._per_channel(value, "lam")
        bad = ~((lam > 0.0) & (lam <= 1.0))
        if bad.any():
            c = int(np.argmax(bad))
            raise ValueError(f"`lam` must be in (0, 1]; got {lam[c]} for channel {c}")
        self._params = self._mode_params(lam, self._R)
        self._lam = lam
        # 1 / lam, applied by the time update: the exponential mode only
        self._il = 1.0 / lam if self._mode == 0 else np.ones(self.n_channels)

    @property
    def R(self):
        """Measurement-noise variances, shape (C,) (a copy; assign to change them)."""
        return self._R.copy()

    @R.setter
    @_locked
    def R(self, value):
        R = self._per_channel_positive(value, "R")
        if "_lam" in self.__dict__:       # the mode's defaults that depend on R follow it
            self._params = self._mode_params(self._lam, R)
        self._R = R

    @property
    def Q(self):
        """Random-walk covariances, shape (C, dim_x, dim_x) (a copy)."""
        return self._Q.copy()

    @Q.setter
    @_locked
    def Q(self, value):
        self._Q = np.asfortranarray(self._covariances(value, "Q"))
        self._Q_is_zero = not self._Q.any()

    @property
    def forgetting(self):
        """Forgetting mode (read-only; chosen at construction)."""
        return MODES[self._mode]

    @forgetting.setter
    def forgetting(self, value):
        refuse_fixed(self, "forgetting", "construct a new bank with forgetting=...")

    @property
    def forgetting_params(self):
        """Constants of the forgetting mode, one array of shape (C,) per name (read-only,
        chosen at construction)."""
        names = _SUPPORTED_PARAMS[self.forgetting]
        return {name: self._params[:, i].copy() for i, name in enumerate(names)}

    @forgetting_params.setter
    def forgetting_params(self, value):
        refuse_fixed(self, "forgetting_params",
                     "construct a new bank with forgetting_params=...")

    def _mode_params(self, lam, R):
        """``(C, 2)`` constants of the mode (those of `_SUPPORTED_PARAMS`, in its
        order), validated by `forgetting.mode_params` once per distinct ``(lam,
        R)`` pair (so the defaults are per channel)."""
        C = self.n_channels
        params = np.zeros((C, 2))
        supported = _SUPPORTED_PARAMS[self.forgetting]
        names = _fg._PARAM_NAMES[self._mode]
        pick = [names.index(name) for name in supported]
        # the exponential mode's windup cap: trace_max defaults to 1e12 trace(P0)
        traces = np.trace(self._P0, axis1=1, axis2=2)
        pairs, inverse = np.unique(np.column_stack([lam, R, traces]), axis=0,
                                   return_inverse=True)
        for k, (lam_k, r_k, tr_k) in enumerate(pairs):
            try:
                values = _fg.mode_params(self._mode, self._forgetting_params_in, self.dim_x,
                                         float(lam_k), float(r_k), float(tr_k))
            except ValueError as exc:
                c = int(np.argmax(inverse.reshape(-1) == k))
                raise ValueError(f"{exc} (channel {c})") from None
            params[inverse.reshape(-1) == k, :len(pick)] = [values[i] for i in pick]
        return params

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    @_atomic
    def predict(self, Q=None):
        r"""Time update of every channel, :math:`P \leftarrow P / \lambda + Q`.

        The estimates are unchanged. For the directional and constant-trace
        modes only ``Q`` is added (their forgetting happens in
        :meth:`update`), as in `RecursiveLeastSquares`.

        As in `RecursiveLeastSquares`, the arithmetic is deferred: the next
        :meth:`update` applies it in its compiled call, and reading ``P`` or
        ``P_prior`` (or assigning the state, :meth:`batch_filter`,
        :meth:`channel`, another ``predict()``) before that runs it at once.
        Every attribute has the bits an immediate time update gives.

        Parameters
        ----------
        Q : float or array_like, optional
            Random-walk covariance for this call only, in the forms of the
            constructor's `Q`; the bank's `Q` if omitted.
        """
        if Q is None:
            Q, Q_is_zero = self._Q, self._Q_is_zero
        else:
            Q = self._covariances(Q, "Q")
            Q_is_zero = not Q.any()
        if self.frozen:                                        # adaptation off: x, P unchanged
            return self._frozen_predict()
        self._settle_pending()                                 # predict() twice
        self._checked_x(), self._checked_P()                   # (the shapes)
        # P^- = P / lam + Q, deferred: run by the next update's compiled call,
        # or by `_settle_pending` when something needs P before; x^- = x.
        # The windup cap: a capped channel's time update keeps P (adds Q) and its
        # next update forgets along its regressor only (w = 1 / lam)
        capped = self._cap
        tf = np.where(capped, 1.0, self._il) if capped.any() else self._il
        self._w = np.where(capped, self._il, 1.0)
        self._pending = (tf, _t(Q), Q_is_zero)
        x, P = self._x, self._P
        self.__dict__["_x_prior"] = x.copy(order="F") if self._x_out else (x, None, None, None)
        self.__dict__["_P_prior"] = (P, *self._pending)
        if self._P_out:                      # its holder may write into P: not deferred
            self._settle_pending()
        self._updates_since_predict = 0

    @_atomic
    def update(self, z, H, R=None):
        r"""Measurement update of every channel.

        A call that raises, or whose warning is turned into an error, leaves
        the bank as it was.

        While the bank is :attr:`frozen` only the diagnostics are computed
        (``y``, ``S``, ``SI``; ``K`` is zero): ``x``, ``P`` and the counters
        stay bit-unchanged.

        Parameters
        ----------
        z : array_like, shape (C,), or None
            One measurement per channel; NaN skips that channel, None every
            channel.
        H : array_like, shape (C, dim_x)
            One regressor row per channel; a row holding NaN skips that
            channel.
        R : float or array_like of shape (C,), optional
            Noise variances for this call only.
        """
        C, n = self.n_channels, self.dim_x
        if z is None:                        # every channel missing
            z = np.full(C, np.nan)
        if self.frozen:                      # adaptation off: only the diagnostics
            return self._frozen_update(z, H, R)
        # shapes and types here; infinities are found by the kernel (no extra pass)
        zz = self._measurements(z, "z", (C,), "({C},) (one measurement per channel)",
                                finite=False)
        Hm = self._measurements(H, "H", (C, n), "({C}, {n}) (one regressor row of dim_x = "
                                                 "{n} per channel)", finite=False)
        r = self._R if R is None else self._per_channel_positive(R, "R")
        xt, Pt = self._checked_x(), self._checked_P()          # (n, C), (n, n, C)
        xn, K = np.empty((n, C)), np.empty((n, C))
        Pn = np.empty((n, n, C))
        y, S, SI, lam_t = np.empty(C), np.empty(C), np.empty(C), np.empty(C)
        pending = self._pending
        il, Qt, q_zero = pending if pending is not None else (self._il, Pt, True)
        cap, n_capped = np.empty(C), self.n_capped.copy()
        bad = _get_kernels().bank_update(
            xt, Pt, zz, Hm, r, self._lam, self._mode, self._params, pending is not None, il,
            Qt, q_zero, xn, Pn, y, S, SI, K, lam_t, self._w, cap, n_capped)
        if bad < 0:                          # an infinite value: name the first one
            for name, arr in (("z", zz), ("H", Hm)):
                self._measurements(arr, name, None, None)
        self._note_update()
        self._pending = None                 # (applied by the kernel)
        self._cap, self._w, self.n_capped = cap != 0.0, np.ones(C), n_capped
        self._x, self._P = xn.T, Pn.T
        self._x_out = self._P_out = False
        d = self.__dict__                    # x_post, P_post: copies of x, P when read
        d["_x_post"], d["_P_post"] = (self._x, None, None, None), (self._P, None, None, None)
        self.z, self.H = zz.copy(), Hm.copy()
        self.y, self.S, self.SI, self.K, self.lam_t = y, S, SI, K.T, lam_t
        self.n_updates += 1
        every = self.check_every
        if every and (bad or not self.n_updates % every):
            self._check_health(f"at update {self.n_updates} since reset")

    @_atomic
    def predict_update(self, z, H, R=None):
        """One textbook step of every channel: :meth:`predict` then :meth:`update`.

        A step whose update raises leaves the bank as it was (no half step).
        """
        self.predict()
        self.update(z, H, R)

    @_atomic
    def update_block(self, Z, H, R=None):
        """Several steps of every channel at once (MATLAB's frame-based input).

        For each row of `Z` and `H` a :meth:`predict` then an :meth:`update`,
        bit for bit those calls one by one, in one compiled call (the loop of
        :meth:`batch_filter`, whose argument names ``zs``, ``Hs``, ``Rs`` its
        messages use). Leaves the diagnostics of the last row's update; a call
        that raises changes nothing. While :attr:`frozen` every row only
        computes the diagnostics.

        Parameters
        ----------
        Z : array_like, shape (N, C)
            Measurements; NaN skips that channel at that step.
        H : array_like, shape (N, C, dim_x)
            Regressor rows; a row holding NaN skips that channel at that step.
        R : float or array_like of shape (C,) or (N, C), optional
            Noise variances: shared, one per channel, or one per step and
            channel (the bank's `R` if omitted).

        Returns
        -------
        RLSBank
            The bank.
        """
        self.batch_filter(Z, H, R, store_covariances=False, store_means=False,
                          store_residuals=False)
        return self

    # ------------------------------------------------------------------
    # adaptation switch (MATLAB's EnableAdaptation)
    # ------------------------------------------------------------------
    @property
    def frozen(self):
        """Whether adaptation is off (:meth:`freeze`): :meth:`update` then
        computes the residuals ``y`` and their variances ``S`` but leaves ``x``,
        ``P`` and the counters bit-unchanged, and :meth:`predict` changes
        nothing (as the single filters)."""
        return self.__dict__.get("_frozen", False)

    @property
    def adapt(self):
        """``not frozen``: assign False to freeze every channel, True to resume
        (MATLAB's ``EnableAdaptation``)."""
        return not self.frozen

    @adapt.setter
    @_locked
    def adapt(self, value):
        self._frozen = not check_bool(value, "adapt")

    @_locked
    def freeze(self):
        """Stop adapting: predictions and residuals continue, ``x`` and ``P`` stay
        as they are until :meth:`unfreeze`. Returns the bank."""
        self._frozen = True
        return self

    @_locked
    def unfreeze(self):
        """Resume adapting from the state held while frozen. Returns the bank."""
        self._frozen = False
        return self

    def _frozen_predict(self):
        """:meth:`predict` while frozen: record ``x_prior`` and ``P_prior``, nothing else."""
        self._settle_pending()               # (a predict before the freeze, as it would run)
        x, P = self._x, self._P
        d = self.__dict__
        d["_x_prior"] = x.copy(order="F") if self._x_out else (x, None, None, None)
        d["_P_prior"] = P.copy(order="F") if self._P_out else (P, None, None, None)

    def _frozen_update(self, z, H, R):
        """:meth:`update` while frozen: validate as ``update`` does, then only the
        diagnostics ``y = z - H x``, ``S = H P H^T + R``, ``SI = 1 / S`` and ``K =
        0`` (`_kernels_bank.bank_residuals`); ``x``, ``P``, ``lam_t`` and the
        counters stay bit-unchanged."""
        C, n = self.n_channels, self.dim_x
        zz = self._measurements(z, "z", (C,), "({C},) (one measurement per channel)")
        Hm = self._measurements(H, "H", (C, n), "({C}, {n}) (one regressor row of dim_x = "
                                                 "{n} per channel)")
        r = self._R if R is None else self._per_channel_positive(R, "R")
        self._settle_pending()
        y, S, SI = np.empty(C), np.empty(C), np.empty(C)
        _get_kernels().bank_residuals(self._checked_x(), self._checked_P(), zz, Hm, r, y, S, SI)
        self.z, self.H = zz.copy(), Hm.copy()
        self.y, self.S, self.SI = y, S, SI
        self.K = np.zeros((C, n), order="F")
        self._fresh = False

    @_atomic
    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True, store_means=True, store_residuals=True, *,
                     _residuals=None):
        r"""Run every channel over a record in one compiled call.

        Parameters
        ----------
        zs : array_like, shape (N, C)
            Measurements; NaN skips that channel at that step.
        Hs : array_like, shape (N, C, dim_x)
            Regressor rows; a row holding NaN skips that channel at that step.
        Rs : float or array_like of shape (C,) or (N, C), optional
            Noise variances: shared, one per channel, or one per step and
            channel (the bank's `R` if omitted).
        update_first : bool, default False
            Update then predict in each step instead of predict then update.
        saver : filterpy.common.Saver, optional
            Saved after every step. The record then runs step by step
            (:meth:`predict` and :meth:`update`, the same arithmetic and
            results as the compiled call, but a Python loop over the steps).
        store_covariances : bool, default True
            With ``False`` no covariance histories are kept (returned as
            None): memory stays ``O(N C dim_x)``.
        store_means : bool, default True
            With ``False`` no estimate histories are kept either (returned as
            None): memory stays ``O(N C)`` (the residual histories).
        store_residuals : bool, default True
            With ``False`` the residual histories are not kept either
            (``residuals`` and ``innovation_variances`` are None): with the
            two options above, the call keeps only the final state (and the
            last step's ``y``, ``S``), in ``O(C dim_x^2)`` memory, and saves
            writing two ``(N, C)`` arrays (a fifth of the run time of 10,000
            channels x 1,000 samples at 4 parameters; ``docs/performance.md``).
        _residuals : ndarray of shape (N, C), optional
            Private (for `fit_many`): a float64 array, possibly a strided view
            of a larger one, that receives the residual histories instead of
            a new array (no copy afterwards); with `store_residuals` and no
            `saver` only.

        Returns
        -------
        BankHistory
            Unpacks as ``means, covariances, means_p, covariances_p``
            (shapes ``(N, C, dim_x)`` and ``(N, C, dim_x, dim_x)``); its
            ``residuals`` and ``innovation_variances`` (``(N, C)``) are the
            a-priori residuals and their variances.

        Notes
        -----
        The channels are processed in blocks that stay in cache for the
        whole record, and the loops over the channels of a block vectorize
        (see :mod:`rlsfilt.filters._kernels_bank`). The health check runs
        every `check_every` steps inside the loop and once at the end. A
        call that raises, or whose warning is turned into an error, leaves
        the bank as it was.
        """
        C, n = self.n_channels, self.dim_x
        update_first = check_bool(update_first, "update_first")
        store_covariances = check_bool(store_covariances, "store_covariances")
        store_means = check_bool(store_means, "store_means")
        store_residuals = check_bool(store_residuals, "store_residuals")
        if saver is not None and not callable(getattr(saver, "save", None)):
            raise TypeError(f"`saver` must be None or have a save() method (filterpy's Saver); "
                            f"got {type(saver).__name__}")
        Z = self._measurements(zs, "zs", None, f"(N, {C}) (one column per channel)", ndim=2,
                               finite=False, strided=True)
        if Z.shape[1] != C:
            raise ValueError(f"`zs` must have shape (N, {C}) (one column per channel, "
                             f"n_channels = {C}); got {Z.shape}")
        if Z.strides[1] != Z.itemsize:       # rows of adjacent channels are read in place
            Z = np.ascontiguousarray(Z)      # (fit_many's column block of a record)
        N = Z.shape[0]
        Hm = self._measurements(Hs, "Hs", (N, C, n),
                                f"({N}, {C}, {n}) (N = len(zs) steps, n_channels = {C}, "
                                f"dim_x = {n})", finite=False, strided=True)
        # regressors stored with the channel index last (a transposed view of an
        # (N, dim_x, C) array, as fit_many builds them) are read in place
        Ht = Hm.transpose(0, 2, 1)
        h_last = Ht.flags.c_contiguous and not Hm.flags.c_contiguous
        Hk = Ht if h_last else np.ascontiguousarray(Hm)
        Rv = self._batch_variances(Rs, N)
        if saver is not None or self.frozen:
            return self._batch_stepwise(Z, Hm, Rv, update_first, saver, store_covariances,
                                        store_means, store_residuals)
        self._settle_pending()                 # a predict() before runs first
        x0t = self._checked_x()
        xt, Pt = x0t.copy(), self._checked_P().copy()     # (n, C), (n, n, C), overwritten
        means = np.empty((N if store_means else 0, C, n))
        covs = np.empty((N if store_covariances else 0, C, n, n))
        covs_p = np.empty_like(covs)
        rows = N if store_residuals else min(N, 1)   # else the last step's only
        ys, ss = np.empty((rows, C)), np.empty((rows, C))
        if _residuals is not None and store_residuals:
            ys = _residuals                       # (N, C) float64, checked by the caller
        x_prior, P_prior = np.empty((n, C)), np.empty((n, n, C))
        x_post, P_post = np.empty((n, C)), np.empty((n, n, C))
        K, lam_t = np.zeros((n, C)), self._lam.copy()
        k_fail = np.full(C, -1, dtype=np.int64)
        k_inf = np.full(C, -1, dtype=np.int64)
        cap, w, n_capped = self._cap.astype(float), self._w.copy(), self.n_capped.copy()
        kern = _get_kernels()
        if N:
            run = kern.bank_batch_parallel if self.parallel else kern.bank_batch
            run(xt, Pt, Z, Hk, h_last, Rv, self._il, self._lam, _t(self._Q), self._Q_is_zero,
                self._mode, self._params, update_first, means, covs, covs_p, ys, ss,
                x_prior, P_prior, x_post, P_post, K, lam_t, self.check_every, self.n_updates,
                self.cond_max, k_fail, k_inf, cap, w, n_capped, kern.block_size(n, C))
            _raise_infinite(k_inf, Z, Hm)          # (checked in the kernel: no extra pass)
        means_p = None
        if store_means:            # the estimate is unchanged by a time update
            means_p = means.copy() if update_first else np.concatenate(
                [x0t.T[None], means[:-1]]) if N else means.copy()
        step0 = self.n_updates
        self._x, self._P = xt.T, Pt.T
        self._x_out = self._P_out = False
        if N:
            self.x_prior, self.P_prior = x_prior.T, P_prior.T
            self.x_post, self.P_post = x_post.T, P_post.T
            self.z, self.H = Z[-1].copy(), Hm[-1].copy()
            self.y, self.S = ys[-1].copy(), ss[-1].copy()
            self.SI, self.K, self.lam_t = 1.0 / self.S, K.T, lam_t
            self.n_updates += N
            self._cap, self._w, self.n_capped = cap != 0.0, w, n_capped
            self._updates_since_predict = 0 if update_first else 1
            self._fresh = False
        failed = np.flatnonzero(k_fail >= 0)
        if failed.size:
            self._warn_health(failed, f"at step {int(k_fail[failed[0]])} of batch_filter "
                                      f"(update {step0 + int(k_fail[failed[0]]) + 1} since "
                                      "reset)")
        if self.check_every:
            self._check_health("at the end of batch_filter")
        return BankHistory(means if store_means else None,
                           covs if store_covariances else None, means_p,
                           covs_p if store_covariances else None,
                           ys if store_residuals else None,
                           ss if store_residuals else None, (N, C))

    def _batch_stepwise(self, Z, Hm, Rv, update_first, saver, store_covariances, store_means,
                        store_residuals):
        """`batch_filter` with a `saver` or while frozen: :meth:`predict`/:meth:`update`
        step by step, ``saver.save()`` after each step (if any). The record is validated first;
        a call that raises is undone by `batch_filter` (see `_atomic`)."""
        C, n = self.n_channels, self.dim_x
        N = len(Z)
        for name, arr in (("zs", Z), ("Hs", Hm)):
            if np.isinf(arr).any():
                idx = tuple(int(v) for v in np.argwhere(np.isinf(arr))[0])
                raise ValueError(f"`{name}` must be finite or NaN (missing); got {arr[idx]} "
                                 f"at index {idx}")
        Rv = np.broadcast_to(Rv, (N, C))
        means = np.empty((N if store_means else 0, C, n))
        means_p = np.empty_like(means)
        covs = np.empty((N if store_covariances else 0, C, n, n))
        covs_p = np.empty_like(covs)
        ys, ss = np.empty((N, C)), np.empty((N, C))
        for k in range(N):
            if not update_first:
                self.predict()
                if store_covariances:
                    covs_p[k] = self.P
            self.update(Z[k], Hm[k], Rv[k])
            ys[k], ss[k] = self.y, self.S
            if store_means:
                means[k] = self.x
            if store_covariances:
                covs[k] = self.P
            if update_first:
                self.predict()
                if store_covariances:
                    covs_p[k] = self.P
            if store_means:
                means_p[k] = self.x_prior
            if saver is not None:
                saver.save()
        return BankHistory(means if store_means else None,
                           covs if store_covariances else None,
                           means_p if store_means else None,
                           covs_p if store_covariances else None,
                           ys if store_residuals else None,
                           ss if store_residuals else None, (N, C))

    @_atomic
    def initialize(self, zs, Hs):
        r"""Start every channel from batch least squares on its first samples.

        As :meth:`RecursiveLeastSquares.initialize` for each channel: with
        the first ``k0`` samples of channel ``c`` stacked as
        :math:`Z_c = \Phi_c x_c + V_c` (rows weighted by
        :math:`\lambda_c^{(k_0 - 1 - i)/2}`, rows with a NaN dropped),
        :math:`x_c = (\Phi_c^T \Phi_c)^{-1} \Phi_c^T Z_c` and
        :math:`P_c = R_c (\Phi_c^T \Phi_c)^{-1}`, both from a QR
        factorization of the regressors with unit-norm columns (batched over
        the channels), never from the normal equations.

        Parameters
        ----------
        zs : array_like, shape (k0, C)
        Hs : array_like, shape (k0, C, dim_x)

        Raises
        ------
        ValueError
            If the rows of some channel do not determine every parameter
            (the channels are named).
        """
        C, n = self.n_channels, self.dim_x
        Z = self._measurements(zs, "zs", None, f"(k0, {C})", ndim=2)
        if Z.shape[1] != C:
            raise ValueError(f"`zs` must have shape (k0, {C}) (one column per channel, "
                             f"n_channels = {C}); got {Z.shape}")
        k0 = Z.shape[0]
        Hm = self._measurements(Hs, "Hs", (k0, C, n), f"({k0}, {C}, {n})")
        keep = ~(np.isnan(Z) | np.isnan(Hm).any(axis=2))              # (k0, C)
        w = self._lam[None, :] ** (0.5 * np.arange(k0 - 1, -1, -1.0))[:, None]
        w = np.where(keep, w, 0.0)
        A = np.where(keep[:, :, None], Hm, 0.0) * w[:, :, None]        # (k0, C, n)
        B = np.where(keep, Z, 0.0) * w                                 # (k0, C)
        # (contiguous copies: every channel's matrices then have the same strides whatever
        # the number of channels, so that matmul and the norms take the same path (BLAS, or
        # NumPy's own loop with its own order of the sums) and a channel gets the same bits
        # in a bank of 1 channel or of 37; a dask block of one channel as in a larger one)
        A = np.ascontiguousarray(A.transpose(1, 0, 2))                 # (C, k0, n)
        B = np.ascontiguousarray(B.T)[:, :, None]                      # (C, k0, 1)
        norms = np.linalg.norm(A, axis=1)                              # (C, n)
        d = np.where(norms > 0.0, norms, 1.0)
        As = A / d[:, None, :]
        Qf, Rf = np.linalg.qr(As) if k0 >= n else (None, None)
        rank, Rinv = full_rank(As, Rf)
        short = np.flatnonzero(rank < n)
        if short.size:
            c = int(short[0])
            raise ValueError(
                f"`Hs` is rank-deficient in {short.size} channel(s) {_list(short)}: channel "
                f"{c} has {int(rank[c])} linearly independent rows in {int(keep[:, c].sum())} "
                f"usable samples; need {n} (one per parameter). Use more samples or a more "
                "exciting input.")
        if Rinv is None:
            Rinv = np.linalg.inv(Rf)                      # upper triangular, batched
        x = (Rinv @ (Qf.transpose(0, 2, 1) @ B))[:, :, 0] / d
        Rinv = Rinv / d[:, :, None]                       # D^-1 R_s^-1
        P = self._R[:, None, None] * (Rinv @ Rinv.transpose(0, 2, 1))
        self._pending = None                  # (overwritten: P, the priors)
        self._x = np.asfortranarray(x)
        self._P = np.asfortranarray(0.5 * (P + P.transpose(0, 2, 1)))
        self._x_out = self._P_out = False
        self.x_prior, self.x_post = self._x.copy(order="F"), self._x.copy(order="F")
        self.P_prior, self.P_post = self._P.copy(order="F"), self._P.copy(order="F")
        self._updates_since_predict = 0
        self._uncap()

    def smooth(self, zs, Hs, Rs=None):
        """``batch_filter(zs, Hs, Rs)``, then the Rauch-Tung-Striebel smoother of every channel.

        Returns a `rlsfilt.filters.smoother.SmoothedTrajectory` whose estimates are
        ``(N, C, dim_x)`` and covariances ``(N, C, dim_x, dim_x)``; each channel's
        equals the smoother of its own `RecursiveLeastSquares`. The bank ends where
        ``batch_filter`` leaves it. See `rlsfilt.filters.smoother.rts_smoother`.
        """
        from . import smoother
        return smoother.smooth(self, zs, Hs, Rs)

    def tune(self, zs, Hs, param="q", *, bounds=None, burn=0, apply=False):
        """Maximum likelihood of every channel's ``lam`` or random walk ``Q`` (and ``R``).

        Returns a `rlsfilt.filters.tuning.BankTuneResult`; each channel equals
        ``bank.channel(c).tune(zs[:, c], Hs[:, c], ...)``. See
        `rlsfilt.filters.tuning.tune_bank`.
        """
        from . import tuning
        return tuning.tune_bank(self, zs, Hs, param, bounds=bounds, burn=burn, apply=apply)

    # ------------------------------------------------------------------
    # channels, copies, reset
    # ------------------------------------------------------------------
    @_locked
    def channel(self, i):
        """Channel `i` as an ordinary :class:`~rlsfilt.RecursiveLeastSquares`.

        The filter has the channel's configuration (`lam`, `R`, `Q`, `x0`,
        `P0`, forgetting mode and constants, health-check settings) and
        state (``x``, ``P``, priors, posteriors, the last step's
        diagnostics and :attr:`adapt`), so further ``predict``/``update`` calls continue
        as channel `i` of the bank would (bit for bit; to round-off in the
        constant-trace mode); its :meth:`reset` returns
        to the channel's ``x0``, ``P0``. The bank is not changed.

        Parameters
        ----------
        i : int
            Channel index, ``0 <= i < n_channels`` (negative counts from the end).

        Returns
        -------
        RecursiveLeastSquares
        """
        from .rls import RecursiveLeastSquares

        C, n = self.n_channels, self.dim_x
        i = check_int(i, "i")
        if not -C <= i < C:
            raise ValueError(f"`i` must be a channel index in [{-C}, {C}); got {i}")
        i %= C
        self._settle_pending()
        f = RecursiveLeastSquares(
            n, lam=float(self._lam[i]), P0=self._P0[i], x0=self._x0[i], R=float(self._R[i]),
            Q=self._Q[i], forgetting=self.forgetting,
            forgetting_params=self._forgetting_params_in, check_every=self.check_every,
            cond_max=self.cond_max)
        f.x = self._checked_x()[:, i].reshape(n, 1).copy()
        f.P = self._checked_P()[:, :, i].T.copy()
        f.x_prior, f.P_prior = self.x_prior[i].reshape(n, 1).copy(), self.P_prior[i].copy()
        f.x_post, f.P_post = self.x_post[i].reshape(n, 1).copy(), self.P_post[i].copy()
        f.n_updates = self.n_updates
        f.n_capped = int(self.n_capped[i])
        f._cap, f._w = bool(self._cap[i]), float(self._w[i])       # the windup cap's state
        f._updates_since_predict = self._updates_since_predict
        f._warned_health = bool(np.isin(i, self.failed_channels))
        f.adapt = self.adapt                 # (a frozen bank gives a frozen filter)
        if not self._fresh:
            f.H = self.H[i].reshape(1, n).copy()
            f.z = np.full((1, 1), self.z[i])
            f.y = np.full((1, 1), self.y[i])
            f.K = self.K[i].reshape(n, 1).copy()
            f.S, f.SI = np.full((1, 1), self.S[i]), np.full((1, 1), self.SI[i])
            f.lam_t = float(self.lam_t[i])
            f._clear_lazy()
            if np.isnan(self.y[i]):
                f._log_likelihood, f._likelihood, f._mahalanobis = 0.0, 1.0, math.nan
        return f

    @_locked
    def reset(self, channels=None):
        """Return every channel (or the given ones) to ``x0``, ``P0``.

        ``lam``, ``R``, ``Q`` and the forgetting mode are kept.

        Parameters
        ----------
        channels : array_like of int or bool, optional
            The channels to reset: indices, or a mask of shape ``(C,)``. By
            default all, and the diagnostics and counters are cleared too;
            given, only those channels' ``x``, ``P``, ``lam_t``, ``n_capped``
            and windup cap are reset, each as its own filter's
            ``RecursiveLeastSquares.reset()`` would (the other channels, the
            last step's diagnostics and ``n_updates`` are kept).
        """
        if channels is not None:
            self._reset_channels(channels)
            return
        C, n = self.n_channels, self.dim_x
        self._pending = None
        self._x = self._x0.copy(order="F")
        self._P = self._P0.copy(order="F")
        self._x_out = self._P_out = False
        self.x_prior, self.P_prior = self._x.copy(order="F"), self._P.copy(order="F")
        self.x_post, self.P_post = self._x.copy(order="F"), self._P.copy(order="F")
        self.H = np.zeros((C, n))
        self.z = np.zeros(C)
        self.y = np.zeros(C)
        self.S = np.zeros(C)
        self.SI = np.zeros(C)
        self.K = np.zeros((C, n), order="F")
        self.lam_t = self._lam.copy()
        self.n_updates = 0
        self.n_capped = np.zeros(C, dtype=np.int64)
        self._uncap()
        self.failed_channels = np.zeros(0, dtype=np.int64)
        self._updates_since_predict = 0
        self._warned_skip = False
        self._fresh = True

    def _reset_channels(self, channels):
        """`reset` of the `channels` only (see there)."""
        C = self.n_channels
        idx = np.asarray(channels)
        if idx.dtype == bool:
            if idx.shape != (C,):
                raise ValueError(f"`channels` as a mask must have shape ({C},); got "
                                 f"{idx.shape}")
            idx = np.flatnonzero(idx)
        elif idx.size == 0:
            idx = idx.astype(np.int64).reshape(-1)
        elif not np.issubdtype(idx.dtype, np.integer):
            raise TypeError(f"`channels` must be channel indices or a boolean mask; got "
                            f"an array of {idx.dtype}")
        idx = idx.reshape(-1)
        if idx.size and (idx.min() < -C or idx.max() >= C):
            raise ValueError(f"`channels` must be in [-{C}, {C}); got {idx.min()} .. "
                             f"{idx.max()}")
        self._settle_pending()
        x, P = self._x.copy(order="F"), self._P.copy(order="F")     # (never write in place:
        x[idx], P[idx] = self._x0[idx], self._P0[idx]               #  lazy copies share them)
        self._x, self._P, self._x_out, self._P_out = x, P, False, False
        lam_t, n_capped = self.lam_t.copy(), self.n_capped.copy()
        lam_t[idx], n_capped[idx] = self._lam[idx], 0
        self.lam_t, self.n_capped = lam_t, n_capped
        mask = np.zeros(C, dtype=bool)
        mask[idx] = True
        self._uncap(mask)

    def _uncap(self, channels=None):
        """The windup cap decides afresh from the next update (a new ``P``), as
        `RecursiveLeastSquares` does after ``initialize`` or an assigned ``P``: in
        every channel, or in those of the mask `channels`."""
        if channels is None:
            self._cap = np.zeros(self.n_channels, dtype=bool)
            self._w = np.ones(self.n_channels)
            return
        self._cap = np.where(channels, False, self._cap)
        self._w = np.where(channels, 1.0, self._w)

    def __repr__(self):
        shown, gap = edge_indices(self.n_channels)
        if gap is None:
            return "\n".join([
                "RLSBank object",
                pretty_str("n_channels", self.n_channels),
                pretty_str("dim_x", self.dim_x),
                pretty_str("lam", self._lam),
                pretty_str("forgetting", self.forgetting),
                pretty_str("x", self.x),
                pretty_str("P", self.P),
                pretty_str("R", self._R),
                pretty_str("y", self.y),
                pretty_str("S", self.S),
                pretty_str("K", self.K),
                pretty_str("failed_channels", self.failed_channels),
            ])
        # many channels: the first and last few, not every channel's matrices
        lines = ["RLSBank object",
                 pretty_str("n_channels", self.n_channels),
                 pretty_str("dim_x", self.dim_x),
                 pretty_str("forgetting", self.forgetting),
                 pretty_str("n_updates", self.n_updates),
                 pretty_str("failed_channels", _list(self.failed_channels)),
                 f"x (first and last {len(shown) // 2} of {self.n_channels} channels):"]
        x = self.x
        for k, c in enumerate(shown):
            if k == len(shown) // 2:
                lines.append(f"  ... {gap} more channels ...")
            lines.append(f"  [{c}] {np.array2string(x[c], precision=6)}")
        return "\n".join(lines)

    def _repr_html_(self):
        return bank_html(self)   # Jupyter: settings, estimate +- std dev of the edge channels

    # ------------------------------------------------------------------
    # health of P
    # ------------------------------------------------------------------
    def _check_health(self, where):
        """Full check of every channel's ``P``; warn about channels that newly fail."""
        bad = np.zeros(self.n_channels, dtype=np.bool_)
        _get_kernels().bank_unhealthy(self._checked_P(), self.cond_max, bad)
        failed = np.flatnonzero(bad)
        if failed.size:
            self._warn_health(failed, where)

    def _warn_health(self, failed, where):
        new = np.setdiff1d(failed, self.failed_channels)
        if not new.size:
            return
        self.failed_channels = np.union1d(self.failed_channels, new)
        c = int(new[0])
        problem = (_health.symmetric_problem(self._P[c], self.cond_max)   # (after updates)
                   or "`P` failed the health check")
        _health.warn_at_caller(
            f"`P` failed the health check in {new.size} of {self.n_channels} channel(s) "
            f"{_list(new)} {where}; channel {c}: {problem}. The estimates of these channels "
            "may be unreliable: use forgetting='directional' or 'constant_trace', or more "
            "exciting input (the channels are listed in `failed_channels`).",
            NumericalWarning)

    # ------------------------------------------------------------------
    # private helpers
    # ------------------------------------------------------------------
    def _note_update(self):
        """Warn once when forgetting is skipped by two updates in a row."""
        if (self._updates_since_predict and not self._warned_skip
                and ((self._mode == 0 and (self._lam < 1.0).any()) or not self._Q_is_zero)):
            self._warned_skip = True
            _health.warn_at_caller(
                "update() was called twice without predict() in between, so the forgetting "
                "(lam < 1) or random walk (Q > 0) of this step was skipped; call predict() "
                "before each update() or use predict_update().", ForgettingSkippedWarning)
        self._updates_since_predict += 1
        self._fresh = False

    def _per_channel(self, value, name):
        """A scalar or one value per channel, as a new float array of shape (C,)."""
        C = self.n_channels
        if np.asarray(value).dtype == bool:
            raise TypeError(f"`{name}` must be a number or one number per channel; got {value!r}")
        arr = as_float_array(value, name)
        if arr.ndim == 0:
            return np.full(C, float(arr))
        if arr.shape != (C,):
            raise ValueError(f"`{name}` must be a scalar or have shape ({C},) (one value per "
                             f"channel, n_channels = {C}); got shape {arr.shape}")
        return arr.copy()

    def _per_channel_positive(self, value, name):
        arr = self._per_channel(value, name)
        bad = ~(np.isfinite(arr) & (arr > 0.0))
        if bad.any():
            c = int(np.argmax(bad))
            raise ValueError(f"`{name}` must be a positive finite variance; got {arr[c]} for "
                             f"channel {c}")
        lo, hi = VARIANCE_RANGE
        bad = (arr < lo) | (arr > hi)
        if bad.any():
            c = int(np.argmax(bad))
            raise ValueError(f"`{name}` must be a variance in [{lo:.0e}, {hi:.0e}] (the update "
                             f"multiplies and divides by it); got {arr[c]:.3g} for channel {c}")
        return arr

    def _covariances(self, value, name, definite=False):
        """``(C, n, n)`` covariances from a scalar, (C,), (n, n) or (C, n, n)."""
        C, n = self.n_channels, self.dim_x
        arr = as_float_array(value, name)
        if arr.ndim == 0 or arr.shape == (n, n):
            one = check_covariance(arr, n, name, definite=definite)
            return np.ascontiguousarray(np.broadcast_to(one, (C, n, n)))
        if arr.shape == (C,):
            scalars = self._per_channel(arr, name)
            bad = ~np.isfinite(scalars) | (scalars <= 0.0 if definite else scalars < 0.0)
            if bad.any():
                c = int(np.argmax(bad))
                want = "positive" if definite else "non-negative"
                raise ValueError(f"`{name}` must hold {want} finite variances; got "
                                 f"{scalars[c]} for channel {c}")
            _check_magnitude(scalars, name)
            return scalars[:, None, None] * np.eye(n)[None]
        if arr.shape != (C, n, n):
            raise ValueError(f"`{name}` must be a scalar or have shape ({C},), ({n}, {n}) or "
                             f"({C}, {n}, {n}) (n_channels = {C}, dim_x = {n}); got shape "
                             f"{arr.shape}")
        # the checks of `check_covariance`, for every channel at once
        arr = np.array(arr, dtype=np.float64)
        finite = np.isfinite(arr).all(axis=(1, 2))
        if not finite.all():
            raise ValueError(f"`{name}` must be finite; got NaN or inf entries (channel "
                             f"{int(np.argmin(finite))})")
        scale = np.maximum(np.abs(arr).max(axis=(1, 2)), np.finfo(float).tiny)
        _check_magnitude(scale, name)
        asym = np.abs(arr - arr.transpose(0, 2, 1)).max(axis=(1, 2))
        if (asym > 1e-10 * scale).any():
            c = int(np.argmax(asym > 1e-10 * scale))
            raise ValueError(f"`{name}` must be symmetric; got max |{name} - {name}^T| = "
                             f"{asym[c]:.3g} (channel {c})")
        arr = 0.5 * (arr + arr.transpose(0, 2, 1))
        eig_min = np.linalg.eigvalsh(arr)[:, 0]
        bad = eig_min <= 0.0 if definite else eig_min < -n * np.finfo(float).eps * scale
        if bad.any():
            c = int(np.argmax(bad))
            kind = "definite" if definite else "semidefinite"
            raise ValueError(f"`{name}` must be positive {kind}; got smallest eigenvalue "
                             f"{eig_min[c]:.3g} (channel {c})")
        return arr

    def _estimates(self, value, name):
        C, n = self.n_channels, self.dim_x
        arr = as_float_array(value, name)
        if arr.shape == (n,):
            arr = np.broadcast_to(arr, (C, n))
        if arr.shape != (C, n):
            raise ValueError(f"`{name}` must have shape ({n},) or ({C}, {n}) (n_channels = "
                             f"{C}, dim_x = {n}); got shape {arr.shape}")
        if not np.isfinite(arr).all():
            bad = np.argwhere(~np.isfinite(arr))[0]
            raise ValueError(f"`{name}` must be finite; got {arr[tuple(bad)]} at index "
                             f"{tuple(int(v) for v in bad)}")
        return np.array(arr, dtype=np.float64, order="C")

    def _measurements(self, value, name, shape, expected, ndim=None, finite=True,
                      strided=False):
        """A float64 array of `shape` (or `ndim`): NaN allowed, inf not (not
        checked here with ``finite=False``: the kernels check it).

        `expected` describes the shape in the error message; it may hold the
        fields ``{C}`` and ``{n}`` (filled in only when the message is made).

        C-contiguous, or with ``strided=True`` in the caller's layout (the
        caller decides). The kernels only read it, so the caller's array is
        passed without a copy, unless it is read-only (a pandas frame's values,
        a memory map): numba types a read-only array apart and would compile every
        kernel again for it (about 20 s of CPU), so it is copied.
        """
        arr = value if (type(value) is np.ndarray and value.dtype == np.float64) \
            else as_float_array(value, name)
        if (shape is not None and arr.shape != shape) or (ndim is not None and arr.ndim != ndim):
            expected = expected.format(C=self.n_channels, n=self.dim_x)
            raise ValueError(f"`{name}` must have shape {expected}; got {arr.shape}")
        if not arr.flags.writeable:
            arr = np.array(arr, order="C")
        elif not strided:
            arr = np.ascontiguousarray(arr)
        if finite:
            with np.errstate(invalid="ignore", over="ignore"):    # inf - inf: NaN, no warning
                total = arr.sum()
            if not np.isfinite(total) and np.isinf(arr).any():
                idx = tuple(int(v) for v in np.argwhere(np.isinf(arr))[0])
                raise ValueError(f"`{name}` must be finite or NaN (missing); got {arr[idx]} at "
                                 f"index {idx}")
        return arr

    def _batch_variances(self, Rs, N):
        C = self.n_channels
        if Rs is None:
            return self._R.reshape(1, C)
        arr = as_float_array(Rs, "Rs")
        if arr.ndim <= 1:
            return self._per_channel_positive(arr, "Rs").reshape(1, C)
        if arr.shape != (N, C):
            raise ValueError(f"`Rs` must be a scalar or have shape ({C},) or ({N}, {C}) (one "
                             f"variance per channel, or per step and channel); got {arr.shape}")
        bad = ~(np.isfinite(arr) & (arr > 0.0))
        if bad.any():
            idx = tuple(int(v) for v in np.argwhere(bad)[0])
            raise ValueError(f"`Rs` must hold positive finite variances; got {arr[idx]} at "
                             f"index {idx}")
        return np.ascontiguousarray(arr)

    def _checked_x(self):
        """``x`` in the kernels' layout, ``x^T`` of shape (dim_x, C) (`_t`)."""
        x = self._x
        C, n = self.n_channels, self.dim_x
        if not isinstance(x, np.ndarray) or x.shape != (C, n):
            raise ValueError(f"`x` must be an array of shape ({C}, {n}); got "
                             f"{getattr(x, 'shape', type(x).__name__)}")
        return _t(x)

    def _checked_P(self):
        """``P`` in the kernels' layout, ``P^T`` of shape (dim_x, dim_x, C) (`_t`)."""
        P = self._P
        C, n = self.n_channels, self.dim_x
        if not isinstance(P, np.ndarray) or P.shape != (C, n, n):
            raise ValueError(f"`P` must be an array of shape ({C}, {n}, {n}); got "
                             f"{getattr(P, 'shape', type(P).__name__)}")
        return _t(P)



def subset(bank, channels):
    """A new `RLSBank` of `channels` (an integer index array) of `bank`, with their
    configuration (``lam``, ``R``, ``Q``, ``P0``, ``x0``, the mode's constants,
    already validated there) and a fresh state, as ``RLSBank(len(channels), ...)``
    with those channels' options would be, without validating them again
    (`rlsfilt.fit_many` takes one chunk of a fleet at a time)."""
    channels = np.asarray(channels, dtype=np.int64)
    new = copy.copy(bank)
    new.__dict__ = {key: value for key, value in bank.__dict__.items()
                    if key in ("dim_x", "_mode", "_forgetting_params_in", "check_every",
                               "cond_max", "parallel")}
    new.n_channels = len(channels)
    for name in ("_lam", "_il", "_R", "_params"):
        setattr(new, name, getattr(bank, name)[channels])           # (copies)
    for name in ("_Q", "_P0", "_x0"):                               # (state layout)
        setattr(new, name, np.asfortranarray(getattr(bank, name)[channels]))
    new._Q_is_zero = not new._Q.any()
    new.reset()
    return new


def full_rank(As, R):
    """``np.linalg.matrix_rank(As)`` of each ``(k0, n)`` matrix of the stack `As`
    (C, k0, n), from its QR factors ``R`` (C, n, n) where they settle the
    answer (`R` is None when ``k0 < n``); and ``R^-1`` when every ``R`` has
    a nonzero diagonal (else None).

    ``matrix_rank`` counts the singular values above ``tol = s_max max(k0,
    n) eps``. With ``As = Q R``, ``s_max <= ||R||_F`` and ``s_min >= 1 /
    ||R^-1||_F``, so ``1 / ||R^-1||_F > 1000 ||R||_F max(k0, n) eps``
    proves full rank ``n`` with a wide margin for the rounding of either
    computation; ``matrix_rank`` (an SVD per matrix) decides the other
    matrices, so the ranks are those ``matrix_rank`` gives. Most channels of
    an excited fleet are settled by the QR (cheaper than the SVD).
    """
    C, k0, n = As.shape
    if R is None or C == 0:
        return np.broadcast_to(np.linalg.matrix_rank(As) if k0 else 0, (C,)), None
    rank = np.full(C, n)
    proved = (np.diagonal(R, axis1=1, axis2=2) != 0.0).all(axis=1)
    every = bool(proved.all())
    Rinv = np.linalg.inv(R if every else R[proved])
    Rp = R if every else R[proved]
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):  # (not proved)
        bound = 1.0 / np.sqrt((Rinv * Rinv).sum(axis=(1, 2)))
        scale = np.sqrt((Rp * Rp).sum(axis=(1, 2)))
    proved[proved] = bound > 1000.0 * scale * max(k0, n) * np.finfo(float).eps
    rest = np.flatnonzero(~proved)
    if rest.size:
        rank[rest] = np.linalg.matrix_rank(As[rest])
    return rank, (Rinv if every else None)


def _t(a):
    """The kernels' view of a state array of the bank: its transpose, C-contiguous
    float64 (no copy when `a` is in the bank's Fortran order, else a copy)."""
    t = a.T
    return t if t.flags.c_contiguous and t.dtype == np.float64 else \
        np.ascontiguousarray(t, dtype=np.float64)


def _check_magnitude(scale, name):
    """The largest entry of each channel's covariance (`scale`, shape (C,)) is at
    most `COVARIANCE_MAX`, as `check_covariance` requires of one matrix."""
    bad = scale > COVARIANCE_MAX
    if bad.any():
        c = int(np.argmax(bad))
        raise ValueError(f"`{name}` must have entries of magnitude at most {COVARIANCE_MAX:.0e} "
                         f"(the update multiplies two of them); got {scale[c]:.3g} for channel "
                         f"{c}")


def _raise_infinite(k_inf, Z, H):
    """Name the first infinite measurement or regressor entry the kernel found."""
    bad = np.flatnonzero(k_inf >= 0)
    if not bad.size:
        return
    k = int(k_inf[bad].min())
    c = int(bad[k_inf[bad] == k][0])
    if np.isinf(Z[k, c]):
        raise ValueError(f"`zs` must be finite or NaN (missing); got {Z[k, c]} at index "
                         f"({k}, {c})")
    j = int(np.argmax(np.isinf(H[k, c])))
    raise ValueError(f"`Hs` must be finite or NaN (missing); got {H[k, c, j]} at index "
                     f"({k}, {c}, {j})")


def _list(channels, most=10):
    """``[3, 17, 40]``, or the first `most` and a count."""
    shown = ", ".join(str(int(c)) for c in channels[:most])
    more = f", ... ({len(channels) - most} more)" if len(channels) > most else ""
    return f"[{shown}{more}]"


RLSBank.__signature__ = init_signature(RLSBank)   # __init__'s, not __new__'s
