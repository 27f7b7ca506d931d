"""What the validation functions take from a fitted model.

Only the declared interface, :class:`rlsfilt.models.IdentifiedModel`:
``regressors`` and ``theta_`` (the one-step predictor in regression form),
``param_names_``, ``theta_cov_``, ``n_samples_``, ``simulate``, ``predict``,
``polydata``/``frequency_response``/``to_tf`` and ``dt``. A new model class
is validated with no change here.
"""

import numpy as np

from ..models._base import check_is_fitted

__all__ = []


def one_step(model, u, y, what="validate"):
    """Regressors, targets and one-step residuals of `model` on ``(u, y)``.

    Returns ``(Phi, target, residuals)`` with rows ``t = max_lag .. N-1``;
    `target` and `residuals` are 2-D ``(n, ny)``.
    """
    check_is_fitted(model, what)
    Phi, target = model.regressors(u, y)
    target = np.asarray(target, dtype=float)
    if target.ndim == 1:
        target = target[:, None]
    theta = np.asarray(model.theta_, dtype=float)
    if theta.ndim == 1:
        theta = theta[:, None]
    if Phi.shape[1] != theta.shape[0] or target.shape[1] != theta.shape[1]:
        raise ValueError(f"`u` and `y` must have the {model.n_inputs_} input and "
                         f"{model.n_outputs_} output column(s) the model was fitted with; got "
                         f"`u` of shape {np.shape(u)} and `y` of shape {np.shape(y)}")
    return Phi, target, target - Phi @ theta


def one_step_records(model, u, y=None, what="validate"):
    """`one_step` over every experiment of a record (``(u, y)``, lists of arrays, or an
    `IOData` with ``y=None``).

    Returns ``(Phi, residuals, U)``: the regressors and residuals of every experiment
    stacked (rows never straddle a seam), and the inputs aligned with them across seams
    (each later experiment without its first ``max_lag`` samples, so that the input
    lags of the residual tests pair samples one after the other as the residuals do).
    A single experiment given as arrays is passed on as given (1-D stays 1-D).
    """
    from ..models.regressors import as_records

    if u is None and y is not None:   # a time series (AR, ARMA): no input to align
        Phi, _, E = one_step(model, None, y, what)
        return Phi, E, None
    records, info = as_records(u, y)
    if info["n_experiments"] == 1 and y is not None:
        Phi, _, E = one_step(model, u, y, what)
        return Phi, E, u
    Phis, Es, glued = [], [], []
    for k, (U, Y) in enumerate(records):
        Phi_k, _, E_k = one_step(model, U if U.shape[1] > 1 else U[:, 0],
                                 Y if Y.shape[1] > 1 else Y[:, 0], what)
        Phis.append(Phi_k)
        Es.append(E_k)
        glued.append(U if k == 0 else U[len(U) - len(E_k):])
    U = np.vstack(glued)
    return np.vstack(Phis), np.vstack(Es), U if U.shape[1] > 1 else U[:, 0]


def n_params(model):
    """Total number of estimated parameters (all outputs)."""
    return int(np.asarray(model.theta_).size)


def model_name(model):
    """``ARX(na=2, nb=2, nk=1)``: the class and its constructor parameters but ``dt``."""
    args = ", ".join(f"{k}={v!r}" for k, v in model._display_params().items() if k != "dt")
    return f"{type(model).__name__}({args})"
