r"""MATLAB's other online estimators for ARX: the gradient methods and finite history.

MATLAB's ``recursiveARX`` offers four ``EstimationMethod`` values
('ForgettingFactor' and 'KalmanFilter' are ``ARX.fit(method="rls")``) and a
``History = 'Finite'`` with a ``WindowLength``. This module runs the other
two and the window on the ARX regressor rows with the filters of
:mod:`rlsfilt.filters`, as ``ARX.fit`` and the streaming objects need them:

- `run_gradient`: ``method="nlms"`` ('NormalizedGradient', `NLMS`:
  :math:`\theta \leftarrow \theta + \mu \varphi^T e / (\epsilon + \varphi
  \varphi^T)`) or ``method="lms"`` ('Gradient', `LMS`: :math:`\theta
  \leftarrow \theta + \mu \varphi^T e`), from ``x0`` (zeros), in the
  signals' units (MATLAB's ``AdaptationGain`` is `mu`, its
  ``NormalizationBias`` `eps`). A gradient estimate has no covariance;
- `run_window`: `SlidingWindowRLS` over the last ``window`` rows, started by
  exact least squares on the first ``k0`` rows, so that the estimate after
  row ``t`` is least squares on rows ``max(0, t - window + 1) .. t``; run in
  the record's power-of-two units (`RecordUnits`) and mapped back exactly.

Both return the estimate, its history, the a-priori residuals and the filter
(``filter_``), and are what the fitted attributes of ``method="rls"`` are for
these methods.
"""

import inspect

import numpy as np

from .._validation import COVARIANCE_MAX, check_covariance, check_int
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


def run_window(Phi, target, window, k0, options, units):
    r"""`SlidingWindowRLS` of `window` rows over ``Phi`` (N, n), ``target`` (N, ny), from
    exact least squares on the first `k0` rows (``k0 = 0``: the prior ``x0``, ``P0``
    until the window first fills), in the scaled units of `units` (a `RecordUnits`).

    Returns ``(theta, C, c, history, prior, filt)``: the estimate, :math:`P / R = C /
    (c c^T)` (``c`` the powers of two of the columns), the estimate after each row
    (history NaN before row ``k0 - 1``), the a-priori residuals (NaN before row
    ``k0``), all but ``C`` in the signals' units, and the filter built from the
    user's options holding the final state in the signals' units.

    The window runs on the rows and targets divided by the powers of two of
    `units` (every column and output of unit size), from ``x0``, ``P0``, ``R``
    mapped exactly into those units (``R~ = 2^r R`` near 1), as `ARX.fit`'s
    recursion does (:mod:`rlsfilt.models._units`): the same least squares over
    each window in any units, in range for records around 1e+-160. A prior start
    whose ``P0`` the scaled units cannot hold (a NumericalWarning naming ``P0``)
    runs in the signals' units. The filter handed back (``filter_``) gets the
    final state mapped back exactly (``x``, ``P``, the window's rows, targets and
    variances, the last update's diagnostics): where ``P`` is beyond the double
    range in the signals' units (e.g. ``b`` coefficients of ``u`` around 1e-160),
    its entries are ``inf`` or underflow to subnormal numbers or zero, as the
    product in exact arithmetic would round; continuing that filter in the
    signals' units is then out of double precision's reach.
    """
    N, n = Phi.shape
    ny = target.shape[1]
    window = check_int(window, "window", minimum=n)
    if k0 > window:
        raise ValueError(f"`k0` must be <= `window` ({window}): the batch start's rows must "
                         f"fit in the window; got {k0}")
    user = SlidingWindowRLS(n, window, ny, **options)        # validates; becomes filter_
    units.check_ratio()
    r = units.r_for(user.R)
    P0 = check_covariance(options.get("P0", 1e4), n, "P0", definite=True)
    start = units.recursion_start(P0, user.R, r=r, prior=True,
                                  default_P0="P0" not in options, stacklevel=5) \
        if k0 == 0 else _batch_start(units, P0, user.R, r)
    if start is None:        # the signals' units (a prior the data cannot bear: warned)
        units = units.unscaled()
        r = 0
        start = {"P0": P0, "R": user.R}
    scaled_options = dict(options) | start
    scaled_options["x0"] = units.start_to_unit(user.x, "x0")
    filt = SlidingWindowRLS(n, window, ny, **scaled_options)
    Phi, target = units.scale_rows(Phi, target)
    history = np.full((N, n, ny), np.nan)
    prior = np.full((N, ny), np.nan)
    if k0:
        filt.initialize(target[:k0], Phi[:k0])
        history[k0 - 1] = filt.x
    if k0 < N:
        means, _, means_p, _ = filt.batch_filter(target[k0:], Phi[k0:], store_covariances=False)
        history[k0:] = means
        prior[k0:] = target[k0:] - np.einsum("ti,tij->tj", Phi[k0:], means_p)
    theta = units.estimate_from_unit(filt.x)
    units.theta_from_unit(history, out=history)
    units.output_from_unit(prior, out=prior)
    _hand_over_window(filt, user, theta, units, r)
    return theta, filt.P / filt.R, np.ldexp(1.0, units.column_exponents), history, prior, user


def _batch_start(units, P0, R, r):
    """``P0`` and ``R`` in the scaled units for a batch start (``k0 > 0``), where ``P0`` is
    only the prior of a window that stops determining the parameters: the user's
    mapped exactly where the scaled units hold it, else the default ``1e4 R~ I`` of the
    record scaled to unit size."""
    out = units.recursion_start(P0, R, r=r, prior=False)
    P = units.P_to_unit(P0, r=r)
    d = np.diagonal(P)
    if not (np.isfinite(P).all() and np.all(d >= np.finfo(float).tiny)
            and np.max(np.abs(P)) <= COVARIANCE_MAX):
        P = 1e4 * out["R"] * np.eye(len(P0))
    out["P0"] = P
    return out


def _hand_over_window(filt, user, theta, units, r):
    """Give `user` (built from the user's options) the final state of `filt`, which ran
    in the scaled units with ``R~ = 2^r R``, mapped exactly to the signals' units (see
    `run_window`): ``x`` (`theta`), ``P``, the window's rows, targets and variances,
    the counters and the last update's diagnostics."""
    state = filt.get_state()
    c, ey = units.column_exponents, units.output_exponents
    with np.errstate(over="ignore", under="ignore"):
        state["x"] = theta
        state["P"] = units.P_from_unit(state["P"], r=r)
        state["window_H"] = np.ldexp(state["window_H"], c[None, :])
        state["window_z"] = np.ldexp(state["window_z"], ey[None, :])
        state["window_R"] = np.ldexp(state["window_R"], -r)
        user.set_state(state)
        maps = units.diagnostics_from_unit(r)
        user.set_diagnostics(**{name: f(getattr(filt, name)) for name, f in maps.items()
                                if getattr(filt, name, None) is not None})
