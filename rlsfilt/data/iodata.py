r"""`IOData`: an input/output record of one or several experiments.

What MATLAB users know as ``iddata``: the samples of the inputs and outputs
(time on axis 0), the sampling period, the names and units of the signals,
and, for data gathered in several runs, one block per experiment. Regressor
rows of a model are built per experiment, so that no row straddles the gap
between two runs.
"""

import html
import numbers

import numpy as np

from .._validation import as_float_array, check_dt, check_finite, check_int

__all__ = ["IOData"]


class IOData:
    r"""Input/output record of one or several experiments (MATLAB's ``iddata``).

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu), or a list of them
        Input samples, time on axis 0 (pandas Series and DataFrames work
        too; their names become the signal names). A ``list`` or ``tuple``
        of arrays gives one experiment per item.
    y : array_like, shape (N,) or (N, ny), or a list of them
        Output samples, the same lengths (and number of experiments) as `u`.
    dt : True or float, default True
        Sampling period in seconds (``True``: unspecified, python-control's
        convention; times are then sample indices).
    input_names, output_names : sequence of str, optional
        One name per signal. Default: the pandas names, else ``"u"``
        (``"u1"``, ``"u2"``, ... for several inputs) and ``"y"``
        (``"y1"``, ...).
    input_units, output_units : sequence of str, optional
        One unit per signal (``""`` by default), used in plots and reports.
    experiment_names : sequence of str, optional
        One name per experiment, ``"exp1"``, ``"exp2"``, ... by default.
    tstart : float or sequence of float, optional
        Time of the first sample of each experiment (default 0).

    Attributes
    ----------
    u, y : ndarray
        One experiment only: its samples, shape ``(N,)`` for one signal,
        ``(N, n)`` otherwise (read-only views: copy them to modify).
    dt : True or float
    n_experiments, n_inputs, n_outputs : int
    n_samples : int
        Total number of samples over all experiments.
    lengths : tuple of int
        Samples per experiment.
    input_names, output_names, input_units, output_units : tuple of str
    experiment_names : tuple of str
    tstart : tuple of float

    Raises
    ------
    ValueError
        Mismatched lengths, different signal counts between experiments,
        NaN or inf samples (the experiment, signal and index are named),
        names or units of the wrong count, an empty experiment.
    TypeError
        Non-numeric or complex samples.

    Notes
    -----
    An `IOData` is immutable: its arrays are read-only and its attributes
    cannot be reassigned. Slicing (``data[100:]``), :meth:`getexp`,
    :meth:`split` and :meth:`merge` return new records that share memory
    with this one.

    Examples
    --------
    Two runs of the same plant, kept apart:

    >>> import numpy as np
    >>> from rlsfilt.data import IOData
    >>> rng = np.random.default_rng(0)
    >>> u1, u2 = rng.standard_normal(300), rng.standard_normal(200)
    >>> data = IOData([u1, u2], [0.5 * u1, 0.5 * u2], dt=0.1,
    ...               input_names=["valve"], output_names=["flow"],
    ...               input_units=["%"], output_units=["l/s"])
    >>> data.n_experiments, data.lengths
    (2, (300, 200))
    >>> est, val = data.split(0.7)              # per experiment
    >>> est.lengths, val.lengths
    ((210, 140), (90, 60))
    >>> data.getexp("exp2").u.shape
    (200,)
    """

    def __init__(self, u, y, dt=True, *, input_names=None, output_names=None, input_units=None,
                 output_units=None, experiment_names=None, tstart=None):
        us, u_listed = _experiments(u, "u")
        ys, y_listed = _experiments(y, "y")
        if len(us) != len(ys):
            raise ValueError(f"`u` and `y` must hold the same number of experiments; got "
                             f"{len(us)} input record(s) and {len(ys)} output record(s)")
        listed = u_listed or y_listed
        U, Y, u_pd, y_pd = [], [], None, None
        for i, (ui, yi) in enumerate(zip(us, ys)):
            tag = f"[{i}]" if listed else ""
            Ui, names_u = _signal(ui, f"u{tag}")
            Yi, names_y = _signal(yi, f"y{tag}")
            if len(Ui) != len(Yi):
                raise ValueError(f"`u{tag}` and `y{tag}` must have the same length; got "
                                 f"{len(Ui)} input samples and {len(Yi)} output samples")
            if len(Ui) == 0:
                raise ValueError(f"`u{tag}` and `y{tag}` must hold at least one sample; got 0")
            for X, first, what in ((Ui, U, "input"), (Yi, Y, "output")):
                if first and X.shape[1] != first[0].shape[1]:
                    raise ValueError(
                        f"every experiment must have the same number of {what}s; experiment 0 "
                        f"has {first[0].shape[1]} and experiment {i} has {X.shape[1]}")
            U.append(Ui)
            Y.append(Yi)
            u_pd = u_pd or names_u
            y_pd = y_pd or names_y
        dt = _check_dt(dt)
        nu, ny, ne = U[0].shape[1], Y[0].shape[1], len(U)
        in_names = _names(input_names, "input_names", nu, u_pd, "u")
        out_names = _names(output_names, "output_names", ny, y_pd, "y")
        both = sorted(set(in_names) & set(out_names))
        if both:
            raise ValueError(f"`input_names` and `output_names` must be distinct; {both[0]!r} "
                             "names an input and an output")
        in_units = _units(input_units, "input_units", nu)
        out_units = _units(output_units, "output_units", ny)
        exp_names = _exp_names(experiment_names, ne)
        tstart = _tstart(tstart, ne)
        for X in U + Y:
            X.setflags(write=False)
        self._init(tuple(U), tuple(Y), dt, in_names, out_names, in_units, out_units, exp_names,
                   tstart)

    # ------------------------------------------------------------------
    # construction helpers
    # ------------------------------------------------------------------
    def _init(self, U, Y, dt, in_names, out_names, in_units, out_units, exp_names, tstart):
        """Store validated parts (read-only arrays, tuples) and freeze."""
        set_ = object.__setattr__
        set_(self, "_U", U)
        set_(self, "_Y", Y)
        set_(self, "_dt", dt)
        set_(self, "_input_names", in_names)
        set_(self, "_output_names", out_names)
        set_(self, "_input_units", in_units)
        set_(self, "_output_units", out_units)
        set_(self, "_experiment_names", exp_names)
        set_(self, "_tstart", tstart)

    def _derive(self, U, Y, *, dt=None, experiment_names=None, tstart=None):
        """A plain `IOData` with this record's signal metadata and new samples."""
        new = IOData.__new__(IOData)
        new._init(tuple(U), tuple(Y), self._dt if dt is None else dt, self._input_names,
                  self._output_names, self._input_units, self._output_units,
                  self._experiment_names if experiment_names is None else tuple(experiment_names),
                  self._tstart if tstart is None else tuple(tstart))
        return new

    def __setattr__(self, name, value):
        raise AttributeError(f"{type(self).__name__} is immutable; build a new record instead "
                             f"of setting `{name}`")

    def __delattr__(self, name):
        raise AttributeError(f"{type(self).__name__} is immutable; cannot delete `{name}`")

    @classmethod
    def from_dataframe(cls, df, inputs, outputs, *, time=None, experiment=None, dt=None,
                       units=None):
        """Build a record from the columns of a pandas DataFrame.

        Parameters
        ----------
        df : pandas.DataFrame
            One row per sample.
        inputs, outputs : str or sequence of str
            Column names of the input and output signals (they become the
            signal names, and python-control's signal labels downstream).
        time : str, optional
            Column (or the index, by its name) holding the sample times:
            numbers in seconds, datetimes or timedeltas. The sampling period
            is inferred from it; the samples of each experiment must be
            increasing and uniformly spaced (to 0.1 % of the period).
        experiment : str, optional
            Column labelling the experiment of each row: the rows of each
            label form one experiment (in the order of first appearance, rows
            in their order in `df`).
        dt : float, optional
            Sampling period; without `time` it defaults to ``True``
            (unspecified). With `time`, it must agree with the inferred one.
        units : dict, optional
            ``{column: unit}`` for some or all of the signals.

        Returns
        -------
        IOData
            A plain `IOData`, also when called on a subclass such as `Dataset`.

        Raises
        ------
        ValueError
            Unknown columns (the available ones are listed), a non-uniform or
            non-increasing time column (the first offending row is named),
            NaN samples, a `dt` that disagrees with `time`.
        TypeError
            If `df` is not a DataFrame.

        Examples
        --------
        >>> import pandas as pd
        >>> from rlsfilt.data import IOData
        >>> df = pd.DataFrame({"t": [0.0, 0.5, 1.0, 0.0, 0.5],
        ...                    "run": ["a", "a", "a", "b", "b"],
        ...                    "Q": [1.0, 2.0, 3.0, 4.0, 5.0],
        ...                    "T": [90.0, 91.0, 93.0, 95.0, 96.0]})
        >>> data = IOData.from_dataframe(df, inputs="Q", outputs="T", time="t",
        ...                              experiment="run", units={"T": "degC"})
        >>> data.dt, data.lengths, data.experiment_names, data.output_units
        (0.5, (3, 2), ('a', 'b'), ('degC',))
        """
        import pandas as pd

        if not isinstance(df, pd.DataFrame):
            raise TypeError(f"`df` must be a pandas DataFrame; got {type(df).__name__}")
        in_labels, in_cols = _columns(inputs, "inputs", df)
        out_labels, out_cols = _columns(outputs, "outputs", df)
        if units is not None and not isinstance(units, dict):
            raise TypeError(f"`units` must be a dict {{column: unit}}; got {type(units).__name__}")
        units = dict(units or {})
        unknown = [c for c in units if c not in in_cols + out_cols]
        if unknown:
            raise ValueError(f"`units` names {unknown!r}, which are not among the signals "
                             f"{in_cols + out_cols!r}")
        if experiment is not None:
            if experiment not in df.columns:
                raise ValueError(f"`experiment` must be a column of `df`; got {experiment!r} "
                                 f"(columns: {list(map(str, df.columns))})")
            labels = df[experiment].to_numpy()
            missing = pd.isna(labels)
            if missing.any():
                raise ValueError(f"`experiment` column {experiment!r} must label every row; "
                                 f"got a missing label at row {df.index[missing.argmax()]!r}")
            order = list(dict.fromkeys(labels.tolist()))
            groups = [np.flatnonzero(labels == lab) for lab in order]
            exp_names = [str(lab) for lab in order]
        else:
            groups = [np.arange(len(df))]
            exp_names = None
        if len(df) == 0:
            raise ValueError("`df` must hold at least one row; got an empty DataFrame")
        times = None
        if time is not None:
            times = _time_values(df, time)
        elif isinstance(df.index, (pd.DatetimeIndex, pd.TimedeltaIndex)) and len(df) > 1:
            times = _time_values(df.set_axis(df.index.rename("__index__")), "__index__")
            time = "index"
        us, ys, tstart, steps = [], [], [], []
        for k, rows in enumerate(groups):
            sub = df.iloc[rows]
            label = f" in experiment {exp_names[k]!r}" if exp_names else ""
            us.append(_frame_block(sub, in_labels, label))
            ys.append(_frame_block(sub, out_labels, label))
            if times is not None:
                tk = times[rows]
                tstart.append(float(tk[0]))
                steps.append(_uniform_step(tk, time, df.index[rows], label))
        if times is not None:
            dt = _infer_dt(steps, dt, time)
        elif dt is None:
            dt = True
        return IOData(us if exp_names else us[0], ys if exp_names else ys[0], dt,
                      input_names=in_cols, output_names=out_cols,
                      input_units=[units.get(c, "") for c in in_cols],
                      output_units=[units.get(c, "") for c in out_cols],
                      experiment_names=exp_names, tstart=tstart or None)

    # ------------------------------------------------------------------
    # read-only views
    # ------------------------------------------------------------------
    @property
    def dt(self):
        """Sampling period (``True`` when unspecified)."""
        return self._dt

    @property
    def n_experiments(self):
        """Number of experiments."""
        return len(self._U)

    @property
    def n_inputs(self):
        """Number of input signals."""
        return self._U[0].shape[1]

    @property
    def n_outputs(self):
        """Number of output signals."""
        return self._Y[0].shape[1]

    @property
    def lengths(self):
        """Samples per experiment."""
        return tuple(len(U) for U in self._U)

    @property
    def n_samples(self):
        """Total number of samples over all experiments."""
        return sum(self.lengths)

    @property
    def input_names(self):
        """One name per input."""
        return self._input_names

    @property
    def output_names(self):
        """One name per output."""
        return self._output_names

    @property
    def input_units(self):
        """One unit per input (``""`` when unknown)."""
        return self._input_units

    @property
    def output_units(self):
        """One unit per output (``""`` when unknown)."""
        return self._output_units

    @property
    def experiment_names(self):
        """One name per experiment."""
        return self._experiment_names

    @property
    def tstart(self):
        """Time of the first sample of each experiment."""
        return self._tstart

    @property
    def u(self):
        """Input samples of a one-experiment record: ``(N,)`` or ``(N, nu)``, read-only."""
        return _one_or_all(self._single("u")[0])

    @property
    def y(self):
        """Output samples of a one-experiment record: ``(N,)`` or ``(N, ny)``, read-only."""
        return _one_or_all(self._single("y")[1])

    @property
    def t(self):
        """Sample times of a one-experiment record, ``tstart + k * dt`` (``k`` if dt is True)."""
        self._single("t")
        return self._times(0)

    def _times(self, i):
        step = 1.0 if self._dt is True else self._dt
        return self._tstart[i] + step * np.arange(self.lengths[i])

    def _single(self, what):
        if len(self._U) != 1:
            raise ValueError(
                f"`{what}` is defined for a record of one experiment; this one holds "
                f"{len(self._U)} ({', '.join(self._experiment_names)}): use "
                f"`getexp(i).{what}`, `experiments` or `arrays()`")
        return self._U[0], self._Y[0]

    def arrays(self):
        """The samples as ``[(U, Y), ...]``, one pair of 2-D read-only arrays per experiment.

        Returns
        -------
        list of tuple of ndarray
            ``U`` of shape ``(N_i, nu)`` and ``Y`` of shape ``(N_i, ny)``.
        """
        return list(zip(self._U, self._Y))

    @property
    def experiments(self):
        """The experiments as a tuple of one-experiment records."""
        return tuple(self.getexp(i) for i in range(self.n_experiments))

    # ------------------------------------------------------------------
    # selection, splitting, merging
    # ------------------------------------------------------------------
    def getexp(self, which):
        """The record restricted to some experiments (MATLAB ``getexp``).

        Parameters
        ----------
        which : int, str, or sequence of them
            Experiment indices (negative counts from the end) or names.

        Returns
        -------
        IOData
            With the chosen experiments, in the order given.
        """
        picks = _exp_indices(which, self._experiment_names)
        if len(set(picks)) != len(picks):
            twice = next(self._experiment_names[k] for k in picks if picks.count(k) > 1)
            raise ValueError(f"`which` picks experiment {twice!r} more than once; an "
                             "experiment's samples are one record (concatenate copies with "
                             "merge() under new names instead)")
        return self._derive([self._U[i] for i in picks], [self._Y[i] for i in picks],
                            experiment_names=[self._experiment_names[i] for i in picks],
                            tstart=[self._tstart[i] for i in picks])

    def __getitem__(self, index):
        """Samples selected by a slice, applied to every experiment.

        ``data[100:]`` drops the first 100 samples of each experiment;
        ``data[::2]`` keeps every other sample and doubles ``dt`` (no
        anti-alias filter is applied).
        """
        if not isinstance(index, slice):
            raise TypeError(f"an IOData is indexed by a slice of samples (data[100:500]); got "
                            f"{type(index).__name__}. Use getexp() to pick experiments")
        start, stop, step = index.start, index.stop, index.step
        for name, v in (("start", start), ("stop", stop), ("step", step)):
            if v is not None:
                check_int(v, f"slice {name}")
        if step is not None and step < 1:
            raise ValueError(f"the slice step must be >= 1 (samples keep their order); got "
                             f"{step}")
        U, Y, t0 = [], [], []
        for i, (Ui, Yi) in enumerate(zip(self._U, self._Y)):
            first, last, stride = index.indices(len(Ui))
            Un, Yn = Ui[first:last:stride], Yi[first:last:stride]
            if len(Un) == 0:
                raise ValueError(f"the slice {_slice_text(index)} leaves no samples of "
                                 f"experiment {self._experiment_names[i]!r} "
                                 f"({len(Ui)} samples)")
            U.append(Un)
            Y.append(Yn)
            t0.append(self._tstart[i] + first * (1.0 if self._dt is True else self._dt))
        step = 1 if step is None else step
        dt = self._dt if self._dt is True or step == 1 else self._dt * step
        return self._derive(U, Y, dt=dt, tstart=t0)

    def split(self, fraction=0.7):
        """Estimation and validation parts: the first `fraction` of each experiment, and the rest.

        Parameters
        ----------
        fraction : float, default 0.7
            Share of each experiment's samples (rounded to the nearest
            sample) that goes to the estimation part, in (0, 1).

        Returns
        -------
        estimation, validation : IOData
            Each with every experiment (the validation part starts where
            the estimation part stops, and keeps its times).

        Raises
        ------
        ValueError
            If `fraction` is not in (0, 1) or leaves an experiment's part
            empty.
        """
        if isinstance(fraction, bool) or not isinstance(fraction, numbers.Real) \
                or not 0.0 < fraction < 1.0:
            raise ValueError(f"`fraction` must be a number in (0, 1); got {fraction!r}")
        est_U, est_Y, val_U, val_Y, t0 = [], [], [], [], []
        for i, (Ui, Yi) in enumerate(zip(self._U, self._Y)):
            n = len(Ui)
            k = int(round(fraction * n))
            if not 0 < k < n:
                raise ValueError(
                    f"`fraction`={fraction} leaves an empty part of experiment "
                    f"{self._experiment_names[i]!r} ({n} samples -> {k} + {n - k})")
            est_U.append(Ui[:k])
            est_Y.append(Yi[:k])
            val_U.append(Ui[k:])
            val_Y.append(Yi[k:])
            t0.append(self._tstart[i] + k * (1.0 if self._dt is True else self._dt))
        return self._derive(est_U, est_Y), self._derive(val_U, val_Y, tstart=t0)

    def merge(self, *others):
        """One record holding the experiments of this one and of `others` (MATLAB ``merge``).

        Parameters
        ----------
        *others : IOData
            Records with the same signals (counts and names) and the same
            sampling period.

        Returns
        -------
        IOData
            The experiments in order. Names are kept when they are unique;
            otherwise every experiment is renamed ``exp1``, ``exp2``, ...

        Raises
        ------
        TypeError
            If an item is not an IOData.
        ValueError
            Different signal counts, names or sampling periods.
        """
        recs = [self]
        for i, other in enumerate(others):
            if not isinstance(other, IOData):
                raise TypeError(f"`others[{i}]` must be an IOData; got {type(other).__name__}")
            for attr in ("input_names", "output_names"):
                if getattr(other, attr) != getattr(self, attr):
                    raise ValueError(f"`others[{i}]` must have the same {attr} to be merged; "
                                     f"got {getattr(other, attr)} and {getattr(self, attr)}")
            if not _same_dt(other.dt, self.dt):
                raise ValueError(f"`others[{i}]` must have the same sampling period to be "
                                 f"merged; got dt={other.dt!r} and dt={self.dt!r}")
            recs.append(other)
        names = [n for r in recs for n in r.experiment_names]
        if len(set(names)) != len(names):
            names = [f"exp{k + 1}" for k in range(len(names))]
        return self._derive([U for r in recs for U in r._U], [Y for r in recs for Y in r._Y],
                            experiment_names=names, tstart=[t for r in recs for t in r._tstart])

    # ------------------------------------------------------------------
    # conversion and display
    # ------------------------------------------------------------------
    def to_dataframe(self, *, time="t", experiment="experiment"):
        """The record as one pandas DataFrame (the inverse of :meth:`from_dataframe`).

        Parameters
        ----------
        time : str or None, default "t"
            Name of the time column (None: no time column).
        experiment : str or None, default "experiment"
            Name of the experiment column, written only for several
            experiments (None: never).

        Returns
        -------
        pandas.DataFrame
            Columns: `experiment`, `time`, the inputs, the outputs.
        """
        import pandas as pd

        frames = []
        for i, (Ui, Yi) in enumerate(zip(self._U, self._Y)):
            cols = {}
            if experiment is not None and self.n_experiments > 1:
                cols[experiment] = [self._experiment_names[i]] * len(Ui)
            if time is not None:
                cols[time] = self._times(i)
            for j, name in enumerate(self._input_names):
                cols[name] = Ui[:, j]
            for j, name in enumerate(self._output_names):
                cols[name] = Yi[:, j]
            frames.append(pd.DataFrame(cols))
        return pd.concat(frames, ignore_index=True)

    def _signal_text(self, names, units):
        return ", ".join(f"{n} [{u}]" if u else n for n, u in zip(names, units))

    def _header(self):
        dt = "unspecified" if self._dt is True else f"{self._dt:g} s"
        ne = self.n_experiments
        return (f"{type(self).__name__}: {ne} experiment{'s' if ne > 1 else ''}, "
                f"{self.n_samples} samples, dt = {dt}\n"
                f"  inputs:  {self._signal_text(self._input_names, self._input_units)}\n"
                f"  outputs: {self._signal_text(self._output_names, self._output_units)}")

    def _exp_rows(self):
        rows = []
        for i, n in enumerate(self.lengths):
            t = self._times(i)
            unit = "" if self._dt is True else " s"
            rows.append((self._experiment_names[i], n, f"{t[0]:g} .. {t[-1]:g}{unit}"))
        return rows

    def __repr__(self):
        lines = [self._header()]
        if self.n_experiments > 1:
            lines += [f"  {name}: {n} samples, t = {span}" for name, n, span in self._exp_rows()]
        return "\n".join(lines)

    def _repr_html_(self):
        esc = html.escape
        dt = "unspecified" if self._dt is True else f"{self._dt:g} s"
        head = (f"<p><b>{esc(type(self).__name__)}</b>: {self.n_experiments} experiment(s), "
                f"{self.n_samples} samples, dt = {dt}<br>inputs: "
                f"{esc(self._signal_text(self._input_names, self._input_units))}<br>outputs: "
                f"{esc(self._signal_text(self._output_names, self._output_units))}</p>")
        rows = "".join(f"<tr><td>{esc(name)}</td><td>{n}</td><td>{esc(span)}</td></tr>"
                       for name, n, span in self._exp_rows())
        return head + ("<table><tr><th>experiment</th><th>samples</th><th>time</th></tr>"
                       f"{rows}</table>")

    def plot(self, fig=None):
        """Inputs and outputs against time, one row of axes per signal.

        Parameters
        ----------
        fig : matplotlib.figure.Figure, optional
            Figure to draw in (a new one by default).

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=(8, 2 * (self.n_inputs + self.n_outputs))) if fig is None \
            else fig
        n_rows = self.n_inputs + self.n_outputs
        axes = fig.subplots(n_rows, 1, sharex=True, squeeze=False)[:, 0]
        signals = ([(self._output_names[j], self._output_units[j], 1, j)
                    for j in range(self.n_outputs)]
                   + [(self._input_names[j], self._input_units[j], 0, j)
                      for j in range(self.n_inputs)])
        for ax, (name, unit, is_out, j) in zip(axes, signals):
            for i in range(self.n_experiments):
                block = self._Y[i] if is_out else self._U[i]
                ax.plot(self._times(i), block[:, j], lw=0.8,
                        label=self._experiment_names[i] if self.n_experiments > 1 else None,
                        drawstyle="default" if is_out else "steps-post")
            ax.set_ylabel(f"{name} [{unit}]" if unit else name)
        axes[-1].set_xlabel("time [s]" if self._dt is not True else "sample")
        if self.n_experiments > 1:
            axes[0].legend(loc="best")
        return fig


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _is_signal_object(x):
    return isinstance(x, np.ndarray) or hasattr(x, "to_numpy")


def _experiments(x, name):
    """``([item, ...], listed)``: a list/tuple of arrays is one experiment per item."""
    if isinstance(x, IOData):
        raise TypeError(f"`{name}` must be array-like; got an IOData (pass it as `data`)")
    if isinstance(x, (list, tuple)) and x and any(_is_signal_object(item) for item in x):
        return list(x), True
    return [x], False


def _signal(x, name):
    """A validated ``(N, n)`` float copy and the pandas names (or None)."""
    names = None
    cols = getattr(x, "columns", None)
    if cols is not None:
        names = [str(c) for c in cols]
    elif getattr(x, "name", None) is not None and hasattr(x, "index"):
        names = [str(x.name)]
    if hasattr(x, "to_numpy"):
        x = x.to_numpy()
    arr = as_float_array(x, name)
    if arr.ndim == 1:
        arr = arr.reshape(-1, 1)
    elif arr.ndim != 2:
        raise ValueError(f"`{name}` must have shape (N,) or (N, n_signals); got {arr.shape}")
    if arr.shape[1] == 0:
        raise ValueError(f"`{name}` must have at least one column; got shape {arr.shape}")
    check_finite(arr[:, 0] if arr.shape[1] == 1 else arr, name)
    return np.array(arr, dtype=float, order="C", copy=True), names


def _check_dt(dt):
    if isinstance(dt, np.floating):
        dt = float(dt)
    return check_dt(dt)


def _strings(value, name, count):
    if isinstance(value, str):
        value = [value]
    try:
        values = list(value)
    except TypeError:
        raise TypeError(f"`{name}` must be a sequence of strings; got "
                        f"{type(value).__name__}") from None
    if len(values) != count:
        raise ValueError(f"`{name}` must have {count} entr{'y' if count == 1 else 'ies'}; got "
                         f"{len(values)}")
    for v in values:
        if not isinstance(v, str):
            raise TypeError(f"`{name}` must hold strings; got {v!r} ({type(v).__name__})")
    return tuple(values)


def _names(value, name, count, from_pandas, prefix):
    if value is None:
        if from_pandas is not None and len(from_pandas) == count:
            value = from_pandas
        else:
            value = [prefix] if count == 1 else [f"{prefix}{k + 1}" for k in range(count)]
    names = _strings(value, name, count)
    if len(set(names)) != len(names):
        raise ValueError(f"`{name}` must be distinct; got {list(names)}")
    return names


def _units(value, name, count):
    return ("",) * count if value is None else _strings(value, name, count)


def _exp_names(value, count):
    if value is None:
        return tuple(f"exp{k + 1}" for k in range(count))
    names = _strings(value, "experiment_names", count)
    if len(set(names)) != len(names):
        raise ValueError(f"`experiment_names` must be distinct; got {list(names)}")
    return names


def _tstart(value, count):
    if value is None:
        return (0.0,) * count
    arr = np.atleast_1d(as_float_array(value, "tstart"))
    if arr.ndim != 1 or len(arr) not in (1, count):
        raise ValueError(f"`tstart` must be a number or have one entry per experiment "
                         f"({count}); got shape {arr.shape}")
    check_finite(arr, "tstart")
    return tuple(float(v) for v in np.broadcast_to(arr, (count,)))


def _one_or_all(X):
    return X[:, 0] if X.shape[1] == 1 else X


def _exp_indices(which, names):
    items = [which] if isinstance(which, (str, numbers.Integral)) else which
    try:
        items = list(items)
    except TypeError:
        raise TypeError(f"`which` must be an experiment index, a name, or a sequence of them; "
                        f"got {type(which).__name__}") from None
    if not items:
        raise ValueError("`which` must name at least one experiment; got an empty sequence")
    n, picks = len(names), []
    for item in items:
        if isinstance(item, str):
            if item not in names:
                raise ValueError(f"`which` names an unknown experiment {item!r}; the "
                                 f"experiments are {list(names)}")
            picks.append(names.index(item))
        else:
            k = check_int(item, "which")
            if not -n <= k < n:
                raise ValueError(f"`which` must be an experiment index in [{-n}, {n - 1}]; "
                                 f"got {k}")
            picks.append(k % n)
    return picks


def _slice_text(index):
    parts = ["" if v is None else str(v) for v in (index.start, index.stop, index.step)]
    return "[" + ":".join(parts if index.step is not None else parts[:2]) + "]"


def _same_dt(a, b):
    if a is True or b is True:
        return a is b
    return abs(a - b) <= 1e-9 * max(abs(a), abs(b))


def _columns(value, name, df):
    """The column labels `value` names (one label, or a list of them) as ``(labels,
    names)``: the labels as `df` has them (text, integers, ...) and their text."""
    cols = [value] if isinstance(value, (str, numbers.Integral)) else value
    try:
        cols = list(cols)
    except TypeError:
        raise TypeError(f"`{name}` must be a column name or a list of them; got "
                        f"{type(value).__name__}") from None
    if not cols:
        raise ValueError(f"`{name}` must name at least one column; got none")
    missing = [c for c in cols if c not in df.columns]
    if missing:
        raise ValueError(f"`{name}` names columns that are not in `df`: {missing!r} "
                         f"(columns: {list(map(str, df.columns))})")
    repeated = [c for c in cols if np.count_nonzero(df.columns == c) > 1]
    if repeated:
        raise ValueError(f"`{name}` names {repeated[0]!r}, which `df` has "
                         f"{np.count_nonzero(df.columns == repeated[0])} columns of; rename "
                         "them so that each signal has one column")
    return cols, [str(c) for c in cols]


def _frame_block(sub, cols, label):
    import pandas as pd

    block = sub[cols]
    for c in cols:
        if not pd.api.types.is_numeric_dtype(block[c]) or pd.api.types.is_bool_dtype(block[c]):
            raise TypeError(f"column {c!r}{label} must be numeric; got dtype {block[c].dtype}")
    values = block.to_numpy(dtype=float)
    bad = ~np.isfinite(values)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise ValueError(f"column {cols[c]!r}{label} must be finite; got {values[r, c]} at row "
                         f"{sub.index[r]!r} (remove or fill missing samples first)")
    return values


def _time_values(df, time):
    """The time column (or the index, by name) in seconds as floats."""
    import pandas as pd

    if time in df.columns:
        col = df[time]
    elif df.index.name == time:
        col = df.index.to_series()
    else:
        raise ValueError(f"`time` must be a column of `df` or the name of its index; got "
                         f"{time!r} (columns: {list(map(str, df.columns))})")
    if time == "__index__":                 # a DatetimeIndex or TimedeltaIndex
        time = "index"
    if pd.api.types.is_datetime64_any_dtype(col):
        col = (col - col.iloc[0]).dt.total_seconds()
    elif pd.api.types.is_timedelta64_dtype(col):
        col = col.dt.total_seconds()
    elif not pd.api.types.is_numeric_dtype(col) or pd.api.types.is_bool_dtype(col):
        raise TypeError(f"`time` column {time!r} must hold numbers, datetimes or timedeltas; "
                        f"got dtype {col.dtype}")
    t = col.to_numpy(dtype=float)
    check_finite(t, f"time column {time!r}")
    return t


def _uniform_step(t, name, index, label):
    """The mean step of one experiment's times, or None for a single sample."""
    if len(t) < 2:
        return None
    d = np.diff(t)
    if np.any(d <= 0):
        r = int(np.argmax(d <= 0)) + 1
        raise ValueError(f"`time` column {name!r}{label} must be increasing; got "
                         f"{t[r - 1]:g} then {t[r]:g} at row {index[r]!r}")
    # the median step is the nominal period (robust to a few irregular steps), so the
    # first step off by more than 0.1 % of it is the one to report
    nominal = float(np.median(d))
    off = np.abs(d - nominal) > 1e-3 * nominal
    if off.any():
        r = int(np.argmax(off)) + 1
        raise ValueError(
            f"`time` column {name!r}{label} is not uniformly sampled: steps range from "
            f"{d.min():g} to {d.max():g} (typical {nominal:g}); the first irregular step ends "
            f"at row {index[r]!r}. Resample the record to a uniform grid first")
    return (t[-1] - t[0]) / (len(t) - 1), len(t) - 1


def _infer_dt(steps, dt, name):
    known = [s for s in steps if s is not None]
    if not known:
        raise ValueError(f"`time` column {name!r} cannot give a sampling period: every "
                         "experiment has a single sample")
    inferred = sum(s * n for s, n in known) / sum(n for _, n in known)
    for s, _ in known:
        if abs(s - inferred) > 1e-3 * inferred:
            raise ValueError(f"the experiments of `time` column {name!r} have different "
                             f"sampling periods ({min(s for s, _ in known):g} to "
                             f"{max(s for s, _ in known):g}); resample them to one rate")
    if dt is not None and dt is not True:
        if isinstance(dt, bool) or not isinstance(dt, numbers.Real) \
                or abs(dt - inferred) > 1e-3 * inferred:
            raise ValueError(f"`dt`={dt!r} disagrees with the sampling period {inferred:g} of "
                             f"`time` column {name!r}")
        return float(dt)
    # the mean step carries the round-off of the time stamps (0.1 -> 0.09999999999999998):
    # twelve significant digits are far below the 0.1 % uniformity tolerance
    return float(f"{inferred:.12g}")


def as_iodata(u, y=None, dt=None, *, u_name="u", y_name="y"):
    """`u` if it is an `IOData` (then `y` must be omitted), else ``IOData(u, y, dt)``.

    The one place where functions that take ``(u, y)`` or an `IOData` sort
    out their first two arguments.
    """
    if isinstance(u, IOData):
        if y is not None:
            raise TypeError(f"`{y_name}` must be omitted when `{u_name}` is an IOData (it "
                            f"holds the outputs); got {type(y).__name__}")
        if dt is not None and not _same_dt(_check_dt(dt), u.dt):
            raise ValueError(f"`dt`={dt!r} disagrees with the IOData's dt={u.dt!r}")
        return u
    if y is None:
        raise TypeError(f"`{y_name}` is required unless `{u_name}` is an IOData")
    return IOData(u, y, dt=True if dt is None else dt)
