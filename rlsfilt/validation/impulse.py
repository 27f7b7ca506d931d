r"""Impulse-response estimate with confidence bands (MATLAB's ``impulseest``).

A finite impulse response (FIR) model of every input,

.. math::

    y(t) = \sum_j \sum_{k=0}^{n-1} g_j(k)\, u_j(t-k) + v(t),

is fitted by least squares. The noise :math:`v` of a real record is colored,
which leaves the least-squares estimate consistent but makes its textbook
standard errors wrong; so the residuals of a first fit are described by a
long autoregression :math:`D(q) v(t) = e(t)` and the fit is repeated on the
prewhitened signals :math:`D(q) y` and :math:`D(q) u_j`, which have the same
impulse response and white noise (a two-step generalized least squares
estimate, Ljung 1999, sec. 7.6 and 8.5). The standard errors are then those
of ordinary least squares, :math:`\hat\sigma^2 (\Phi^\top\Phi)^{-1}`, from a
QR factorization.

By default (as MATLAB's ``impulseest``) the estimate is regularized instead: a
Gaussian prior on the coefficients, the TC kernel (or DC) whose hyperparameters
maximize the marginal likelihood of the data (empirical Bayes), gives the posterior
mean and covariance (:mod:`rlsfilt.validation._kernel_fir`; Chen, Ohlsson and Ljung
2012). It sees a long response, or one through a narrow-band input such as a
logarithmic sweep, where least squares with as many coefficients drowns in variance.
"""

import html
from collections import namedtuple

import numpy as np

from .._display import Summary, frame_html, table_html
from .._validation import check_int
from ..data.iodata import as_iodata
from ..plotting import plot_impulse
from ._kernel_fir import KERNEL_PARAMS, fit_kernel

__all__ = ["ImpulseResponse", "impulseest"]

_Band = namedtuple("Band", ["lower", "upper"])


class ImpulseResponse:
    r"""Result of :func:`impulseest`.

    Attributes
    ----------
    coefficients : ndarray, shape (n_coeffs, nu)
        :math:`g_j(k)`, lag ``k`` on axis 0, input ``j`` on axis 1.
    stderr : ndarray, shape (n_coeffs, nu)
        Their standard errors.
    lags : ndarray of int, shape (n_coeffs,)
        ``0 .. n_coeffs - 1`` (samples).
    dt : float or True
        Sampling period (True: unknown; lags are then in samples).
    input_names : tuple of str
    output_name : str
    noise_order : int
        Order of the autoregression that prewhitened the noise (0: none).
    noise_ar : ndarray
        Its polynomial ``[1, d1, .., d_p]``.
    n_rows : int
        Number of regression rows (over all experiments).
    regularization : {"tc", "dc"} or None
        The kernel of the regularized estimate (None: least squares).
    hyperparameters : dict or None
        The kernel's hyperparameters, each an array with one value per input
        (``c``, ``lam``; and ``rho`` for DC); None without regularization.
    log_marginal_likelihood : float or None
        :math:`\log p(Y \mid \eta)` of the regression at those
        hyperparameters (the maximum, unless they were given); None without
        regularization.
    noise_variance : float
        :math:`\hat\sigma^2`, from the least-squares residuals of the
        (prewhitened) regression.
    """

    def __init__(self, coefficients, stderr, dt, input_names, output_name, noise_ar, n_rows,
                 *, regularization=None, hyperparameters=None, log_marginal_likelihood=None,
                 noise_variance=None):
        self.coefficients = coefficients
        self.stderr = stderr
        self.lags = np.arange(coefficients.shape[0])
        self.dt = dt
        self.input_names = tuple(input_names)
        self.output_name = output_name
        self.noise_ar = noise_ar
        self.noise_order = len(noise_ar) - 1
        self.n_rows = n_rows
        self.regularization = regularization
        self.hyperparameters = hyperparameters
        self.log_marginal_likelihood = log_marginal_likelihood
        self.noise_variance = noise_variance

    def __repr__(self):
        return (f"<ImpulseResponse: {self.coefficients.shape[0]} coefficients per input, "
                f"inputs {list(self.input_names)}, first significant lag {self.delay()}>")

    @property
    def n_inputs(self):
        return self.coefficients.shape[1]

    def z_value(self, level=0.99, familywise=False):
        """The multiple of the standard error that bounds the band.

        Parameters
        ----------
        level : float, default 0.99
            Confidence level, in (0, 1).
        familywise : bool, default False
            Bonferroni over the ``n_coeffs`` lags of an input: the band then
            covers all of them together with probability `level`.
        """
        from scipy import stats

        if not 0 < level < 1:
            raise ValueError(f"`level` must be in (0, 1); got {level!r}")
        alpha = 1 - level
        if familywise:
            alpha /= self.coefficients.shape[0]
        return float(stats.norm.ppf(1 - alpha / 2))

    def band(self, level=0.99):
        """``(lower, upper)`` of the pointwise `level` confidence band, shape (n_coeffs, nu)."""
        z = self.z_value(level)
        return _Band(self.coefficients - z * self.stderr, self.coefficients + z * self.stderr)

    def significant(self, level=0.99, familywise=False):
        """Boolean (n_coeffs, nu): coefficients whose band excludes zero."""
        z = self.z_value(level, familywise)
        return np.abs(self.coefficients) > z * self.stderr

    def delay(self, level=0.99, familywise=False):
        """The first significant lag of each input (None where none is).

        Parameters
        ----------
        level : float, default 0.99
        familywise : bool, default False
            See :meth:`z_value`; :func:`~rlsfilt.delayest` checks its answer
            with ``familywise=True``, so that a chance excursion among the
            lags before the true delay is rare.

        Returns
        -------
        int, tuple of int, or None
            One value per input (a tuple for several inputs).
        """
        sig = self.significant(level, familywise)
        first = [int(np.argmax(sig[:, j])) if sig[:, j].any() else None
                 for j in range(self.n_inputs)]
        return first[0] if self.n_inputs == 1 else tuple(first)

    def truncated(self, level=0.99, n_tail=5):
        """Whether the response of each input has not died out within the lags estimated.

        True for an input when any of its last `n_tail` coefficients differs from zero at
        `level`: the FIR model then omits a tail that correlates with the coefficients kept
        (through the input's colour and the prewhitening), which biases them, so early lags
        can look significant that are not. Raise ``n_coeffs`` (as
        :func:`~rlsfilt.delayest` does before it trusts :meth:`delay`).

        Returns
        -------
        bool or tuple of bool
            One value per input (a tuple for several inputs).
        """
        n_tail = check_int(n_tail, "n_tail", minimum=1)
        out = [bool(v) for v in self.significant(level)[-n_tail:].any(axis=0)]
        return out[0] if self.n_inputs == 1 else tuple(out)

    def summary(self, level=0.99):
        """Per input the first significant lag and the significant coefficients.

        Parameters
        ----------
        level : float, default 0.99
            Confidence level of the bands that decide significance.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table).
        """
        z = self.z_value(level)
        if self.regularization is None:
            how = f"noise prewhitened by AR({self.noise_order})"
        else:
            hyp = ", ".join(f"{k} = " + ", ".join(f"{v:.3g}" for v in vals)
                            for k, vals in self.hyperparameters.items())
            how = (f"regularized by the {self.regularization.upper()} kernel ({hyp})"
                   + (f", noise prewhitened by AR({self.noise_order})" if self.noise_order
                      else ""))
        lines = [f"Impulse response estimate: {self.coefficients.shape[0]} coefficients per "
                 f"input, {self.n_rows} rows, {how}; "
                 f"{100 * level:g} % bands (+-{z:.3g} standard errors)"]
        sig = self.significant(level)
        rows = []
        for j, name in enumerate(self.input_names):
            ks = np.flatnonzero(sig[:, j])
            first = f"first significant lag {ks[0]}" if ks.size else "no significant lag"
            lags = f"{', '.join(map(str, ks[:12]))}{' ...' if ks.size > 12 else ''}"
            lines.append(f"  {name} -> {self.output_name}: {first}; significant at lags {lags}")
            if sig[-5:, j].any():
                lines.append(f"    (not died out within {self.coefficients.shape[0]} lags: the "
                             f"coefficients kept may be biased; raise n_coeffs)")
            rows.append([f"{name} -> {self.output_name}", ks[0] if ks.size else "none", lags])
        page = frame_html(html.escape(lines[0]),
                          table_html(["input -> output", "first significant lag",
                                      "significant lags"], rows))
        return Summary("\n".join(lines), page)

    def plot(self, ax=None, level=0.99):
        """Coefficients against lag with the `level` band (:func:`rlsfilt.plotting.plot_impulse`).

        Parameters
        ----------
        ax : matplotlib.axes.Axes or sequence of them, optional
            One per input.
        level : float, default 0.99

        Returns
        -------
        matplotlib.figure.Figure
        """
        return plot_impulse(self, ax=ax, level=level)


def impulseest(u, y=None, n_coeffs=None, *, regularization="tc", hyperparameters=None,
               noise_order="auto", dt=None):
    r"""Estimate the impulse response of every input, with confidence bands.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu), or IOData
        Input record, or an `IOData` holding inputs and outputs (then `y`
        is omitted); several experiments are used together, no regression
        row straddling two of them.
    y : array_like, shape (N,), optional
        Output record (one output).
    n_coeffs : int, optional
        Number of coefficients per input, lags ``0 .. n_coeffs - 1``;
        ``min(70, N // (4 nu))`` by default (MATLAB uses 70).
    regularization : {"tc", "dc", None}, default "tc"
        The prior of the regularized estimate (MATLAB's
        ``RegularizationKernel``, whose default is also TC): ``"tc"``
        (tuned/correlated, :math:`P_{kj} = c \lambda^{\max(k, j)}`),
        ``"dc"`` (diagonal/correlated, :math:`P_{kj} = c
        \lambda^{(k+j)/2} \rho^{|k-j|}`), one kernel per input, lags
        :math:`k = 1 .. n`; or None for (prewhitened) least squares.
    hyperparameters : dict, optional
        Fixed kernel hyperparameters instead of the marginal-likelihood
        optimum: ``{"c": .., "lam": ..}`` (and ``"rho"`` for DC), each a
        number or one per input, with ``c >= 0``, ``0 <= lam <= 1``,
        ``-1 <= rho <= 1``. Only with a `regularization`.
    noise_order : int or "auto", default "auto"
        Order of the autoregression that prewhitens the noise before the
        final fit (0: none). ``"auto"``: 10 for least squares, 0 for a
        regularized estimate (MATLAB's ``PW = 'auto'``).
    dt : float, optional
        Sampling period (for an IOData, its own).

    Returns
    -------
    ImpulseResponse
        ``.coefficients`` and ``.stderr`` of shape ``(n_coeffs, nu)`` (the
        posterior mean and standard deviations of a regularized estimate),
        ``.band(level)``, ``.delay()`` (the first significant lag per
        input), ``.summary()``, ``.plot()``; ``.hyperparameters`` and
        ``.log_marginal_likelihood`` of a regularized one.

    Raises
    ------
    ValueError
        Several outputs, a record too short for `n_coeffs` (fewer rows
        than coefficients), an unknown `regularization`, or
        `hyperparameters` missing a name, out of range, or given without a
        `regularization`.

    Notes
    -----
    The means of the whole record are removed first. With :math:`\Phi` the
    FIR regressors on rows :math:`t \ge n-1` of each experiment, the first
    estimate :math:`\hat g = \arg\min \lVert \Phi g - y \rVert` leaves
    residuals :math:`\hat v`; an AR(:math:`p`) fit :math:`\hat D` of them by
    least squares filters :math:`y` and every :math:`u_j`
    (:math:`\hat D(q) y = \sum_j G_j(q) \hat D(q) u_j + e`), and least
    squares on the filtered signals (rows :math:`t \ge n - 1 + p`) gives
    the estimate and its covariance :math:`\hat\sigma^2 (\Phi_f^\top
    \Phi_f)^{-1} = \hat\sigma^2 R^{-1} R^{-\top}` from :math:`\Phi_f = QR`.
    The input need not be white: a swept sine (chirp) works as long as it
    excites every frequency the response has.

    **Regularized estimate** (the default). The noise variance
    :math:`\hat\sigma^2` is that of the least-squares residuals; with the
    prior :math:`g \sim N(0, P(\eta))` the data are Gaussian,
    :math:`Y \sim N(0, \Phi P \Phi^\top + \hat\sigma^2 I)`, and the
    hyperparameters :math:`\eta` maximize that marginal likelihood
    (empirical Bayes, scipy's L-BFGS-B from several decay rates). The
    estimate is the posterior mean :math:`\hat g = (\Phi^\top\Phi +
    \hat\sigma^2 P^{-1})^{-1} \Phi^\top Y` and the bands come from the
    posterior covariance :math:`\hat\sigma^2 (\Phi^\top\Phi + \hat\sigma^2
    P^{-1})^{-1}`. The prior pulls the poorly excited directions toward a
    smooth, decaying response instead of letting them blow up: on a
    logarithmic sweep, which spends little time at high frequencies, least
    squares with 70 coefficients per input sees nothing while the
    regularized estimate shows the response and its delay. Bayesian bands
    are narrower where the prior is informative, and the estimate is
    biased toward zero there (the price of its lower variance);
    :func:`~rlsfilt.delayest` checks its delays with the least-squares
    estimate (``regularization=None``), whose tests it was calibrated on.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 6.1 and 7.6.
    .. [2] T. Chen, H. Ohlsson and L. Ljung, "On the estimation of transfer
       functions, regularizations and Gaussian processes - Revisited",
       *Automatica* 48(8), 1525-1535, 2012.
    .. [3] MATLAB System Identification Toolbox, ``impulseest`` and
       ``impulseestOptions``.

    Examples
    --------
    A plant with a dead time of 5 samples:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.validation import impulseest
    >>> rng = np.random.default_rng(1)
    >>> u = rng.standard_normal(2000)
    >>> y = lfilter([0] * 5 + [1.0, 0.5], [1, -0.7], u) + 0.1 * rng.standard_normal(2000)
    >>> g = impulseest(u, y, n_coeffs=30)
    >>> g.delay(), g.regularization
    (5, 'tc')
    >>> round(float(g.coefficients[5, 0]), 2)
    1.0
    """
    data = as_iodata(u, y, dt)
    if data.n_outputs != 1:
        raise ValueError(f"`y` must hold one output; got {data.n_outputs} (estimate the "
                         "impulse responses of each output separately)")
    if regularization is not None and regularization not in KERNEL_PARAMS:
        raise ValueError(f"`regularization` must be 'tc', 'dc' or None; got {regularization!r}")
    nu = data.n_inputs
    if n_coeffs is None:
        n_coeffs = max(min(70, min(data.lengths) // (4 * nu)), 1)
    n = check_int(n_coeffs, "n_coeffs", minimum=1)
    hyper = _hyperparameters(hyperparameters, regularization, nu)
    if isinstance(noise_order, str) and noise_order == "auto":
        noise_order = 10 if regularization is None else 0
    p = check_int(noise_order, "noise_order", minimum=0)
    arrays = list(data.arrays())
    mu_u = np.vstack([U for U, _ in arrays]).mean(axis=0)
    mu_y = np.vstack([Y for _, Y in arrays]).mean(axis=0)
    arrays = [(U - mu_u, Y[:, 0] - mu_y[0]) for U, Y in arrays]
    n_par = n * nu
    rows = sum(max(len(Y) - (n - 1) - p, 0) for _, Y in arrays)
    if rows <= n_par + p:
        raise ValueError(f"the record is too short for n_coeffs={n}: {data.n_samples} samples "
                         f"leave {rows} rows for {n_par} coefficients"
                         + (f" (and AR({p}) prewhitening)" if p else "")
                         + "; lower `n_coeffs` or `noise_order`")
    from scipy.signal import lfilter

    Phi, target = _fir_rows(arrays, n, 0)
    g = np.linalg.lstsq(Phi, target, rcond=None)[0]
    D = np.ones(1)
    if p:
        # the residuals of each experiment, then a long AR of them by least squares
        resid, start = [], 0
        for _, Y in arrays:
            m = max(len(Y) - (n - 1), 0)
            resid.append(target[start:start + m] - Phi[start:start + m] @ g)
            start += m
        lag_rows = [np.column_stack([-v[p - k:len(v) - k] for k in range(1, p + 1)])
                    for v in resid if len(v) > p]
        lag_tgt = [v[p:] for v in resid if len(v) > p]
        d = np.linalg.lstsq(np.vstack(lag_rows), np.concatenate(lag_tgt), rcond=None)[0]
        D = np.concatenate([[1.0], d])
        filtered = [(lfilter(D, [1.0], U, axis=0), lfilter(D, [1.0], Y)) for U, Y in arrays]
        Phi, target = _fir_rows(filtered, n, p)
    Q, R = np.linalg.qr(Phi)
    g = np.linalg.solve(R, Q.T @ target)
    res = target - Phi @ g
    dof = max(len(target) - n_par, 1)
    sigma2 = float(res @ res) / dof     # the least-squares noise variance (both estimates)
    lml = None
    if regularization is None:
        Rinv = np.linalg.solve(R, np.eye(n_par))
        var = sigma2 * np.sum(Rinv * Rinv, axis=1)     # diag(R^-1 R^-T)
    else:
        # posterior mean and covariance under the kernel prior (module _kernel_fir)
        g, cov, hyper, lml = fit_kernel(Phi, target, regularization, nu, n, sigma2, hyper)
        var = np.clip(np.diag(cov), 0.0, None)
        hyper = {k: np.array(v, dtype=float) for k, v in hyper.items()}
    # columns are ordered input by input: reshape to (nu, n) then transpose
    coeffs = g.reshape(nu, n).T
    stderr = np.sqrt(var).reshape(nu, n).T
    return ImpulseResponse(coeffs, stderr, data.dt, data.input_names, data.output_names[0], D,
                           len(target), regularization=regularization, hyperparameters=hyper,
                           log_marginal_likelihood=lml, noise_variance=sigma2)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _fir_rows(arrays, n, skip):
    """FIR regressors ``u_j(t - k)``, k = 0..n-1 (input by input), rows ``t >= n - 1 + skip``
    of each experiment, stacked; and the output on the same rows."""
    Phis, targets = [], []
    for U, Y in arrays:
        t0 = n - 1 + skip
        N = len(Y)
        if N <= t0:
            continue
        cols = [U[t0 - k:N - k, j] for j in range(U.shape[1]) for k in range(n)]
        Phis.append(np.column_stack(cols))
        targets.append(Y[t0:])
    return np.vstack(Phis), np.concatenate(targets)


def _hyperparameters(hyperparameters, regularization, nu):
    """The fixed hyperparameters as ``{name: array of nu}`` (validated), or None."""
    if hyperparameters is None:
        return None
    if regularization is None:
        raise ValueError("`hyperparameters` needs a `regularization` ('tc' or 'dc'); got "
                         "regularization=None")
    if not isinstance(hyperparameters, dict):
        raise TypeError(f"`hyperparameters` must be a dict such as {{'c': 1.0, 'lam': 0.9}}; "
                        f"got {type(hyperparameters).__name__}")
    names = KERNEL_PARAMS[regularization]
    if set(hyperparameters) != set(names):
        raise ValueError(f"`hyperparameters` of the {regularization.upper()} kernel must have "
                         f"the keys {list(names)}; got {sorted(hyperparameters)}")
    bounds = {"c": (0.0, np.inf), "lam": (0.0, 1.0), "rho": (-1.0, 1.0)}
    out = {}
    for name in names:
        v = np.array(hyperparameters[name], dtype=float).reshape(-1)
        if v.size == 1:
            v = np.repeat(v, nu)
        lo, hi = bounds[name]
        if v.size != nu or not np.all(np.isfinite(v)) or np.any(v < lo) or np.any(v > hi):
            raise ValueError(f"`hyperparameters['{name}']` must be one number in [{lo:g}, "
                             f"{hi:g}] or one per input ({nu}); got {hyperparameters[name]!r}")
        out[name] = v
    return out
