r"""Streaming change detection on the normalized innovations of a filter.

Under the model the filter assumes (parameters as it tracks them, noise
variance ``R``), its normalized innovations

.. math::

    e_t = y_t / \sqrt{S_t}, \qquad y_t = z_t - H_t \hat x^-_t, \quad
    S_t = H_t P^-_t H_t^T + R

are independent :math:`N(0, 1)` (Brown, Durbin & Evans 1975): whatever ``P``
is, even right after a reset, ``S`` carries the uncertainty of the estimate.
A change of the parameters that the filter has not followed shifts their
mean (where the regressors have a mean, as a bias term or a step input has).
`ChangeDetector` runs a two-sided CUSUM (Page 1954), a Page-Hinkley test or
a window-limited generalized likelihood ratio test (Basseville & Nikiforov
1993, sec. 2.4; Lai 1995) on them, one sample at a time, with its threshold
set from the wanted average run length between false alarms (Siegmund 1985;
Siegmund & Venkatraman 1995), and can act on the filter when it alarms.

The detector reads only the filter's public ``y``, ``S`` (and ``P``,
``reset()`` for its action), so it serves `RecursiveLeastSquares` and the
other single-output filters alike.
"""

import math

import numpy as np

from .._validation import as_float_array

__all__ = ["ChangeDetector", "cusum_threshold", "glr_threshold"]

_METHODS = ("cusum", "page_hinkley", "glr")
_ACTIONS = ("none", "reset", "boost", "lambda")
_SIEGMUND = 1.166      # Siegmund's correction of the threshold for the overshoot: 2 * 0.583


def _one_sided_arl(h, k):
    """Siegmund's (1985) approximation of the average run length of a one-sided CUSUM
    with reference value `k` and threshold `h` on N(0, 1) data (in-control mean 0)."""
    b = h + _SIEGMUND
    a = 2.0 * k * b
    return (math.expm1(a) - a) / (2.0 * k * k)


def cusum_threshold(arl, shift=1.0):
    r"""Threshold of the two-sided CUSUM for an average run length `arl` between false alarms.

    Parameters
    ----------
    arl : float
        Wanted in-control average run length (samples between false alarms),
        greater than 1.
    shift : float, default 1.0
        Smallest mean shift of the normalized innovations to detect quickly, in
        standard deviations; the reference value is :math:`k = \text{shift}/2`.

    Returns
    -------
    float
        The threshold :math:`h`.

    Notes
    -----
    Siegmund's approximation of the one-sided run length on :math:`N(0, 1)`
    data with drift :math:`-k`,
    :math:`\mathrm{ARL}_1 \approx (e^{2 k b} - 2 k b - 1) / (2 k^2)`,
    :math:`b = h + 1.166` (Siegmund 1985, sec. X.2; Basseville & Nikiforov
    1993, eq. 5.2.44), and the two sides together alarm twice as often,
    :math:`1/\mathrm{ARL} = 2/\mathrm{ARL}_1`; solved for :math:`h`.

    References
    ----------
    .. [1] D. Siegmund, *Sequential Analysis: Tests and Confidence Intervals*,
       Springer, 1985.
    .. [2] M. Basseville and I. V. Nikiforov, *Detection of Abrupt Changes:
       Theory and Application*, Prentice Hall, 1993.

    Examples
    --------
    >>> from rlsfilt.validation import cusum_threshold
    >>> round(cusum_threshold(1000.0, shift=1.0), 2)
    5.75
    """
    from scipy.optimize import brentq  # lazy: keeps `import rlsfilt` light

    arl, shift = float(arl), float(shift)
    if not (math.isfinite(arl) and arl > 1.0):
        raise ValueError(f"`arl` must be a finite number > 1; got {arl}")
    if not (math.isfinite(shift) and shift > 0.0):
        raise ValueError(f"`shift` must be a positive finite number; got {shift}")
    k = 0.5 * shift
    target = 2.0 * arl                                       # each side's run length
    hi = 1.0
    while _one_sided_arl(hi, k) < target:
        hi *= 2.0
    if _one_sided_arl(0.0, k) >= target:
        return 0.0
    return brentq(lambda h: _one_sided_arl(h, k) - target, 0.0, hi, xtol=1e-12)


def _overshoot_nu(x):
    """Siegmund's overshoot correction nu(x) of a Gaussian random walk, in the
    approximation of Siegmund & Yakir (2007, eq. 4.38)."""
    if x < 1e-8:
        return 1.0
    half = 0.5 * x
    cdf = 0.5 * math.erfc(-half / math.sqrt(2.0))
    pdf = math.exp(-0.5 * half * half) / math.sqrt(2.0 * math.pi)
    return (2.0 / x) * (cdf - 0.5) / (half * cdf + pdf)


def _glr_arl(b, window):
    """Average run length of the two-sided window-limited GLR with threshold
    ``b**2 / 2`` on N(0, 1) data (see `glr_threshold`)."""
    from scipy.integrate import quad  # lazy: keeps `import rlsfilt` light

    lo, hi = b / math.sqrt(window + 0.5), b / math.sqrt(0.5)
    integral = quad(lambda x: x * _overshoot_nu(x) ** 2, lo, hi, epsabs=0.0,
                    epsrel=1e-12, limit=200)[0]
    log_pdf = -0.5 * b * b - 0.5 * math.log(2.0 * math.pi)
    return math.exp(-log_pdf) / (b * integral)


def glr_threshold(arl, window=100):
    r"""Threshold of the two-sided window-limited GLR test for an average run length `arl`.

    Parameters
    ----------
    arl : float
        Wanted in-control average run length (samples between false alarms),
        greater than 1.
    window : int, default 100
        Longest window :math:`M` of the test (the change times it considers
        are the last `window` samples).

    Returns
    -------
    float
        The threshold :math:`h` on :math:`g_k = \max_j (S_j^k)^2 / (2 (k - j + 1))`.

    Notes
    -----
    With :math:`b = \sqrt{2 h}`, the test alarms when some window sum
    :math:`|S_j^k| / \sqrt{k - j + 1} \ge b`. The rate of such crossings
    of the two-parameter Gaussian field (change time and window length) is,
    for large :math:`b` (Siegmund & Venkatraman 1995; Siegmund & Yakir 2007,
    ch. 7),

    .. math::

        \frac{1}{\mathrm{ARL}} \approx 2 \cdot \frac{b\,\varphi(b)}{2}
        \int_{b/\sqrt{M + 1/2}}^{b/\sqrt{1/2}} x\,\nu^2(x)\,dx ,

    the factor 2 for the two signs, :math:`\nu` Siegmund's overshoot
    correction for discrete time in the approximation
    :math:`\nu(x) \approx (2/x)(\Phi(x/2) - 1/2) / ((x/2)\Phi(x/2) +
    \varphi(x/2))`, and the window lengths :math:`1, \dots, M` taken as
    the interval :math:`[1/2, M + 1/2]` (midpoint rule). Solved for
    :math:`h`. Simulation (``tests/test_detection.py``) puts the true run
    length within about 10 % of `arl` for windows of 10 to 100 samples, on the
    long side for windows of 50 and more.

    References
    ----------
    .. [1] D. Siegmund and E. S. Venkatraman, "Using the generalized
       likelihood ratio statistic for sequential detection of a
       change-point", *Ann. Statist.* 23(1), 1995.
    .. [2] D. Siegmund and B. Yakir, *The Statistics of Gene Mapping*,
       Springer, 2007.
    .. [3] T. L. Lai, "Sequential changepoint detection in quality control
       and dynamical systems", *J. R. Stat. Soc. B* 57(4), 1995.

    Examples
    --------
    >>> from rlsfilt.validation import glr_threshold
    >>> round(glr_threshold(1000.0, window=100), 2)
    6.97
    """
    from scipy.optimize import brentq  # lazy: keeps `import rlsfilt` light

    arl = float(arl)
    if not (math.isfinite(arl) and arl > 1.0):
        raise ValueError(f"`arl` must be a finite number > 1; got {arl}")
    window = _check_window(window)
    target = math.log(arl)
    lo, hi = 0.5, 2.0
    while math.log(_glr_arl(hi, window)) < target:
        hi *= 2.0
    if math.log(_glr_arl(lo, window)) >= target:
        return 0.5 * lo * lo
    b = brentq(lambda b: math.log(_glr_arl(b, window)) - target, lo, hi, xtol=1e-13)
    return 0.5 * b * b


def _check_window(window):
    if isinstance(window, bool) or not isinstance(window, (int, np.integer)) or window < 1:
        raise ValueError(f"`window` must be an integer >= 1; got {window!r}")
    return int(window)


class ChangeDetector:
    r"""CUSUM, Page-Hinkley or GLR test on a filter's normalized innovations.

    Parameters
    ----------
    method : {"cusum", "page_hinkley", "glr"}, default "cusum"
        ``"cusum"``: Page's two-sided CUSUM of :math:`e_t` around the known
        in-control mean 0. ``"page_hinkley"``: the Page-Hinkley test, the same
        sums around the running mean of :math:`e_t` since the last alarm
        (robust to a constant offset of the innovations, slower to react).
        ``"glr"``: the window-limited generalized likelihood ratio test of a
        mean jump of unknown size (no `shift` to choose; `window` samples of
        memory).
    arl : float, default 1000
        Wanted average run length between false alarms (samples); sets the
        threshold by `cusum_threshold` (or `glr_threshold`) unless
        `threshold` is given.
    shift : float, default 1.0
        Smallest shift of the mean of :math:`e_t` (standard deviations) to
        detect quickly; the reference value is ``shift / 2`` (not used by
        ``"glr"``).
    window : int, default 100
        ``"glr"`` only: the longest window :math:`M` (the change times
        considered are the last `window` samples since the last alarm).
    threshold : float, optional
        The threshold :math:`h` itself (overrides `arl`).
    action : {"none", "reset", "boost", "lambda"}, default "none"
        What :meth:`step` does to the filter on an alarm: ``"none"``;
        ``"reset"``: ``filt.reset()`` (back to ``x0``, ``P0``: identification
        starts again from the next sample); ``"boost"``: ``P <- boost * P``
        (the estimate is kept, its gain reopened: covariance resetting);
        ``"lambda"``: ``filt.lam <- alarm_lam`` for the next `hold` samples,
        then the filter's own ``lam`` back (a temporary shorter memory).
    boost : float, default 1000
        Factor of ``"boost"``.
    alarm_lam : float, default 0.9
        Forgetting factor of ``"lambda"``, in (0, 1].
    hold : int, default 20
        Number of samples (calls of :meth:`step`, missing ones included)
        that ``"lambda"`` keeps `alarm_lam` after an alarm; an alarm during
        the hold starts it again.

    Attributes
    ----------
    threshold : float
        :math:`h`.
    drift : float
        The reference value :math:`k` (CUSUM, Page-Hinkley).
    g_plus, g_minus : float
        The two statistics now (zero after an alarm); for ``"glr"`` the
        largest :math:`(S_j^k)^2 / (2 (k - j + 1))` over the windows whose sum
        is positive, and negative.
    n_samples : int
        Innovations seen since :meth:`reset` (missing ones are not counted).
    alarms : list of int
        Indices (counted in innovations seen) of the samples that raised an alarm.

    Notes
    -----
    With :math:`e_t` the normalized innovation and :math:`k` the drift,
    the CUSUM is

    .. math::

        g^+_t = \max(0, g^+_{t-1} + e_t - k), \qquad
        g^-_t = \max(0, g^-_{t-1} - e_t - k),

    alarming when either exceeds :math:`h`; the Page-Hinkley test replaces
    :math:`e_t` by :math:`e_t - \bar e_t`, :math:`\bar e_t` the mean since the
    last alarm (Page 1954; Hinkley 1971). The GLR test of a jump of the mean
    from 0 to an unknown :math:`\mu` at an unknown time :math:`j` maximizes
    the log-likelihood ratio over both; over :math:`\mu` in closed form
    (:math:`\hat\mu = S_j^k / (k - j + 1)`), over :math:`j` in the last
    :math:`M` samples (Basseville & Nikiforov 1993, eq. 2.4.40; Lai 1995):

    .. math::

        g_k = \max_{k - M < j \le k} \frac{(S_j^k)^2}{2 (k - j + 1)}, \qquad
        S_j^k = \sum_{i=j}^k e_i ,

    alarming when :math:`g_k > h` (`glr_threshold`). On an alarm the
    statistics (the running mean, the GLR's window) restart empty, so the
    run lengths between alarms are independent, and the action is applied
    to the filter; a missing sample (NaN ``y``) changes no statistic.

    References
    ----------
    .. [1] E. S. Page, "Continuous inspection schemes", *Biometrika* 41, 1954.
    .. [2] D. V. Hinkley, "Inference about the change-point from cumulative
       sum tests", *Biometrika* 58(3), 1971.
    .. [3] R. L. Brown, J. Durbin and J. M. Evans, "Techniques for testing the
       constancy of regression relationships over time", *J. R. Stat. Soc.
       B* 37(2), 1975.
    .. [4] M. Basseville and I. V. Nikiforov, *Detection of Abrupt Changes:
       Theory and Application*, Prentice Hall, 1993, ch. 2.
    .. [5] T. L. Lai, "Sequential changepoint detection in quality control
       and dynamical systems", *J. R. Stat. Soc. B* 57(4), 1995.

    Examples
    --------
    A bias that jumps by five noise standard deviations at sample 300:

    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.validation import ChangeDetector
    >>> rng = np.random.default_rng(0)
    >>> H = np.column_stack([np.ones(600), rng.standard_normal(600)])
    >>> z = H @ [1.0, 0.5] + 0.1 * rng.standard_normal(600)
    >>> z[300:] += 0.5
    >>> rls = RecursiveLeastSquares(2, R=0.01)
    >>> det = ChangeDetector(arl=10_000, shift=2.0, action="boost")
    >>> for k in range(600):
    ...     rls.predict_update(z[k], H[k])
    ...     _ = det.step(rls)
    >>> det.alarms[0]                  # the first alarm, one sample after the jump
    301
    """

    def __init__(self, method="cusum", *, arl=1000.0, shift=1.0, window=100, threshold=None,
                 action="none", boost=1e3, alarm_lam=0.9, hold=20):
        settings = _settings(method, arl, shift, window, threshold, action, boost, alarm_lam,
                             hold)
        (self.method, self.threshold, self.drift, self.window, self.action, self.boost,
         self.alarm_lam, self.hold) = settings
        self._held = None
        self.reset()

    def reset(self):
        """Forget everything seen: statistics, running mean, counters and alarms.

        A temporary forgetting factor (``action="lambda"``) still in force
        ends: the filter gets its own ``lam`` back.
        """
        if self._held is not None:
            filt, lam, _ = self._held
            filt.lam = lam
        self._held = None
        self.alarms = []
        self.n_samples = 0
        self._half_inverse = 0.5 / np.arange(1.0, self.window + 1.0)   # 1 / (2 L)
        self._restart()

    def update(self, y, S):
        """Feed one innovation `y` with its variance `S`; return whether it alarms.

        `y` and `S` are those of a single-output filter after its update (any
        shape holding one value each); a NaN `y` (missing sample) is skipped.
        """
        y = float(as_float_array(y, "y").reshape(-1)[0])
        s = float(as_float_array(S, "S").reshape(-1)[0])
        if y != y:
            return False
        if not (math.isfinite(s) and s > 0.0):
            raise ValueError(f"`S` must be a positive finite variance; got {s}")
        return self._feed(y / math.sqrt(s))

    def step(self, filt):
        """:meth:`update` with ``filt.y`` and ``filt.S`` (call it after each
        ``filt.update``), and on an alarm apply the action to `filt`; returns
        whether it alarmed."""
        if self.action == "lambda" and not hasattr(filt, "lam"):
            raise TypeError(f'action="lambda" needs a filter with a forgetting factor `lam`; '
                            f"got {type(filt).__name__}")
        alarm = self.update(filt.y, filt.S)          # (first: a bad S changes nothing)
        if self._held is not None:                   # the hold counts every sample
            held_filt, lam, left = self._held
            self._held = (held_filt, lam, left - 1) if left > 1 else None
            if left == 1:
                held_filt.lam = lam
        if alarm and self.action == "reset":
            filt.reset()
        elif alarm and self.action == "boost":
            filt.P = self.boost * filt.P
        elif alarm and self.action == "lambda":
            own = filt.lam if self._held is None else self._held[1]
            filt.lam = self.alarm_lam
            self._held = (filt, own, self.hold)
        return alarm

    def run(self, ys, Ss):
        """Feed a record of innovations and variances (``(N,)`` each); returns the
        indices of its alarms (no action: the record is past). Same numbers as
        :meth:`update` one by one."""
        ys = as_float_array(ys, "ys").reshape(-1)
        Ss = as_float_array(Ss, "Ss").reshape(-1)
        if len(ys) != len(Ss):
            raise ValueError(f"`ys` and `Ss` must have the same length; got {len(ys)} "
                             f"and {len(Ss)}")
        found = []
        for y, s in zip(ys, Ss, strict=True):
            if self.update(y, s):
                found.append(self.alarms[-1])
        return np.array(found, dtype=int)

    @property
    def statistic(self):
        """``max(g_plus, g_minus)``, the value compared with the threshold."""
        return max(self.g_plus, self.g_minus)

    def __repr__(self):
        k = f", M={self.window}" if self.method == "glr" else f", k={self.drift:.4g}"
        return (f"<ChangeDetector {self.method}: h={self.threshold:.4g}{k}, "
                f"{len(self.alarms)} alarm(s) in {self.n_samples} samples>")

    # ------------------------------------------------------------------
    def _restart(self):
        self.g_plus = self.g_minus = 0.0
        self._mean, self._count = 0.0, 0
        self._recent = np.zeros(self.window)      # the GLR's window, newest first
        self._filled = 0

    def _feed(self, e):
        t = self.n_samples
        self.n_samples = t + 1
        if self.method == "glr":
            self._glr(e)
        else:
            if self.method == "page_hinkley":
                # e_t - mean since the last alarm (the mean including e_t)
                self._count += 1
                self._mean += (e - self._mean) / self._count
                e = e - self._mean
            k = self.drift
            self.g_plus = max(0.0, self.g_plus + e - k)      # g+ = max(0, g+ + e - k)
            self.g_minus = max(0.0, self.g_minus - e - k)    # g- = max(0, g- - e - k)
        if self.g_plus > self.threshold or self.g_minus > self.threshold:
            self.alarms.append(t)
            self._restart()
            return True
        return False

    def _glr(self, e):
        recent = self._recent
        recent[1:] = recent[:-1].copy()                       # shift the window by one
        recent[0] = e
        n = self._filled = min(self._filled + 1, self.window)
        sums = np.cumsum(recent[:n])                          # S_j^k, j = k, k-1, ...
        g = sums * sums * self._half_inverse[:n]              # (S_j^k)^2 / (2 (k - j + 1))
        up = sums > 0.0
        self.g_plus = float(g[up].max()) if up.any() else 0.0
        self.g_minus = float(g[~up].max()) if not up.all() else 0.0


def _settings(method, arl, shift, window, threshold, action, boost, alarm_lam, hold):
    """The checked settings of a detector: ``(method, threshold, drift, window,
    action, boost, alarm_lam, hold)`` (shared with the bank's detector)."""
    if method not in _METHODS:
        raise ValueError(f"`method` must be one of {', '.join(map(repr, _METHODS))}; "
                         f"got {method!r}")
    if action not in _ACTIONS:
        raise ValueError(f"`action` must be one of {', '.join(map(repr, _ACTIONS))}; "
                         f"got {action!r}")
    boost = float(boost)
    if not (math.isfinite(boost) and boost >= 1.0):
        raise ValueError(f"`boost` must be a finite number >= 1; got {boost}")
    alarm_lam = float(alarm_lam)
    if not (0.0 < alarm_lam <= 1.0):
        raise ValueError(f"`alarm_lam` must be in (0, 1]; got {alarm_lam}")
    if isinstance(hold, bool) or not isinstance(hold, (int, np.integer)) or hold < 1:
        raise ValueError(f"`hold` must be an integer >= 1; got {hold!r}")
    window = _check_window(window)
    drift = 0.5 * float(shift)
    cusum_threshold(2.0, shift)                             # (checks `shift`)
    if threshold is None:
        threshold = (glr_threshold(arl, window) if method == "glr"
                     else cusum_threshold(arl, shift))
    else:
        threshold = float(threshold)
        if not (math.isfinite(threshold) and threshold > 0.0):
            raise ValueError(f"`threshold` must be a positive finite number; "
                             f"got {threshold}")
    return method, threshold, drift, window, action, boost, alarm_lam, int(hold)
