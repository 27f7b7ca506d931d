r"""Streaming recursive instrumental variables for ARX models, one call per sample."""

import numbers
import warnings

import numpy as np

from .._validation import (
    as_float_array,
    check_covariance,
    check_finite,
    check_int,
    check_lam,
    check_variance,
)
from ..exceptions import NumericalWarning
from ._stability import reflect
from .recursive import _scalar
from .regressors import arx_structure

__all__ = ["RecursiveIV"]

_kernels = None


def _get_kernels():
    global _kernels
    if _kernels is None:
        from . import _recursive_kernels as k
        _kernels = k
    return _kernels


class RecursiveIV:
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
    instruments : {"model", "given"}, default "model"
        ``"model"``: the ``-y`` block of the regressor replaced by the output
        of an auxiliary model :math:`\hat B/\hat A\,u`, refreshed from the
        running estimate every `refresh` samples (Young's refined IV; with
        `prefilter` every signal also passes through :math:`1/\hat A`).
        ``"given"``: :meth:`step` takes the instrument row ``z`` (for example
        lags of a reference signal in closed loop).
    k0 : int, default 0
        Rows of an exact start :math:`P = (Z_0^T\Phi_0)^{-1}` (``0``: the
        prior `P0`, `x0`).
    lam, Q, R, P0, x0
        Forgetting factor, random walk, gain-denominator constant, prior
        covariance and estimate, as ``ARX.fit(method="riv")``.
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
        if instruments not in ("model", "given"):
            raise ValueError(f"`instruments` must be 'model' or 'given'; got {instruments!r}")
        self._orders = {"na": na, "nb": nb, "nk": nk}
        self._s = s
        self.instruments = instruments
        self.k0 = check_int(k0, "k0", minimum=0)
        self.lam = check_lam(lam)
        self.R = check_variance(R, "R")
        Qm = check_covariance(Q, n, "Q")
        self._q_zero = not Qm.any()
        self._Q = np.ascontiguousarray(Qm) if not self._q_zero else np.zeros((0, 0))
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
        self._ints = (s.na, np.array(s.nb, dtype=np.int64), np.array(s.nk, dtype=np.int64))
        self.reset()

    def reset(self):
        """Return to the initial estimate, covariance and auxiliary model."""
        s, n = self._s, self._s.n_params
        self._theta = self._theta0.copy()
        self._P = self._P0.copy()
        self._alpha = self._alpha0.copy()
        self._beta = self._beta0.copy()
        self._buf = np.zeros((4 + 2 * s.n_inputs, s.max_lag + 1))
        m = max(self.k0, 1)
        self._start = (np.empty((m, n)), np.empty((m, n)), np.empty(m))
        self._work = tuple(np.empty(n) for _ in range(5)) + (np.empty(1),)
        self._z = np.zeros(n)
        self._u = np.empty(s.n_inputs)
        self.n_steps = 0
        self.n_skipped = 0
        self.last_error = np.nan
        self._warned = False

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
        yv = _scalar(y, "y")
        s, n = self._s, self._s.n_params
        uv = check_finite(as_float_array(u, "u").reshape(-1), "u")
        if uv.size != s.n_inputs:
            raise ValueError(f"`u` must have {s.n_inputs} entries (one per input); got "
                             f"{uv.size}")
        self._u[:] = uv
        given = self.instruments == "given"
        if given:
            if z is None:
                raise ValueError("`z` must be given: instruments='given'")
            zv = check_finite(as_float_array(z, "z").reshape(-1), "z")
            if zv.size != n:
                raise ValueError(f"`z` must have n_params = {n} entries; got {zv.size}")
            self._z[:] = zv
        elif z is not None:
            raise ValueError("`z` only applies to instruments='given'")
        row = self.n_steps - s.max_lag
        pred_theta = self._theta[:, 0].copy()
        na, nb, nk = self._ints
        phi, zw, g, h, K, eps = self._work
        status, _ = _get_kernels().riv_stream(
            self._theta, self._P, self._buf, yv, self._u, self._z, given, row, na, nb, nk,
            self.k0, self._alpha, self._beta, self.refresh if not given else 0,
            self.prefilter and not given, 1.0 / self.lam, self._Q, self._q_zero, self.R,
            self.tol, *self._start, phi, zw, g, h, K, eps)
        self.n_steps += 1
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
        yhat = float(phi @ pred_theta) if status in (1, 2) or row < 0 else np.nan
        self.last_error = yv - yhat
        return yhat, self._theta[:, 0].copy()

    __call__ = step

    def __repr__(self):
        args = ", ".join(f"{k}={v!r}" for k, v in self._orders.items())
        return (f"RecursiveIV({args}, instruments={self.instruments!r}), "
                f"{self.n_steps} steps")
