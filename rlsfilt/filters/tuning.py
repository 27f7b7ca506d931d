r"""Maximum-likelihood tuning of the forgetting factor or the random walk of a filter.

A recursive least-squares filter is the Kalman filter of its parameters, and
its innovations :math:`y_t = z_t - H_t \hat x^-_t` with variances
:math:`S_t = H_t P^-_t H_t^T + R` are exact at every step, so the Gaussian
log-likelihood of the record is their prediction-error decomposition
(Schweppe 1965; Harvey 1989, sec. 3.4):

.. math::

    \ell = -\tfrac12 \sum_t \left(\log 2\pi + \log S_t + y_t^2 / S_t\right).

In the scale-free parametrization, where the noise variance :math:`\sigma^2 = R`
multiplies every covariance (:math:`Q = q\,\sigma^2`, :math:`P_0 = p_0\,\sigma^2`),
the innovations do not depend on :math:`\sigma^2` and :math:`S_t = \sigma^2 s_t`,
so :math:`\sigma^2` concentrates out, :math:`\hat\sigma^2 = \frac1N \sum_t y_t^2 / s_t`,
and the profile log-likelihood of the remaining parameter is

.. math::

    \ell_p = -\tfrac12 \left(N (\log 2\pi + \log \hat\sigma^2 + 1) + \sum_t \log s_t\right).

`tune` maximizes it over the forgetting factor :math:`\lambda`, a scalar random
walk :math:`Q = q \sigma^2 I` or a diagonal one, by a bounded search on a
transformed parameter (the likelihood at one value is evaluated exactly by
one ``batch_filter`` run), and takes standard errors from the observed
information (the numerical second derivative of :math:`\ell_p`).
"""

import html
import math

import numpy as np

from .._display import Summary, frame_html, table_html
from .._lazy import lazy_module
from .._validation import as_float_array, check_int

__all__ = ["BankTuneResult", "TuneResult", "tune", "tune_bank"]

_LOG_2PI = math.log(2.0 * math.pi)
_PARAMS = ("lam", "q", "q_diag")
_kernels = lazy_module("rlsfilt.filters._kernels_tuning")
_H = 1e-3            # step of the numerical second derivative in the search variable


class TuneResult:
    r"""What `tune` returns: the maximum-likelihood estimate and its uncertainty.

    Attributes
    ----------
    param : {"lam", "q", "q_diag"}
        What was tuned.
    estimate : float or ndarray of shape (dim_x,)
        :math:`\hat\lambda`, or :math:`\hat q = Q / R` (a vector of diagonal
        entries for ``"q_diag"``).
    stderr : float or ndarray
        Standard error of `estimate` from the observed information (for ``q``
        by the delta method from :math:`\log q`, the scale it is searched
        on); NaN when the estimate lies on a bound.
    loglik : float
        Profile log-likelihood at the estimate (the noise variance
        concentrated out).
    R : float
        :math:`\hat\sigma^2`, the noise variance at the estimate; the random walk
        is ``Q = estimate * R``.
    converged : bool
        The search met its tolerance inside the bounds.
    at_bound : bool
        The estimate lies on a bound of the search (for ``lam``: 1, no
        forgetting; for ``q``: its lower bound, constant parameters).
    n_obs : int
        Innovations in the likelihood (missing and burnt-in samples excluded).
    n_evals : int
        Likelihood evaluations (passes over the record) of the search and the
        standard errors.
    """

    def __init__(self, param, estimate, stderr, loglik, R, converged, at_bound, n_obs,
                 n_evals, _log_stderr=None):
        self.param = param
        self.estimate = estimate
        self.stderr = stderr
        self.loglik = loglik
        self.R = R
        self.converged = converged
        self.at_bound = at_bound
        self.n_obs = n_obs
        self.n_evals = n_evals
        self._log_stderr = _log_stderr

    def interval(self, level=0.95):
        r"""Wald confidence interval ``(low, high)`` at `level`.

        For ``lam``: :math:`\hat\lambda \pm z\,\mathrm{se}`, the upper end at
        most 1. For ``q``: on the log scale it is searched on,
        :math:`\hat q \exp(\pm z\,\mathrm{se}(\log \hat q))` (positive, and
        closer to the likelihood's shape).
        """
        from scipy.stats import norm  # lazy: keeps `import rlsfilt` light

        if not 0.0 < level < 1.0:
            raise ValueError(f"`level` must be in (0, 1); got {level}")
        zq = norm.ppf(0.5 + 0.5 * level)
        if self.param == "lam":
            return self.estimate - zq * self.stderr, min(1.0, self.estimate + zq * self.stderr)
        half = zq * self._log_stderr
        return self.estimate * np.exp(-half), self.estimate * np.exp(half)

    def apply(self, filt):
        """Set `filt`'s ``R`` and its ``lam`` or ``Q`` to the estimate (its state is kept:
        :meth:`reset` it to run the record again). Returns `filt`."""
        if self.param == "lam":
            Q = filt.Q / filt.R                 # the random walk relative to R, kept
            filt.R = self.R
            filt.lam = self.estimate
            filt.Q = Q * self.R
        else:
            filt.R = self.R
            filt.Q = np.diag(np.broadcast_to(self.estimate, (filt.dim_x,)) * self.R)
        return filt

    def summary(self):
        """One line per quantity: the estimate, its standard error and interval, R, loglik.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table).
        """
        est = np.atleast_1d(self.estimate)
        se = np.atleast_1d(self.stderr)
        lo, hi = (np.atleast_1d(v) for v in self.interval())
        lines = [f"maximum likelihood of {self.param} ({self.n_obs} innovations, "
                 f"{self.n_evals} filter runs, {'converged' if self.converged else 'NOT converged'}"
                 f"{', at a bound' if self.at_bound else ''})"]
        for i in range(len(est)):
            name = self.param if len(est) == 1 else f"q[{i}]"
            lines.append(f"  {name:8s} {est[i]:.6g}  (se {se[i]:.3g}; 95 % [{lo[i]:.6g}, "
                         f"{hi[i]:.6g}])")
        lines.append(f"  R        {self.R:.6g}")
        lines.append(f"  loglik   {self.loglik:.6f}")
        rows = [[self.param if len(est) == 1 else f"q[{i}]", f"{est[i]:.6g}", f"{se[i]:.3g}",
                 f"[{lo[i]:.6g}, {hi[i]:.6g}]"] for i in range(len(est))]
        rows += [["R", f"{self.R:.6g}", "", ""], ["loglik", f"{self.loglik:.6f}", "", ""]]
        page = frame_html(html.escape(lines[0]),
                          table_html(["quantity", "estimate", "std error", "95 % interval"], rows))
        return Summary("\n".join(lines), page)

    def __repr__(self):
        return (f"<TuneResult {self.param}={np.round(self.estimate, 6)!r} "
                f"loglik={self.loglik:.4f} converged={self.converged}>")


class BankTuneResult:
    """What `tune_bank` (`RLSBank.tune`) returns: one `TuneResult` per channel, and their
    fields as arrays.

    Attributes
    ----------
    results : list of TuneResult
        Channel by channel.
    param : str
        What was tuned.
    estimate, stderr : ndarray, shape (C,) or (C, dim_x)
    loglik, R : ndarray, shape (C,)
    converged, at_bound : ndarray of bool, shape (C,)
    n_obs, n_evals : ndarray of int, shape (C,)
    """

    def __init__(self, results):
        self.results = results
        self.param = results[0].param if results else None
        for name in ("estimate", "stderr", "loglik", "R", "converged", "at_bound", "n_obs",
                     "n_evals"):
            setattr(self, name, np.array([getattr(r, name) for r in results]))

    def channel(self, i):
        """The `TuneResult` of channel `i`."""
        return self.results[i]

    def interval(self, level=0.95):
        """Each channel's `TuneResult.interval`, as arrays ``(low, high)``."""
        lows, highs = zip(*(r.interval(level) for r in self.results), strict=True)
        return np.array(lows), np.array(highs)

    def apply(self, bank):
        """Set every channel's ``R`` and ``lam`` or ``Q`` to its estimate; returns `bank`."""
        R_old, n = bank.R, bank.dim_x
        if self.param == "lam":
            Q_rel = bank.Q / R_old[:, None, None]
            bank.R = self.R
            bank.lam = self.estimate
            bank.Q = Q_rel * self.R[:, None, None]
        else:
            q = np.broadcast_to(self.estimate.reshape(len(self.results), -1),
                                (len(self.results), n))
            bank.R = self.R
            bank.Q = np.einsum("ci,ij->cij", q * self.R[:, None], np.eye(n))
        return bank

    def __repr__(self):
        return (f"<BankTuneResult {self.param}: {len(self.results)} channels, "
                f"{int(self.converged.sum())} converged>")


def tune(filt, zs, Hs, param="q", *, bounds=None, burn=0, apply=False):
    r"""Maximum likelihood of the forgetting factor or the random walk of a filter.

    Parameters
    ----------
    filt : RecursiveLeastSquares
        The filter, with ``forgetting="exponential"``; its current state
        ``(x, P)`` starts every run (a new filter: ``x0``, ``P0``), with ``P``
        relative to its ``R`` (``P0 = p0 R`` in the scale-free
        parametrization). It is left unchanged unless `apply`.
    zs, Hs : array_like
        The record, as for ``batch_filter``; NaN in `zs` marks missing samples.
    param : {"q", "lam", "q_diag"}, default "q"
        What to estimate: ``"q"``, the random walk ``Q = q R I`` (the filter's
        ``lam`` kept); ``"lam"``, the forgetting factor (the filter's ``Q / R``
        kept); ``"q_diag"``, a diagonal random walk ``Q = R diag(q)``.
    bounds : (float, float), optional
        Search interval of the parameter: ``(0.5, 1.0)`` for ``lam``,
        ``(1e-12, 1e2)`` for ``q`` and each entry of ``q_diag`` (relative to ``R``).
    burn : int, default 0
        Innovations left out of the likelihood at the start (statsmodels'
        ``loglikelihood_burn``: with a broad ``P0``, the first ``dim_x`` are the
        diffuse part).
    apply : bool, default False
        Also set the filter's ``R`` and ``lam`` or ``Q`` to the estimate
        (`TuneResult.apply`).

    Returns
    -------
    TuneResult

    Notes
    -----
    See the module docstring for the profile likelihood. The search runs on
    :math:`\lambda` itself (bounded Brent, ``scipy.optimize.minimize_scalar``)
    or on :math:`\log q` (bounded Brent; for ``"q_diag"`` L-BFGS-B with
    central-difference gradients, from the scalar estimate). The standard
    errors come from the observed information :math:`-\partial^2 \ell_p /
    \partial v^2` in the search variable ``v`` by central differences, mapped
    to ``q`` by the delta method.

    References
    ----------
    .. [1] F. C. Schweppe, "Evaluation of likelihood functions for Gaussian
       signals", *IEEE Trans. Information Theory* 11(1), 1965.
    .. [2] A. C. Harvey, *Forecasting, Structural Time Series Models and the
       Kalman Filter*, Cambridge University Press, 1989, sec. 3.4.
    .. [3] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 7.4.

    Examples
    --------
    A gain that drifts as a random walk of standard deviation 0.02 per sample,
    in noise of standard deviation 0.1 (so ``q = 0.04``):

    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((2000, 1))
    >>> gain = 1.0 + np.cumsum(0.02 * rng.standard_normal(2000))
    >>> z = H[:, 0] * gain + 0.1 * rng.standard_normal(2000)
    >>> fit = RecursiveLeastSquares(1).tune(z, H, "q")
    >>> lo, hi = fit.interval()
    >>> bool(lo < 0.04 < hi), round(fit.R, 3)
    (True, 0.01)
    """
    if param not in _PARAMS:
        raise ValueError(f"`param` must be one of {', '.join(map(repr, _PARAMS))}; got {param!r}")
    if getattr(filt, "forgetting", None) != "exponential":
        raise ValueError("`tune` needs a RecursiveLeastSquares with forgetting='exponential' "
                         "(a Kalman time update P / lam + Q)")
    burn = check_int(burn, "burn", minimum=0)
    Z, Hm = filt._as_batch(zs, Hs)
    bounds = _bounds(param, bounds)
    R0 = filt.R
    out = _tune_record(Z, Hm, filt.x, filt.P / R0, filt.Q / R0, filt.lam, param, bounds, burn)
    if apply:
        out.apply(filt)
    return out


def tune_bank(bank, zs, Hs, param="q", *, bounds=None, burn=0, apply=False):
    r"""`tune` of every channel of an `RLSBank`: `RLSBank.tune`.

    Each channel ``c`` is tuned on its own column of the record, from its own
    state, ``R``, ``Q`` and ``lam``, exactly as `tune` tunes
    ``bank.channel(c)`` (the same compiled passes, one channel after another).

    Parameters
    ----------
    bank : RLSBank
        With ``forgetting="exponential"``; left unchanged unless `apply`.
    zs : array_like, shape (N, C)
        Measurements; NaN skips that channel at that step.
    Hs : array_like, shape (N, C, dim_x)
        Regressor rows; a row holding NaN skips that channel at that step.
    param, bounds, burn, apply
        As for `tune` (`apply` sets every channel's ``R`` and ``lam`` or ``Q``).

    Returns
    -------
    BankTuneResult
    """
    if param not in _PARAMS:
        raise ValueError(f"`param` must be one of {', '.join(map(repr, _PARAMS))}; got {param!r}")
    if getattr(bank, "forgetting", None) != "exponential":
        raise ValueError("`tune` needs forgetting='exponential' (a Kalman time update "
                         "P / lam + Q)")
    burn = check_int(burn, "burn", minimum=0)
    C, n = bank.n_channels, bank.dim_x
    Z = as_float_array(zs, "zs")
    if Z.ndim != 2 or Z.shape[1] != C:
        raise ValueError(f"`zs` must have shape (N, {C}) (one column per channel); got {Z.shape}")
    Hm = as_float_array(Hs, "Hs")
    if Hm.shape != (len(Z), C, n):
        raise ValueError(f"`Hs` must have shape ({len(Z)}, {C}, {n}); got {Hm.shape}")
    bounds = _bounds(param, bounds)
    x, P, Q, R, lam = bank.x, bank.P, bank.Q, bank.R, bank.lam
    results = [_tune_record(Z[:, c:c + 1], Hm[:, c], x[c].reshape(n, 1), P[c] / R[c],
                            Q[c] / R[c], float(lam[c]), param, bounds, burn)
               for c in range(C)]
    out = BankTuneResult(results)
    if apply:
        out.apply(bank)
    return out


def _tune_record(Z, Hm, x_start, P_rel, Q_rel, lam0, param, bounds, burn):
    """`tune` on a validated record ``Z`` (N, m), ``Hm`` (N, n) from ``x_start`` (n, m),
    with ``P`` and ``Q`` relative to ``R``; returns the `TuneResult`."""
    from scipy.optimize import minimize, minimize_scalar  # lazy: keeps `import rlsfilt` light

    lo, hi = bounds
    n, m = x_start.shape
    evals = [0]
    x_start = np.ascontiguousarray(x_start, dtype=np.float64)
    P_rel = np.ascontiguousarray(P_rel, dtype=np.float64)
    Zc, Hc = np.ascontiguousarray(Z, dtype=np.float64), np.ascontiguousarray(Hm, dtype=np.float64)
    terms = _kernels().profile_terms

    def profile(lam, Q):
        """``(loglik, sigma2, n_obs)`` of one run (R = 1, P and Q relative to R)."""
        evals[0] += 1
        # sum log s_t, sum y_t^2 / s_t (s_t = S_t / sigma^2), compiled
        slog, sq, n_obs = terms(x_start, P_rel, Zc, Hc, 1.0 / lam,
                                np.ascontiguousarray(Q, dtype=np.float64), burn)
        if n_obs == 0:
            raise ValueError("`zs` has no measurement left for the likelihood (all missing "
                             "or burnt in)")
        sigma2 = sq / n_obs                                  # sigma^2 = mean(y^2 / s)
        ll = -0.5 * (n_obs * (_LOG_2PI + math.log(sigma2) + 1.0) + m * slog)
        return ll, sigma2, n_obs

    if param == "lam":
        def run(v):
            return profile(float(v), Q_rel)

        v_lo, v_hi = lo, hi
    elif param == "q":
        def run(v):
            return profile(lam0, math.exp(float(v)) * np.eye(n))

        v_lo, v_hi = math.log(lo), math.log(hi)
    else:
        def run(v):
            return profile(lam0, np.diag(np.exp(np.asarray(v, dtype=float))))

        v_lo, v_hi = math.log(lo), math.log(hi)

    def negll(v):
        return -run(v)[0]

    if param in ("lam", "q"):
        res = minimize_scalar(negll, bounds=(v_lo, v_hi), method="bounded",
                              options={"xatol": 1e-10, "maxiter": 500})
        v = float(res.x)
        converged = bool(res.success)
        width = v_hi - v_lo
        at_bound = min(v - v_lo, v_hi - v) < 1e-6 * width
    else:
        start = minimize_scalar(lambda u: negll(np.full(n, u)), bounds=(v_lo, v_hi),
                                method="bounded",
                                options={"xatol": 1e-6, "maxiter": 500})
        res = minimize(negll, np.full(n, float(start.x)), method="L-BFGS-B", jac="3-point",
                       bounds=[(v_lo, v_hi)] * n,
                       options={"ftol": 1e-15, "gtol": 1e-7, "maxiter": 500})
        v = np.asarray(res.x, dtype=float)
        # (a line search that stops at round-off is converged when the gradient is nil:
        # 1e-4 per unit of log q moves q by less than 1e-5 of itself at any usual curvature)
        converged = bool(res.success) or float(np.max(np.abs(res.jac))) < 1e-4
        width = v_hi - v_lo
        at_bound = bool(np.any(np.minimum(v - v_lo, v_hi - v) < 1e-6 * width))
    ll, sigma2, n_obs = run(v)
    se_v = _stderr(run, v, ll, v_lo, v_hi, param)
    if at_bound:                         # no curvature to read on a bound
        se_v = np.nan if param != "q_diag" else np.full(n, np.nan)
    if param == "lam":
        estimate, stderr, log_se = v, se_v, None
    elif param == "q":
        estimate = math.exp(v)
        stderr, log_se = estimate * se_v, se_v
    else:
        estimate = np.exp(v)
        stderr, log_se = estimate * se_v, se_v
    return TuneResult(param, estimate, stderr, ll, sigma2, converged and not at_bound, at_bound,
                      n_obs, evals[0], _log_stderr=log_se)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _bounds(param, bounds):
    """The search interval of `param` (checked)."""
    if bounds is None:
        return (0.5, 1.0) if param == "lam" else (1e-12, 1e2)
    try:
        lo, hi = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise TypeError(f"`bounds` must be a pair of numbers; got {bounds!r}") from None
    ok = (0.0 < lo < hi <= 1.0) if param == "lam" else (0.0 < lo < hi < math.inf)
    if not ok:
        allowed = "0 < low < high <= 1" if param == "lam" else "0 < low < high < inf"
        raise ValueError(f"`bounds` must satisfy {allowed} for {param!r}; got {bounds!r}")
    return lo, hi


def _stderr(run, v, ll, v_lo, v_hi, param):
    """Standard errors in the search variable from the observed information (central
    differences of the profile log-likelihood); NaN on a bound or where the curvature
    is not negative."""
    v = np.atleast_1d(np.asarray(v, dtype=float))
    k = len(v)
    h = np.full(k, _H)
    if param == "lam":                   # stay inside (0, 1]
        h = np.minimum(h * max(1.0 - float(v[0]), 1e-6), 0.5 * (v_hi - v))
    if np.any(v - h < v_lo) or np.any(v + h > v_hi) or np.any(h <= 0):
        return np.nan if k == 1 else np.full(k, np.nan)

    def f(w):
        return run(float(w[0]) if k == 1 else w)[0]

    Hs = np.empty((k, k))
    for i in range(k):
        ei = np.zeros(k)
        ei[i] = h[i]
        Hs[i, i] = (f(v + ei) - 2.0 * ll + f(v - ei)) / h[i] ** 2
        for j in range(i):
            ej = np.zeros(k)
            ej[j] = h[j]
            Hs[i, j] = Hs[j, i] = (f(v + ei + ej) - f(v + ei - ej) - f(v - ei + ej)
                                   + f(v - ei - ej)) / (4.0 * h[i] * h[j])
    try:
        cov = np.linalg.inv(-Hs)
    except np.linalg.LinAlgError:
        return np.nan if k == 1 else np.full(k, np.nan)
    d = np.diag(cov)
    se = np.where(d > 0, np.sqrt(np.abs(d)), np.nan)
    return float(se[0]) if k == 1 else se
