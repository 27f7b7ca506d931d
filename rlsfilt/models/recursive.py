r"""Streaming estimators of the polynomial family, one call per sample (MATLAB's recursive objects).

``RecursiveARMAX``, ``RecursiveOE``, ``RecursiveBJ``, ``RecursiveARX``,
``RecursiveAR`` and ``RecursiveARMA`` are what MATLAB's ``recursiveARMAX``,
``recursiveOE``, ... are: objects that take one measurement ``(y, u)`` at a
time, return the one-step prediction made *before* the measurement and the
updated parameters, and can run beside a Kalman filter in a loop. They are
thin wrappers around the compiled RPEM/RPLR step of
:mod:`rlsfilt.models._recursive_kernels`, the same step that
``fit(u, y, method="rpem")`` runs over a record, so stepping through a
record gives bit for bit the estimates of the batch run.

**Units.** A streaming estimator sees one sample at a time and cannot know
the scale of the record in advance: ``P0``, ``R``, ``Q``, ``x0`` and their
defaults (``P0 = 1e4 I``, ``R = 1``, as MATLAB's recursive objects) are in
the signals' units, and the recursion runs in them. For signals far from
unit size give options of that size (``P0`` about ``1e4 R / max|phi_k|^2``
for parameter ``k``, ``R`` of the size of the noise variance) or scale the
signals first: around 1e-160 the default prior outweighs every sample,
around 1e160 the covariance update overflows. The batch fits read the same
options in the same units and give the same numbers, but run in scaled units
and name a default prior that does not suit the data
(:mod:`rlsfilt.models._units`).

**Copies and threads.** ``copy.copy`` of an estimator is as deep as
``copy.deepcopy`` (the recursion state is updated in place, so a shallow copy
would move with the original); an estimator shared by threads takes one call
at a time (``step``, ``batch``, ``restart``, ``reset`` and the reads of the
estimate hold its lock; copies and pickles get their own).
"""

import copy
import numbers
import threading

import numpy as np

from .._locking import init_signature
from .._validation import as_float_array, check_bool, check_finite
from . import _recursive_filter
from ._family import family_structure, param_names, split_theta
from ._recursive_pem import RecursionState

__all__ = ["RecursiveARMAX", "RecursiveOE", "RecursiveBJ", "RecursiveARX", "RecursiveAR",
           "RecursiveARMA"]


class _Guarded:
    """A reentrant lock per estimator, left out of pickles and copies (each copy
    makes its own), and ``copy.copy`` as deep as ``copy.deepcopy``: the recursion
    state is updated in place, so a copy that shared it would move with the original."""

    def __new__(cls, *args, **kwargs):
        self = super().__new__(cls)
        self._lock = threading.RLock()
        return self

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        cls.__signature__ = init_signature(cls)   # __init__'s, not __new__'s (*args, **kwargs)

    def __copy__(self):
        """``copy.copy``: an independent estimator (``copy.deepcopy``)."""
        return copy.deepcopy(self)

    def __getstate__(self):
        """The attributes without the lock, read under it (pickle, deepcopy)."""
        with self._lock:
            state = self.__dict__.copy()
        del state["_lock"]
        return state

    def __setstate__(self, state):
        self._lock = threading.RLock()      # (made by __new__ too; not by pickle protocol 0, 1)
        self.__dict__.update(state)


def _n_inputs(nb):
    if isinstance(nb, np.ndarray) and nb.ndim == 0:
        nb = nb.item()
    if isinstance(nb, numbers.Integral) or not hasattr(nb, "__len__"):
        return 1
    return len(nb)


class _RecursiveModel(_Guarded):
    """One-sample-at-a-time estimation of a model of the family (shared machinery).

    Parameters of every subclass: the orders, then keyword options
    ``method`` (``"rpem"`` or ``"rplr"``) and those of the recursion
    (``lam``, ``lam_start``, ``lam_rate``, ``P0``, ``x0``, ``R``, ``Q``,
    ``forgetting``, ``forgetting_params``, ``gate``, ``project``; see
    :meth:`ARMAX.fit`), in the signals' units (see the module notes).

    **Copies and threads.** ``copy.copy`` and ``copy.deepcopy`` both give an
    independent estimator (the recursion state is copied, so stepping one
    never moves the other). An estimator shared by threads takes one call at a
    time: :meth:`step`, :meth:`batch`, :meth:`restart`, :meth:`reset` and the
    reads of the estimate hold its lock.

    **Adaptation switch.** :meth:`freeze` (``adapt = False``, MATLAB's
    ``EnableAdaptation = false``) holds the estimate, ``P`` and the forgetting
    profile while the predictions and the regressor's signals go on;
    :meth:`unfreeze` resumes as if those samples' updates had been skipped.
    """

    def __init__(self, s, method, options, window=None):
        self._structure = s
        self._options = dict(options)
        self.method = method
        self.window = window
        if method in _recursive_filter.GRADIENT or window is not None:
            # MATLAB's gradient methods and finite history: a filter on the regressor
            filt = _recursive_filter.make_filter(s.n_params, method, window, options)
            self._state = _recursive_filter.FilterRecursion(s, filt)
        else:
            self._state = RecursionState(s, method, **options)
        self._initial = self._state.copy()
        self._frozen = False
        self.last_error = np.nan
        self._nu = s.n_inputs
        self._ubuf = np.zeros(s.n_inputs)      # the input sample of the fast path

    # ------------------------------------------------------------------
    def step(self, y, u=None):
        """Take one sample: return the prediction made before it and the new estimate.

        Parameters
        ----------
        y : float
            The measured output ``y(t)``.
        u : float or array_like, shape (nu,)
            The input ``u(t)`` (omit for AR/ARMA). With a delay ``nk >= 1``
            the prediction does not depend on it.

        Returns
        -------
        yhat : float
            :math:`\\hat y(t \\mid t-1)`, the prediction with the previous estimate.
        theta : ndarray, shape (n_params,)
            The updated estimate (a copy).
        """
        # fast path (the loop of a real-time application): float samples need only a
        # finiteness check (x - x is NaN for NaN and inf); anything else is validated in full
        with self._lock:                     # one call at a time (threads)
            if isinstance(y, float) and y - y == 0.0:
                if self._nu == 1 and isinstance(u, float) and u - u == 0.0:
                    uv = self._ubuf
                    uv[0] = u
                elif self._nu == 0 and u is None:
                    uv = self._ubuf
                else:
                    uv = self._input(u)
            else:
                y = _scalar(y, "y")
                uv = self._input(u)
            state = self._state
            yhat, eps, _ = state.step(y, uv)
            self.last_error = eps
            return yhat, state.theta.copy()

    __call__ = step

    def batch(self, y, u=None):
        """Run a record through the same compiled recursion; return the estimates.

        All or nothing: a call that raises (a bad sample, a health warning turned
        into an error) leaves the estimator as it was. While :attr:`frozen`, the
        predictions of the held estimate (its rows all equal to it).

        Parameters
        ----------
        y : array_like, shape (N,)
        u : array_like, shape (N,) or (N, nu)
            The inputs; omitted for AR/ARMA (an input given to them is a
            ``ValueError``, as in `step`).

        Returns
        -------
        yhat : ndarray, shape (N,)
            One-step predictions.
        theta_history : ndarray, shape (N, n_params)
            The estimate after each sample.
        """
        yv = as_float_array(y, "y")
        if yv.ndim == 2 and yv.shape[1] == 1:
            yv = yv[:, 0]
        if yv.ndim != 1:
            raise ValueError(f"`y` must have shape (N,) or (N, 1) (one output sample per "
                             f"row); got {yv.shape}")
        check_finite(yv, "y")
        nu = self._structure.n_inputs
        if nu:
            if u is None:
                raise ValueError(f"`u` must be given: the model has {nu} input(s)")
            U = as_float_array(u, "u")
            U = U[:, None] if U.ndim == 1 else U
            if U.shape != (len(yv), nu):
                raise ValueError(f"`u` must have shape ({len(yv)},) or ({len(yv)}, {nu}); got "
                                 f"{np.shape(u)}")
            check_finite(U, "u")
        else:
            self._no_input(u)
            U = np.zeros((len(yv), 0))
        with self._lock:
            state = self._state.copy()       # a call that raises leaves the estimator as it was
            out = state.run(yv, U)
            self._state = state
            if len(yv):
                self.last_error = float(out["eps"][-1])
        return out["yhat"], out["theta_history"]

    def restart(self):
        """Start a new experiment: the regressor and filter signals restart from rest
        (zero past), while the estimate, ``P`` and the forgetting profile carry on (as
        ``fit`` does at each experiment boundary of an `IOData`)."""
        with self._lock:
            self._state.restart()

    def reset(self):
        """Return to the initial estimate and covariance."""
        with self._lock:
            self._state = self._initial.copy()
            self._state.frozen = self.frozen           # the switch is the user's setting
            self.last_error = np.nan

    # ------------------------------------------------------------------
    # adaptation switch (MATLAB's EnableAdaptation)
    # ------------------------------------------------------------------
    @property
    def frozen(self):
        """Whether adaptation is off (:meth:`freeze`): :meth:`step` and :meth:`batch`
        still return the predictions of the held estimate and move the regressor's
        signals (lagged ``y``, ``u`` and the noise and simulated-output states, through
        the filters of the held estimate), while :attr:`theta`, :attr:`P` and the
        forgetting profile stay bit-unchanged."""
        return self.__dict__.get("_frozen", False)

    @property
    def adapt(self):
        """``not frozen``: assign False to freeze the estimate, True to resume
        (MATLAB's ``EnableAdaptation``)."""
        return not self.frozen

    @adapt.setter
    def adapt(self, value):
        value = check_bool(value, "adapt")
        with self._lock:
            self._frozen = not value
            self._state.frozen = not value

    def freeze(self):
        """Stop adapting (MATLAB's ``EnableAdaptation = false``): predictions
        continue, the estimate and ``P`` stay as they are until :meth:`unfreeze`.
        Returns the estimator."""
        self.adapt = False
        return self

    def unfreeze(self):
        """Resume adapting from the held estimate, with the signals of the frozen
        samples in the regressor. Returns the estimator."""
        self.adapt = True
        return self

    # ------------------------------------------------------------------
    @property
    def theta(self):
        """The current estimate (a copy), in the order of :attr:`param_names`."""
        with self._lock:
            return self._state.theta.copy()

    @property
    def P(self):
        """The covariance matrix of the recursion (a copy; a gradient method has none:
        AttributeError)."""
        with self._lock:
            return self._state.P.copy()

    @property
    def param_names(self):
        """Names of the entries of :attr:`theta`."""
        return param_names(self._structure)

    @property
    def n_steps(self):
        """Samples taken since construction or :meth:`reset`."""
        return self._state.n_steps

    @property
    def lam_t(self):
        """Forgetting factor the last step applied."""
        return self._state.lam_t

    def polynomials(self):
        """Current ``(A, B, C, D, F)`` in MATLAB's form (``B``, ``F`` lists per input)."""
        with self._lock:
            return split_theta(self._state.theta.copy(), self._structure)

    @property
    def A(self):
        """Current ``A`` polynomial ``[1, a1, ..]``."""
        return self.polynomials()[0]

    @property
    def B(self):
        """Current ``B`` polynomial ``[0]*nk + [b1, ..]`` (a list for several inputs)."""
        B = self.polynomials()[1]
        return B[0] if len(B) == 1 else B

    @property
    def C(self):
        """Current ``C`` polynomial."""
        return self.polynomials()[2]

    @property
    def D(self):
        """Current ``D`` polynomial."""
        return self.polynomials()[3]

    @property
    def F(self):
        """Current ``F`` polynomial (a list for several inputs)."""
        F = self.polynomials()[4]
        return F[0] if len(F) == 1 else F

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self._orders.items())
        window = "" if self.window is None else f", window={self.window}"
        frozen = ", frozen" if self.frozen else ""
        return (f"{type(self).__name__}({args}, method={self.method!r}{window}), "
                f"{self.n_steps} steps{frozen}")

    def _input(self, u):
        nu = self._structure.n_inputs
        if nu == 0:
            self._no_input(u)
            return np.zeros(0)
        if u is None:
            raise ValueError(f"`u` must be given: the model has {nu} input(s)")
        if isinstance(u, numbers.Real) and nu == 1:
            v = float(u)
            if v - v != 0.0:
                raise ValueError(f"`u` must be finite; got {v}")
            return np.array([v])
        arr = as_float_array(u, "u").reshape(-1)
        if arr.size != nu:
            raise ValueError(f"`u` must have {nu} entries (one per input); got {arr.size}")
        return check_finite(arr, "u")


    def _no_input(self, u):
        """Refuse an input given to a time-series model (`step` and `batch` alike)."""
        if u is not None and np.size(u):
            raise ValueError(f"`u` must be omitted: {type(self).__name__} has no input")


def _scalar(y, name):
    if isinstance(y, numbers.Real) and not isinstance(y, bool):
        v = float(y)
    else:
        arr = as_float_array(y, name)
        if arr.size != 1:
            raise ValueError(f"`{name}` must be a scalar (one sample); got shape {arr.shape}")
        v = float(arr.reshape(()))
    if v - v != 0.0:
        raise ValueError(f"`{name}` must be finite; got {v}")
    return v


class RecursiveARMAX(_RecursiveModel):
    r"""Streaming ARMAX estimation (MATLAB ``recursiveARMAX``).

    Parameters
    ----------
    na, nb, nc, nk
        Orders as :class:`~rlsfilt.ARMAX` (``nb``, ``nk`` per input).
    method : {"rpem", "rplr"}, default "rpem"
        Gradient-filtered regressors, or extended least squares.
    **options
        Of the recursion (see :class:`_RecursiveModel`).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import RecursiveARMAX
    >>> rng = np.random.default_rng(5)
    >>> u, e = rng.standard_normal(20000), 0.5 * rng.standard_normal(20000)
    >>> y = lfilter([0, 1.0], [1, -0.7], u) + lfilter([1, 0.4], [1, -0.7], e)
    >>> est = RecursiveARMAX(1, 1, 1, 1)
    >>> for t in range(len(y)):
    ...     yhat, theta = est.step(y[t], u[t])
    >>> np.round(theta, 1)
    array([-0.7,  1. ,  0.4])
    """

    def __init__(self, na, nb, nc, nk=1, *, method="rpem", **options):
        self._orders = {"na": na, "nb": nb, "nc": nc, "nk": nk}
        s = family_structure(na=na, nb=nb, nc=nc, nk=nk, n_inputs=_n_inputs(nb))
        super().__init__(s, method, options)


class RecursiveOE(_RecursiveModel):
    """Streaming output-error estimation (MATLAB ``recursiveOE``): orders as :class:`~rlsfilt.OE`.

    ``method`` is ``"rpem"`` (the default) or ``"rplr"``. ``window=W``
    (MATLAB's finite history, ``WindowLength``) replaces the recursion by
    least squares over the last ``W`` pseudo-linear regressor rows
    ``[u(t-nk) ..., -w(t-1) ...]``, ``w = B/F u`` simulated with the estimate
    after each update (`SlidingWindowRLS`, ``method`` ``"rplr"``; options
    ``P0``, ``R``, ``x0``, ``refresh``).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import RecursiveOE
    >>> rng = np.random.default_rng(6)
    >>> u = rng.standard_normal(20000)
    >>> y = lfilter([0, 1.0], [1, -0.7], u) + 0.3 * rng.standard_normal(20000)
    >>> yhat, theta = RecursiveOE(1, 1, 1).batch(y, u)
    >>> np.round(theta[-1], 2)
    array([ 1. , -0.7])
    """

    def __init__(self, nb, nf, nk=1, *, method=None, window=None, **options):
        self._orders = {"nb": nb, "nf": nf, "nk": nk}
        s = family_structure(nb=nb, nf=nf, nk=nk, n_inputs=_n_inputs(nb))
        if window is not None and method not in (None, "rplr"):
            raise ValueError(f"`method` must be 'rplr' (or omitted) with a `window`: the "
                             f"window is least squares on the pseudo-linear regressor; got "
                             f"{method!r}")
        method = ("rplr" if window is not None else "rpem") if method is None else method
        super().__init__(s, method, options, window)


class RecursiveBJ(_RecursiveModel):
    """Streaming Box-Jenkins estimation (MATLAB ``recursiveBJ``): orders as :class:`~rlsfilt.BJ`."""

    def __init__(self, nb, nc, nd, nf, nk=1, *, method="rpem", **options):
        self._orders = {"nb": nb, "nc": nc, "nd": nd, "nf": nf, "nk": nk}
        s = family_structure(nb=nb, nc=nc, nd=nd, nf=nf, nk=nk, n_inputs=_n_inputs(nb))
        super().__init__(s, method, options)


class RecursiveARX(_RecursiveModel):
    """Streaming ARX estimation (MATLAB ``recursiveARX``): orders as :class:`~rlsfilt.ARX`.

    By default the recursion is `RecursiveLeastSquares` on the ARX regressor
    (RPLR and RPEM coincide for ARX; ``method`` reads ``"rplr"``); every
    option of the filter applies. MATLAB's other estimation methods and its
    finite history run a filter on the same regressor rows instead:

    - ``method="nlms"`` ('NormalizedGradient': `NLMS`, options ``mu``,
      ``eps``, ``leak``, ``x0``) or ``method="lms"`` ('Gradient': `LMS`,
      options ``mu``, ``leak``, ``x0``); there is no ``P``;
    - ``window=W`` (``History = 'Finite'``, ``WindowLength``):
      `SlidingWindowRLS`, least squares on the last ``W`` regressor rows
      (options ``P0``, ``R``, ``x0``, ``refresh``; the prior counts until
      the window first fills).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import RecursiveARX
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(3000)
    >>> y = lfilter([0, 1.0], [1, -0.5], u)
    >>> yhat, theta = RecursiveARX(1, 1, method="nlms", mu=0.5).batch(y, u)
    >>> np.round(theta[-1], 3)
    array([-0.5,  1. ])
    """

    def __init__(self, na, nb, nk=1, *, method="rls", window=None, **options):
        self._orders = {"na": na, "nb": nb, "nk": nk}
        s = family_structure(na=na, nb=nb, nk=nk, n_inputs=_n_inputs(nb))
        super().__init__(s, _arx_method(method, window), options, window)


class RecursiveAR(_RecursiveModel):
    """Streaming AR estimation (MATLAB ``recursiveAR``): ``step(y)``.

    ``method`` (``"rls"``, ``"nlms"``, ``"lms"``) and ``window`` as
    :class:`RecursiveARX`.
    """

    def __init__(self, na, *, method="rls", window=None, **options):
        self._orders = {"na": na}
        super().__init__(family_structure(na=na, n_inputs=0), _arx_method(method, window),
                         options, window)


def _arx_method(method, window):
    """The engine's name of an ARX/AR streaming `method`: ``"rls"`` is the RPLR
    recursion (least squares on the ARX regressor); the gradient methods keep theirs."""
    if method == "rls":
        return "rplr"
    if method in _recursive_filter.GRADIENT:
        if window is not None:
            raise TypeError(f"`window` only applies to method='rls'; got method={method!r}")
        return method
    raise ValueError(f"`method` must be 'rls', 'nlms' or 'lms'; got {method!r}")


class RecursiveARMA(_RecursiveModel):
    """Streaming ARMA estimation (MATLAB ``recursiveARMA``): ``step(y)``."""

    def __init__(self, na, nc, *, method="rpem", **options):
        self._orders = {"na": na, "nc": nc}
        super().__init__(family_structure(na=na, nc=nc, n_inputs=0), method, options)
