r"""The stochastic-gradient family as filters: LMS, NLMS, sign variants, affine projection.

The filters of padasip (``FilterLMS``, ``FilterNLMS``, ``FilterSSLMS``,
``FilterAP``) and MATLAB's ``dsp.LMSFilter``/``recursiveLS(...,
'EstimationMethod', 'NormalizedGradient')`` with filterpy's interface: ``x``
(``(dim_x, dim_z)``, zeros by default, not padasip's random weights),
``predict``/``update(z, H)``/``batch_filter``, the residual ``y``, the step's
gain ``K`` and no covariance (``has_covariance = False``). Every update uses the
a-priori residual ``y = z - H x`` (padasip's order: predict with the current
weights, then adapt).

=================  ===========================================================  ====================
class              update of ``x``                                              padasip
=================  ===========================================================  ====================
`LMS`              :math:`(1 - \mu a) x + \mu h y`                              ``FilterLMS``
`NLMS`             :math:`(1 - \mu a) x + \mu h y / (\epsilon + h^T h)`         ``FilterNLMS``
`SignErrorLMS`     :math:`(1 - \mu a) x + \mu h\, \mathrm{sign}(y)`
`SignDataLMS`      :math:`(1 - \mu a) x + \mu\, \mathrm{sign}(h) y`
`SignSignLMS`      :math:`(1 - \mu a) x + \mu\, \mathrm{sign}(h) \mathrm{sign}(y)`  ``FilterSSLMS``
`APA`              :math:`x + \mu X^T (X X^T + \epsilon I)^{-1} (D - X x)`      ``FilterAP``
=================  ===========================================================  ====================

``a`` is the leak (`leak`, 0 by default: Haykin's leaky LMS; MATLAB's
``LeakageFactor`` is ``1 - mu * leak``); ``X`` and ``D`` hold the ``order``
newest regressor rows and measurements, newest first, zeros before the first
samples (as padasip). The noise variance ``R`` does not enter the update; it
is the predictive variance of the diagnostics (``S = R I``, so
``log_likelihood`` is that of the residual under ``N(0, R)``).

References
----------
Haykin, S. (2002). *Adaptive Filter Theory*, 4th ed., ch. 5 (LMS), 6 (NLMS,
affine projection) and 13 (leakage). Ozeki, K. & Umeda, T. (1984), An adaptive
filtering algorithm using an orthogonal projection to an affine subspace.
*Electronics and Communications in Japan* 67(5).
"""

import numpy as np

from .._lazy import lazy_module
from .._locking import locked as _locked
from .._validation import check_bool, check_int, check_real, check_variance
from ._base import _FilterBase, refuse_fixed
from .contract import check_state

__all__ = ["LMS", "NLMS", "SignErrorLMS", "SignDataLMS", "SignSignLMS", "APA"]

_kernels = lazy_module("rlsfilt.filters._kernels_gradient")


class _GradientFilter(_FilterBase):
    """The shared engine of the gradient filters: ``x``, the diagnostics, the batch
    loop; a subclass sets ``_METHOD`` (a code of ``_kernels_gradient.METHODS``)."""

    has_covariance = False
    least_squares = False
    _METHOD = "lms"
    _options = _FilterBase._options | {"mu", "eps", "leak"}
    _NO_FADING_MEMORY = ("adapts by its step size `mu`, it has no fading-memory factor "
                         "(filterpy's alpha)")

    def __init__(self, dim_x, dim_z=1, mu=0.01, *, eps=0.0, leak=0.0, x0=None, R=1.0):
        self.dim_x = check_int(dim_x, "dim_x", minimum=1)
        self.dim_z = check_int(dim_z, "dim_z", minimum=1)
        self.mu = check_real(mu, "mu", minimum=0, strict=True)
        # only the rules that take them read eps and leak (kept private, so that a
        # filter without them refuses them by name: `_options`)
        self._eps = check_real(eps, "eps", minimum=0)
        self._leak = check_real(leak, "leak", minimum=0)
        self.R = R
        self._x0 = self._as_state(np.zeros((self.dim_x, self.dim_z)) if x0 is None else x0,
                                  "x0")
        self.reset()

    @property
    def x(self):
        """Estimate (the weights), ``(dim_x, dim_z)``; assigning copies the value."""
        return self._x

    @x.setter
    @_locked
    def x(self, value):
        self._x = self._as_state(value, "x")

    @property
    def eps(self):
        """Regularization of the normalization, ``>= 0`` (`NLMS`, `APA`)."""
        return self._eps

    @eps.setter
    @_locked
    def eps(self, value):
        self._eps = check_real(value, "eps", minimum=0)

    @property
    def leak(self):
        """Leakage ``a >= 0`` (`LMS`, `NLMS` and the sign variants)."""
        return self._leak

    @leak.setter
    @_locked
    def leak(self, value):
        self._leak = check_real(value, "leak", minimum=0)

    @property
    def method(self):
        """The update rule: ``"lms"``, ``"nlms"``, ``"sign_error"``, ``"sign_data"``,
        ``"sign_sign"`` or ``"apa"`` (read-only: the class's)."""
        return self._METHOD

    @method.setter
    def method(self, value):
        refuse_fixed(self, "method", "it is the class's rule; construct the class of "
                                     "another rule (NLMS, SignSignLMS, ...)")

    @_locked
    def predict(self, u=None, B=None, F=None):
        """No time update (constant weights): ``x_prior`` is a copy of ``x``.

        `u`, `B`, `F` are filterpy's control input, control matrix and state
        transition (filterpy's ``IMMEstimator`` calls ``f.predict(u)`` with
        ``u = None``): any value but None raises a `TypeError`.
        """
        if u is not None or B is not None or F is not None:
            self._refuse_control(u, B, F)
        self.x_prior = self._x.copy()

    @_locked
    def update(self, z, H=None, R=None):
        """One gradient step with measurement `z` and regressor row `H` (``self.H``
        when omitted, as filterpy); `R` is only the predictive variance of the
        diagnostics. A missing `z` (None or NaN) changes nothing but ``z`` and
        ``y`` (NaN); ``K`` and ``S`` keep their values (as filterpy)."""
        if self.frozen:
            return self._frozen_update(z, H, R)
        phi = self._as_regressor(self.H if H is None else H, "H")
        r = self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        x, y, K = self._x.copy(), np.empty(self.dim_z), self.K.copy()
        work = self._work()
        if zc is not None:
            self._step(x, phi[0], zc[:, 0], K, y, work)   # y = z - x^T h; x <- x + K g(y)
        self._commit(x, phi, zc, y, K, r, work, zc is not None)

    @_locked
    def initialize(self, zs, Hs):
        """Start from least squares on the samples `zs`, `Hs` (the measurement
        buffers of `APA` then hold the newest of them)."""
        Z, Hm = self._as_batch(zs, Hs)
        keep = ~np.isnan(Z).any(axis=1)
        if np.linalg.matrix_rank(Hm[keep]) < self.dim_x:
            raise ValueError(f"`Hs` is rank-deficient: need {self.dim_x} independent rows "
                             f"(dim_x); got rank {np.linalg.matrix_rank(Hm[keep])}")
        self._x = np.linalg.lstsq(Hm[keep], Z[keep], rcond=None)[0]
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()   # (as every filter)

    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True):
        """`predict`/`update` over a record in one compiled loop, bit for bit the
        steps one by one.

        Returns ``(means, None, means_p, None)``: the estimates after each update
        and before it (``update_first=False``; after it otherwise), each
        ``(N, dim_x, dim_z)``. A gradient filter has no covariances to store.
        As in `RecursiveLeastSquares` (``store_covariances=False``), `means_p`
        is a read-only view of the array that holds `means` (a predict does not
        change the estimate), so a record costs one array of estimates.
        """
        check_bool(store_covariances, "store_covariances")
        return self._batch(zs, Hs, Rs, update_first, saver, False)

    def _batch_compiled(self, Z, Hm, Rv, update_first, store_covariances):
        N, n, m = len(Z), self.dim_x, self.dim_z
        x, y, K = self._x.copy(), np.full(m, np.nan), self.K.copy()
        work = self._work()
        # one array of estimates: trajectory[0] the start, trajectory[k + 1] after sample k;
        # the estimates before each update are a read-only view of it (no time update: the
        # estimate after a predict is the one before it), as RecursiveLeastSquares does
        trajectory = np.empty((N + 1, n, m))
        last = self._run(x, Hm, Z, K, y, work, trajectory)
        means = trajectory[1:]
        means_p = (means if update_first else trajectory[:-1]).view()
        means_p.flags.writeable = False
        x_prior = x.copy() if update_first else trajectory[-2].copy()
        self._commit_batch(x, Hm, Z, Rv, y, K, work, last, x_prior)
        return means, None, means_p, None

    def _commit(self, x, phi, zc, y, K, r, work, updated):
        """Make a step's arrays the filter's (nothing is written before this)."""
        self.H, self.n_updates = phi, self.n_updates + 1
        if not updated:                     # missing: the estimate is kept (posterior = prior)
            self.x_post = self._x.copy()
            nan = np.full((self.dim_z, 1), np.nan)
            self.set_diagnostics(z=nan, y=nan.copy())
            return
        self._x = x
        self._set_work(work)
        self.x_post = x.copy()
        S = r * np.eye(self.dim_z)
        self.set_diagnostics(z=zc, y=y.reshape(-1, 1), K=K, S=S, SI=S / (r * r))

    def _commit_batch(self, x, Hm, Z, Rv, y, K, work, last, x_prior):
        N = len(Z)
        self._x = x
        self._set_work(work)
        self.H = Hm[-1].reshape(1, -1).copy()
        self.n_updates += N
        self.x_prior, self.x_post = x_prior, x.copy()
        if last >= 0:
            r = float(Rv[last])
            S = r * np.eye(self.dim_z)
            self.set_diagnostics(K=K, S=S, SI=S / (r * r))
        if last == N - 1:
            self.set_diagnostics(z=Z[-1].reshape(-1, 1).copy(), y=y.reshape(-1, 1))
        else:
            nan = np.full((self.dim_z, 1), np.nan)
            self.set_diagnostics(z=nan, y=nan.copy())

    # the family's step, work space and batch loop (APA overrides them)
    def _work(self):
        return ()

    def _set_work(self, work):
        pass

    def _step(self, x, h, z, K, y, work):
        k = _kernels()
        k.lms_update(k.METHODS.index(self._METHOD), x, h.reshape(1, -1), z.reshape(1, -1),
                     self.mu, self._eps, self._leak, K.reshape(-1), y)

    def _run(self, x, Hm, Z, K, y, work, trajectory):
        k = _kernels()
        return k.lms_batch(k.METHODS.index(self._METHOD), x, np.ascontiguousarray(Hm),
                           np.ascontiguousarray(Z), self.mu, self._eps, self._leak,
                           K.reshape(-1), y, trajectory)

    def _final_health_check(self):
        """No covariance, no health check."""

    def _gain_shape(self):
        return (self.dim_x, 1)

    @_locked
    def reset(self):
        """Back to ``x0``; diagnostics, counters and buffers cleared."""
        self._x = self._x0.copy()
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self._reset_diagnostics()
        self.K = np.zeros(self._gain_shape())
        self.n_updates = 0

    @_locked
    def get_state(self):
        """``x`` and the update count (a copy)."""
        return {"x": self._x.copy(), "n_updates": int(self.n_updates)}

    @_locked
    def set_state(self, state):
        """Continue from a dict of :meth:`get_state`."""
        s = check_state(self, state)
        self._x, self.n_updates = s["x"], s["n_updates"]

    def __repr__(self):
        extra = f", eps={self._eps}" if self._METHOD in ("nlms", "apa") else ""
        extra += f", leak={self._leak}" if self._leak else ""
        return (f"{type(self).__name__}(dim_x={self.dim_x}, dim_z={self.dim_z}, "
                f"mu={self.mu}{extra})")


class LMS(_GradientFilter):
    r"""Least-mean-squares filter (Widrow-Hoff), with optional leakage.

    .. math::

        y = z - H x, \qquad K = \mu H^T, \qquad x \leftarrow (1 - \mu a) x + K y^T

    Parameters
    ----------
    dim_x : int
        Number of parameters (regressor entries).
    dim_z : int, default 1
        Number of outputs sharing the regressor row.
    mu : float, default 0.01
        Step size, positive; stable in the mean for ``mu < 2 / trace(E[h h^T])``.
    leak : float, default 0.0
        Leakage ``a >= 0`` (leaky LMS); MATLAB's ``LeakageFactor`` is ``1 - mu a``.
    x0 : array_like, optional
        Initial weights ``(dim_x,)`` or ``(dim_x, dim_z)``; zeros by default.
    R : float, default 1.0
        Measurement-noise variance: the predictive variance ``S`` of the
        diagnostics (not used by the update).

    Notes
    -----
    padasip's ``FilterLMS(n, mu, w="zeros")`` gives the same weights: its
    ``adapt(d, x)`` is ``update(d, x)``. Haykin (2002), ch. 5.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import LMS
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((2000, 2))
    >>> z = H @ [0.5, -0.3]
    >>> f = LMS(2, mu=0.05)
    >>> means, _, _, _ = f.batch_filter(z, H)
    >>> np.round(f.x.ravel(), 3)
    array([ 0.5, -0.3])
    """

    _METHOD = "lms"
    _options = _FilterBase._options | {"mu", "leak"}

    def __init__(self, dim_x, dim_z=1, mu=0.01, *, leak=0.0, x0=None, R=1.0):
        _GradientFilter.__init__(self, dim_x, dim_z, mu, leak=leak, x0=x0, R=R)


class NLMS(_GradientFilter):
    r"""Normalized least-mean-squares filter.

    .. math::

        y = z - H x, \qquad K = \frac{\mu H^T}{\epsilon + H H^T}, \qquad
        x \leftarrow (1 - \mu a) x + K y^T

    Parameters
    ----------
    dim_x, dim_z, x0, R
        As `LMS`.
    mu : float, default 0.1
        Step size, in (0, 2) for stability.
    eps : float, default 0.001
        Regularization of the normalization, ``>= 0`` (padasip's default).
    leak : float, default 0.0
        Leakage, as `LMS`.

    Notes
    -----
    padasip's ``FilterNLMS(n, mu, eps, w="zeros")``; MATLAB's
    ``'NormalizedGradient'`` with ``AdaptationGain = mu`` and
    ``NormalizationBias = eps``. Haykin (2002), ch. 6.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import NLMS
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((500, 3))
    >>> f = NLMS(3, mu=0.5)
    >>> _ = f.batch_filter(H @ [1.0, 0.0, -2.0], H)
    >>> np.round(f.x.ravel(), 6)
    array([ 1.,  0., -2.])
    """

    _METHOD = "nlms"

    def __init__(self, dim_x, dim_z=1, mu=0.1, *, eps=0.001, leak=0.0, x0=None, R=1.0):
        super().__init__(dim_x, dim_z, mu, eps=eps, leak=leak, x0=x0, R=R)


class SignErrorLMS(_GradientFilter):
    r"""Sign-error LMS: :math:`x \leftarrow (1 - \mu a) x + \mu H^T \mathrm{sign}(y)^T`.

    Parameters as `LMS`. Robust to impulsive noise; converges slowly.
    Haykin (2002), ch. 5; MATLAB's ``dsp.LMSFilter(Method="Sign-Error LMS")``.
    """

    _METHOD = "sign_error"
    _options = LMS._options
    __init__ = LMS.__init__                  # no eps: the sign rules do not normalize


class SignDataLMS(_GradientFilter):
    r"""Sign-data LMS: :math:`x \leftarrow (1 - \mu a) x + \mu\, \mathrm{sign}(H)^T y^T`.

    Parameters as `LMS`; ``K = mu sign(H)^T``. MATLAB's
    ``dsp.LMSFilter(Method="Sign-Data LMS")``.
    """

    _METHOD = "sign_data"
    _options = LMS._options
    __init__ = LMS.__init__


class SignSignLMS(_GradientFilter):
    r"""Sign-sign LMS: :math:`x \leftarrow (1 - \mu a) x + \mu\, \mathrm{sign}(H)^T
    \mathrm{sign}(y)^T`.

    Parameters as `LMS`. padasip's ``FilterSSLMS``; MATLAB's
    ``dsp.LMSFilter(Method="Sign-Sign LMS")``.
    """

    _METHOD = "sign_sign"
    _options = LMS._options
    __init__ = LMS.__init__


class APA(_GradientFilter):
    r"""Affine projection algorithm of order `order`.

    The ``order`` newest regressor rows ``X`` (``(order, dim_x)``, newest
    first) and measurements ``D`` (``(order, dim_z)``) update the weights
    together:

    .. math::

        E = D - X x, \qquad K = \mu X^T (X X^T + \epsilon I)^{-1}, \qquad
        x \leftarrow x + K E

    ``K`` is ``(dim_x, order)`` and ``y`` the residual of the newest row
    (``E[0]``). Before ``order`` samples have arrived the buffers hold zeros,
    as padasip's; a missing measurement leaves them as they are.

    Parameters
    ----------
    dim_x, dim_z, x0, R
        As `LMS`.
    order : int, default 5
        Projection order ``k >= 1`` (1 is NLMS without the ``mu`` in the
        denominator's regularization).
    mu : float, default 0.1
        Step size, in (0, 2) for stability.
    eps : float, default 0.001
        Regularization of ``X X^T``, positive (padasip's ``ifc``).

    Notes
    -----
    padasip's ``FilterAP(n, order, mu, ifc=eps, w="zeros")``. Ozeki & Umeda
    (1984); Haykin (2002), ch. 6.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import APA
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((300, 3))
    >>> f = APA(3, order=3, mu=0.5)
    >>> _ = f.batch_filter(H @ [1.0, 0.5, -1.0], H)
    >>> np.round(f.x.ravel(), 6)
    array([ 1. ,  0.5, -1. ])
    """

    _METHOD = "apa"
    _options = _FilterBase._options | {"mu", "eps"}

    def __init__(self, dim_x, dim_z=1, order=5, mu=0.1, *, eps=0.001, x0=None, R=1.0):
        self._order = check_int(order, "order", minimum=1)
        super().__init__(dim_x, dim_z, mu, eps=check_real(eps, "eps", minimum=0, strict=True),
                         x0=x0, R=R)

    @property
    def order(self):
        """Projection order (read-only: the size of the buffers ``X`` and ``D``, chosen
        at construction)."""
        return self._order

    @order.setter
    def order(self, value):
        refuse_fixed(self, "order", "it is the size of the buffers X and D; construct a "
                                    "new APA(dim_x, order=...)")

    @property
    def eps(self):
        """Regularization of ``X X^T``, positive (padasip's ``ifc``)."""
        return self._eps

    @eps.setter
    @_locked
    def eps(self, value):
        self._eps = check_real(value, "eps", minimum=0, strict=True)

    def _gain_shape(self):
        return (self.dim_x, self.order)

    @_locked
    def reset(self):
        """Back to ``x0``; diagnostics, counters and the buffers (zeros) cleared."""
        super().reset()
        self.X = np.zeros((self.order, self.dim_x))
        self.D = np.zeros((self.order, self.dim_z))

    @_locked
    def initialize(self, zs, Hs):
        """Least squares on `zs`, `Hs`; the buffers then hold their newest rows."""
        super().initialize(zs, Hs)
        Z, Hm = self._as_batch(zs, Hs)
        keep = ~np.isnan(Z).any(axis=1)
        rows, meas = Hm[keep][::-1][:self.order], Z[keep][::-1][:self.order]
        self.X, self.D = np.zeros_like(self.X), np.zeros_like(self.D)
        self.X[:len(rows)], self.D[:len(meas)] = rows, meas

    def _work(self):
        k, n, m = self._order, self.dim_x, self.dim_z
        return (self.X.copy(), self.D.copy(), np.empty((k, k)), np.empty((k, n)),
                np.empty((k, m)), np.empty((k, k)))

    def _set_work(self, work):
        self.X, self.D = work[0], work[1]

    def _step(self, x, h, z, K, y, work):
        _kernels().apa_update(x, h.reshape(1, -1), z.reshape(1, -1), self.mu, self._eps,
                              *work[:2], K, y, *work[2:])

    def _run(self, x, Hm, Z, K, y, work, trajectory):
        return _kernels().apa_batch(x, np.ascontiguousarray(Hm), np.ascontiguousarray(Z),
                                    self.mu, self._eps, *work[:2], K, y, *work[2:], trajectory)

    @_locked
    def get_state(self):
        """``x``, the buffers ``X`` and ``D`` and the update count (copies)."""
        return {"x": self._x.copy(), "X": self.X.copy(), "D": self.D.copy(),
                "n_updates": int(self.n_updates)}

    @_locked
    def set_state(self, state):
        """Continue from a dict of :meth:`get_state`."""
        s = check_state(self, state)
        self._x, self.X, self.D, self.n_updates = s["x"], s["X"], s["D"], s["n_updates"]

    def __repr__(self):
        return (f"APA(dim_x={self.dim_x}, dim_z={self.dim_z}, order={self.order}, "
                f"mu={self.mu}, eps={self._eps})")
