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


def n_params(model):
    """Total number of estimated parameters (all outputs)."""
    return int(np.asarray(model.theta_).size)


def model_name(model):
    """``ARX(na=2, nb=2, nk=1)``: the class and its constructor parameters but ``dt``."""
    args = ", ".join(f"{k}={v!r}" for k, v in model._display_params().items() if k != "dt")
    return f"{type(model).__name__}({args})"
