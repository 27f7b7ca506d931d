r"""Fleets of channels: one ARX model per channel, fitted together.

`fit_many` fits the same ARX structure to every channel of a fleet (every
loop of a plant, every sensor of an array, every cell of a battery pack)
and returns an `ARXBank`: the parameters, standard errors, fit percentages
and residual-test p-values of every channel as arrays with a leading
channel axis, a ``summary()`` with one row per channel (``to_dataframe()``
for all of them in pandas), and
``model(i)``, an ordinary fitted `ARX` of channel ``i``.

The numbers are those of ``ARX(...).fit(u[:, i], y[:, i])`` and
:func:`rlsfilt.validation.validate` for each channel (the tests hold them
equal); what changes is the cost. Batch least squares runs NumPy's stacked
QR over the channels, recursive least squares runs one `RLSBank` (one
compiled call for all channels), and the statistics are vectorized over
channels. The channels are processed in chunks that fit in cache; a
channel's numbers do not depend on which other channels share its chunk,
so :mod:`rlsfilt.dask` can split a fleet over machines and get the same
numbers.
"""

import contextlib
import html
import inspect
import math
import numbers
import warnings

import numpy as np

from .._display import Summary, edge_indices, frame_html, table_html, table_text
from .._lazy import lazy_module
from .._scale import pow2_exponent, times_pow2, unit_columns
from .._validation import (
    COVARIANCE_MAX,
    as_float_array,
    check_dt,
    check_int,
    check_not_dates,
    check_probability,
)
from ..exceptions import NumericalWarning, OperatingPointWarning
from ..filters._health import warn_at_caller as _warn_at_caller
from ..filters.bank import RLSBank, full_rank, subset
from ..filters.gradient_bank import GradientBank
from ._offset import far_from_zero, operating_point_remedy, record_means
from ._offset import offset_mode as _offset_mode
from ._tuning_option import tuning_param
from ._units import equivariant_forgetting, estimate_in_units, tune_start, tuned_random_walk
from .regressors import _full_rank_rows, arx_structure

__all__ = ["ARXBank", "fit_many"]

#: The compiled statistics of a fleet, imported on first use.
_fleet_kernels = lazy_module("rlsfilt.models._kernels_fleet")

_RLS_OPTIONS = ("k0", "lam", "P0", "R", "Q", "x0")
#: The gradient methods (MATLAB's 'NormalizedGradient', 'Gradient'): a `GradientBank`.
_GRADIENT = ("nlms", "lms")
# bytes of regressors per chunk of channels (about a second-level cache or two)
_CHUNK_BYTES = 16 * 2 ** 20
# bytes of the lagged-input matrices per batch of the independence test
_TEST_BYTES = 16 * 2 ** 20


class ARXBank:
    r"""Fitted ARX models of many channels: what :func:`fit_many` returns.

    Every fitted quantity has the channel as its leading axis (``C``
    channels, ``n_params`` parameters per channel); `summary` shows them
    one row per channel (`to_dataframe`: all of them in a pandas
    DataFrame), and `model` returns
    channel ``i`` as an ordinary fitted `ARX`.

    Attributes
    ----------
    template : ARX
        The (unfitted) model every channel is fitted as (orders and offset).
    intercept_ : ndarray, shape (C,)
        ``offset=True`` only: the intercept ``c`` of each channel (also the
        last column of ``theta_``).
    input_offset_, output_offset_ : ndarray, shapes (C, n_inputs) and (C,)
        ``offset="mean"`` only: the means removed from each channel.
    channels_ : list
        Channel labels (the columns of a pandas `y`, the `channels` given to
        :func:`fit_many`, or ``0 .. C-1``).
    theta_ : ndarray, shape (C, n_params)
        Parameters of each channel in regressor order (``param_names_``).
    tune_ : BankTuneResult
        ``lam="tune"`` or ``Q="tune"`` only: each channel's maximum-likelihood
        estimate (`rlsfilt.filters.tuning.BankTuneResult`; NaN for channels
        not fitted).
    theta_cov_ : ndarray, shape (C, n_params, n_params)
        Parameter covariances, as ``ARX.theta_cov_``.
    std_errors_ : ndarray, shape (C, n_params)
        Standard errors (square roots of the diagonals of ``theta_cov_``).
    noise_variance_ : ndarray, shape (C,)
        Unbiased residual variances.
    residuals_ : ndarray, shape ``(n_samples_, C)``
        ``target - Phi @ theta`` on the fitted rows, one column per channel.
    simulation_fit_, prediction_fit_ : ndarray, shape (C,)
        :func:`~rlsfilt.validation.fit_percent` of the free-run simulation
        (started from the measured outputs of the first ``max_lag`` samples)
        and of the one-step prediction, on the estimation data: the numbers
        of :func:`~rlsfilt.validation.validate`.
    q_statistic_, pvalue_white_ : ndarray, shape (C,)
        Ljung-Box whiteness test of the residuals
        (:func:`~rlsfilt.validation.residual_analysis`), ``df_white_``
        degrees of freedom.
    f_statistic_, pvalue_independent_ : ndarray, shape (C,)
        F test that lagged inputs do not explain the residuals;
        ``df_independent_`` (C,) numerator degrees of freedom.
    is_white_, is_independent_ : ndarray of bool, shape (C,)
        ``pvalue > alpha``.
    k0_ : ndarray of int, shape (C,)
        ``method="rls"``: rows of each channel's batch start (0 for the
        gradient methods; None for ``"ls"``).
    recursive_residuals_ : ndarray, shape ``(n_samples_, C)``
        ``method="rls"``, ``"nlms"``, ``"lms"``: the a-priori residuals of
        the filter (NaN on the rows of the batch start), as
        ``ARX.recursive_residuals_``.
    healthy_ : ndarray of bool, shape (C,)
        ``method="rls"``: the channel's covariance passed every health
        check (always True for ``"ls"``), with the threshold ``ARX.fit`` sets
        from the channel's regressors (``cond_max = max(1e12, 1e4 cond^2)``)
        unless ``cond_max`` is given: the verdict of ``ARX.fit`` on the channel.
    errors_ : list of (str or None)
        With ``on_error="nan"``: why a channel could not be fitted (its
        numbers are NaN), or None.
    n_samples_, n_params_ : int
        Rows of the regression and parameters per channel.
    param_names_ : list of str
        ``a1 .. a_na, b1 .. b_nb`` (``b1[u2]`` with several inputs).
    method_ : str
        ``"ls"``, ``"rls"``, ``"nlms"`` or ``"lms"``.
    max_lag, alpha : int, float
        Settings of the residual tests.
    """

    def __init__(self, **fields):
        for key, value in fields.items():
            setattr(self, key, value)

    def __len__(self):
        return len(self.channels_)

    @property
    def a_(self):
        """``[a1 .. a_na]`` of each channel, shape (C, na)."""
        return self.theta_[:, :self.structure_.na].copy()

    @property
    def b_(self):
        """``[b1 .. b_nb]`` of each channel, shape (C, nb); a list of such
        arrays, one per input, with several inputs."""
        _, b_sls = self.structure_.param_slices()
        bs = [self.theta_[:, sl].copy() for sl in b_sls]
        return bs[0] if len(bs) == 1 else bs

    def model(self, i):
        """Channel `i` as an ordinary fitted :class:`~rlsfilt.ARX`.

        The model is fitted by ``ARX.fit`` on the channel's record with the
        channel's options, so it has every attribute of a fit (for
        ``method="rls"`` also ``theta_history_`` and ``filter_``); its
        numbers equal row `i` of this bank's arrays (to round-off). The bank
        refers to the arrays given to :func:`fit_many` without copying them
        (a fleet's record can be large); if the channel's record was
        modified since, this raises instead of fitting other data.

        Parameters
        ----------
        i : int or label
            A position ``0 .. C-1`` (negative counts from the end), or a
            label of ``channels_``.

        Returns
        -------
        ARX
        """
        c = self._position(i)
        if self.errors_[c] is not None:
            raise ValueError(f"channel {self.channels_[c]!r} was not fitted: {self.errors_[c]}")
        U, Y = self._data
        if not np.array_equal(_fingerprint(U[:, c:c + 1], Y[:, c:c + 1]),
                              self._fingerprint[:, c:c + 1], equal_nan=True):
            raise ValueError(f"the record of channel {self.channels_[c]!r} was modified after "
                             "fit_many (the bank refers to the arrays it was given, without a "
                             "copy); fit it with ARX.fit on the record you mean")
        u = U[:, c, 0] if U.shape[2] == 1 else U[:, c]
        model = type(self.template)(**self.template.get_params())
        return model.fit(u, Y[:, c], self.method_, **self._channel_options(c))

    def summary(self):
        """The fleet at a glance: fits and residual tests, one row per channel.

        The first and last 5 channels of a larger fleet are listed; for
        every channel (and every column) use :meth:`to_dataframe`.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table): per channel
            the parameters with their standard errors, the simulation and
            prediction fits (percent), the p-values of the residual tests,
            ``healthy`` (``method="rls"``) and the error of a failed channel.
        """
        shown, gap = edge_indices(len(self))
        header = ["channel", *(f"{n} ± se" for n in self.param_names_), "sim. fit %",
                  "pred. fit %"]
        tests = self.q_statistic_ is not None
        rls = self.method_ == "rls"
        header += ["p white", "p independent"] if tests else []
        header += ["healthy"] if rls else []
        failed = any(e is not None for e in self.errors_)
        header += ["error"] if failed else []
        rows = []
        for k, c in enumerate(shown):
            if gap and k == len(shown) // 2:
                rows.append(f"... {gap} more channels ...")
            row = [self.channels_[c],
                   *(f"{self.theta_[c, p]:.5g} ± {self.std_errors_[c, p]:.2g}"
                     for p in range(len(self.param_names_))),
                   f"{self.simulation_fit_[c]:.2f}", f"{self.prediction_fit_[c]:.2f}"]
            if tests:
                row += [f"{self.pvalue_white_[c]:.3g}", f"{self.pvalue_independent_[c]:.3g}"]
            if rls:
                row.append("yes" if self.healthy_[c] else "no")
            if failed:
                row.append(self.errors_[c] or "")
            rows.append(row)
        head = repr(self)
        text = head + "\n\n" + table_text(header, rows)
        first, *rest = head.splitlines()
        page = frame_html(html.escape(first) + "".join("<br>" + html.escape(line.strip())
                                                       for line in rest),
                          table_html(header, rows))
        return Summary(text, page)

    def to_dataframe(self):
        """Every channel and every number in a pandas DataFrame, one row per channel.

        Returns
        -------
        pandas.DataFrame
            Indexed by channel; columns ``n_samples``, the parameters
            (``a1``, ``b1``, ...), their standard errors (``se_a1``, ...),
            ``noise_variance``, ``simulation_fit``, ``prediction_fit`` (in
            percent), ``q_statistic``, ``pvalue_white``, ``f_statistic``,
            ``pvalue_independent``, ``is_white``, ``is_independent`` (with
            residual tests), ``k0`` and ``healthy`` (``method="rls"``) and
            ``error`` (when a channel failed with ``on_error="nan"``).
            Sort and filter it as any DataFrame, e.g.
            ``to_dataframe().sort_values("simulation_fit")``.
        """
        import pandas as pd

        return pd.DataFrame(self._columns(), index=pd.Index(self.channels_, name="channel"))

    def _columns(self):
        cols = {"n_samples": np.full(len(self), self.n_samples_)}
        for p, name in enumerate(self.param_names_):
            cols[name] = self.theta_[:, p]
        for p, name in enumerate(self.param_names_):
            cols["se_" + name] = self.std_errors_[:, p]
        cols["noise_variance"] = self.noise_variance_
        cols["simulation_fit"] = self.simulation_fit_
        cols["prediction_fit"] = self.prediction_fit_
        if self.q_statistic_ is not None:
            cols["q_statistic"] = self.q_statistic_
            cols["pvalue_white"] = self.pvalue_white_
            cols["f_statistic"] = self.f_statistic_
            cols["pvalue_independent"] = self.pvalue_independent_
            cols["is_white"] = self.is_white_
            cols["is_independent"] = self.is_independent_
        if self.method_ == "rls":
            cols["k0"] = self.k0_
            cols["healthy"] = self.healthy_
        if any(e is not None for e in self.errors_):
            cols["error"] = np.array(self.errors_, dtype=object)
        return cols

    def __repr__(self):
        t = self.template
        lines = [f"ARXBank: {len(self)} channels of {_describe(t.get_params())} fitted by "
                 f"{self.method_!r} on {self.n_samples_} rows each"]
        ok = np.array([e is None for e in self.errors_])
        if ok.any():
            lines.append(f"  simulation fit: median {np.nanmedian(self.simulation_fit_[ok]):.2f}%, "
                         f"worst {np.nanmin(self.simulation_fit_[ok]):.2f}%")
            if self.q_statistic_ is not None:
                lines.append(f"  residuals white in {int(self.is_white_[ok].sum())}, independent "
                             f"of the input in {int(self.is_independent_[ok].sum())} of "
                             f"{int(ok.sum())} channels (alpha = {self.alpha:g})")
        if not ok.all():
            lines.append(f"  {int((~ok).sum())} channel(s) not fitted (see errors_)")
        return "\n".join(lines)

    def _repr_html_(self):
        return self.summary().as_html()

    def _position(self, i):
        C = len(self)
        if isinstance(i, numbers.Integral) and not isinstance(i, bool):
            if not -C <= int(i) < C:
                raise IndexError(f"`i` must be a channel position in [{-C}, {C}) or a channel "
                                 f"label; got {i}")
            return int(i) % C
        try:
            return self.channels_.index(i)
        except ValueError:
            raise KeyError(f"`i` must be a channel position or one of the channel labels; got "
                           f"{i!r}") from None

    def _channel_options(self, c):
        opts = {}
        for key, value in self._options.items():
            if key in ("lam", "R", "mu", "eps", "leak"):
                opts[key] = float(value[c])
            elif key in ("P0", "Q", "x0"):
                opts[key] = value[c]
            else:
                opts[key] = value
        return opts


def _warn_operating_points(model, U, Y, todo, labels):
    """Warn (`OperatingPointWarning`) once when channels `todo` sit far from zero (the rule of
    `ARX.fit`, :func:`~rlsfilt.models._offset.far_from_zero`, channel by channel) while the
    model has no ``offset``: naming how many, the first few, and the remedy."""
    if not len(todo):
        return
    whole = len(todo) == U.shape[1]                     # no copy when every channel is fitted
    Us, Ys = (U, Y) if whole else (U[:, todo], Y[:, todo])
    far = far_from_zero(Ys)[0] | far_from_zero(
        Us.reshape(len(Us), -1))[0].reshape(len(todo), -1).any(axis=1)
    if not far.any():
        return
    names = [str(labels[c]) for c in todo[far][:5]]
    more = ", ..." if far.sum() > 5 else ""
    warnings.warn(
        f"fit_many: {int(far.sum())} of {U.shape[1]} channels ({', '.join(names)}{more}) have "
        "an input or output far from zero (mean above 5 standard deviations, no sample "
        "reaching zero), and the model has no offset: their fits mostly describe the "
        "operating point, not the dynamics. " + operating_point_remedy(model),
        OperatingPointWarning, stacklevel=3)


def fit_many(model, u, y, method="ls", *, k0=None, lam=None, P0=None, R=None, Q=None, x0=None,
             max_lag="auto", alpha=0.01, residual_tests=True, on_error="raise",
             progress=False,
             channels=None, **filter_options):
    r"""Fit the orders of `model` to every channel of a fleet.

    Parameters
    ----------
    model : ARX
        The model of every channel (``na``, ``nb``, ``nk``, ``dt``,
        ``offset``); not changed. Every channel is fitted exactly as this
        model: with ``offset=True`` the intercept ``c`` is estimated (the
        last parameter, ``"c"``, and ``intercept_``), with ``"mean"`` each
        channel's means are removed first (``input_offset_``,
        ``output_offset_``). Only `ARX` is accepted (a TypeError names any
        other class): ARMAX, OE, BJ and the other polynomial models need a
        prediction-error fit per channel, which `fit_many` does not run;
        fit them channel by channel with their own ``fit``.
    u : array_like, shape (N, C) or (N, C, n_inputs)
        Inputs of the ``C`` channels (time on axis 0); a pandas DataFrame
        with one column per channel works too. When `u` and `y` are both
        DataFrames, each channel's input is the column of `u` with the
        label of its column in `y` (in any order; labels that do not match,
        or indexes that differ, are a ValueError). A DataFrame `u` with an
        array `y` is taken by the labels `channels` when given; otherwise its
        columns label the channels, in their order.
    y : array_like, shape (N, C)
        Outputs, one column per channel (a DataFrame's columns label the
        channels).
    method : {"ls", "rls", "nlms", "lms"}, default "ls"
        As in :meth:`ARX.fit`: batch least squares (QR), recursive least
        squares started by batch least squares on the first ``k0`` rows of
        each channel, or the gradient methods (one `GradientBank` for the
        channels of a chunk; options ``mu``, ``leak``, ``x0`` and, for
        ``"nlms"``, ``eps``, each shared or one per channel; ``theta_cov_``
        and the standard errors are NaN).
    k0, lam, P0, R, Q, x0
        ``"rls"`` only, as in :meth:`ARX.fit`; `lam` and `R` may also hold
        one value per channel (shape (C,)), `P0` and `Q` one scalar or
        matrix per channel (shapes (C,) or (C, n_params, n_params)), `x0`
        one row per channel (C, n_params). ``lam="tune"`` or ``Q="tune"``:
        each channel's by maximum likelihood first, as :meth:`ARX.fit` does
        (`RLSBank.tune` on the channels' regressor rows, in each channel's
        power-of-two units, with :meth:`ARX.fit`'s prior and its ``Q = q R I``
        of the record at unit size: each channel's estimate and ``R`` are
        those of :meth:`ARX.fit` on it, bit for bit); the results are
        ``tune_`` of the returned bank.
    max_lag : int or "auto", default "auto"
        Largest lag of the residual tests. ``"auto"`` (as in
        :func:`~rlsfilt.validate`): ``min(25, n // 4)`` for ``n`` residuals
        per channel (MATLAB ``resid``'s 25 on records of a few hundred
        samples), halved until the tests are defined on a short record; the
        bank's ``max_lag`` is the lag used.
    alpha : float, default 0.01
        Significance level of ``is_white_`` and ``is_independent_``.
    residual_tests : bool, default True
        Compute the whiteness and independence tests. The independence test
        (a QR of ``2 max_lag + 1`` lagged inputs per channel) costs far more
        than the fit itself; ``False`` skips both tests.
    on_error : {"raise", "nan"}, default "raise"
        What a channel that cannot be fitted does (non-finite data,
        regressors without full rank): raise the error ``ARX.fit`` would
        raise, naming the channel, or give NaN numbers and an entry in
        ``errors_`` (and an ``error`` column in the summary).
    progress : bool, default False
        Show a progress bar (tqdm; install ``tqdm``).
    channels : sequence, optional
        Labels of the channels (default: the columns of a pandas `y`, else
        ``0 .. C-1``).
    **filter_options
        ``"rls"``: ``forgetting`` (``"exponential"``, ``"directional"``,
        ``"constant_trace"``), ``forgetting_params``, ``check_every``,
        ``cond_max`` of `RLSBank`. ``"nlms"``, ``"lms"``: ``mu``, ``leak``
        and (``"nlms"``) ``eps`` of `GradientBank`.

    Returns
    -------
    ARXBank

    Raises
    ------
    ValueError
        For the reasons of :meth:`ARX.fit` (bad orders, too few samples,
        non-finite data, regressors without full rank), naming the channel;
        for shapes that disagree, naming the argument.
    TypeError
        For an option that `method` does not take, or a `model` that is not
        an `ARX`.

    Notes
    -----
    Channel ``i`` gets the numbers of ``ARX(...).fit(u[:, i], y[:, i],
    method, ...)`` and of :func:`rlsfilt.validation.validate` on the same
    record: the same QR least squares, the same recursive filter arithmetic
    (:class:`~rlsfilt.RLSBank` runs each channel exactly as a
    `RecursiveLeastSquares`, the windup cap of exponential forgetting
    included: a channel whose input stops exciting stays finite), the same
    statistics. Like ``ARX.fit``, each channel runs in its own power-of-two units
    (every signal divided by a power of two near its largest entry, which is exact,
    the results mapped back): records around 1e-160 or 1e160 fit as records of unit
    size do, and at ordinary scales the numbers are those of the fit in the signals'
    units, bit for bit (constant-trace forgetting and the gradient methods run in the
    signals' units). ``offset=True`` runs as one more input, constant 1, of one
    coefficient and no delay (its regressor column is ARX's column of
    ones); the residual tests regress on a constant and the model's
    regressors, as :func:`~rlsfilt.validation.residual_analysis`. The regressors follow
    the convention of :func:`~rlsfilt.models.arx_regressors`, built with a
    channel axis (one shifted slice of the record per column, for all
    channels at once).

    BLAS runs one thread inside `fit_many` when threadpoolctl is installed:
    the stacked factorizations of small matrices are much slower threaded
    (0.9 s against 12 s for the residual tests of 500 channels on a busy
    2-core machine). Without threadpoolctl, set ``OPENBLAS_NUM_THREADS=1``
    (or ``OMP_NUM_THREADS=1``) before NumPy starts.

    Examples
    --------
    Two hundred first-order loops, each with its own gain and pole:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import ARX
    >>> from rlsfilt.models import fit_many
    >>> rng = np.random.default_rng(0)
    >>> a = rng.uniform(-0.9, -0.5, 200)
    >>> u = rng.standard_normal((500, 200))
    >>> e = 0.01 * rng.standard_normal((500, 200))
    >>> y = np.column_stack([lfilter([0, 1.0], [1, a[c]], u[:, c])
    ...                      + lfilter([1.0], [1, a[c]], e[:, c]) for c in range(200)])
    >>> fleet = fit_many(ARX(1, 1), u, y)
    >>> bool(np.allclose(fleet.a_[:, 0], a, atol=0.01))
    True
    >>> table = fleet.to_dataframe()
    >>> list(table.columns[:5])
    ['n_samples', 'a1', 'b1', 'se_a1', 'se_b1']
    >>> int(table["is_white"].sum()) >= 190
    True
    """
    params = _fleet_params(model)
    na, nb, nk, dt = params["na"], params["nb"], params["nk"], params["dt"]
    offset = _offset_mode(params["offset"])
    if method not in ("ls", "rls", *_GRADIENT):
        raise ValueError(f"`method` must be 'ls', 'rls', 'nlms' or 'lms'; got {method!r}")
    tuning = tuning_param(method, lam, Q, "fit_many")
    opts = {"k0": k0, "lam": lam, "P0": P0, "R": R, "Q": Q, "x0": x0}
    given = [key for key, value in opts.items() if value is not None]
    if tuning is not None:                   # estimated below, per channel
        opts["lam" if tuning == "lam" else "Q"] = None
    if method == "ls" and (given or filter_options):
        raise TypeError(f"`{(given + list(filter_options))[0]}` only applies to method='rls'; "
                        "got method='ls'")
    if method in _GRADIENT:
        _check_gradient_options(method, [key for key in given if key != "x0"], filter_options)
    else:
        _check_filter_options(filter_options)
    if on_error not in ("raise", "nan"):
        raise ValueError(f"`on_error` must be 'raise' or 'nan'; got {on_error!r}")
    auto_lag = isinstance(max_lag, str) and max_lag == "auto"
    if not auto_lag:
        max_lag = check_int(max_lag, "max_lag", minimum=1)
    alpha = check_probability(alpha, "alpha")
    check_dt(dt)
    U, Y, labels = _fleet_data(u, y, channels)
    N, C, nu = U.shape
    s = arx_structure(na, nb, nk, nu, 1)
    n, rows = s.n_params + (offset == "intercept"), N - s.max_lag
    if rows < n:
        raise ValueError(
            f"`y` must have at least max_lag + n_params = {s.max_lag} + {n} = {s.max_lag + n} "
            f"samples for {_describe(params)}; got {N}")
    if auto_lag:
        from ._residual_tests import fleet_max_lag

        max_lag = fleet_max_lag(rows, n, nu)
    if residual_tests and rows <= 2 * max_lag + 2:
        raise ValueError(f"`max_lag` must be small against the {rows} residuals (need n > "
                         f"2 max_lag + 2); got max_lag = {max_lag}")
    per_channel = (_gradient_options(C, n, method, x0, filter_options) if method in _GRADIENT
                   else _rls_options(C, n, method, opts, filter_options))
    k0 = None if k0 is None else check_int(k0, "k0", minimum=0)
    if k0 is not None and k0 > rows:
        raise ValueError(f"`k0` must be <= the number of regressor rows ({rows}); got {k0}")
    if k0 and (P0 is not None or x0 is not None):
        name = "P0" if P0 is not None else "x0"
        raise ValueError(f"`{name}` only applies to a prior start (k0=0); the batch start on "
                         f"k0={k0} rows sets both x0 and P0. Pass k0=0 to start from `{name}`.")
    out = _Results(C, rows, n, method, residual_tests)
    sums = _fingerprint(U, Y)
    errors = _data_errors(U, Y, sums, labels, on_error)
    out.errors = errors
    good = np.array([e is None for e in errors])
    if offset == "none":
        _warn_operating_points(model, U, Y, np.flatnonzero(good), labels)
    bar = _progress_bar(progress, C)
    chunk = max(1, _CHUNK_BYTES // (8 * max(rows, 1) * (n + 2)))
    todo = np.flatnonzero(good)
    buffer = np.empty(rows * n * min(chunk, C))               # the regressors of a chunk
    # what the fit runs on: the record itself, its deviations from the channels' means
    # (offset="mean"), or the record with a constant input of one coefficient and no
    # delay, whose column of ones is ARX's intercept column (offset=True)
    tuned = None
    if tuning is not None:                   # (in each channel's power-of-two units, as ARX.fit)
        tunits = _ChannelUnits(U, Y, s, offset == "intercept", scaled=True, good=good)
        with _one_blas_thread():
            tuned = _tune_channels(_FitRecord(*tunits.scale(U, Y), s, offset), per_channel,
                                   todo, chunk, buffer, tuning, C, tunits, P0 is not None)
    # ... each channel scaled to unit size by powers of two (exact), as ARX.fit runs
    units = _ChannelUnits(U, Y, s, offset == "intercept", good=good, scaled=(
        "far" if method == "ls" else (method == "rls" and equivariant_forgetting(
            filter_options.get("forgetting", "exponential"),
            filter_options.get("forgetting_params")))))
    if method == "rls":
        per_channel["bank"] = units.bank(per_channel, filter_options, labels, (U, Y),
                                         prior=k0 == 0 or (k0 is None and per_channel["prior"]))
    rec = _FitRecord(*units.scale(U, Y), s, offset)
    try:
        with _one_blas_thread():
            for start in range(0, C, chunk):
                cs = todo[(todo >= start) & (todo < start + chunk)]
                if cs.size:
                    _fit_chunk(cs, rec, method, per_channel, k0, max_lag, residual_tests,
                               on_error, labels, out, buffer)
                if bar is not None:
                    bar.update(min(chunk, C - start))
    finally:
        if bar is not None:
            bar.close()
    units.results(out, labels, on_error)
    out.finish()
    unhealthy = [labels[c] for c in np.flatnonzero(~out.healthy & good)]
    if unhealthy:
        _warn_at_caller(f"the covariance of {len(unhealthy)} channel(s) failed the health "
                        f"check of RLSBank: {unhealthy[:10]}"
                        f"{' ...' if len(unhealthy) > 10 else ''}; their estimates may be "
                        "unreliable (see `healthy_`)", NumericalWarning)
    names = _param_names(s) + (["c"] if offset == "intercept" else [])
    kept = {key: value for key, value in per_channel.items() if key in given}
    kept.update(filter_options if method not in _GRADIENT else
                {key: per_channel[key] for key in filter_options})
    if "k0" in given:
        kept["k0"] = k0
    return ARXBank(
        template=type(model)(**params), channels_=labels, structure_=s,
        theta_=out.theta, theta_cov_=out.cov, std_errors_=np.sqrt(
            np.diagonal(out.cov, axis1=1, axis2=2)) if out.std_errors is None
        else out.std_errors,
        noise_variance_=out.sigma2, residuals_=out.resid, simulation_fit_=out.sim_fit,
        prediction_fit_=out.pred_fit, q_statistic_=out.Q, df_white_=max_lag,
        pvalue_white_=out.p_white, f_statistic_=out.F, df_independent_=out.q,
        pvalue_independent_=out.p_indep,
        is_white_=None if out.Q is None else out.p_white > alpha,
        is_independent_=None if out.Q is None else out.p_indep > alpha,
        k0_=out.k0, recursive_residuals_=out.rec,
        healthy_=out.healthy, errors_=list(errors), n_samples_=rows, n_params_=n,
        **({} if tuned is None else {"tune_": tuned}),
        param_names_=names, method_=method, max_lag=max_lag, alpha=alpha,
        **rec.operating_point(out.theta, units), _data=(U, Y), _fingerprint=sums, _options=kept)


# ----------------------------------------------------------------------
# records in long format (one row per sample, a channel column)
# ----------------------------------------------------------------------
def _summary_long(model, frame, channel, inputs, output, method="ls", **options):
    """`ARXBank.to_dataframe` of the channels of a long-format pandas DataFrame.

    `frame` holds one row per sample: the channel label in column
    `channel`, the inputs in the columns `inputs`, the output in `output`;
    each channel's rows are in time order (other channels' rows may be
    interleaved). Channels of equal length are fitted together by
    `fit_many`; the rows of the result follow the first appearance of the
    channels, and the ``error`` column is always present (None where the
    channel was fitted). Used by the command line and :mod:`rlsfilt.dask`.
    """
    import pandas as pd

    inputs = [inputs] if isinstance(inputs, str) else list(inputs)
    for col in [channel, *inputs, output]:
        if col not in frame.columns:
            raise ValueError(f"column {col!r} is not in the data; the columns are "
                             f"{list(frame.columns)}")
    codes, labels = pd.factorize(frame[channel], sort=False)
    order = np.argsort(codes, kind="stable")                # each channel's rows, in order
    counts = np.bincount(codes, minlength=len(labels))
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    check_not_dates([frame[output].dtype], "output")
    check_not_dates(frame[inputs].dtypes, "input")
    Yall = frame[output].to_numpy(dtype=float)
    Uall = frame[inputs].to_numpy(dtype=float)
    on_error = options.get("on_error", "raise")
    parts = []
    for L in np.unique(counts):
        group = np.flatnonzero(counts == L)
        rows = order[starts[group][None, :] + np.arange(L)[:, None]]      # (L, Cg)
        names = list(labels[group])
        U = Uall[rows]                                                      # (L, Cg, nu)
        try:
            table = fit_many(model, U, Yall[rows], method, channels=names, **options).to_dataframe()
        except ValueError as exc:
            if on_error == "raise":
                if "channel" in str(exc):        # the message names the channel already
                    raise
                raise ValueError(f"channel(s) {names[:10]} with {L} samples: {exc}") from None
            table = _failed_rows(model, len(inputs), method, options, names, str(exc))
        if "error" not in table:
            table["error"] = None
        parts.append(table)
    out = pd.concat(parts)
    return out.loc[list(labels)] if len(parts) > 1 else out


def _summary_schema(model, n_inputs, method, options):
    """``{column: dtype}`` of `ARXBank.to_dataframe` (with the ``error`` column)."""
    params = _fleet_params(model)
    s = arx_structure(params["na"], params["nb"], params["nk"], n_inputs, 1)
    names = _param_names(s) + (["c"] if _offset_mode(params["offset"]) == "intercept" else [])
    schema = {"n_samples": "int64"}
    schema.update({name: "float64" for name in names})
    schema.update({"se_" + name: "float64" for name in names})
    schema.update(dict.fromkeys(("noise_variance", "simulation_fit", "prediction_fit"),
                                "float64"))
    if options.get("residual_tests", True):
        schema.update(dict.fromkeys(("q_statistic", "pvalue_white", "f_statistic",
                                     "pvalue_independent"), "float64"))
        schema.update({"is_white": "bool", "is_independent": "bool"})
    if method == "rls":
        schema.update({"k0": "int64", "healthy": "bool"})
    schema["error"] = "object"
    return schema


def _failed_rows(model, n_inputs, method, options, names, message):
    """Summary rows of channels that could not be fitted at all."""
    import pandas as pd

    schema = _summary_schema(model, n_inputs, method, options)
    data = {}
    for col, dtype in schema.items():
        fill = {"float64": np.nan, "int64": 0, "bool": False, "object": message}[dtype]
        data[col] = np.full(len(names), fill, dtype=dtype)
    return pd.DataFrame(data, index=pd.Index(names, name="channel"))


# ----------------------------------------------------------------------
# one chunk of channels
# ----------------------------------------------------------------------
class _Results:
    """The result arrays, filled chunk by chunk (NaN for channels not fitted)."""

    def __init__(self, C, rows, n, method, tests):
        nan = np.nan
        self.theta = np.full((C, n), nan)
        self.cov = np.full((C, n, n), nan)
        self.sigma2 = np.full(C, nan)
        self.resid = np.empty((rows, C))            # (NaN for failed channels: `finish`)
        self.sim_fit = np.full(C, nan)
        self.pred_fit = np.full(C, nan)
        self.healthy = np.ones(C, dtype=bool)
        self.k0 = np.zeros(C, dtype=int) if method != "ls" else None
        self.rec = np.empty((rows, C)) if method != "ls" else None
        self.Q = np.full(C, nan) if tests else None
        self.p_white = np.full(C, nan) if tests else None
        self.F = np.full(C, nan) if tests else None
        self.q = np.zeros(C, dtype=int) if tests else None
        self.p_indep = np.full(C, nan) if tests else None
        self.errors = None
        self.std_errors = None          # (from the scaled units: `_ChannelUnits.results`)

    def finish(self):
        """NaN residuals for the channels that were not fitted."""
        bad = np.array([e is not None for e in self.errors])
        self.resid[:, bad] = np.nan
        if self.rec is not None:
            self.rec[:, bad] = np.nan


def _fit_chunk(cs, rec, method, per_channel, k0, max_lag, tests, on_error, labels, out,
               buffer):
    """Fit channels `cs` of the record `rec` (a `_FitRecord`) and write their numbers
    into `out` (`buffer`: the memory of the chunk's regressors, reused from chunk to
    chunk)."""
    U, Y, s = rec.U, rec.Y, rec.s
    cs, sel = _as_slice(cs)                                  # a view when `cs` is a range
    norms = np.empty((cs.size, s.n_params))                  # column norms of the regressors
    Phi, target = _regressors(U, Y, s, sel, buffer, norms)   # (rows, c, n), (rows, c)
    if method == "ls":
        ok, theta, cov = _least_squares(Phi, target, norms)
        rank_msg = ("the regressor matrix has rank < n_params = {n}: the input is not "
                    "persistently exciting for these orders (or the orders are too high); use a "
                    "richer input, more data or lower orders")
        for j in np.flatnonzero(~ok):
            _fail(out, cs[j], labels, rank_msg.format(n=s.n_params), on_error)
    elif method in _GRADIENT:
        ok, theta, cov = _gradient(cs, Phi, target, method, per_channel, out)
    else:
        ok, theta, cov = _recursive(cs, Phi, target, norms, per_channel, k0, labels, on_error,
                                    out)
    if not ok.any():
        return
    if not ok.all():
        cs, Phi, theta, cov = cs[ok], Phi[:, ok], theta[ok], cov[ok]
    rows, c, n = Phi.shape
    cs, sel = _as_slice(cs)
    # the statistics read the record itself (not the regressors) and write the
    # residuals in place when the channels are consecutive (no copies)
    Yc, c0, Uc, cu0 = _record_views(U, Y, sel)
    resid = out.resid if isinstance(sel, slice) else np.empty((rows, c))
    sigma2, pred_fit, sim_fit = np.empty(c), np.empty(c), np.empty(c)
    u_lag, u_input = _input_columns(s)
    _fleet_kernels().fleet_statistics(Yc, c0, Uc, cu0, s.na, u_lag, u_input, theta, resid,
                                      sigma2, pred_fit, sim_fit)
    out.theta[sel], out.sigma2[sel] = theta, sigma2
    if isinstance(sel, slice):
        resid = resid[:, sel]
    else:
        out.resid[:, sel] = resid
    out.cov[sel] = sigma2[:, None, None] * cov
    out.pred_fit[sel], out.sim_fit[sel] = pred_fit, sim_fit
    if tests:
        from ._residual_tests import input_lag_test_many, ljung_box_many

        start = s.max_lag
        resid = np.ascontiguousarray(resid.T)                  # one row per channel
        Q, _, p_white = ljung_box_many(resid, max_lag)
        out.Q[sel], out.p_white[sel] = Q, p_white
        # the test regresses on a constant and the model's regressors (as
        # residual_analysis): without the intercept column, the same span
        U = rec.U_test[:, sel]
        Phi = Phi[:, :, :rec.n_test] if rec.n_test < n else Phi
        n = Phi.shape[2]
        nu = U.shape[2]
        width = 8 * rows * (nu * (2 * max_lag + 1) + n + 2)
        step = max(1, _TEST_BYTES // width)
        for j in range(0, c, step):
            sl = slice(j, j + step)
            PhiT = np.ascontiguousarray(Phi[:, sl].transpose(1, 0, 2))
            UT = np.ascontiguousarray(U[:, sl].transpose(1, 0, 2))
            F, q, p = input_lag_test_many(resid[sl], PhiT, UT, start, max_lag)
            out.F[cs[sl]], out.q[cs[sl]], out.p_indep[cs[sl]] = F, q, p


def _least_squares(Phi, target, norms):
    r"""Batch least squares of each channel through QR, as ``ARX.fit(method="ls")``.

    One Householder QR of ``[Phi, y]`` per channel (NumPy's stacked QR)
    gives :math:`R_1` and :math:`Q_1^T y`; :math:`\hat\theta = R_1^{-1}
    Q_1^T y` and :math:`(\Phi^T\Phi)^{-1} = R_1^{-1} R_1^{-T}`. The rank is
    decided, as in ``ARX.fit``, on the columns scaled to unit norm (from the
    singular values of :math:`R_1 D^{-1}`, those of :math:`\Phi D^{-1}`).

    ``norms`` (c, n) are the column norms of ``Phi`` (from `_regressors`).
    Returns ``ok`` (c,) full rank, ``theta`` (c, n), ``cov`` (c, n, n).
    """
    rows, c, n = Phi.shape
    A = np.empty((c, rows, n + 1))
    A[:, :, :n] = Phi.transpose(1, 0, 2)
    A[:, :, n] = target.T
    R = np.linalg.qr(A, mode="r")
    R1, qty = R[:, :n, :n], R[:, :n, n]
    d = np.where(norms > 0.0, norms, 1.0)
    sv = np.linalg.svd(R1 / d[:, None, :], compute_uv=False)
    tol = sv[:, :1] * max(rows, n) * np.finfo(float).eps
    ok = (sv > tol).sum(axis=1) == n
    theta = np.full((c, n), np.nan)
    cov = np.full((c, n, n), np.nan)
    if ok.any():
        Rinv = np.linalg.inv(R1[ok])                          # triangular inverse
        theta[ok] = (Rinv @ qty[ok][:, :, None])[:, :, 0]
        C = Rinv @ Rinv.transpose(0, 2, 1)
        cov[ok] = 0.5 * (C + C.transpose(0, 2, 1))
    return ok, theta, cov


def _recursive(cs, Phi, target, norms, opts, k0, labels, on_error, out):
    """Recursive least squares of each channel, as ``ARX.fit(method="rls")``:
    an `RLSBank` per group of channels with the same batch start ``k0``."""
    rows, c, n = Phi.shape
    ok = np.ones(c, dtype=bool)
    theta = np.full((c, n), np.nan)
    cov = np.full((c, n, n), np.nan)
    if k0 is not None:
        k0s = np.full(c, k0)
    elif opts["prior"]:
        k0s = np.zeros(c, dtype=int)
    else:
        k0s = _batch_start_rows(Phi, norms)
        for j in np.flatnonzero(k0s < 0):
            ok[j] = False
            rank = int(np.linalg.matrix_rank(unit_columns(Phi[:, j])))
            _fail(out, cs[j], labels,
                  f"the regressor matrix has rank {rank} < n_params = {n}: the input is not "
                  "persistently exciting for these orders (or the orders are too high); use a "
                  "richer input, more data or lower orders", on_error)
    for kv in np.unique(k0s[ok]):
        group = np.flatnonzero(ok & (k0s == kv))
        group = _run_group(cs, group, int(kv), Phi, target, opts, labels, on_error, out)
        if group is None:
            continue
        g, bank = group
        theta[g] = bank.x
        cov[g] = bank.P / bank.R[:, None, None]
        _, sel = _as_slice(cs[g])
        out.k0[sel] = kv
        out.rec[:kv, sel] = np.nan                       # the rows of the batch start
        healthy = ~np.isin(np.arange(len(g)), bank.failed_channels)
        if not healthy.all() and "cond_max" not in opts["filter"]:
            _health_as_arx(cs, g, int(kv), Phi, target, opts, healthy)
        out.healthy[sel] = healthy
        ok[np.setdiff1d(np.flatnonzero(k0s == kv), g)] = False
    return ok, theta, cov


def _gradient(cs, Phi, target, method, opts, out):
    """The gradient filter of each channel, as ``ARX.fit(method="nlms" | "lms")``: one
    `GradientBank` over the chunk from ``x0``; the a-priori residuals go into
    ``out.rec``. A gradient estimate has no covariance (NaN)."""
    rows, c, n = Phi.shape
    bank = GradientBank(c, n, opts["mu"][cs], method=method, eps=opts["eps"][cs],
                        leak=opts["leak"][cs], x0=opts["x0"][cs])
    hist = bank.batch_filter(target, Phi, store_means=False)
    _, sel = _as_slice(cs)
    out.rec[:, sel] = hist.residuals
    return np.ones(c, dtype=bool), bank.x.copy(), np.full((c, n, n), np.nan)


def _run_group(cs, g, k0, Phi, target, opts, labels, on_error, out):
    """Batch start on ``k0`` rows and the filter over the rest, for channels `g`:
    their recursive residuals are written into ``out.rec``; returns the channels
    that were started (``g`` or fewer) and their bank."""
    rows = Phi.shape[0]

    def make(channels):                 # the fleet's bank, validated once, cut to `channels`
        return subset(opts["bank"], cs[channels])

    bank = make(g)
    g_sel = slice(None) if len(g) == Phi.shape[1] else g      # no copy for a whole chunk
    if k0 > 0:
        try:
            bank.initialize(target[:k0, g_sel], Phi[:k0, g_sel])
        except ValueError:
            # some channel's first k0 rows are rank-deficient: find it, keep the others
            good = []
            for j in g:
                try:
                    make(np.array([j])).initialize(target[:k0, [j]], Phi[:k0, [j]])
                    good.append(j)
                except ValueError as exc:
                    _fail(out, cs[j], labels, str(exc).replace(" in 1 channel(s) [0]", ""),
                          on_error)
            if not good:
                return None
            g = g_sel = np.array(good)
            bank = make(g)
            bank.initialize(target[:k0, g], Phi[:k0, g])
    if k0 < rows:
        # the recursive residuals go straight into the result when the channels
        # are consecutive (a strided view of `out.rec`), else through a copy
        _, sel = _as_slice(cs[g])
        into = out.rec[k0:, sel] if isinstance(sel, slice) else None
        with warnings.catch_warnings():       # one warning for the fleet, by label
            warnings.simplefilter("ignore", NumericalWarning)
            hist = bank.batch_filter(target[k0:, g_sel], Phi[k0:, g_sel],
                                     store_covariances=False, store_means=False,
                                     _residuals=into)
        if into is None:
            out.rec[k0:, sel] = hist.residuals
    return g, bank


def _health_as_arx(cs, g, k0, Phi, target, opts, healthy):
    r"""The health verdicts of ``ARX.fit`` for the channels `g` that failed the bank's:
    ``ARX.fit`` sets the check's ``cond_max`` from the data, :math:`\max(10^{12}, 10^4
    \kappa(\Phi)^2)` (the condition number the regressors give P is no failure), the bank
    has one ``cond_max`` (1e12) for all its channels. A failed channel whose own
    ``cond_max`` is larger runs again alone with it (the same bits: a channel's numbers do
    not depend on the bank's other channels) and takes that verdict; a channel healthy
    at 1e12 is healthy at any larger ``cond_max``. Updates `healthy` in place."""
    for j in np.flatnonzero(~healthy):
        c = g[j]
        sv = np.linalg.svd(Phi[:, c], compute_uv=False)
        with np.errstate(over="ignore", divide="ignore"):
            cond = sv[0] / sv[-1] if sv[-1] > 0 else np.inf
            cond_max = min(max(1e12, 1e4 * cond ** 2), np.finfo(float).max)
        bank = subset(opts["bank"], cs[[c]])
        if not cond_max > bank.cond_max:
            continue
        bank.cond_max = cond_max
        if k0 > 0:
            bank.initialize(target[:k0, [c]], Phi[:k0, [c]])
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            bank.batch_filter(target[k0:, [c]], Phi[k0:, [c]], store_covariances=False,
                              store_means=False)
        healthy[j] = not len(bank.failed_channels)


_NEAR = 100


class _ChannelUnits:
    r"""The powers of two that bring each channel to unit size, as `ARX.fit` does
    (:mod:`rlsfilt.models._units`), with a channel axis.

    Input ``i`` of channel ``c`` is :math:`2^{e_{ci}}\tilde u`, its output
    :math:`2^{e_{y,c}}\tilde y` (`pow2_exponent` of each column); regressor
    column ``k`` of channel ``c`` has the exponent :math:`c_{ck}` of its signal
    (0 for the intercept's ones) and the parameter is :math:`\theta_{ck} =
    2^{g_{ck}}\tilde\theta_{ck}`, :math:`g_{ck} = e_{y,c} - c_{ck}`. Dividing the
    record by powers of two is exact, and least squares, the bank's recursion
    (exponential or directional forgetting, from ``P0``, ``R``, ``Q``, ``x0``
    mapped as `RecordUnits.recursion_start` maps them) and the statistics then
    run operation for operation as in the signals' units times powers of two: the
    same bits wherever both runs stay in the normal range, and in range for
    records of any size (around 1e+-160 too). The gradient methods and the
    forgetting modes whose constants bound ``trace(P)`` run in the signals' units
    (every exponent 0).
    """

    def __init__(self, U, Y, s, intercept, scaled, good):
        # scaled: True, False, or "far" (least squares: only a record with some signal
        # beyond 2^+-_NEAR; nearer ones give the same bits unscaled, every operation
        # of the fit being homogeneous and in range, and save the scaled copy)
        C, nu = U.shape[1], U.shape[2]
        self.eu, self.ey = np.zeros((C, nu), dtype=int), np.zeros(C, dtype=int)
        if scaled and good.any():           # (channels of NaN or inf, `~good`: exponent 0)
            Ug, Yg = (U, Y) if good.all() else (U[:, good], Y[:, good])
            self.eu[good] = np.reshape(pow2_exponent(Ug, axis=0), (-1, nu))
            self.ey[good] = np.reshape(pow2_exponent(Yg, axis=0), -1)
            if scaled == "far" and max(np.abs(self.eu).max(initial=0),
                                       np.abs(self.ey).max(initial=0)) <= _NEAR:
                self.eu[:], self.ey[:] = 0, 0
        self._s, self._intercept = s, intercept

    @property
    def identity(self):
        """Every exponent 0: the fit runs on the record itself."""
        return not (self.eu.any() or self.ey.any())

    def columns(self):
        """:math:`c_{ck}` (C, n_params): the exponents of the regressor columns."""
        parts = [np.repeat(self.ey[:, None], self._s.na, axis=1),
                 self.eu[:, _input_columns(self._s)[1]]]
        if self._intercept:
            parts.append(np.zeros((len(self.ey), 1), dtype=int))
        return np.concatenate(parts, axis=1)

    def theta(self):
        """:math:`g_{ck}` (C, n_params): the exponents of the parameters."""
        return self.ey[:, None] - self.columns()

    def scale(self, U, Y):
        """The record in the scaled units (new arrays; the caller's are not touched)."""
        if self.identity:
            return U, Y
        N, C, nu = U.shape                  # (rows of C nu columns: a fast inner loop)
        Us = times_pow2(U.reshape(N, C * nu), -self.eu.reshape(-1)).reshape(N, C, nu)
        return Us, times_pow2(Y, -self.ey)

    def bank(self, opts, filter_options, labels, record, prior):
        """The fleet's `RLSBank` in the scaled units, from the channels' options `opts`
        (`_rls_options`, validated in the signals' units): ``R~ = 2^r R`` (``r``
        bringing ``R`` to about 1), ``P0~`` of a `prior` start (``k0 = 0``) and ``Q~`` as
        ``2^(c_k + c_l + r)`` times the user's, ``x0~ = 2^-g x0``; a batch start keeps
        the default ``P0`` (the windup cap's default trace limit) in the scaled units,
        as `ARX.fit`. A ``P0``, ``Q`` or ``x0`` beyond the filters' range there is a
        ValueError naming it; channels whose prior ``P0`` outweighs their data are
        warned about (NumericalWarning naming ``P0``), and those where it underflows
        run in their own units, as `ARX.fit` runs them."""
        R = opts["R"]
        r = -np.round(np.log2(R)).astype(int)
        P0 = None
        if prior:                           # (a prior start: k0 = 0)
            P0 = self._to_unit(opts["P0"], r)
            if not np.max(np.abs(P0), initial=0.0) <= COVARIANCE_MAX:
                raise ValueError(
                    "`P0` must suit the scale of the data: read in the signals' units (as R) "
                    "it is too diffuse for double precision for the record scaled to unit size "
                    "(the first update would lose every digit of P); pass P0 and R in the "
                    "signals' units (P0 about 1e4 * R / max|phi_k|^2 for parameter k), or "
                    "scale the signals")
            d = np.abs(np.diagonal(P0, axis1=1, axis2=2))
            lost = (d < np.finfo(float).tiny).any(axis=1)
            with np.errstate(over="ignore"):      # the prior's information, scaled
                info = np.ldexp(R, r)[:, None] / np.where(d > 0, d, 1.0)
            weak = lost | (info > 1e-2 * self._energy(record)).any(axis=1)
            if weak.any():
                names = [labels[c] for c in np.flatnonzero(weak)]
                _warn_at_caller(
                    f"P0 (in the signals' units, as R) outweighs the data of {len(names)} "
                    f"channel(s) scaled to unit size: {names[:10]}"
                    f"{' ...' if len(names) > 10 else ''}; the prior holds their estimates "
                    "toward `x0`. Pass P0 and R in the signals' units (P0 about 1e4 * R / "
                    "max|phi_k|^2 for parameter k), or scale the signals to unit size",
                    NumericalWarning)
            if lost.any():                        # these channels run in their own units
                self.eu[lost], self.ey[lost] = 0, 0
                P0 = self._to_unit(opts["P0"], r)
        if self.identity:
            return opts["bank"]
        Q = self._to_unit(opts["Q"], r)
        if opts.get("Q_scaled") is not None:   # Q="tune": from its value in the tune's units
            c, ct = self.columns(), opts["Q_columns"]
            with np.errstate(over="ignore", under="ignore"):
                Q = np.ldexp(opts["Q_scaled"], c[:, :, None] + c[:, None, :] - ct[:, :, None]
                             - ct[:, None, :] + r[:, None, None])
        with np.errstate(over="ignore", under="ignore"):
            x0 = np.ldexp(opts["x0"], -self.theta())
        if not np.max(np.abs(Q), initial=0.0) <= COVARIANCE_MAX:
            raise ValueError("`Q` must suit the scale of the data: read in the signals' units "
                             "it is beyond the range of the recursion for the record scaled to "
                             "unit size; pass a smaller Q or scale the signals")
        if not np.isfinite(x0).all():
            raise ValueError("`x0` must have b coefficients of the size the record's units "
                             "allow (|b| up to about max|y| / max|u| times 1e300); got "
                             "coefficients that overflow")
        return RLSBank(len(R), x0.shape[1], opts["lam"], R=np.ldexp(R, r), Q=Q, x0=x0,
                       **({} if P0 is None else {"P0": P0}), **filter_options)

    def _to_unit(self, P, r):
        """``P0`` or ``Q`` (C, n, n) -> the scaled units: ``2^(c_k + c_l + r)`` times."""
        c = self.columns()
        with np.errstate(over="ignore", under="ignore"):
            return np.ldexp(P, c[:, :, None] + c[:, None, :] + r[:, None, None])

    def _energy(self, record):
        """The sum of squares of each regressor column's signal in the scaled units (the
        intercept's ones: the number of samples), (C, n_params)."""
        U, Y = self.scale(*record)
        parts = [np.repeat(np.einsum("tc,tc->c", Y, Y)[:, None], self._s.na, axis=1),
                 np.einsum("tci,tci->ci", U, U)[:, _input_columns(self._s)[1]]]
        if self._intercept:
            parts.append(np.full((Y.shape[1], 1), float(len(Y))))
        return np.concatenate(parts, axis=1)

    def results(self, out, labels, on_error):
        """The fit's numbers in `out` (computed in the scaled units) -> the signals'
        units, in place (before `_Results.finish`): a coefficient beyond the largest
        double there is the error of `estimate_in_units`, for its channel."""
        if self.identity:
            return
        g = self.theta()
        with np.errstate(over="ignore", under="ignore", invalid="ignore"):
            se = np.ldexp(np.sqrt(np.diagonal(out.cov, axis1=1, axis2=2)), g)
            theta = np.ldexp(out.theta, g)
            out.cov = np.ldexp(out.cov, g[:, :, None] + g[:, None, :])
            out.sigma2 = np.ldexp(out.sigma2, 2 * self.ey)
        out.std_errors = se
        for c in np.flatnonzero(np.isfinite(out.theta).all(axis=1)
                                & ~np.isfinite(theta).all(axis=1)):
            try:
                estimate_in_units(out.theta[c], g[c])
            except ValueError as exc:
                _fail(out, c, labels, str(exc), on_error)
            theta[c], se[c], out.cov[c] = np.nan, np.nan, np.nan
            out.sigma2[c], out.sim_fit[c], out.pred_fit[c] = np.nan, np.nan, np.nan
        out.theta = theta
        times_pow2(out.resid, self.ey[None, :], out=out.resid)
        if out.rec is not None:
            times_pow2(out.rec, self.ey[None, :], out=out.rec)

    def means(self, means):
        """The channels' means (``offset="mean"``, in the scaled units) -> the signals'."""
        return np.ldexp(means[0], self.eu), np.ldexp(means[1], self.ey)


class _FitRecord:
    """The record a fleet's fit runs on, for the `offset` of its ARX model.

    ``offset=False``: the record ``U`` (N, C, nu), ``Y`` (N, C) itself.
    ``"mean"``: the deviations from each channel's means (``ARX.fit`` removes
    the means of the estimation record). ``"intercept"`` (``offset=True``):
    ``U`` with one more input, constant 1, of one coefficient and no delay,
    whose regressor column is the column of ones ``ARX`` appends (last, as
    the intercept ``c`` is the last entry of ``theta_``); the constant input
    adds no lag, so the rows are those of the model. ``U_test`` and
    ``n_test`` are the inputs and the number of leading regressor columns
    the independence test reads (``residual_analysis`` regresses on a
    constant and the model's regressors: a second column of ones adds
    nothing to that span).
    """

    def __init__(self, U, Y, s, offset):
        self.offset, self.s, self.n_test = offset, s, s.n_params
        self.U, self.Y, self.U_test = U, Y, U
        self.means = None
        if offset == "mean":
            u_bar, y_bar = record_means(U), record_means(Y)         # (C, nu), (C,)
            self.means = (u_bar, y_bar)
            self.U = self.U_test = np.ascontiguousarray(U - u_bar)
            self.Y = np.ascontiguousarray(Y - y_bar)
        elif offset == "intercept":
            N, C, nu = U.shape
            Ua = np.empty((N, C, nu + 1))
            Ua[:, :, :nu] = U
            Ua[:, :, nu] = 1.0
            self.U = Ua
            self.s = arx_structure(s.na, list(s.nb) + [1], list(s.nk) + [0], nu + 1, 1)

    def operating_point(self, theta, units):
        """The fitted attributes of the offset: ``intercept_`` (C,) for
        ``offset=True``; ``input_offset_`` (C, nu), ``output_offset_`` (C,) (the
        channels' means, from the record in the scaled `units`) for ``"mean"``;
        nothing without an offset."""
        if self.offset == "intercept":
            return {"intercept_": theta[:, -1].copy()}
        if self.offset == "mean":
            u_bar, y_bar = units.means(self.means)
            return {"input_offset_": u_bar, "output_offset_": y_bar}
        return {}


def _fleet_params(model):
    """The constructor parameters of `model`, an `ARX` (anything else is refused: a
    fleet fits exactly the model it is given)."""
    # the class by its name and module, not by an import of it: arx.py imports this
    # module (ARX.fit_many), and the import graph has no cycle
    cls = type(model)
    if (cls.__module__, cls.__qualname__) != ("rlsfilt.models.arx", "ARX"):
        name = type(model).__name__
        why = (" (its noise or output-error polynomials need a prediction-error fit per "
               "channel: fit them one by one with its own fit method)"
               if hasattr(model, "get_params") else "")
        raise TypeError(f"`model` must be an ARX (fit_many fits ARX(na, nb, nk, dt, offset) "
                        f"by least squares; it accepts no other class); got {name}{why}")
    params = model.get_params()
    _offset_mode(params["offset"])                       # validated (the message names it)
    return params


def _describe(params):
    text = f"ARX(na={params['na']!r}, nb={params['nb']!r}, nk={params['nk']!r}"
    if _offset_mode(params.get("offset", False)) != "none":
        text += f", offset={params['offset']!r}"
    return text + ")"


def _as_slice(cs):
    """``(cs, selector)``: a slice when the positions `cs` are consecutive."""
    if cs.size and cs[-1] - cs[0] + 1 == cs.size:
        return cs, slice(int(cs[0]), int(cs[-1]) + 1)
    return cs, cs


def _batch_start_rows(Phi, norms):
    """The default ``k0`` of ``ARX.fit(method="rls")`` for each channel: the
    fewest leading rows with full column rank (``regressors._full_rank_rows``),
    -1 when all rows together are rank-deficient (`norms`: the column norms of
    ``Phi``, whose unit columns decide the rank, as ``regressors._column_rank``)."""
    rows, c, n = Phi.shape
    Ps = Phi[:n].transpose(1, 0, 2) / np.where(norms > 0, norms, 1.0)[:, None, :]
    k0s = np.full(c, n)
    # the ranks of np.linalg.matrix_rank(Ps), most settled by a QR (bank.full_rank)
    rank, _ = full_rank(Ps, np.linalg.qr(Ps, mode="r"))
    for j in np.flatnonzero(rank < n):
        k = _full_rank_rows(Phi[:, j])
        k0s[j] = -1 if k is None else k
    return k0s


def _input_columns(s):
    """Lags and input indices of the input columns of the ARX regressor (in its
    order: input by input, increasing lag), as two int64 arrays."""
    lags = [k for j in range(s.n_inputs) for k in range(s.nk[j], s.nk[j] + s.nb[j])]
    inputs = [j for j in range(s.n_inputs) for _ in range(s.nb[j])]
    return np.array(lags, dtype=np.int64), np.array(inputs, dtype=np.int64)


def _regressors(U, Y, s, channels=None, buffer=None, norms=None):
    r"""Regressors ``(rows, c, n)`` and targets ``(rows, c)`` of the `channels`.

    The convention of :func:`~rlsfilt.models.arx_regressors` (rows
    ``t = max_lag .. N-1``, blocks ``-y`` then ``u`` by increasing lag) with a
    channel axis, for the channels `channels` (a slice or positions; all by
    default) of the record ``U`` (N, C, n_inputs), ``Y`` (N, C). The tests
    hold it equal to ``ARX.regressors`` channel by channel. The regressors
    are built by one compiled pass over the record
    (:func:`~rlsfilt.models._kernels_fleet.build_regressors`), stored as
    ``(rows, n, c)`` and returned as the transposed view, which
    `RLSBank.batch_filter` reads without a copy. With a `buffer` (a 1-d
    float64 array of at least ``rows n c`` elements) they are written into
    its first elements (`fit_many` reuses one buffer for all chunks); with
    `norms` (c, n) that array receives the norms of their columns (summed in
    time order, in the same pass).
    """
    U, Y = np.ascontiguousarray(U, dtype=float), np.ascontiguousarray(Y, dtype=float)
    channels = slice(0, Y.shape[1]) if channels is None else channels
    Yc, c0, Uc, cu0 = _record_views(U, Y, channels)
    c = len(range(Y.shape[1])[channels]) if isinstance(channels, slice) else len(channels)
    shape = (Y.shape[0] - s.max_lag, s.n_params, c)
    Phi = np.empty(shape) if buffer is None else buffer[:math.prod(shape)].reshape(shape)
    norms = np.empty((c, s.n_params)) if norms is None else norms
    u_lag, u_input = _input_columns(s)
    _fleet_kernels().build_regressors(Yc, c0, Uc, cu0, s.na, u_lag, u_input, Phi, norms)
    return Phi.transpose(0, 2, 1), Y[s.max_lag:, channels]


def _record_views(U, Y, channels):
    """The record of `channels` as the compiled kernels read it: ``(Y, c0, U, cu0)``
    with channel ``c`` in column ``c0 + c`` of ``Y`` (N, C') and ``cu0 + c`` of
    ``U`` (n_inputs, N, C'). Views of the whole (C-ordered) record when
    `channels` is a slice (for ``U`` with one input), otherwise copies of the
    channels' columns."""
    N, C, nu = U.shape
    if isinstance(channels, slice):
        c0 = range(C)[channels].start
        Yc = Y
    else:
        c0, Yc = 0, np.ascontiguousarray(Y[:, channels])
    if nu == 1 and isinstance(channels, slice):
        return Yc, c0, U.reshape(1, N, C), c0
    return Yc, c0, np.ascontiguousarray(U[:, channels].transpose(2, 0, 1)), 0


def _fleet_data(u, y, channels):
    """``U (N, C, nu)``, ``Y (N, C)`` as float64 C-ordered arrays, and the channel labels."""
    names = None
    if _is_frame(y):
        names = list(y.columns)
        u = _aligned_inputs(u, names, "y", y.index)
    elif _is_frame(u):                 # labelled inputs, outputs by position
        if channels is None:
            names = list(u.columns)    # the channels are u's columns, in their order
        else:
            u = _aligned_inputs(u, list(channels), "channels")
    Y = as_float_array(y.to_numpy() if hasattr(y, "to_numpy") else y, "y")
    U = as_float_array(u.to_numpy() if hasattr(u, "to_numpy") else u, "u")
    if Y.ndim != 2:
        raise ValueError(f"`y` must have shape (N, C) (one column per channel); got {Y.shape} "
                         "(use ARX.fit for one channel)")
    N, C = Y.shape
    if U.ndim == 2:
        U = U[:, :, None]
    if U.ndim != 3:
        raise ValueError(f"`u` must have shape (N, C) or (N, C, n_inputs); got {U.shape}")
    if len(U) != N:
        raise ValueError(f"`u` and `y` must have the same length; got {len(U)} input samples "
                         f"and {N} output samples")
    if U.shape[1] != C:
        raise ValueError(f"`u` must have one column per channel of `y` ({C}); got "
                         f"{U.shape[1]} (shape {U.shape[:2] if U.shape[2] == 1 else U.shape})")
    if channels is not None:
        names = list(channels)
        if len(names) != C:
            raise ValueError(f"`channels` must have one label per channel ({C}); got "
                             f"{len(names)}")
    if names is None:
        names = list(range(C))
    if len(set(map(repr, names))) != len(names):
        raise ValueError("`channels` must be distinct labels")
    # read only below: the caller's arrays when they are float64 and C-ordered (no copy)
    return np.ascontiguousarray(U), np.ascontiguousarray(Y), names


def _is_frame(x):
    return hasattr(x, "columns") and hasattr(x, "to_numpy")


def _aligned_inputs(u, labels, other, index=None):
    """`u` with its columns in the order of the channel `labels` (``y``'s columns, or
    the `channels` given), when `u` is a pandas DataFrame: a fleet pairs a channel's
    input with its output by label, never by position. Labels that do not match, or
    time indexes that differ (`index`, ``y``'s), are a ValueError naming them."""
    if not _is_frame(u):
        return u                             # an array: paired by position, as documented
    ucols = list(u.columns)
    for name, cols in (("u", ucols), (other, labels)):
        if len(set(map(repr, cols))) != len(cols):
            raise ValueError(f"the columns of `{name}` must be distinct channel labels; got "
                             f"{cols[:10]}{' ...' if len(cols) > 10 else ''}"
                             if name != "channels" else "`channels` must be distinct labels")
    if ucols != labels:
        missing = [c for c in labels if c not in ucols]
        extra = [c for c in ucols if c not in labels]
        what = "the columns of `u` and `y`" if other == "y" else \
            "the columns of `u` and the labels `channels`"
        if missing or extra:
            raise ValueError(
                f"{what} must carry the same channel labels (a channel's input is paired with "
                f"its output by label); `u` lacks {missing[:10]}, and has {extra[:10]} that "
                f"`{other}` lacks")
        u = u[labels]                        # the same labels in another order
    if index is not None and not u.index.equals(index):
        raise ValueError("`u` and `y` must have the same index (time on axis 0, sample by "
                         "sample); got different indexes")
    return u


def _fingerprint(U, Y):
    """Per-channel sums of the record (2, C): `ARXBank.model` refits from the
    caller's arrays and checks with them that the record is still the one fitted."""
    out = np.empty((2, Y.shape[1]))
    _fleet_kernels().record_sums(np.ascontiguousarray(Y), np.ascontiguousarray(U), out)
    return out


def _data_errors(U, Y, sums, labels, on_error):
    """One entry per channel: None, or why its data cannot be fitted.

    Only the channels whose `sums` (the record fingerprint) are not finite
    are searched: a finite sum means finite samples.
    """
    errors = [None] * Y.shape[1]
    for c in np.flatnonzero(~np.isfinite(sums).all(axis=0)):
        for name, arr in (("y", Y[:, c]), ("u", U[:, c])):
            bad = ~np.isfinite(arr)
            if not bad.any():
                continue
            where = np.argwhere(bad)[0]
            index = (int(where[0]), int(c)) if arr.ndim == 1 or U.shape[2] == 1 else (
                int(where[0]), int(c), int(where[1]))
            value = arr[tuple(where)]
            msg = (f"`{name}` must be finite; got {value} at index {index} (channel "
                   f"{labels[c]!r})")
            if on_error == "raise":
                raise ValueError(msg)
            errors[c] = msg
            break
    return errors


def _fail(out, c, labels, message, on_error):
    if on_error == "raise":
        raise ValueError(f"channel {labels[c]!r}: {message}")
    out.errors[c] = message


def _tune_channels(rec, per_channel, todo, chunk, buffer, param, C, units, given_P0):
    """Maximum likelihood of every fitted channel's ``lam`` or ``q`` on its regressor rows
    (`RLSBank.tune`, the first ``n_params`` innovations left out) in the channel's
    power-of-two `units` (`rec` scaled by them), from the exact images of ``P0 / R``,
    ``Q / R`` and ``x0`` there (`tune_start`: as `ARX.fit` tunes each channel); sets the
    estimates in `per_channel` and its bank (``Q = q R I`` in the record's units: its
    image in the signals' units, and ``"Q_scaled"`` for `_ChannelUnits.bank`) and returns
    the `BankTuneResult` (``R`` in the signals' units; channels not fitted: NaN)."""
    from ..filters.tuning import BankTuneResult, TuneResult

    s, bank = rec.s, per_channel["bank"]
    n = s.n_params
    c, R = units.columns(), bank.R
    P, Q = tune_start(c, per_channel["P0"] / R[:, None, None],
                      per_channel["Q"] / R[:, None, None], given_P0)
    with np.errstate(over="ignore", under="ignore"):
        x0 = np.ldexp(per_channel["x0"], -units.theta())
    if not np.isfinite(x0).all():
        raise ValueError("`x0` must have b coefficients of the size the record's units "
                         "allow (|b| up to about max|y| / max|u| times 1e300); got "
                         "coefficients that overflow")
    scaled = RLSBank(C, bank.dim_x, bank.lam, R=1.0, Q=Q, P0=P, x0=x0, **per_channel["filter"])
    nan = TuneResult(param, np.nan, np.nan, np.nan, np.nan, False, False, 0, 0,
                     _log_stderr=np.nan)
    results = [nan] * C
    for start in range(0, C, chunk):
        cs = todo[(todo >= start) & (todo < start + chunk)]
        if not cs.size:
            continue
        cs, sel = _as_slice(cs)
        norms = np.empty((cs.size, n))
        Phi, target = _regressors(rec.U, rec.Y, s, sel, buffer, norms)
        fits = subset(scaled, cs).tune(target, Phi, param, burn=n)
        for j, ch in enumerate(cs):
            results[ch] = fits.channel(j)
            with np.errstate(over="ignore", under="ignore"):    # R in the signals' units
                results[ch].R = float(np.ldexp(results[ch].R, 2 * units.ey[ch]))
    est = np.array([r.estimate for r in results])
    fitted = ~np.isnan(est)
    if param == "lam":
        lam = bank.lam.copy()
        lam[fitted] = est[fitted]
        bank.lam = lam
    else:
        Q, Qs = bank.Q.copy(), np.zeros_like(bank.Q)
        Qs[fitted], Q[fitted] = tuned_random_walk(est[fitted], R[fitted], c[fitted])
        bank.Q = Q
        per_channel.update(Q_scaled=Qs, Q_columns=c)
    per_channel.update(lam=bank.lam, Q=bank.Q)
    return BankTuneResult(results)


def _rls_options(C, n, method, opts, filter_options):
    """Per-channel filter options, validated and normalized by an `RLSBank`."""
    if method != "rls":
        return {}
    kw = {key: opts[key] for key in ("lam", "R", "Q", "P0", "x0") if opts[key] is not None}
    proto = RLSBank(C, n, **kw, **filter_options)
    # (a new bank's state is its start: P = P0, x = x0)
    return {"lam": proto.lam, "R": proto.R, "Q": proto.Q, "P0": proto.P.copy(),
            "x0": proto.x.copy(),
            "filter": dict(filter_options), "bank": proto,
            "prior": opts["P0"] is not None or opts["x0"] is not None}


def _gradient_options(C, n, method, x0, options):
    """Per-channel ``mu``, ``eps``, ``leak`` and ``x0`` of a gradient `method`, validated
    by a `GradientBank` (scalars or one per channel; its defaults those of `NLMS`/`LMS`)."""
    defaults = {"mu": 0.1 if method == "nlms" else 0.01, "eps": 0.001, "leak": 0.0}
    kw = defaults | dict(options)
    proto = GradientBank(C, n, kw["mu"], method=method, eps=kw["eps"], leak=kw["leak"],
                         x0=x0)
    return {"mu": proto.mu, "eps": proto.eps, "leak": proto.leak, "x0": proto.x.copy()}


def _check_gradient_options(method, given, options):
    """Refuse the least-squares options and anything but ``mu``, ``leak`` (and ``eps`` for
    ``"nlms"``) for a gradient `method`."""
    valid = ["mu", "leak"] + (["eps"] if method == "nlms" else [])
    for name in list(given) + list(options):
        if name not in valid:
            raise TypeError(f"`{name}` is not an option of method={method!r}; its options are "
                            f"{valid + ['x0']}")


def _check_filter_options(options):
    """Reject keywords that `RLSBank` does not take, naming the valid ones."""
    params = inspect.signature(RLSBank).parameters
    valid = [name for name, p in params.items()
             if p.kind == p.KEYWORD_ONLY and name not in ("Q", "R", "P0", "x0")]
    for name in options:
        if name not in valid:
            raise TypeError(f"`{name}` is not an option of fit_many or RLSBank; the filter's "
                            f"other options are {valid}")


def _param_names(s):
    names = [f"a{k}" for k in range(1, s.na + 1)]
    for j in range(s.n_inputs):
        tag = "" if s.n_inputs == 1 else f"[u{j + 1}]"
        names += [f"b{k}{tag}" for k in range(1, s.nb[j] + 1)]
    return names


def _one_blas_thread():
    """One BLAS thread while fitting, with threadpoolctl if installed.

    The stacked QR factorizations and products of small matrices that
    `fit_many` makes are slower with a threaded BLAS (measured: 12 s instead
    of 0.9 s for the residual tests of 500 channels on a busy 2-core machine).
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:
        return contextlib.nullcontext()
    return threadpool_limits(limits=1, user_api="blas")


def _progress_bar(progress, total):
    if not progress:
        return None
    try:
        from tqdm.auto import tqdm
    except ImportError:
        raise ImportError("`progress=True` needs tqdm: pip install tqdm") from None
    return tqdm(total=total, unit="channel", desc="fit_many")

