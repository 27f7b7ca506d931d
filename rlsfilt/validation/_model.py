"""What the validation functions need from a fitted model.

Everything goes through the public ARX interface (``regressors``,
``theta_``, ``na``/``nb``/``nk``, ``to_tf``), so any model with that
interface can be validated.
"""

import numpy as np

from ..exceptions import NotFittedError

__all__ = []


def check_fitted(model, name="model"):
    """Raise `NotFittedError` (or `TypeError`) unless `model` is a fitted ARX-like model."""
    for attr in ("regressors", "to_tf"):
        if not callable(getattr(model, attr, None)):
            raise TypeError(f"`{name}` must be a fitted ARX model (with `regressors` and "
                            f"`to_tf`); got {type(model).__name__}")
    if getattr(model, "theta_", None) is None:
        raise NotFittedError(f"this {type(model).__name__} is not fitted yet; call "
                             "`fit(u, y)` before validating it")


def one_step(model, u, y):
    """Regressors, targets and one-step residuals of `model` on ``(u, y)``.

    Returns ``(Phi, target, residuals)`` with rows ``t = t0 .. N-1``;
    `target` and `residuals` are 2-D ``(n, ny)``.
    """
    check_fitted(model)
    Phi, target = model.regressors(u, y)
    target = np.asarray(target, dtype=float)
    if target.ndim == 1:
        target = target[:, None]
    theta = np.asarray(model.theta_, dtype=float)
    if theta.ndim == 1:
        theta = theta[:, None]
    if Phi.shape[1] != theta.shape[0] or target.shape[1] != theta.shape[1]:
        nu, ny = getattr(model, "n_inputs_", "?"), getattr(model, "n_outputs_", theta.shape[1])
        raise ValueError(f"`u` and `y` must have the {nu} input and {ny} output column(s) the "
                         f"model was fitted with; got `u` of shape {np.shape(u)} and `y` of "
                         f"shape {np.shape(y)}")
    return Phi, target, target - Phi @ theta


def orders(model):
    """``(na, nb tuple, nk tuple)`` of `model`: the fitted structure when known
    (constructor parameters may have been changed by ``set_params`` since)."""
    s = getattr(model, "structure_", None)
    if s is not None:
        return s.na, tuple(s.nb), tuple(s.nk)
    na = int(model.na)
    nb = np.atleast_1d(np.asarray(model.nb, dtype=int))
    nk = np.atleast_1d(np.asarray(model.nk, dtype=int))
    if nk.size == 1 and nb.size > 1:
        nk = np.repeat(nk, nb.size)
    if nb.size == 1 and nk.size > 1:
        nb = np.repeat(nb, nk.size)
    return na, tuple(int(b) for b in nb), tuple(int(k) for k in nk)


def n_params(model):
    """Total number of estimated parameters (all outputs)."""
    return int(np.asarray(model.theta_).size)
