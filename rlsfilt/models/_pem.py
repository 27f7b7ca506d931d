r"""Batch prediction-error estimation of the general polynomial model family.

For :math:`A y = \sum_i B_i/F_i\, u_i + C/D\, e` (orders in
:class:`~rlsfilt.models._family.FamilyStructure`) the exact one-step
predictor is :math:`\hat y(t|\theta) = y(t) - \varepsilon(t, \theta)` with the
prediction error

.. math::

    w_i = \frac{B_i}{F_i} u_i,\qquad v = A y - \sum_i w_i,\qquad
    \varepsilon = \frac{D}{C} v,

every filter started from rest (all signals zero before ``t = 0``: MATLAB's
``InitialCondition = 'zero'``). The criterion is

.. math::

    V(\theta) = \frac12 \sum_{t = t_0}^{N-1} \varepsilon(t, \theta)^2,
    \qquad t_0 = \max(n_a, \max_i(n_{k,i} + n_{b,i} - 1)),

which for an ARX structure is least squares on the ARX regressor rows. With
several experiments (:func:`pem_records`) the criterion is the sum of the
criteria of the experiments, each with its predictor started from rest at
its own first sample (MATLAB's multi-experiment ``iddata``), so no
prediction error pairs samples of two experiments. Its
gradient :math:`\psi = \partial\hat y/\partial\theta = -\partial\varepsilon/
\partial\theta` is exact (the initial states are zero, whatever
:math:`\theta`), one filter per block followed by shifts (``q^{-k}`` commutes
with every filter):

.. math::

    \psi_{a_k} = -\frac{D}{C} y(t-k),\quad
    \psi_{b_{i,k}} = \frac{D}{C F_i} u_i(t-n_{k,i}-k+1),\quad
    \psi_{c_k} = \frac{1}{C}\varepsilon(t-k),\quad
    \psi_{d_k} = -\frac{1}{C} v(t-k),\quad
    \psi_{f_{i,k}} = -\frac{D}{C F_i} w_i(t-k).

`pem` minimizes :math:`V` by a Levenberg-Marquardt search
(`_levenberg_marquardt`) with this analytic Jacobian, from the lowest
criterion of the consistent starts of :mod:`rlsfilt.models._initial`
(refined IV or Hannan-Rissanen, the ARX of the same orders, a reduced
high-order ARX), optionally also from random stable starts. ``C``, ``D``
and ``F_i`` are kept stable as in MATLAB's ``pem``: a start or a trial step
that leaves the stability region has its zeros reflected inside, so every
iterate has a stable predictor and the search is not stopped at the
boundary. A `ConvergenceWarning` says when the result may not be the
optimum: a zero on the boundary at the end, a limit reached, or a
criterion above that of the ARX of the same orders. The covariance is
The covariance is
:math:`\hat\sigma^2 (J^T J)^{-1}` at the minimum, with
:math:`\hat\sigma^2 = 2V / (N - t_0 - n_\theta)` (Ljung 1999, ch. 9).

The search runs in scaled units (:class:`~rlsfilt.models._units.RecordUnits`):
each input and the output divided by a power of two near its largest entry,
so that the criterion, a sum of squares, stays inside the double range for
records around :math:`10^{\pm 160}` (:mod:`rlsfilt._scale`). The model is linear in the
signals: with :math:`u_i = 2^{e_i} \tilde u_i` and :math:`y = 2^{e_y}\tilde y`,
the minimizer for the scaled record has the same ``a, c, d, f`` and
:math:`b_i = 2^{e_y - e_i}\tilde b_i`; the prediction errors are
:math:`2^{e_y}\tilde\varepsilon`, the noise variance
:math:`2^{2 e_y}\tilde\sigma^2` and the covariance
:math:`G \tilde P G` with :math:`G` the diagonal of those factors. Multiplying
by a power of two is exact, so the estimate in the user's units is the
estimate in the scaled units, bit for bit, unless a number in the user's
units is not representable (a noise variance of a record around
:math:`10^{160}` is ``inf``).

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
   Prentice Hall, 1999, sec. 4.2, 7.2, 9.2 and 10.2.
.. [2] T. Soderstrom and P. Stoica, *System Identification*, Prentice Hall,
   1989, ch. 7.
.. [3] K. Madsen, H. B. Nielsen and O. Tingleff, *Methods for Non-Linear
   Least Squares Problems*, 2nd ed., Technical University of Denmark, 2004,
   sec. 3.2 (the damping update).
"""

import contextlib
import numbers
import warnings

import numpy as np

from .._lazy_scipy import lfilter
from .._progress import AFTER, LazyProgress
from .._validation import check_int
from ..exceptions import ConvergenceWarning
from ._family import split_theta
from ._initial import arx_in_structure, arx_reduced, initial_estimate, random_start
from ._stability import predictor_is_stable, stabilize_theta
from ._units import RecordUnits
from .regressors import _column_rank

__all__ = []


def _shift(x, k):
    """``x(t - k)`` with zeros before the record."""
    if k == 0:
        return x
    out = np.zeros_like(x)
    if k < len(x):
        out[k:] = x[:-k]
    return out


def prediction_error_parts(theta, s, U, y):
    r"""The prediction error and its intermediate signals.

    Parameters
    ----------
    theta : ndarray, shape (n_params,)
    s : FamilyStructure
    U : ndarray, shape (N, nu)
    y : ndarray, shape (N,)

    Returns
    -------
    eps : ndarray, shape (N,)
        :math:`\varepsilon = D/C\,(A y - \sum_i B_i/F_i\, u_i)`.
    v : ndarray, shape (N,)
        :math:`A y - \sum_i w_i`.
    w : list of ndarray
        :math:`w_i = B_i/F_i\, u_i`, one per input.
    """
    A, B, C, D, F = split_theta(theta, s)
    w = [lfilter(B[i], F[i], U[:, i]) for i in range(s.n_inputs)]
    v = lfilter(A, [1.0], y)
    for wi in w:
        v = v - wi
    eps = lfilter(D, C, v)
    return eps, v, w


def prediction_errors(theta, s, U, y):
    r"""One-step prediction errors :math:`\varepsilon(t, \theta)`, ``t = 0 .. N-1``.

    Examples
    --------
    For an ARX structure the errors after ``t0`` are the least-squares
    residuals ``A y - B u``:

    >>> import numpy as np
    >>> from rlsfilt.models._family import family_structure
    >>> from rlsfilt.models._pem import prediction_errors
    >>> s = family_structure(na=1, nb=1, nk=1)
    >>> y, u = np.array([0.0, 1.0, 1.5, 1.75]), np.ones((4, 1))
    >>> prediction_errors(np.array([-0.5, 1.0]), s, u, y)
    array([0., 0., 0., 0.])
    """
    return prediction_error_parts(theta, s, U, y)[0]


def predictor_gradient(theta, s, U, y, parts=None):
    r"""Gradient :math:`\psi(t) = \partial\hat y(t|\theta)/\partial\theta`, shape (N, n_params).

    `parts` may pass the output of `prediction_error_parts` at the same
    ``theta`` to save its computation.
    """
    A, B, C, D, F = split_theta(theta, s)
    eps, v, w = prediction_error_parts(theta, s, U, y) if parts is None else parts
    N = len(y)
    psi = np.empty((N, s.n_params))
    sl = s.slices()
    if s.na:
        yf = lfilter(D, C, y)
        for k in range(1, s.na + 1):
            psi[:, sl["a"].start + k - 1] = -_shift(yf, k)
    for i in range(s.n_inputs):
        CF = np.convolve(C, F[i])
        uf = lfilter(D, CF, U[:, i])
        for k in range(s.nb[i]):
            psi[:, sl["b"][i].start + k] = _shift(uf, s.nk[i] + k)
        if s.nf[i]:
            wf = lfilter(D, CF, w[i])
            for k in range(1, s.nf[i] + 1):
                psi[:, sl["f"][i].start + k - 1] = -_shift(wf, k)
    if s.nc:
        ef = lfilter([1.0], C, eps)
        for k in range(1, s.nc + 1):
            psi[:, sl["c"].start + k - 1] = _shift(ef, k)
    if s.nd:
        vf = lfilter([1.0], C, v)
        for k in range(1, s.nd + 1):
            psi[:, sl["d"].start + k - 1] = -_shift(vf, k)
    return psi


def criterion(theta, s, U, y):
    r""":math:`V(\theta) = \frac12\sum_{t \ge t_0} \varepsilon(t, \theta)^2`."""
    eps = prediction_errors(theta, s, U, y)[s.t0:]
    return 0.5 * float(eps @ eps)


def criterion_rows(s, records):
    """Number of prediction errors in the criterion: ``sum_i max(N_i - t0, 0)``."""
    return sum(max(len(y) - s.t0, 0) for _, y in records)


def stacked_errors(theta, s, records):
    r"""Prediction errors :math:`\varepsilon(t)`, ``t >= t0``, of every experiment (each
    from rest), one experiment after the other."""
    return np.concatenate([prediction_errors(theta, s, U, y)[s.t0:] for U, y in records])


def stacked_gradient(theta, s, records, parts=None):
    """`predictor_gradient` rows ``t >= t0`` of every experiment, stacked (`parts`: the
    `prediction_error_parts` of each experiment at ``theta``)."""
    parts = [None] * len(records) if parts is None else parts
    return np.vstack([predictor_gradient(theta, s, U, y, parts=p)[s.t0:]
                      for (U, y), p in zip(records, parts)])


def joined(records):
    """The experiments end to end ``(U, y)`` (for the consistent start only)."""
    if len(records) == 1:
        return records[0]
    return np.vstack([U for U, _ in records]), np.concatenate([y for _, y in records])


class PEMFit:
    """Result of `pem`.

    Attributes
    ----------
    theta : ndarray, shape (n_params,)
        Minimizer of the criterion (stable ``C``, ``D``, ``F_i``).
    cov : ndarray, shape (n_params, n_params)
        :math:`\\hat\\sigma^2 (J^T J)^{-1}`.
    noise_variance : float
        :math:`\\hat\\sigma^2 = 2 V / (N - t_0 - n_\\theta)`.
    eps : ndarray, shape (N,)
        Prediction errors at ``theta`` (from ``t = 0``; with several
        experiments, those of every experiment one after the other).
    residuals : ndarray, shape (rows,)
        The errors of the criterion: ``t >= t0`` of every experiment.
    cost : float
        :math:`V(\\hat\\theta)`.
    theta0 : ndarray
        The start.
    n_fev, n_jev : int
        Function and Jacobian evaluations.
    status : int
    message : str
        Of ``least_squares``.
    """

    def __init__(self, **kw):
        self.__dict__.update(kw)


def pem(U, y, s, theta0=None, **options):
    r"""Batch prediction-error estimate of the general family.

    Parameters
    ----------
    U : ndarray, shape (N, nu)
        Inputs (``nu = 0``: a time series).
    y : ndarray, shape (N,)
    s : FamilyStructure
    theta0 : ndarray, optional
        Start (reflected into the stability region if needed); by default
        the best (lowest criterion) of the consistent starts of
        :mod:`rlsfilt.models._initial`.
    **options
        ``ftol``, ``xtol``, ``gtol``, ``max_nfev``, ``n_starts``, ``rng``,
        ``progress``, ``max_time``: see `pem_records`.

    Returns
    -------
    PEMFit

    Raises
    ------
    ValueError
        When there are no spare equations (``N - t0 <= n_params``), or
        when the gradient of the predictor at the start has deficient rank
        (the input is not persistently exciting for these orders).

    Warns
    -----
    ConvergenceWarning
        See `pem_records`.

    Examples
    --------
    OE(2, 2, 1): ``y = (u(t-1) + 0.5 u(t-2)) / (1 - 1.5 q^-1 + 0.7 q^-2) + e``.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.models._family import family_structure
    >>> from rlsfilt.models._pem import pem
    >>> rng = np.random.default_rng(3)
    >>> u = rng.standard_normal(5000)
    >>> y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.3 * rng.standard_normal(5000)
    >>> fit = pem(u[:, None], y, family_structure(nb=2, nf=2, nk=1))
    >>> np.round(fit.theta, 2)          # [b1, b2, f1, f2]
    array([ 1. ,  0.5, -1.5,  0.7])
    """
    return pem_records([(U, y)], s, theta0, **options)


def pem_records(records, s, theta0=None, *, ftol=1e-12, xtol=1e-12, gtol=1e-12,
                max_nfev=None, n_starts=1, rng=None, progress="auto", max_time=None,
                stacklevel=2):
    r"""`pem` over several experiments: the summed criterion
    :math:`\frac12\sum_i\sum_{t \ge t_0} \varepsilon_i(t, \theta)^2`, each
    experiment's predictor started from rest.

    Parameters
    ----------
    records : list of (ndarray (N_i, nu), ndarray (N_i,))
        The experiments.
    s : FamilyStructure
    theta0 : ndarray, optional
        As `pem`; the default starts are computed on the experiments joined
        end to end (only the starts: the seams perturb them slightly, never
        the criterion), leaving out those of at most ``t0`` samples (no
        prediction error of the criterion).
    ftol, xtol, gtol : float, default 1e-12
        The search stops when an accepted step lowers the criterion by less
        than ``ftol`` relative, moves ``theta`` by less than
        ``xtol (xtol + |theta|)``, or when the largest cosine between the
        errors and a column of the Jacobian is below ``gtol``.
    max_nfev : int, optional
        Largest number of criterion evaluations of the search from each
        start (default ``100 n_params``, at least 200).
    n_starts : int, default 1
        Searches to run: the default (or given) start and ``n_starts - 1``
        random stable starts (`_initial.random_start`); the lowest
        criterion wins.
    rng : None, int or numpy.random.Generator
        Seed of the random starts.
    progress : {"auto", True, False}, default "auto"
        A tqdm progress bar: ``"auto"`` shows one once the fit has run for
        `PROGRESS_AFTER` seconds, if tqdm is installed.
    max_time : float, optional
        Wall-clock limit in seconds for all searches (warned when reached).

    Returns
    -------
    PEMFit
        In the units of `records` (the search itself runs in the scaled
        units of `RecordUnits`).

    Raises
    ------
    ValueError
        As `pem`.

    Warns
    -----
    ConvergenceWarning
        When the search ends with a zero of ``F_i``, ``C`` or ``D`` on the
        stability boundary (modulus above ``1 - BOUNDARY_TOL``), when it
        stops at `max_nfev` or `max_time`, or when its criterion is larger
        than that of the least-squares ARX of the same orders written in
        the structure (`_initial.arx_in_structure`).
    """
    N = sum(len(y) for _, y in records)
    rows = criterion_rows(s, records)
    if rows <= s.n_params:
        per = " in all" if len(records) > 1 else ""
        raise ValueError(f"`y` must have more than t0 + n_params = {s.t0} + {s.n_params} = "
                         f"{s.t0 + s.n_params} samples{per} for this structure; got {N}")
    max_nfev = max(200, 100 * s.n_params) if max_nfev is None else check_int(
        max_nfev, "max_nfev", minimum=1)
    n_starts = check_int(n_starts, "n_starts", minimum=1)
    if max_time is not None and not (isinstance(max_time, numbers.Real) and max_time > 0):
        raise ValueError(f"`max_time` must be a positive number of seconds or None; got "
                         f"{max_time!r}")
    units = RecordUnits(records, s)
    scaled = units.scale_records(records)
    with _one_blas_thread():
        clock = _Clock(max_time, progress, max_nfev * n_starts)
        try:
            fit = _pem_unit(scaled, s, None if theta0 is None else
                            units.start_to_unit(np.asarray(theta0, dtype=float), "theta0"),
                            rows, ftol=ftol, xtol=xtol, gtol=gtol, max_nfev=max_nfev,
                            n_starts=n_starts, rng=rng, clock=clock)
        finally:
            clock.close()
    for message in fit.warnings:
        warnings.warn(message, ConvergenceWarning, stacklevel=stacklevel + 1)
    theta = units.estimate_from_unit(fit.theta)   # a clear error if b is not a double
    arx_cost = None if fit.arx_cost is None else float(units.output_from_unit(fit.arx_cost, 2))
    return PEMFit(theta=theta, cov=units.cov_from_unit(fit.cov),
                  noise_variance=float(units.output_from_unit(fit.noise_variance, 2)),
                  eps=units.output_from_unit(fit.eps),
                  residuals=units.output_from_unit(fit.residuals),
                  cost=float(units.output_from_unit(fit.cost, 2)),
                  theta0=units.theta_from_unit(fit.theta0), n_fev=fit.n_fev, n_jev=fit.n_jev,
                  n_iter=fit.n_iter, status=fit.status, message=fit.message,
                  converged=fit.converged, start=fit.start, max_root=fit.max_root,
                  arx_cost=arx_cost, warnings=list(fit.warnings), n_starts=n_starts,
                  start_costs={k: float(units.output_from_unit(v, 2))
                               for k, v in fit.start_costs.items() if np.isfinite(v)})


#: A zero of ``F_i``, ``C`` or ``D`` with modulus above ``1 - BOUNDARY_TOL`` at the end of
#: the search is "on the stability boundary" (warned: the predictor barely decays there, and
#: the criterion usually has a better minimum inside).
BOUNDARY_TOL = 1e-4

#: ``progress="auto"`` shows a bar once a fit has run this many seconds.
PROGRESS_AFTER = AFTER


def _one_blas_thread():
    """One BLAS thread during the search, with threadpoolctl if installed.

    The search factorizes a tall ``(N, n_params)`` Jacobian at every
    iteration; a threaded BLAS on a busy machine makes that QR 100 times
    slower (measured: 0.19 s against 2 ms for 2048 x 28 on a loaded 2-core
    machine), which was most of the time of a multi-input OE fit.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


class _Clock:
    """Time limit and (lazy) progress bar shared by the searches of one fit."""

    def __init__(self, max_time, progress, total):
        self.max_time = max_time
        self.bar = LazyProgress(total, progress, desc="pem", after=PROGRESS_AFTER, unit="eval")

    def tick(self, cost):
        """One criterion evaluation; returns False once the time limit is reached."""
        elapsed = self.bar.tick(cost=f"{cost:.6g}")
        return self.max_time is None or elapsed < self.max_time

    def close(self):
        self.bar.close()


def _max_root(theta, s):
    """Largest zero modulus of ``C``, ``D`` and the ``F_i`` (0 if none)."""
    _, _, C, D, F = split_theta(theta, s)
    radii = [np.abs(np.roots(p)).max() for p in [C, D, *F] if len(p) > 1]
    return float(max(radii, default=0.0))


def _pem_unit(records, s, theta0, rows, *, ftol, xtol, gtol, max_nfev, n_starts=1, rng=None,
              clock=None):
    """The search of `pem_records` on records already in unit size."""
    clock = _Clock(None, False, 0) if clock is None else clock

    def fun(theta):
        if not (np.isfinite(theta).all() and predictor_is_stable(theta, s)):
            return None, None
        parts = [prediction_error_parts(theta, s, U, y) for U, y in records]
        r = np.concatenate([p[0][s.t0:] for p in parts])
        return (r, parts) if np.isfinite(r).all() else (None, None)

    def jac(theta, parts):
        return -stacked_gradient(theta, s, records, parts)

    def cost_of(theta):
        r, _ = fun(theta)
        return np.inf if r is None else 0.5 * float(r @ r)

    # the starts see only the experiments with rows in the criterion (a shorter one would
    # only add a seam, and move the start to another minimum: the fit would depend on it)
    U_all, y_all = joined([r for r in records if len(r[1]) > s.t0])
    # the starts: the given one, or the lowest criterion of the consistent ones
    arx_theta, arx_exact = (None, False) if s.is_arx else arx_in_structure(U_all, y_all, s)
    arx_cost = cost_of(arx_theta) if arx_exact else None
    if theta0 is not None:
        starts = {"theta0": stabilize_theta(theta0, s)[0]}
    else:
        starts = {"iv" if any(s.nf) else "hannan-rissanen": initial_estimate(U_all, y_all, s)}
        if arx_theta is not None:
            starts["arx"] = arx_theta
        if not s.is_arx:
            reduced = arx_reduced(U_all, y_all, s)
            if reduced is not None:
                starts["arx-reduced"] = reduced
    start_costs = {k: cost_of(v) for k, v in starts.items()}
    name = min(start_costs, key=lambda k: (start_costs[k], list(starts).index(k)))
    theta_start = starts[name]
    r0, parts0 = fun(theta_start)
    J = jac(theta_start, parts0) if r0 is not None else np.full((rows, s.n_params), np.nan)
    rank = _column_rank(J) if np.isfinite(J).all() else 0
    if rank < s.n_params:
        raise ValueError(
            f"the gradient of the predictor has rank {rank} < n_params = {s.n_params}: "
            "the input is not persistently exciting for these orders (or the orders "
            "are too high); use a richer input, more data or lower orders")
    if s.is_arx:
        theta = theta_start - np.linalg.lstsq(J, r0, rcond=None)[0]
        res = _SearchResult(theta, 1, 1, 0, 1, "linear least squares (ARX structure): "
                            "solved exactly", True)
    else:
        res = _levenberg_marquardt(fun, jac, theta_start, (r0, parts0, J), s, ftol=ftol,
                                   xtol=xtol, gtol=gtol, max_nfev=max_nfev, clock=clock)
        res.start = name
        gen = np.random.default_rng(rng)
        for k in range(1, n_starts):
            if res.status == _TIMEOUT:
                break
            th = random_start(U_all, y_all, s, theta_start, gen)
            r, parts = fun(th)
            if r is None:
                continue
            other = _levenberg_marquardt(fun, jac, th, (r, parts, jac(th, parts)), s,
                                         ftol=ftol,
                                         xtol=xtol, gtol=gtol, max_nfev=max_nfev, clock=clock)
            other.start = f"random {k}"
            if other.cost < res.cost:
                other.n_fev += res.n_fev
                other.n_jev += res.n_jev
                res = other
            else:
                res.n_fev += other.n_fev
                res.n_jev += other.n_jev
    theta = res.theta
    r, parts = fun(theta)
    eps = np.concatenate([p[0] for p in parts])
    J = jac(theta, parts)
    cost = 0.5 * float(r @ r)
    sigma2 = 2.0 * cost / (rows - s.n_params)
    cov = sigma2 * _inverse_normal_matrix(J)
    max_root = _max_root(theta, s)
    messages = []
    if not s.is_arx:
        if max_root > 1.0 - BOUNDARY_TOL:
            messages.append(
                f"the prediction-error fit ended on the stability boundary: a zero of F, C or "
                f"D has modulus {max_root:.8f} > 1 - {BOUNDARY_TOL:g}; the criterion probably "
                f"has a better minimum inside (try n_starts=10, other orders, or detrend the "
                f"data)")
        if res.status in (_MAX_NFEV, _TIMEOUT):
            what = "max_nfev" if res.status == _MAX_NFEV else "max_time"
            messages.append(f"the prediction-error fit stopped at its limit {what} before "
                            f"converging ({res.message}); raise `{what}` or start from this "
                            f"model with init_model=")
        if arx_cost is not None and cost > arx_cost * (1.0 + 1e-8):
            messages.append(f"the prediction-error fit ended with a criterion "
                            f"{cost / arx_cost:.4g} times that of the least-squares ARX of "
                            f"the same orders: it stopped in a poor local minimum; try "
                            f"n_starts=10 or the default start")
    return PEMFit(theta=theta, cov=cov, noise_variance=sigma2, eps=eps, residuals=r, cost=cost,
                  theta0=theta_start, n_fev=res.n_fev, n_jev=res.n_jev, n_iter=res.n_iter,
                  status=res.status, message=res.message, converged=res.converged,
                  start=getattr(res, "start", name), max_root=max_root, arx_cost=arx_cost,
                  warnings=messages, start_costs=start_costs)


_EPS = np.finfo(float).eps

#: Largest number of undamped steps that finish a converged search, and the largest
#: relative rise of the criterion they may make (far below any statistical meaning).
_POLISH_STEPS = 10
_POLISH_RISE = 1e-10

# status codes of the search (those of scipy's least_squares where they exist)
_MAX_NFEV, _GTOL, _FTOL, _XTOL, _NO_DESCENT, _TIMEOUT = 0, 1, 2, 3, 4, -2


def _stop_reason(small_f):
    """Status and message of a converged search: ``small_f`` True (``ftol``), False
    (``xtol``) or None (``gtol``)."""
    if small_f is None:
        return _GTOL, "`gtol` termination condition is satisfied."
    if small_f:
        return _FTOL, "`ftol` termination condition is satisfied."
    return _XTOL, "`xtol` termination condition is satisfied."


class _SearchResult:
    def __init__(self, theta, n_fev, n_jev, n_iter, status, message, converged, cost=np.nan):
        self.theta, self.n_fev, self.n_jev, self.n_iter = theta, n_fev, n_jev, n_iter
        self.status, self.message, self.converged, self.cost = status, message, converged, cost


def _levenberg_marquardt(fun, jac, theta, first, s, *, ftol, xtol, gtol, max_nfev, clock):
    r"""Damped Gauss-Newton (Levenberg-Marquardt) search with stability by reflection.

    At :math:`\theta` with errors :math:`r` and Jacobian :math:`J`, the step
    solves :math:`\min_p \|J p + r\|^2 + \lambda \|D p\|^2` (``D`` the running
    largest column norms of ``J``, Moré's scaling) through the QR factors of
    ``J``, computed once per iteration. A trial :math:`\theta + p` whose
    ``F_i``, ``C`` or ``D`` left the unit circle has those zeros reflected
    inside (`stabilize_theta`, as MATLAB's ``pem``) instead of being
    rejected, so the search is not stopped at the boundary; a trial is
    accepted when it lowers the criterion, and :math:`\lambda` follows
    Nielsen's gain-ratio rule (Madsen, Nielsen & Tingleff 2004).
    """
    from scipy.linalg import qr, solve_triangular

    r, parts, J = first
    cost = 0.5 * float(r @ r)
    n_fev, n_jev, n_iter = 1, 1, 0
    d = np.linalg.norm(J, axis=0)
    d[d == 0] = 1.0
    lam, nu, lam_kept = 1e-3, 2.0, 1e-3
    polish = None
    status, message = None, ""
    if not clock.tick(cost):
        status = _TIMEOUT
    while status is None:
        n_iter += 1
        in_time = True
        d = np.maximum(d, np.linalg.norm(J, axis=0))
        g = J.T @ r
        rn = np.sqrt(2.0 * cost)
        if rn == 0.0:
            status, message = _stop_reason(None)
            break
        if polish is None and np.max(np.abs(g) / (d * rn)) <= gtol:
            polish, lam_kept = [None, 0, None], lam     # finish with undamped steps (below)
            lam = 0.0
        Q, R = qr(np.asfortranarray(J), mode="economic", check_finite=False)
        qtr = Q.T @ r
        rest = max(float(r @ r) - float(qtr @ qtr), 0.0)
        while True:
            if n_fev >= max_nfev:
                status, message = _MAX_NFEV, (f"the number of criterion evaluations reached "
                                              f"max_nfev = {max_nfev}")
                break
            M = np.vstack([R, np.sqrt(lam) * np.diag(d)])
            Qm, Rm = np.linalg.qr(M)
            p = -solve_triangular(Rm, Qm[:len(R)].T @ qtr, check_finite=False)
            pred = 0.5 * (float(r @ r) - float(np.sum((R @ p + qtr) ** 2)) - rest)
            trial, reflected = stabilize_theta(theta + p, s)
            r_t, parts_t = fun(trial)
            n_fev += 1
            cost_t = np.inf if r_t is None else 0.5 * float(r_t @ r_t)
            in_time = clock.tick(min(cost, cost_t))
            step = np.linalg.norm(trial - theta)
            if polish is None:
                accept = cost_t < cost
            else:
                # undamped steps while they shrink (a Gauss-Newton iteration to the
                # stationary point: near it the criterion changes below its round-off,
                # so it cannot judge the steps; a guard against a step that leaves it)
                accept = (not reflected and cost_t <= cost * (1.0 + _POLISH_RISE)
                          and (polish[2] is None or step < 0.5 * polish[2]))
            if accept:
                rho = (cost - cost_t) / pred if pred > 0 and not reflected else 0.5
                lam = (lam if lam > 0 else lam_kept) * max(1.0 / 3.0,
                                                           1.0 - (2.0 * rho - 1.0) ** 3)
                nu = 2.0
                small_f = cost - cost_t <= ftol * cost
                small_x = step <= xtol * (xtol + np.linalg.norm(theta))
                theta, r, parts, cost = trial, r_t, parts_t, cost_t
                J = jac(theta, parts)
                n_jev += 1
                if polish is None and (small_f or small_x):
                    # converged to the tolerance: finish with undamped (Gauss-Newton)
                    # steps while they shrink, so that the estimate is the minimizer
                    # to round-off, not to sqrt(ftol)
                    polish, lam_kept = [small_f, 0, None], lam
                    lam = 0.0
                elif polish is not None:
                    polish[1] += 1
                    polish[2] = step
                    if (step <= 4.0 * _EPS * np.linalg.norm(theta)
                            or polish[1] >= _POLISH_STEPS):
                        status, message = _stop_reason(polish[0])
                break
            if polish is not None:        # the undamped step failed: stop where we are
                status, message = _stop_reason(polish[0])
                break
            lam = lam * nu if lam > 0 else lam_kept * nu
            nu *= 2.0
            if np.linalg.norm(p) <= xtol * (xtol + np.linalg.norm(theta)):
                status, message = _XTOL, "`xtol` termination condition is satisfied."
                break
            if lam > 1e20:
                status, message = _NO_DESCENT, "no step lowers the criterion (a minimum)"
                break
            if not in_time:
                break
        if status is None and not in_time:
            status, message = _TIMEOUT, "the time limit max_time was reached"
    converged = status in (_GTOL, _FTOL, _XTOL, _NO_DESCENT)
    return _SearchResult(theta, n_fev, n_jev, n_iter, status, message, converged, cost)


def _inverse_normal_matrix(J):
    r""":math:`(J^T J)^{-1}` through the SVD of `J` (never forming :math:`J^TJ`)."""
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    tiny = sv[0] * max(J.shape) * np.finfo(float).eps if len(sv) else 0.0
    inv = np.where(sv > tiny, 1.0 / np.where(sv > tiny, sv, 1.0) ** 2, np.inf)
    cov = (Vt.T * inv) @ Vt
    return 0.5 * (cov + cov.T)
