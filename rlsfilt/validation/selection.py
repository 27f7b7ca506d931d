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

import numpy as np

from .._resources import check_memory
from .._scale import pow2_scale, safe_norm
from .._serialize import jsonable
from .._validation import check_dt, check_int
from ..exceptions import ExactFitError, InsufficientDataError
from ..models.regressors import _build, arx_structure, as_io_data
from ..plotting import _axes
from .criteria import _criteria

__all__ = ["OrderSelection", "select_order"]

# largest number of floating-point operations select_order agrees to spend on its
# candidates (a few minutes on one core); a realistic grid (na, nb, nk up to 10 with
# one input: 1210 candidates) needs about 1e7
_MAX_WORK = 1e11
_CRITERIA = ("aic", "aicc", "bic", "naic", "fpe", "mdl", "loss")
_FIELDS = [("na", int), ("nb", int), ("nk", int), ("n_params", int), ("loss", float),
           ("val_loss", float), ("aic", float), ("aicc", float), ("bic", float),
           ("naic", float), ("fpe", float), ("mdl", float)]


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
        rows, NaN without validation data) and ``aic``, ``aicc``, ``bic``,
        ``naic``, ``fpe``, ``mdl`` (computed from ``val_loss`` when
        validation data were given, else from ``loss``).
    values : ndarray
        The criterion column of `table` (``val_loss`` for ``"loss"``);
        smaller is better.
    n_rows : int
        Number of aligned estimation rows (the same for every candidate).
    n_val_rows : int or None
        Number of aligned validation rows.
    thetas : list of ndarray
        The least-squares parameters of each candidate (in ARX regressor
        order ``[a1..a_na, b1..b_nb]``, on the aligned rows).
    """

    def __init__(self, table, criterion, values, thetas, n_rows, n_val_rows, data, dt,
                 rank_key=None):
        self.table = table
        self.criterion = criterion
        self.values = np.asarray(values, dtype=float)
        # the order of `values` (a monotone transform of them that stays finite for
        # records in any units, see select_order)
        self._rank_key = self.values if rank_key is None else np.asarray(rank_key, float)
        i = int(np.nanargmin(self._rank_key))
        self.best = (int(table["na"][i]), int(table["nb"][i]), int(table["nk"][i]))
        self.best_index = i
        self.thetas = thetas
        self.n_rows = n_rows
        self.n_val_rows = n_val_rows
        self._data = data
        self._dt = dt

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
        u, y = self._data
        return ARX(na, nb, nk, dt=self._dt).fit(u, y)

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
        order = np.argsort(self._rank_key, kind="stable")[:top]
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
        ax = _axes(ax)
        d = self.table["n_params"]
        v = self.values
        ax.plot(d, v, "o", color="C0", alpha=0.4, ms=4, label="candidates")
        sizes = np.unique(d)
        best_per = [np.nanmin(v[d == s]) for s in sizes]
        ax.plot(sizes, best_per, "-", color="C0", lw=1, label="best of each size")
        i = self.best_index
        ax.plot(d[i], v[i], "*", color="C3", ms=14,
                label=f"selected (na, nb, nk) = {self.best}")
        ax.set_xlabel("number of parameters $d$")
        ax.set_ylabel(self.criterion.upper() if self.criterion != "loss" else "loss $V$")
        ax.set_title("ARX order selection")
        ax.legend(loc="best")
        return ax


def select_order(u, y, na=range(1, 6), nb=range(1, 6), nk=range(1, 4), criterion="bic",
                 validation=None, *, dt=True):
    r"""Choose ARX orders ``(na, nb, nk)`` by an information criterion.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu)
        Estimation input. With several inputs every candidate uses the same
        ``nb`` and ``nk`` for all of them.
    y : array_like, shape (N,)
        Estimation output (one output).
    na, nb, nk : int or iterable of int
        Candidate orders; every combination is tried (``na >= 0``,
        ``nb >= 1``, ``nk >= 0``).
    criterion : {"bic", "aic", "aicc", "naic", "fpe", "mdl", "loss"}, default "bic"
        What to minimize (see :func:`criteria_from_loss`); ``"loss"`` is the
        plain mean squared residual, sensible only with `validation`.
    validation : tuple (u_val, y_val), optional
        Validation record. The candidates are then still estimated on
        ``(u, y)`` but scored on the loss of their one-step predictions on
        the validation record (MATLAB's ``arxstruc(ze, zv, NN)``; the
        criteria penalize that loss as ``selstruc`` does).
    dt : True or float, default True
        Sampling period given to :meth:`OrderSelection.best_model`.

    Returns
    -------
    OrderSelection
        ``.best``, ``.table`` of every candidate, ``.plot()``,
        ``.best_model()``.

    Raises
    ------
    InsufficientDataError
        When the largest orders leave no more aligned rows than regressors
        (checked first, so ``na=10**9`` fails at once).
    ValueError
        When the grid would need more than about 1e11 floating-point
        operations (minutes of computation): narrow it or search it in parts.
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
    """
    if criterion not in _CRITERIA:
        raise ValueError(f"`criterion` must be one of {', '.join(_CRITERIA)}; got {criterion!r}")
    check_dt(dt)  # here, not later in best_model()
    na_list = _order_list(na, "na", 0)
    nb_list = _order_list(nb, "nb", 1)
    nk_list = _order_list(nk, "nk", 0)
    U, Y, info = _io(u, y, "u", "y")
    # the lists are sorted (ranges ascending): first and last are the extremes
    kmin = nk_list[0]
    kmax = nk_list[-1] + nb_list[-1] - 1
    na_max = na_list[-1]
    t_max = max(na_max, kmax)
    nu = U.shape[1]
    n_lags = kmax - kmin + 1
    n_cols = na_max + nu * n_lags

    # limits first, before anything of the size of the orders is allocated
    rows = len(Y) - t_max
    if rows <= n_cols:
        raise InsufficientDataError(
            f"`y` is too short for these orders: {len(Y)} samples leave {max(rows, 0)} aligned "
            f"rows for up to {n_cols} regressors (largest na = {na_max}, nb = {nb_list[-1]}, "
            f"nk = {nk_list[-1]}); use more data or smaller orders")
    n_cand = len(na_list) * len(nb_list) * len(nk_list)
    # each candidate is a least-squares problem with n_cols + 1 rows and up to
    # na + nu nb columns: refuse a grid that would take hours rather than run it
    work = n_cand * (n_cols + 1) * (na_max + nu * nb_list[-1]) ** 2
    if work > _MAX_WORK:
        raise ValueError(
            f"`na`, `nb`, `nk` span {n_cand} candidate structures with up to "
            f"{na_max + nu * nb_list[-1]} parameters: about {work:.1e} floating-point "
            f"operations, more than select_order's limit of {_MAX_WORK:.0e} (minutes of "
            "computation); narrow the grid or search it in parts")
    # the regressor matrix, its scaled copy and the QR work array; per candidate a table
    # row, its parameters and their array
    check_memory(8 * 3 * rows * (n_cols + 1) + n_cand * (200 + 8 * (na_max + nu * nb_list[-1])),
                 f"select_order with {n_cand} candidates (`na`, `nb`, `nk`) and up to {n_cols} "
                 f"regressors on {len(Y)} samples")

    Psi, target = _full_regressor(U, Y, na_max, kmin, kmax, t_max)
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
        try:
            u_val, y_val = validation
        except (TypeError, ValueError):
            raise TypeError("`validation` must be a pair (u_val, y_val); got "
                            f"{type(validation).__name__}") from None
        Uv, Yv, _ = _io(u_val, y_val, "validation[0]", "validation[1]")
        if Uv.shape[1] != nu:
            raise ValueError(f"`validation` input must have {nu} column(s) like `u`; got "
                             f"{Uv.shape[1]}")
        Psi_v, target_v = _full_regressor(Uv, Yv, na_max, kmin, kmax, t_max)
        if len(target_v) == 0:
            raise InsufficientDataError(f"`validation` record is too short: {len(Yv)} samples "
                                        f"for a largest lag of {t_max}")
    elif criterion == "loss":
        raise ValueError("`criterion`='loss' needs `validation` data (on the estimation data "
                         "the largest model always has the smallest loss)")

    cands = list(itertools.product(na_list, nb_list, nk_list))
    table = np.zeros(len(cands), dtype=_FIELDS)
    thetas = []
    loss_s = np.empty(len(cands))        # the losses in units of ty^2
    for i, (a, b, k) in enumerate(cands):
        S = list(range(a)) + [na_max + j * n_lags + (k - kmin) + m
                              for j in range(nu) for m in range(b)]
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
        thetas.append(theta)

    use_val = validation is not None
    N = len(target_v) if use_val else rows
    if np.any(loss_s <= 1e-24 * float(np.mean((target / ty) ** 2))):
        raise ExactFitError("a candidate fits the data exactly (zero loss); information criteria "
                         "are undefined for noise-free data")
    V = table["val_loss"] if use_val else table["loss"]
    log_V = np.log(loss_s) + 2.0 * np.log(ty)
    crit = _criteria(V, N, table["n_params"], log_loss=log_V)
    for name in ("aic", "aicc", "bic", "naic", "fpe", "mdl"):
        table[name] = crit[name]
    values = table["val_loss"] if criterion == "loss" else table[criterion]
    # the ranking uses logarithms where a criterion is proportional to V, so that it
    # does not depend on the units even where V itself is out of range
    d = table["n_params"].astype(float)
    with np.errstate(divide="ignore", invalid="ignore"):
        rank_key = {"loss": log_V,
                    "fpe": np.where(N - d > 0, log_V + np.log((1 + d / N) / (1 - d / N)), np.inf),
                    "mdl": log_V + np.log1p(d * np.log(N) / N)}.get(criterion, values)
    # best_model() refits on the record as given: a 1-D input stays one signal `u`, and
    # pandas names are kept, so its summary names the signals as a direct ARX fit does
    data = (_as_given(U, info["u_1d"], info["u_names"]), _as_given(Y[:, 0], True, info["y_names"]))
    return OrderSelection(table, criterion, values, thetas, rows, N if use_val else None,
                          data, dt, rank_key=rank_key)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _order_list(value, name, minimum):
    """Sorted distinct orders: a list, or an ascending ``range`` (never materialized here,
    so that ``range(10**12)`` is refused by the limits, not by a frozen loop)."""
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


def _io(u, y, uname, yname):
    U, Y, info = as_io_data(u, y, names=(uname, yname))
    if Y.shape[1] != 1:
        raise ValueError(f"`{yname}` must have shape (N,) (one output); got {Y.shape}")
    return U, Y, info


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
