r"""Brown-Durbin-Evans tests of parameter constancy on recursive residuals.

The recursive residuals of a regression :math:`z_t = h_t^T x + v_t` are the
standardized one-step prediction errors of recursive least squares started
exactly on the first :math:`k` rows,

.. math::

    w_t = \frac{z_t - h_t^T \hat x_{t-1}}
               {\sqrt{1 + h_t^T (H_{t-1}^T H_{t-1})^{-1} h_t}},
    \qquad t = k+1, \dots, T,

which under constant parameters and Gaussian noise are independent
:math:`N(0, \sigma^2)` (Brown, Durbin & Evans 1975). They are computed here
with :class:`~rlsfilt.RecursiveLeastSquares` (``R = 1``, no forgetting,
:meth:`~rlsfilt.RecursiveLeastSquares.initialize` on the first rows), whose
``y / sqrt(S)`` is exactly :math:`w_t`. The CUSUM test looks for a drift of
their mean, the CUSUM of squares test for a drift of their variance.
"""

import math

import numpy as np

from .._scale import pow2_scale, unit_columns
from .._validation import as_float_array, check_finite, check_probability
from ..exceptions import ExactFitError
from ..filters import RecursiveLeastSquares
from ..models.regressors import _column_rank, _full_rank_rows
from ..plotting import plot_cusum

__all__ = ["CusumResult", "cusum", "cusum_squares", "recursive_residuals"]

# Brown, Durbin & Evans (1975), Table 1 / eq. (2.3)-(2.4): the constant `a` of
# the CUSUM lines for the three tabulated significance levels.
_BDE_A = {0.01: 1.143, 0.05: 0.948, 0.10: 0.850}

# Edgerton & Wells (1994), Table 1: response-surface coefficients
# c = c1 / sqrt(n) + c2 / n + c3 / n**1.5 approximating Durbin's (1969)
# critical values of the CUSUM of squares, indexed by the one-sided level.
_EW_LEVELS = (0.1, 0.05, 0.025, 0.01, 0.005)
_EW_COEF = {
    0.1: (1.0729830, -0.6698868, -0.5816458),
    0.05: (1.2238734, -0.6700069, -0.7351697),
    0.025: (1.3581015, -0.6701218, -0.8858694),
    0.01: (1.5174271, -0.6702672, -1.0847745),
    0.005: (1.6276236, -0.6703724, -1.2365861),
}


class CusumResult:
    r"""Outcome of :func:`cusum` or :func:`cusum_squares`.

    Attributes
    ----------
    kind : {"cusum", "cusum_squares"}
        Which test.
    statistic : ndarray, shape (m,)
        The path: :math:`W_r` (CUSUM) or :math:`S_r` (CUSUM of squares),
        one value per recursive residual.
    bounds : tuple of ndarray
        ``(lower, upper)``, each of shape ``(m,)``: the significance lines at
        the same points as `statistic`.
    rejected : bool
        True if the path leaves the band somewhere (parameter constancy is
        rejected at level `alpha`).
    alpha : float
        Significance level.
    index : ndarray of int, shape (m,)
        Sample (row) index of each point of the path.
    residuals : ndarray, shape (m,)
        The recursive residuals :math:`w_t` used.
    start : int
        Number of rows spent on the exact start (``k`` for a regressor of
        full column rank on its first ``k`` rows).
    crossings : ndarray of int
        Row indices where the path is outside the band (empty if none).
    pvalue : float or None
        CUSUM: the probability of a crossing of the BDE lines at least as far
        as observed (from the same boundary-crossing formula that gives the
        bounds). ``None`` for the CUSUM of squares, whose critical values are
        only tabulated.
    critical_value : float
        ``a`` for the CUSUM lines, :math:`c_0` for the CUSUM of squares.
    """

    def __init__(self, kind, statistic, bounds, alpha, index, residuals, start,
                 critical_value, pvalue=None):
        self.kind = kind
        self.statistic = statistic
        self.bounds = bounds
        self.alpha = alpha
        self.index = index
        self.residuals = residuals
        self.start = start
        self.critical_value = critical_value
        self.pvalue = pvalue
        outside = (statistic < bounds[0]) | (statistic > bounds[1])
        self.crossings = index[outside]
        self.rejected = bool(outside.any())

    def __repr__(self):
        name = "CUSUM" if self.kind == "cusum" else "CUSUM of squares"
        p = "" if self.pvalue is None else f", pvalue={self.pvalue:.4g}"
        return (f"<CusumResult {name}: rejected={self.rejected} at alpha={self.alpha:g}"
                f"{p}, {len(self.statistic)} recursive residuals>")

    def plot(self, ax=None, t=None):
        """Plot the path and its significance band (:func:`rlsfilt.plotting.plot_cusum`).

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional
            Axes to draw in; a new figure is made if omitted.
        t : array_like, shape (N,), optional
            Time or sample number of each regression row, so the marks read
            in the record's samples (for ARX regressors row ``r`` is sample
            ``r + max_lag``); the row index by default.

        Returns
        -------
        matplotlib.axes.Axes
        """
        return plot_cusum(self, ax, t=t)


def recursive_residuals(zs, Hs):
    r"""Recursive residuals of the regression ``zs = Hs x + v``.

    Parameters
    ----------
    zs : array_like, shape (N,)
        Measurements.
    Hs : array_like, shape (N, k)
        Regressor rows (for an ARX model, the ``Phi`` of its
        ``regressors(u, y)``).

    Returns
    -------
    w : ndarray, shape (N - start,)
        Recursive residuals :math:`w_t` for rows ``start, ..., N - 1``.
    start : int
        Number of rows used for the exact start: the smallest ``k0 >= k``
        whose first ``k0`` rows have rank ``k``.

    Notes
    -----
    Recursive least squares with ``R = 1`` is started by
    :meth:`~rlsfilt.RecursiveLeastSquares.initialize` on the first ``start``
    rows (so the recursion equals ordinary least squares on all rows so far),
    and its :meth:`~rlsfilt.RecursiveLeastSquares.batch_filter` over the
    remaining rows gives the prior estimate and covariance of each step, so
    :math:`w_t = y_t / \sqrt{S_t}` with ``y`` the a-priori residual
    :math:`z_t - h_t^T x_{t-1}` and :math:`S_t = 1 + h_t^T P_{t-1} h_t`
    (the filter's ``y`` and ``S``; Brown, Durbin & Evans 1975, eq. (2);
    Harvey 1990, sec. 2.6). The residuals depend on the column space of
    `Hs` only, so its columns are scaled to unit norm first.

    References
    ----------
    .. [1] R. L. Brown, J. Durbin and J. M. Evans, "Techniques for testing the
       constancy of regression relationships over time", *J. R. Stat. Soc.
       B* 37(2), 149-192, 1975.
    .. [2] A. C. Harvey, *The Econometric Analysis of Time Series*, 2nd ed.,
       Philip Allan, 1990.

    Examples
    --------
    Under a constant regression the recursive residuals are white with the
    noise's standard deviation (here 0.1):

    >>> import numpy as np
    >>> from rlsfilt.validation import recursive_residuals
    >>> rng = np.random.default_rng(0)
    >>> H = np.column_stack([np.ones(50), rng.standard_normal(50)])
    >>> z = H @ [1.0, 2.0] + 0.1 * rng.standard_normal(50)
    >>> w, start = recursive_residuals(z, H)
    >>> start, w.shape, round(float(np.std(w, ddof=1)), 3)
    (2, (48,), 0.103)
    """
    w, scale, start, _ = _scaled_recursive_residuals(zs, Hs)
    with np.errstate(over="ignore"):
        return w * scale, start


def _scaled_recursive_residuals(zs, Hs):
    """``(w / c, c, start, z / c)``: the recursive residuals and the measurements divided by
    a power of two ``c`` near ``max|z|``, so that their squares stay in range."""
    z, H = _as_regression(zs, Hs)
    k = H.shape[1]
    start = _exact_start(H)
    # w_t depends on the column space of H only, so unit columns change nothing but
    # keep the filter's rank decision independent of the regressors' units; w_t is
    # proportional to z, so the filter runs on z / c (exact) for any units of z
    H = unit_columns(H)
    c = pow2_scale(z)
    z = z / c
    rls = RecursiveLeastSquares(dim_x=k, R=1.0)
    rls.initialize(z[:start], H[:start])
    Hr = H[start:]
    # priors of each step: x_{t-1} and P_{t-1}; then y = z - h x, S = h P h^T + R
    _, _, x_prior, P_prior = rls.batch_filter(z[start:], Hr)
    y = z[start:] - np.einsum("ti,ti->t", Hr, x_prior[:, :, 0])
    S = np.einsum("ti,tij,tj->t", Hr, P_prior, Hr) + rls.R
    return y / np.sqrt(S), c, start, z


def cusum(zs, Hs, alpha=0.05):
    r"""CUSUM test of parameter constancy (Brown, Durbin & Evans 1975).

    Parameters
    ----------
    zs : array_like, shape (N,)
        Measurements.
    Hs : array_like, shape (N, k)
        Regressor rows; for an ARX model use ``Phi, target =
        model.regressors(u, y)`` and pass ``cusum(target, Phi)``.
    alpha : float, default 0.05
        Significance level in (0, 1).

    Returns
    -------
    CusumResult
        ``statistic`` is the path :math:`W_r`, ``bounds`` the two lines,
        ``rejected`` the decision and ``pvalue`` the crossing probability.

    Notes
    -----
    With :math:`w_{k+1}, \dots, w_T` the recursive residuals
    (:func:`recursive_residuals`, :math:`m = T - k` of them) and
    :math:`\hat\sigma` their sample standard deviation (``ddof=1``),

    .. math::

        W_r = \frac{1}{\hat\sigma} \sum_{j=k+1}^{r} w_j, \qquad r = k+1, \dots, T,

    normalized as statsmodels' ``RecursiveLSResults.cusum`` and R's
    strucchange. Under constancy :math:`W_r` behaves like a Brownian motion
    with variance :math:`r - k`; the test rejects when the path crosses one
    of the lines

    .. math::

        \pm \left( a \sqrt{m} + 2 a \frac{r - k}{\sqrt{m}} \right),

    where :math:`a` solves (Brown, Durbin & Evans 1975, eq. (2.4))

    .. math::

        \alpha = 2\left[1 - \Phi(3a) + e^{-4a^2} \Phi(a)\right].

    For ``alpha`` in {0.01, 0.05, 0.10} the paper's three-decimal values
    ``a`` = 1.143, 0.948, 0.850 are used (the same as statsmodels for 1% and
    5%, and the root of the equation rounded); other levels use the root.
    ``pvalue`` is the right-hand side evaluated at the smallest ``a`` whose
    lines the path touches.

    The CUSUM test reacts to changes that move the mean of the recursive
    residuals; it has little power against a change of a coefficient whose
    regressor has mean zero (Kramer, Ploberger & Alt 1988), where
    :func:`cusum_squares` (a change of the residual variance) helps.

    References
    ----------
    .. [1] R. L. Brown, J. Durbin and J. M. Evans, "Techniques for testing the
       constancy of regression relationships over time", *J. R. Stat. Soc.
       B* 37(2), 149-192, 1975.
    .. [2] A. Zeileis, F. Leisch, K. Hornik and C. Kleiber, "strucchange: an R
       package for testing for structural change in linear regression
       models", *J. Stat. Softw.* 7(2), 2002.
    .. [3] W. Kramer, W. Ploberger and R. Alt, "Testing for structural change
       in dynamic models", *Econometrica* 56(6), 1355-1369, 1988.

    Examples
    --------
    A regression whose intercept shifts halfway is flagged:

    >>> import numpy as np
    >>> from rlsfilt.validation import cusum
    >>> rng = np.random.default_rng(0)
    >>> H = np.column_stack([np.ones(400), rng.standard_normal(400)])
    >>> level = np.where(np.arange(400) < 200, 0.5, 0.6)
    >>> z = level + 1.0 * H[:, 1] + 0.1 * rng.standard_normal(400)
    >>> result = cusum(z, H)
    >>> result.rejected, int(result.crossings[0])
    (True, 266)
    """
    alpha = check_probability(alpha, "alpha")
    w, c, start, z = _scaled_recursive_residuals(zs, Hs)   # W is invariant to the scale c
    m = len(w)
    if m < 2:
        raise ValueError(f"`zs` must have at least 2 rows beyond the {start} used for the exact "
                         f"start; got {m}")
    sigma = np.std(w, ddof=1)
    if sigma <= 1e-10 * math.sqrt(np.mean(z ** 2)):
        raise ExactFitError("the recursive residuals are all equal to round-off (an exact fit); "
                         "CUSUM is undefined")
    W = np.cumsum(w) / sigma
    j = np.arange(1, m + 1)
    a = _bde_constant(alpha)
    upper = a * math.sqrt(m) + 2.0 * a * j / math.sqrt(m)
    # smallest `a` whose lines the path touches, and its crossing probability
    a_obs = float(np.max(np.abs(W) / (math.sqrt(m) + 2.0 * j / math.sqrt(m))))
    with np.errstate(over="ignore"):
        w = w * c
    return CusumResult("cusum", W, (-upper, upper), alpha, np.arange(start, start + m), w,
                       start, a, pvalue=_bde_crossing_probability(a_obs))


def cusum_squares(zs, Hs, alpha=0.05):
    r"""CUSUM of squares test of constant variance (Brown, Durbin & Evans 1975).

    Parameters
    ----------
    zs : array_like, shape (N,)
        Measurements.
    Hs : array_like, shape (N, k)
        Regressor rows (for an ARX model, ``Phi`` of ``regressors(u, y)``).
    alpha : float, default 0.05
        Two-sided significance level; one of 0.2, 0.1, 0.05, 0.02, 0.01
        (the levels for which critical values are tabulated).

    Returns
    -------
    CusumResult
        ``statistic`` is :math:`S_r`, ``bounds`` the lines
        :math:`(r - k)/m \pm c_0`, ``rejected`` the decision and
        ``critical_value`` :math:`c_0`.

    Notes
    -----
    With the recursive residuals :math:`w_{k+1}, \dots, w_T` (:math:`m` of
    them),

    .. math::

        S_r = \frac{\sum_{j=k+1}^{r} w_j^2}{\sum_{j=k+1}^{T} w_j^2},

    whose mean under constancy is :math:`(r - k)/m`. Constancy is rejected if
    :math:`|S_r - (r - k)/m| > c_0` for some :math:`r`. Pairs of squared
    normal residuals are exponential, so :math:`S_{k+2i}` are the order
    statistics of :math:`n = m/2 - 1` uniforms and :math:`c_0` is the
    critical value of Durbin's (1969) modified Kolmogorov-Smirnov statistic
    at one-sided level ``alpha / 2``. It is computed from the response
    surface of Edgerton & Wells (1994, Table 1),

    .. math::

        c_0 = \frac{c_1}{\sqrt{n}} + \frac{c_2}{n} + \frac{c_3}{n^{3/2}},

    which fits Durbin's table closely for any ``n`` (statsmodels uses the
    same approximation). Its leading coefficient is the asymptotic value
    :math:`c_1 = \sqrt{-\log(\alpha/2) / 2}`, the level-:math:`\alpha/2`
    crossing point of a Brownian bridge :math:`B` (:math:`P(\sup B > c) =
    e^{-2c^2}`), since :math:`\sqrt{n}\,(S_r - (r-k)/m)` tends to one.

    **Level in practice.** The distribution theory assumes regressors fixed
    in advance. An ARX regressor holds lagged outputs, so the recursive
    residuals are independent only asymptotically and the level is
    approximate (as for the CUSUM test, Kramer, Ploberger & Alt 1988).
    Measured over 1000 seeds at ``alpha = 0.05`` with the true structure on
    the constant plants of `rlsfilt.datasets` at their default lengths, the
    test rejected 5.6 % of ``dc_motor`` records (2000 samples) and 5.3 % of
    ``nonminimum_phase`` records (1000 samples); the 95 % binomial
    uncertainty of such a rate is about +-1.4 points. The path is checked
    at every :math:`r` rather than only at Durbin's even points, which makes
    the test slightly liberal for i.i.d. residuals (5.3 % and 5.8 % at
    ``m = 1000`` and ``2000``, 400 seeds);
    a static regression with a constant and three white regressors gave
    3 % (400 seeds). Small seed sets scatter widely: seeds 0-19 give 3 and
    4 rejections in 20 for these two plants (15 % and 20 %), which is
    within binomial chance for a 5 % test, not a sign of a wrong bound.

    References
    ----------
    .. [1] R. L. Brown, J. Durbin and J. M. Evans, "Techniques for testing the
       constancy of regression relationships over time", *J. R. Stat. Soc.
       B* 37(2), 149-192, 1975.
    .. [2] J. Durbin, "Tests for serial correlation in regression analysis
       based on the periodogram of least-squares residuals", *Biometrika*
       56(1), 1-15, 1969.
    .. [3] D. Edgerton and C. Wells, "Critical values for the CUSUMSQ
       statistic in medium and large sized samples", *Oxford Bull. Econ.
       Stat.* 56(3), 355-365, 1994.
    .. [4] W. Kramer, W. Ploberger and R. Alt, "Testing for structural change
       in dynamic models", *Econometrica* 56(6), 1355-1369, 1988.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.validation import cusum_squares
    >>> rng = np.random.default_rng(1)
    >>> H = np.column_stack([np.ones(400), rng.standard_normal(400)])
    >>> scale = np.where(np.arange(400) < 200, 0.1, 0.4)
    >>> z = 1.0 + 2.0 * H[:, 1] + scale * rng.standard_normal(400)
    >>> cusum_squares(z, H).rejected
    True
    """
    alpha = check_probability(alpha, "alpha")
    one_sided = alpha / 2.0
    level = next((lv for lv in _EW_LEVELS if math.isclose(lv, one_sided)), None)
    if level is None:
        raise ValueError("`alpha` must be one of 0.2, 0.1, 0.05, 0.02, 0.01 (the levels of the "
                         f"Edgerton-Wells critical values); got {alpha}")
    w, c, start, z = _scaled_recursive_residuals(zs, Hs)   # S is invariant to the scale c
    m = len(w)
    n = 0.5 * m - 1.0
    if n < 1.0:
        raise ValueError(f"`zs` must have at least 4 rows beyond the {start} used for the exact "
                         f"start; got {m}")
    sq = np.cumsum(w * w)
    if sq[-1] <= 1e-20 * m * np.mean(z ** 2):
        raise ExactFitError("the recursive residuals are zero to round-off (an exact fit); the "
                         "CUSUM of squares is undefined")
    S = sq / sq[-1]
    c1, c2, c3 = _EW_COEF[level]
    c0 = c1 / math.sqrt(n) + c2 / n + c3 / n**1.5
    line = np.arange(1, m + 1) / m
    with np.errstate(over="ignore"):
        w = w * c
    return CusumResult("cusum_squares", S, (line - c0, line + c0), alpha,
                       np.arange(start, start + m), w, start, c0)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _bde_log_crossing_probability(a):
    """Logarithm of the right-hand side of BDE (1975) eq. (2.4), exact in the far tail."""
    from scipy.stats import norm  # lazy: keeps `import rlsfilt` light
    return math.log(2.0) + float(np.logaddexp(norm.logsf(3.0 * a),
                                              -4.0 * a * a + norm.logcdf(a)))


def _bde_crossing_probability(a):
    """BDE (1975) eq. (2.4): P(a Brownian path crosses a(1 + 2t), t in [0, 1])."""
    return min(1.0, math.exp(_bde_log_crossing_probability(a)))


def _bde_constant(alpha):
    from scipy.optimize import brentq  # lazy: keeps `import rlsfilt` light
    for level, a in _BDE_A.items():
        if math.isclose(alpha, level):
            return a
    # solved in logarithms, so that any level down to the smallest double has its root
    # (at a = 40 the log-probability is about -6400, below log(5e-324) = -744)
    log_alpha = math.log(alpha)
    return brentq(lambda a: _bde_log_crossing_probability(a) - log_alpha, 1e-6, 40.0,
                  xtol=1e-12)


def _as_regression(zs, Hs):
    z = check_finite(as_float_array(zs, "zs"), "zs")
    H = check_finite(as_float_array(Hs, "Hs"), "Hs")
    if z.ndim == 2 and z.shape[1] == 1:
        z = z[:, 0]
    if z.ndim != 1:
        raise ValueError(f"`zs` must have shape (N,) (one output); got {z.shape}")
    if H.ndim == 1:
        H = H[:, None]
    if H.ndim != 2 or len(H) != len(z):
        raise ValueError(f"`Hs` must have shape ({len(z)}, k) (one regressor row per "
                         f"measurement); got {H.shape}")
    if H.shape[1] == 0:
        raise ValueError("`Hs` must have at least one column; got 0")
    # one memory layout (a pandas frame is Fortran-ordered): the same numbers bit for bit
    return np.ascontiguousarray(z), np.ascontiguousarray(H)


def _exact_start(H):
    """Smallest k0 >= k such that the first k0 rows of `H` have rank k."""
    start = _full_rank_rows(H)
    if start is None:
        raise ValueError(f"`Hs` must have full column rank {H.shape[1]}; got rank "
                         f"{_column_rank(H)} (a regressor is a combination of others)")
    return start
