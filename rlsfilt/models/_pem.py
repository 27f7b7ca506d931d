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

`pem` minimizes :math:`V` by ``scipy.optimize.least_squares`` (trust-region
reflective) with this analytic Jacobian, from the consistent start of
:mod:`rlsfilt.models._initial`. ``C``, ``D`` and ``F_i`` are kept stable: the
start is reflected into the unit circle, and a trial step that leaves the
stability region gets non-finite residuals, which makes the trust region
shrink, so every iterate has a stable predictor. The covariance is
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
"""

import numpy as np

from .._lazy_scipy import least_squares, lfilter
from ._family import split_theta
from ._initial import initial_estimate
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


def pem(U, y, s, theta0=None, *, ftol=1e-12, xtol=1e-12, gtol=1e-12, max_nfev=None):
    r"""Batch prediction-error estimate of the general family.

    Parameters
    ----------
    U : ndarray, shape (N, nu)
        Inputs (``nu = 0``: a time series).
    y : ndarray, shape (N,)
    s : FamilyStructure
    theta0 : ndarray, optional
        Start (reflected into the stability region if needed); the
        consistent start of `initial_estimate` by default.
    ftol, xtol, gtol : float, default 1e-12
        Tolerances of ``scipy.optimize.least_squares``.
    max_nfev : int, optional
        Largest number of residual evaluations (default ``100 n_params``,
        at least 200).

    Returns
    -------
    PEMFit

    Raises
    ------
    ValueError
        When there are no spare equations (``N - t0 <= n_params``), or
        when the gradient of the predictor at the start has deficient rank
        (the input is not persistently exciting for these orders).

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
    return pem_records([(U, y)], s, theta0, ftol=ftol, xtol=xtol, gtol=gtol,
                       max_nfev=max_nfev)


def pem_records(records, s, theta0=None, *, ftol=1e-12, xtol=1e-12, gtol=1e-12,
                max_nfev=None):
    r"""`pem` over several experiments: the summed criterion
    :math:`\frac12\sum_i\sum_{t \ge t_0} \varepsilon_i(t, \theta)^2`, each
    experiment's predictor started from rest.

    Parameters
    ----------
    records : list of (ndarray (N_i, nu), ndarray (N_i,))
        The experiments.
    s, theta0, ftol, xtol, gtol, max_nfev
        As `pem`; the default start is computed on the experiments joined
        end to end (only the start: the seams perturb it slightly, never the
        criterion).

    Returns
    -------
    PEMFit
        In the units of `records` (the search itself runs in the scaled
        units of `RecordUnits`).

    Raises
    ------
    ValueError
        As `pem`.
    """
    N = sum(len(y) for _, y in records)
    rows = criterion_rows(s, records)
    if rows <= s.n_params:
        per = " in all" if len(records) > 1 else ""
        raise ValueError(f"`y` must have more than t0 + n_params = {s.t0} + {s.n_params} = "
                         f"{s.t0 + s.n_params} samples{per} for this structure; got {N}")
    units = RecordUnits(records, s)
    scaled = units.scale_records(records)
    if theta0 is None:
        theta0 = initial_estimate(*joined(scaled), s)
    else:
        theta0 = units.start_to_unit(np.asarray(theta0, dtype=float), "theta0")
    theta0, _ = stabilize_theta(theta0, s)
    J = stacked_gradient(theta0, s, scaled)
    rank = _column_rank(J) if np.isfinite(J).all() else 0
    if rank < s.n_params:
        raise ValueError(
            f"the gradient of the predictor has rank {rank} < n_params = {s.n_params}: "
            "the input is not persistently exciting for these orders (or the orders "
            "are too high); use a richer input, more data or lower orders")
    fit = _pem_unit(scaled, s, theta0, rows, ftol=ftol, xtol=xtol, gtol=gtol,
                    max_nfev=max_nfev)
    theta = units.estimate_from_unit(fit.theta)   # a clear error if b is not a double
    return PEMFit(theta=theta, cov=units.cov_from_unit(fit.cov),
                  noise_variance=float(units.output_from_unit(fit.noise_variance, 2)),
                  eps=units.output_from_unit(fit.eps),
                  residuals=units.output_from_unit(fit.residuals),
                  cost=float(units.output_from_unit(fit.cost, 2)),
                  theta0=units.theta_from_unit(fit.theta0), n_fev=fit.n_fev, n_jev=fit.n_jev,
                  status=fit.status, message=fit.message)


def _pem_unit(records, s, theta0, rows, *, ftol, xtol, gtol, max_nfev):
    """The search of `pem_records` on records already in unit size, from a stable `theta0`."""
    cache = {}

    def parts(theta):
        key = theta.tobytes()
        if cache.get("key") != key:
            cache.clear()
            cache["key"] = key
            cache["parts"] = ([prediction_error_parts(theta, s, U, y) for U, y in records]
                              if predictor_is_stable(theta, s) else None)
        return cache["parts"]

    def fun(theta):
        p = parts(theta)
        if p is None:                 # outside the stability region: reject the step
            return np.full(rows, np.nan)
        return np.concatenate([pk[0][s.t0:] for pk in p])

    def jac(theta):
        return -stacked_gradient(theta, s, records, parts(theta))

    if s.is_arx:
        theta, res = _linear_least_squares(theta0, fun, jac)
    else:
        max_nfev = max(200, 100 * s.n_params) if max_nfev is None else max_nfev
        res = least_squares(fun, theta0, jac=jac, method="trf", x_scale="jac", ftol=ftol,
                            xtol=xtol, gtol=gtol, max_nfev=max_nfev)
        theta = res.x
    eps = np.concatenate([pk[0] for pk in parts(theta)])
    J = jac(theta)
    r = fun(theta)
    cost = 0.5 * float(r @ r)
    sigma2 = 2.0 * cost / (rows - s.n_params)
    cov = sigma2 * _inverse_normal_matrix(J)
    return PEMFit(theta=theta, cov=cov, noise_variance=sigma2, eps=eps, residuals=r, cost=cost,
                  theta0=theta0, n_fev=int(res.nfev), n_jev=int(res.njev or 0),
                  status=int(res.status), message=str(res.message))


class _LinearResult:
    nfev = 1
    njev = 1
    status = 1
    message = "linear least squares (ARX structure): solved exactly"


def _linear_least_squares(theta0, fun, jac):
    """An ARX structure: the criterion is quadratic; one Gauss-Newton step is exact."""
    r = fun(theta0)
    J = jac(theta0)
    step = np.linalg.lstsq(J, -r, rcond=None)[0]
    return theta0 + step, _LinearResult()


def _inverse_normal_matrix(J):
    r""":math:`(J^T J)^{-1}` through the SVD of `J` (never forming :math:`J^TJ`)."""
    _, sv, Vt = np.linalg.svd(J, full_matrices=False)
    tiny = sv[0] * max(J.shape) * np.finfo(float).eps if len(sv) else 0.0
    inv = np.where(sv > tiny, 1.0 / np.where(sv > tiny, sv, 1.0) ** 2, np.inf)
    cov = (Vt.T * inv) @ Vt
    return 0.5 * (cov + cov.T)
