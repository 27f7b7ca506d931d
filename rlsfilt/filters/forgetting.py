r"""Forgetting modes of recursive least squares: names, codes and constants.

Plain exponential forgetting (``P <- P / lam`` in every step) winds up: when
the regressor stops exciting some direction, nothing ever shrinks ``P`` in
that direction again and it grows like ``lam**-k`` (covariance windup).
Diagonal forgetting (``P <- L^-1/2 P L^-1/2``, ``L = diag(lam)``: a factor per
parameter) forgets in the time update too, and shares the exponential mode's
windup cap (`TIME_UPDATE_MODES`). The other modes bound ``P`` by forgetting
only what new data replaces; they forget inside the measurement update,
because they need the step's regressor or residual.

This module is the one home of the modes' configuration: their names
(:data:`MODES`), the integer codes the compiled kernels dispatch on, the
validation and defaults of ``forgetting_params``, EFRA's invariant interval,
and the layout of the configuration array the kernels receive
(:func:`kernel_config`). The arithmetic of each mode is written once as
NumPy in ``tests/_reference.py`` (``update_<mode>``, the
textbook) and once compiled in :mod:`rlsfilt.filters._kernels`
(``measurement_update``, the production path); the tests hold the two equal
step by step.

References
----------
.. [1] R. Kulhavy and M. Karny, "Tracking of slowly varying parameters by
   directional forgetting", *Proc. 9th IFAC World Congress*, Budapest, 1984.
.. [2] S. Bittanti, P. Bolzern and M. Campi, "Convergence and exponential
   convergence of identification algorithms with directional forgetting
   factor", *Automatica* 26(5), 929-932, 1990.
.. [3] G. C. Goodwin and K. S. Sin, *Adaptive Filtering, Prediction and
   Control*, Prentice Hall, 1984, sec. 3.6.
.. [4] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
   Addison-Wesley, 1995, sec. 11.5 (constant-trace algorithm).
.. [5] M. E. Salgado, G. C. Goodwin and R. H. Middleton, "Modified least
   squares algorithm incorporating exponential resetting and forgetting",
   *Int. J. Control* 47(2), 477-491, 1988.
.. [6] T. R. Fortescue, L. S. Kershenbaum and B. E. Ydstie, "Implementation
   of self-tuning regulators with variable forgetting factors",
   *Automatica* 17(6), 831-835, 1981.
"""

import math

import numpy as np

from .._validation import as_float_array, check_scalar

__all__ = []

#: Mode names accepted by ``RecursiveLeastSquares(forgetting=...)``, in code order.
MODES = ("exponential", "directional", "constant_trace", "efra", "variable", "diagonal")
EXPONENTIAL, DIRECTIONAL, CONSTANT_TRACE, EFRA, VARIABLE, DIAGONAL = range(6)

# Names of each mode's parameters, in the order of the params tuple.
_PARAM_NAMES = {
    EXPONENTIAL: ("spread_max", "trace_max"),
    DIRECTIONAL: ("eps",),
    CONSTANT_TRACE: ("trace", "ratio"),
    EFRA: ("alpha", "beta", "delta"),
    VARIABLE: ("lam_min", "trace_max"),
    DIAGONAL: ("spread_max", "trace_max"),      # the windup cap, as the exponential mode's
}

#: The modes that forget in the time update (``predict``), with the windup cap.
TIME_UPDATE_MODES = (EXPONENTIAL, DIAGONAL)


def mode_code(forgetting):
    """Integer code of a mode name, with a message naming the choices."""
    if not isinstance(forgetting, str) or forgetting not in MODES:
        raise ValueError(f"`forgetting` must be one of {', '.join(map(repr, MODES))}; "
                         f"got {forgetting!r}")
    return MODES.index(forgetting)


#: Default ``spread_max`` of the exponential mode's windup cap (see `mode_params`).
SPREAD_MAX = 1e15
#: Default ``trace_max`` of the exponential mode's windup cap, in units of ``trace(P0)``.
TRACE_MAX_FACTOR = 1e12


def mode_params(code, params, dim_x, lam, R=1.0, P0_trace=1.0):
    """Validate the user's ``forgetting_params`` dict; return a float tuple.

    Defaults: exponential (the windup cap) ``spread_max = 1e15``,
    ``trace_max = 1e12 trace(P0)`` (`P0_trace`); directional
    ``eps = 1e-12``; constant trace ``trace = dim_x R
    (1 - lam)`` (the trace at which plain exponential forgetting settles for
    white, unit-power regressors; needs ``lam < 1``), ``ratio = 1e4``; EFRA
    ``alpha = 0.5``, ``beta = delta = 0.005``; variable
    ``lam_min = max(0.5, 1 - 10 (1 - lam))`` (at most `lam`),
    ``trace_max = 10 dim_x``; diagonal as exponential (`lam` is then the
    smallest factor: only a default that depends on it would read it).
    """
    if params is None:
        params = {}
    if not isinstance(params, dict):
        raise TypeError(f"`forgetting_params` must be a dict or None; got "
                        f"{type(params).__name__}")
    names = _PARAM_NAMES[code]
    unknown = sorted(set(params) - set(names))
    if unknown:
        allowed = ", ".join(names) if names else "none"
        raise TypeError(f"`forgetting_params` has unknown keys {unknown} for forgetting="
                        f"{MODES[code]!r}; allowed: {allowed}")
    p = {k: check_scalar(v, f"forgetting_params['{k}']") for k, v in params.items()}

    def positive(name):
        if not (math.isfinite(p[name]) and p[name] > 0.0):
            raise ValueError(f"`forgetting_params['{name}']` must be a positive finite number; "
                             f"got {p[name]}")

    def positive_or_inf(name):
        if not p[name] > 0.0 or math.isnan(p[name]):
            raise ValueError(f"`forgetting_params['{name}']` must be a positive number (inf "
                             f"turns the cap off); got {p[name]}")

    if code in TIME_UPDATE_MODES:
        p.setdefault("spread_max", SPREAD_MAX)
        p.setdefault("trace_max", TRACE_MAX_FACTOR * P0_trace)
        positive_or_inf("spread_max")
        positive_or_inf("trace_max")
    elif code == DIRECTIONAL:
        p.setdefault("eps", 1e-12)
        positive("eps")
    elif code == CONSTANT_TRACE:
        if "trace" not in p:
            if lam == 1.0:
                raise ValueError("forgetting='constant_trace' with lam = 1 needs an explicit "
                                 "`forgetting_params['trace']` (the default is "
                                 "dim_x * R * (1 - lam))")
            p["trace"] = dim_x * R * (1.0 - lam)
        p.setdefault("ratio", 1e4)
        positive("trace")
        positive("ratio")
    elif code == EFRA:
        p.setdefault("alpha", 0.5)
        p.setdefault("beta", 0.005)
        p.setdefault("delta", 0.005)
        for name in ("alpha", "beta", "delta"):
            positive(name)
        if p["alpha"] > 1.0:
            raise ValueError(f"`forgetting_params['alpha']` must be in (0, 1]; got {p['alpha']}")
        lo, hi = efra_bounds(lam, p["alpha"], p["beta"], p["delta"])
        if 2.0 * lam * p["delta"] * hi >= 1.0:
            raise ValueError(
                "EFRA constants give an unstable recursion: need 2 lam delta sigma_max < 1; got "
                f"lam = {lam}, delta = {p['delta']}, sigma_max = {hi:.3g}. Decrease "
                "`forgetting_params['delta']` or `['beta']`.")
    elif code == VARIABLE:
        p.setdefault("lam_min", min(lam, max(0.5, 1.0 - 10.0 * (1.0 - lam))))
        p.setdefault("trace_max", 10.0 * dim_x)
        if not 0.0 < p["lam_min"] <= lam:
            raise ValueError(f"`forgetting_params['lam_min']` must be in (0, lam] = (0, {lam}]; "
                             f"got {p['lam_min']}")
        positive("trace_max")
    return tuple(p[name] for name in names)


def diagonal_lam(lam, dim_x):
    """The forgetting factors of ``forgetting="diagonal"``: `lam` a number (every
    parameter) or an array of shape ``(dim_x,)``, each in (0, 1]; a new read-only
    float64 array."""
    if isinstance(lam, (bool, np.bool_)):
        raise TypeError(f"`lam` must be a real number or an array of {dim_x}; got {lam!r}")
    arr = np.array(as_float_array(lam, "lam"), dtype=np.float64)    # a copy of its own
    if arr.ndim == 0:
        arr = np.full(dim_x, float(arr))
    if arr.shape != (dim_x,):
        raise ValueError(f"`lam` must be a number or have shape ({dim_x},) (one forgetting "
                         f"factor per parameter, dim_x = {dim_x}); got shape {arr.shape}")
    bad = ~((arr > 0.0) & (arr <= 1.0))                  # also NaN
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"`lam` must be in (0, 1]; got lam[{i}] = {arr[i]}")
    arr.flags.writeable = False
    return arr


# The configuration array of the kernels: [mode, lam, gate, params (3), (the diagonal
# factors), projector].
CFG_MODE, CFG_LAM, CFG_GATE, CFG_PARAMS, CFG_PI = 0, 1, 2, 3, 6


def kernel_config(code, lam, params, gate=None, Pi=None):
    """The float64 array the compiled kernels take as their configuration.

    ``[mode, lam, gate, p1, p2, p3, Pi...]``: the mode's code, the forgetting
    factor, the gate (``inf`` without one: no residual exceeds it), the mode's
    parameters padded to three and, with constraints, the projector ``Pi``
    onto the null space of ``A`` (flattened; absent without constraints).

    The diagonal mode (`lam` an array of the ``n`` factors ``lam_i``) holds the
    smallest factor in the ``lam`` slot (the ``lam_t`` of its steps) and its time
    update's factors ``w_i = 1 / sqrt(lam_i)`` in ``n`` entries from ``CFG_PI``,
    before the projector: ``[mode, min lam, gate, p1, p2, p3, w..., Pi...]``
    (`_kernels.diagonal_factors`, `_kernels.projector`).
    """
    pad = (0.0,) * (CFG_PI - CFG_PARAMS - len(params))
    w = np.zeros(0)
    if code == DIAGONAL:
        lam = np.asarray(lam, dtype=np.float64)
        w = 1.0 / np.sqrt(lam)              # w_i = lam_i^(-1/2), as `tuning._model` forms them
        lam = float(lam.min())
    head = [code, lam, math.inf if gate is None else gate, *params, *pad]
    return np.concatenate([head, w, np.zeros(0) if Pi is None else np.ravel(Pi)])


# ----------------------------------------------------------------------
# EFRA's invariant set
# ----------------------------------------------------------------------
def efra_bounds(lam, alpha, beta, delta):
    r"""Eigenvalue bounds ``(sigma_min, sigma_max)`` that EFRA keeps ``P`` in.

    With :math:`\eta = (1 - \lambda)/\lambda`, the upper bound is the fixed
    point of the unexcited recursion :math:`p = p/\lambda + \beta - \delta
    p^2`, and the lower bound that of a direction excited without limit,
    :math:`p = p/\lambda - \alpha p + \beta - \delta p^2` (Salgado et al.
    1988 give the approximations :math:`\beta/(\alpha - \eta)` and
    :math:`\eta/\delta + \beta/\eta`):

    .. math:: \sigma_{max} = \frac{\eta + \sqrt{\eta^2 + 4\beta\delta}}{2\delta},\qquad
              \sigma_{min} = \frac{\eta - \alpha + \sqrt{(\alpha - \eta)^2 + 4\beta\delta}}
                                  {2\delta}
    """
    eta = (1.0 - lam) / lam
    hi = (eta + math.sqrt(eta * eta + 4.0 * beta * delta)) / (2.0 * delta)
    lo = (eta - alpha + math.sqrt((alpha - eta) ** 2 + 4.0 * beta * delta)) / (2.0 * delta)
    return lo, hi


def clip_eigenvalues(P, lo, hi):
    """``P`` with its eigenvalues clipped to ``[lo, hi]`` (exactly symmetric)."""
    w, V = np.linalg.eigh(0.5 * (P + P.T))
    P = (V * np.clip(w, lo, hi)) @ V.T
    return 0.5 * (P + P.T)
