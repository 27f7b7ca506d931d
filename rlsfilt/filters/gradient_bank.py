r"""A bank of independent gradient (NLMS, LMS, sign-LMS) filters, one per channel.

`GradientBank` is to the gradient filters of :mod:`rlsfilt.filters.gradient`
what `RLSBank` is to `RecursiveLeastSquares`: ``n_channels`` single-output
filters of the same size and rule side by side, the state with a leading
channel axis (``x`` is ``(C, dim_x)``), every channel updated by one
compiled call per :meth:`GradientBank.update` and per
:meth:`GradientBank.batch_filter` (``_kernels_gradient.bank_step``: the
operations of ``lms_step`` in the same order, so each channel has the bits
of its own `NLMS`, `LMS`, ... filter, and so padasip's weights). The API is
the bank's (`RLSBank`): ``(C,)`` measurements, ``(C, dim_x)`` regressor rows,
a `BankHistory` from ``batch_filter``, NaN as missing data per channel,
``channel(i)``, ``freeze()``, ``update_block``; there is no covariance.
"""


import numpy as np

from .._lazy import lazy_module
from .._locking import atomic as _atomic
from .._locking import init_signature
from .._locking import locked as _locked
from .._validation import as_float_array, check_bool, check_dimension, check_int, check_length
from . import gradient as _gradient
from ._base import refuse_fixed
from .bank import BankBase, BankHistory

__all__ = ["GradientBank"]

_kernels = lazy_module("rlsfilt.filters._kernels_gradient")
_CLASSES = {"lms": _gradient.LMS, "nlms": _gradient.NLMS,
            "sign_error": _gradient.SignErrorLMS, "sign_data": _gradient.SignDataLMS,
            "sign_sign": _gradient.SignSignLMS}


class GradientBank(BankBase):
    r"""``n_channels`` independent gradient filters (NLMS by default) updated together.

    Channel ``c`` estimates ``x[c]`` in its own regression
    :math:`z_{k,c} = H_{k,c}\, x_c + v_{k,c}` with the rule `method` and its
    own step size, as the single filter of that rule (`NLMS`, `LMS`,
    `SignErrorLMS`, `SignDataLMS`, `SignSignLMS`) with ``dim_z = 1`` would,
    bit for bit; one compiled call updates every channel.

    Parameters
    ----------
    n_channels : int
        Number of channels ``C``.
    dim_x : int
        Number of parameters of every channel.
    mu : float or array_like of shape (C,), default 0.1
        Step size, positive, shared or one per channel.
    method : {"nlms", "lms", "sign_error", "sign_data", "sign_sign"}, default "nlms"
        The update rule (see :mod:`rlsfilt.filters.gradient`).
    eps : float or array_like of shape (C,), default 0.001
        Regularization of the normalization (``"nlms"`` only), ``>= 0``.
    leak : float or array_like of shape (C,), default 0.0
        Leakage ``a >= 0``: ``x <- (1 - mu a) x + ...``.
    x0 : array_like of shape (dim_x,) or (C, dim_x), optional
        Initial weights, shared or one per channel; zeros by default.
    R : float or array_like of shape (C,), default 1.0
        Measurement-noise variance: the predictive variance ``S`` of the
        diagnostics (not used by the update).

    Attributes
    ----------
    x : ndarray, shape (C, dim_x)
        Estimates, one row per channel.
    x_prior, x_post : ndarray, shape (C, dim_x)
        Copies of ``x`` after the last predict and update.
    H : ndarray, shape (C, dim_x)
        Regressors of the last update.
    z, y : ndarray, shape (C,)
        Last measurements and a-priori residuals :math:`z - H x^-` (NaN
        where a channel skipped the update).
    S, SI : ndarray, shape (C,)
        ``R`` and ``1 / R`` (NaN where the regressor held NaN).
    K : ndarray, shape (C, dim_x)
        Gains of the last update (zero where a channel skipped it).
    n_updates : int
        Measurement updates since :meth:`reset`.

    Notes
    -----
    Each channel runs (Haykin 2002, ch. 5-6)

    .. math::

        y_c = z_c - H_c x_c, \qquad K_c = \mu_c\, s(H_c)^T / n_c, \qquad
        x_c \leftarrow (1 - \mu_c a_c)\, x_c + K_c\, g(y_c)

    with ``s``, ``g`` the identity or the sign and ``n_c = eps_c + H_c H_c^T``
    (``"nlms"``) or 1. A NaN in ``z[c]`` or in the regressor ``H[c]`` skips
    channel ``c`` at that step (``y`` NaN, ``K`` zero); infinite values are
    errors. A call that raises leaves the bank as it was; the bank's own
    reentrant lock makes every call whole when threads share it.

    References
    ----------
    .. [1] S. Haykin, *Adaptive Filter Theory*, 4th ed., Prentice Hall, 2002,
       ch. 5 and 6.

    Examples
    --------
    Three plants ``z = H x`` identified by normalized LMS at once:

    >>> import numpy as np
    >>> from rlsfilt import GradientBank
    >>> rng = np.random.default_rng(0)
    >>> theta = np.array([[1.0, -0.5], [0.3, 2.0], [-1.0, 0.25]])
    >>> Hs = rng.standard_normal((500, 3, 2))             # (N, C, dim_x)
    >>> zs = np.einsum("kci,ci->kc", Hs, theta)
    >>> bank = GradientBank(3, 2, mu=0.5)
    >>> _ = bank.batch_filter(zs, Hs)
    >>> np.round(bank.x, 6)
    array([[ 1.  , -0.5 ],
           [ 0.3 ,  2.  ],
           [-1.  ,  0.25]])
    """

    has_covariance = False
    least_squares = False
    _NO_FADING_MEMORY = "adapts by its step sizes `mu`, it has no fading-memory factor"

    def __init__(self, n_channels, dim_x, mu=0.1, *, method="nlms", eps=0.001, leak=0.0,
                 x0=None, R=1.0):
        self.dim_x = check_dimension(dim_x, "dim_x")
        self.n_channels = check_length(n_channels, "n_channels",
                                       bytes_per_item=64 * self.dim_x)
        if not isinstance(method, str) or method not in _CLASSES:
            raise ValueError(f"`method` must be one of {', '.join(map(repr, _CLASSES))}; got "
                             f"{method!r}")
        self._method = method
        self._mu = self._per_channel(mu, "mu", strict=True)
        self._eps = self._per_channel(eps, "eps")
        self._leak = self._per_channel(leak, "leak")
        self.R = R
        self._x0 = self._estimates(np.zeros(self.dim_x) if x0 is None else x0, "x0")
        self.reset()

    # ------------------------------------------------------------------
    # state and configuration; assigning stores a copy
    # ------------------------------------------------------------------
    @property
    def x(self):
        """Estimates, ``(C, dim_x)``; assigning stores a copy."""
        return self._x

    @x.setter
    @_locked
    def x(self, value):
        self._x = self._estimates(value, "x")

    @property
    def method(self):
        """The update rule (read-only; chosen at construction)."""
        return self._method

    @method.setter
    def method(self, value):
        refuse_fixed(self, "method", "construct a new bank with method=...")

    @property
    def mu(self):
        """Step sizes, shape (C,) (a copy; read-only, chosen at construction)."""
        return self._mu.copy()

    @mu.setter
    def mu(self, value):
        refuse_fixed(self, "mu", "construct a new bank with mu=...")

    @property
    def eps(self):
        """Regularizations of the normalization, shape (C,) (a copy; read-only)."""
        return self._eps.copy()

    @eps.setter
    def eps(self, value):
        refuse_fixed(self, "eps", "construct a new bank with eps=...")

    @property
    def leak(self):
        """Leakages, shape (C,) (a copy; read-only)."""
        return self._leak.copy()

    @leak.setter
    def leak(self, value):
        refuse_fixed(self, "leak", "construct a new bank with leak=...")

    @property
    def R(self):
        """Measurement-noise variances, shape (C,) (a copy; assign to change them)."""
        return self._R.copy()

    @R.setter
    @_locked
    def R(self, value):
        self._R = self._variances(value, "R")

    # ------------------------------------------------------------------
    # the recursion
    # ------------------------------------------------------------------
    @_locked
    def predict(self):
        """No time update (constant weights): ``x_prior`` is a copy of ``x``."""
        self.x_prior = self._x.copy()

    @_atomic
    def update(self, z, H, R=None):
        r"""One gradient step of every channel (only the diagnostics while :attr:`frozen`).

        Parameters
        ----------
        z : array_like, shape (C,), or None
            One measurement per channel; NaN skips that channel, None every
            channel.
        H : array_like, shape (C, dim_x)
            One regressor row per channel; a row holding NaN skips that channel.
        R : float or array_like of shape (C,), optional
            Noise variances for this call only (the diagnostics' ``S``).
        """
        C, n = self.n_channels, self.dim_x
        zz = self._measured(np.full(C, np.nan) if z is None else z, "z", (C,),
                            f"({C},) (one measurement per channel)")
        Hm = self._measured(H, "H", (C, n),
                            f"({C}, {n}) (one regressor row of dim_x = {n} per channel)")
        r = (self._R if R is None else self._variances(R, "R")).reshape(1, C)
        x, K, y, S = self._x.copy(), np.empty((C, n)), np.empty(C), np.empty(C)
        if self.frozen:                      # adaptation off: only the diagnostics
            with np.errstate(invalid="ignore"):
                y = zz - (Hm * x).sum(axis=1)                   # y = z - H x
            S = np.where(np.isnan(Hm).any(axis=1), np.nan, r[0])
            self._diagnostics(zz, Hm, y, S, np.zeros((C, n)))
            return
        # y = z - H x, K = mu s(H)^T / n, x <- (1 - mu a) x + K g(y) (_kernels_gradient)
        k = _kernels()
        k.bank_update(k.METHODS.index(self._method), x, Hm[None], zz[None], self._mu,
                      self._eps, self._leak, K, y, S, r)
        self._x, self.x_post = x, x.copy()
        self.n_updates += 1
        self._diagnostics(zz, Hm, y, S, K)

    @_atomic
    def predict_update(self, z, H, R=None):
        """:meth:`predict` then :meth:`update`."""
        self.predict()
        self.update(z, H, R)

    @_atomic
    def update_block(self, Z, H, R=None):
        """Several steps of every channel at once (MATLAB's frame-based input):
        :meth:`predict` then :meth:`update` for each row of `Z` (``(N, C)``) and
        `H` (``(N, C, dim_x)``), bit for bit, in one compiled call (the loop of
        :meth:`batch_filter`, whose argument names its messages use). `R` is
        shared, one per channel or ``(N, C)``. Returns the bank."""
        self.batch_filter(Z, H, R, store_means=False, store_residuals=False)
        return self

    @_atomic
    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True, store_means=True, store_residuals=True):
        r"""Run every channel over a record in one compiled call.

        Parameters
        ----------
        zs : array_like, shape (N, C)
            Measurements; NaN skips that channel at that step.
        Hs : array_like, shape (N, C, dim_x)
            Regressor rows; a row holding NaN skips that channel at that step.
        Rs : float or array_like of shape (C,) or (N, C), optional
            Noise variances of the diagnostics (the bank's `R` if omitted).
        update_first : bool, default False
            ``means_p`` holds the estimates after each update instead of before.
        saver : filterpy.common.Saver, optional
            Saved after every step (the record then runs step by step).
        store_covariances : bool, default True
            Accepted for `RLSBank`'s signature; a gradient bank has no covariances.
        store_means, store_residuals : bool, default True
            Keep the estimate and the residual histories.

        Returns
        -------
        BankHistory
            ``means, None, means_p, None`` (``(N, C, dim_x)``), with
            ``residuals`` and ``innovation_variances`` (``(N, C)``).
        """
        C, n = self.n_channels, self.dim_x
        update_first = check_bool(update_first, "update_first")
        check_bool(store_covariances, "store_covariances")
        store_means = check_bool(store_means, "store_means")
        store_residuals = check_bool(store_residuals, "store_residuals")
        if saver is not None and not callable(getattr(saver, "save", None)):
            raise TypeError(f"`saver` must be None or have a save() method (filterpy's Saver); "
                            f"got {type(saver).__name__}")
        Z = self._measured(zs, "zs", None, f"(N, {C}) (one column per channel)", ndim=2)
        if Z.shape[1] != C:
            raise ValueError(f"`zs` must have shape (N, {C}) (one column per channel, "
                             f"n_channels = {C}); got {Z.shape}")
        N = len(Z)
        Hm = self._measured(Hs, "Hs", (N, C, n), f"({N}, {C}, {n}) (N = len(zs) steps, "
                                                  f"n_channels = {C}, dim_x = {n})")
        Rv = self._batch_variances(Rs, N)
        means = np.empty((N if store_means else 0, C, n))
        means_p = np.empty_like(means)
        ys, ss = np.empty((N if store_residuals else 0, C)), np.empty((0, C))
        if store_residuals:
            ss = np.empty((N, C))
        if saver is not None or self.frozen or not N:
            for k in range(N):               # step by step (the same arithmetic)
                if not update_first:
                    self.predict()
                    if store_means:
                        means_p[k] = self._x
                self.update(Z[k], Hm[k], Rv[k if len(Rv) == N else 0])
                if store_means:
                    means[k] = self._x
                if update_first:
                    self.predict()
                    if store_means:
                        means_p[k] = self._x
                if store_residuals:
                    ys[k], ss[k] = self.y, self.S
                if saver is not None:
                    saver.save()
        else:
            x, K, y, S = self._x.copy(), np.empty((C, n)), np.empty(C), np.empty(C)
            x_last = np.empty((C, n))
            k = _kernels()
            k.bank_batch(k.METHODS.index(self._method), x, Hm, Z, self._mu, self._eps,
                         self._leak, update_first, K, y, S, Rv, means, means_p, ys, ss, x_last)
            self.x_prior = x.copy() if update_first else x_last   # (x after the last predict)
            self._x, self.x_post = x, x.copy()
            self.n_updates += N
            self._diagnostics(Z[-1].copy(), Hm[-1].copy(), y, S, K)
        return BankHistory(means if store_means else None, None,
                           means_p if store_means else None, None,
                           ys if store_residuals else None,
                           ss if store_residuals else None, (N, C))

    @_atomic
    def initialize(self, zs, Hs):
        """Start every channel from least squares on its samples `zs` (``(k0,
        C)``), `Hs` (``(k0, C, dim_x)``), rows with a NaN dropped (as the single
        filter's ``initialize`` per channel); a channel whose rows do not
        determine every parameter is a ValueError naming it."""
        C, n = self.n_channels, self.dim_x
        Z = self._measured(zs, "zs", None, f"(k0, {C})", ndim=2)
        if Z.shape[1] != C:
            raise ValueError(f"`zs` must have shape (k0, {C}) (one column per channel, "
                             f"n_channels = {C}); got {Z.shape}")
        Hm = self._measured(Hs, "Hs", (len(Z), C, n), f"({len(Z)}, {C}, {n})")
        x = np.empty((C, n))
        for c in range(C):
            keep = ~(np.isnan(Z[:, c]) | np.isnan(Hm[:, c]).any(axis=1))
            rank = np.linalg.matrix_rank(Hm[keep, c]) if keep.any() else 0
            if rank < n:
                raise ValueError(f"`Hs` is rank-deficient in channel {c}: need {n} "
                                 f"independent rows (dim_x); got rank {rank}")
            x[c] = np.linalg.lstsq(Hm[keep, c], Z[keep, c], rcond=None)[0]
        self._x, self.x_prior, self.x_post = x, x.copy(), x.copy()

    # ------------------------------------------------------------------
    # the adaptation switch (MATLAB's EnableAdaptation)
    # ------------------------------------------------------------------
    @property
    def frozen(self):
        """Whether adaptation is off (:meth:`freeze`): :meth:`update` then computes
        ``y`` and ``S`` but leaves ``x`` and the counters bit-unchanged."""
        return self.__dict__.get("_frozen", False)

    @property
    def adapt(self):
        """``not frozen``: assign False to freeze every channel, True to resume."""
        return not self.frozen

    @adapt.setter
    @_locked
    def adapt(self, value):
        self._frozen = not check_bool(value, "adapt")

    @_locked
    def freeze(self):
        """Stop adapting (predictions and residuals continue). Returns the bank."""
        self._frozen = True
        return self

    @_locked
    def unfreeze(self):
        """Resume adapting. Returns the bank."""
        self._frozen = False
        return self

    # ------------------------------------------------------------------
    # channels, state, copies, reset
    # ------------------------------------------------------------------
    @_locked
    def channel(self, i):
        """Channel `i` as the single filter of the bank's rule (`NLMS`, `LMS`, ...),
        with its configuration and state, so that it continues as channel `i`
        would (bit for bit). The bank is not changed."""
        C, n = self.n_channels, self.dim_x
        i = check_int(i, "i")
        if not -C <= i < C:
            raise ValueError(f"`i` must be a channel index in [{-C}, {C}); got {i}")
        i %= C
        kw = {"leak": float(self._leak[i]), "x0": self._x0[i], "R": float(self._R[i])}
        if self._method == "nlms":
            kw["eps"] = float(self._eps[i])
        f = _CLASSES[self._method](n, 1, float(self._mu[i]), **kw)
        f.x = self._x[i].reshape(n, 1)
        f.x_prior = self.x_prior[i].reshape(n, 1).copy()
        f.x_post = self.x_post[i].reshape(n, 1).copy()
        f.n_updates = self.n_updates
        f.adapt = self.adapt
        return f

    @_locked
    def get_state(self):
        """``x`` (a copy) and the update count."""
        return {"x": self._x.copy(), "n_updates": int(self.n_updates)}

    @_locked
    def set_state(self, state):
        """Continue from a dict of :meth:`get_state`."""
        if not hasattr(state, "keys") or list(state.keys()) != ["x", "n_updates"]:
            raise ValueError("`state` must be a dict from get_state() with the keys ['x', "
                             f"'n_updates']; got {state!r:.60}")
        x = self._estimates(state["x"], "state['x']")
        self._x, self.n_updates = x, int(state["n_updates"])

    @_locked
    def reset(self):
        """Every channel back to ``x0``; diagnostics and counters cleared."""
        C, n = self.n_channels, self.dim_x
        self._x = self._x0.copy()
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self.H, self.K = np.zeros((C, n)), np.zeros((C, n))
        self.z, self.y = np.zeros(C), np.zeros(C)
        self.S, self.SI = np.zeros(C), np.zeros(C)
        self.n_updates = 0
        self._fresh = True

    def __repr__(self):
        return (f"GradientBank(n_channels={self.n_channels}, dim_x={self.dim_x}, "
                f"method={self._method!r}, n_updates={self.n_updates}"
                f"{', frozen' if self.frozen else ''})")

    # ------------------------------------------------------------------
    # private helpers
    # ------------------------------------------------------------------
    def _diagnostics(self, z, H, y, S, K):
        self.z, self.H, self.y, self.S, self.K = z, H, y, S, K
        with np.errstate(divide="ignore", invalid="ignore"):
            self.SI = 1.0 / S
        self._fresh = False

    def _per_channel(self, value, name, strict=False):
        """A non-negative (positive: `strict`) finite scalar or one per channel, (C,)."""
        C = self.n_channels
        if np.asarray(value).dtype == bool:
            raise TypeError(f"`{name}` must be a number or one number per channel; got {value!r}")
        arr = as_float_array(value, name)
        if arr.ndim == 0:
            arr = np.full(C, float(arr))
        if arr.shape != (C,):
            raise ValueError(f"`{name}` must be a scalar or have shape ({C},) (one value per "
                             f"channel, n_channels = {C}); got shape {arr.shape}")
        bad = ~np.isfinite(arr) | ((arr <= 0.0) if strict else (arr < 0.0))
        if bad.any():
            c = int(np.argmax(bad))
            want = "positive" if strict else "non-negative"
            raise ValueError(f"`{name}` must be {want} and finite; got {arr[c]} for channel {c}")
        return np.array(arr, dtype=np.float64)

    def _variances(self, value, name):
        return self._per_channel(value, name, strict=True)

    def _batch_variances(self, Rs, N):
        C = self.n_channels
        if Rs is None:
            return self._R.reshape(1, C)
        arr = as_float_array(Rs, "Rs")
        if arr.ndim <= 1:
            return self._variances(arr, "Rs").reshape(1, C)
        if arr.shape != (N, C):
            raise ValueError(f"`Rs` must be a scalar or have shape ({C},) or ({N}, {C}) (one "
                             f"variance per channel, or per step and channel); got {arr.shape}")
        bad = ~(np.isfinite(arr) & (arr > 0.0))
        if bad.any():
            idx = tuple(int(v) for v in np.argwhere(bad)[0])
            raise ValueError(f"`Rs` must hold positive finite variances; got {arr[idx]} at "
                             f"index {idx}")
        return np.ascontiguousarray(arr, dtype=np.float64)

    def _estimates(self, value, name):
        C, n = self.n_channels, self.dim_x
        arr = as_float_array(value, name)
        if arr.shape == (n,):
            arr = np.broadcast_to(arr, (C, n))
        if arr.shape != (C, n):
            raise ValueError(f"`{name}` must have shape ({n},) or ({C}, {n}) (n_channels = "
                             f"{C}, dim_x = {n}); got shape {arr.shape}")
        if not np.isfinite(arr).all():
            bad = tuple(int(v) for v in np.argwhere(~np.isfinite(arr))[0])
            raise ValueError(f"`{name}` must be finite; got {arr[bad]} at index {bad}")
        return np.array(arr, dtype=np.float64, order="C")

    @staticmethod
    def _measured(value, name, shape, expected, ndim=None):
        """A C-contiguous float64 array of `shape` (or `ndim`); NaN allowed (missing),
        inf not."""
        arr = as_float_array(value, name)
        if (shape is not None and arr.shape != shape) or (ndim is not None and arr.ndim != ndim):
            raise ValueError(f"`{name}` must have shape {expected}; got {arr.shape}")
        if np.isinf(arr).any():
            idx = tuple(int(v) for v in np.argwhere(np.isinf(arr))[0])
            raise ValueError(f"`{name}` must be finite or NaN (missing); got {arr[idx]} at "
                             f"index {idx}")
        return np.ascontiguousarray(arr, dtype=np.float64)


GradientBank.__signature__ = init_signature(GradientBank)   # __init__'s, not __new__'s
