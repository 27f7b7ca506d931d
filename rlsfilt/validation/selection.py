r"""ARX order selection from one factorization (MATLAB's ``arxstruc`` + ``selstruc``).

Every candidate structure ``(na, nb, nk)`` uses a subset of the columns of
one regressor matrix built with the largest lags, so one QR factorization of
that matrix (with the output appended) serves all of them: with
:math:`[\Psi \; y] = Q R`, the residual norm of any column subset :math:`S`
is :math:`\min_b \lVert \Psi_S b - y \rVert = \min_b \lVert R_S b - r_y
\rVert`, a problem with as many rows as there are columns.
"""

import itertools
import numbers
import warnings

import numpy as np

from .._serialize import jsonable
from .._validation import check_dt, check_int
from ..exceptions import ExactFitError, InsufficientDataError, OrderSelectionWarning
from ..models.regressors import _build, arx_structure, as_records
from ..plotting import plot_order_selection
from .criteria import _criteria

__all__ = ["OrderSelection", "select_order"]

_CRITERIA = ("aic", "aicc", "bic", "naic", "fpe", "mdl", "loss")
_FIELDS = [("na", int), ("nb", int), ("nk", int), ("n_params", int), ("loss", float),
           ("val_loss", float), ("aic", float), ("aicc", float), ("bic", float),
           ("naic", float), ("fpe", float), ("mdl", float), ("max_pole", float),
           ("stable", bool)]


class OrderSelection:
    """Result of :func:`select_order`.

    Attributes
    ----------
    best : tuple of int
        ``(na, nb, nk)`` minimizing the criterion.
    criterion : str
        The criterion used.
    table : numpy structured array
        One row per candidate, in the order tried, with fields ``na``,
        ``nb``, ``nk``, ``n_params``, ``loss`` (mean squared one-step
        residual on the estimation rows), ``val_loss`` (on the validation
        rows, NaN without validation data), ``aic``, ``aicc``, ``bic``,
        ``naic``, ``fpe``, ``mdl`` (computed from ``val_loss`` when
        validation data were given, else from ``loss``), ``max_pole`` (the
        largest pole magnitude of the candidate's ``A``) and ``stable``.
    values : ndarray
        The criterion column of `table` (``val_loss`` for ``"loss"``);
        smaller is better (``inf`` for the unstable candidates with
        ``stable_only``).
    n_rows : int
        Number of aligned estimation rows (the same for every candidate).
    n_val_rows : int or None
        Number of aligned validation rows.
    thetas : list of ndarray
        The least-squares parameters of each candidate (in ARX regressor
        order ``[a1..a_na, b1..b_nb]``, on the aligned rows).
    """

    def __init__(self, table, criterion, values, thetas, n_rows, n_val_rows, data, dt,
                 offset=False):
        self.table = table
        self.criterion = criterion
        self.values = np.asarray(values, dtype=float)
        i = int(np.nanargmin(self.values))
        self.best = (int(table["na"][i]), int(table["nb"][i]), int(table["nk"][i]))
        self.best_index = i
        self.thetas = thetas
        self.n_rows = n_rows
        self.n_val_rows = n_val_rows
        self._data = data
        self._dt = dt
        self._offset = offset

    def __repr__(self):
        return (f"<OrderSelection: best (na, nb, nk) = {self.best} by {self.criterion} among "
                f"{len(self.table)} candidates>")

    def best_model(self):
        """An ``ARX`` of the best structure fitted on the whole estimation record.

        Returns
        -------
        ARX
            Fitted with ``method="ls"`` on all rows of the estimation data
            (the selection itself used the rows aligned to the largest lag).
        """
        from ..models import ARX

        na, nb, nk = self.best
        return ARX(na, nb, nk, dt=self._dt, offset=self._offset).fit(*self._data)

    def to_dict(self):
        """The selection as a JSON-ready dict.

        Returns
        -------
        dict
            ``best`` (``[na, nb, nk]``), ``criterion``, ``n_rows``,
            ``n_val_rows`` and ``candidates``: one dict per row of
            :attr:`table` (non-finite numbers as None, as in
            :meth:`ValidationReport.to_dict`).
        """
        names = self.table.dtype.names
        return jsonable({"best": self.best, "criterion": self.criterion, "n_rows": self.n_rows,
                         "n_val_rows": self.n_val_rows,
                         "candidates": [{k: row[k] for k in names} for row in self.table]})

    def to_dataframe(self):
        """The table as a ``pandas.DataFrame`` (pandas must be installed)."""
        import pandas as pd

        return pd.DataFrame({name: self.table[name] for name in self.table.dtype.names})

    def summary(self, top=10):
        """Text table of the `top` candidates, best first.

        Parameters
        ----------
        top : int, default 10
            Number of candidates listed.

        Returns
        -------
        str
        """
        top = check_int(top, "top", minimum=1)
        order = np.argsort(self.values, kind="stable")[:top]
        val = not np.all(np.isnan(self.table["val_loss"]))
        head = f"{'na':>3} {'nb':>3} {'nk':>3} {'d':>3} {'loss':>11}"
        head += f" {'val_loss':>11}" if val else ""
        extra = self.criterion != "loss"
        head += f" {self.criterion:>12}" if extra else ""
        lines = [f"Order selection by {self.criterion} ({len(self.table)} candidates, "
                 f"{self.n_rows} aligned rows)", head]
        for i in order:
            r = self.table[i]
            line = f"{r['na']:>3} {r['nb']:>3} {r['nk']:>3} {r['n_params']:>3} {r['loss']:>11.5g}"
            line += f" {r['val_loss']:>11.5g}" if val else ""
            line += f" {self.values[i]:>12.6g}" if extra else ""
            line += "  unstable" if not r["stable"] else ""
            line += "  <- best" if i == self.best_index else ""
            lines.append(line)
        return "\n".join(lines)

    def plot(self, ax=None):
        """Criterion against the number of parameters (as MATLAB's ``selstruc``).

        Every candidate is a dot; the line joins the best candidate of each
        size, and the selected structure is marked.

        Parameters
        ----------
        ax : matplotlib.axes.Axes, optional

        Returns
        -------
        matplotlib.axes.Axes
        """
        return plot_order_selection(self, ax)


def select_order(u, y=None, na=range(1, 6), nb=range(1, 6), nk=range(1, 4), criterion="bic",
                 validation=None, *, dt=True, offset=False, stable_only=False):
    r"""Choose ARX orders ``(na, nb, nk)`` by an information criterion.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu), or IOData
        Estimation input, or an `IOData` holding inputs and outputs (then
        `y` is omitted and the other arguments are given by keyword); with
        several experiments no regressor row straddles two of them. With
        several inputs every candidate uses the same ``nb`` and ``nk`` for
        all of them.
    y : array_like, shape (N,)
        Estimation output (one output).
    na, nb : int or iterable of int
        Candidate orders; every combination is tried (``na >= 0``,
        ``nb >= 1``).
    nk : int or iterable of int, default range(1, 4)
        Candidate delays, independent of the orders (``nk >= 0``): a dead
        time of 16 samples needs ``nk=range(14, 19)``, not larger orders
        (:func:`~rlsfilt.delayest` estimates it first).
    criterion : {"bic", "aic", "aicc", "naic", "fpe", "mdl", "loss"}, default "bic"
        What to minimize (see :func:`criteria_from_loss`); ``"loss"`` is the
        plain mean squared residual, sensible only with `validation`.
    validation : tuple (u_val, y_val) or IOData, optional
        Validation record. The candidates are then still estimated on
        ``(u, y)`` but scored (and picked) on the loss of their one-step
        predictions on the validation record (MATLAB's ``arxstruc(ze, zv,
        NN)``; the criteria penalize that loss as ``selstruc`` does).
    dt : True or float, default True
        Sampling period given to :meth:`OrderSelection.best_model`.
    offset : {False, True, "mean"}, default False
        Operating point handling of every candidate, as in
        :class:`~rlsfilt.ARX`: ``True`` adds an intercept column to all of
        them, ``"mean"`` removes the estimation record's means (from the
        validation record too).
    stable_only : bool, default False
        Only candidates whose ``A`` has every pole inside the unit circle
        can be picked (an unstable ARX model predicts one step ahead but
        its simulation diverges).

    Returns
    -------
    OrderSelection
        ``.best``, ``.table`` of every candidate, ``.plot()``,
        ``.best_model()``.

    Warns
    -----
    OrderSelectionWarning
        When the best candidate lies at the upper edge of a range of
        several values (or at its lower edge, for a range starting above
        1): the message names the bound to widen.

    Raises
    ------
    ValueError
        Bad orders or criterion, a record too short for the largest lags,
        noise-free data (a zero loss), or no stable candidate with
        `stable_only`.

    Notes
    -----
    As in MATLAB's ``arxstruc``, all candidates are fitted on the same rows
    :math:`t = t_{max} \dots N - 1` with :math:`t_{max} = \max(\max n_a,
    \max n_k + \max n_b - 1)`, so that their losses are comparable; the
    first rows that a small model could use are dropped for all of them.
    (A model fitted alone with :class:`~rlsfilt.ARX` uses its own first
    complete row, so its loss can differ slightly.)

    One regressor matrix :math:`\Psi` with columns
    :math:`-y(t-1) \dots -y(t-\max n_a)` and
    :math:`u(t - \min n_k) \dots u(t - \max n_k - \max n_b + 1)` holds every
    candidate's regressors as a column subset :math:`S`. One Householder QR
    factorization :math:`[\Psi\; y] = Q R` (never the normal equations) gives
    for each candidate the least-squares problem
    :math:`\min_b \lVert R_S b - r_y \rVert` with only
    :math:`\mathrm{cols}(\Psi) + 1` rows, whose residual norm equals that of
    the full problem because :math:`Q` preserves norms. Selection on 4000
    samples and 60 candidates takes a few milliseconds.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 16.4.
    .. [2] MATLAB System Identification Toolbox, ``arxstruc`` and
       ``selstruc``.

    Examples
    --------
    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.validation import select_order
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(2000)
    >>> e = 0.1 * rng.standard_normal(2000)
    >>> y = lfilter([0, 0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1], [1, -1.5, 0.7], e)
    >>> select_order(u, y, na=range(1, 5), nb=range(1, 5), nk=range(1, 4)).best
    (2, 2, 2)
    """
    if criterion not in _CRITERIA:
        raise ValueError(f"`criterion` must be one of {', '.join(_CRITERIA)}; got {criterion!r}")
    check_dt(dt)  # here, not later in best_model()
    from ..models.arx import _offset_mode

    mode = _offset_mode(offset)
    na_list = _order_list(na, "na", 0)
    nb_list = _order_list(nb, "nb", 1)
    nk_list = _order_list(nk, "nk", 0)
    records, info = _records(u, y, "u", "y")
    kmin = min(nk_list)
    kmax = max(nk_list) + max(nb_list) - 1
    na_max = max(na_list)
    t_max = max(na_max, kmax)
    nu = records[0][0].shape[1]
    n_lags = kmax - kmin + 1
    n_cols = na_max + nu * n_lags + (mode == "intercept")
    op = _means(records) if mode == "mean" else None

    Psi, target = _stacked_regressor(records, na_max, kmin, kmax, t_max, op, mode)
    rows = len(target)
    if rows <= n_cols:
        n = sum(len(U) for U, _ in records)
        raise InsufficientDataError(
            f"`y` is too short for these orders: {n} samples leave {rows} aligned rows "
            f"for up to {n_cols} regressors; use more data or smaller orders")
    # unit columns: the least-squares cut-off of rank-deficient candidates and the
    # conditioning no longer depend on the signals' units (losses are unchanged)
    scale = np.linalg.norm(Psi, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    R = np.linalg.qr(np.column_stack([Psi / scale, target]), mode="r")
    r_y = R[:, -1]

    if validation is not None:
        from ..data.iodata import IOData

        if isinstance(validation, IOData):
            val_records, _ = _records(validation, None, "validation", "validation")
        else:
            try:
                u_val, y_val = validation
            except (TypeError, ValueError):
                raise TypeError("`validation` must be a pair (u_val, y_val) or an IOData; got "
                                f"{type(validation).__name__}") from None
            val_records, _ = _records(u_val, y_val, "validation[0]", "validation[1]")
        if val_records[0][0].shape[1] != nu:
            raise ValueError(f"`validation` input must have {nu} column(s) like `u`; got "
                             f"{val_records[0][0].shape[1]}")
        Psi_v, target_v = _stacked_regressor(val_records, na_max, kmin, kmax, t_max, op, mode)
        if len(target_v) == 0:
            raise InsufficientDataError(
                f"`validation` record is too short: {sum(len(U) for U, _ in val_records)} "
                f"samples for a largest lag of {t_max}")
    elif criterion == "loss":
        raise ValueError("`criterion`='loss' needs `validation` data (on the estimation data "
                         "the largest model always has the smallest loss)")

    cands = list(itertools.product(na_list, nb_list, nk_list))
    table = np.zeros(len(cands), dtype=_FIELDS)
    thetas = []
    const = [n_cols - 1] if mode == "intercept" else []
    for i, (a, b, k) in enumerate(cands):
        S = list(range(a)) + [na_max + j * n_lags + (k - kmin) + m
                              for j in range(nu) for m in range(b)] + const
        M = R[:, S]
        theta = np.linalg.lstsq(M, r_y, rcond=None)[0] if S else np.zeros(0)
        res = r_y - M @ theta
        theta = theta / scale[S]
        table[i]["na"], table[i]["nb"], table[i]["nk"] = a, b, k
        table[i]["n_params"] = len(S)
        table[i]["loss"] = float(res @ res) / rows
        if validation is not None:
            ev = target_v - Psi_v[:, S] @ theta
            table[i]["val_loss"] = float(ev @ ev) / len(ev)
        else:
            table[i]["val_loss"] = np.nan
        poles = np.roots(np.concatenate([[1.0], theta[:a]])) if a else np.zeros(0)
        table[i]["max_pole"] = float(np.max(np.abs(poles))) if a else 0.0
        table[i]["stable"] = table[i]["max_pole"] < 1.0
        thetas.append(theta)

    use_val = validation is not None
    V = table["val_loss"] if use_val else table["loss"]
    N = len(target_v) if use_val else rows
    if np.any(V <= 1e-24 * float(np.mean(target ** 2))):
        raise ExactFitError("a candidate fits the data exactly (zero loss); information "
                            "criteria are undefined for noise-free data")
    crit = _criteria(V, N, table["n_params"])
    for name in ("aic", "aicc", "bic", "naic", "fpe", "mdl"):
        table[name] = crit[name]
    values = np.array(table["val_loss"] if criterion == "loss" else table[criterion], float)
    if stable_only:
        if not table["stable"].any():
            raise ValueError(f"`stable_only`: none of the {len(cands)} candidates is stable "
                             f"(smallest largest-pole magnitude {table['max_pole'].min():.4g});"
                             " check the data (operating point, delay) or widen the orders")
        values[~table["stable"]] = np.inf
    # best_model() refits on the record as given: a 1-D input stays one signal `u`, and
    # pandas names are kept, so its summary names the signals as a direct ARX fit does
    data = _given(u, y, records, info)
    result = OrderSelection(table, criterion, values, thetas, rows, N if use_val else None,
                            data, dt, offset)
    _warn_edges(result.best, {"na": na_list, "nb": nb_list, "nk": nk_list})
    return result


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _order_list(value, name, minimum):
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        values = [value]
    elif isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise TypeError(f"`{name}` must be an integer or an iterable of integers; got "
                        f"{type(value).__name__}")
    else:
        values = list(value)
    if not values:
        raise ValueError(f"`{name}` must hold at least one order; got an empty range")
    return sorted({check_int(v, name, minimum=minimum) for v in values})


def _records(u, y, uname, yname):
    """Experiments ``[(U, Y), ...]`` of a one-output record (IOData, lists or arrays)."""
    records, info = as_records(u, y, names=(uname, yname))
    if records[0][1].shape[1] != 1:
        raise ValueError(f"`{yname}` must have shape (N,) (one output); got "
                         f"{records[0][1].shape[1]} outputs")
    return records, info


def _given(u, y, records, info):
    """``(u, y)`` for best_model(): the IOData itself, or the arrays in the form given."""
    from ..data.iodata import IOData

    if isinstance(u, IOData):
        return (u,)
    if len(records) > 1:
        return ([U for U, _ in records], [Y[:, 0] for _, Y in records])
    U, Y = records[0]
    return (_as_given(U, info["u_1d"], info["u_names"]), _as_given(Y[:, 0], True,
                                                                   info["y_names"]))


def _means(records):
    U = np.vstack([U for U, _ in records])
    Y = np.vstack([Y for _, Y in records])
    return U.mean(axis=0), Y.mean(axis=0)


def _stacked_regressor(records, na_max, kmin, kmax, t_max, op, mode):
    """`_full_regressor` of every experiment, one after the other (+ ones for an intercept)."""
    Psis, targets = [], []
    for U, Y in records:
        if op is not None:
            U, Y = U - op[0], Y - op[1]
        Psi, target = _full_regressor(U, Y, na_max, kmin, kmax, t_max)
        if mode == "intercept":
            Psi = np.column_stack([Psi, np.ones(len(target))])
        Psis.append(Psi)
        targets.append(target)
    return np.vstack(Psis), np.concatenate(targets)


def _warn_edges(best, ranges):
    """Warn (once) when the best structure sits at edges of ranges that could be widened."""
    edges = []
    for (name, values), value in zip(ranges.items(), best):
        if len(values) < 2:
            continue
        span = f"({min(values)}..{max(values)})"
        if value == max(values):
            edges.append(f"the upper edge of the `{name}` range {span}: widen `{name}` upwards")
        elif value == min(values) and min(values) > 1:
            edges.append(f"the lower edge of the `{name}` range {span}: widen `{name}` "
                         "downwards")
    if edges:
        text = "; and at ".join(edges)
        warnings.warn(f"the best structure (na, nb, nk) = {best} is at {text} (the best may "
                      "lie outside the grid)", OrderSelectionWarning, stacklevel=3)


def _as_given(X, was_1d, names):
    """The validated copy `X` in the form the caller gave: 1-D, or pandas with its names."""
    if was_1d and X.ndim == 2:
        X = X[:, 0]
    if names is None:
        return X
    import pandas as pd  # names only come from pandas objects

    if X.ndim == 1:
        return pd.Series(X, name=names[0])
    return pd.DataFrame(X, columns=names)


def _full_regressor(U, Y, na_max, kmin, kmax, t_max):
    """The regressors of ``ARX(na_max, kmax - kmin + 1, kmin)``, rows t_max..N-1: columns
    ``-y(t-1..na_max)`` then per input ``u(t-kmin..kmax)``, every candidate a column subset."""
    s = arx_structure(na_max, kmax - kmin + 1, kmin, U.shape[1], 1)
    return _build(U, Y, s, t_max), Y[t_max:, 0]
