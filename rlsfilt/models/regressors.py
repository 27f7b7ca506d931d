r"""ARX structure and regressor matrices.

One convention for the whole package, the one of MATLAB's System
Identification Toolbox (``arx(data, [na nb nk])``):

.. math::

    y(t) + a_1 y(t-1) + \dots + a_{n_a} y(t-n_a)
        = b_1 u(t-n_k) + \dots + b_{n_b} u(t-n_k-n_b+1) + e(t),

so that :math:`y(t) = \varphi(t)\,\theta + e(t)` with the regressor row,
per-signal blocks each ordered by increasing lag,

.. math::

    \varphi(t) = [-y(t-1), \dots, -y(t-n_a),\;
                  u(t-n_k), \dots, u(t-n_k-n_b+1)],
    \qquad \theta = [a_1, \dots, a_{n_a}, b_1, \dots, b_{n_b}]^T,

stacked for :math:`t = t_0, \dots, N-1` with
:math:`t_0 = \max(n_a, n_k + n_b - 1)`, the first sample whose regressor is
complete. With several inputs there is one ``u`` block per input (``nb`` and
``nk`` per input); with several outputs the ``-y`` blocks of every output come
first, and every output is regressed on the same row.
"""

import numbers
from collections.abc import Mapping, Sequence

import numpy as np

from .._scale import unit_columns
from .._validation import as_float_array, check_finite, check_int, check_not_dates

__all__ = ["arx_regressors", "arx_structure", "ARXStructure"]


class ARXStructure:
    """Validated orders of an ARX model with a known number of signals.

    Attributes
    ----------
    na : int
        Number of past outputs of each output signal.
    nb, nk : tuple of int
        Number of input coefficients and input delay, one per input.
    n_inputs, n_outputs : int
        Number of input and output signals.
    max_lag : int
        ``t0 = max(na, max(nk + nb - 1))``: the first sample with a complete
        regressor, and the number of samples lost at the start.
    n_params : int
        Length of the regressor row, ``n_outputs * na + sum(nb)``.
    """

    __slots__ = ("na", "nb", "nk", "n_inputs", "n_outputs", "max_lag", "n_params")

    def __init__(self, na, nb, nk, n_inputs, n_outputs):
        self.na, self.nb, self.nk = na, nb, nk
        self.n_inputs, self.n_outputs = n_inputs, n_outputs
        self.max_lag = max([na] + [k + b - 1 for b, k in zip(nb, nk)])
        self.n_params = n_outputs * na + sum(nb)

    def param_slices(self):
        """``(a_slice, [b_slice per input])`` into the regressor row."""
        na_tot = self.n_outputs * self.na
        b_slices, start = [], na_tot
        for b in self.nb:
            b_slices.append(slice(start, start + b))
            start += b
        return slice(0, na_tot), b_slices

    def __repr__(self):
        return (f"ARXStructure(na={self.na}, nb={self.nb}, nk={self.nk}, "
                f"n_inputs={self.n_inputs}, n_outputs={self.n_outputs})")

    def to_dict(self):
        """Plain ints and lists (for saving a model); :meth:`from_dict` rebuilds it."""
        return {"na": self.na, "nb": list(self.nb), "nk": list(self.nk),
                "n_inputs": self.n_inputs, "n_outputs": self.n_outputs}

    @classmethod
    def from_dict(cls, d):
        """The structure saved by :meth:`to_dict` (validated again)."""
        return arx_structure(d["na"], list(d["nb"]), list(d["nk"]), d["n_inputs"],
                             d["n_outputs"])


def _per_input(value, name, n_inputs, minimum):
    """A scalar order or one per input, as a tuple of validated ints."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return (check_int(value, name, minimum=minimum),) * n_inputs
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        check_int(value, name, minimum=minimum)  # raises the TypeError
    if not isinstance(value, (Sequence, np.ndarray)):  # sets and dicts have no input order
        raise TypeError(f"`{name}` must be an integer or a sequence of integers (one per "
                        f"input, in input order); got {type(value).__name__}")
    values = list(value)
    if len(values) != n_inputs:
        raise ValueError(
            f"`{name}` must be an integer or have one entry per input ({n_inputs}); "
            f"got {len(values)} entries")
    return tuple(check_int(v, f"{name}[{i}]", minimum=minimum) for i, v in enumerate(values))


def arx_structure(na, nb, nk=1, n_inputs=1, n_outputs=1):
    """Validate ARX orders and return an `ARXStructure`.

    Parameters
    ----------
    na : int
        Number of past outputs, ``>= 0`` (``0`` is an FIR model).
    nb : int or sequence of int
        Number of input coefficients, ``>= 1``; one per input or a scalar
        for all.
    nk : int or sequence of int, default 1
        Input delay in samples, ``>= 0`` (``0``: direct feed-through).
    n_inputs, n_outputs : int, default 1
        Number of input and output signals.

    Raises
    ------
    ValueError
        For negative orders, ``nb < 1``, or a list of the wrong length.
    TypeError
        For non-integer orders.
    """
    n_inputs = check_int(n_inputs, "n_inputs", minimum=1)
    n_outputs = check_int(n_outputs, "n_outputs", minimum=1)
    na = check_int(na, "na", minimum=0)
    nb = _per_input(nb, "nb", n_inputs, minimum=1)
    nk = _per_input(nk, "nk", n_inputs, minimum=0)
    return ARXStructure(na, nb, nk, n_inputs, n_outputs)


def _as_signal(x, name, copy=True):
    """Return ``(array of shape (N, n), was_1d, names)`` from array-like or pandas.

    A mapping of names to 1-D signals (``{"volts": v, "amps": i}``) is read
    like a DataFrame: one column per entry, named by its key. ``copy=False``
    may return a view of the caller's array (for a caller that only reads it).
    """
    names = None
    if isinstance(x, Mapping):
        if not x:
            raise ValueError(f"`{name}` must have at least one column; got an empty mapping")
        names = [str(k) for k in x]
        cols = [as_float_array(v, f"{name}[{k!r}]") for k, v in x.items()]
        for k, c in zip(x, cols):
            if c.ndim != 1 or len(c) != len(cols[0]):
                raise ValueError(f"`{name}` must map names to 1-D signals of one length; "
                                 f"`{name}[{k!r}]` has shape {c.shape}")
        x = np.column_stack(cols)
    cols = getattr(x, "columns", None)
    if cols is not None:  # pandas DataFrame
        names = [str(c) for c in cols]
    elif getattr(x, "name", None) is not None and hasattr(x, "index"):  # pandas Series
        names = [str(x.name)]
    if hasattr(x, "to_numpy"):
        # (pandas' to_numpy(dtype=float) reads dates as nanoseconds since 1970)
        check_not_dates(x.dtypes if cols is not None else [getattr(x, "dtype", None)], name)
        if np.iscomplexobj(x.to_numpy()):
            raise TypeError(f"`{name}` must be real; got complex values")
        try:
            x = x.to_numpy(dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"`{name}` must be numeric; got {exc}") from None
    arr = as_float_array(x, name)
    if arr.ndim == 1:
        was_1d = True
        arr = arr.reshape(-1, 1)
    elif arr.ndim == 2:
        was_1d = False
    else:
        raise ValueError(f"`{name}` must have shape (N,) or (N, n_signals); got {arr.shape}")
    if arr.shape[1] == 0:
        raise ValueError(f"`{name}` must have at least one column; got shape {arr.shape}")
    check_finite(arr if not was_1d else arr[:, 0], name)
    return (arr.copy() if copy else arr), was_1d, names


def as_io_data(u, y, names=("u", "y"), copy=True):
    """Validate an input/output record: ``U (N, nu)``, ``Y (N, ny)`` and metadata.

    Returns ``(U, Y, info)`` with ``info`` a dict holding ``u_1d``, ``y_1d``,
    ``u_names`` and ``y_names`` (from pandas, or None). `names` are the
    argument names used in error messages. ``copy=False``: ``U`` and ``Y`` may
    be views of the caller's arrays, for a caller that only reads them.
    """
    uname, yname = names
    U, u_1d, u_names = _as_signal(u, uname, copy)
    Y, y_1d, y_names = _as_signal(y, yname, copy)
    if len(U) != len(Y):
        raise ValueError(f"`{uname}` and `{yname}` must have the same length; got {len(U)} "
                         f"input samples and {len(Y)} output samples")
    return U, Y, {"u_1d": u_1d, "y_1d": y_1d, "u_names": u_names, "y_names": y_names}


def is_listed(x):
    """True for a list or tuple of signals (arrays or pandas objects): one per experiment."""
    return isinstance(x, (list, tuple)) and bool(x) and any(
        isinstance(v, np.ndarray) or hasattr(v, "to_numpy") for v in x)


def as_records(u, y=None, names=("u", "y"), copy=True):
    """Validate one or several experiments: ``([(U, Y), ...], info)``.

    `u` may be an :class:`~rlsfilt.data.IOData` (then `y` is omitted), lists
    of arrays (one per experiment, as `IOData` takes them), or one record as
    :func:`as_io_data` takes it. ``U`` is ``(N_i, nu)`` and ``Y`` is
    ``(N_i, ny)`` per experiment; ``info`` is the dict of :func:`as_io_data`
    (for an `IOData`: its signal names and units, one signal counting as
    1-D) with ``"n_experiments"`` added. ``copy=False``: one record's ``U``
    and ``Y`` may be views of the caller's arrays (for a caller that only
    reads them).
    """
    from ..data.iodata import IOData, as_iodata

    listed = is_listed(u) or is_listed(y)
    if isinstance(u, IOData) or listed:
        data = as_iodata(u, y, u_name=names[0], y_name=names[1])
        info = {"u_1d": data.n_inputs == 1, "y_1d": data.n_outputs == 1,
                "u_names": list(data.input_names), "y_names": list(data.output_names),
                "u_units": list(data.input_units), "y_units": list(data.output_units),
                "n_experiments": data.n_experiments}
        return data.arrays(), info
    if y is None:
        raise TypeError(f"`{names[1]}` is required unless `{names[0]}` is an IOData")
    U, Y, info = as_io_data(u, y, names=names, copy=copy)
    info["n_experiments"] = 1
    return [(U, Y)], info


def _build(U, Y, s, start):
    """Regressor matrix for rows ``t = start .. N-1`` with zero past before t = 0.

    Each column is a shifted slice of the record written in place: no padded
    copies, no index arrays, so the memory is the matrix itself.
    """
    N = len(U)
    rows = max(N - start, 0)
    Phi = np.empty((rows, s.n_params))
    if rows == 0:
        return Phi

    def shifted(col, x, k, negate=False):
        # Phi[r, col] = x(start + r - k), zero where start + r - k < 0
        first = min(max(k - start, 0), rows)
        Phi[:first, col] = 0.0
        seg = x[start + first - k:N - k] if first < rows else x[:0]
        if negate:
            np.negative(seg, out=Phi[first:, col])
        else:
            Phi[first:, col] = seg

    col = 0
    for i in range(s.n_outputs):
        for k in range(1, s.na + 1):
            shifted(col, Y[:, i], k, negate=True)
            col += 1
    for j in range(s.n_inputs):
        for k in range(s.nk[j], s.nk[j] + s.nb[j]):
            shifted(col, U[:, j], k)
            col += 1
    return Phi


def arx_regressors(u, y=None, na=None, nb=None, nk=1, *, start=None):
    r"""Regressor matrix and target of an ARX model.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu), or IOData
        Input record (time on axis 0); pandas objects work too. Or an
        `IOData` (or lists of arrays, one per experiment) holding inputs
        and outputs: then `y` is omitted (pass the orders by keyword) and
        the rows of every experiment come one after the other, none
        straddling two experiments.
    y : array_like, shape (N,) or (N, ny)
        Output record.
    na, nb, nk
        Orders as in :func:`arx_structure` (`na` and `nb` are required).
    start : int, optional
        First row (of each experiment). Defaults to ``max_lag``, the first
        sample whose regressor is complete; a smaller ``start`` (``0`` gives
        one row per sample) takes inputs and outputs before ``t = 0`` as zero.

    Returns
    -------
    Phi : ndarray, shape (N - start, n_params)
        Rows :math:`\varphi(t)`, blocks ``-y_1, ..., -y_ny, u_1, ..., u_nu``,
        each by increasing lag: ``[-y(t-1) ... -y(t-na), u(t-nk) ...
        u(t-nk-nb+1)]``.
    target : ndarray, shape (N - start,) or (N - start, ny)
        ``y(t)`` for the same rows (1-D when `y` is 1-D).

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.models import arx_regressors
    >>> u = np.arange(5.0)
    >>> y = 10 * np.arange(5.0)
    >>> Phi, target = arx_regressors(u, y, na=1, nb=2, nk=1)
    >>> Phi            # rows t = 2, 3, 4: [-y(t-1), u(t-1), u(t-2)]
    array([[-10.,   1.,   0.],
           [-20.,   2.,   1.],
           [-30.,   3.,   2.]])
    >>> target
    array([20., 30., 40.])

    Two experiments: no row mixes the end of one with the start of the other.

    >>> from rlsfilt import IOData
    >>> Phi, target = arx_regressors(IOData([u, u], [y, y]), na=1, nb=2)
    >>> Phi.shape, target
    ((6, 3), array([20., 30., 40., 20., 30., 40.]))
    """
    for value, name in ((na, "na"), (nb, "nb")):
        if value is None:
            raise TypeError(f"`{name}` is required (the orders of the model)")
    records, info = as_records(u, y)
    s = arx_structure(na, nb, nk, records[0][0].shape[1], records[0][1].shape[1])
    start = s.max_lag if start is None else check_int(start, "start", minimum=0)
    shortest = min(len(U) for U, _ in records)
    if start > shortest:
        raise ValueError(f"`start` must be <= N = {shortest}; got {start}")
    Phi = np.vstack([_build(U, Y, s, start) for U, Y in records])
    target = np.vstack([Y[start:] for _, Y in records])
    return Phi, (target[:, 0] if info["y_1d"] else target).copy()


def _full_rank_rows(Phi):
    """Fewest leading rows of `Phi` (at least its column count) with full column rank.

    This is where an exact least-squares start can be made (the lecture notes'
    batch start of recursive least squares, and the start of the recursive
    residuals of Brown, Durbin & Evans). The rank of a prefix grows with its
    length, so the search doubles from ``n`` rows until full rank, then
    bisects: ``O(log k0)`` rank computations on prefixes of at most ``2 k0``
    rows (the columns of each prefix scaled to unit norm), so a long record
    costs no more than its first full-rank block; only a record that is
    rank-deficient throughout is scanned to its end.

    Returns
    -------
    int or None
        The number of rows, or None when even all rows are rank-deficient.
    """
    rows, n = Phi.shape
    if n == 0:
        return 0

    def full(k):
        return np.linalg.matrix_rank(unit_columns(Phi[:k])) == n

    if rows < n:
        return None
    if full(n):
        return n
    lo, hi = n, min(2 * n, rows)  # full(lo) is False
    while not full(hi):
        if hi == rows:
            return None
        lo, hi = hi, min(2 * hi, rows)
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if full(mid):
            hi = mid
        else:
            lo = mid
    return hi


def check_input_rank(records, nb, nk, start):
    """Refuse inputs whose lagged values (the ``B`` regressors) are linearly dependent.

    The rows ``t >= start`` of every experiment, columns ``u_j(t - k)`` for
    ``k = nk_j .. nk_j + nb_j - 1``, must have full column rank (decided by
    `_column_rank`): otherwise the input is not persistently exciting of
    order ``nb``, or two inputs are collinear (one a multiple, or a delayed
    copy, of another) and what each input contributes cannot be told apart.
    ARX (through its least squares) and ARMAX (through the gradient of its
    predictor) refuse such records; OE and BJ, whose inputs each have their
    own ``F``, have a gradient of full rank at most starts and need this check.
    """
    keep = [j for j, n_j in enumerate(nb) if n_j > 0]      # an input with nb = 0 is unused
    if not keep:                                         # (or a time series: no input)
        return
    s = arx_structure(0, [nb[j] for j in keep], [nk[j] for j in keep], len(keep), 1)
    n = s.n_params
    Phi = np.vstack([_build(U[:, keep], Y[:, None], s, start) for U, Y in records
                     if len(Y) > start])
    rank = _column_rank(Phi) if np.isfinite(Phi).all() else 0
    if rank < n:
        what = (", or two of its inputs are collinear (one a multiple or a delayed copy of "
                "another: what each contributes cannot be told apart)" if len(nb) > 1 else "")
        raise ValueError(f"`u` is not persistently exciting for these orders{what}: its lagged "
                         f"values (the regressors of B) have rank {rank} < sum(nb) = {n}; use a "
                         "richer input, fewer inputs or lower orders")


def _column_rank(Phi):
    """Numerical rank of `Phi` after scaling its columns to unit norm.

    The rank decision then does not depend on the units of the signals: a
    regressor in nanoamperes beside one in megapascals is not mistaken for a
    zero column (Householder QR, which solves the problem, is itself
    insensitive to column scaling; Golub & Van Loan 2013, sec. 5.3.7), nor
    whether the entries are around 1e-160 or 1e160 (`rlsfilt._scale`).
    """
    return int(np.linalg.matrix_rank(unit_columns(Phi))) if Phi.shape[1] else 0
