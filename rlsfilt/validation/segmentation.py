r"""Piecewise-constant AR and ARX models by dynamic programming (MATLAB's ``segment``).

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
(several inputs too) are supported; ARMAX is not (its segment losses are not
least-squares losses: fit a higher-order ARX instead).
"""

import math

import numpy as np

from .._display import Summary
from .._validation import as_float_array, check_int
from ..models import arx_regressors

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
        :func:`rlsfilt.models.arx_regressors`: ``[a_1 .. a_na, b ...]``).
    covariances : ndarray, shape (n_segments, n_params, n_params)
        Their covariances, :math:`\sigma_s^2 (\Phi_s^T \Phi_s)^{-1}` with
        :math:`\sigma_s^2` ``R2`` when given, else the segment's residual
        variance ``RSS / (n_s - n_params)``.
    noise_variances : ndarray, shape (n_segments,)
        :math:`\sigma_s^2` of each segment.
    rss : ndarray, shape (n_segments,)
        Residual sum of squares of each segment.
    objective : float
        The minimum of the criterion :math:`V`.
    penalty : float
        :math:`\beta`, the price of a change.
    orders : tuple
        ``(na, nb, nk)``.
    max_lag : int
        Samples lost at the start (no complete regressor).
    n_samples : int
        Length of the record.
    """

    def __init__(self, segments, theta, covariances, noise_variances, rss, objective, penalty,
                 orders, max_lag, n_samples):
        self.segments = segments
        self.change_times = np.array([a for a, _ in segments[1:]], dtype=int)
        self.theta, self.covariances = theta, covariances
        self.noise_variances, self.rss = noise_variances, rss
        self.objective, self.penalty = objective, penalty
        self.orders, self.max_lag, self.n_samples = orders, max_lag, n_samples

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


def segment(y, u=None, *, na, nb=0, nk=1, R2=None, q=0.01, penalty=None, min_length=None):
    r"""Piecewise-constant AR/ARX model of a record: the segmentation minimizing a
    penalized least-squares criterion, found exactly by dynamic programming.

    Parameters
    ----------
    y : array_like, shape (N,)
        Output record.
    u : array_like, shape (N,) or (N, nu), optional
        Input record; omitted for an AR model (then `nb` must be 0).
    na : int
        Number of past outputs.
    nb, nk : int or sequence of int, default 0 and 1
        Input coefficients and delay (one per input), as in `ARX`.
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

    Returns
    -------
    Segmentation

    Notes
    -----
    See the module :mod:`rlsfilt.validation.segmentation`. The minimizer is
    exact for the criterion: every segmentation into segments of at least
    `min_length` rows is considered. Time and memory: :math:`O(N^2 d^3)`
    operations (batched) and :math:`O(N d^2)` memory.

    References
    ----------
    .. [1] F. Gustafsson, *Adaptive Filtering and Change Detection*, Wiley,
       2000, ch. 7.
    .. [2] I. E. Auger and C. E. Lawrence, "Algorithms for the optimal
       identification of segment neighborhoods", *Bull. Math. Biol.* 51(1),
       1989.
    .. [3] B. Jackson et al., "An algorithm for optimal partitioning of data
       on an interval", *IEEE Signal Process. Lett.* 12(2), 2005.

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
    """
    y = as_float_array(y, "y")
    if y.ndim != 1:
        raise ValueError(f"`y` must have shape (N,); got {y.shape}")
    na = check_int(na, "na", minimum=0)
    if u is None:
        if not (nb == 0 or (np.ndim(nb) and not np.any(nb))):
            raise ValueError(f"`nb` must be 0 for an AR model (no `u`); got {nb}")
        if na == 0:
            raise ValueError("`na` must be >= 1 for an AR model (no `u`); got 0")
        Phi = np.column_stack([-y[na - 1 - i:len(y) - 1 - i] for i in range(na)])
        target, max_lag = y[na:].copy(), na
        orders = (na, 0, 0)
    else:
        Phi, target = arx_regressors(u, y, na=na, nb=nb, nk=nk)
        max_lag = len(y) - len(target)
        orders = (na, nb, nk)
    rows, d = Phi.shape
    if not np.all(np.isfinite(Phi)) or not np.all(np.isfinite(target)):
        raise ValueError("`y` and `u` must be finite (segment has no missing-data handling)")
    if R2 is not None:
        R2 = float(R2)
        if not (math.isfinite(R2) and R2 > 0.0):
            raise ValueError(f"`R2` must be a positive finite variance; got {R2}")
    q = float(q)
    if not (0.0 < q < 1.0):
        raise ValueError(f"`q` must be in (0, 1); got {q}")
    if min_length is None:
        min_length = max(2 * d, 10)
    min_length = check_int(min_length, "min_length", minimum=d + 1)
    if rows < min_length:
        raise ValueError(f"the record has {rows} regression rows; `min_length` = "
                         f"{min_length} needs at least that many")
    if penalty is None:
        k = d + (0 if R2 is not None else 1)
        penalty = 2.0 * math.log((1.0 - q) / q) + k * math.log(rows)
    else:
        penalty = float(penalty)
        if not (math.isfinite(penalty) and penalty >= 0.0):
            raise ValueError(f"`penalty` must be a non-negative finite number; got {penalty}")
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
    segments = [(a + max_lag, b + max_lag) for a, b in bounds]
    return Segmentation(segments, theta, cov, sig2, rss, objective, penalty, orders, max_lag,
                        len(y))


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
