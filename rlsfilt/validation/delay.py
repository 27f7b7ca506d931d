r"""Input delay estimation from one factorization (MATLAB's ``delayest``).

Every candidate delay :math:`n_k` of an ARX model with fixed orders
``(na, nb)`` uses a subset of the columns of one wide regressor matrix

.. math::

    \Psi(t) = [-y(t-1), \dots, -y(t-n_a),\;
               u_j(t - n_{k,\min}), \dots, u_j(t - n_{k,\max} - n_b + 1)
               \text{ for every input } j],

so, as in :func:`~rlsfilt.validation.select_order`, one QR factorization
:math:`[\Psi\; y] = QR` gives the loss of every candidate from a problem with
as many rows as :math:`\Psi` has columns.
"""

import warnings
from collections import namedtuple

import numpy as np

from .._scale import pow2_scale
from .._validation import check_int
from ..data.iodata import as_iodata
from ..exceptions import OrderSelectionWarning

__all__ = ["delayest", "DelayEstimate"]

DelayEstimate = namedtuple("DelayEstimate", ["nk", "losses", "nk_range", "n_rows"])
DelayEstimate.__doc__ = """Full output of :func:`delayest`.

Attributes
----------
nk : int or tuple of int
    The estimated delay (one per input for several inputs).
losses : list of ndarray
    Per input, the mean squared one-step residual of each delay in
    ``nk_range[j]`` with the other inputs at their estimated delays.
nk_range : list of range
    Per input, the delays tried.
n_rows : int
    Number of aligned regressor rows (over all experiments).
"""

# rows of the wide regressor matrix fed to the QR factorization at once: the memory of the
# factorization stays bounded by this block (and the triangular factor), whatever N
_BLOCK_ROWS = 16384
_MAX_SWEEPS = 20
# coefficients at the end of the impulse response estimate that must be insignificant
# before delayest trusts its early lags
_TAIL = 5


def delayest(u, y=None, na=2, nb=2, nk_min=0, nk_max=None, *, full_output=False):
    r"""Estimate the input delay(s) of a plant from an input/output record.

    ARX models ``(na, nb, nk)`` are fitted for every delay
    ``nk_min <= nk <= nk_max`` and the delay with the smallest one-step
    prediction loss is returned (all candidates have the same number of
    parameters and are fitted on the same rows, so their losses compare
    directly). With several inputs the delays are found coordinate-wise:
    each input alone first, then sweeps over the inputs, each time with the
    other delays fixed, until no delay changes.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu), or IOData
        Input record, or an `IOData` holding inputs and outputs (then `y`
        is omitted); several experiments are used together, no regressor
        row straddling two of them.
    y : array_like, shape (N,), optional
        Output record (one output).
    na : int, default 2
        Number of past outputs of the test models.
    nb : int or sequence of int, default 2
        Number of input coefficients of the test models (per input).
    nk_min : int or sequence of int, default 0
        Smallest delay tried (per input).
    nk_max : int or sequence of int, optional
        Largest delay tried (per input); ``nk_min + 20`` by default.
    full_output : bool, default False
        Return a `DelayEstimate` with the loss of every delay tried.

    Returns
    -------
    nk : int or tuple of int
        The delay in samples (a tuple, one per input, for several inputs);
        a `DelayEstimate` when `full_output` is true.

    Warns
    -----
    OrderSelectionWarning
        When an estimated delay is at ``nk_max`` (or at ``nk_min > 0``):
        the true delay may lie outside the range, so widen that bound. And
        when the losses point to ``nk_max`` but the impulse response
        estimate is significant earlier (then that shorter delay is
        returned, see Notes).

    Raises
    ------
    ValueError
        Bad orders or ranges, several outputs, or a range so large that the
        record leaves fewer rows than regressors (the message says how many
        of each).

    Notes
    -----
    Candidates whose loss :math:`V` lies within the noise of the best,
    :math:`V \le V_{min}\,(1 + F_{0.95}(1, n_{dof}) / n_{dof})`, count as
    ties. Among them the shortest delay whose leading input coefficient
    differs significantly from zero (a t-test at the 5 % level) is
    returned: a longer delay ties with the true one when noise hides the
    first coefficient, and a shorter one ties when the model's ``nb``
    exceeds the plant's (its leading coefficient is then zero: a delay means
    exactly that the first coefficients vanish).

    A delay at the upper edge ``nk_max`` is checked against the impulse
    response estimate of :func:`~rlsfilt.validation.impulseest` (noise
    prewhitened), over lags ``0 .. n - 1`` with ``n`` from ``nk_max + nb +
    10`` on, lengthened by half while any of its last 5 coefficients differs
    from zero (1 % level): a response cut off before it has died out biases
    the coefficients kept (the omitted tail is correlated with them through
    the input's colour and the prewhitening), which shows early lags as
    significant that are not. When no length up to a quarter of the record
    covers the response, there is no check. When a coefficient at a
    lag :math:`k_g` inside the range differs from zero with all lags tested
    together at the 1 % level (Bonferroni), the delay cannot exceed
    :math:`k_g` (a delay :math:`n_k` states that the first :math:`n_k`
    coefficients vanish), and the best delay up to :math:`k_g` is returned,
    with a warning. This guards against low-order test models that fit a
    swept or narrow-band input equally well at any delay.

    One Householder QR factorization of :math:`[\Psi\;y]`, accumulated over
    blocks of rows (:math:`R \leftarrow \mathrm{qr}([R;\,\text{block}])`,
    so memory does not grow with the record), gives for every candidate the
    problem :math:`\min_b \lVert R_S b - r_y \rVert` with only
    :math:`\mathrm{cols}(\Psi) + 1` rows; columns are scaled to unit norm
    (:math:`\Psi D^{-1} = Q (R D^{-1})`) so rank decisions do not depend on
    the units of the signals.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 16.4.
    .. [2] MATLAB System Identification Toolbox, ``delayest``.

    Examples
    --------
    A second-order plant with 7 samples of dead time:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.validation.delay import delayest
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(1000)
    >>> y = lfilter([0] * 7 + [1.0, 0.5], [1, -1.5, 0.7], u) + 0.1 * rng.standard_normal(1000)
    >>> delayest(u, y)
    7
    """
    data = as_iodata(u, y)
    if data.n_outputs != 1:
        raise ValueError(f"`y` must hold one output; got {data.n_outputs} (estimate the delays "
                         "of each output separately)")
    nu = data.n_inputs
    na = check_int(na, "na", minimum=0)
    nb = _per_input(nb, "nb", nu, 1)
    nk_min = _per_input(nk_min, "nk_min", nu, 0)
    nk_max = tuple(k + 20 for k in nk_min) if nk_max is None else _per_input(nk_max, "nk_max",
                                                                             nu, 0)
    for j in range(nu):
        if nk_max[j] < nk_min[j]:
            raise ValueError(f"`nk_max` must be >= `nk_min`; got nk_max={nk_max[j]} < "
                             f"nk_min={nk_min[j]}" + (f" for input {j}" if nu > 1 else ""))
    lags = [range(nk_min[j], nk_max[j] + nb[j]) for j in range(nu)]
    t_max = max([na] + [nk_max[j] + nb[j] - 1 for j in range(nu)])
    n_cols = na + sum(len(lag) for lag in lags)
    rows = _rows(data.lengths, na, nb, nk_max)
    if rows <= n_cols:
        def fits(k):       # rows for the columns of a common nk_max = k (fewer as k grows)
            return _rows(data.lengths, na, nb, (k,) * nu) > na + sum(
                k - lo + b for lo, b in zip(nk_min, nb))

        largest = _last_true(fits, max(nk_min), max(nk_max))
        hint = (f" (at most nk_max={largest} fits)" if largest is not None
                and len(set(nk_max)) == 1 else "")
        raise ValueError(
            f"the record is too short for delays up to nk_max={_fmt(nk_max)}: {data.n_samples} "
            f"samples leave {rows} aligned rows for {n_cols} regressor columns (the largest lag "
            f"is {t_max}); lower `nk_max`{hint} or give a longer record")
    R, y_unit = _triangular_factor(data, na, lags, t_max)
    scale = np.linalg.norm(R[:, :-1], axis=0)  # = column norms of Psi (Q is orthogonal)
    Rs = R[:, :-1] / np.where(scale > 0, scale, 1.0)
    r_y = R[:, -1]
    n_params = na + sum(nb)
    dof = rows - n_params
    from scipy import stats  # lazy: keeps `import rlsfilt` light
    tie = 1.0 + (stats.f.ppf(0.95, 1, dof) / dof if dof > 0 else 0.0)
    t_crit = float(stats.t.ppf(0.975, max(dof, 1)))
    offsets = np.cumsum([na] + [len(lag) for lag in lags])[:-1]

    def columns(j, k):
        start = offsets[j] + (k - nk_min[j])
        return list(range(start, start + nb[j]))

    def fit(delays, inputs):
        S = list(range(na)) + [c for j in inputs for c in columns(j, delays[j])]
        M = Rs[:, S]
        b = np.linalg.lstsq(M, r_y, rcond=None)[0]
        res = r_y - M @ b
        return float(res @ res) / rows, M, b

    def loss(delays, inputs):
        return fit(delays, inputs)[0]

    def leading_significant(j, delays, inputs):
        # the first coefficient of input j (at the delay tried) differs from zero at
        # the 5 % level: t = b / se(b), se from sigma^2 (M^T M)^-1
        v, M, b = fit(delays, inputs)
        at = na + sum(nb[i] for i in inputs if i < j)
        sigma2 = v * rows / max(dof, 1)
        try:
            cov = sigma2 * np.linalg.inv(M.T @ M)
        except np.linalg.LinAlgError:
            return False
        se = np.sqrt(max(cov[at, at], 0.0))
        return se > 0 and abs(b[at]) / se > t_crit

    def best_for(j, delays, inputs, upper=None):
        ks = range(nk_min[j], (nk_max[j] if upper is None else upper) + 1)
        curve = np.array([loss({**delays, j: k}, inputs) for k in ks])
        ok = np.flatnonzero(curve <= curve.min() * tie)
        # among the delays whose loss ties with the best, the shortest whose leading
        # coefficient is significant: a longer delay ties when noise hides the first
        # coefficient, a shorter one when the model's nb exceeds the plant's (its
        # leading coefficient is then zero)
        for i in ok:
            if leading_significant(j, {**delays, j: ks[int(i)]}, inputs):
                return ks[int(i)], curve
        return ks[int(np.argmin(curve))], curve

    delays = {j: nk_min[j] for j in range(nu)}
    for j in range(nu):  # each input alone: a start that does not depend on input order
        delays[j] = best_for(j, delays, [j])[0]
    curves = [None] * nu
    for _ in range(_MAX_SWEEPS):
        changed = False
        for j in range(nu):
            k, curves[j] = best_for(j, delays, range(nu))
            changed |= k != delays[j]
            delays[j] = k
        if not changed:
            break
    names = data.input_names
    for j, k_imp in _impulse_check(data, delays, nk_min, nk_max, nb):
        # the loss curve ran to the upper edge while the impulse response estimate is
        # significant (all lags tested together at the 1 % level) much earlier: the
        # delay is at most that lag (a longer delay claims those coefficients are zero)
        k_edge = delays[j]
        delays[j] = _best_upto(best_for, j, delays, nu, k_imp)
        warnings.warn(f"the ARX losses of input {names[j]!r} are smallest at the edge "
                      f"nk_max={k_edge}, but its impulse response estimate (impulseest) is "
                      f"significant from lag {k_imp} on: returning nk={delays[j]}, the best "
                      f"delay up to lag {k_imp}; check with impulseest(...).plot()",
                      OrderSelectionWarning, stacklevel=2)
    for j in range(nu):
        for bound, value, edge in (("nk_max", nk_max[j], True),
                                   ("nk_min", nk_min[j], nk_min[j] > 0)):
            if edge and delays[j] == value and nk_max[j] > nk_min[j]:
                warnings.warn(f"the estimated delay of input {names[j]!r} is {bound}={value}, "
                              f"the edge of the range tried; widen `{bound}`",
                              OrderSelectionWarning, stacklevel=2)
    nk = delays[0] if nu == 1 else tuple(delays[j] for j in range(nu))
    if full_output:   # the losses in the units of y (inf where their squares overflow)
        with np.errstate(over="ignore"):
            curves = [c * y_unit * y_unit for c in curves]
        return DelayEstimate(nk, curves, [range(nk_min[j], nk_max[j] + 1) for j in range(nu)],
                             rows)
    return nk


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _impulse_check(data, delays, nk_min, nk_max, nb):
    """``[(j, first significant lag)]`` for the inputs whose delay is at ``nk_max`` while
    the impulse response estimate (:func:`impulseest`, lags 0 .. n - 1, ``n`` from
    nk_max + nb + 10 on, lengthened until the response has died out) is significant, at
    the family-wise 1 % level, at a lag inside the range before it."""
    at_edge = [j for j in delays if delays[j] == nk_max[j] > nk_min[j]]
    if not at_edge:
        return []
    from .impulse import impulseest

    n = max(nk_max) + max(nb) + 10
    n_most = max(n, min(data.lengths) // (4 * data.n_inputs))
    while True:
        try:
            g = impulseest(data, n_coeffs=n, regularization=None)
        except ValueError:        # too short a record for the FIR estimate: no check
            return []
        # the response must have died out within the lags estimated (its last _TAIL
        # coefficients not significant): a truncated FIR biases the coefficients it keeps
        # (the omitted tail correlates with them through a coloured or prewhitened input)
        # and shows early lags as significant that are not
        cut = g.truncated(n_tail=_TAIL)
        cut = (cut,) if data.n_inputs == 1 else cut
        if not any(cut[j] for j in at_edge):
            break
        if n >= n_most:
            return []
        n = min(n + n // 2, n_most)
    first = g.delay(familywise=True)
    first = (first,) if data.n_inputs == 1 else first
    return [(j, first[j]) for j in at_edge
            if first[j] is not None and nk_min[j] <= first[j] < delays[j]]


def _best_upto(best_for, j, delays, nu, k_max):
    """The delay of input `j` chosen among ``nk_min .. k_max`` (the others fixed)."""
    k, _ = best_for(j, delays, range(nu), k_max)
    return k


def _per_input(value, name, nu, minimum):
    if isinstance(value, (list, tuple, np.ndarray)):
        values = list(value)
        if len(values) != nu:
            raise ValueError(f"`{name}` must be an integer or have one entry per input ({nu}); "
                             f"got {len(values)} entries")
        return tuple(check_int(v, f"{name}[{i}]", minimum=minimum) for i, v in enumerate(values))
    return (check_int(value, name, minimum=minimum),) * nu


def _rows(lengths, na, nb, nk_max):
    """Aligned rows over the experiments for the largest lag of these ranges."""
    t_max = max([na] + [k + b - 1 for k, b in zip(nk_max, nb)])
    return sum(max(n - t_max, 0) for n in lengths)


def _last_true(predicate, lo, hi):
    """The largest ``k`` in ``[lo, hi)`` with ``predicate(k)`` true, for a predicate true up
    to some point and false after it (bisection: O(log(hi - lo)) calls); None if none."""
    if hi <= lo or not predicate(lo):
        return None
    while hi - lo > 1:               # predicate(lo) holds, hi is past the range or fails
        mid = (lo + hi) // 2
        lo, hi = (mid, hi) if predicate(mid) else (lo, mid)
    return lo


def _fmt(values):
    return values[0] if len(set(values)) == 1 else list(values)


def _triangular_factor(data, na, lags, t_max):
    """``R`` of ``[Psi y] = Q R``, rows of every experiment, accumulated by blocks, with
    the signals in units of powers of two; and the unit of ``y``."""
    n_cols = na + sum(len(lag) for lag in lags) + 1
    R = np.zeros((0, n_cols))
    # the signals in units of a power of two near their largest magnitude (exact: the
    # losses only change by a common factor, the estimate not at all), so that records
    # near 1e160 or 1e-160 neither overflow nor underflow in the squares below
    arrays = list(data.arrays())
    su = pow2_scale(np.vstack([U for U, _ in arrays]), axis=0)
    sy = pow2_scale(np.vstack([Y for _, Y in arrays]), axis=0)
    for U, Y in ((U / su, Y / sy) for U, Y in arrays):
        N = len(Y)
        for start in range(t_max, N, _BLOCK_ROWS):
            stop = min(start + _BLOCK_ROWS, N)
            block = np.empty((stop - start, n_cols))
            c = 0
            for k in range(1, na + 1):
                np.negative(Y[start - k:stop - k, 0], out=block[:, c])
                c += 1
            for j, lag in enumerate(lags):
                for k in lag:
                    block[:, c] = U[start - k:stop - k, j]
                    c += 1
            block[:, c] = Y[start:stop, 0]
            R = np.linalg.qr(np.vstack([R, block]), mode="r")
    # square: the caller checked that there are more rows than columns
    return R, float(sy[0])
