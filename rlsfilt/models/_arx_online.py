r"""MATLAB's other online estimators for ARX: the gradient methods and finite history.

MATLAB's ``recursiveARX`` offers four ``EstimationMethod`` values
('ForgettingFactor' and 'KalmanFilter' are ``ARX.fit(method="rls")``) and a
``History = 'Finite'`` with a ``WindowLength``. This module runs the other
two and the window on the ARX regressor rows with the filters of
:mod:`rlsfilt.filters`, as ``ARX.fit`` and the streaming objects need them:

- `fit_gradient`: ``method="nlms"`` ('NormalizedGradient', `NLMS`:
  :math:`\theta \leftarrow \theta + \mu \varphi^T e / (\epsilon + \varphi
  \varphi^T)`) or ``method="lms"`` ('Gradient', `LMS`: :math:`\theta
  \leftarrow \theta + \mu \varphi^T e`), from ``x0`` (zeros), in the
  signals' units (MATLAB's ``AdaptationGain`` is `mu`, its
  ``NormalizationBias`` `eps`). A gradient estimate has no covariance;
- `fit_window`: `SlidingWindowRLS` over the last ``window`` rows, started by
  exact least squares on the first ``k0`` rows, so that the estimate after
  row ``t`` is least squares on rows ``max(0, t - window + 1) .. t``.

Both return the estimate, its history, the a-priori residuals and the filter
(``filter_``), and are what the fitted attributes of ``method="rls"`` are for
these methods.
"""

import inspect

import numpy as np

from .._validation import check_int
from ..filters import LMS, NLMS, SlidingWindowRLS

__all__ = []

#: ``ARX.fit`` methods run by a gradient filter, and its class.
GRADIENT = {"nlms": NLMS, "lms": LMS}
#: Options of the window fit (beyond ``k0``): those `SlidingWindowRLS` takes.
WINDOW_OPTIONS = ("P0", "R", "x0", "refresh", "check_every", "cond_max")


def gradient_options(method, options):
    """The keyword options of a gradient `method` (``mu``, ``leak``, and ``eps`` for
    ``"nlms"``), checked by name: anything else is a TypeError naming it and the
    valid ones."""
    valid = [name for name, p in inspect.signature(GRADIENT[method]).parameters.items()
             if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
             and name not in ("dim_x", "dim_z", "R")]
    for name in options:
        if name not in valid:
            raise TypeError(f"`{name}` is not an option of method={method!r}; its options "
                            f"are {valid}")
    return dict(options)


def run_gradient(Phi, target, method, options):
    """Run the gradient filter of `method` over the rows ``Phi`` (N, n), ``target`` (N, ny).

    Returns ``(theta, history, prior, filt)``: the final estimate (n, ny), the
    estimate after each row (N, n, ny), the a-priori residuals ``y(t) - phi(t)
    theta(t-1)`` (N, ny) and the filter after the last row.
    """
    n, ny = Phi.shape[1], target.shape[1]
    filt = GRADIENT[method](n, ny, **options)
    means, _, means_p, _ = filt.batch_filter(target, Phi)
    prior = target - np.einsum("ti,tij->tj", Phi, means_p)       # y(t) - phi(t) theta(t-1)
    return filt.x.copy(), means, prior, filt


def run_window(Phi, target, window, k0, options):
    """`SlidingWindowRLS` of `window` rows over ``Phi`` (N, n), ``target`` (N, ny), from
    exact least squares on the first `k0` rows (``k0 = 0``: the prior ``x0``, ``P0``
    until the window first fills).

    Returns ``(theta, P / R, history, prior, filt)`` as `run_gradient` (history NaN
    before row ``k0 - 1``, prior NaN before row ``k0``).
    """
    N, n = Phi.shape
    ny = target.shape[1]
    window = check_int(window, "window", minimum=n)
    if k0 > window:
        raise ValueError(f"`k0` must be <= `window` ({window}): the batch start's rows must "
                         f"fit in the window; got {k0}")
    filt = SlidingWindowRLS(n, window, ny, **options)
    history = np.full((N, n, ny), np.nan)
    prior = np.full((N, ny), np.nan)
    if k0:
        filt.initialize(target[:k0], Phi[:k0])
        history[k0 - 1] = filt.x
    if k0 < N:
        means, _, means_p, _ = filt.batch_filter(target[k0:], Phi[k0:], store_covariances=False)
        history[k0:] = means
        prior[k0:] = target[k0:] - np.einsum("ti,tij->tj", Phi[k0:], means_p)
    return filt.x.copy(), filt.P / filt.R, history, prior, filt
