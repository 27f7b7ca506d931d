r"""Residual analysis: whiteness and independence of the one-step residuals.

A model structure is adequate when its one-step prediction errors
:math:`\varepsilon(t)` are white (nothing left to predict from the past) and
independent of past inputs (nothing left to explain from the input), as in
MATLAB's ``resid`` and Ljung (1999, sec. 16.6).
"""

import numpy as np

from .._display import Summary, frame_html, table_html
from .._scale import pow2_scale
from .._validation import check_int, check_probability
from ..exceptions import ExactFitError, InsufficientDataError
from ..models._residual_tests import auto_max_lag, input_lag_test
from ..models.regressors import _as_signal
from ..plotting import plot_autocorrelation, plot_cross_correlation, plot_residuals
from ._model import one_step_records

__all__ = ["ResidualAnalysis", "residual_analysis"]


class ResidualAnalysis:
    r"""Correlation tests of a model's one-step residuals.

    Attributes
    ----------
    residuals : ndarray, shape (n,)
        One-step residuals :math:`\varepsilon(t)` on the rows with a complete
        regressor.
    lags : ndarray of int, shape (max_lag + 1,)
        ``0 .. max_lag``, the lags of `autocorrelation`.
    autocorrelation : ndarray, shape (max_lag + 1,)
        Normalized autocorrelation :math:`\hat\rho_\varepsilon(k)`
        (1 at lag 0).
    autocorrelation_band : float
        Half-width of the ``1 - alpha`` band under whiteness,
        :math:`z_{1-\alpha/2} / \sqrt{n}`.
    cross_lags : ndarray of int, shape (2 max_lag + 1,)
        ``-max_lag .. max_lag``, the lags :math:`\tau` of
        `cross_correlation`; positive :math:`\tau` pairs
        :math:`\varepsilon(t)` with the past input :math:`u(t-\tau)`.
    cross_correlation : ndarray, shape (nu, 2 max_lag + 1)
        Normalized cross-correlation :math:`\hat\rho_{\varepsilon u}(\tau)`
        with each input.
    cross_correlation_band : ndarray, shape (nu,)
        Half-width of the ``1 - alpha`` band for each input.
    q_statistic, df_white, pvalue_white : float, int, float
        Ljung-Box statistic, its degrees of freedom and p-value.
    f_statistic, df_independent, pvalue_independent : float, int, float
        F statistic of the input-lag test, its numerator degrees of freedom
        and p-value.
    is_white : bool
        ``pvalue_white > alpha``: whiteness is not rejected at level `alpha`.
    is_independent : bool or None
        ``pvalue_independent > alpha``: independence is not rejected at level
        `alpha`. None for a time series (AR, ARMA: no input, so no
        cross-correlation and no independence test; `cross_correlation` has
        zero rows and the F statistic and its p-value are NaN).
    alpha : float
        Significance level.
    max_lag : int
        Largest lag.
    output : int
        Which output's residual was analysed.
    """

    def __init__(self, **fields):
        for key, value in fields.items():
            setattr(self, key, value)

    def __repr__(self):
        indep = (f"independent={self.is_independent} (p={self.pvalue_independent:.3g})"
                 if self.has_input else "no input (time series)")
        return (f"<ResidualAnalysis: white={self.is_white} (p={self.pvalue_white:.3g}), "
                f"{indep}, alpha={self.alpha:g}, max_lag={self.max_lag}>")

    @property
    def has_input(self):
        """False for a time series (no input: only the whiteness test ran)."""
        return self.is_independent is not None

    def summary(self):
        """The two tests and their decisions, a line each.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table).
        """
        white = (f"  whiteness (Ljung-Box, {self.df_white} df): Q = {self.q_statistic:.4g}, "
                 f"p = {self.pvalue_white:.4g} -> {'white' if self.is_white else 'NOT white'}")
        rows = [["whiteness (Ljung-Box)", self.df_white, f"Q = {self.q_statistic:.4g}",
                 f"{self.pvalue_white:.4g}", "white" if self.is_white else "NOT white"]]
        if not self.has_input:
            text = white + "\n  independence of inputs: not applicable (time series: no input)"
            rows.append("independence of inputs: not applicable (time series: no input)")
        else:
            text = "\n".join([
                white,
                f"  independence of inputs (F, {self.df_independent} df): "
                f"F = {self.f_statistic:.4g}, p = {self.pvalue_independent:.4g} -> "
                f"{'independent' if self.is_independent else 'NOT independent'}",
            ])
            rows.append(["independence of inputs (F)", self.df_independent,
                         f"F = {self.f_statistic:.4g}", f"{self.pvalue_independent:.4g}",
                         "independent" if self.is_independent else "NOT independent"])
        page = frame_html(f"Residual tests (alpha = {self.alpha:g}, max lag {self.max_lag})",
                          table_html(["test", "df", "statistic", "p", "decision"], rows))
        return Summary(text, page)

    # the figures: each method is its plotting function applied to this analysis, which
    # documents the argument and the return value
    def plot(self, fig=None):
        """Autocorrelation and input cross-correlations with their bands (MATLAB ``resid``).

        Refer to :func:`rlsfilt.plotting.plot_residuals` for full documentation.
        """
        return plot_residuals(self, fig)

    def plot_autocorrelation(self, ax=None):
        r"""Stem plot of :math:`\hat\rho_\varepsilon(k)` with its band.

        Refer to :func:`rlsfilt.plotting.plot_autocorrelation` for full documentation.
        """
        return plot_autocorrelation(self, ax)

    def plot_cross_correlation(self, ax=None):
        r"""Cross-correlation :math:`\hat\rho_{\varepsilon u}(\tau)` with each input.

        Refer to :func:`rlsfilt.plotting.plot_cross_correlation` for full documentation.
        """
        return plot_cross_correlation(self, ax)


def residual_analysis(model, u, y=None, max_lag="auto", alpha=0.01, *, output=0, model_df=0):
    r"""Whiteness and input-independence tests of the one-step residuals.

    Parameters
    ----------
    model : IdentifiedModel
        A fitted model (`ARX` or any other `IdentifiedModel`).
    u : array_like, shape (N,) or (N, nu), IOData, or None
        Input record (estimation or validation data), or an `IOData` with
        inputs and outputs (then `y` is omitted: pass `max_lag` and `alpha`
        by keyword). Several experiments (an `IOData` or lists of arrays)
        are analysed as :func:`validate` does: the residuals of every
        experiment one after the other, each from its own start. None for a
        time series (`AR`, `ARMA`), which gets the whiteness test only.
    y : array_like, shape (N,) or (N, ny)
        Output record.
    max_lag : int or "auto", default "auto"
        Largest lag :math:`M` of the correlations. ``"auto"`` (as in
        :func:`validate` and the command line): ``min(25, n // 4)`` for ``n``
        residuals (25 is MATLAB ``resid``'s default), halved while the
        record is too short for the tests at that lag (down to
        ``model_df + 1``), so a short validation record (100 samples) is
        analysed; an integer is used as given.
    alpha : float, default 0.01
        Significance level of the tests and of the plotted bands (MATLAB's
        99% band).
    output : int, default 0
        Which output's residual to analyse, for models with several outputs.
    model_df : int, default 0
        Degrees of freedom subtracted from the Ljung-Box test. ``0`` is the
        plain :math:`\chi^2(M)` of Ljung (1999) and MATLAB's ``resid``.
        For a pure autoregression Box & Pierce (1970) subtract ``na``,
        because the fitted AR part makes low-lag residual correlations
        small; with an exogenous input that explains most of the output the
        reduction vanishes, so ``na`` would make the test too liberal. The
        default is therefore exact at high signal-to-noise ratio and
        conservative (fewer false alarms) at low.

    Returns
    -------
    ResidualAnalysis

    Notes
    -----
    With :math:`n` residuals, centered, and
    :math:`\hat R_\varepsilon(k) = \frac1n \sum_t \varepsilon(t)\varepsilon(t-k)`,
    the autocorrelation is :math:`\hat\rho_\varepsilon(k) = \hat
    R_\varepsilon(k) / \hat R_\varepsilon(0)`. **Whiteness** is tested with
    the Ljung-Box portmanteau statistic

    .. math::

        Q = n (n + 2) \sum_{k=1}^{M} \frac{\hat\rho_\varepsilon(k)^2}{n - k}
        \;\sim\; \chi^2(M - \mathtt{model\_df})

    (Ljung & Box 1978), the same as ``statsmodels.stats.diagnostic.
    acorr_ljungbox(e, lags=[M], model_df=model_df)``.

    The cross-correlation with input :math:`u` (centered) is
    :math:`\hat\rho_{\varepsilon u}(\tau) = \hat R_{\varepsilon u}(\tau) /
    \sqrt{\hat R_\varepsilon(0) \hat R_u(0)}`,
    :math:`\hat R_{\varepsilon u}(\tau) = \frac1n \sum_t \varepsilon(t)
    u(t - \tau)`. If :math:`\varepsilon` is white and independent of
    :math:`u`, :math:`\sqrt n\,\hat\rho_{\varepsilon u}(\tau)` is
    asymptotically normal with variance
    :math:`P = \sum_{k=-M}^{M} \hat\rho_\varepsilon(k) \hat\rho_u(k)`
    (Ljung 1999, sec. 16.6), which gives the plotted band
    :math:`\pm z_{1-\alpha/2} \sqrt{P / n}`.

    **Independence** is tested jointly over all lags and inputs by the
    Lagrange-multiplier (Breusch-Godfrey) form of Ljung's test: the
    residuals are regressed on the model's regressors, a constant, and the
    lagged inputs :math:`u(t-\tau)`, :math:`|\tau| \le M`, and the
    improvement over the regressors alone is tested with

    .. math::

        F = \frac{(\mathrm{RSS}_0 - \mathrm{RSS}_1) / q}
                 {\mathrm{RSS}_1 / (n' - p)} \;\sim\; F(q, n' - p),

    where :math:`q` is the number of lagged-input directions not already in
    the regressors (the lags :math:`n_k \dots n_k + n_b - 1` are, so they
    cannot be tested) and :math:`p` the rank of the full regression over
    the :math:`n'` rows where every lag exists. Unlike a sum of squared
    cross-correlations this keeps its level for colored inputs and on
    estimation data, where least squares makes the residuals orthogonal to
    the regressors.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 16.6.
    .. [2] G. E. P. Box and D. A. Pierce, "Distribution of residual
       autocorrelations in autoregressive-integrated moving average time
       series models", *J. Am. Stat. Assoc.* 65(332), 1509-1526, 1970.
    .. [3] G. M. Ljung and G. E. P. Box, "On a measure of lack of fit in time
       series models", *Biometrika* 65(2), 297-303, 1978.
    .. [4] L. G. Godfrey, "Testing against general autoregressive and moving
       average error models when the regressors include lagged dependent
       variables", *Econometrica* 46(6), 1293-1301, 1978.

    Examples
    --------
    A first-order model of a second-order plant leaves colored residuals:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import ARX
    >>> from rlsfilt.validation import residual_analysis
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(1000)
    >>> e = 0.1 * rng.standard_normal(1000)
    >>> y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1], [1, -1.5, 0.7], e)
    >>> residual_analysis(ARX(2, 2).fit(u, y), u, y).is_white
    True
    >>> residual_analysis(ARX(1, 1).fit(u, y), u, y).is_white
    False
    """
    auto = isinstance(max_lag, str) and max_lag == "auto"
    if not auto:
        max_lag = check_int(max_lag, "max_lag", minimum=1)
    alpha = check_probability(alpha, "alpha")
    model_df = check_int(model_df, "model_df", minimum=0)
    Phi, E, U = one_step_records(model, u, y, "residual_analysis")
    if getattr(model, "n_inputs_", None) == 0:        # a time series: no input to test
        U = np.zeros((len(E) + model.max_lag, 0))
    if not auto:
        return _residual_analysis(Phi, E, U, max_lag, alpha, output, model_df)
    lag = max(auto_max_lag(len(E)), model_df + 1)
    while True:
        try:
            return _residual_analysis(Phi, E, U, lag, alpha, output, model_df)
        except InsufficientDataError:
            if lag // 2 <= model_df:     # no shorter lag leaves the Ljung-Box test a degree
                raise
            lag //= 2


def _residual_analysis(Phi, E, u, max_lag, alpha, output=0, model_df=0):
    """`residual_analysis` on the regressors `Phi` and residuals `E` (n, ny) of a model.

    `u` with zero columns (``(N, 0)``, a time series) gives the whiteness test
    only: no cross-correlation, ``is_independent`` None.
    """
    from scipy.stats import chi2, norm  # lazy: keeps `import rlsfilt` light
    ny = E.shape[1]
    output = check_int(output, "output", minimum=0)
    if output >= ny:
        raise ValueError(f"`output` must be < {ny} (the number of outputs); got {output}")
    model_df = check_int(model_df, "model_df", minimum=0)
    if model_df >= max_lag:
        raise ValueError(f"`max_lag` must exceed `model_df` = {model_df} (degrees of freedom "
                         f"left for the Ljung-Box test); got max_lag = {max_lag}")
    if isinstance(u, np.ndarray) and u.ndim == 2 and u.shape[1] == 0:
        U = u                      # a time series: no input
    else:
        U = _as_signal(u, "u")[0]  # (N, nu), validated by `one_step`
    e = E[:, output]
    n = len(e)
    N = len(U)
    t0 = N - n  # first row with a complete regressor
    if n <= 2 * max_lag + 2:
        raise InsufficientDataError(f"`max_lag` must be small against the {n} residuals (need n > "
                         f"2 max_lag + 2); got max_lag = {max_lag}")

    # every statistic below is invariant to the units of e and u: compute them on the
    # signals divided by powers of two near their largest entries (exact), so that
    # records around 1e160 or 1e-160 neither overflow nor underflow (rlsfilt._scale)
    es = e / pow2_scale(e)
    Us = U / pow2_scale(U, axis=0)

    # autocorrelation and Ljung-Box
    ec = es - es.mean()
    r0 = float(ec @ ec) / n
    if r0 == 0.0:
        raise ExactFitError("the residuals are constant (an exact fit); their correlations are "
                         "undefined")
    lags = np.arange(max_lag + 1)
    acf = np.array([ec[k:] @ ec[:n - k] for k in lags]) / (n * r0)
    z = norm.ppf(1.0 - alpha / 2.0)
    k = lags[1:]
    Q = float(n * (n + 2) * np.sum(acf[1:] ** 2 / (n - k)))
    df_white = max_lag - model_df
    p_white = float(chi2.sf(Q, df_white))

    # cross-correlations with each input and their bands; residual i is at time t0 + i and
    # pairs with u(t0 + i - tau) where that exists (slices: no index arrays of length n)
    taus = np.arange(-max_lag, max_lag + 1)
    Uc = Us - Us.mean(axis=0)
    nu = U.shape[1]
    ccf = np.zeros((nu, len(taus)))
    band = np.empty(nu)
    acf_sym = np.concatenate([acf[:0:-1], acf])  # rho_e(k), k = -M..M
    for j in range(nu):
        ru0 = float(Uc[:, j] @ Uc[:, j]) / N
        for i, tau in enumerate(taus):
            lo, hi = max(0, tau - t0), min(n, N - t0 + tau)
            if hi > lo:
                src = t0 + lo - tau
                ccf[j, i] = float(ec[lo:hi] @ Uc[src:src + hi - lo, j]) / n
        ccf[j] /= np.sqrt(r0 * ru0) if ru0 > 0 else np.inf
        acf_u = np.array([Uc[abs(kk):, j] @ Uc[:N - abs(kk), j] for kk in taus]) / (N * ru0) \
            if ru0 > 0 else np.zeros(len(taus))
        P = max(float(acf_sym @ acf_u), 0.0)
        band[j] = z * np.sqrt(P / n)

    # joint LM / F test of the lagged inputs given the regressors (none without an input)
    if nu:
        F, q, p_indep = input_lag_test(es, Phi, Us, t0, max_lag)
        independent = bool(p_indep > alpha)
    else:
        F, q, p_indep, independent = np.nan, 0, np.nan, None
    return ResidualAnalysis(
        residuals=e.copy(), lags=lags, autocorrelation=acf, autocorrelation_band=z / np.sqrt(n),
        cross_lags=taus, cross_correlation=ccf, cross_correlation_band=band,
        q_statistic=Q, df_white=df_white, pvalue_white=p_white,
        f_statistic=F, df_independent=q, pvalue_independent=p_indep,
        is_white=bool(p_white > alpha), is_independent=independent,
        alpha=alpha, max_lag=max_lag, output=output)
