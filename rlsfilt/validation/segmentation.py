r"""Piecewise-constant AR, ARX and ARMAX models by dynamic programming (MATLAB's ``segment``).

The record is cut into segments, each with its own constant parameter vector
:math:`\theta_s` of the same AR or ARX structure, by minimizing over every
segmentation the penalized least-squares criterion

.. math::

    V = \sum_{s} c(\text{segment } s) + \beta \,(\text{number of segments} - 1),

with :math:`c` the exact least-squares loss of the segment's own regression
(its residual sum of squares divided by the noise variance ``R2``, or
:math:`n_s \log(\mathrm{RSS}_s / n_s)` when the variance is unknown and each
segment has its own), and :math:`\beta` the price of a change. The minimum
over all segmentations is found exactly by dynamic programming (Bellman
1961; Auger & Lawrence 1989; Jackson et al. 2005): with :math:`F(t)` the
best criterion of the first :math:`t` regression rows,

.. math::

    F(0) = -\beta, \qquad F(t) = \min_{s \le t - m} F(s) + c(s, t) + \beta ,

:math:`m` the shortest segment allowed. Each segment's loss comes from
running sums of :math:`\varphi\varphi^T`, :math:`\varphi y` and :math:`y^2`
from its first row, so all :math:`O(N^2)` candidate segments cost
:math:`O(N^2 d^3)` in batches; the parameters of the segments found are then
computed by least squares on their rows (``numpy.linalg.lstsq``).

MATLAB's ``segment`` runs a bank of Kalman filters with jump hypotheses
(Andersson 1985); here the same criterion (noise variance ``R2``, jump
probability ``q``) is minimized exactly, offline. AR and ARX structures
(several inputs too) are segmented exactly. An ARMAX (or ARMA) segment's
loss is not a least-squares loss: its innovations :math:`e(t)` are first
estimated by long ARX models fitted per segment of a preliminary ARX
segmentation (Hannan & Rissanen 1982), then the regression on
``[-y lags, u lags, e lags]`` is segmented exactly by the same dynamic
programme, the estimates refined with the segments found; an approximation
in the spirit of MATLAB's pseudo-linear regressions for ARMAX.
"""

import itertools
import math

import numpy as np

from .._display import Summary
from .._lazy_scipy import lfilter, lfiltic
from .._validation import as_float_array, check_int
from ..models import arx_regressors, arx_structure
from ..models._long_ar import long_arx_residuals
from ..models._stability import reflect

__all__ = ["Segmentation", "segment"]


class Segmentation:
    r"""Result of :func:`segment`: the segments, their change times and parameters.

    Attributes
    ----------
    segments : list of tuple of int
        ``(start, stop)`` of each segment in samples of the record (``stop``
        excluded); the first starts at ``max_lag``, the first sample with a
        complete regressor.
    change_times : ndarray of int
        The first sample of every segment after the first.
    theta : ndarray, shape (n_segments, n_params)
        Least-squares parameters of each segment (regressor layout of
        :func:`rlsfilt.models.arx_regressors`: ``[a_1 .. a_na, b ...]``,
        then ``c_1 .. c_nc`` for an ARMAX model).
    covariances : ndarray, shape (n_segments, n_params, n_params)
        Their covariances, :math:`\sigma_s^2 (\Phi_s^T \Phi_s)^{-1}` with
        :math:`\sigma_s^2` ``R2`` when given, else the segment's residual
        variance ``RSS / (n_s - n_params)`` (for an ARMAX model with estimated
        innovations, the pseudo-linear regression's, see :func:`segment`).
    noise_variances : ndarray, shape (n_segments,)
        :math:`\sigma_s^2` of each segment.
    rss : ndarray, shape (n_segments,)
        Residual sum of squares of each segment.
    objective : float
        The minimum of the criterion :math:`V`.
    penalty : float
        :math:`\beta`, the price of a change.
    orders : tuple
        ``(na, nb, nk)``, or ``(na, nb, nc, nk)`` for an ARMAX model (MATLAB's
        order).
    max_lag : int
        Samples lost at the start (no complete regressor; for an ARMAX model
        with estimated innovations, also the samples before the first
        innovation estimate and its `nc` lags).
    n_samples : int
        Length of the record.
    innovations : ndarray, shape (N,) or None
        ARMAX only: the innovations :math:`\hat e(t)` regressed on (NaN
        where there is no estimate); None otherwise.
    """

    def __init__(self, segments, theta, covariances, noise_variances, rss, objective, penalty,
                 orders, max_lag, n_samples, innovations=None):
        self.segments = segments
        self.change_times = np.array([a for a, _ in segments[1:]], dtype=int)
        self.theta, self.covariances = theta, covariances
        self.noise_variances, self.rss = noise_variances, rss
        self.objective, self.penalty = objective, penalty
        self.orders, self.max_lag, self.n_samples = orders, max_lag, n_samples
        self.innovations = innovations

    @property
    def n_segments(self):
        """Number of segments."""
        return len(self.segments)

    @property
    def parameters(self):
        """The parameters at every sample, shape ``(N, n_params)`` (NaN before
        ``max_lag``): MATLAB's ``segment`` output."""
        out = np.full((self.n_samples, self.theta.shape[1]), np.nan)
        for (a, b), th in zip(self.segments, self.theta, strict=True):
            out[a:b] = th
        return out

    def std_errors(self):
        """Standard errors of `theta`, shape ``(n_segments, n_params)``."""
        return np.sqrt(np.diagonal(self.covariances, axis1=1, axis2=2))

    def summary(self):
        """One line per segment with its samples and parameters.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook.
        """
        lines = [f"Segmentation, {self.n_segments} segment(s), orders {self.orders}, "
                 f"criterion {self.objective:.6g} (change penalty {self.penalty:.4g})"]
        se = self.std_errors()
        for (a, b), th, s in zip(self.segments, self.theta, se, strict=True):
            par = ", ".join(f"{v:.4g} ± {e:.2g}" for v, e in zip(th, s, strict=True))
            lines.append(f"  samples {a:6d} .. {b - 1:6d}: [{par}]")
        return Summary("\n".join(lines))

    def _repr_html_(self):
        """The :meth:`summary` for Jupyter."""
        return self.summary().as_html()

    def __repr__(self):
        return (f"<Segmentation: {self.n_segments} segment(s), changes at "
                f"{self.change_times.tolist()}>")

    def plot(self, ax=None, *, names=None, true_values=None):
        """Parameters per sample with the change times
        (:func:`rlsfilt.plotting.plot_segmentation`); returns the axes."""
        from ..plotting import plot_segmentation

        return plot_segmentation(self, ax, names=names, true_values=true_values)


def segment(y, u=None, *, na, nb=0, nk=1, nc=0, R2=None, q=0.01, penalty=None, min_length=None,
            innovations=None, n_iter=2):
    r"""Piecewise-constant AR/ARX/ARMAX model of a record: the segmentation minimizing
    a penalized least-squares criterion, found exactly by dynamic programming.

    Parameters
    ----------
    y : array_like, shape (N,)
        Output record.
    u : array_like, shape (N,) or (N, nu), optional
        Input record; omitted for an AR (or ARMA) model (then `nb` must be 0).
    na : int
        Number of past outputs.
    nb, nk : int or sequence of int, default 0 and 1
        Input coefficients and delay (one per input), as in `ARX`.
    nc : int, default 0
        Number of noise coefficients :math:`c_1 .. c_{nc}` (MATLAB's
        ``[na nb nc nk]``): ``nc > 0`` makes the model ARMAX (ARMA without
        `u`), segmented on the Hannan-Rissanen regression (see Notes).
    R2 : float, optional
        Noise variance. Given, a segment costs :math:`\mathrm{RSS}_s / R_2`;
        omitted, each segment has its own unknown variance and costs
        :math:`n_s \log(\mathrm{RSS}_s / n_s)` (both are :math:`-2 \log`
        likelihoods up to constants).
    q : float, default 0.01
        Probability of a change at any sample, in (0, 1) (MATLAB's `q`).
    penalty : float, optional
        The price :math:`\beta` of a change, overriding the default
        :math:`2 \log((1 - q) / q) + k \log N`, with :math:`k` the number of
        new parameters a segment brings (``n_params``, plus 1 for its
        variance when `R2` is omitted), a BIC term.
    min_length : int, optional
        Shortest segment (regression rows); default ``max(2 n_params, 10)``,
        at least ``n_params + 1``.
    innovations : array_like, shape (N,), optional
        ARMAX only: the innovations :math:`e(t)` to regress on, instead of
        their Hannan-Rissanen estimates (for instance from a model fitted
        elsewhere); finite.
    n_iter : int, default 2
        ARMAX only: the most rounds of "innovations at the pseudo-linear
        fixed point on the latest segments, then the segmentation of the
        extended regression" (it stops earlier when the change times repeat).

    Returns
    -------
    Segmentation

    Notes
    -----
    See the module :mod:`rlsfilt.validation.segmentation`. The minimizer is
    exact for the criterion: every segmentation into segments of at least
    `min_length` rows is considered. Time and memory: :math:`O(N^2 d^3)`
    operations (batched) and :math:`O(N d^2)` memory.

    **ARMAX** (``nc > 0``). The loss of an ARMAX segment is not a
    least-squares loss; the innovations are estimated first, as in the
    Hannan-Rissanen method, and the segmentation is then exact for the
    pseudo-linear regression

    .. math::

        y(t) = -\sum_{k=1}^{n_a} a_k y(t-k) + \sum_i \sum_k b_{i,k} u_i(t-n_{k,i}-k+1)
               + \sum_{k=1}^{n_c} c_k \hat e(t-k) + e(t).

    The first estimates :math:`\hat e(t)` are the residuals of a long ARX
    model (order :math:`L = \max(20, 3(n_a + n_c))`, at most an eighth of the
    segment per signal) fitted *per segment* of a preliminary segmentation,
    the ARX (``nc = 0``) one with unknown variance. Then, for up to `n_iter`
    rounds: on the latest segments, the pseudo-linear regression is iterated
    to its fixed point (each segment's least squares on the extended rows,
    then :math:`\hat e = (A y - B u) / C` with each segment's polynomials,
    ``C`` reflected into the unit circle), and the regression with these
    :math:`\hat e` is segmented exactly. Samples before the first long-model
    row have no :math:`\hat e` and no regression row
    (`Segmentation.max_lag` counts them). The approximation is the one of
    MATLAB's ``segment``, whose ARMAX filters regress on estimated
    innovations as well (pseudo-linear regression): the segmentation is
    exact for the regression, not for the ARMAX likelihood, and an
    innovation estimate near a change mixes the two regimes. The
    covariances are those of the fixed point,
    :math:`\sigma^2 (\Phi^T \Psi)^{-1} \Phi^T \Phi (\Psi^T \Phi)^{-1}` with
    :math:`\psi = \varphi / C(q)` (the plain :math:`\sigma^2 (\Phi^T \Phi)^{-1}`
    would understate them); with given `innovations`,
    :math:`\sigma^2 (\Phi^T \Phi)^{-1}`.

    References
    ----------
    .. [1] F. Gustafsson, *Adaptive Filtering and Change Detection*, Wiley,
       2000, ch. 7.
    .. [2] I. E. Auger and C. E. Lawrence, "Algorithms for the optimal
       identification of segment neighborhoods", *Bull. Math. Biol.* 51(1),
       1989.
    .. [3] B. Jackson et al., "An algorithm for optimal partitioning of data
       on an interval", *IEEE Signal Process. Lett.* 12(2), 2005.
    .. [4] E. J. Hannan and J. Rissanen, "Recursive estimation of mixed
       autoregressive-moving average order", *Biometrika* 69(1), 81-94, 1982.

    Examples
    --------
    A first-order plant whose pole moves at sample 150:

    >>> import numpy as np
    >>> from rlsfilt.validation import segment
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(300)
    >>> y = np.zeros(300)
    >>> for t in range(1, 300):
    ...     a = -0.5 if t < 150 else -0.9
    ...     y[t] = -a * y[t - 1] + u[t - 1] + 0.1 * rng.standard_normal()
    >>> seg = segment(y, u, na=1, nb=1, R2=0.01)
    >>> seg.change_times
    array([150])
    >>> np.round(seg.theta, 1)          # [a_1, b_1] of each segment
    array([[-0.5,  1. ],
           [-0.9,  1. ]])

    The same plant with coloured noise :math:`e(t) + 0.7 e(t-1)`, an ARMAX:

    >>> e = 0.1 * rng.standard_normal(600)
    >>> u = rng.standard_normal(600)
    >>> y = np.zeros(600)
    >>> for t in range(1, 600):
    ...     a = -0.5 if t < 300 else -0.9
    ...     y[t] = -a * y[t - 1] + u[t - 1] + e[t] + 0.7 * e[t - 1]
    >>> seg = segment(y, u, na=1, nb=1, nc=1, R2=0.01)
    >>> seg.change_times, seg.orders
    (array([300]), (1, 1, 1, 1))
    >>> np.round(seg.theta, 1)          # [a_1, b_1, c_1] of each segment
    array([[-0.5,  1. ,  0.7],
           [-0.9,  1. ,  0.7]])
    """
    y = as_float_array(y, "y")
    if y.ndim != 1:
        raise ValueError(f"`y` must have shape (N,); got {y.shape}")
    na = check_int(na, "na", minimum=0)
    nc = check_int(nc, "nc", minimum=0)
    n_iter = check_int(n_iter, "n_iter", minimum=1)
    if u is None:
        if not (nb == 0 or (np.ndim(nb) and not np.any(nb))):
            raise ValueError(f"`nb` must be 0 for an AR model (no `u`); got {nb}")
        if na + nc == 0:
            raise ValueError("`na` (or `nc`) must be >= 1 for an AR model (no `u`); got 0")
        Phi = np.column_stack([-y[na - 1 - i:len(y) - 1 - i] for i in range(na)]) \
            if na else np.zeros((len(y) - na, 0))
        target, max_lag = y[na:].copy(), na
        U, nks = np.zeros((len(y), 0)), ()
        orders = (na, 0, 0)
    else:
        Phi, target = arx_regressors(u, y, na=na, nb=nb, nk=nk)
        max_lag = len(y) - len(target)
        U = as_float_array(u, "u").reshape(len(y), -1)
        nks = arx_structure(na, nb, nk, U.shape[1]).nk
        orders = (na, nb, nk)
    if not np.all(np.isfinite(Phi)) or not np.all(np.isfinite(target)):
        raise ValueError("`y` and `u` must be finite (segment has no missing-data handling)")
    if R2 is not None:
        R2 = float(R2)
        if not (math.isfinite(R2) and R2 > 0.0):
            raise ValueError(f"`R2` must be a positive finite variance; got {R2}")
    q = float(q)
    if not (0.0 < q < 1.0):
        raise ValueError(f"`q` must be in (0, 1); got {q}")
    if penalty is not None:
        penalty = float(penalty)
        if not (math.isfinite(penalty) and penalty >= 0.0):
            raise ValueError(f"`penalty` must be a non-negative finite number; got {penalty}")
    d = Phi.shape[1] + nc
    if min_length is None:
        min_length = max(2 * d, 10)
    min_length = check_int(min_length, "min_length", minimum=d + 1)
    if nc == 0:
        if innovations is not None:
            raise ValueError("`innovations` are regressed on only in an ARMAX model; "
                             "got them with `nc` = 0")
        fit = _segment_rows(Phi, target, R2, q, penalty, min_length)
        return _result(fit, orders, max_lag, len(y), None)
    orders = (*orders[:2], nc, orders[2])
    if innovations is not None:
        e = np.array(as_float_array(innovations, "innovations"), dtype=float)   # (a copy)
        if e.shape != y.shape or not np.all(np.isfinite(e)):
            raise ValueError(f"`innovations` must be finite with the shape of `y`, {y.shape}; "
                             f"got shape {e.shape}" + (" with non-finite values"
                                                       if e.shape == y.shape else ""))
        rows = _armax_rows(Phi, target, max_lag, e, 0, nc)
        return _result(_segment_rows(*rows[:2], R2, q, penalty, min_length), orders,
                       rows[2], len(y), e)
    # Hannan-Rissanen: innovations from long ARX models on the segments of the ARX fit
    if len(target) < min_length:
        raise ValueError(f"the record has {len(target)} regression rows; `min_length` = "
                         f"{min_length} needs at least that many")
    arx = _segment_rows(Phi, target, None, q, None, min_length)
    cuts = [a + max_lag for a, _ in arx["bounds"][1:]]
    e, e_start = _innovation_estimates(y, U, nks, cuts, max(20, 3 * (na + nc)))
    for _ in range(n_iter):
        e = _pseudo_linear_fixed_point(Phi, target, max_lag, e, e_start, nc, cuts)
        rows = _armax_rows(Phi, target, max_lag, e, e_start, nc)
        fit = _segment_rows(*rows[:2], R2, q, penalty, min_length)
        new_cuts = [a + rows[2] for a, _ in fit["bounds"][1:]]
        if new_cuts == cuts:
            break
        cuts = new_cuts
    fit["cov"] = _pseudo_linear_covariances(rows[0], fit, Phi.shape[1])
    e = e.copy()
    e[:e_start] = np.nan
    return _result(fit, orders, rows[2], len(y), e)


def _pseudo_linear_fixed_point(Phi, target, max_lag, e, e_start, nc, cuts, max_iter=50,
                               rtol=1e-8):
    r"""Innovations at the fixed point of the pseudo-linear regression on the
    segments between `cuts`: alternately each segment's least squares on
    ``[phi(t), e(t-1) .. e(t-nc)]`` and the innovations of the piecewise
    ARMAX model, :math:`e(t) = (y(t) - \varphi(t)^T [a; b]) / C(q)` (each
    ``C`` reflected into the unit circle), from ``e = 0`` before the first
    ARX row; `e` (from `e_start` on) is the start."""
    N, d0 = len(e), Phi.shape[1]
    theta = None
    for _ in range(max_iter):
        A, z, start = _armax_rows(Phi, target, max_lag, e, e_start, nc)
        edges = [start, *cuts, N]
        new = np.array([np.linalg.lstsq(A[a - start:b - start], z[a - start:b - start],
                                        rcond=None)[0]
                        for a, b in itertools.pairwise(edges)])
        e = np.zeros(N)
        edges[0] = max_lag
        for (a, b), th in zip(itertools.pairwise(edges), new, strict=True):
            v = target[a - max_lag:b - max_lag] - Phi[a - max_lag:b - max_lag] @ th[:d0]
            C = reflect(np.r_[1.0, th[d0:]])
            e[a:b] = lfilter([1.0], C, v, zi=lfiltic([1.0], C, e[max(a - nc, 0):a][::-1]))[0]
        if theta is not None and np.max(np.abs(new - theta)) <= rtol * (1.0 + np.max(
                np.abs(theta))):
            break
        theta = new
    return e


def _pseudo_linear_covariances(A, fit, d0):
    r"""Covariances of the pseudo-linear regression's fixed point per segment:
    :math:`\sigma^2 (\Phi^T \Psi)^{-1} \Phi^T \Phi (\Psi^T \Phi)^{-1}`,
    :math:`\psi(t) = \varphi(t) / C(q)` (the gradient of the prediction error,
    filtered from zero at the segment's first row), from the linearized
    fixed-point condition :math:`\sum \varphi(t)\,\varepsilon(t, \hat\theta) = 0`,
    :math:`\varepsilon(t, \hat\theta) \approx e(t) - \psi(t)^T (\hat\theta - \theta)`
    (Ljung 1999, sec. 9.5); `d0` columns of `A` are the ARX part."""
    cov = np.empty_like(fit["cov"])
    for s, ((a, b), th) in enumerate(zip(fit["bounds"], fit["theta"], strict=True)):
        P = A[a:b]
        Psi = lfilter([1.0], reflect(np.r_[1.0, th[d0:]]), P, axis=0)
        M = np.linalg.pinv(P.T @ Psi)
        cov[s] = fit["sig2"][s] * (M @ (P.T @ P) @ M.T)
    return cov


def _armax_rows(Phi, target, max_lag, e, e_start, nc):
    """``(Phi, target, max_lag)`` of the extended regression: the ARX rows from the
    first sample whose ``nc`` lags of ``e`` are known, with the columns
    ``e(t-1) .. e(t-nc)`` appended."""
    N = len(e)
    start = max(max_lag, e_start + nc)
    if start >= N:
        raise ValueError(f"the record has no regression row: the innovations are known "
                         f"from sample {e_start} and `nc` = {nc}")
    E = np.column_stack([e[start - k:N - k] for k in range(1, nc + 1)])
    return np.hstack([Phi[start - max_lag:], E]), target[start - max_lag:], start


def _innovation_estimates(y, U, nk, cuts, long_order):
    r"""``(e, e_start)``: residuals of a long ARX model fitted on each segment
    (between the `cuts`), the first stage of Hannan-Rissanen; ``e`` is zero
    before ``e_start``, the first sample with an estimate. The order is at
    most an eighth of the segment per signal; its rows may reach back into
    the previous segment's samples."""
    N, nu = U.shape
    max_nk = max(nk) if nu else 0
    e = np.zeros(N)
    edges = [0, *cuts, N]
    e_start = N
    for a, b in itertools.pairwise(edges):
        L = max(1, min(long_order, (b - a) // (8 * (1 + nu))))
        a0 = max(0, a - L - max_nk)                  # the slice's row L + max_nk is sample a
        first = a0 + L + max_nk
        r = long_arx_residuals(U[a0:b], y[a0:b], L, nk if nu else None)
        e[max(a, first):b] = r[max(a, first) - a0:]
        if a == 0:
            e_start = first
    return e, e_start


def _segment_rows(Phi, target, R2, q, penalty, min_length):
    """The optimal segmentation of the regression rows and each segment's least squares."""
    rows, d = Phi.shape
    if rows < min_length:
        raise ValueError(f"the record has {rows} regression rows; `min_length` = "
                         f"{min_length} needs at least that many")
    if penalty is None:
        k = d + (0 if R2 is not None else 1)
        penalty = 2.0 * math.log((1.0 - q) / q) + k * math.log(rows)
    starts, objective = _optimal_partition(Phi, target, R2, penalty, min_length)
    bounds = list(zip(starts, [*starts[1:], rows], strict=True))
    theta = np.empty((len(bounds), d))
    cov = np.empty((len(bounds), d, d))
    sig2, rss = np.empty(len(bounds)), np.empty(len(bounds))
    for s, (a, b) in enumerate(bounds):
        A, z = Phi[a:b], target[a:b]
        theta[s] = np.linalg.lstsq(A, z, rcond=None)[0]
        r = z - A @ theta[s]
        rss[s] = r @ r
        sig2[s] = R2 if R2 is not None else rss[s] / (b - a - d)
        Rinv = np.linalg.pinv(np.linalg.qr(A, mode="r"))       # (Phi^T Phi)^-1 = R^-1 R^-T
        cov[s] = sig2[s] * (Rinv @ Rinv.T)
    return {"bounds": bounds, "theta": theta, "cov": cov, "sig2": sig2, "rss": rss,
            "objective": objective, "penalty": penalty}


def _result(fit, orders, max_lag, n_samples, innovations):
    """The `Segmentation` of a `_segment_rows` fit (rows shifted to samples)."""
    segments = [(a + max_lag, b + max_lag) for a, b in fit["bounds"]]
    return Segmentation(segments, fit["theta"], fit["cov"], fit["sig2"], fit["rss"],
                        fit["objective"], fit["penalty"], orders, max_lag, n_samples,
                        innovations)


def _segment_losses(outer, Phi, target, start, min_length):
    """Residual sums of squares of the segments ``[start, stop)`` of the rows, for
    ``stop = start + min_length, ..., N``: running sums from `start`,
    ``RSS = y^T y - b^T A^{-1} b`` (``A = sum phi phi^T``, ``b = sum phi y``)."""
    P, z = Phi[start:], target[start:]
    A = np.cumsum(outer[start:], axis=0)[min_length - 1:]
    b = np.cumsum(P * z[:, None], axis=0)[min_length - 1:]
    yy = np.cumsum(z * z)[min_length - 1:]
    try:
        sol = np.linalg.solve(A, b[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:                       # a singular segment: least norm
        sol = (np.linalg.pinv(A) @ b[:, :, None])[:, :, 0]
    return np.maximum(yy - np.sum(b * sol, axis=1), 0.0)


def _optimal_partition(Phi, target, R2, penalty, min_length):
    """``(starts, objective)``: the first rows of the optimal segments and the minimum."""
    N = len(target)
    F = np.full(N + 1, np.inf)          # F[t]: best criterion of rows [0, t)
    last = np.zeros(N + 1, dtype=int)   # the start of the last segment of that optimum
    F[0] = -penalty
    outer = Phi[:, :, None] * Phi[:, None, :]
    for s in range(N - min_length + 1):
        if not np.isfinite(F[s]):
            continue
        rss = _segment_losses(outer, Phi, target, s, min_length)
        if R2 is not None:
            cost = rss / R2
        else:
            n = np.arange(min_length, N - s + 1)
            with np.errstate(divide="ignore"):
                cost = n * np.log(rss / n)
        total = F[s] + cost + penalty
        ends = np.arange(s + min_length, N + 1)
        better = total < F[ends]
        F[ends[better]], last[ends[better]] = total[better], s
    if not np.isfinite(F[N]):
        raise ValueError("no segmentation satisfies `min_length`")  # (unreachable: N >= m)
    starts, t = [], N
    while t > 0:
        starts.append(int(last[t]))
        t = last[t]
    return starts[::-1], float(F[N])
