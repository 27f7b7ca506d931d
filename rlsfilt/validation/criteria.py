r"""Information criteria for comparing model structures.

All criteria are computed from the loss function

.. math::

    V = \det\Big(\frac{1}{N} \sum_{t} \varepsilon(t)\,\varepsilon(t)^T\Big)

of the one-step prediction errors :math:`\varepsilon(t)` (for one output,
the mean squared residual), the number :math:`N` of residuals and the number
:math:`d` of estimated parameters, with the definitions of MATLAB's System
Identification Toolbox (``aic``, ``fpe``, ``selstruc``) and Ljung (1999,
sec. 16.4), so numbers carry over from MATLAB directly.
"""

import math

import numpy as np

from .._scale import pow2_scale
from .._validation import check_int, check_scalar
from ..exceptions import ExactFitError
from ._model import n_params, one_step_records

__all__ = ["InformationCriteria", "criteria_from_loss", "information_criteria"]

_LOG_2PI = math.log(2.0 * math.pi)


class InformationCriteria:
    """Information criteria of one model on one record (smaller is better).

    Attributes
    ----------
    loss : float
        :math:`V`, the (determinant of the) residual covariance, ``1/N sum e^2``.
    n_samples : int
        :math:`N`, the number of residuals.
    n_params : int
        :math:`d`, the number of estimated parameters.
    n_outputs : int
        Number of outputs :math:`n_y`.
    aic, aicc, bic : float
        Raw Akaike, small-sample corrected Akaike and Bayesian criteria
        (MATLAB's ``aic(sys, 'aic' | 'AICc' | 'BIC')``).
    naic : float
        Normalized AIC, ``log V + 2 d / N`` (MATLAB's default ``aic(sys)``).
    fpe : float
        Akaike's final prediction error.
    mdl : float
        Rissanen's minimum description length in the form of ``selstruc``.
    """

    _FIELDS = ("loss", "n_samples", "n_params", "n_outputs", "aic", "aicc", "bic", "naic",
               "fpe", "mdl")

    def __init__(self, **values):
        for name in self._FIELDS:
            setattr(self, name, values[name])

    def as_dict(self):
        """The criteria as a plain dict (field name to value)."""
        return {name: getattr(self, name) for name in self._FIELDS}

    def __repr__(self):
        return ("InformationCriteria(" + ", ".join(
            f"{k}={v:.6g}" if isinstance(v, float) else f"{k}={v}"
            for k, v in self.as_dict().items()) + ")")


def criteria_from_loss(loss, n_samples, n_params, n_outputs=1):
    r"""Information criteria from a loss, a sample size and a parameter count.

    Parameters
    ----------
    loss : float
        :math:`V > 0`: the mean squared one-step residual (for several
        outputs, the determinant of the residual covariance).
    n_samples : int
        :math:`N`, the number of residuals behind `loss`.
    n_params : int
        :math:`d`, the number of estimated parameters.
    n_outputs : int, default 1
        :math:`n_y`.

    Returns
    -------
    InformationCriteria

    Notes
    -----
    With :math:`c = N n_y (\log 2\pi + 1)` the constant of the Gaussian
    log-likelihood, :math:`-2 \log L = N \log V + c`:

    .. math::

        \mathrm{AIC} &= N \log V + 2 d + c
            &&\text{(Akaike 1974)} \\
        \mathrm{AIC_c} &= \mathrm{AIC} + \frac{2 d (d + 1)}{N - d - 1}
            &&\text{(Hurvich \& Tsai 1989)} \\
        \mathrm{BIC} &= N \log V + d \log N + c
            &&\text{(Schwarz 1978)} \\
        \mathrm{nAIC} &= \log V + 2 d / N
            &&\text{(Ljung 1999, sec. 16.4)} \\
        \mathrm{FPE} &= V \frac{1 + d/N}{1 - d/N}
            &&\text{(Akaike 1969)} \\
        \mathrm{MDL} &= V \left(1 + \frac{d \log N}{N}\right)
            &&\text{(Rissanen 1978)}

    These are the definitions of MATLAB's ``aic``, ``fpe`` and
    ``selstruc``: for MATLAB's documented ``aic`` example (``V = 1.6575``,
    ``N = 300``, ``d = 6``) they reproduce its printed AIC 1.0150e+03,
    AICc 1.0153e+03, BIC 1.0372e+03, nAIC 0.5453 and FPE 1.7252 to the
    rounding of the printed ``V``. AICc and FPE are
    infinite when :math:`N \le d + 1` (respectively :math:`N \le d`).

    References
    ----------
    .. [1] H. Akaike, "Fitting autoregressive models for prediction", *Ann.
       Inst. Stat. Math.* 21, 243-247, 1969.
    .. [2] H. Akaike, "A new look at the statistical model identification",
       *IEEE Trans. Autom. Control* 19(6), 716-723, 1974.
    .. [3] G. Schwarz, "Estimating the dimension of a model", *Ann. Stat.*
       6(2), 461-464, 1978.
    .. [4] J. Rissanen, "Modeling by shortest data description",
       *Automatica* 14(5), 465-471, 1978.
    .. [5] C. M. Hurvich and C.-L. Tsai, "Regression and time series model
       selection in small samples", *Biometrika* 76(2), 297-307, 1989.
    .. [6] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 16.4.

    Examples
    --------
    >>> from rlsfilt.validation import criteria_from_loss
    >>> ic = criteria_from_loss(1.6575, n_samples=300, n_params=6)
    >>> round(ic.aic, 1), round(ic.fpe, 4)
    (1015.0, 1.7252)
    """
    V = check_scalar(loss, "loss")
    if not (np.isfinite(V) and V > 0.0):
        raise ValueError(f"`loss` must be a positive finite number; got {V}")
    N = check_int(n_samples, "n_samples", minimum=1)
    d = check_int(n_params, "n_params", minimum=0)
    ny = check_int(n_outputs, "n_outputs", minimum=1)
    return _criteria(V, N, d, ny)


def information_criteria(model, u, y=None):
    """Information criteria of a fitted model on a record.

    Parameters
    ----------
    model : IdentifiedModel
        A fitted model (`ARX` or any other `IdentifiedModel`).
    u : array_like, shape (N,) or (N, nu), or IOData
        Input record, or an `IOData` with inputs and outputs (then `y` is
        omitted). With several experiments the one-step residuals of every
        experiment count, each from its own start.
    y : array_like, shape (N,) or (N, ny)
        Output record. Pass the estimation data for the classical criteria;
        on fresh data they penalize a validation loss (as MATLAB's
        ``selstruc`` does on the losses of ``arxstruc`` with validation data).

    Returns
    -------
    InformationCriteria
        With :math:`V` the loss of the one-step residuals on the rows with a
        complete regressor, :math:`N` their number and :math:`d` the number
        of entries of ``model.theta_`` (all outputs together). See
        :func:`criteria_from_loss` for the formulas.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import ARX
    >>> from rlsfilt.validation import information_criteria
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(500)
    >>> y = np.zeros(500)
    >>> for t in range(1, 500):
    ...     y[t] = 0.8 * y[t - 1] + 0.5 * u[t - 1] + 0.1 * rng.standard_normal()
    >>> model = ARX(na=1, nb=1).fit(u, y)
    >>> ic = information_criteria(model, u, y)
    >>> ic.n_samples, ic.n_params
    (499, 2)
    """
    _, e, _ = one_step_records(model, u, y, "information_criteria")
    return _from_residuals(e, n_params(model))


def _from_residuals(e, d):
    r"""`information_criteria` from the one-step residuals `e` (N, ny) and `d` parameters.

    Each residual column is divided by a power of two ``t_j`` near its
    largest entry first (exact), so :math:`\log V = \log V_s + 2 \sum_j
    \log t_j` is finite for a record in any units, and so are AIC, BIC and
    nAIC; ``V`` itself (and FPE, MDL) is ``inf`` or 0 only where it is not
    representable.
    """
    N, ny = e.shape
    t = pow2_scale(e, axis=0)
    es = e / t
    cov = (es.T @ es) / N
    if ny > 1:
        sign, log_det = np.linalg.slogdet(cov)
        V_s = float(np.linalg.det(cov))
    else:
        V_s = float(cov[0, 0])
        sign, log_det = (1.0, math.log(V_s)) if V_s > 0.0 else (0.0, -np.inf)
    if not (sign > 0.0 and np.isfinite(log_det)):
        raise ExactFitError("the residuals are zero (an exact fit); information criteria are "
                         "undefined")
    with np.errstate(over="ignore", under="ignore"):
        V = V_s * float(np.prod(t * t))
    return _criteria(V, N, d, ny, log_loss=log_det + 2.0 * float(np.sum(np.log(t))))


def _criteria(V, N, d, ny=1, log_loss=None):
    r"""The formulas of `criteria_from_loss`, vectorized over numpy arrays.

    `log_loss` is :math:`\log V` when ``V`` itself may be out of range
    (computed from scaled residuals); by default ``log(V)``.
    """
    V = np.asarray(V, dtype=float)
    N = np.asarray(N, dtype=float)
    d = np.asarray(d, dtype=float)
    logV = np.log(V) if log_loss is None else np.asarray(log_loss, dtype=float)
    const = N * ny * (_LOG_2PI + 1.0)
    aic = N * logV + 2.0 * d + const
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        aicc = np.where(N - d - 1.0 > 0.0, aic + 2.0 * d * (d + 1.0) / (N - d - 1.0), np.inf)
        fpe = np.where(N - d > 0.0, V * (1.0 + d / N) / (1.0 - d / N), np.inf)
        mdl = V * (1.0 + d * np.log(N) / N)
    bic = N * logV + d * np.log(N) + const
    naic = logV + 2.0 * d / N
    if V.ndim == 0 and N.ndim == 0 and d.ndim == 0:
        return InformationCriteria(loss=float(V), n_samples=int(N), n_params=int(d),
                                   n_outputs=int(ny), aic=float(aic), aicc=float(aicc),
                                   bic=float(bic), naic=float(naic), fpe=float(fpe),
                                   mdl=float(mdl))
    return {"aic": aic, "aicc": aicc, "bic": bic, "naic": naic, "fpe": fpe, "mdl": mdl}
