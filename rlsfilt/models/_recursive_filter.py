r"""Streaming ARX, AR and OE estimation by a filter of :mod:`rlsfilt.filters`.

MATLAB's ``recursiveARX`` and ``recursiveAR`` offer the gradient estimation
methods ('NormalizedGradient', 'Gradient'), and ``recursiveARX``,
``recursiveAR``, ``recursiveOE`` a finite history (``History = 'Finite'``,
``WindowLength``). `FilterRecursion` runs them for the streaming objects of
:mod:`rlsfilt.models.recursive` with the interface of their usual engine
(``_recursive_pem.RecursionState``: ``step``, ``run``, ``restart``,
``copy``, ``theta``, ``P``, ``n_steps``, ``lam_t``): it keeps the lags of the
signals, forms the regressor of each sample and hands it to a filter
(`NLMS`, `LMS` or `SlidingWindowRLS`):

.. math::

    \varphi(t) = [-y(t-1) \dots -y(t-n_a),\; u_j(t-n_{k,j}) \dots
    u_j(t-n_{k,j}-n_{b,j}+1),\; -w_j(t-1) \dots -w_j(t-n_{f,j})],
    \qquad \hat y(t) = \varphi(t)\, \hat\theta(t-1)

with, for OE, the simulated output of each input
:math:`w_j(t) = B_j(q)/F_j(q)\, u_j(t)` formed from the estimate after the
update (the pseudo-linear regressor of RPLR, Ljung 1999, sec. 11.3), so that
with a window the estimate after each sample is least squares on the last
``window`` regressor rows.
"""

import copy

import numpy as np

from ..filters import SlidingWindowRLS
from . import _arx_online

__all__ = []

#: The streaming methods `FilterRecursion` runs (besides a window on least squares).
GRADIENT = tuple(_arx_online.GRADIENT)


def make_filter(n, method, window, options):
    """The filter of a streaming `method` (``"nlms"``, ``"lms"``) or of a `window`,
    with its options checked by name (a TypeError names an unknown one)."""
    if method in GRADIENT:
        if window is not None:
            raise TypeError(f"`window` only applies to least squares; got method={method!r}")
        return _arx_online.GRADIENT[method](n, 1, **_arx_online.gradient_options(method,
                                                                                 options))
    for name in options:
        if name not in _arx_online.WINDOW_OPTIONS:
            raise TypeError(f"`{name}` does not apply with a `window` (options: "
                            f"{list(_arx_online.WINDOW_OPTIONS)})")
    return SlidingWindowRLS(n, window, 1, **options)


class FilterRecursion:
    """A streaming ARX/AR/OE recursion run by the filter `filt` (see the module notes).

    Parameters
    ----------
    s : FamilyStructure
        The orders (``nc = nd = 0``; ``na = 0`` for OE).
    filt : NLMS, LMS or SlidingWindowRLS
        The filter, with ``dim_x = s.n_params``, ``dim_z = 1``.
    """

    def __init__(self, s, filt):
        self.s, self.filt = s, filt
        self.method = getattr(filt, "method", "rls")
        nu = s.n_inputs
        self._off_b = np.cumsum((s.na,) + tuple(s.nb))[:nu]
        self._off_f = np.cumsum((s.na + sum(s.nb) + s.nc + s.nd,) + tuple(s.nf))[:nu]
        self.restart()
        self.n_steps, self.lam_t = 0, 1.0

    @property
    def theta(self):
        """The current estimate, (n_params,)."""
        return self.filt.x[:, 0]

    @property
    def P(self):
        """``P`` of the window's least squares (a gradient method has none)."""
        if not self.filt.has_covariance:
            raise AttributeError(f"method={self.method!r} has no covariance `P` (a gradient "
                                 "method)")
        return self.filt.P

    @property
    def frozen(self):
        """Whether adaptation is off (the filter's :attr:`frozen`): a step forms the
        regressor and the prediction, the estimate and ``P`` stay as they are."""
        return self.filt.frozen

    @frozen.setter
    def frozen(self, value):
        self.filt.adapt = not value

    def restart(self):
        """Signal lags back to rest (zero); the estimate carries on."""
        s = self.s
        self._y = np.zeros(s.na)                                   # y(t-1) ..
        self._u = [np.zeros(nk + nb) for nk, nb in zip(s.nk, s.nb)]   # u_j(t) ..
        self._w = [np.zeros(nf) for nf in s.nf]                    # w_j(t-1) ..

    def _regressor(self, ulags):
        s = self.s
        phi = np.empty(s.n_params)
        phi[:s.na] = -self._y
        for j in range(s.n_inputs):
            b, f = self._off_b[j], self._off_f[j]
            phi[b:b + s.nb[j]] = ulags[j][s.nk[j]:]
            phi[f:f + s.nf[j]] = -self._w[j]
        return phi

    def step(self, y, u):
        """One sample ``y`` (float), ``u`` ((nu,) float64): ``(yhat, eps, False)``.

        A step that raises (the filter's health warning turned into an error)
        leaves the recursion as it was: the lags move only after the filter's
        ``predict_update``, which undoes itself when it raises. A diverging
        gradient estimate gives non-finite predictions without a warning, as
        the filters' compiled steps do.
        """
        s = self.s
        # u_j(t) enters the lags (new arrays: committed after the update)
        ulags = [np.concatenate(([u[j]], uj[:-1])) if len(uj) else uj
                 for j, uj in enumerate(self._u)]
        phi = self._regressor(ulags)
        filt = self.filt
        with np.errstate(over="ignore", invalid="ignore"):
            yhat = float(phi @ filt.x[:, 0])             # y^(t) = phi(t) theta(t-1)
        filt.predict_update(y, phi)
        theta = filt.x[:, 0]
        self._u = ulags
        for j in range(s.n_inputs):                      # w_j(t) = B_j / F_j u_j(t)
            if s.nf[j]:
                b, f = self._off_b[j], self._off_f[j]
                w = self._w[j]
                with np.errstate(over="ignore", invalid="ignore"):
                    wt = (phi[b:b + s.nb[j]] @ theta[b:b + s.nb[j]]
                          - w @ theta[f:f + s.nf[j]])
                w[1:] = w[:-1].copy()
                w[0] = wt
        if s.na:
            self._y[1:] = self._y[:-1].copy()
            self._y[0] = y
        self.phi = phi
        self.n_steps += 1
        return yhat, y - yhat, False

    def run(self, y, U):
        """`step` over a record ``y`` (N,), ``U`` (N, nu): ``theta_history`` (N, n),
        ``yhat`` and ``eps`` (N,), ``gated`` (all False)."""
        N, n = len(y), self.s.n_params
        out = {"theta_history": np.empty((N, n)), "yhat": np.empty(N), "eps": np.empty(N),
               "gated": np.zeros(N, dtype=np.bool_)}
        for t in range(N):
            out["yhat"][t], out["eps"][t], _ = self.step(float(y[t]), U[t])
            out["theta_history"][t] = self.filt.x[:, 0]
        return out

    def copy(self):
        """An independent copy."""
        return copy.deepcopy(self)
