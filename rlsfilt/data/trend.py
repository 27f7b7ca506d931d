r"""Operating points: remove a constant or piecewise-linear trend, and put it back.

Measured signals sit on offsets (a heat exchanger's outlet near 97 degC, a
valve near 40 %). A linear model describes the deviations from the operating
point, so the means (or linear trends) are removed before identification and
added back to the model's output afterwards (MATLAB's ``detrend`` with its
``TrendInfo`` and ``retrend``).

For each experiment and signal, on each segment :math:`[b_m, b_{m+1})`
between breakpoints, the trend is the least-squares fit

.. math::

    \tau(k) = c_m + s_m (k - b_m), \qquad b_m \le k < b_{m+1},

with :math:`s_m = 0` for ``type="constant"`` (so :math:`c_m` is the mean of
the segment). Segments are fitted independently, as in
``scipy.signal.detrend``; the last segment extends beyond the record when a
trend is applied to longer data.
"""

import numbers

import numpy as np

from .._display import trend_html
from .._validation import as_float_array, check_finite, check_int
from .iodata import IOData

__all__ = ["Trend", "detrend", "retrend"]

_TYPES = {"constant": "constant", "c": "constant", "linear": "linear", "l": "linear"}


class Trend:
    r"""The trend removed by :func:`detrend` (MATLAB's ``TrendInfo``).

    Attributes
    ----------
    type : {"constant", "linear"}
    breakpoints : tuple of tuple of int
        Per experiment, the first sample of each segment (starting with 0).
    intercept, slope : tuple of ndarray
        Per experiment, arrays of shape ``(n_segments, n_columns)``: the
        trend of column ``c`` at sample ``k`` of segment ``m`` is
        ``intercept[m, c] + slope[m, c] * (k - breakpoints[m])``.
    n_inputs, n_outputs : int or None
        For the trend of an `IOData`, the columns are the inputs then the
        outputs; None for the trend of a plain array.
    offset : ndarray
        Mean of the trend over each experiment (equal to the mean of the
        signal, since every segment's fit has an intercept): shape
        ``(n_columns,)`` for one experiment, ``(n_experiments, n_columns)``
        otherwise; a float for a 1-D array.
    input_offset, output_offset : ndarray
        `IOData` trends only: the `offset` of the inputs and of the outputs
        (the operating point).

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.data import detrend, retrend
    >>> x = 97.0 + np.array([0.5, -0.5, 1.0, -1.0])
    >>> xd, trend = detrend(x)
    >>> xd, trend.offset
    (array([ 0.5, -0.5,  1. , -1. ]), 97.0)
    >>> np.allclose(retrend(xd, trend), x)
    True
    """

    def __init__(self, type, breakpoints, intercept, slope, n_inputs=None, n_outputs=None,
                 one_d=False, lengths=None):
        self.type = type
        self.breakpoints = tuple(tuple(int(b) for b in bp) for bp in breakpoints)
        self.intercept = tuple(np.array(c, dtype=float) for c in intercept)
        self.slope = tuple(np.array(s, dtype=float) for s in slope)
        self.n_inputs = n_inputs
        self.n_outputs = n_outputs
        self._one_d = bool(one_d)
        # samples per experiment of the record the trend was fitted on (for `offset`)
        self._lengths = tuple(int(n) for n in lengths) if lengths is not None else None

    @property
    def n_experiments(self):
        """Number of experiments the trend was fitted on."""
        return len(self.breakpoints)

    @property
    def n_columns(self):
        """Number of signals (inputs + outputs for an `IOData`)."""
        return self.intercept[0].shape[1]

    def values(self, n_samples, experiment=0):
        """The trend of every column over ``n_samples`` samples of one experiment.

        Parameters
        ----------
        n_samples : int
            Number of samples (the last segment is extended beyond the
            fitted record).
        experiment : int, default 0
            Which experiment's trend.

        Returns
        -------
        ndarray, shape (n_samples, n_columns)
        """
        n_samples = check_int(n_samples, "n_samples", minimum=0)
        experiment = check_int(experiment, "experiment")
        if not 0 <= experiment < self.n_experiments:
            raise ValueError(f"`experiment` must be in [0, {self.n_experiments - 1}]; got "
                             f"{experiment}")
        starts = np.asarray(self.breakpoints[experiment])
        k = np.arange(n_samples)
        seg = np.searchsorted(starts, k, side="right") - 1
        c, s = self.intercept[experiment], self.slope[experiment]
        return c[seg] + s[seg] * (k - starts[seg])[:, None]

    @property
    def offset(self):
        """Mean of the trend over each experiment (the signals' means)."""
        if self._lengths is None:
            raise ValueError("`offset` needs the lengths of the fitted record; this Trend was "
                             "built without them")
        means = np.array([self.values(n, i).mean(axis=0) for i, n in enumerate(self._lengths)])
        if self._one_d:
            return float(means[0, 0]) if self.n_experiments == 1 else means[:, 0]
        return means[0] if self.n_experiments == 1 else means

    def _split_offset(self, which):
        if self.n_inputs is None:
            raise ValueError(f"`{which}_offset` is defined for the trend of an IOData; this "
                             "one was fitted on a plain array (use `offset`)")
        off = np.atleast_2d(self.offset)
        part = off[:, :self.n_inputs] if which == "input" else off[:, self.n_inputs:]
        return part[0] if self.n_experiments == 1 else part

    @property
    def input_offset(self):
        """Mean of the input trend over each experiment (the input operating point)."""
        return self._split_offset("input")

    @property
    def output_offset(self):
        """Mean of the output trend over each experiment (the output operating point)."""
        return self._split_offset("output")

    # ------------------------------------------------------------------
    # applying the trend
    # ------------------------------------------------------------------
    def remove(self, data):
        """`data` minus this trend (for new data with the operating point of the fitted one).

        Parameters
        ----------
        data : IOData or array_like
            The kind of record the trend was fitted on, with the same
            signals; one experiment, or as many as the trend (a trend of
            one experiment applies to every experiment).

        Returns
        -------
        IOData or ndarray
        """
        return self._apply(data, -1.0, "data")

    def add(self, data):
        """`data` plus this trend (:func:`retrend`)."""
        return self._apply(data, 1.0, "data")

    def _apply(self, data, sign, name):
        if isinstance(data, IOData):
            if self.n_inputs is None:
                raise TypeError(f"`{name}` must be an array like the one this trend was fitted "
                                "on; got an IOData")
            if (data.n_inputs, data.n_outputs) != (self.n_inputs, self.n_outputs):
                raise ValueError(
                    f"`{name}` must have {self.n_inputs} input(s) and {self.n_outputs} "
                    f"output(s) like the trend; got {data.n_inputs} and {data.n_outputs}")
            exps = self._experiment_map(data.n_experiments, name)
            U, Y = [], []
            for i, (Ui, Yi) in enumerate(data.arrays()):
                tr = self.values(len(Ui), exps[i])
                U.append(Ui + sign * tr[:, :self.n_inputs])
                Y.append(Yi + sign * tr[:, self.n_inputs:])
            return _rebuild(data, U, Y)
        if self.n_inputs is not None:
            raise TypeError(f"`{name}` must be an IOData like the one this trend was fitted "
                            f"on; got {type(data).__name__}")
        X, one_d = _as_columns(data, name)
        if X.shape[1] != self.n_columns:
            raise ValueError(f"`{name}` must have {self.n_columns} column(s) like the trend; "
                             f"got {X.shape[1]}")
        self._experiment_map(1, name)
        out = X + sign * self.values(len(X), 0)
        return out[:, 0] if one_d else out

    def _experiment_map(self, n, name):
        if self.n_experiments == 1:
            return [0] * n
        if n != self.n_experiments:
            raise ValueError(f"`{name}` must have {self.n_experiments} experiments like the "
                             f"trend (or the trend one); got {n}")
        return list(range(n))

    # ------------------------------------------------------------------
    # persistence and display
    # ------------------------------------------------------------------
    def to_dict(self):
        """Plain lists and numbers (for JSON); :meth:`from_dict` rebuilds the trend exactly."""
        return {"type": self.type, "breakpoints": [list(b) for b in self.breakpoints],
                "intercept": [c.tolist() for c in self.intercept],
                "slope": [s.tolist() for s in self.slope],
                "n_inputs": self.n_inputs, "n_outputs": self.n_outputs,
                "one_d": self._one_d,
                "lengths": list(self._lengths) if self._lengths is not None else None}

    @classmethod
    def from_dict(cls, d):
        """The `Trend` stored by :meth:`to_dict`."""
        return cls(d["type"], d["breakpoints"], d["intercept"], d["slope"], d["n_inputs"],
                   d["n_outputs"], d["one_d"], d["lengths"])

    def _repr_html_(self):
        return trend_html(self)   # Jupyter: intercept (and slope) of each signal and segment

    def __repr__(self):
        segs = sorted({len(b) for b in self.breakpoints})
        what = (f"{self.n_inputs} input(s), {self.n_outputs} output(s)" if self.n_inputs
                is not None else f"{self.n_columns} column(s)")
        text = (f"Trend(type={self.type!r}, {self.n_experiments} experiment(s), {what}, "
                f"{'/'.join(map(str, segs))} segment(s) per experiment)")
        if self._lengths is not None:
            off = np.round(np.atleast_1d(self.offset), 6).tolist()
            text += f"\n  offset (mean of the trend): {off}"
        return text


def detrend(data, type="constant", bp=None):
    r"""Remove the mean (or a piecewise-linear trend) of every signal.

    Parameters
    ----------
    data : IOData or array_like, shape (N,) or (N, n)
        The record. For an `IOData` every input and output of every
        experiment is detrended; for an array, every column (time on
        axis 0).
    type : {"constant", "linear"}, default "constant"
        Remove the mean (``"constant"``) or a least-squares line
        (``"linear"``) of each segment.
    bp : sequence of int, optional
        Breakpoints: sample indices where a new segment starts (``0`` and
        ``N`` are implied; the trend is fitted on each segment separately,
        as in ``scipy.signal.detrend``, and ``type="constant"`` removes each
        segment's mean). For an `IOData` of several experiments, one
        sequence applies to every experiment, or give one sequence per
        experiment.

    Returns
    -------
    detrended : IOData or ndarray
        The same kind and shape as `data`.
    trend : Trend
        What was removed: ``retrend(detrended, trend)`` gives `data` back,
        ``trend.output_offset`` is the operating point.

    Raises
    ------
    ValueError
        Unknown `type`, breakpoints outside ``[0, N]`` or not integers.

    Notes
    -----
    Without breakpoints the result equals ``scipy.signal.detrend(x,
    axis=0, type=type)`` (the tests hold them equal to round-off); with
    breakpoints it equals scipy's for ``"linear"``, while scipy ignores
    `bp` for ``"constant"``.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 14.1 (pretreatment of data: offsets and
       trends).

    Examples
    --------
    A heater record around 40 % power and 97 degC:

    >>> import numpy as np
    >>> from rlsfilt.data import IOData, detrend
    >>> rng = np.random.default_rng(0)
    >>> u = 40.0 + rng.standard_normal(500)
    >>> y = 97.0 + 0.5 * u - 20.0 + 0.1 * rng.standard_normal(500)
    >>> data_d, trend = detrend(IOData(u, y, dt=1.0))
    >>> np.round(trend.input_offset, 2), np.round(trend.output_offset, 2)
    (array([39.97]), array([96.98]))
    >>> bool(abs(data_d.y.mean()) < 1e-12)
    True
    """
    if not isinstance(type, str) or type not in _TYPES:
        raise ValueError(f"`type` must be 'constant' or 'linear'; got {type!r}")
    kind = _TYPES[type]
    if isinstance(data, IOData):
        bps = _breakpoints(bp, data.lengths)
        U, Y, inter, slope = [], [], [], []
        for (Ui, Yi), b in zip(data.arrays(), bps):
            X = np.hstack([Ui, Yi])
            Xd, c, s = _fit(X, b, kind)
            U.append(Xd[:, :data.n_inputs])
            Y.append(Xd[:, data.n_inputs:])
            inter.append(c)
            slope.append(s)
        trend = Trend(kind, [b[:-1] for b in bps], inter, slope, data.n_inputs, data.n_outputs,
                      lengths=data.lengths)
        return _rebuild(data, U, Y), trend
    X, one_d = _as_columns(data, "data")
    (b,) = _breakpoints(bp, (len(X),))
    Xd, c, s = _fit(X, b, kind)
    trend = Trend(kind, [b[:-1]], [c], [s], one_d=one_d, lengths=(len(X),))
    return (Xd[:, 0] if one_d else Xd), trend


def retrend(data, trend):
    """Add a trend back (MATLAB ``retrend``): the inverse of :func:`detrend`.

    Parameters
    ----------
    data : IOData or array_like
        Detrended data (or a model's output on detrended data), the kind of
        record `trend` was fitted on.
    trend : Trend
        From :func:`detrend`.

    Returns
    -------
    IOData or ndarray
    """
    if not isinstance(trend, Trend):
        raise TypeError(f"`trend` must be a Trend (from detrend); got {type(trend).__name__}")
    return trend.add(data)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _as_columns(data, name):
    if hasattr(data, "to_numpy"):
        data = data.to_numpy()
    X = as_float_array(data, name)
    if X.ndim == 1:
        X2 = X.reshape(-1, 1)
    elif X.ndim == 2:
        X2 = X
    else:
        raise ValueError(f"`{name}` must have shape (N,) or (N, n) (time on axis 0); got "
                         f"{X.shape}")
    if len(X2) == 0:
        raise ValueError(f"`{name}` must hold at least one sample; got 0")
    check_finite(X2, name)
    return X2, X.ndim == 1


def _breakpoints(bp, lengths):
    """Per experiment, the sorted segment bounds ``[0, .., N]``."""
    if bp is None:
        return [[0, n] for n in lengths]
    if isinstance(bp, (str, bytes)) or isinstance(bp, numbers.Number) \
            and not isinstance(bp, numbers.Integral):
        raise TypeError(f"`bp` must be a sequence of sample indices; got {bp!r}")
    items = [bp] if isinstance(bp, numbers.Integral) else list(np.atleast_1d(bp)) \
        if isinstance(bp, np.ndarray) else list(bp)
    per_exp = bool(items) and all(isinstance(b, (list, tuple, np.ndarray)) for b in items)
    if per_exp and len(items) != len(lengths):
        raise ValueError(f"`bp` must be one sequence of breakpoints for every experiment, or "
                         f"one per experiment ({len(lengths)}); got {len(items)} sequences")
    out = []
    for i, n in enumerate(lengths):
        raw = list(items[i]) if per_exp else items
        name = f"bp[{i}]" if per_exp else "bp"
        vals = [check_int(b, name, minimum=0) for b in raw]
        if any(v > n for v in vals):
            raise ValueError(f"`{name}` must hold sample indices in [0, N = {n}]; got "
                             f"{max(vals)}")
        out.append(sorted(set([0, n] + vals)))
    return out


def _fit(X, bounds, kind):
    """Detrended copy of `X` and the per-segment (intercept, slope) arrays."""
    Xd = X.copy()
    n_seg = len(bounds) - 1
    inter = np.zeros((n_seg, X.shape[1]))
    slope = np.zeros((n_seg, X.shape[1]))
    for m in range(n_seg):
        sl = slice(bounds[m], bounds[m + 1])
        seg = X[sl]
        n = len(seg)
        if kind == "constant" or n == 1:
            mean = seg.mean(axis=0)
            Xd[sl] = seg - mean
            inter[m] = mean
            continue
        # tau(k) = c + s (k - b_m): least squares on [1, (k - b_m)/n] (unit-scale columns,
        # the regressor of scipy.signal.detrend up to a shift), solved by lstsq (SVD)
        A = np.column_stack([np.ones(n), np.arange(n) / n])
        coef = np.linalg.lstsq(A, seg, rcond=None)[0]
        Xd[sl] = seg - A @ coef
        inter[m] = coef[0]
        slope[m] = coef[1] / n
    return Xd, inter, slope


def _rebuild(data, U, Y):
    """A record with `data`'s metadata and new samples (plain IOData)."""
    return data._derive([_frozen(U_) for U_ in U], [_frozen(Y_) for Y_ in Y])


def _frozen(X):
    X = np.ascontiguousarray(X, dtype=float)
    X.setflags(write=False)
    return X
