r"""Streaming recursive instrumental variables for ARX models, one call per sample."""

import numbers
import warnings

import numpy as np

from .._lazy import lazy_module
from .._locking import locked as _locked
from .._validation import (
    as_float_array,
    check_bool,
    check_covariance,
    check_finite,
    check_int,
    check_lam,
    check_variance,
)
from ..exceptions import NumericalWarning
from ._stability import reflect
from .recursive import _Guarded, _scalar
from .regressors import arx_structure

__all__ = ["RecursiveIV"]

_get_kernels = lazy_module("rlsfilt.models._recursive_kernels")


class RecursiveIV(_Guarded):
    r"""Streaming ARX estimation by recursive instrumental variables.

    The online form of ``ARX.fit(u, y, method="riv")``: each
    :meth:`step` takes ``(y, u)`` (and, for user instruments, ``z``),
    returns the one-step prediction made before the sample and the updated
    parameters. It runs the same compiled step as the batch fit with
    auxiliary-model instruments, so stepping through a record gives the
    batch estimates bit for bit.

    Parameters
    ----------
    na, nb, nk
        ARX orders (``nb``, ``nk`` per input), as :class:`~rlsfilt.ARX`.
    instruments : {"model", "delayed", "given"}, default "model"
        ``"model"``: the ``-y`` block of the regressor replaced by the output
        of an auxiliary model :math:`\hat B/\hat A\,u`, refreshed from the
        running estimate every `refresh` samples (Young's refined IV; with
        `prefilter` every signal also passes through :math:`1/\hat A`).
        ``"delayed"``: the ``-y`` block replaced by further delayed samples
        of the first input, :math:`u_1(t - n_{k,1} - n_{b,1} - k + 1)`,
        ``k = 1 .. na`` (as ``ARX.fit(method="riv", instruments="delayed")``;
        open loop, no auxiliary model).
        ``"given"``: :meth:`step` takes the instrument row ``z`` (for example
        lags of a reference signal in closed loop).
    k0 : int, default 0
        Rows of an exact start :math:`P = (Z_0^T\Phi_0)^{-1}` (``0``: the
        prior `P0`, `x0`).
    lam, Q, R, P0, x0
        Forgetting factor, random walk, gain-denominator constant, prior
        covariance and estimate, as ``ARX.fit(method="riv")``, in the
        signals' units (defaults ``P0 = 1e4 I``, ``R = 1``): one sample at a
        time, the estimator cannot know the scale of the record in advance.
        For signals far from unit size give a prior of that size (``P0``
        about ``1e4 R / max|phi_k|^2``) or use the exact start (``k0 > 0``),
        which does not depend on the units.
    refresh : int, optional
        ``"model"``: samples between refreshes of the auxiliary model
        (default ``max(50, 10 n_params)``; ``0`` never).
    prefilter : bool, default False
        ``"model"``: filter the signals by :math:`1/\hat A`.
    theta_aux : array_like, optional
        ``"model"``: the first auxiliary model ``[a, b]`` (default `x0`);
        a rough batch estimate gives a fast start.
    tol : float, default 1e-10
        Conditioning check: an update whose denominator
        :math:`R + \varphi^T P z` nearly vanishes is skipped (counted in
        ``n_skipped``, warned once).

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import RecursiveIV
    >>> rng = np.random.default_rng(8)
    >>> u, e = rng.standard_normal(20000), rng.standard_normal(20000)
    >>> a, c = [1, -1.5, 0.7], [1, -1, 0.2]
    >>> y = lfilter([0, 1, 0.5], a, u) + lfilter(c, a, e)      # coloured equation error
    >>> est = RecursiveIV(2, 2, 1, theta_aux=[-1.0, 0.3, 1.0, 0.0])
    >>> for t in range(len(y)):
    ...     yhat, theta = est.step(y[t], u[t])
    >>> np.round(theta, 1)
    array([-1.5,  0.7,  1. ,  0.5])
    """

    def __init__(self, na, nb, nk=1, *, instruments="model", k0=0, lam=1.0, Q=0.0, R=1.0,
                 P0=1e4, x0=None, refresh=None, prefilter=False, theta_aux=None, tol=1e-10):
        nu = 1 if isinstance(nb, numbers.Integral) or not hasattr(nb, "__len__") else len(nb)
        s = arx_structure(na, nb, nk, nu, 1)
        n = s.n_params
        if instruments not in ("model", "delayed", "given"):
            raise ValueError(f"`instruments` must be 'model', 'delayed' or 'given'; got "
                             f"{instruments!r}")
        self._orders = {"na": na, "nb": nb, "nk": nk}
        self._s = s
        self.instruments = instruments
        self.k0 = check_int(k0, "k0", minimum=0)
        self.lam = check_lam(lam)
        self.R = check_variance(R, "R")
        Qm = check_covariance(Q, n, "Q")
        self._Q = np.ascontiguousarray(Qm) if Qm.any() else np.zeros((0, 0))
        P = check_covariance(P0, n, "P0", definite=True)
        theta = np.zeros(n) if x0 is None else as_float_array(x0, "x0").reshape(-1)
        if theta.shape != (n,):
            raise ValueError(f"`x0` must have n_params = {n} entries; got {theta.size}")
        check_finite(theta, "x0")
        aux = theta if theta_aux is None else as_float_array(theta_aux, "theta_aux").reshape(-1)
        if aux.shape != (n,):
            raise ValueError(f"`theta_aux` must have n_params = {n} entries; got {aux.size}")
        check_finite(aux, "theta_aux")
        self.refresh = max(50, 10 * n) if refresh is None else check_int(refresh, "refresh",
                                                                           minimum=0)
        self.prefilter = bool(prefilter)
        self.tol = float(tol)
        self._theta0 = theta.reshape(n, 1).copy()
        self._P0 = np.ascontiguousarray(P)
        self._alpha0 = reflect(np.concatenate([[1.0], aux[:s.na]]))[1:].copy()
        self._beta0 = aux[s.na:].copy()
        given = instruments != "model"
        # the packed arguments of the compiled step (_recursive_kernels.riv_stream)
        self._spec = np.array([s.na, self.k0, 0 if given else self.refresh,
                               self.prefilter and not given, given, s.n_inputs]
                              + list(s.nb) + list(s.nk), dtype=np.int64)
        self._fpar = np.array([1.0 / self.lam, self.R, self.tol, 0.0])   # (RF_FROZEN last)
        self._nu = s.n_inputs
        self.reset()

    @_locked
    def reset(self):
        """Return to the initial estimate, covariance and auxiliary model."""
        s, n = self._s, self._s.n_params
        self._theta = self._theta0.copy()
        self._P = self._P0.copy()
        self._alpha = self._alpha0.copy()
        self._beta = self._beta0.copy()
        self._buf = np.zeros((4 + 2 * s.n_inputs, s.max_lag + 1))
        m = max(self.k0, 1)
        self._start = (np.empty((2, m, n)), np.empty(m))      # Phi0, Z0 and Y0
        self._work = np.zeros((7, n))     # phi, z, g, h, K, theta before the step, eps
        self._z = np.zeros(n)
        self._u = np.empty(s.n_inputs)
        # "delayed": the last samples of every input, lag 0 first (zero before the record)
        self._ulags = np.zeros((s.n_inputs, max(s.nk[0] + s.nb[0] + s.na,
                                                max(k + b for k, b in zip(s.nk, s.nb)))))
        self.n_steps = 0
        self._frozen_rows = 0             # regressor rows taken while frozen (not counted)
        self.n_skipped = 0
        self.last_error = np.nan
        self._warned = False

    # ------------------------------------------------------------------
    # adaptation switch (MATLAB's EnableAdaptation)
    # ------------------------------------------------------------------
    @property
    def frozen(self):
        """Whether adaptation is off (:meth:`freeze`): :meth:`step` still returns the
        prediction of the held estimate and moves the signals (through the held
        auxiliary model), while ``theta``, ``P`` and the auxiliary model stay
        bit-unchanged; the rows taken while frozen count neither towards the exact
        start nor towards the refresh period."""
        return bool(self._fpar[_get_kernels().RF_FROZEN])

    @property
    def adapt(self):
        """``not frozen``: assign False to freeze the estimate, True to resume."""
        return not self.frozen

    @adapt.setter
    @_locked
    def adapt(self, value):
        self._fpar[_get_kernels().RF_FROZEN] = 0.0 if check_bool(value, "adapt") else 1.0

    def freeze(self):
        """Stop adapting (MATLAB's ``EnableAdaptation = false``). Returns the estimator."""
        self.adapt = False
        return self

    def unfreeze(self):
        """Resume adapting from the held estimate. Returns the estimator."""
        self.adapt = True
        return self

    @property
    def theta(self):
        """The current estimate ``[a, b]`` (a copy)."""
        return self._theta[:, 0].copy()

    @property
    def P(self):
        """The current (non-symmetric) ``P`` (a copy)."""
        return self._P.copy()

    @property
    def phi(self):
        """The regressor row of the last sample (a copy)."""
        return self._work[0].copy()

    @property
    def z(self):
        """The instrument row of the last sample (a copy)."""
        return self._work[1].copy()

    def _input(self, u):
        """`u` as a finite float array of shape (nu,) (the full validation)."""
        uv = check_finite(as_float_array(u, "u").reshape(-1), "u")
        if uv.size != self._nu:
            raise ValueError(f"`u` must have {self._nu} entries (one per input); got "
                             f"{uv.size}")
        return uv

    @_locked
    def step(self, y, u, z=None):
        """Take one sample: return the prediction made before it and the new estimate.

        Parameters
        ----------
        y : float
            The output ``y(t)``.
        u : float or array_like, shape (nu,)
            The input ``u(t)``.
        z : array_like, shape (n_params,)
            ``instruments="given"`` only: the instrument row of this sample.

        Returns
        -------
        yhat : float
            :math:`\\varphi(t)^T\\hat\\theta(t-1)` (NaN during the exact start).
        theta : ndarray, shape (n_params,)
            The updated estimate.
        """
        # fast path: float samples need only a finiteness check (x - x is NaN for NaN, inf)
        if isinstance(y, float) and y - y == 0.0:
            yv = y
        else:
            yv = _scalar(y, "y")
        if self._nu == 1 and isinstance(u, float) and u - u == 0.0:
            self._u[0] = u
        else:
            self._u[:] = self._input(u)
        uv = self._u
        s, n = self._s, self._s.n_params
        if self.instruments == "delayed":
            if z is not None:
                raise ValueError("`z` only applies to instruments='given'")
            self._delayed_row(uv)
        elif self.instruments == "given":
            if z is None:
                raise ValueError("`z` must be given: instruments='given'")
            zv = check_finite(as_float_array(z, "z").reshape(-1), "z")
            if zv.size != n:
                raise ValueError(f"`z` must have n_params = {n} entries; got {zv.size}")
            self._z[:] = zv
        elif z is not None:
            raise ValueError("`z` only applies to instruments='given'")
        row = self.n_steps - s.max_lag - self._frozen_rows
        status, yhat = _get_kernels().riv_stream(
            self._theta, self._P, self._buf, yv, uv, self._z, row, self._spec, self._fpar,
            self._alpha, self._beta, self._Q, *self._start, self._work)
        self.n_steps += 1
        if status == 4 and row >= 0:       # frozen: the row does not count (start, refresh)
            self._frozen_rows += 1
        if status == 3:
            self.n_steps -= 1
            raise ValueError(f"the exact start on the first k0 = {self.k0} rows is singular "
                             "(Z0^T Phi0 not invertible): use a larger `k0` or a prior start")
        if status == 2:
            self.n_skipped += 1
            if not self._warned:
                self._warned = True
                warnings.warn(f"RecursiveIV: the gain denominator R + phi^T P z nearly vanished "
                              f"at sample {self.n_steps - 1}; that update was skipped",
                              NumericalWarning, stacklevel=2)
        self.last_error = yv - yhat
        return yhat, self._theta[:, 0].copy()

    __call__ = step

    def _delayed_row(self, u):
        """Shift the input lags and write the delayed-input instrument row into ``_z``:
        ``[u_1(t - nk_1 - nb_1 - k + 1)]_{k=1..na}``, then the input block of the regressor."""
        L = self._ulags
        L[:, 1:] = L[:, :-1]
        L[:, 0] = u
        s, z = self._s, self._z
        first = s.nk[0] + s.nb[0]
        z[:s.na] = L[0, first:first + s.na]
        j = s.na
        for i in range(s.n_inputs):
            z[j:j + s.nb[i]] = L[i, s.nk[i]:s.nk[i] + s.nb[i]]
            j += s.nb[i]

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self._orders.items())
        return (f"RecursiveIV({args}, instruments={self.instruments!r}), "
                f"{self.n_steps} steps{', frozen' if self.frozen else ''}")
