r"""Structure selection for any model class: fit a grid of orders, rank by a criterion.

:func:`select_order` searches ARX orders by least squares on nested regressors;
model classes whose fits are not linear regressions (ARMAX, OE, BJ, ARMA)
need every candidate fitted by prediction error. :func:`select_structure`
does that for any :class:`~rlsfilt.models.IdentifiedModel` class and ranks
the candidates by the information criteria of their one-step prediction
errors (:func:`information_criteria`, MATLAB's ``aic``/``fpe`` definitions),
or by the loss on validation data.
"""

import itertools
import math

import numpy as np

from .._display import Summary, ranking_html
from .._progress import LazyProgress
from .._serialize import jsonable
from .._validation import check_int
from ._model import one_step_records
from .criteria import _criteria, information_criteria

__all__ = ["StructureSelection", "select_structure"]

_CRITERIA = ("aic", "aicc", "bic", "naic", "fpe", "mdl", "loss")


class StructureSelection:
    """Result of :func:`select_structure`.

    Attributes
    ----------
    candidates : list of dict
        One per structure tried, in the order tried: the orders, ``n_params``,
        ``loss`` (mean squared one-step prediction error on the estimation
        data; for several outputs the determinant of its covariance, as
        :func:`information_criteria`), ``val_loss`` (the same on the
        validation data, NaN without), the
        criteria ``aic`` .. ``mdl`` and ``error`` (the message when the fit
        was refused, else None).
    criterion : str
    values : ndarray
        The criterion of each candidate (NaN when its fit was refused).
    best : dict
        The orders of the best candidate.
    best_model : IdentifiedModel
        The best candidate, fitted on the estimation data.
    models : list
        Every fitted candidate (None where the fit was refused).
    """

    def __init__(self, candidates, criterion, values, models):
        self.candidates = candidates
        self.criterion = criterion
        self.values = np.asarray(values, dtype=float)
        if np.all(np.isnan(self.values)):
            errors = "; ".join(sorted({c["error"] for c in candidates if c["error"]}))
            raise ValueError(f"no candidate structure could be fitted: {errors}")
        i = int(np.nanargmin(self.values))
        self.best_index = i
        self.models = models
        self.best_model = models[i]
        self.best = {k: v for k, v in candidates[i]["orders"].items()}

    def __repr__(self):
        return (f"<StructureSelection: best {type(self.best_model).__name__} {self.best} by "
                f"{self.criterion} among {len(self.candidates)} candidates>")

    def _repr_html_(self):
        return self._html()

    def _html(self, top=10):
        c = self.candidates
        labels = [", ".join(f"{k}={v}" for k, v in ci["orders"].items()) for ci in c]
        columns = [("n_params", [ci.get("n_params") for ci in c]),
                   ("loss", [ci.get("loss") for ci in c]),
                   (self.criterion, self.values)]
        return ranking_html(f"{type(self).__name__} of {type(self.best_model).__name__}",
                            self.criterion, labels, columns, self.values,
                            errors=[ci.get("error") for ci in c], top=top)

    def summary(self, top=10):
        """Table of the `top` candidates, best first.

        Parameters
        ----------
        top : int, default 10

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table).
        """
        top = check_int(top, "top", minimum=1)
        order = np.argsort(np.where(np.isnan(self.values), np.inf, self.values),
                           kind="stable")[:top]
        name = type(self.best_model).__name__
        lines = [f"Structure selection of {name} by {self.criterion} "
                 f"({len(self.candidates)} candidates)"]
        for i in order:
            c = self.candidates[i]
            orders = ", ".join(f"{k}={v}" for k, v in c["orders"].items())
            if c["error"]:
                lines.append(f"  {orders:<40} refused: {c['error']}")
                continue
            mark = "  <- best" if i == self.best_index else ""
            lines.append(f"  {orders:<40} d={c['n_params']:<3} loss={c['loss']:<11.5g} "
                         f"{self.criterion}={self.values[i]:.6g}{mark}")
        return Summary("\n".join(lines), self._html(top))

    def to_dict(self):
        """The selection as a JSON-ready dict (non-finite numbers as None)."""
        return jsonable({"model": type(self.best_model).__name__, "best": self.best,
                         "criterion": self.criterion, "candidates": self.candidates})

    def to_dataframe(self):
        """The candidates as a ``pandas.DataFrame`` (one column per order and number)."""
        import pandas as pd

        rows = [{**c["orders"], **{k: v for k, v in c.items() if k != "orders"}}
                for c in self.candidates]
        return pd.DataFrame(rows)


#: The most candidates `select_structure` fits unless told otherwise (`max_candidates`):
#: each is a prediction-error fit (an iterative search), so 10^4 of them already take
#: minutes to hours; a larger grid is refused before anything is fitted
MAX_CANDIDATES = 10_000


def _grid(grid, max_candidates):
    """The candidates of `grid` as a list of dicts, counted before any is built: more than
    `max_candidates` is a ValueError saying how many and how to narrow the grid."""
    if isinstance(grid, dict):
        if not grid:
            raise ValueError("`grid` must name at least one order; got an empty dict")
        names = list(grid)
        values = []
        for name in names:
            v = grid[name]
            if not hasattr(v, "__iter__") or isinstance(v, (str, bytes)):
                v = [v]
            elif not hasattr(v, "__len__"):     # a generator: at most what could be fitted
                v = list(itertools.islice(v, max_candidates + 1))
            if not len(v):
                raise ValueError(f"`grid['{name}']` must hold at least one value; got none")
            values.append(v)
        n = math.prod(len(v) for v in values)
        if n > max_candidates:
            sizes = " x ".join(f"{len(v):,} {name}" for name, v in zip(names, values))
            _too_many(f"{n:,}", max_candidates, f" ({sizes} values)")
        return [dict(zip(names, combo)) for combo in itertools.product(*map(list, values))]
    if hasattr(grid, "__len__") and len(grid) > max_candidates:
        _too_many(f"{len(grid):,}", max_candidates)
    combos = [dict(c) for c in itertools.islice(grid, max_candidates + 1)]
    if len(combos) > max_candidates:
        _too_many(f"more than {max_candidates:,}", max_candidates)
    if not combos:
        raise ValueError("`grid` must hold at least one structure; got none")
    return combos


def _estimation(u, y, grid, time_series):
    """``(u, y, grid)`` with an `IOData` `u` kept whole (``y`` None) and a grid given in the
    place of `y` moved to `grid`."""
    from ..data.iodata import IOData

    if isinstance(u, IOData):
        if time_series:
            raise TypeError("`u` must be None for a time-series class (the record is `y`); "
                            "got an IOData")
        if grid is None and y is not None and not _is_signal(y):
            y, grid = None, y       # select_structure(OE, data, {"nb": ...})
        if y is not None:
            raise TypeError(f"`y` must be omitted when `u` is an IOData (it holds the "
                            f"outputs); got {type(y).__name__}")
    elif y is None:
        raise TypeError("`y` is required unless `u` is an IOData")
    if grid is None:
        raise TypeError("`grid` is required: a dict from each order to its values, e.g. "
                        "{'nb': [1, 2], 'nf': [1, 2], 'nk': [1]}")
    return u, y, grid


def _is_signal(x):
    """A record (array, pandas object, list of arrays), not a grid (dict, list of dicts)."""
    if isinstance(x, dict):
        return False
    if isinstance(x, (list, tuple)) and x and all(isinstance(c, dict) for c in x):
        return False
    return True


def _validation_pair(validation):
    """``(u_v, y_v)`` of the validation argument: a pair, or an `IOData` as ``(data, None)``."""
    from ..data.iodata import IOData

    if validation is None:
        return None
    if isinstance(validation, IOData):
        return validation, None
    if not isinstance(validation, (tuple, list)) or len(validation) != 2:
        raise TypeError(f"`validation` must be a pair (u_v, y_v) or an IOData; got "
                        f"{type(validation).__name__}")
    return tuple(validation)


def _too_many(count, max_candidates, sizes=""):
    raise ValueError(f"`grid` gives {count} candidate structures{sizes}, each a "
                     f"prediction-error fit; `max_candidates` is {max_candidates:,}: narrow the "
                     "grid (fewer values per order, a coarse grid first and then a fine one "
                     "around its best, or select_order for ARX orders), or pass a larger "
                     "max_candidates to fit them all")


def select_structure(model_class, u, y=None, grid=None, *, criterion="bic", validation=None,
                     dt=True, max_candidates=MAX_CANDIDATES, progress="auto", **fit_options):
    r"""Fit every structure of a grid and rank them by a criterion of the prediction errors.

    Parameters
    ----------
    model_class : type
        An :class:`~rlsfilt.models.IdentifiedModel` class (`ARMAX`, `OE`,
        `BJ`, `ARMA`, `ARX`, ...).
    u : array_like, shape (N,) or (N, nu), IOData, or None
        Input record, or an `IOData` holding inputs and outputs (then `y`
        is omitted: ``select_structure(OE, data, grid=...)``, or the grid
        given third, ``select_structure(OE, data, {...})``); several
        experiments are fitted together, no prediction straddling two of
        them. None for a time-series class such as `ARMA`.
    y : array_like, shape (N,), optional
        Output record (omitted with an `IOData`).
    grid : dict or iterable of dict
        Orders to try: a dict from each constructor parameter to its values
        (every combination is tried; per-input orders of several inputs as
        tuples, ``{"nb": [(2, 1), (3, 1)]}``), or an explicit list of dicts.
    criterion : {"bic", "aic", "aicc", "naic", "fpe", "mdl", "loss"}, default "bic"
        Smaller is better. ``"loss"`` is the mean squared one-step prediction
        error on the validation data (or the estimation data without them).
    validation : tuple ``(u_v, y_v)`` or IOData, optional
        Fresh data: the criteria then penalize the validation loss (as
        MATLAB's ``selstruc`` on validation losses). An `IOData` of several
        experiments is scored over all of them (each predictor started
        afresh). For a time-series class, ``(None, y_v)``.
    dt : True or float, default True
        Sampling period of the candidates.
    max_candidates : int, default 10_000
        The most candidates fitted. The grid is counted before anything is
        fitted, and a larger one is a ``ValueError`` saying how many
        candidates it gives (each is an iterative prediction-error fit:
        10^4 of them take minutes to hours); pass a larger value to fit
        them all anyway.
    progress : {"auto", True, False}, default "auto"
        A tqdm progress bar over the candidates: ``"auto"`` shows one once
        the search has run a few seconds (if tqdm is installed), True at
        once, False never.
    **fit_options
        Passed to every ``fit`` (for example ``method="rpem"``).

    Returns
    -------
    StructureSelection

    Raises
    ------
    ValueError
        When the grid gives more than `max_candidates` structures (before
        any fit), or names an order with no values.

    Notes
    -----
    A candidate whose fit is refused (too few samples, an input that is not
    persistently exciting for its orders) is kept in the table with its
    error message and no criterion. With :math:`V` the mean squared one-step
    prediction error on the :math:`N` rows after the candidate's own
    ``max_lag`` and :math:`d` its number of parameters, the criteria are
    those of :func:`criteria_from_loss`.

    Examples
    --------
    Output-error data: among OE structures, BIC picks the true orders.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import OE
    >>> from rlsfilt.validation import select_structure
    >>> rng = np.random.default_rng(7)
    >>> u = rng.standard_normal(2000)
    >>> y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.3 * rng.standard_normal(2000)
    >>> sel = select_structure(OE, u, y, {"nb": [1, 2, 3], "nf": [1, 2, 3], "nk": [1]})
    >>> sel.best
    {'nb': 2, 'nf': 2, 'nk': 1}
    """
    if criterion not in _CRITERIA:
        raise ValueError(f"`criterion` must be one of {', '.join(map(repr, _CRITERIA))}; got "
                         f"{criterion!r}")
    if not isinstance(model_class, type):
        raise TypeError(f"`model_class` must be a model class such as ARMAX; got "
                        f"{type(model_class).__name__}")
    time_series = bool(getattr(model_class, "_TIME_SERIES", False))
    u, y, grid = _estimation(u, y, grid, time_series)
    validation = _validation_pair(validation)
    max_candidates = check_int(max_candidates, "max_candidates", minimum=1)
    combos = _grid(grid, max_candidates)
    bar = LazyProgress(len(combos), progress, desc=f"select_structure({model_class.__name__})")
    candidates, values, models = [], [], []
    for orders in combos:
        bar.tick()
        row = {"orders": dict(orders), "n_params": None, "loss": math.nan,
               "val_loss": math.nan, **{k: math.nan for k in _CRITERIA if k != "loss"},
               "error": None}
        try:
            model = model_class(**orders, dt=dt)
        except TypeError as exc:
            raise TypeError(f"`grid` names a parameter {model_class.__name__} does not take: "
                            f"{exc}") from None
        try:
            model = model.fit(y, **fit_options) if time_series else \
                model.fit(u, y, **fit_options)
        except ValueError as exc:
            row["error"] = str(exc).split(";")[0]
            candidates.append(row)
            values.append(math.nan)
            models.append(None)
            continue
        ic = information_criteria(model, u, y)
        row["n_params"] = ic.n_params
        row["loss"] = ic.loss
        if validation is not None:
            uv, yv = validation
            _, e, _ = one_step_records(model, uv, yv, "select_structure")
            # the loss of `information_criteria`: V = mean e^2, for several outputs the
            # determinant of the residual covariance (was the mean over all outputs' e^2)
            n_v, ny = e.shape
            V = float(np.mean(e ** 2)) if ny == 1 else float(np.linalg.det(e.T @ e / n_v))
            row["val_loss"] = V
            crit = _criteria(V, n_v, ic.n_params, ny)
            crit = {k: getattr(crit, k) for k in ("aic", "aicc", "bic", "naic", "fpe", "mdl")}
        else:
            crit = {k: getattr(ic, k) for k in ("aic", "aicc", "bic", "naic", "fpe", "mdl")}
        row.update(crit)
        candidates.append(row)
        models.append(model)
        if criterion == "loss":
            values.append(row["val_loss"] if validation is not None else row["loss"])
        else:
            values.append(row[criterion])
    bar.close()
    return StructureSelection(candidates, criterion, values, models)
