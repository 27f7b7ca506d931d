r"""Forgetting schemes for recursive least squares, one small function per mode.

Plain exponential forgetting (``P <- P / lam`` in every step) winds up: when
the regressor stops exciting some direction, nothing ever shrinks ``P`` in
that direction again and it grows like ``lam**-k`` (covariance windup). The
schemes here bound ``P`` by forgetting only what new data replaces. Each
function performs the *measurement update including the forgetting* of one
step, because all of them need the step's regressor or residual; they share
one signature so that the step loop (and the compiled kernels that mirror
it) can dispatch on an integer code::

    x, P, y, K, lam_t = update_<mode>(x, P, phi, z, g, s, r, params)

with ``x`` (n, m) the prior estimate, ``P`` (n, n) the prior covariance,
``phi`` (1, n) the regressor row, ``z`` (m, 1) the measurement, ``g = P
phi^T``, ``s = phi P phi^T + r`` and ``r`` the noise variance. ``lam_t`` is
the forgetting factor that the step effectively applied (reported as
``RecursiveLeastSquares.lam_t``).

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

from .._validation import check_scalar

__all__ = []

#: Mode names accepted by ``RecursiveLeastSquares(forgetting=...)``, in code order.
MODES = ("exponential", "directional", "constant_trace", "efra", "variable")
EXPONENTIAL, DIRECTIONAL, CONSTANT_TRACE, EFRA, VARIABLE = range(5)

# Names of each mode's parameters, in the order of the params tuple.
_PARAM_NAMES = {
    EXPONENTIAL: (),
    DIRECTIONAL: ("eps",),
    CONSTANT_TRACE: ("trace", "ratio"),
    EFRA: ("alpha", "beta", "delta"),
    VARIABLE: ("lam_min", "trace_max"),
}


def mode_code(forgetting):
    """Integer code of a mode name, with a message naming the choices."""
    if not isinstance(forgetting, str) or forgetting not in MODES:
        raise ValueError(f"`forgetting` must be one of {', '.join(map(repr, MODES))}; "
                         f"got {forgetting!r}")
    return MODES.index(forgetting)


def mode_params(code, params, dim_x, lam, R=1.0):
    """Validate the user's ``forgetting_params`` dict; return a float tuple.

    Defaults: directional ``eps = 1e-12``; constant trace ``trace = dim_x R
    (1 - lam)`` (the trace at which plain exponential forgetting settles for
    white, unit-power regressors; needs ``lam < 1``), ``ratio = 1e4``; EFRA
    ``alpha = 0.5``, ``beta = delta = 0.005``; variable
    ``lam_min = max(0.5, 1 - 10 (1 - lam))`` (at most `lam`),
    ``trace_max = 10 dim_x``.
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

    if code == DIRECTIONAL:
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


# ----------------------------------------------------------------------
# per-mode measurement updates (the reference arithmetic)
# ----------------------------------------------------------------------
def update_exponential(x, P, phi, z, g, s, r, lam, params):
    r"""Standard update; the forgetting ``P / lam`` already happened in ``predict``.

    .. math:: K = P\phi^T / s,\quad x \leftarrow x + K y^T,\quad
              P \leftarrow P - g g^T / s
    """
    y = z - (phi @ x).T                    # y = z - H x          (m, 1)
    K = g / s                              # K = P H^T / S         (n, 1)
    x = x + K * y.T                        # x = x + K y^T         (n, m)
    P = P - (g * g.T) / s                  # P = P - g g^T / S     exactly symmetric
    return x, P, y, K, lam


def update_directional(x, P, phi, z, g, s, r, lam, params):
    r"""Directional forgetting (Kulhavy & Karny 1984; Bittanti et al. 1990).

    With :math:`\rho = \phi P \phi^T / r` the information along the
    regressor, :math:`\varepsilon = \lambda - (1 - \lambda)/\rho` when
    :math:`\rho >` ``eps`` (else 1) and the information update
    :math:`P^{-1} \leftarrow P^{-1} + \varepsilon \phi^T\phi / r`:

    .. math:: P \leftarrow P - \frac{\varepsilon\, g g^T}{r (1 + \varepsilon\rho)},\quad
              K = \frac{g}{r (1 + \varepsilon\rho)},\quad x \leftarrow x + K y^T

    Only the excited direction is forgotten; ``phi P phi^T`` settles at
    ``r (1 - lam) / lam`` along a constant regressor and the other
    directions are untouched, so ``P`` cannot wind up.
    """
    (eps,) = params
    rho = (s - r) / r                      # phi P phi^T / r
    e = lam - (1.0 - lam) / rho if rho > eps else 1.0
    d = r * (1.0 + e * rho)                # = r lam (1 + rho) when forgetting
    y = z - (phi @ x).T
    K = g / d
    x = x + K * y.T
    P = P - (e / d) * (g * g.T)
    return x, P, y, K, e


def update_constant_trace(x, P, phi, z, g, s, r, lam, params):
    r"""Constant-trace algorithm (Goodwin & Sin 1984; Astrom & Wittenmark 1995).

    .. math:: \bar P = P - g g^T / s,\qquad
              P \leftarrow c_1 \bar P / \operatorname{tr}\bar P + c_2 I

    with :math:`c_1 + n c_2 =` ``trace`` and :math:`c_1 / c_2 =` ``ratio``,
    so ``trace(P)`` is constant and ``cond(P)`` is at most about ``ratio``.
    The normalization is the forgetting (``lam_t = tr(P_bar) / tr(P)``
    before the ``c_2`` term), so `lam` enters only through the default ``trace``.
    """
    trace, ratio = params
    n = P.shape[0]
    c2 = trace / (ratio + n)
    c1 = trace - n * c2
    x, Pb, y, K, _ = update_exponential(x, P, phi, z, g, s, r, lam, ())
    tb = np.trace(Pb)
    P = (c1 / tb) * Pb
    P[np.diag_indices(n)] += c2
    return x, P, y, K, tb / c1


def update_efra(x, P, phi, z, g, s, r, lam, params):
    r"""Exponential forgetting and resetting (Salgado, Goodwin & Middleton 1988).

    .. math:: K = \alpha g / s,\quad x \leftarrow x + K y^T,\quad
              P \leftarrow P / \lambda - \alpha g g^T / s + \beta r I - (\delta / r) P^2

    This is the paper's recursion (written for unit noise variance) applied
    to ``P / r``, so the constants do not depend on the units of the data.
    ``P / r`` stays between :func:`efra_bounds` ``(sigma_min, sigma_max)``
    once it starts there (the filter clips the eigenvalues of ``P`` once
    before the first EFRA step).
    """
    alpha, beta, delta = params
    n = P.shape[0]
    y = z - (phi @ x).T
    K = (alpha / s) * g
    x = x + K * y.T
    Pn = P / lam - (alpha / s) * (g * g.T) - (delta / r) * (P @ P)
    Pn = 0.5 * (Pn + Pn.T)                 # P @ P is symmetric only to round-off
    Pn[np.diag_indices(n)] += beta * r
    return x, Pn, y, K, lam


def update_variable(x, P, phi, z, g, s, r, lam, params):
    r"""Variable forgetting factor (Fortescue, Kershenbaum & Ydstie 1981).

    The information lost per step equals the information a typical residual
    brings: with the nominal memory :math:`N_0 = 1/(1 - \lambda)`,

    .. math:: \lambda_t = 1 - (1 - \lambda)\, \frac{y^T y}{m\, s},\qquad
              \bar P = P - g g^T / s,\qquad P \leftarrow \bar P / \lambda_t

    (the paper's :math:`1 - (1 - \phi K) e^2 / \Sigma_0` with
    :math:`\Sigma_0 = r N_0`), clipped to ``[lam_min, 1]``; and, because
    noise alone keeps :math:`\lambda_t < 1` while the input is not exciting,
    :math:`\lambda_t` is raised so that ``trace(P)`` does not pass
    ``trace_max`` (Fortescue et al.'s bound on ``P``).
    """
    lam_min, trace_max = params
    x, Pb, y, K, _ = update_exponential(x, P, phi, z, g, s, r, lam, ())
    m = y.shape[0]
    lt = 1.0 - (1.0 - lam) * float(np.vdot(y, y)) / (m * s)
    lt = min(1.0, max(lam_min, lt))
    lt = max(lt, min(1.0, np.trace(Pb) / trace_max))
    return x, Pb / lt if lt != 1.0 else Pb, y, K, lt


#: Dispatch table indexed by mode code.
UPDATES = (update_exponential, update_directional, update_constant_trace, update_efra,
           update_variable)


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
