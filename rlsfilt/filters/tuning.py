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
walk :math:`Q = q \sigma^2 I` or a diagonal one, on a transformed parameter
(:math:`\log(1 - \lambda)`, :math:`\log q`). Each pass over the record is one
compiled run of the filter's recursion that carries the sensitivities
:math:`\partial x_t, \partial P_t` (and their second derivatives) along, so it
returns the exact gradient and Hessian of :math:`\ell_p` with its value: a
handful of passes find the maximum, and the standard errors come from the
exact observed information :math:`-\partial^2 \ell_p`.
"""

import html
import math

import numpy as np

from .._display import Summary, frame_html, table_html
from .._lazy import lazy_module
from .._validation import as_float_array, check_int

__all__ = ["BankTuneResult", "TuneResult", "tune", "tune_bank"]

_LOG_2PI = math.log(2.0 * math.pi)
_PARAMS = ("lam", "q", "q_diag", "lam_diag")
_kernels = lazy_module("rlsfilt.filters._kernels_tuning")
_LAM_GAP = 1e-12     # lam = 1 is searched as 1 - lam = 1e-12 (u = log(1 - lam) finite)
_F64 = np.dtype(np.float64)
_DIMS = {}           # the dimension witness of the scalar search per dim_x (`_dims`)
#: The sizes whose passes (`_kernels_tuning.scalar_pass`, `diag_pass`) are compiled with
#: ``dim_x`` a constant (loops unrolled; each size and search a compile of its own, about
#: 6 s of CPU the first time, then loaded from numba's disk cache). A pass of 2,000
#: samples against the loop for every size (orders 1 and 2): 0.99x and 0.97x at 1 (not
#: kept), 0.81x at 2, 0.69x and 0.73x at 4, 0.64x and 0.73x at 6, 0.66x at 8 (sizes
#: above 6 run the loop: each size kept is one more compile).
_SPECIALISED = (2, 3, 4, 5, 6)
_Q_BOUNDS = (1e-12, 1e2)                     # the default search interval of q
_Q_SEARCH = (math.log(1e-12), math.log(1e2), math.log(1e-3))   # (low, high, start) of log q


class TuneResult:
    r"""What `tune` returns: the maximum-likelihood estimate and its uncertainty.

    Attributes
    ----------
    param : {"lam", "q", "q_diag", "lam_diag"}
        What was tuned.
    estimate : float or ndarray of shape (dim_x,)
        :math:`\hat\lambda`, or :math:`\hat q = Q / R` (vectors of diagonal
        entries for ``"q_diag"`` and ``"lam_diag"``).
    stderr : float or ndarray
        Standard error of `estimate` from the observed information (for ``q``
        and ``lam`` by the delta method from :math:`\log q` and
        :math:`\log(1 - \lambda)`, the scales they are searched on); NaN for
        an entry on a bound (the others from the information of the free ones).
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
    Q_shape : ndarray of shape (dim_x,), or None
        For ``"q"`` and ``"q_diag"``: the random walk :meth:`apply` sets is
        ``Q = R diag(estimate * Q_shape)``; None (the default) is the identity, the
        units the record was tuned in. ``ARX.fit(..., Q="tune")`` tunes in its
        record's power-of-two units and sets it to their image, so that `apply`
        on a filter in the signals' units runs the fit's random walk (``filter_.Q``
        up to the estimated ``R``).
    """

    #: see the class docstring (set by the caller that tuned in other units)
    Q_shape = None

    def __init__(self, param, estimate, stderr, loglik, R, converged, at_bound, n_obs,
                 n_evals, _log_stderr=None, _gradient=None, _hessian=None, _loglik_at=None):
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
        self._grad = _gradient           # of the profile log-likelihood in the search variable
        self._hess = _hessian            # (floats for one variable: arrays when asked)
        self._loglik_at = _loglik_at     # the profile log-likelihood at one parameter value

    @property
    def _gradient(self):
        """The gradient of the profile log-likelihood in the search variable, shape (k,)."""
        return None if self._grad is None else np.atleast_1d(np.asarray(self._grad, float))

    @property
    def _hessian(self):
        """Its second derivatives, shape (k, k)."""
        return None if self._hess is None else np.atleast_2d(np.asarray(self._hess, float))

    def interval(self, level=0.95):
        r"""Wald confidence interval ``(low, high)`` at `level`.

        On the scale the parameter is searched on (closer to the likelihood's
        shape, and inside the parameter's range): for ``q``,
        :math:`\hat q \exp(\pm z\,\mathrm{se}(\log \hat q))`; for ``lam``,
        :math:`1 - (1 - \hat\lambda) \exp(\mp z\,\mathrm{se}(\log(1 - \hat\lambda)))`,
        below 1.
        """
        from scipy.stats import norm  # lazy: keeps `import rlsfilt` light

        if not 0.0 < level < 1.0:
            raise ValueError(f"`level` must be in (0, 1); got {level}")
        zq = norm.ppf(0.5 + 0.5 * level)
        if self.param == "lam_diag":     # Wald, on lam itself
            return (self.estimate - zq * self.stderr,
                    np.minimum(1.0, self.estimate + zq * self.stderr))
        half = zq * self._log_stderr
        if self.param == "lam":          # on log(1 - lam), the scale it is searched on
            gap = 1.0 - self.estimate
            return 1.0 - gap * np.exp(half), 1.0 - gap * np.exp(-half)
        return self.estimate * np.exp(-half), self.estimate * np.exp(half)

    def profile(self, values):
        r"""The profile log-likelihood :math:`\ell_p` (``R`` concentrated out) at each of
        `values` of the parameter (``lam`` or ``q``; one compiled pass each).

        Parameters
        ----------
        values : array_like
            Values of ``lam`` in ``(0, 1]`` or of ``q`` in ``[0, inf)``.

        Returns
        -------
        ndarray, the shape of `values`
        """
        if self._loglik_at is None:
            raise ValueError("the profile needs the record: it is kept for a scalar 'lam' or "
                             "'q' of one filter (for a bank channel, tune `bank.channel(c)`); "
                             f"got {self.param!r}")
        v = as_float_array(values, "values")
        ok = (v > 0) & (v <= 1) if self.param == "lam" else v >= 0
        if not np.all(ok):
            allowed = "in (0, 1]" if self.param == "lam" else ">= 0"
            raise ValueError(f"`values` of {self.param} must be {allowed}; got "
                             f"{v[~ok].ravel()[0]!r}")
        return np.vectorize(self._loglik_at, otypes=[float])(v)

    def likelihood_interval(self, level=0.95):
        r"""Likelihood-ratio confidence interval ``(low, high)`` at `level`: the values
        whose profile log-likelihood is within :math:`\chi^2_1(\text{level}) / 2`
        (1.92 at 95 %) of the maximum (Wilks), found by root finding on the
        profile; an end is the search bound where the profile does not fall that
        far (``lam = 1``, or the lower bound of ``q``).
        """
        from scipy.optimize import brentq
        from scipy.stats import chi2

        if not 0.0 < level < 1.0:
            raise ValueError(f"`level` must be in (0, 1); got {level}")
        if self._loglik_at is None:
            self.profile([])                              # raises with the reason
        cut = self.loglik - 0.5 * chi2.ppf(level, 1)
        lo_b, hi_b = self._bounds
        if self.param == "lam":                # on u = log(1 - lam): lam = 1 is u = -inf
            to_v = lambda p: math.log(1.0 - p) if p < 1.0 else -math.inf  # noqa: E731
            from_v = lambda v: 1.0 - math.exp(v)                         # noqa: E731
        else:
            to_v, from_v = math.log, math.exp
        v_hat = to_v(self.estimate) if self.estimate > 0 else -math.inf
        if not math.isfinite(v_hat):           # on the bound lam = 1 (or q = 0)
            v_hat = math.log(_LAM_GAP) if self.param == "lam" else math.log(lo_b)
        ends = []
        for bound in (lo_b, hi_b):
            v_b = to_v(bound) if bound > 0 else -math.inf
            v_b = max(v_b, math.log(_LAM_GAP)) if self.param == "lam" else v_b
            f = lambda v: self._loglik_at(from_v(v)) - cut                # noqa: E731
            if abs(v_b - v_hat) < 1e-12 or f(v_b) >= 0.0:
                ends.append(bound)
                continue
            ends.append(from_v(brentq(f, v_hat, v_b, xtol=1e-12, rtol=1e-12)))
        return tuple(sorted(ends))

    def plot_profile(self, ax=None, *, level=0.95, n_points=61):
        """Plot the profile log-likelihood around the estimate with the likelihood-ratio
        interval: `rlsfilt.plotting.plot_profile_likelihood`. Returns the Axes."""
        from ..plotting import plot_profile_likelihood

        return plot_profile_likelihood(self, ax=ax, level=level, n_points=n_points)

    def apply(self, filt):
        """Set `filt`'s ``R`` and its ``lam`` or ``Q`` to the estimate (its state is kept:
        :meth:`reset` it to run the record again). Returns `filt`.

        For ``"lam_diag"`` the filter's forgetting becomes ``"diagonal"`` with
        ``lam = estimate`` (the time update :math:`P^- = L^{-1/2} P L^{-1/2} + Q` the
        likelihood ran; an exponential filter switches mode, its ``Q / R`` kept), so
        its innovations are those the likelihood was computed from."""
        if self.param == "lam_diag":
            Q = filt.Q / filt.R                 # the random walk relative to R, kept
            filt._forget_per_parameter(self.estimate)    # checks before changing anything
            filt.R = self.R
            filt.Q = Q * self.R
        elif self.param == "lam":
            Q = filt.Q / filt.R                 # the random walk relative to R, kept
            filt.R = self.R
            filt.lam = self.estimate
            filt.Q = Q * self.R
        else:
            q = np.broadcast_to(self.estimate, (filt.dim_x,))
            if self.Q_shape is not None:
                q = q * self.Q_shape
            filt.R = self.R
            filt.Q = np.diag(q * self.R)
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
            name = self.param if len(est) == 1 else f"{self.param.split('_')[0]}[{i}]"
            lines.append(f"  {name:8s} {est[i]:.6g}  (se {se[i]:.3g}; 95 % [{lo[i]:.6g}, "
                         f"{hi[i]:.6g}])")
        lines.append(f"  R        {self.R:.6g}")
        lines.append(f"  loglik   {self.loglik:.6f}")
        rows = [[self.param if len(est) == 1 else f"{self.param.split('_')[0]}[{i}]",
                 f"{est[i]:.6g}", f"{se[i]:.3g}",
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
        if self.param == "lam_diag":
            raise ValueError("a diagonal forgetting factor cannot be applied to RLSBank: its "
                             "kernels have no forgetting='diagonal'; apply each channel's "
                             "estimate to a RecursiveLeastSquares (`fits.channel(c).apply(f)`), "
                             "or tune 'lam'")
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
        The filter, with ``forgetting="exponential"`` (or ``"diagonal"`` for
        ``param="lam_diag"``); its current state
        ``(x, P)`` starts every run (a new filter: ``x0``, ``P0``), with ``P``
        relative to its ``R`` (``P0 = p0 R`` in the scale-free
        parametrization). It is left unchanged unless `apply`.
    zs, Hs : array_like
        The record, as for ``batch_filter``; NaN in `zs` marks missing samples.
    param : {"q", "lam", "q_diag", "lam_diag"}, default "q"
        What to estimate: ``"q"``, the random walk ``Q = q R I`` (the filter's
        ``lam`` kept); ``"lam"``, the forgetting factor (the filter's ``Q / R``
        kept); ``"q_diag"``, a diagonal random walk ``Q = R diag(q)``;
        ``"lam_diag"``, a forgetting factor per parameter (diagonal forgetting,
        :math:`P^- = L^{-1/2} P L^{-1/2} + Q`, :math:`L = \operatorname{diag}(\lambda)`:
        parameter ``i`` keeps a memory of about :math:`1 / (1 - \lambda_i)` samples;
        the filter's ``Q / R`` kept). `apply` runs it:
        ``RecursiveLeastSquares(forgetting="diagonal", lam=estimate)``, the same
        recursion. A filter with ``forgetting="diagonal"`` can be tuned for
        ``"lam_diag"`` only.
    bounds : (float, float), optional
        Search interval of the parameter: ``(0.5, 1.0)`` for ``lam`` and each
        entry of ``lam_diag``,
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
    See the module docstring for the profile likelihood. Every likelihood
    evaluation is one compiled pass of the filter with its sensitivity
    recursions (the exact derivatives of ``x``, ``P``, the innovations and their
    variances with respect to the search variable). The search runs on
    :math:`\log(1 - \lambda)` or :math:`\log q`: one variable by a safeguarded
    Newton search (the exact second derivative at the start, then the slopes of
    the quadratic interpolation of the exact first derivatives, steps halved
    until the likelihood rises), the whole search one compiled call;
    ``"q_diag"`` by a projected Newton search on the exact gradient and Hessian
    (from the scalar estimate), also one compiled call; ``"lam_diag"`` by
    L-BFGS-B on the exact gradient (from the scalar estimate). A last step
    short enough is taken on the local quadratic model of the likelihood
    without a pass (the log-likelihood and ``R`` there from their Taylor
    expansions). The standard errors come from the observed information
    :math:`-\partial^2 \ell_p / \partial v^2` in the search variable ``v``
    (exact for ``"q_diag"`` and ``"lam_diag"``; the converged interpolated slope
    for one variable), mapped to the parameter by the delta method.

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
    mode = getattr(filt, "forgetting", None)
    if mode == "diagonal" and param != "lam_diag":
        raise ValueError("`tune` of a filter with forgetting='diagonal' estimates "
                         f"param='lam_diag' only; got {param!r}")
    if mode not in ("exponential", "diagonal"):
        raise ValueError("`tune` needs a RecursiveLeastSquares with forgetting='exponential' "
                         "(a Kalman time update P / lam + Q)")
    if type(burn) is not int or burn < 0:
        burn = check_int(burn, "burn", minimum=0)
    bounds = _bounds(param, bounds)
    R0 = filt.R
    if param == "q" or param == "lam":
        # the lean path of one variable: a record of C-contiguous float64 arrays of the
        # usual shapes goes to the kernel as it is, screened there (`scalar_search`);
        # anything else (or a record that fails the screen) is validated here
        plain = _plain_record(zs, Hs, filt.dim_x, filt.dim_z)
        if plain is not None:
            Z, Hm = plain
        else:
            Z, Hm = filt._as_batch(zs, Hs)
            Z, Hm = np.ascontiguousarray(Z, dtype=np.float64), np.ascontiguousarray(Hm, np.float64)
        x_start = np.ascontiguousarray(filt.x, dtype=np.float64)
        # (a copy, kept by the result's profile; P / 1 is P: no division where R is 1)
        P_rel = np.ascontiguousarray(filt.P.copy() if R0 == 1.0 else filt.P / R0,
                                     dtype=np.float64)
        Q_rel = None if param == "q" else np.ascontiguousarray(filt.Q / R0, dtype=np.float64)
        out = _tune_scalar(Z, Hm, x_start, P_rel, Q_rel, filt.lam, param, bounds, burn, True,
                           screen=plain is not None)
        if out is None:                  # the screen failed: the validation names the entry
            filt._as_batch(zs, Hs)
            raise ValueError("`zs` must hold no infinity and `Hs` must be finite")
    else:
        Z, Hm = filt._as_batch(zs, Hs)
        lam0 = float(np.min(filt.lam))          # (a diagonal filter: its smallest factor)
        out = _tune_record(Z, Hm, filt.x, filt.P / R0, filt.Q / R0, lam0, param, bounds,
                           burn, keep=True)
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


def _tune_record(Z, Hm, x_start, P_rel, Q_rel, lam0, param, bounds, burn, keep=False):
    """`tune` on a validated record ``Z`` (N, m), ``Hm`` (N, n) from ``x_start`` (n, m),
    with ``P`` and ``Q`` relative to ``R``; returns the `TuneResult` (with `keep`, one
    that keeps the record for its `TuneResult.profile`)."""
    n, m = x_start.shape
    x_start = np.ascontiguousarray(x_start, dtype=np.float64)
    P_rel = np.ascontiguousarray(P_rel, dtype=np.float64)
    Zc, Hc = np.ascontiguousarray(Z, dtype=np.float64), np.ascontiguousarray(Hm, dtype=np.float64)
    Q_rel = np.ascontiguousarray(Q_rel, dtype=np.float64)
    if param in ("q", "lam"):
        return _tune_scalar(Zc, Hc, x_start, P_rel, Q_rel, lam0, param, bounds, burn, keep)
    v_lo, v_hi, v0 = _search_interval(param, bounds, lam0, n)
    # (for q_diag, the Newton search needs no more than a start: the scalar search to 1e-2
    # in log q, about two passes fewer)
    one = _tune_scalar(Zc, Hc, x_start, P_rel, Q_rel, lam0, param[:-5], bounds, burn, False,
                       xtol=1e-2 if param == "q_diag" else 1e-8)
    evals = [one.n_evals]                # start from the scalar estimate
    v0 = np.clip(np.full(n, math.log(one.estimate) if param == "q_diag" else one.estimate),
                 v_lo, v_hi)

    if param == "q_diag":                # the whole Newton search one compiled call
        v, ll, sigma2, n_obs, grad, hess, converged, fixed, passes = _kernels().diag_search(
            x_start, P_rel, Zc, Hc, 1.0 / lam0, burn, v0, v_lo, v_hi, 4.0, 100, 1e-8,
            _dims(n))
        evals[0] += passes
    else:
        def run(v, order):
            evals[0] += 1
            return _profile(x_start, P_rel, Zc, Hc, _model(param, v, n, lam0, Q_rel), burn, m,
                            order)

        v, (ll, sigma2, n_obs, grad, hess), converged, fixed = _quasi_newton(run, v0, v_lo,
                                                                             v_hi)
    at_bound = bool(np.any(fixed))
    se_v = np.full(len(v), np.nan)
    free = ~np.asarray(fixed)            # no curvature to read on a bound
    if free.any():
        try:                             # the observed information of the free variables
            d = np.diag(np.linalg.inv(-hess[np.ix_(free, free)]))
            se_v[free] = np.where(d > 0, np.sqrt(np.abs(d)), np.nan)
        except np.linalg.LinAlgError:
            pass
    if param == "lam_diag":
        estimate, stderr, log_se = v, se_v, None
    else:
        estimate = np.exp(v)
        stderr, log_se = estimate * se_v, se_v
    out = TuneResult(param, estimate, stderr, ll, sigma2, converged and not at_bound, at_bound,
                     n_obs, evals[0], _log_stderr=log_se, _gradient=grad, _hessian=hess)
    out._bounds = bounds
    return out


def _tune_scalar(Z, H, x_start, P_rel, Q_rel, lam0, param, bounds, burn, keep, screen=False,
                 xtol=1e-8):
    """`_tune_record` of ``"q"`` or ``"lam"`` (contiguous float64 arrays; `Q_rel` unused
    for ``"q"``): the whole search is one compiled call (`_kernels_tuning.scalar_search`).
    With `screen`, the kernel screens the record first, and None is returned when it
    fails (`tune` validates it again, to name the bad entry)."""
    kern = _kernels()
    lo, hi = bounds
    if param == "q":                     # v = log q, Q = exp(v) I
        kind, Qb = 0, None               # None: the identity (a pass of its own, leaner)
        if bounds == _Q_BOUNDS:
            v_lo, v_hi, v0 = _Q_SEARCH
        else:
            v_lo, v_hi = math.log(lo), math.log(hi)
            v0 = min(max(math.log(1e-3), v_lo), v_hi)
    else:                                # v = log(1 - lam): lam = 1 is v = log(_LAM_GAP)
        kind, Qb = 1, np.triu(Q_rel) + np.triu(Q_rel, 1).T   # its upper triangle, as before
        start = lam0 if lo < lam0 < hi else min(max(0.99, 0.5 * (lo + hi)), hi)
        v_lo, v_hi = math.log(max(1.0 - hi, _LAM_GAP)), math.log(1.0 - lo)
        v0 = min(max(math.log(max(1.0 - start, _LAM_GAP)), v_lo), v_hi)
    dims = _DIMS.get(len(P_rel))
    if dims is None:
        dims = _DIMS[len(P_rel)] = _dims(len(P_rel))
    v, ll, sigma2, n_obs, g, h, converged, held, passes = kern.scalar_search(
        x_start, P_rel, Z, H, Qb, kind, lam0, burn, v0, v_lo, v_hi, 4.0, 100, xtol, screen,
        dims)
    if n_obs < 0:
        return None
    if n_obs == 0:
        raise ValueError("`zs` has no measurement left for the likelihood (all missing "
                         "or burnt in)")
    # the observed information -h (none on a bound), by the delta method to the parameter
    log_se = math.sqrt(-1.0 / h) if (not held and h < 0.0) else math.nan
    if param == "lam":                   # lam = 1 - exp(v)
        gap = math.exp(v)
        if held and v <= v_lo and hi == 1.0:
            gap = 0.0                    # the upper bound lam = 1 itself
            work = kern.scalar_work(*x_start.shape)
            ll, sigma2, n_obs = kern.scalar_profile(x_start, P_rel, Z, H, Qb, kind, -math.inf,
                                                    lam0, burn, 0, work, dims)[:3]
        estimate, stderr = 1.0 - gap, gap * log_se
    else:
        estimate = math.exp(v)
        stderr = estimate * log_se
    loglik_at = None
    if keep:                             # the profile at a value of lam or q (the record kept)
        def loglik_at(value):
            if param == "lam":
                w = math.log(1.0 - value) if value < 1.0 else -math.inf
            else:
                w = math.log(value) if value > 0 else -math.inf
            return kern.scalar_profile(x_start, P_rel, Z, H, Qb, kind, w, lam0, burn, 0,
                                       kern.scalar_work(*x_start.shape), dims)[0]
    out = TuneResult(param, estimate, stderr, ll, sigma2, converged and not held, held,
                     n_obs, passes, _log_stderr=log_se, _gradient=g, _hessian=h,
                     _loglik_at=loglik_at)
    out._bounds = bounds
    return out


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _plain_record(zs, Hs, n, m):
    """``(Z, H)``, shapes (N, m) and (N, n), when `zs` and `Hs` are C-contiguous float64
    arrays of the shapes ``batch_filter`` takes (``zs`` (N,) for one output): views of
    them, not checked for infinities (`scalar_search` screens them); else None."""
    if (type(zs) is not np.ndarray or type(Hs) is not np.ndarray or zs.dtype is not _F64
            or Hs.dtype is not _F64 or Hs.ndim != 2 or Hs.shape[1] != n):
        return None
    if zs.ndim == 1 and m == 1:
        Z = zs.reshape(-1, 1)
    elif zs.ndim == 2 and zs.shape[1] == m:
        Z = zs
    else:
        return None
    if len(Z) != len(Hs) or not (Z.flags.c_contiguous and Hs.flags.c_contiguous):
        return None
    return Z, Hs


def _dims(n):
    """The dimension witness of the searches' passes (`_kernels_tuning.scalar_pass`,
    `diag_pass`): a tuple of `n` zeros for the sizes of `_SPECIALISED` (``n`` a constant
    of the compiled pass), else an array of length `n` (one compiled pass for every other
    size)."""
    return (0,) * n if n in _SPECIALISED else np.zeros(n, dtype=np.int8)


def _bounds(param, bounds):
    """The search interval of `param` (checked)."""
    if bounds is None:
        return (0.5, 1.0) if param in ("lam", "lam_diag") else _Q_BOUNDS
    try:
        lo, hi = (float(b) for b in bounds)
    except (TypeError, ValueError):
        raise TypeError(f"`bounds` must be a pair of numbers; got {bounds!r}") from None
    is_lam = param in ("lam", "lam_diag")
    ok = (0.0 < lo < hi <= 1.0) if is_lam else (0.0 < lo < hi < math.inf)
    if not ok:
        allowed = "0 < low < high <= 1" if is_lam else "0 < low < high < inf"
        raise ValueError(f"`bounds` must satisfy {allowed} for {param!r}; got {bounds!r}")
    return lo, hi


def _search_interval(param, bounds, lam0, n):
    """``(low, high, start)`` of the search variable of ``"q_diag"`` (``log q``) or
    ``"lam_diag"`` (``lam`` itself), arrays of length `n`."""
    lo, hi = bounds
    if param == "lam_diag":
        start = lam0 if lo < lam0 < hi else min(max(0.99, 0.5 * (lo + hi)), hi)
        return np.full(n, lo), np.full(n, hi), np.full(n, start)
    v_lo, v_hi = math.log(lo), math.log(hi)
    start = min(max(math.log(1e-3), v_lo), v_hi)
    return np.full(n, v_lo), np.full(n, v_hi), np.full(n, start)


def _model(param, v, n, lam0, Q_rel):
    """The time update ``P^- = A * P + Q`` at the search variable `v` and the derivatives
    ``(A, Q, dA, dQ, d2A, d2Q)`` of `A` and `Q` in `v` (the kernel's arguments)."""
    k = len(v)
    dA, dQ = np.zeros((k, n, n)), np.zeros((k, n, n))
    d2A, d2Q = np.zeros((k, k, n, n)), np.zeros((k, k, n, n))
    if param == "q":                     # Q = exp(v) I: dQ = d2Q = Q
        A = np.full((n, n), 1.0 / lam0)
        Q = math.exp(v[0]) * np.eye(n)
        dQ[0] = d2Q[0, 0] = Q
    elif param == "q_diag":              # Q = diag(exp(v)): dQ_a = d2Q_aa = exp(v_a) E_aa
        A = np.full((n, n), 1.0 / lam0)
        q = np.exp(v)
        Q = np.diag(q)
        for a in range(k):
            dQ[a, a, a] = d2Q[a, a, a, a] = q[a]
    elif param == "lam":                 # A = 1 / lam, lam = 1 - exp(u)
        d = math.exp(v[0])               # 1 - lam
        lam = 1.0 - d
        A = np.full((n, n), 1.0 / lam)
        Q = Q_rel
        dA[0] = d / (lam * lam)                              # dA/du = (1 - lam) / lam^2
        d2A[0, 0] = d * (2.0 - lam) / lam ** 3               # (1 - lam)(2 - lam) / lam^3
    else:                                # A_ij = (lam_i lam_j)^(-1/2), c_a = [i = a] + [j = a]
        lam = np.asarray(v, dtype=float)
        w = 1.0 / np.sqrt(lam)
        A = np.outer(w, w)
        Q = Q_rel
        eye = np.eye(n)
        c = 0.5 * (eye[:, :, None] + eye[:, None, :])        # c[a] / 2
        for a in range(k):
            dA[a] = -A * c[a] / lam[a]
            for b in range(k):
                d2A[a, b] = A * c[a] * c[b] / (lam[a] * lam[b])
            d2A[a, a] += A * c[a] / lam[a] ** 2
    return A, np.ascontiguousarray(Q, dtype=np.float64), dA, dQ, d2A, d2Q


def _profile(x_start, P_rel, Z, H, model, burn, m, order):
    r"""``(loglik, sigma2, n_obs, gradient, Hessian)`` of the profile log-likelihood at one
    point (one compiled pass; the derivatives in the search variable when `order` asks).

    With ``slog = sum log s_t`` and ``sq = sum y_t^2 / s_t`` over ``N`` outputs:
    :math:`\ell_p = -\tfrac12 (N (\log 2\pi + \log(sq/N) + 1) + m\,slog)`,
    :math:`\partial_a \ell_p = -\tfrac12 (N\,sq_a / sq + m\,slog_a)`,
    :math:`\partial_{ab} \ell_p = -\tfrac12 (N (sq_{ab}/sq - sq_a sq_b / sq^2) + m\,slog_{ab})`.
    """
    slog, sq, n_obs, dslog, dsq, d2slog, d2sq = _kernels().profile_derivs(
        x_start, P_rel, Z, H, *model, burn, order)
    if n_obs == 0:
        raise ValueError("`zs` has no measurement left for the likelihood (all missing "
                         "or burnt in)")
    sigma2 = sq / n_obs                                      # sigma^2 = mean(y^2 / s)
    ll = -0.5 * (n_obs * (_LOG_2PI + math.log(sigma2) + 1.0) + m * slog)
    grad = -0.5 * (n_obs * dsq / sq + m * dslog)
    hess = -0.5 * (n_obs * (d2sq / sq - np.outer(dsq, dsq) / sq ** 2) + m * d2slog)
    return ll, sigma2, n_obs, grad, hess


def _quasi_newton(run, v0, lo, hi):
    """Maximize the profile log-likelihood of several variables in the box ``[lo, hi]`` by
    L-BFGS-B on the exact gradients (`run(v, 1)`), then one pass with the exact Hessian
    (`run(v, 2)`) for the observed information. Returns ``(v, (loglik, sigma2, n_obs,
    gradient, Hessian), converged, held)``. (``ftol = 1e-12``: a relative change of
    the likelihood of 1e-12 moves the estimates by about 1e-7 of themselves; a
    tighter one only adds line searches lost in round-off.)"""
    from scipy.optimize import minimize  # lazy: keeps `import rlsfilt` light

    def negll(v):
        out = run(v, 1)
        return -out[0], -out[3]

    res = minimize(negll, np.clip(v0, lo, hi), jac=True, method="L-BFGS-B",
                   bounds=list(zip(lo, hi, strict=True)),
                   options={"ftol": 1e-12, "gtol": 1e-8, "maxiter": 500})
    v = np.asarray(res.x, dtype=float)
    out = run(v, 2)
    grad = out[3]
    held = ((v <= lo) & (grad < 0)) | ((v >= hi) & (grad > 0))
    # (a line search that stops at round-off is converged when the gradient is nil:
    # 1e-4 per unit of log q moves q by less than 1e-5 of itself at any usual curvature)
    free = ~held
    converged = bool(res.success) or float(np.max(np.abs(grad[free]), initial=0.0)) < 1e-4
    return v, out, converged, held
