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

from .._display import Summary, ranking_html
from .._resources import check_memory
from .._scale import pow2_scale, safe_norm
from .._serialize import jsonable
from .._validation import check_dt, check_int
from ..exceptions import ExactFitError, InsufficientDataError, OrderSelectionWarning
from ..models._offset import record_means
from ..models.regressors import _build, arx_structure, as_records
from ..plotting import plot_order_selection
from .criteria import _criteria

__all__ = ["OrderSelection", "select_order"]

# largest number of floating-point operations select_order agrees to spend on its
# candidates (a few minutes on one core); a realistic grid (na, nb, nk up to 10 with
# one input: 1210 candidates) needs about 1e7
_MAX_WORK = 1e11
# the delays select_order tries per input around delayest's estimate when `nk` is not given
_SEED_HALF_WIDTH = 1
_CRITERIA = ("aic", "aicc", "bic", "naic", "fpe", "mdl", "loss")
_FIELDS = [("na", int), ("nb", int), ("nk", int), ("n_params", int), ("loss", float),
           ("val_loss", float), ("aic", float), ("aicc", float), ("bic", float),
           ("naic", float), ("fpe", float), ("mdl", float), ("max_pole", float),
           ("stable", bool)]


class OrderSelection:
    """Result of :func:`select_order`.

    Attributes
    ----------
    best : tuple
        ``(na, nb, nk)`` minimizing the criterion; with per-input ranges
        (see :func:`select_order`) ``nb`` and ``nk`` are tuples, one entry
        per input: ``(na, (nb_1, nb_2), (nk_1, nk_2))``.
    nk_ranges : list of list of int or None
        The delays tried per input when the search was per input, else None.
    seeded_by_delayest : tuple of int or None
        The per-input delays :func:`~rlsfilt.delayest` estimated when they
        seeded the `nk` ranges (several inputs and `nk` not given), else None.
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
                 offset=False, rank_key=None):
        self.table = table
        self.criterion = criterion
        self.values = np.asarray(values, dtype=float)
        # the order of `values` (a monotone transform of them that stays finite for
        # records in any units, see select_order)
        self._rank_key = self.values if rank_key is None else np.asarray(rank_key, float)
        i = int(np.nanargmin(self._rank_key))
        self.best = (int(table["na"][i]), _orders(table["nb"][i]), _orders(table["nk"][i]))
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

    def _repr_html_(self):
        return self._html()

    def _html(self, top=10):
        t = self.table
        labels = [f"na={t['na'][i]} nb={_text(_orders(t['nb'][i]))} nk={_text(_orders(t['nk'][i]))}"
                  for i in range(len(t))]
        columns = [("n_params", t["n_params"]), ("loss", t["loss"])]
        if not np.all(np.isnan(t["val_loss"])):
            columns.append(("val_loss", t["val_loss"]))
        if self.criterion != "loss":
            columns.append((self.criterion, self.values))
        columns.append(("stable", t["stable"]))
        return ranking_html(type(self).__name__, self.criterion, labels, columns,
                            self._rank_key, top=top)

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
        nb, nk = (list(v) if isinstance(v, tuple) else v for v in (nb, nk))
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
                         "candidates": [{k: _plain(row[k]) for k in names}
                                        for row in self.table]})

    def to_dataframe(self):
        """The table as a ``pandas.DataFrame`` (pandas must be installed)."""
        import pandas as pd

        return pd.DataFrame({name: [_plain(v) for v in self.table[name]]
                             if self.table[name].ndim > 1 else self.table[name]
                             for name in self.table.dtype.names})

    def summary(self, top=10):
        """Table of the `top` candidates, best first.

        Parameters
        ----------
        top : int, default 10
            Number of candidates listed.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table).
        """
        top = check_int(top, "top", minimum=1)
        order = np.argsort(self._rank_key, kind="stable")[:top]
        val = not np.all(np.isnan(self.table["val_loss"]))
        w = 3 if self.table["nb"].ndim == 1 else 4 * self.table["nb"].shape[1] + 1
        head = f"{'na':>3} {'nb':>{w}} {'nk':>{w}} {'d':>3} {'loss':>11}"
        head += f" {'val_loss':>11}" if val else ""
        extra = self.criterion != "loss"
        head += f" {self.criterion:>12}" if extra else ""
        lines = [f"Order selection by {self.criterion} ({len(self.table)} candidates, "
                 f"{self.n_rows} aligned rows)", head]
        for i in order:
            r = self.table[i]
            nb, nk = (_text(_orders(r[k])) for k in ("nb", "nk"))
            line = f"{r['na']:>3} {nb:>{w}} {nk:>{w}} {r['n_params']:>3} {r['loss']:>11.5g}"
            line += f" {r['val_loss']:>11.5g}" if val else ""
            line += f" {self.values[i]:>12.6g}" if extra else ""
            line += "  unstable" if not r["stable"] else ""
            line += "  <- best" if i == self.best_index else ""
            lines.append(line)
        return Summary("\n".join(lines), self._html(top))

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


class _Default:
    """A default order range, told apart from the same range given explicitly."""

    def __init__(self, values):
        self.values = values

    def __repr__(self):
        return repr(self.values)


_NA, _NB, _NK = _Default(range(1, 6)), _Default(range(1, 6)), _Default(range(1, 4))


def select_order(u, y=None, na=_NA, nb=_NB, nk=_NK, criterion="bic", validation=None, *, dt=True,
                 offset=False, stable_only=False, model=None, nc=None, nd=None, nf=None,
                 fit_options=None):
    r"""Choose model orders by an information criterion: ARX ``(na, nb, nk)`` or any family.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu), or IOData
        Estimation input, or an `IOData` holding inputs and outputs (then
        `y` is omitted and the other arguments are given by keyword); with
        several experiments no regressor row straddles two of them. With
        several inputs `nb` and `nk` may be given per input (below).
    y : array_like, shape (N,)
        Estimation output (one output).
    na, nb : int or iterable of int
        Candidate orders; every combination is tried (``na >= 0``,
        ``nb >= 1``). With several inputs `nb` may be given per input: a
        sequence of ranges, one per input (``nb=[range(1, 4), range(1,
        3)]``), or a dict from input name or index to a range; every
        combination of the inputs' orders is then tried.
    nk : int or iterable of int, default range(1, 4)
        Candidate delays, independent of the orders (``nk >= 0``): a dead
        time of 16 samples needs ``nk=range(14, 19)``, not larger orders
        (:func:`~rlsfilt.delayest` estimates it first). Per input as `nb`
        (``nk={"heater": range(0, 3), "fan": range(15, 22)}``). With
        several inputs and `nk` not given, each input's delays are
        ``d - 1 .. d + 1`` around the delay ``d`` that
        :func:`~rlsfilt.delayest` estimates for it
        (``result.seeded_by_delayest``); with one input ``range(1, 4)``.
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
        its simulation diverges). ARX only.
    model : model class, default ARX
        The structure searched. ``ARX`` (the default) is searched by least
        squares as described below. Any other
        :class:`~rlsfilt.models.IdentifiedModel` class (``ARMAX``, ``OE``,
        ``BJ``, ``ARMA``, ``AR``) is searched by :func:`select_structure`:
        every candidate fitted by prediction error and ranked by the same
        criteria of its one-step prediction errors. Its orders are the
        keywords its constructor takes (``ARMAX``: `na`, `nb`, `nc`, `nk`;
        ``OE``: `nb`, `nf`, `nk`; ``BJ``: `nb`, `nc`, `nd`, `nf`, `nk`); an
        order it does not take is refused. For these classes an order not
        given tries 1 and 2 (`nk`: 1, 2, 3), and for a time-series class
        (``ARMA``, ``AR``) `u` is None.
    nc, nd, nf : int or iterable of int, optional
        Candidate orders of ``C``, ``D`` and ``F`` for the classes that have
        them (not ARX).
    fit_options : dict, optional
        Passed to every candidate's ``fit`` for the classes other than ARX
        (for example ``{"method": "rpem"}``).

    Returns
    -------
    OrderSelection or StructureSelection
        For ARX an `OrderSelection`: ``.best`` (a tuple ``(na, nb, nk)``),
        ``.table`` of every candidate, ``.plot()``, ``.best_model()``,
        ``.summary()``, ``.to_dataframe()``. For another class the
        :class:`StructureSelection` of :func:`select_structure` on the same
        grid: ``.best`` (a dict of orders), ``.candidates``,
        ``.best_model`` (the fitted model itself, an attribute),
        ``.summary()``, ``.to_dataframe()``.

    Warns
    -----
    OrderSelectionWarning
        When the best candidate lies at the upper edge of a range of
        several values (or at its lower edge, for a range starting above
        1): the message names the bound to widen.

    Raises
    ------
    InsufficientDataError
        When the largest orders leave no more aligned rows than regressors
        (checked first, so ``na=10**9`` fails at once).
    ValueError
        Bad orders or criterion, noise-free data (a zero loss), no stable
        candidate with `stable_only`, or a grid that would need more than
        about 1e11 floating-point operations (minutes of computation):
        narrow it or search it in parts.
    MemoryError
        When the regressor matrix and the table would need more memory than
        the process can get (checked before they are built).

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

    The same entry point searches ARMAX orders on data with coloured
    (moving-average) noise:

    >>> from rlsfilt import ARMAX
    >>> y = (lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u)
    ...      + lfilter([1, -1.0, 0.2], [1, -1.5, 0.7], e))
    >>> select_order(u, y, model=ARMAX, na=[1, 2, 3], nb=[2], nc=[1, 2, 3], nk=[1]).best
    {'na': 2, 'nb': 2, 'nc': 2, 'nk': 1}
    """
    if criterion not in _CRITERIA:
        raise ValueError(f"`criterion` must be one of {', '.join(_CRITERIA)}; got {criterion!r}")
    check_dt(dt)  # here, not later in best_model()
    orders = {"na": na, "nb": nb, "nk": nk, "nc": nc, "nd": nd, "nf": nf}
    if model is not None:
        from ..models import ARX

        if not isinstance(model, type):
            raise TypeError(f"`model` must be a model class such as ARMAX (not an instance); "
                            f"got {type(model).__name__}")
        if model is not ARX:
            return _select_family(model, u, y, orders, criterion, validation, dt, offset,
                                  stable_only, fit_options)
    for name in ("nc", "nd", "nf"):
        if orders[name] is not None:
            raise ValueError(f"`{name}` is not an order of ARX (its orders: na, nb, nk); pass "
                             f"`model=` a class with that polynomial (ARMAX, OE, BJ)")
    if fit_options is not None:
        raise ValueError("`fit_options` applies to the classes fitted by prediction error, "
                         "not to ARX (searched by least squares); remove it")
    from ..models._offset import offset_mode

    mode = offset_mode(offset)
    records, info = _records(u, y, "u", "y")
    nu = records[0][0].shape[1]
    names = info["u_names"] or [f"u{j + 1}" for j in range(nu)]
    nb_per, nk_per, seeded = _input_ranges(nb, nk, nu, names, u, y)
    na = na.values if isinstance(na, _Default) else na
    na_list = _order_list(na, "na", 0)
    per_input = nb_per is not None
    if not per_input:
        nb = nb.values if isinstance(nb, _Default) else nb
        nk = nk.values if isinstance(nk, _Default) else nk
        nb_per = [_order_list(nb, "nb", 1)] * nu
        nk_per = [_order_list(nk, "nk", 0)] * nu
    # the lists are sorted (ranges ascending): first and last are the extremes; per input
    # the columns u_j(t - kmin_j) .. u_j(t - kmax_j)
    kmins = [nk_per[j][0] for j in range(nu)]
    kmaxs = [nk_per[j][-1] + nb_per[j][-1] - 1 for j in range(nu)]
    n_lags = [kmaxs[j] - kmins[j] + 1 for j in range(nu)]
    na_max = na_list[-1]
    t_max = max([na_max] + kmaxs)
    n_cols = na_max + sum(n_lags) + (mode == "intercept")
    starts = np.cumsum([na_max] + n_lags)[:-1]

    # limits first, before anything of the size of the orders is allocated
    n = sum(len(U) for U, _ in records)
    rows = sum(max(len(U) - t_max, 0) for U, _ in records)
    if rows <= n_cols:
        raise InsufficientDataError(
            f"`y` is too short for these orders: {n} samples leave {rows} aligned rows "
            f"for up to {n_cols} regressors (largest `na` = {na_max}, `nb` = "
            f"{_largest(nb_per, per_input)}, `nk` = {_largest(nk_per, per_input)}); use more "
            "data or smaller orders")
    if per_input:
        n_cand = len(na_list) * int(np.prod([len(nb_per[j]) * len(nk_per[j])
                                             for j in range(nu)]))
    else:
        n_cand = len(na_list) * len(nb_per[0]) * len(nk_per[0])
    n_par = na_max + sum(nb_per[j][-1] for j in range(nu)) + (mode == "intercept")
    # each candidate is a least-squares problem with n_cols + 1 rows and up to n_par
    # columns: refuse a grid that would take hours rather than run it
    work = n_cand * (n_cols + 1) * n_par ** 2
    if work > _MAX_WORK:
        raise ValueError(
            f"`na`, `nb`, `nk` span {n_cand} candidate structures with up to {n_par} "
            f"parameters: about {work:.1e} floating-point operations, more than "
            f"select_order's limit of {_MAX_WORK:.0e} (minutes of computation); narrow the "
            "grid or search it in parts")
    # the regressor matrix, its scaled copy and the QR work array; per candidate a table
    # row, its parameters and their array
    check_memory(8 * 3 * rows * (n_cols + 1) + n_cand * (200 + 8 * n_par),
                 f"select_order with {n_cand} candidates (`na`, `nb`, `nk`) and up to {n_cols} "
                 f"regressors on {n} samples")
    op = _means(records) if mode == "mean" else None

    Psi, target = _stacked_regressor(records, na_max, kmins, kmaxs, t_max, op, mode)
    # unit columns: the least-squares cut-off of rank-deficient candidates and the
    # conditioning no longer depend on the signals' units (losses are unchanged); the
    # target divided by a power of two near its largest entry (exact), so that losses are
    # computed as ty^2 * loss_s without squaring a number around 1e160 or 1e-160
    scale = safe_norm(Psi, axis=0)
    scale = np.where(scale > 0, scale, 1.0)
    ty = pow2_scale(target)
    R = np.linalg.qr(np.column_stack([Psi / scale, target / ty]), mode="r")
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
        Psi_v, target_v = _stacked_regressor(val_records, na_max, kmins, kmaxs, t_max, op,
                                             mode)
        if len(target_v) == 0:
            raise InsufficientDataError(
                f"`validation` record is too short: {sum(len(U) for U, _ in val_records)} "
                f"samples for a largest lag of {t_max}")
    elif criterion == "loss":
        raise ValueError("`criterion`='loss' needs `validation` data (on the estimation data "
                         "the largest model always has the smallest loss)")

    if per_input:   # (na, (nb_1, .., nb_nu), (nk_1, .., nk_nu)), inputs varying independently
        pairs = list(itertools.product(*[itertools.product(nb_per[j], nk_per[j])
                                         for j in range(nu)]))
        cands = [(a, tuple(p[0] for p in pair), tuple(p[1] for p in pair))
                 for a in na_list for pair in pairs]
    else:
        cands = list(itertools.product(na_list, nb_per[0], nk_per[0]))
    table = np.zeros(len(cands), dtype=_fields(nu if per_input else None))
    thetas = []
    loss_s = np.empty(len(cands))        # the losses in units of ty^2
    const = [n_cols - 1] if mode == "intercept" else []
    for i, (a, b, k) in enumerate(cands):
        bs, ks = (b, k) if per_input else ((b,) * nu, (k,) * nu)
        S = list(range(a)) + [int(starts[j]) + (ks[j] - kmins[j]) + m
                              for j in range(nu) for m in range(bs[j])] + const
        M = R[:, S]
        theta = np.linalg.lstsq(M, r_y, rcond=None)[0] if S else np.zeros(0)
        res = r_y - M @ theta
        theta = theta * (ty / scale[S])
        table[i]["na"], table[i]["nb"], table[i]["nk"] = a, b, k
        table[i]["n_params"] = len(S)
        if validation is not None:
            ev = (target_v - Psi_v[:, S] @ theta) / ty
            loss_s[i] = float(ev @ ev) / len(ev)
        else:
            loss_s[i] = float(res @ res) / rows
        with np.errstate(over="ignore", under="ignore"):
            table[i]["loss"] = float(res @ res) / rows * ty * ty
            table[i]["val_loss"] = loss_s[i] * ty * ty if validation is not None else np.nan
        poles = np.roots(np.concatenate([[1.0], theta[:a]])) if a else np.zeros(0)
        table[i]["max_pole"] = float(np.max(np.abs(poles))) if a else 0.0
        table[i]["stable"] = table[i]["max_pole"] < 1.0
        thetas.append(theta)

    use_val = validation is not None
    N = len(target_v) if use_val else rows
    if np.any(loss_s <= 1e-24 * float(np.mean((target / ty) ** 2))):
        raise ExactFitError("a candidate fits the data exactly (zero loss); information "
                            "criteria are undefined for noise-free data")
    V = table["val_loss"] if use_val else table["loss"]
    log_V = np.log(loss_s) + 2.0 * np.log(ty)
    crit = _criteria(V, N, table["n_params"], log_loss=log_V)
    for name in ("aic", "aicc", "bic", "naic", "fpe", "mdl"):
        table[name] = crit[name]
    values = np.array(table["val_loss"] if criterion == "loss" else table[criterion], float)
    # the ranking uses logarithms where a criterion is proportional to V, so that it
    # does not depend on the units even where V itself is out of range
    d = table["n_params"].astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rank_key = {"loss": log_V,
                    "fpe": np.where(N - d > 0, log_V + np.log((1 + d / N) / (1 - d / N)), np.inf),
                    "mdl": log_V + np.log1p(d * np.log(N) / N)}.get(criterion, values.copy())
    if stable_only:
        if not table["stable"].any():
            raise ValueError(f"`stable_only`: none of the {len(cands)} candidates is stable "
                             f"(smallest largest-pole magnitude {table['max_pole'].min():.4g});"
                             " check the data (operating point, delay) or widen the orders")
        values[~table["stable"]] = np.inf
        rank_key[~table["stable"]] = np.inf
    # best_model() refits on the record as given: a 1-D input stays one signal `u`, and
    # pandas names are kept, so its summary names the signals as a direct ARX fit does
    data = _given(u, y, records, info)
    result = OrderSelection(table, criterion, values, thetas, rows, N if use_val else None,
                            data, dt, offset, rank_key=rank_key)
    result.nk_ranges = [nk_per[j] for j in range(nu)] if per_input else None
    result.seeded_by_delayest = seeded
    if per_input:
        ranges = {"na": na_list}
        best = [result.best[0]]
        for name, lists, at in (("nb", nb_per, 1), ("nk", nk_per, 2)):
            for j in range(nu):
                ranges[_input_key(name, j, names, nu)] = lists[j]
                best.append(result.best[at][j])
        _warn_edges(tuple(best), ranges)
    else:
        _warn_edges(result.best, {"na": na_list, "nb": nb_per[0], "nk": nk_per[0]})
    return result


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
_FAMILY_ORDERS = ("na", "nb", "nc", "nd", "nf", "nk")


def _select_family(model, u, y, orders, criterion, validation, dt, offset, stable_only,
                   fit_options):
    """select_order for a class other than ARX: its orders as a grid for select_structure."""
    import inspect

    from .structure import select_structure

    name = model.__name__
    params = [p for p in inspect.signature(model.__init__).parameters
              if p in _FAMILY_ORDERS]
    if not params:
        raise TypeError(f"`model` must be a model class with orders such as ARMAX; got "
                        f"{name}, whose constructor takes none of {', '.join(_FAMILY_ORDERS)}")
    for key, value in orders.items():
        if key not in params and value is not None and not isinstance(value, _Default):
            raise ValueError(f"`{key}` is not an order of {name} (its orders: "
                             f"{', '.join(params)})")
    if offset is not False:
        raise ValueError(f"`offset` applies to ARX only; got offset={offset!r} with {name}: "
                         "remove the operating point from the record first (IOData.detrend)")
    if stable_only:
        raise ValueError(f"`stable_only` applies to ARX only; with {name}, inspect "
                         "`.models` (each has `is_stable`)")
    if fit_options is not None and not isinstance(fit_options, dict):
        raise TypeError(f"`fit_options` must be a dict; got {type(fit_options).__name__}")
    if getattr(model, "_TIME_SERIES", False) and u is not None:
        raise ValueError(f"`u` must be None for the time-series class {name} (the record is "
                         f"`y`); got {type(u).__name__}")
    nu, names = 0, []
    if not getattr(model, "_TIME_SERIES", False):
        records, info = _records(u, y, "u", "y")
        nu = records[0][0].shape[1]
        names = info["u_names"] or [f"u{j + 1}" for j in range(nu)]
    grid, ranges, seeded = {}, {}, None
    for key in params:
        value = orders[key]
        per = _per_input_lists(value, key, nu, names, 1 if key == "nb" else 0) \
            if key in ("nb", "nf", "nk") and nu else None
        if per is None and key == "nk" and nu > 1 and isinstance(value, (_Default,
                                                                         type(None))):
            per, seeded = _seed_delays(u, y, nu)
        if per is not None:     # one tuple of per-input orders per candidate
            grid[key] = list(itertools.product(*per))
            for j in range(nu):
                ranges[(key, j)] = (_input_key(key, j, names, nu), per[j])
            continue
        if value is None or isinstance(value, _Default):
            value = range(1, 4) if key == "nk" else range(1, 3)
        grid[key] = _order_list(value, key, 1 if key == "nb" else 0)
        ranges[(key, None)] = (key, grid[key])
    result = select_structure(model, u, y, grid, criterion=criterion, validation=validation,
                              dt=dt, **(fit_options or {}))
    result.seeded_by_delayest = seeded
    best = tuple(result.best[k] if j is None else result.best[k][j] for k, j in ranges)
    _warn_edges(best, dict(ranges.values()), stacklevel=4)
    return result


def _order_list(value, name, minimum):
    """Sorted distinct orders: a list, or an ascending ``range`` (never materialized here,
    so that ``range(10**12)`` is refused by the limits, not by a frozen loop)."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if isinstance(value, numbers.Integral) and not isinstance(value, bool):
        return [check_int(value, name, minimum=minimum)]
    if isinstance(value, range):
        if not value:
            raise ValueError(f"`{name}` must hold at least one order; got an empty range")
        if value.step < 0:
            value = value[::-1]
        check_int(value[0], name, minimum=minimum)
        return value
    if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
        raise TypeError(f"`{name}` must be an integer or an iterable of integers; got "
                        f"{type(value).__name__}")
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
    # (the means ARX(offset="mean").fit removes, to the bit)
    U = np.vstack([U for U, _ in records])
    Y = np.vstack([Y for _, Y in records])
    return record_means(U), record_means(Y)


def _stacked_regressor(records, na_max, kmins, kmaxs, t_max, op, mode):
    """`_full_regressor` of every experiment, one after the other (+ ones for an intercept)."""
    Psis, targets = [], []
    for U, Y in records:
        if op is not None:
            U, Y = U - op[0], Y - op[1]
        Psi, target = _full_regressor(U, Y, na_max, kmins, kmaxs, t_max)
        if mode == "intercept":
            Psi = np.column_stack([Psi, np.ones(len(target))])
        Psis.append(Psi)
        targets.append(target)
    return np.vstack(Psis), np.concatenate(targets)


def _warn_edges(best, ranges, stacklevel=3):
    """Warn (once) when the best structure sits at edges of ranges that could be widened."""
    edges = []
    for (name, values), value in zip(ranges.items(), best):
        if len(values) < 2:
            continue
        lo, hi = values[0], values[-1]      # sorted lists, ascending ranges
        span = f"({lo}..{hi})"
        if value == hi:
            edges.append(f"the upper edge of the `{name}` range {span}: widen `{name}` upwards")
        elif value == lo and lo > 1:
            edges.append(f"the lower edge of the `{name}` range {span}: widen `{name}` "
                         "downwards")
    if edges:
        text = "; and at ".join(edges)
        names = ", ".join(ranges)
        warnings.warn(f"the best structure ({names}) = {best} is at {text} (the best may "
                      "lie outside the grid)", OrderSelectionWarning,
                      stacklevel=stacklevel)


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


def _full_regressor(U, Y, na_max, kmins, kmaxs, t_max):
    """The regressors of ``ARX(na_max, kmax - kmin + 1, kmin)`` (per input), rows
    t_max..N-1: columns ``-y(t-1..na_max)`` then per input ``u_j(t-kmin_j..kmax_j)``, every
    candidate a column subset."""
    s = arx_structure(na_max, [b - a + 1 for a, b in zip(kmins, kmaxs)], list(kmins),
                      U.shape[1], 1)
    return _build(U, Y, s, t_max), Y[t_max:, 0]


def _fields(nu):
    """The table's dtype: ``nb`` and ``nk`` one per input when searched per input."""
    if nu is None:
        return _FIELDS
    return [(name, kind, (nu,)) if name in ("nb", "nk") else (name, kind)
            for name, kind in _FIELDS]


def _orders(value):
    """An int, or a tuple of ints for per-input orders."""
    value = np.asarray(value)
    return int(value) if value.ndim == 0 else tuple(int(v) for v in value)


def _plain(value):
    value = np.asarray(value)
    return value.item() if value.ndim == 0 else [v.item() for v in value]


def _text(order):
    return str(order) if isinstance(order, int) else ",".join(map(str, order))


def _largest(lists, per_input):
    return [lst[-1] for lst in lists] if per_input else lists[0][-1]


def _input_key(name, j, names, nu):
    """``nk[u2]``: the per-input range's name in messages."""
    return f"{name}[{names[j]}]" if nu > 1 else name


def _is_order_range(v):
    return isinstance(v, (range, list, tuple, np.ndarray)) and not (
        isinstance(v, np.ndarray) and v.ndim == 0)


def _per_input_lists(value, name, nu, names, minimum):
    """Per-input order lists when `value` is per input (a dict, or a sequence of ranges),
    else None."""
    if isinstance(value, _Default) or value is None:
        return None
    if isinstance(value, dict):
        lists = [None] * nu
        for key, v in value.items():
            if isinstance(key, str) and key in names:
                j = list(names).index(key)
            elif isinstance(key, numbers.Integral) and not isinstance(key, bool) \
                    and 0 <= key < nu:
                j = int(key)
            else:
                raise ValueError(f"`{name}` keys must be input indices 0..{nu - 1} or input "
                                 f"names {list(names)}; got {key!r}")
            lists[j] = _order_list(v, f"{name}[{key}]", minimum)
        missing = [names[j] for j in range(nu) if lists[j] is None]
        if missing:
            raise ValueError(f"`{name}` must give every input a range; missing "
                             f"{', '.join(map(repr, missing))}")
        return lists
    if isinstance(value, (list, tuple)) and value and all(_is_order_range(v) for v in value):
        if len(value) != nu:
            raise ValueError(f"`{name}` must hold one range per input ({nu}); got "
                             f"{len(value)}")
        return [_order_list(v, f"{name}[{j}]", minimum) for j, v in enumerate(value)]
    return None


def _input_ranges(nb, nk, nu, names, u, y):
    """Per-input ``(nb lists, nk lists, seeded)``, or ``(None, None, None)`` when every
    input shares one ``nb`` and one ``nk`` range.

    Per input when `nb` or `nk` is given per input, or when several inputs have no `nk`:
    then each input's delays are a window around its delay estimated by
    :func:`delayest` (``seeded`` is that estimate)."""
    nb_per = _per_input_lists(nb, "nb", nu, names, 1)
    nk_per = _per_input_lists(nk, "nk", nu, names, 0)
    seeded = None
    if nk_per is None and isinstance(nk, _Default) and nu > 1:
        nk_per, seeded = _seed_delays(u, y, nu)
    if nb_per is None and nk_per is None:
        return None, None, None
    if nb_per is None:
        nb_per = [_order_list(nb.values if isinstance(nb, _Default) else nb, "nb", 1)] * nu
    if nk_per is None:
        nk_per = [_order_list(nk.values if isinstance(nk, _Default) else nk, "nk", 0)] * nu
    return nb_per, nk_per, seeded


def _seed_delays(u, y, nu):
    """Per input the delays ``d_j - 1 .. d_j + 1`` (never below 0) around the estimate
    ``d_j`` of :func:`delayest` (its defaults: ARX(2, 2) test models, delays 0..20)."""
    from .delay import delayest

    with warnings.catch_warnings():   # an edge here shows as select_order's own edge warning
        warnings.simplefilter("ignore", OrderSelectionWarning)
        d = delayest(u, y)
    d = (d,) if nu == 1 else tuple(d)
    return [range(max(k - _SEED_HALF_WIDTH, 0), k + _SEED_HALF_WIDTH + 1) for k in d], d

