"""Shared base of the rlsfilt filters: argument checks and filterpy diagnostics.

`RecursiveLeastSquares`, `SlidingWindowRLS` and `SquareRootRLS` differ in how
they store and update the covariance, not in what they accept or report, so
the validation of regressors, measurements and batch records, the lazy
filterpy diagnostics (``log_likelihood``, ``likelihood``, ``mahalanobis``) and
the small filterpy helpers live here once.

**Threads.** Every filter carries a reentrant lock (`_locked`): each public
call that changes its state (``predict``, ``update``, ``predict_update``,
``batch_filter``, ``initialize``, ``reset``, ``constrain``, ``set_state``,
``set_diagnostics`` and the property setters) holds it, so a filter shared
by threads applies every call whole, one at a time, and loses none; copies
and pickles are taken under it too. The lock costs about 0.1 us per call
(``python benchmarks/bench_rls.py --lock-cost``); it is not pickled or
copied: each filter, and each copy, has its own.
"""

import copy
import functools
import inspect
import math
import threading
import warnings
import weakref

import numpy as np

from .._display import filter_html
from .._locking import init_signature
from .._locking import locked as _locked
from .._validation import (
    VARIANCE_RANGE,
    as_float_array,
    check_bool,
    check_finite,
    check_int,
    check_scalar,
    check_variance,
)
from . import _health
from .contract import Filter

__all__ = []

_LOG_2PI = math.log(2.0 * math.pi)
_TINY = float(np.finfo(float).tiny)
#: The diagnostics of a missing measurement: it adds nothing to the log-likelihood,
#: and there is no residual to measure.
MISSING_DIAGNOSTICS = (0.0, 1.0, math.nan)
#: The diagnostics of the last update that `set_diagnostics` assigns.
_DIAGNOSTICS = ("x_prior", "P_prior", "x_post", "P_post", "H", "K", "S", "SI", "z", "y")


class _FilterBase(Filter):
    """Validation helpers and diagnostics shared by the filters.

    Subclasses set ``dim_x``, ``dim_z``, ``_R`` and provide ``x`` (and ``P`` when
    ``has_covariance``) and the abstract members of `rlsfilt.filters.contract.Filter`.
    Each instance has its own reentrant lock ``_lock`` (made in ``__new__``, so
    also for copies and unpickled filters); see the module docstring.
    """

    # a slot, not in ``__dict__``: filterpy's Saver deep-copies ``__dict__``, and a
    # lock can be neither copied nor pickled
    __slots__ = ("_lock",)
    # why `alpha` (and `lam`) cannot be assigned to a filter without `lam` (the message's end)
    _NO_FADING_MEMORY = "has no fading-memory factor"
    #: The settings (of `OPTION_NAMES`) whose assignment this class honours; each class
    #: declares its own whole set. Every other name of `OPTION_NAMES` is refused by name
    #: on assignment (an AttributeError saying why and what to use instead) and reads as
    #: absent, unless the class defines it itself (a read-only property, the base's
    #: ``F``, ``B``, ``inv``, ``Q``, ``alpha``, ``check_every``). See `_guard`.
    _options = frozenset({"x", "R"})

    def __new__(cls, *args, **kwargs):
        self = super().__new__(cls)
        self._lock = threading.RLock()
        return self

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.__signature__ = init_signature(cls)   # __init__'s, not __new__'s (*args, **kwargs)
        register_filter_class(cls)

    def __getstate__(self):
        """The attributes without the lock, read under it (pickle, copy, deepcopy)."""
        with self._lock:
            return self._shallow_state()

    def __setstate__(self, state):
        self._lock = threading.RLock()      # (made by __new__ too; not by pickle protocol 0, 1)
        self._restore(state)

    def _repr_html_(self):
        return filter_html(self)   # Jupyter: dimensions, settings, estimate +- std dev, health

    @property
    def R(self):
        """Measurement-noise variance (a positive float)."""
        return self._R

    @property
    def check_every(self):
        """Health check period in updates (0: off); assign None for the default
        ``max(250, 32 dim_x)``, which keeps the O(dim_x^3) test under 5 % of the
        O(dim_x^2) updates at every size. A filter without a covariance
        (``has_covariance = False``) has no health check: 0, read-only."""
        return self._check_every if self.has_covariance else 0

    @check_every.setter
    @_locked
    def check_every(self, value):
        if not self.has_covariance:
            raise AttributeError(_refused(
                "check_every", f"{type(self).__name__} keeps no covariance, so it has no "
                "health check; a least-squares filter (RecursiveLeastSquares(check_every=...)) "
                "has one"))
        self._check_every = (max(250, 32 * self.dim_x) if value is None
                             else check_int(value, "check_every", minimum=0))

    @R.setter
    @_locked
    def R(self, value):
        self._R = check_variance(value, "R")

    # ------------------------------------------------------------------
    # lazily computed diagnostics, as in filterpy
    # ------------------------------------------------------------------
    @property
    def log_likelihood(self):
        """Log-likelihood of the last measurement, ``log N(y; 0, S)``."""
        return self._diagnostics()[0]

    @property
    def likelihood(self):
        """``exp(log_likelihood)``, floored at the smallest positive float."""
        return self._diagnostics()[1]

    @property
    def mahalanobis(self):
        """Mahalanobis distance ``sqrt(y^T S^-1 y)`` of the last residual."""
        return self._diagnostics()[2]

    @_locked
    def set_diagnostics(self, **values):
        """Assign the diagnostics of the last update (``H``, ``z``, ``y``, ``K``, ``S``,
        ``SI``, ``x_prior``, ``P_prior``, ``x_post``, ``P_post``), as a filter handed a
        run over from another one (``ARX.fit``) does; ``log_likelihood`` and its
        relatives are computed from them on first use (a NaN ``z``: a missing sample)."""
        unknown = sorted(set(values) - set(_DIAGNOSTICS))
        if unknown:
            raise TypeError(f"`{unknown[0]}` is not a diagnostic; expected one of "
                            f"{', '.join(_DIAGNOSTICS)}")
        for name, value in values.items():
            setattr(self, name, value)
        z = values.get("z", getattr(self, "z", None))
        self._lazy = (MISSING_DIAGNOSTICS if z is not None and np.isnan(z).any()
                      else None)

    def _diagnostics(self):
        """``(log_likelihood, likelihood, mahalanobis)``, computed on first use after
        an update (``_lazy`` is None until then)."""
        if self._lazy is None:
            ll = _gaussian_logpdf(self.y, self.S[0, 0])
            self._lazy = (ll, max(math.exp(ll), _TINY),
                          math.sqrt(float(np.vdot(self.y, self.y)) / self.S[0, 0]))
        return self._lazy

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

    def as_iosystem(self, regressor, dt=True):
        """This filter as a python-control system: `rlsfilt.adaptive.estimator_iosystem`."""
        from ._estimator_io import estimator_iosystem
        return estimator_iosystem(self, regressor, dt)

    # ------------------------------------------------------------------
    # filterpy's KalmanFilter names that least squares does not use
    # ------------------------------------------------------------------
    @property
    def F(self):
        """State transition: the identity (constant parameters); read-only."""
        return np.eye(self.dim_x)

    @F.setter
    def F(self, value):
        raise AttributeError(_refused("F", "the state transition of least squares is the "
                                           f"identity (constant parameters) in "
                                           f"{type(self).__name__}; model drift with Q "
                                           "(RecursiveLeastSquares)"))

    @property
    def Q(self):
        """Random-walk covariance: zero, read-only, for the filters without a random walk
        (`RecursiveLeastSquares` has its own, settable)."""
        return np.zeros((self.dim_x, self.dim_x))

    @Q.setter
    def Q(self, value):
        raise AttributeError(_refused("Q", f"{type(self).__name__} has no random walk (filterpy's "
                                           "process noise); RecursiveLeastSquares(Q=...) has one"))

    @property
    def B(self):
        """Control matrix: None (least squares has no control input); read-only."""
        return None

    @B.setter
    def B(self, value):
        raise AttributeError(_refused("B", "least squares has no control input: "
                                           f"{type(self).__name__} estimates the parameters of "
                                           "H x; known inputs belong in the regressor H"))

    @property
    def inv(self):
        """filterpy's matrix inverse: `numpy.linalg.inv`, unused (the filters never
        invert ``S`` or ``P``); read-only."""
        return np.linalg.inv

    @inv.setter
    def inv(self, value):
        raise AttributeError(_refused("inv", f"{type(self).__name__} never inverts a matrix "
                                             "(S is a scalar times I); there is no inverse "
                                             "to replace"))

    @property
    def alpha(self):
        """filterpy's fading-memory factor, ``alpha**2 = 1 / lam`` (1 without
        forgetting; an array with ``forgetting="diagonal"``); assigning it sets `lam`
        to ``1 / alpha**2``. The filter then equals filterpy's ``KalmanFilter`` with
        that ``alpha`` in the exponential mode; in the directional, constant-trace,
        EFRA and variable modes `lam` is that mode's factor, which forgets along the
        regressor or bounds ``P`` instead of scaling all of ``P``."""
        lam = getattr(self, "lam", 1.0)
        return 1.0 / np.sqrt(lam) if isinstance(lam, np.ndarray) else 1.0 / math.sqrt(lam)

    @alpha.setter
    @_locked
    def alpha(self, value):
        if not hasattr(type(self), "lam"):
            raise AttributeError(_refused("alpha", f"{type(self).__name__} "
                                                   f"{self._NO_FADING_MEMORY}; "
                                                   "RecursiveLeastSquares and SquareRootRLS "
                                                   "have one (lam)"))
        alpha = check_scalar(value, "alpha")
        if not (math.isfinite(alpha) and alpha >= 1.0):
            raise ValueError("`alpha` must be a finite number >= 1 (filterpy's fading memory, "
                             f"alpha**2 = 1 / lam with lam in (0, 1]); got {alpha}")
        self.lam = 1.0 / (alpha * alpha)

    def _refuse_control(self, u, B, F):
        """Raise for filterpy's `u`, `B`, `F` arguments of ``predict`` (any but None)."""
        # the hint only where predict takes a random walk (not the square-root, window
        # and gradient filters)
        hint = (" A random walk is predict(Q=...)"
                if "Q" in inspect.signature(type(self).predict).parameters else "")
        for name, value in (("u", u), ("B", B), ("F", F)):
            if value is not None:
                raise TypeError(
                    f"`{name}` is not an argument {type(self).__name__}.predict() uses: least "
                    "squares has F = I and no control input (filterpy's predict(u, B, F)); "
                    f"got {name}={value!r}.{hint}")

    def get_update(self, z, H=None, R=None):
        """Return ``(x, P)`` after an :meth:`update` with `z`, `H` (``self.H`` if
        omitted) and `R`, without changing the filter (filterpy's ``get_update``).

        Runs the update on a copy of the filter, so the numbers are those of
        :meth:`update` bit for bit; its warnings are not issued.
        """
        twin = copy.deepcopy(self)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            twin.update(z, H, R)
        return twin.x, twin.P

    # ------------------------------------------------------------------
    # adaptation switch (MATLAB's EnableAdaptation) and frames of rows
    # ------------------------------------------------------------------
    @property
    def frozen(self):
        """Whether adaptation is off (:meth:`freeze`): ``update`` then computes the
        residual ``y`` and its variance ``S`` but leaves ``x``, ``P`` and the
        counters bit-unchanged, and ``predict`` changes nothing."""
        return self.__dict__.get("_frozen", False)

    @property
    def adapt(self):
        """``not frozen``: assign False to freeze the estimate, True to resume
        (MATLAB's ``EnableAdaptation``)."""
        return not self.frozen

    @adapt.setter
    @_locked
    def adapt(self, value):
        self._frozen = not check_bool(value, "adapt")

    def freeze(self):
        """Stop adapting: predictions and residuals continue, ``x`` and ``P`` stay
        as they are until :meth:`unfreeze`. Returns the filter."""
        self._frozen = True
        return self

    def unfreeze(self):
        """Resume adapting from the state held while frozen. Returns the filter."""
        self._frozen = False
        return self

    def _frozen_predict(self):
        """``predict`` while frozen: record ``x_prior`` (and ``P_prior``), nothing else."""
        self.x_prior = self.x.copy()
        if self.has_covariance:
            self.P_prior = self.P.copy()

    def _frozen_update(self, z, H, R):
        """``update`` while frozen: validate as ``update`` does, then only the
        diagnostics: ``y = z - H x``, ``S = (H P H^T + R) I`` (``R I`` without a
        covariance), ``K = 0``; ``x``, ``P`` and the counters stay bit-unchanged."""
        phi = self._as_regressor(self.H if H is None else H, "H")
        r = self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        x = self._checked_x()
        if self.has_covariance:
            _, s = _innovation(self._checked_P(), phi, r)
        else:
            s = r
        m = self.dim_z
        if zc is None:
            zc = np.full((m, 1), np.nan)
        y = zc - (phi @ x).T                          # y = z - H x (NaN when missing)
        S = s * np.eye(m)
        self.H = phi
        self.set_diagnostics(z=zc, y=y, K=np.zeros_like(self.K), S=S, SI=np.eye(m) / s)

    def update_block(self, Z, H, R=None):
        """Several samples at once (MATLAB's frame-based input): for each row of
        `Z` (``(N,)`` or ``(N, dim_z)``, NaN for missing) and of `H` (``(N,
        dim_x)``), a :meth:`predict` then an :meth:`update`, bit for bit those
        calls one by one, in one compiled call (``batch_filter``'s loop; its
        arguments are named ``zs``, ``Hs``, ``Rs`` in its messages). `R` is a
        variance for every row or one per row. Leaves the diagnostics of the last
        row's update; a call that raises changes nothing. Returns the filter.
        """
        self._batch(Z, H, R, False, None, False)
        return self

    @_locked
    def predict_update(self, z, H=None, R=None):
        """One textbook step: :meth:`predict` then :meth:`update`.

        If :meth:`update` rejects its input (or its warning is turned into an
        error), the :meth:`predict` is undone too: the filter is left as it was.
        """
        before = self._shallow_state()
        self.predict()
        try:
            self.update(z, H, R)
        except BaseException:
            self._restore(before)
            raise

    @_locked
    def _batch(self, zs, Hs, Rs, update_first, saver, store_covariances):
        """`batch_filter` of every filter: validate the record, then run the
        compiled loop (``_batch_compiled``) or, with a `saver` or an empty
        record, ``predict``/``update`` step by step. Either way a call that
        raises (or whose warning is turned into an error) leaves the filter
        as it was."""
        Z, Hm = self._as_batch(zs, Hs)
        Rv = self._as_batch_variances(Rs, len(Z))
        update_first = check_bool(update_first, "update_first")
        store_covariances = check_bool(store_covariances, "store_covariances")
        if saver is not None and not callable(getattr(saver, "save", None)):
            raise TypeError(f"`saver` must be None or have a save() method (filterpy's Saver); "
                            f"got {type(saver).__name__}")
        if saver is None and len(Z) and not self.frozen:
            return self._batch_compiled(Z, Hm, Rv, update_first, store_covariances)
        before = copy.deepcopy(self)._shallow_state()
        self._batch_start = self.n_updates
        try:
            out = self._batch_stepwise(Z, Hm, Rv, update_first, saver, store_covariances)
            self._batch_start = None
            self._final_health_check()
        except BaseException:
            self._restore(before)
            raise
        return out

    def _batch_stepwise(self, Z, Hm, Rv, update_first, saver, store_covariances):
        """Run ``predict``/``update`` over a validated record (the generic batch loop)."""
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
            if saver is not None:
                saver.save()
        return means, covs, means_p, covs_p

    def _health_due(self, n_updates, cheap_failed):
        """Whether the full health check runs after update `n_updates`: every
        ``check_every`` updates, or when the cheap check failed; not again after
        the warning (until :meth:`reset`)."""
        every = self.check_every
        return (bool(every) and not self._warned_health
                and (cheap_failed or n_updates % every == 0))

    def _warn_health(self, problem):
        """Issue the health warning for `problem` (None: nothing). Called before
        a step changes the state, so a warning turned into an error leaves the
        filter as it was."""
        if problem is not None:
            _health.warn(problem, self._HEALTH_ADVICE)
            self._warned_health = True

    def _shallow_state(self):
        """The attributes (``__dict__`` and slots) as a new dict. The steps never
        write into an array they leave behind, except those in ``_written_in_place``
        (which the filter's own step puts back on failure), so this is enough to
        undo one."""
        state = self.__dict__.copy()
        for cls in type(self).__mro__:
            for name in getattr(cls, "__slots__", ()):
                state[name] = getattr(self, name)
        del state["_lock"]                  # the filter's own: never copied or restored
        return state

    def _restore(self, state):
        """Put back `state` (from `_shallow_state`, of this filter or of a deep copy)."""
        slots = _slots(type(self))
        for name, value in state.items():
            if name in slots:
                setattr(self, name, value)
            else:
                self.__dict__[name] = value

    def _reset_diagnostics(self):
        """The filterpy attributes of a filter that has seen no data yet."""
        n, m = self.dim_x, self.dim_z
        self.H = np.zeros((1, n))
        self.z = np.zeros((m, 1))
        self.y = np.zeros((m, 1))
        self.K = np.zeros((n, 1))
        self._I_z = np.eye(m)
        self.S = np.zeros((m, m))
        self.SI = np.zeros((m, m))
        # before any update, as filterpy: nothing observed yet
        self._lazy = (math.log(_TINY), _TINY, 0.0)

    def _clear_lazy(self):
        self._lazy = None


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
        if isinstance(z, float) and self.dim_z == 1 and z - z == 0.0:   # a finite float
            return np.array(z, ndmin=2)
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
        for arg, value in (("zs", zs), ("Hs", Hs)):
            if value is None or isinstance(value, (str, bytes)):
                raise TypeError(f"`{arg}` must be an array of one row per sample; got {value!r}")
        if isinstance(zs, np.ndarray) or not _has_none(zs):
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
        # one summation pass screens long records (check_finite); NaN in zs marks
        # a missing sample, so only inf is an error there
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
        lo, hi = VARIANCE_RANGE
        bad = (arr < lo) | (arr > hi)
        if bad.any():
            i = int(np.argmax(bad))
            raise ValueError(f"`Rs` must hold variances in [{lo:.0e}, {hi:.0e}] (the update "
                             f"multiplies and divides by them); got {arr[i]:.3g} at index {i}")
        return arr.copy()


def own_array(value, name):
    """`value` as the filter's own C-contiguous float64 array (always a copy).

    What assigning ``x`` or ``P`` stores: the caller's array is never kept,
    so neither can later change the other. Shapes are checked where the
    array is used, so that the error names the method that cannot use it.
    """
    return np.array(as_float_array(value, name), dtype=np.float64, order="C")


def _refused(name, why):
    """The message of an assignment to a filterpy attribute the filters do not use."""
    return f"`{name}` cannot be assigned: {why}"


# ----------------------------------------------------------------------
# settings a filter does not take: refused by name (#29 item 4)
# ----------------------------------------------------------------------
#: filterpy's ``KalmanFilter`` settings (besides the sizes ``dim_x``, ``dim_z`` and the
#: results of a step every filter writes: ``H``, which ``update(z)`` also reads, as in
#: filterpy, ``z``, ``y``, ``K``, ``S``, ``SI``, the priors and the posteriors).
FILTERPY_OPTIONS = ("x", "P", "Q", "R", "F", "B", "M", "alpha", "inv", "dim_u")
#: Names that are not guarded: the sizes (the hot paths read them as plain attributes)
#: and ``adapt``, which every filter and bank takes (``freeze``/``unfreeze``).
_NOT_GUARDED = ("self", "dim_x", "dim_z", "n_channels", "adapt")
# every name a filter may be handed: filterpy's settings and, as rlsfilt's filters are
# defined, their constructor arguments and settable properties (`_register`)
_OPTION_NAMES = set(FILTERPY_OPTIONS)
_FILTER_CLASSES = weakref.WeakSet()      # every filter and bank class, to guard
# why a filter that lacks a setting lacks it ({cls}: its class name); the message
# then says which filters take the setting
_WHY_NOT = {
    # (the filters' base answers F, B, inv, alpha and Q itself; these are the banks')
    "F": "the state transition of {cls} is the identity (constant parameters); model "
         "drift with a random walk Q",
    "B": "{cls} has no control input; known inputs belong in the regressors H",
    "inv": "{cls} never inverts a matrix (S is a scalar per channel); there is no "
           "inverse to replace",
    "alpha": "{cls} has no fading-memory factor in filterpy's form (alpha**2 = 1 / lam)",
    "Q": "{cls} has no random walk (filterpy's process noise)",
    "P": "{cls} keeps no covariance (has_covariance is False); a least-squares filter "
         "has one",
    "P0": "the initial covariance of {cls} is fixed at construction (reset() returns to "
          "it); assign P for the current covariance, or construct a new filter with P0=...",
    "x0": "the initial estimate of {cls} is fixed at construction (reset() returns to "
          "it); assign x for the current estimate, or construct a new filter with x0=...",
    "M": "{cls} has no correlation between measurement and process noise (filterpy's "
         "M); least squares' random walk Q, where there is one, is independent of R",
    "dim_u": "{cls} has no control input; known inputs belong in the regressor H",
    "gate": "{cls} has no outlier gate",
    "forgetting": "{cls} has no choice of forgetting mode",
    "forgetting_params": "{cls} has no choice of forgetting mode",
    "window": "{cls} has no sliding window",
    "refresh": "{cls} has no window to refit",
    "mu": "{cls} has no step size (it is not a gradient filter)",
    "method": "{cls} has no choice of gradient rule",
    "parallel": "{cls} has no multi-threaded batch loop",
    "check_every": "{cls} keeps no covariance, so it has no health check",
    "eps": "{cls} has no regularized normalization",
    "leak": "{cls} has no leakage",
    "order": "{cls} has no projection order",
    "cond_max": "{cls} keeps no covariance, so no health check of its condition number",
}


def option_names():
    """Every setting name a filter refuses when it does not take it: filterpy's
    ``KalmanFilter`` settings (`FILTERPY_OPTIONS`) and the constructor arguments
    and settable properties of rlsfilt's filters (a new filter's join as it is
    defined). A sorted tuple."""
    return tuple(sorted(_OPTION_NAMES))


def _own_options(cls):
    """The settings `cls` introduces: its constructor's arguments (not the sizes) and
    its public properties with a setter."""
    params = inspect.signature(cls.__init__).parameters.values()
    names = {p.name for p in params if p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)}
    names.update(n for n, v in vars(cls).items()
                 if isinstance(v, property) and v.fset is not None and not n.startswith("_"))
    return names - set(_NOT_GUARDED)


def register_filter_class(cls):
    """Guard the new filter (or bank) class `cls` (its ``__init_subclass__`` calls this;
    it declares ``_options``); an rlsfilt class's own settings join `_OPTION_NAMES`
    and every class known so far is guarded again (a setting added by a later class is
    refused by the earlier ones too). A user's filter adds no names (its own attributes
    stay free on the other filters), but is guarded against rlsfilt's."""
    _FILTER_CLASSES.add(cls)
    new = (_own_options(cls) - _OPTION_NAMES) if cls.__module__.startswith("rlsfilt.") else ()
    _OPTION_NAMES.update(new)
    # bases first: a subclass sees the refusals its bases have
    for c in (sorted(_FILTER_CLASSES, key=lambda c: len(c.__mro__)) if new else [cls]):
        _guard(c)


def _guard(cls):
    """Put a `_Refused` descriptor on `cls` for every name of `_OPTION_NAMES` it does not
    take (``cls._options``) unless a class of its MRO defines the name and handles it
    itself (the base's ``F``, ``Q``, ..., a read-only property such as ``forgetting``, a
    refusal already there): where nothing defines it, or a base that takes it does.
    A name it takes that a base refuses gets a `_Plain` one (an instance attribute)."""
    for name in _OPTION_NAMES:
        if name in vars(cls):                  # the class's own (or already guarded)
            continue
        owner = next((c for c in cls.__mro__ if name in vars(c)), None)
        if name in cls._options:
            if owner is not None and isinstance(vars(owner)[name], _Refused):
                setattr(cls, name, _Plain(name))
        elif owner is None or name in getattr(owner, "_options", ()):
            setattr(cls, name, _Refused(name))


class _Refused:
    """A setting the class it is put on does not take: assigning it raises an
    AttributeError that names it, the class, why and which filters take it; reading it
    (on the instance or the class) raises AttributeError as for any missing attribute,
    so ``hasattr`` and ``getattr(f, name, default)`` see it absent."""

    __slots__ = ("name",)

    def __init__(self, name):
        self.name = name

    def why(self, cls):
        """Why `cls` refuses the setting and where to find it instead."""
        name = self.name
        if name == "lam":
            why = f"{cls.__name__} {getattr(cls, '_NO_FADING_MEMORY', 'has no forgetting')}"
        else:
            if name == "P0" and not getattr(cls, "has_covariance", True):
                name = "P"
            why = _WHY_NOT.get(name, f"{cls.__name__} does not take `{name}`").format(
                cls=cls.__name__)
        if self.name in ("P0", "x0"):
            return why
        # the public rlsfilt filters that take it (assigned, or at construction)
        takers = sorted(c.__name__ for c in list(_FILTER_CLASSES)
                        if c.__module__.startswith("rlsfilt.") and not c.__name__[0] == "_"
                        and (name in c._options or name in inspect.signature(c).parameters))
        if takers:
            why += f"; {name} is an option of {', '.join(takers)}"
        return why

    def __get__(self, obj, cls=None):
        owner = cls if obj is None else type(obj)
        what = (f"type object {owner.__name__!r}" if obj is None
                else f"{owner.__name__!r} object")
        raise AttributeError(f"{what} has no attribute {self.name!r} ({self.why(owner)})",
                             name=self.name, obj=obj)

    def __set__(self, obj, value):
        raise AttributeError(_refused(self.name, self.why(type(obj))), name=self.name, obj=obj)

    def __delete__(self, obj):
        self.__set__(obj, None)


class _Plain:
    """A setting a subclass takes although a base refuses it: an instance attribute."""

    __slots__ = ("name",)

    def __init__(self, name):
        self.name = name

    def __get__(self, obj, cls=None):
        if obj is None:
            return self
        try:
            return obj.__dict__[self.name]
        except KeyError:
            raise AttributeError(f"{type(obj).__name__!r} object has no attribute "
                                 f"{self.name!r}", name=self.name, obj=obj) from None

    def __set__(self, obj, value):
        obj.__dict__[self.name] = value

    def __delete__(self, obj):
        del obj.__dict__[self.name]


def refuse_fixed(f, name, instead):
    """Raise the AttributeError of assigning `name`, a setting of filter `f` fixed at
    construction (the setter of its read-only property); `instead` says what to do."""
    raise AttributeError(_refused(name, f"the {name} of {type(f).__name__} is fixed at "
                                        f"construction; {instead}"), name=name, obj=f)


def _has_none(values):
    """Whether a sequence of measurements marks a missing one by None (a scalar: no)."""
    try:
        return any(v is None for v in values)
    except TypeError:            # not iterable: a scalar, refused by the shape check
        return False


@functools.cache
def _slots(cls):
    """The slot names of `cls` and its bases (once per class: `_restore` runs per sample
    inside python-control)."""
    return frozenset(name for c in cls.__mro__ for name in getattr(c, "__slots__", ()))


def _innovation(P, phi, r):
    """``g = P phi^T`` (dim_x, 1) and the scalar ``s = phi P phi^T + r``."""
    g = P @ phi.T
    return g, (phi @ g).item() + r


def _gaussian_logpdf(y, s):
    """``log N(y; 0, s I)`` for a residual column `y` and scalar variance `s`."""
    m = y.size
    return -0.5 * (m * (_LOG_2PI + math.log(s)) + float(np.vdot(y, y)) / s)
