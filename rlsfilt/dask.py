r"""Fleets past one machine: :func:`rlsfilt.fit_many` over Dask collections.

Install with ``pip install "rlsfilt[dask]"``; ``import rlsfilt`` never imports
Dask, only ``import rlsfilt.dask`` does.

The fits of a fleet are independent per channel, so the fleet is split by
channel: every block of channels (a chunk of a dask array, a partition of a
dask DataFrame) becomes one task that runs the in-memory
:func:`rlsfilt.models.fit_many` on its channels where the block lives and
returns only its per-channel summary (one row per channel: parameters,
standard errors, fits, residual tests). The records themselves never travel
back; a channel's estimates and fits do not depend on which other channels
share its block, so they equal the in-memory ``fit_many(...).to_dataframe()``
bit for bit; its residual-test statistics (computed vectorized over a
block) to round-off; and so, like it, each channel's own ``ARX.fit`` and
``validate`` to round-off (a few units in the last place: the fleet's
least squares and recursion are not the single model's code).

Any scheduler works: with a ``dask.distributed.Client`` active (or passed
as `client`), the tasks run on its workers, and its dashboard and
:func:`dask.distributed.progress` show their progress.

Examples
--------
Two workers on this machine, and a fleet chunked by channel (on a cluster,
create the arrays where the data lives, e.g. ``da.from_zarr``, so that the
records go from storage to the workers and only summaries come back):

>>> import numpy as np
>>> import dask.array as da
>>> from dask.distributed import Client, LocalCluster
>>> from rlsfilt import ARX
>>> import rlsfilt.dask
>>> client = Client(LocalCluster(n_workers=2, threads_per_worker=1))  # doctest: +SKIP
>>> rng = np.random.default_rng(0)
>>> u = da.from_array(rng.standard_normal((500, 64)), chunks=(-1, 16))
>>> y = 0.5 * u + 0.1 * da.from_array(rng.standard_normal((500, 64)), chunks=(-1, 16))
>>> table = rlsfilt.dask.fit_many(ARX(0, 1, 0), u, y)   # a pandas DataFrame
>>> table.shape[0]
64
"""

import dask
import dask.array as da
import dask.dataframe as dd
import numpy as np
import pandas as pd

from .models.fleet import _summary_long, _summary_schema
from .models.fleet import fit_many as _fit_many

__all__ = ["fit_many", "fit_many_frame"]


def fit_many(model, u, y, method="ls", *, channels=None, client=None, compute=True,
             **options):
    r"""`fit_many` over dask arrays chunked by channel.

    Parameters
    ----------
    model : ARX
        The orders of every channel.
    u : dask.array.Array or array_like, shape (N, C) or (N, C, n_inputs)
        Inputs, time on axis 0. Each task gets the whole time axis of a block
        of channels: `u` is rechunked to one chunk along time (and inputs),
        with the channel chunks of `y`.
    y : dask.array.Array or array_like, shape (N, C)
        Outputs, chunked by channel (axis 1).
    method : {"ls", "rls", "nlms", "lms"}, default "ls"
    channels : sequence, optional
        Channel labels (default ``0 .. C-1``).
    client : dask.distributed.Client, optional
        Where to compute; the current default scheduler if omitted.
    compute : bool, default True
        Return the computed pandas DataFrame; with ``False``, the lazy dask
        DataFrame (one partition per channel block), to ``persist``,
        ``compute`` or watch with :func:`dask.distributed.progress`.
    **options
        Any option of :func:`rlsfilt.models.fit_many` (``lam``, ``k0``,
        ``residual_tests``, ``on_error``, ``forgetting``, ...); per-channel
        arrays of length C are split with the channels.

    Returns
    -------
    pandas.DataFrame or dask.dataframe.DataFrame
        ``fit_many(model, u, y, method, **options).to_dataframe()``: the estimates
        and fits equal to it bit for bit, the residual-test statistics to
        round-off (see the module notes). The ``error`` column of the lazy frame (None where a
        channel was fitted) is dropped from the computed one when no
        channel failed, as in the in-memory summary.
    """
    y = da.asarray(y)
    u = da.asarray(u)
    if y.ndim != 2:
        raise ValueError(f"`y` must have shape (N, C) (one column per channel); got {y.shape}")
    if u.ndim not in (2, 3):
        raise ValueError(f"`u` must have shape (N, C) or (N, C, n_inputs); got {u.shape}")
    N, C = y.shape
    if u.shape[0] != N:
        raise ValueError(f"`u` and `y` must have the same length; got {u.shape[0]} input "
                         f"samples and {N} output samples")
    if u.shape[1] != C:
        raise ValueError(f"`u` must have one column per channel of `y` ({C}); got {u.shape[1]}")
    labels = list(range(C)) if channels is None else list(channels)
    if len(labels) != C:
        raise ValueError(f"`channels` must have one label per channel ({C}); got {len(labels)}")
    y = y.rechunk({0: -1})
    u = u.rechunk({0: -1, 1: y.chunks[1]} | ({2: -1} if u.ndim == 3 else {}))
    bounds = np.concatenate([[0], np.cumsum(y.chunks[1])])
    yb = y.to_delayed().reshape(-1)
    ub = u.to_delayed().reshape(-1)
    fit = dask.delayed(_fit_block)
    parts = [fit(model, ub[i], yb[i], method, labels[lo:hi], _split(options, lo, hi, C))
             for i, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:]))]
    n_inputs = 1 if u.ndim == 2 else u.shape[2]
    return _collect(parts, _meta(model, n_inputs, method, options, labels), client, compute)


def fit_many_frame(model, frame, *, channel, input, output, method="ls", client=None,
                   compute=True, **options):
    r"""`fit_many` over a long-format dask DataFrame partitioned by channel.

    Parameters
    ----------
    model : ARX
        The orders of every channel.
    frame : dask.dataframe.DataFrame or pandas.DataFrame
        One row per sample: the channel label in column `channel`, the
        input(s) in `input`, the output in `output`, each channel's rows in
        time order. Every channel must lie in one partition (as after
        reading one file per group of channels, or ``frame.shuffle(channel)``);
        each partition is fitted where it lives. Channels may have different
        lengths.
    channel, output : str
        Column names.
    input : str or list of str
        Input column(s).
    method, client, compute, **options
        As in :func:`fit_many` (per-channel arrays are not accepted here).

    Returns
    -------
    pandas.DataFrame or dask.dataframe.DataFrame
        One row per channel, in order of appearance, as
        ``fit_many(...).to_dataframe()`` of the channels (with the ``error``
        column when the frame is lazy or some channel failed).

    Raises
    ------
    ValueError
        When a channel has rows in more than one partition (when computed,
        also the lazy frame of ``compute=False``: no duplicate rows of a
        channel fitted piecewise), naming the channel and the partitions.
    """
    if isinstance(frame, pd.DataFrame):
        frame = dd.from_pandas(frame, npartitions=1)
    if not isinstance(frame, dd.DataFrame):
        raise TypeError(f"`frame` must be a dask or pandas DataFrame; got "
                        f"{type(frame).__name__}")
    for name, value in options.items():
        if np.ndim(value) > 0 and name not in ("P0", "Q", "x0", "forgetting_params"):
            raise ValueError(f"`{name}` must be one value for every channel in "
                             "fit_many_frame; got an array")
    inputs = [input] if isinstance(input, str) else list(input)
    meta = _meta(model, len(inputs), method, options, frame[channel]._meta.to_numpy())
    # each partition's task also gets the labels of every partition (small), so that
    # a channel split over partitions is refused where it is fitted, lazy or not
    blocks = frame.to_delayed()
    label_sets = [dask.delayed(_labels)(part, channel) for part in blocks]
    fit = dask.delayed(_fit_partition)
    parts = [fit(i, label_sets, model, part, channel, inputs, output, method, options)
             for i, part in enumerate(blocks)]
    return _collect(parts, meta, client, compute)


def _fit_block(model, u, y, method, labels, options):
    """One task: the summary of a block of channels (the only thing sent back)."""
    table = _fit_many(model, u, y, method, channels=labels, **options).to_dataframe()
    if "error" not in table:
        table["error"] = None
    return table


def _labels(part, channel):
    """The distinct channel labels of one partition."""
    return pd.unique(part[channel])


def _fit_partition(i, label_sets, model, part, channel, inputs, output, method, options):
    """One task of `fit_many_frame`: partition `i`'s summary, after checking that
    none of its channels has rows in another partition (`label_sets`, one per
    partition): such a channel's record would be fitted piecewise, as several
    channels with the same label."""
    mine = label_sets[i]
    for j, other in enumerate(label_sets):
        if j == i or not len(other):
            continue
        shared = pd.Index(mine).intersection(pd.Index(other))
        if len(shared):
            first, second = min(i, j), max(i, j)
            label = shared[0].item() if isinstance(shared[0], np.generic) else shared[0]
            raise ValueError(f"channel {label!r} has rows in partitions {first} and "
                             f"{second} of `frame`: each channel must lie in one partition "
                             f"(its record is fitted where it lives); repartition by channel "
                             f"first, keeping each channel's rows in time order")
    return _summary_long(model, part, channel, inputs, output, method, **options)


def _split(options, lo, hi, C):
    """Options for channels ``lo .. hi - 1``: per-channel arrays are sliced."""
    out = {}
    for key, value in options.items():
        arr = np.asarray(value) if not isinstance(value, (str, dict)) else None
        if arr is not None and arr.ndim >= 1 and arr.shape[0] == C and key != "channels" and (
                key not in ("P0", "Q") or arr.ndim in (1, 3)) and (key != "x0" or arr.ndim == 2):
            out[key] = arr[lo:hi]
        else:
            out[key] = value
    return out


def _meta(model, n_inputs, method, options, labels):
    schema = _summary_schema(model, n_inputs, method, options)
    index = pd.Index(np.asarray(labels)[:0], name="channel")
    return pd.DataFrame({col: pd.Series(dtype=dtype) for col, dtype in schema.items()},
                        index=index)


def _collect(parts, meta, client, compute):
    """The lazy frame, or the computed one in the types of `ARXBank.to_dataframe`."""
    lazy = dd.from_delayed(parts, meta=meta, verify_meta=False)
    if not compute:
        return lazy
    table = client.compute(lazy).result() if client is not None else lazy.compute()
    # Dask may hand back strings as Arrow strings: rebuild the index and the
    # error column as the in-memory summary makes them
    table.index = pd.Index(table.index.tolist(), name="channel")
    errors = [None if pd.isna(e) else str(e) for e in table["error"]]
    if all(e is None for e in errors):
        return table.drop(columns="error")
    table["error"] = pd.Series(errors, index=table.index, dtype=object)
    return table

