r"""ARX models: the estimator (batch and recursive least squares) and its parameter layout.

This is the one module that knows how ``theta_`` is laid out (``_split``,
``param_names_``, the difference equation); everything generic comes from
`IdentifiedModel`: conversion to python-control and scipy
(:mod:`._conversion`, from :meth:`ARX.polydata`), the summary table
(:mod:`._summary`) and polynomial algebra (:mod:`._polynomials`).

`ARX` is an estimator in the scikit-learn manner (``__init__`` stores the
orders, ``fit`` returns ``self``, learned quantities end in ``_``) for the
model of MATLAB's System Identification Toolbox; its docstring holds the
convention and the translation table to SIPPY and the lecture notes.
"""

import html
import inspect
import warnings

import numpy as np

from .._resources import check_memory
from .._scale import pow2_exponent, pow2_factors, safe_norm, times_pow2
from .._serialize import jsonable
from .._validation import (
    as_float_array,
    check_covariance,
    check_finite,
    check_int,
    check_scalar,
)
from ..exceptions import InsufficientDataError, NumericalWarning
from ..filters import RecursiveLeastSquares, SquareRootRLS
from . import _arx_online as _online
from . import _conversion
from ._arx_iv import check_options as check_iv_options
from ._arx_iv import fit_arx_iv
from ._base import IdentifiedModel, Polynomials
from ._lag_rows import LagRows, MatrixRows
from ._offset import offset_mode as _offset_mode
from ._offset import record_means, warn_fit_operating_point
from ._summary import EQUATION_STYLES, ModelSummary
from ._tuning_option import tuning_param
from ._units import (
    RecordUnits,
    equivariant_forgetting,
    estimate_in_units,
    tune_start,
    tuned_random_walk,
)
from .regressors import (
    _as_signal,
    _build,
    _full_rank_rows,
    arx_structure,
    as_records,
)

__all__ = ["ARX", "ARXSummary"]


class ARX(IdentifiedModel):
    r"""ARX model ``A(q) y(t) = B(q) u(t - nk) + e(t)`` fitted by batch or recursive least squares.

    Parameters
    ----------
    na : int
        Number of past outputs (``>= 0``; ``0`` is an FIR model).
    nb : int or sequence of int
        Number of input coefficients (``>= 1``), a scalar or one per input.
    nk : int or sequence of int, default 1
        Input delay in samples (``>= 0``); ``0`` gives direct feed-through.
        A scalar or one per input.
    dt : True or float, default True
        Sampling period, passed to python-control and scipy (``True``:
        discrete time with an unspecified period).
    offset : {False, True, "mean"}, default False
        Operating point handling. ``True`` estimates an intercept ``c``
        (``A(q) y = B(q) u + c + e``, the last entry ``"c"`` of ``theta_``,
        batch and recursive); ``"mean"`` removes the means of the estimation
        record before the fit. Either way the model keeps its operating point
        (``input_offset_``, ``output_offset_``) and predicts and simulates in
        the units of the data; ``False`` means the data are already centred
        (see :func:`rlsfilt.detrend`).

    Attributes
    ----------
    theta_ : ndarray, shape (n_params,) or (n_params, ny)
        Parameter vector in regressor order (see :meth:`regressors`); one
        column per output when `y` was 2-D.
    a_ : ndarray
        ``[a1, ..., a_na]`` (without the leading 1) of shape ``(na,)`` when
        `y` was 1-D; for 2-D `y`, shape ``(ny, ny, na)`` with ``a_[i, j, k-1]``
        the coefficient of ``y_j(t-k)`` in the equation of output ``i``.
    b_ : ndarray or list of ndarray
        ``[b1, ..., b_nb]`` with ``b1`` multiplying ``u(t-nk)``: shape
        ``(nb,)`` (1-D `y`) or ``(ny, nb)`` (2-D `y`); a list of such arrays,
        one per input, when `u` was 2-D.
    theta_cov_ : ndarray, shape (n_params, n_params) or (ny, n_params, n_params)
        Parameter covariance :math:`\hat\sigma^2 (\Phi^T\Phi)^{-1}`, one per
        output (the outputs share :math:`\Phi`); for ``"iv"``/``"riv"`` the
        IV covariance under coloured equation error (a long-AR model of the
        residuals; see :doc:`/guide/model-family`).
    noise_variance_ : float or ndarray of shape (ny,)
        Unbiased residual variance :math:`\hat\sigma^2 = \|y - \Phi\hat\theta\|^2
        / (N_{rows} - n_{params})` (NaN when there are no spare equations).
    noise_covariance_ : ndarray, shape (ny, ny)
        2-D `y` only: unbiased covariance of the residuals of the outputs
        (its diagonal is ``noise_variance_``); the covariance of
        ``vec(theta_)`` is ``kron(noise_covariance_, (Phi^T Phi)^-1)``.
    residuals_ : ndarray, shape ``(n_samples_,)`` or ``(n_samples_, ny)``
        ``target - Phi @ theta_`` on the fitted rows.
    n_samples_ : int
        Number of equations (rows of ``Phi``) used: ``N - max_lag``.
    n_params_ : int
        Number of parameters per output, ``ny * na + sum(nb)``.
    n_inputs_, n_outputs_ : int
        Number of input and output signals.
    n_experiments_ : int
        Number of experiments of the record (regressor rows never straddle
        two of them).
    input_offset_, output_offset_ : ndarray, shapes (nu,) and (ny,)
        The operating point the model's dynamics are about: zero without
        `offset`; the estimation means for ``"mean"``; for ``True`` the mean
        input and the equilibrium output there,
        :math:`A(1)^{-1}(c + B(1)\bar u)`.
    intercept_ : float or ndarray of shape (ny,)
        ``offset=True`` only: the estimated ``c``.
    input_names_, output_names_, input_units_, output_units_ : tuple of str
        Signal names (from pandas or an `IOData`, else ``u``, ``y``, ...)
        and units (``""`` when unknown).
    method_ : str
        ``"ls"``, ``"rls"``, ``"iv"``, ``"riv"``, ``"nlms"`` or ``"lms"``.
    theta_history_ : ndarray, shape ``(n_samples_, n_params[, ny])``
        ``method="rls"``, ``"riv"``, ``"nlms"`` or ``"lms"`` only: the
        estimate after each row; rows
        before the batch start (``k0 - 1``) are NaN.
    instruments_ : ndarray, shape ``(n_samples_, n_z)``
        ``method="iv"`` or ``"riv"`` only: the instrument rows used (for
        ``"model"`` instruments with the prefilter, prefiltered).
    recursive_residuals_ : ndarray, shape ``(n_samples_,)`` or ``(n_samples_, ny)``
        ``method="rls"`` (and the gradient methods) only: the a-priori residuals
        :math:`y(t) - \varphi(t)\hat\theta(t-1)`, the errors the filter
        actually made (NaN for the rows of the batch start). Under forgetting
        these, not ``residuals_``, show how well the model tracked.
    k0_ : int
        ``method="rls"`` only: number of rows of the batch start (0 for the
        gradient methods).
    lam_ : float or ndarray
        ``method="rls"`` only: the forgetting factor used (one per parameter,
        shape ``(n_params,)``, with ``forgetting="diagonal"``).
    tune_ : TuneResult
        ``method="rls"`` with ``lam="tune"`` or ``Q="tune"`` only: the
        maximum-likelihood estimate (`rlsfilt.filters.tuning.TuneResult`:
        estimate, standard error, interval, profile plot) of the tune in the
        record's power-of-two units (``R`` mapped to the signals' units; see
        `fit`). For ``Q="tune"``, ``filter_.Q`` is the random walk the fit ran
        (``tune_.apply(filt)`` sets its image in the signals' units,
        ``R diag(q 2^(-2 c_k))`` with the estimated ``R``: ``tune_.Q_shape``).
    form_ : str
        ``method="rls"`` only: ``"covariance"``, ``"square_root"`` or
        ``"window"`` (`SlidingWindowRLS`), the recursion that ran (see `form`
        and `window` of :meth:`fit`).
    filter_ : RecursiveLeastSquares, SquareRootRLS, SlidingWindowRLS, NLMS or LMS
        ``method="rls"``, ``"nlms"``, ``"lms"`` only: the filter after the
        last sample, ready for
        more ``predict``/``update`` calls (not kept by a saved model).

    Notes
    -----
    **Convention** (MATLAB's ``arx(data, [na nb nk])``), for one input:

    .. math::

        y(t) + a_1 y(t-1) + \dots + a_{n_a} y(t-n_a)
            = b_1 u(t-n_k) + \dots + b_{n_b} u(t-n_k-n_b+1) + e(t),

    i.e. :math:`A(q) y(t) = B(q) u(t) + e(t)` with
    :math:`A(q) = 1 + a_1 q^{-1} + \dots` and
    :math:`B(q) = q^{-n_k}(b_1 + b_2 q^{-1} + \dots)`. Translation table:

    ==================  ===========================  ==========================  ==================
    quantity            rlsfilt and MATLAB           SIPPY                       lecture notes
    ==================  ===========================  ==========================  ==================
    orders              ``na, nb, nk``               ``[na, nb, theta]``         ``n`` (``m = n``)
    delay               ``nk``: first term u(t-nk)   ``theta = nk - 1``          none: ``b0 u[k]``
    b numbering         ``b1 .. b_nb``               ``b1 .. b_nb``              ``b0 .. bn`` = our
                                                                                 ``b1 .. b_(n+1)``
    the notes' model    ``ARX(n, n + 1, nk=0)``      not expressible (theta=-1)  order ``n``
    sampled plant       ``ARX(2, 2, nk=1)``          ``[2, 2, 0]``               needs ``b0 = 0``
    MATLAB ``B``        ``[zeros(1, nk), b1 ..]``    ``NUMERATOR``               --
    ==================  ===========================  ==========================  ==================

    The model in regression form is :math:`y(t) = \varphi(t)\theta + e(t)`
    with

    .. math::

        \varphi(t) = [-y(t-1), \dots, -y(t-n_a), u(t-n_k), \dots,
        u(t-n_k-n_b+1)],

    one ``-y`` block per output followed by one ``u`` block per input, for
    :math:`t = t_0 \dots N-1`, :math:`t_0 = \max(n_a, n_k + n_b - 1)`. The
    lecture notes' model :math:`\hat y[k] = -a_1 y[k-1] - \dots - a_n y[k-n]
    + b_0 u[k] + \dots + b_n u[k-n]` is ``ARX(na=n, nb=n + 1, nk=0)``; its
    ``b0`` is our ``b1``.

    ``method="ls"`` solves :math:`\min\|\Phi\theta - Y\|` through the QR
    factorization :math:`\Phi = Q_1 R_1` (:math:`\hat\theta = R_1^{-1}Q_1^TY`,
    :math:`(\Phi^T\Phi)^{-1} = R_1^{-1}R_1^{-T}`), never through the normal
    equations. ``method="rls"`` runs `RecursiveLeastSquares`, started by
    batch least squares on the first ``k0`` rows as in the lecture notes;
    with ``lam = 1`` it ends at the batch answer. Under white equation error
    the estimate is consistent; with colored noise it is biased (Ljung 1999,
    sec. 8.3), which the colored-noise datasets of `rlsfilt.datasets` show.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 4.2 and 7.3.
    .. [2] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 2.

    Examples
    --------
    Identify ``y(t) - 1.5 y(t-1) + 0.7 y(t-2) = u(t-1) + 0.5 u(t-2) + e(t)``:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import ARX
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(2000)
    >>> e = 0.05 * rng.standard_normal(2000)
    >>> y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1], [1, -1.5, 0.7], e)
    >>> model = ARX(na=2, nb=2, nk=1).fit(u, y)
    >>> np.round(model.a_, 2), np.round(model.b_, 2)
    (array([-1.5,  0.7]), array([1. , 0.5]))
    """

    # learned attributes that only some fits set, and which ones
    _ONLY_SET_BY = {**{name: "fit(..., method='rls')" for name in ("lam_", "form_")},
                    "tune_": "fit(..., method='rls', lam='tune' or Q='tune')",
                    "filter_": "fit(..., method='rls', 'nlms' or 'lms')",
                    **{name: "fit(..., method='rls', 'riv', 'nlms' or 'lms')" for name in
                       ("theta_history_", "recursive_residuals_", "k0_")},
                    "instruments_": "fit(..., method='iv' or 'riv')",
                    "noise_covariance_": "a fit on 2-D `y` (several outputs)"}

    # the name a model file stores (rlsfilt.persistence: a closed set, not inherited)
    _FILE_NAME = "ARX"

    def __init__(self, na, nb, nk=1, dt=True, offset=False):
        self.na = na
        self.nb = nb
        self.nk = nk
        self.dt = dt
        self.offset = offset

    # ------------------------------------------------------------------
    # structure
    # ------------------------------------------------------------------
    def _structure(self, n_inputs, n_outputs):
        self._check_dt()
        _offset_mode(self.offset)
        return arx_structure(self.na, self.nb, self.nk, n_inputs, n_outputs)

    def regressors(self, u, y=None):
        r"""Regressor matrix and target for this model's orders.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu), or IOData
            Input record (time on axis 0; pandas works too), or an `IOData`
            holding inputs and outputs (then `y` is omitted).
        y : array_like, shape (N,) or (N, ny)
            Output record.

        Returns
        -------
        Phi : ndarray, shape (N - max_lag, n_params)
            Rows :math:`\varphi(t)` for ``t = max_lag .. N-1``: blocks
            ``-y_1 .. -y_ny`` then ``u_1 .. u_nu``, each by increasing lag,
            ``[-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1)]``, and a last
            column of ones with ``offset=True``. With ``offset="mean"`` the
            rows are built from the deviations from the operating point (the
            fitted one, or the record's means before a fit). Several
            experiments give their rows one after the other (no row
            straddles two experiments).
        target : ndarray, shape (N - max_lag,) or (N - max_lag, ny)
            ``y(t)`` on the same rows (minus the operating point for
            ``offset="mean"``).
        """
        records, info = as_records(u, y)
        s = self._structure(records[0][0].shape[1], records[0][1].shape[1])
        if _offset_mode(self.offset) == "mean":
            op = self._fitted_op() if "theta_" in self.__dict__ else _means(records)
        else:
            op = None
        Phi, target = self._design(records, s, op)
        return Phi, (target[:, 0] if info["y_1d"] else target).copy()

    def _design(self, records, s, op=None):
        """``(Phi, target)`` stacked over the experiments; rows ``max_lag..N_i-1`` of each.

        `op` is ``(u_op, y_op)`` to subtract first (``offset="mean"``).
        """
        Phis, targets = [], []
        for U, Y in records:
            if op is not None:
                U, Y = U - op[0], Y - op[1]
            Phi = _build(U, Y, s, s.max_lag)
            if _offset_mode(self.offset) == "intercept":
                Phi = np.hstack([Phi, np.ones((len(Phi), 1))])
            Phis.append(Phi)
            targets.append(Y[s.max_lag:])
        if len(Phis) == 1:           # Phi is a new array already; the target may be a view
            return Phis[0], targets[0].copy()
        return np.vstack(Phis), np.vstack(targets)

    # ------------------------------------------------------------------
    # fitting
    # ------------------------------------------------------------------
    def fit(self, u, y=None, method="ls", *, k0=None, lam=None, P0=None, R=None, Q=None,
            x0=None, form=None, window=None, **filter_options):
        r"""Estimate the parameters from an input/output record.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu), or IOData
            Input record; pandas Series/DataFrame work too. Or an `IOData`
            (then `y` is omitted), or a list of input arrays, one per
            experiment.
        y : array_like, shape (N,) or (N, ny), or a list of them
            Output record, same length (a list: one per experiment).
        method : {"ls", "rls", "iv", "riv", "nlms", "lms"}, default "ls"
            ``"ls"``: batch least squares through QR. ``"rls"``:
            `RecursiveLeastSquares` over the rows, started by batch least
            squares on the first `k0` rows (with `window`: least squares over
            the last `window` rows). ``"nlms"``, ``"lms"``: the gradient
            filters `NLMS` and `LMS` over the rows from `x0` (zeros), MATLAB's
            'NormalizedGradient' and 'Gradient' estimation methods (options
            ``mu``, ``leak`` and, for ``"nlms"``, ``eps``; in the signals'
            units; ``theta_cov_`` is NaN: a gradient estimate has no
            covariance). ``"iv"``, ``"riv"``: batch and
            recursive instrumental variables, unbiased under coloured
            equation error (options ``instruments`` = ``"model"`` (refined
            IV with an auxiliary model, the default for one output),
            ``"delayed"`` or an ``(N, n_z)`` array of instrument rows;
            ``prefilter``; ``n_iter`` for ``"iv"``; ``k0``, ``lam``, ``P0``,
            ``R``, ``Q``, ``x0``, ``refresh`` for ``"riv"``; see
            :doc:`/guide/model-family`).
        k0 : int, optional
            ``"rls"`` only: number of rows of the batch start. By default
            ``n_params`` (the lecture notes' choice), or, when those first
            rows do not determine every parameter (for example a PRBS held
            for several samples), the fewest leading rows that do. ``0``
            starts from the prior ``x0``, ``P0`` instead (MATLAB ``rarx``);
            that is the default when `P0` or `x0` is given.
        lam, P0, R, Q, x0
            ``"rls"`` only: passed to `RecursiveLeastSquares` (forgetting
            factor, initial covariance and estimate for a prior start with
            ``k0 = 0``, noise variance, random-walk covariance), in the
            signals' units, as their defaults (``P0 = 1e4 I``, ``R = 1``,
            MATLAB's ``rarx``). The batch start does not depend on the units;
            a prior start is the same fit for a record in other units only
            with ``P0 / R`` (and ``Q / R``) in those units. ``lam="tune"`` or
            ``Q="tune"`` (one of them): estimate it first by maximum likelihood
            on the model's regressor rows (`rlsfilt.filters.tuning.tune` of a
            `RecursiveLeastSquares` with the other options, from its prior
            ``x0``, ``P0``, the first ``n_params`` innovations left out of the
            likelihood), then fit with the estimate; the result is ``tune_``.
            The tune runs in the record's power-of-two units, as the fit
            (Notes), from the exact images of ``x0``, ``P0 / R`` and (for
            ``lam``) ``Q / R``: a record scaled by ``2^k`` tunes to the same
            bits. Without `P0` its prior is ``P0 / R = 1e4 I`` of the record
            scaled to unit size (diffuse at any scale). ``Q="tune"`` is
            ``Q = q R I`` in those units, isotropic relative to each
            regressor column's scale (so that it does not depend on the units
            of ``u`` and ``y``), ``Q_kl = 2^-(c_k + c_l) q R`` in the
            signals' units (``filter_.Q``; a ValueError naming ``Q`` and ``R``
            where a filter there cannot hold it, for signals far below unit
            size). ``tune_.R`` is in the signals' units, ``tune_.loglik``
            (and ``tune_.profile``) those of the record at unit size. With
            ``forgetting="diagonal"`` (passed to the filter) `lam` may be one
            factor per parameter, an array of
            shape ``(n_params,)`` in ``param_names_`` order (a diagonal
            forgetting, :math:`P^- = L^{-1/2} P L^{-1/2} + Q`); its batch
            start does not weight the rows.
        form : {"auto", "covariance", "square_root"}, optional
            ``"rls"`` only: the recursion. ``"covariance"`` is
            `RecursiveLeastSquares` (updates ``P``); ``"square_root"`` is
            `SquareRootRLS` (updates a triangular square root of the
            information matrix by orthogonal rotations: its round-off grows
            with the condition number of the regressors, not its square).
            ``"auto"`` (the default) takes the square-root form when the
            regressors (columns scaled to unit norm) have a condition number
            above 1e4 and the options allow it (no `Q`, no other forgetting
            mode), so that the recursive fit stays within about 1e-8
            (relative) of batch least squares up to condition numbers of
            1e8.
        window : int, optional
            ``"rls"`` only: finite history (MATLAB's ``History = 'Finite'``,
            ``WindowLength``): `SlidingWindowRLS` over the last `window` rows
            (at least ``n_params``), so that the estimate after each row is
            batch least squares on the last `window` rows (fewer at the
            start); options `k0` (at most `window`), `P0`, `R`, `x0` (in the
            signals' units) and the filter's `refresh`. The window runs in
            the record's power-of-two units as the other methods (Notes);
            ``filter_`` is a `SlidingWindowRLS` in the signals' units
            holding the final window. ``theta_cov_`` is that of the last
            window, ``form_`` is ``"window"``.
        **filter_options
            ``"rls"`` only: any other keyword argument of
            `RecursiveLeastSquares` (for example its forgetting mode), passed
            through unchanged.

        Returns
        -------
        self : ARX

        Raises
        ------
        ValueError
            NaN/inf in the data (the first bad index is named), mismatched
            lengths, bad orders, too few samples, or a regressor matrix
            without full column rank (input not persistently exciting);
            ``u`` and ``y`` in units whose ratio makes a ``b`` coefficient
            exceed the double range (every method; the message names both);
            a recursive prior start whose ``P0`` (the default for signals
            around 1e160) is too diffuse for double precision in the
            record's units, or whose ``R`` is outside the recursion's range
            there (the message names it and the scale).
        MemoryError
            When the regressor matrix and the factorization would need more
            memory than the process can get (checked before they are built).

        Warns
        -----
        NumericalWarning
            ``"rls"`` on ill-conditioned regressors when the accuracy of the
            recursion cannot be guaranteed: the covariance form (asked for,
            or forced by `Q` or a forgetting mode) above a condition number
            of 1e6, or any form above 1e10. ``"rls"``/``"riv"`` with a prior
            start from the default ``P0`` when it outweighs the data
            (signals far below unit size).
        OperatingPointWarning
            ``offset=False`` on a record around an operating point: a signal's
            mean above 5 standard deviations with no sample reaching zero
            (the rule :func:`~rlsfilt.validation.validate` applies too). The
            fit then mostly describes the operating point; fit with
            ``offset=True`` or ``"mean"``, or detrend the record first.

        Notes
        -----
        Every method runs on the record scaled to unit size (each signal
        divided by a power of two near its largest entry; the columns of
        :math:`\Phi` for ``"ls"``) and maps the results back exactly:
        records around :math:`10^{\pm 160}`, whose sums of squares leave
        the double range, give the fit of the same record at unit size, in
        their units. The recursions run from the exact images of ``P0``,
        ``R``, ``Q``, ``x0`` in the scaled units: the same numbers, bit for
        bit, as the recursion in the signals' units wherever that stays in
        the double range (:mod:`rlsfilt.models._units`), and ``filter_``
        holds the final state in the signals' units (``P`` over- or
        underflows there for records around :math:`10^{\pm 160}`: continue
        such a record with the square-root form, whose factor stays in
        range; with `window`, whose ``filter_`` then has ``inf`` or
        subnormal entries of ``P``, refit the record instead of continuing
        the filter). Forgetting modes with constants that bound ``trace(P)``
        (``"constant_trace"``, ``"efra"``, ``"variable"``, an explicit
        ``trace_max``) run in the signals' units.

        With ``method="rls"``, ``theta_`` is the filter's last estimate and
        ``theta_cov_`` is ``noise_variance_ * P / R``, its covariance; with
        ``lam = 1``, ``Q = 0`` and a batch start both equal the batch answer.
        With forgetting they describe the exponentially weighted fit at the
        end of the record, while ``noise_variance_`` (residuals of the final
        estimate over all rows) overstates the noise if the plant changed.
        """
        if method not in ("ls", "rls", "iv", "riv", *_online.GRADIENT):
            raise ValueError("`method` must be 'ls', 'rls', 'iv', 'riv', 'nlms' or 'lms'; got "
                             f"{method!r}")
        tuning = tuning_param(method, lam, Q, "ARX.fit")
        opts = {"k0": k0, "lam": lam, "P0": P0, "R": R, "Q": Q, "x0": x0, "form": form}
        if window is not None and method != "rls":
            raise TypeError(f"`window` only applies to method='rls'; got method={method!r}")
        if method == "ls":
            given = [k for k, v in opts.items() if v is not None] + list(filter_options)
            if given:
                raise TypeError(f"`{given[0]}` only applies to method='rls'; got method='ls'")
        iv_options = {k: v for k, v in opts.items() if v is not None} | filter_options
        if method in _online.GRADIENT:
            given = [k for k, v in opts.items() if v is not None and k != "x0"]
            if given:
                raise TypeError(f"`{given[0]}` does not apply to method={method!r} (a gradient "
                                "method: options `mu`, `leak`, `x0` and, for 'nlms', `eps`)")
            gradient = _online.gradient_options(method, filter_options) | (
                {} if x0 is None else {"x0": x0})
        elif window is not None:
            given = [k for k in ("lam", "Q", "form") if opts[k] is not None] + [
                k for k in filter_options if k not in _online.WINDOW_OPTIONS]
            if given:
                raise TypeError(f"`{given[0]}` does not apply to method='rls' with a `window` "
                                "(options `k0`, `P0`, `R`, `x0`, `refresh`, `check_every`, "
                                "`cond_max`)")
        elif method in ("iv", "riv"):
            check_iv_options(method, iv_options)
        else:
            _check_filter_options(filter_options)
        opts["extra"] = filter_options
        # the recursive fit only reads the record: no copy of it
        records, info = as_records(u, y, copy=method != "rls")
        s = self._structure(records[0][0].shape[1], records[0][1].shape[1])
        n_params = s.n_params + (_offset_mode(self.offset) == "intercept")
        rows = sum(max(len(U) - s.max_lag, 0) for U, _ in records)
        if rows < n_params:
            N = sum(len(U) for U, _ in records)
            per = " (over all experiments)" if len(records) > 1 else ""
            raise InsufficientDataError(
                f"`y` must have at least max_lag + n_params = {s.max_lag} + {n_params} = "
                f"{s.max_lag + n_params} samples{per} for ARX(na={s.na}, nb={_fmt(s.nb)}, "
                f"nk={_fmt(s.nk)}); got {N} (use a longer record or smaller `na`, `nb`, "
                "`nk`)")
        check_memory(_fit_bytes(rows, n_params, s, method),
                     f"ARX.fit(method={method!r}) with {n_params} parameters on `u`, `y` of "
                     f"{sum(len(U) for U, _ in records)} samples")
        warn_fit_operating_point(self, records, (info.get("u_names"), info.get("y_names")),
                                 stacklevel=2)
        op = _means(records) if _offset_mode(self.offset) == "mean" else None
        # compute everything first: a fit that raises leaves the model as it was
        recursive, cov_iv = {}, None
        inv_scaled, col_scale = None, np.ones(n_params)
        direct = method != "rls" or window is not None    # (the rows as one matrix)
        if direct:
            Phi, target = self._design(records, s, op)
        if method in _online.GRADIENT:
            theta, history, prior, filt = _online.run_gradient(Phi, target, method, gradient)
            recursive = {"filter_": filt, "k0_": 0,
                         "theta_history_": history[:, :, 0] if info["y_1d"] else history,
                         "recursive_residuals_": prior[:, 0] if info["y_1d"] else prior}
        elif window is not None:
            if k0 is not None:
                k0 = check_int(k0, "k0", minimum=0)
            else:
                k0 = 0 if (P0 is not None or x0 is not None) else _full_rank_rows(Phi)
                if k0 is None:            # not even all rows determine theta
                    _qr_least_squares(Phi, target)      # raises with the rank in the message
            options = {k: v for k, v in (("P0", P0), ("R", R), ("x0", x0)) if v is not None}
            dev = records if op is None else [(U - op[0], Y - op[1]) for U, Y in records]
            units = RecordUnits(dev, s, intercept=_offset_mode(self.offset) == "intercept")
            theta, inv_scaled, col_scale, history, prior, filt = _online.run_window(
                Phi, target, window, k0, options | filter_options, units)
            recursive = {"filter_": filt, "k0_": k0, "lam_": 1.0, "form_": "window",
                         "theta_history_": history[:, :, 0] if info["y_1d"] else history,
                         "recursive_residuals_": prior[:, 0] if info["y_1d"] else prior}
        elif method == "ls":
            theta, inv_scaled, col_scale = _qr_least_squares(Phi, target,
                                                             _output_lags(s, Phi.shape[1]))
        elif method in ("iv", "riv"):
            dev = records if op is None else [(U - op[0], Y - op[1]) for U, Y in records]
            theta, cov_iv, recursive = fit_arx_iv(
                dev, s, method, iv_options, info["y_1d"],
                intercept=_offset_mode(self.offset) == "intercept")
        else:
            dev = records if op is None else [(U - op[0], Y - op[1]) for U, Y in records]
            intercept = _offset_mode(self.offset) == "intercept"
            units = RecordUnits(dev, s, intercept=intercept)
            tuned = None if tuning is None else self._tune(records, s, op, opts, tuning, units)
            # the rows read from the signals: the regressor matrix only where a path needs it
            lagged = LagRows(dev, s, intercept, lambda: self._design(records, s, op))
            theta, inv_scaled, rls, history, prior, col_scale, k0 = _fit_rls(lagged, s, opts,
                                                                             units)
            # prior: the a-priori (recursive) residuals y(t) - phi(t) theta(t-1) after
            # the batch start
            lam_used = rls.lam.copy() if np.ndim(rls.lam) else float(rls.lam)
            recursive = {"filter_": rls, "k0_": k0, "lam_": lam_used,
                         "form_": "square_root" if isinstance(rls, SquareRootRLS)
                         else "covariance",
                         "theta_history_": history[:, :, 0] if info["y_1d"] else history,
                         "recursive_residuals_": prior[:, 0] if info["y_1d"] else prior}
            if tuned is not None:
                recursive["tune_"] = tuned
        if not direct:               # with the largest residuals (their scale, below)
            resid, top = lagged.residuals(theta)
        else:
            resid, top = target - Phi @ theta, None
        dof = rows - n_params
        sigma2, cov, noise_cov = _noise_and_covariance(resid, dof, inv_scaled, col_scale, top)
        # everything is computed: only now the model changes
        for name in ("theta_history_", "filter_", "k0_", "lam_", "form_", "recursive_residuals_",
                     "tune_", "noise_covariance_", "intercept_", "instruments_", "trend_"):
            self.__dict__.pop(name, None)
        self.__dict__.update(recursive)
        self._store(theta, s, info)
        self._set_operating_point(records, op)
        cov = cov if cov_iv is None else cov_iv
        if cov is None:              # a gradient estimate: no covariance (MATLAB's neither)
            cov = np.full((s.n_outputs, n_params, n_params), np.nan)
        self.theta_cov_ = cov[0] if info["y_1d"] else cov
        self.noise_variance_ = float(sigma2[0]) if info["y_1d"] else sigma2
        if not info["y_1d"]:
            self.noise_covariance_ = noise_cov
        self.residuals_ = resid[:, 0] if info["y_1d"] else resid
        self.n_samples_ = rows
        self.n_experiments_ = len(records)
        self.method_ = method
        return self

    def _tune(self, records, s, op, opts, param, units):
        """Maximum likelihood of `param` (``"lam"`` or ``"q"``) on the regressor rows, by a
        `RecursiveLeastSquares` with the other options, in the record's power-of-two
        `units` (as the fit runs): writes the estimate into `opts` (``Q = q R I`` in the
        record's units, its image in the signals' units, and the former as
        ``"Q_scaled"`` for `_fit_rls`) and returns the `TuneResult` (``R`` mapped to the
        signals' units; ``loglik`` that of the record scaled to unit size)."""
        Phi, target = self._design(records, s, op)
        n = Phi.shape[1]
        kw = {key: opts[key] for key in ("P0", "R", "x0") if opts[key] is not None}
        other = "Q" if param == "lam" else "lam"
        if opts[other] is not None:
            kw[other] = opts[other]
        user = RecursiveLeastSquares(n, dim_z=s.n_outputs, **kw, **opts["extra"])  # validates
        # the rows scaled to unit size: columns by 2^-c, every output by one 2^-e (the
        # likelihood gives the outputs one noise variance: one power of two keeps it so)
        c = units.column_exponents
        e = int(np.max(units.output_exponents))
        P, Q = tune_start(c, user.P if user.R == 1.0 else user.P / user.R, user.Q / user.R,
                          opts["P0"] is not None)
        with np.errstate(over="ignore", under="ignore"):
            x0 = np.ldexp(user.x, c[:, None] - e)
        if not np.isfinite(x0).all():
            raise ValueError("`x0` must have b coefficients of the size the record's units "
                             "allow (|b| up to about max|y| / max|u| times 1e300); got "
                             "coefficients that overflow")
        filt = RecursiveLeastSquares(n, dim_z=s.n_outputs, lam=user.lam, P0=P, Q=Q, x0=x0,
                                     **opts["extra"])
        fit = filt.tune(times_pow2(target, -e), times_pow2(Phi, -c), param, burn=n)
        with np.errstate(over="ignore", under="ignore"):    # R in the signals' units
            fit.R = float(np.ldexp(fit.R, 2 * e))
        if param == "lam":
            opts["lam"] = fit.estimate
        else:
            opts["Q_scaled"], opts["Q"] = tuned_random_walk(fit.estimate, user.R, c)
            with np.errstate(over="ignore", under="ignore"):   # apply(): the fit's Q
                fit.Q_shape = np.ldexp(1.0, -2 * c)
        return fit

    def _store(self, theta, s, info):
        """Set every fitted attribute derived from ``theta`` (n_params, ny)."""
        self.structure_ = s
        self._info = dict(info)
        self.n_params_ = theta.shape[0]
        self.n_inputs_ = s.n_inputs
        self.n_outputs_ = s.n_outputs
        y_1d, u_1d = info["y_1d"], info["u_1d"]
        self.theta_ = theta[:, 0].copy() if y_1d else theta.copy()
        A, self._B = _split(theta, s)
        self._A = A
        self.a_ = A[0, 0].copy() if y_1d else A.copy()
        Bs = [b[0].copy() if y_1d else b.copy() for b in self._B]
        self.b_ = Bs[0] if u_1d else Bs
        self.input_names_ = tuple(self._u_name(j) for j in range(s.n_inputs))
        self.output_names_ = tuple(self._y_name(i) for i in range(s.n_outputs))
        self.input_units_ = tuple(info.get("u_units") or ("",) * s.n_inputs)
        self.output_units_ = tuple(info.get("y_units") or ("",) * s.n_outputs)
        if theta.shape[0] > s.n_params:  # offset=True: the intercept is the last row
            self.intercept_ = float(theta[-1, 0]) if y_1d else theta[-1].copy()
        else:
            self.__dict__.pop("intercept_", None)

    def _restore_fitted(self, fitted):
        """Rebuild a saved model (:func:`rlsfilt.load_model`): attributes and derived caches."""
        missing = [k for k in ("theta_", "structure_", "b_", "input_names_", "output_names_")
                   if k not in fitted]
        if missing:
            raise ValueError(f"the saved ARX model lacks its learned attributes {missing}; "
                             "was it written by ARX.save?")
        theta = np.asarray(fitted["theta_"], dtype=float)
        s = fitted["structure_"]
        y_1d, u_1d = theta.ndim == 1, not isinstance(fitted["b_"], list)
        names = {}
        for key, attr, n, one in (("u", "input", s.n_inputs, u_1d),
                                  ("y", "output", s.n_outputs, y_1d)):
            given = list(fitted[f"{attr}_names_"])
            default = [key] if one else [f"{key}{i + 1}" for i in range(n)]
            names[f"{key}_names"] = None if given == default else given  # None: not named
            names[f"{key}_units"] = list(fitted.get(f"{attr}_units_", [""] * n))
        info = {"u_1d": u_1d, "y_1d": y_1d, **names}
        self._store(theta.reshape(len(theta), -1), s, info)
        for key, value in fitted.items():
            if key not in ("theta_", "a_", "b_", "structure_"):
                setattr(self, key, value)

    def _set_operating_point(self, records, op):
        r"""``input_offset_``, ``output_offset_``: the point the model's deviations are about.

        ``offset=False``: zero. ``offset="mean"``: the means of the
        estimation record. ``offset=True``: the mean input :math:`\bar u` and
        the equilibrium output there, :math:`y_{op} = A(1)^{-1} (c + B(1)
        \bar u)`, so that :math:`A(q)(y - y_{op}) = B(q)(u - \bar u) + e`
        is the same model as :math:`A(q) y = B(q) u + c + e`.
        """
        nu, ny = self.n_inputs_, self.n_outputs_
        if _offset_mode(self.offset) == "mean":
            u_op, y_op = op
        elif _offset_mode(self.offset) == "intercept":
            u_bar, y_bar = _means(records)
            u_op, y_op = _equilibrium(self._A, self._B, np.atleast_1d(self.intercept_), u_bar,
                                      y_bar)
        else:
            u_op, y_op = np.zeros(nu), np.zeros(ny)
        self.input_offset_ = np.asarray(u_op, dtype=float).reshape(nu).copy()
        self.output_offset_ = np.asarray(y_op, dtype=float).reshape(ny).copy()

    def _fitted_op(self):
        return self.input_offset_, self.output_offset_

    # ------------------------------------------------------------------
    # the IdentifiedModel interface: structure, names, polynomials
    # ------------------------------------------------------------------
    @property
    def max_lag(self):
        """``max(na, nk + nb - 1)``: samples lost at the start of a record; needs a fit."""
        self._check_fitted("max_lag")
        return self.structure_.max_lag

    @property
    def param_names_(self):
        """Names of the entries of ``theta_`` (``a1``, ``b2``, ``b1[u2]``, ``a1[y2]``)."""
        self._check_fitted("param_names_")
        s, info = self.structure_, self._info
        names = []
        for j in range(s.n_outputs):
            tag = "" if info["y_1d"] else f"[{self._y_name(j)}]"
            names += [f"a{k}{tag}" for k in range(1, s.na + 1)]
        for j in range(s.n_inputs):
            tag = "" if info["u_1d"] else f"[{self._u_name(j)}]"
            names += [f"b{k}{tag}" for k in range(1, s.nb[j] + 1)]
        if self.n_params_ > s.n_params:
            names.append("c")
        return names

    @property
    def orders_(self):
        """The fitted orders ``{"na": int, "nb": tuple, "nk": tuple}`` (one ``nb``, ``nk`` per
        input), which ``set_params`` after the fit does not change."""
        self._check_fitted("orders_")
        s = self.structure_
        return {"na": s.na, "nb": tuple(s.nb), "nk": tuple(s.nk)}

    def polydata(self, theta=None):
        """The model as MATLAB's polynomials ``A, B, C, D, F`` (``C = D = F = 1``).

        Parameters
        ----------
        theta : array_like, shape of ``theta_``, optional
            Parameters in ``theta_`` order (``theta_`` by default).

        Returns
        -------
        Polynomials
            ``A`` of shape ``(ny, ny, na + 1)``, ``B`` of shape
            ``(ny, nu, max(nk + nb))`` with ``nk`` leading zeros per input,
            and ``C``, ``D``, ``F`` equal to one.

        Examples
        --------
        >>> from rlsfilt import ARX
        >>> p = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=2).polydata()
        >>> p.A[0, 0], p.B[0, 0], p.F[0, 0]
        (array([ 1. , -1.5,  0.7]), array([0. , 0. , 1. , 0.5]), array([1.]))
        """
        self._check_fitted("polydata")
        s = self.structure_
        if theta is None:
            A, B = self._A, self._B
        else:
            theta = np.asarray(theta, dtype=float)
            if theta.size != self.n_params_ * s.n_outputs:
                raise ValueError(f"`theta` must have the shape of `theta_` "
                                 f"{np.shape(self.theta_)}; got {theta.shape}")
            A, B = _split(theta.reshape(self.n_params_, s.n_outputs), s)
        ny, nu = s.n_outputs, s.n_inputs
        Apoly = np.zeros((ny, ny, s.na + 1))
        Apoly[:, :, 0] = np.eye(ny)
        Apoly[:, :, 1:] = A
        lb = max(k + b for k, b in zip(s.nk, s.nb))
        Bpoly = np.zeros((ny, nu, lb))
        for j in range(nu):
            Bpoly[:, j, s.nk[j]:s.nk[j] + s.nb[j]] = B[j]
        return Polynomials(A=Apoly, B=Bpoly, C=np.ones((ny, 1)), D=np.ones((ny, 1)),
                           F=np.ones((ny, nu, 1)))

    def to_dict(self):
        """The fitted model as a JSON-ready dict (see `IdentifiedModel.to_dict`).

        Adds ARX's own fields: ``na``, ``nb``, ``nk`` (lists, one entry per
        input), ``a`` (``a_``), ``b`` (a list of ``b_`` arrays, one per input),
        ``method``, ``lam`` (1 for batch least squares), ``forgetting``
        (the filter's mode, None for ``"ls"`` and for a loaded model),
        ``k0`` (rows of the batch start, None for ``"ls"``), ``offset``,
        ``input_offset``, ``output_offset`` (the operating point),
        ``intercept`` (None without ``offset=True``) and ``n_experiments``.
        """
        out = super().to_dict()
        s = self.structure_
        rls = self.method_ == "rls"
        filt = self.__dict__.get("filter_")
        out.update(jsonable({
            "na": s.na, "nb": s.nb, "nk": s.nk, "a": self.a_,
            "b": self.b_ if isinstance(self.b_, list) else [self.b_],
            "method": self.method_, "lam": self.lam_ if rls else 1.0,
            "forgetting": getattr(filt, "forgetting", "exponential") if filt is not None
            else None,
            "form": self.__dict__.get("form_"),
            "k0": self.k0_ if rls else None,
            "offset": self.offset, "input_offset": self.input_offset_,
            "output_offset": self.output_offset_,
            "intercept": self.__dict__.get("intercept_"),
            "n_experiments": self.__dict__.get("n_experiments_", 1)}))
        return out

    def _theta2(self):
        return self.theta_.reshape(self.n_params_, -1)

    def _input_part(self, U):
        """``sum_j B_j(q) u_j(t)`` with zero inputs before t = 0, shape (N, ny)."""
        s = self.structure_
        Phi0 = _build(U, np.zeros((len(U), s.n_outputs)), s, 0)
        return Phi0 @ self._theta2()[:s.n_params]

    # ------------------------------------------------------------------
    # prediction and simulation
    # ------------------------------------------------------------------
    def predict(self, u, y=None, horizon=1):
        r"""``horizon``-step-ahead prediction (MATLAB ``predict``).

        ``yhat[t]`` is the prediction of ``y(t)`` from the outputs up to
        ``t - horizon`` and the inputs up to ``t``: the model is run
        ``horizon`` steps from the measured past, replacing the unmeasured
        outputs by their own predictions. Signals before ``t = 0`` are taken
        as zero (MATLAB's ``InitialCondition='z'``), so
        ``predict(u, y)[max_lag:] == Phi @ theta_`` on the rows of
        :meth:`regressors`, and a horizon ``>= N`` (or ``np.inf``) is
        :meth:`simulate`.

        With an operating point (``offset`` True or ``"mean"``) the model
        runs on the deviations from it, the past before ``t = 0`` is the
        operating point, and the prediction is in the units of the data.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu), or IOData
            Input record, or an `IOData` (then `y` is omitted).
        y : array_like, shape (N,) or (N, ny)
            Measured outputs.
        horizon : int or np.inf, default 1
            Prediction horizon ``>= 1``.

        Returns
        -------
        yhat : ndarray, shape (N,) or (N, ny)
            (a list of them, one per experiment, for an `IOData` of several).

        Examples
        --------
        Two-step-ahead prediction of ``y(t) = 0.9 y(t-1) + u(t-1)``: from
        ``y(t-2)`` the model first predicts ``y(t-1)``, then ``y(t)``.

        >>> import numpy as np
        >>> from rlsfilt import ARX
        >>> model = ARX.from_polynomials([-0.9], [1.0])
        >>> u = np.array([1.0, 0.0, 0.0, 0.0])
        >>> y = np.array([0.0, 1.0, 1.0, 0.5])   # measured, with disturbances
        >>> model.predict(u, y, horizon=1)
        array([0. , 1. , 0.9, 0.9])
        >>> model.predict(u, y, horizon=2)       # yhat(3) = 0.9 * 0.9 * y(1)
        array([0.  , 1.  , 0.9 , 0.81])
        """
        self._check_fitted("predict")
        return self._each_experiment(self._predict, u, y, horizon)

    def _predict(self, u, y, horizon):
        U, Y = self._data(u, y)
        N = len(U)
        if self._horizon_is_inf(horizon):
            horizon = N
        horizon = check_int(horizon, "horizon", minimum=1)
        if horizon >= N:
            return self._simulate(U, None)
        # deviations from the operating point (zero without an offset); the past before
        # t = 0 is the operating point
        u_op, y_op = self._fitted_op()
        Y = Y - y_op
        bu = self._input_part(U - u_op)
        A, na = self._A, self.structure_.na
        preds = []  # preds[h - 1] is yhat_h; only the last na are needed
        for h in range(1, horizon + 1):
            yh = bu.copy()
            for k in range(1, na + 1):
                src = Y if k >= h else preds[h - k - 1]
                yh[k:] -= src[:-k] @ A[:, :, k - 1].T
            preds.append(yh)
            if len(preds) > na + 1:
                preds[h - na - 2] = None
        return self._shape_out(preds[-1] + y_op)

    def simulate(self, u, y0=None):
        r"""Free-run simulation (MATLAB ``sim``): the output from the input alone.

        Parameters
        ----------
        u : array_like, shape (N,) or (N, nu), or IOData
            Input record (or the inputs of an `IOData`); inputs before
            ``t = 0`` are zero (the operating point for a model with an
            offset, whose simulation then starts at its equilibrium and is in
            the units of the data).
        y0 : array_like, shape (L,) or (L, ny), optional
            Known outputs ``y(0) .. y(L-1)`` (for example ``y[:na]`` of a
            measured record); the simulation continues from ``t = L``. By
            default everything before ``t = 0`` is zero, and the result
            equals ``scipy.signal.lfilter(B, A, u)`` and
            ``control.forced_response(model.to_tf(), T, u)``.

        Returns
        -------
        y_sim : ndarray, shape (N,) or (N, ny)
            (a list of them, one per experiment, for an `IOData` of several).

        Examples
        --------
        >>> import numpy as np
        >>> from rlsfilt import ARX
        >>> model = ARX.from_polynomials([-0.5], [1.0])   # y(t) = 0.5 y(t-1) + u(t-1)
        >>> model.simulate(np.ones(4))
        array([0.  , 1.  , 1.5 , 1.75])
        >>> model.simulate(np.ones(4), y0=[4.0])          # continue from y(0) = 4
        array([4.  , 3.  , 2.5 , 2.25])
        """
        self._check_fitted("simulate")
        return self._each_experiment(self._simulate, u, None, y0, outputs=False)

    def _simulate(self, u, y0):
        from scipy import signal  # lazy: keeps `import rlsfilt` light
        U, _ = self._data(u)
        N, ny = len(U), self.n_outputs_
        u_op, y_op = self._fitted_op()
        bu = self._input_part(U - u_op)
        A, na = self._A, self.structure_.na
        L = 0
        Ysim = np.zeros((N, ny))
        if y0 is not None:
            Y0, _, _ = _as_signal(y0, "y0")
            if Y0.shape[1] != ny:
                raise ValueError(f"`y0` must have {ny} output column(s); got {Y0.shape[1]}")
            L = len(Y0)
            if L > N:
                raise ValueError(f"`y0` must have at most N = {N} samples; got {L}")
            Ysim[:L] = Y0 - y_op
        if ny == 1:
            a = np.concatenate([[1.0], A[0, 0]])
            past = Ysim[max(L - na, 0):L, 0][::-1]
            zi = signal.lfiltic([1.0], a, past) if na else None
            if L < N:
                if zi is None:
                    Ysim[L:, 0] = bu[L:, 0]
                else:
                    Ysim[L:, 0] = signal.lfilter([1.0], a, bu[L:, 0], zi=zi)[0]
        else:
            Ak = [A[:, :, k - 1] for k in range(1, na + 1)]
            for t in range(L, N):
                acc = bu[t].copy()
                for k in range(1, min(na, t) + 1):
                    acc -= Ak[k - 1] @ Ysim[t - k]
                Ysim[t] = acc
        return self._shape_out(Ysim + y_op)

    # ------------------------------------------------------------------
    # polynomials and the python-control / scipy bridge
    # ------------------------------------------------------------------
    def polynomials(self):
        """``(A, B)`` in MATLAB's form, coefficients of ascending powers of ``q^-1``.

        Returns
        -------
        A : ndarray
            Single output and input: ``[1, a1, .., a_na]``; otherwise shape
            ``(ny, ny, na + 1)`` with ``A[:, :, 0]`` the identity.
        B : ndarray
            Single output and input: ``[0]*nk + [b1, .., b_nb]``; otherwise
            shape ``(ny, nu, max(nk + nb))``.

        Examples
        --------
        >>> from rlsfilt import ARX
        >>> A, B = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=2).polynomials()
        >>> A, B
        (array([ 1. , -1.5,  0.7]), array([0. , 0. , 1. , 0.5]))
        """
        self._check_fitted("polynomials")
        p = self.polydata()
        if self._info["y_1d"] and self._info["u_1d"]:
            return p.A[0, 0], p.B[0, 0]
        return p.A, p.B

    # ------------------------------------------------------------------
    # construction from a true plant
    # ------------------------------------------------------------------
    @classmethod
    def from_polynomials(cls, a, b, nk=1, dt=True, noise_variance=0.0):
        """An ARX model with given coefficients (a true plant, no fit).

        Parameters
        ----------
        a : array_like, shape (na,)
            ``[a1, .., a_na]`` **without** the leading 1 (the layout of
            ``a_``); ``[]`` for an FIR model.
        b : array_like, shape (nb,), or a list of them (one per input)
            ``[b1, .., b_nb]``, ``b1`` multiplying ``u(t - nk)`` (the layout
            of ``b_``).
        nk : int or sequence of int, default 1
            Input delay(s).
        dt : True or float, default True
            Sampling period.
        noise_variance : float, default 0.0
            Variance of ``e(t)``, stored as ``noise_variance_``.

        Returns
        -------
        ARX
            A model usable as if fitted (``theta_cov_`` is zero and
            ``n_samples_`` is 0).

        Examples
        --------
        >>> from rlsfilt import ARX
        >>> true = ARX.from_polynomials([-1.5, 0.7], [1.0, 0.5], nk=1, dt=0.1)
        >>> [round(float(abs(p)), 4) for p in true.to_tf().poles()]
        [0.8367, 0.8367]
        """
        a = np.atleast_1d(as_float_array(a, "a"))
        if a.ndim != 1:
            raise ValueError(f"`a` must be 1-D [a1, ..., a_na]; got shape {a.shape}")
        check_finite(a, "a")
        multi = isinstance(b, (list, tuple)) and len(b) > 0 and np.ndim(b[0]) >= 1
        bs = []
        for j, bj in enumerate(b if multi else [b]):
            name = f"b[{j}]" if multi else "b"
            bj = np.atleast_1d(as_float_array(bj, name))
            if bj.ndim != 1 or bj.size == 0:
                raise ValueError(f"`b` must hold 1-D coefficient arrays with nb >= 1; got shape "
                                 f"{bj.shape}" + (f" for input {j}" if multi else ""))
            bs.append(check_finite(bj, name))
        noise_variance = check_scalar(noise_variance, "noise_variance")
        if not (np.isfinite(noise_variance) and noise_variance >= 0.0):
            raise ValueError(f"`noise_variance` must be a finite value >= 0; got {noise_variance}")
        nb = [len(bj) for bj in bs]
        model = cls(na=len(a), nb=nb if multi else nb[0], nk=nk, dt=dt)
        s = model._structure(len(bs), 1)
        theta = np.concatenate([a] + bs).reshape(-1, 1)
        info = {"u_1d": not multi, "y_1d": True, "u_names": None, "y_names": None}
        model._set_truth(theta, s, info, noise_variance)
        return model

    @classmethod
    def from_tf(cls, G):
        """An ARX model with the same input-output behaviour as the discrete plant `G`.

        ``G`` is a discrete ``control.TransferFunction`` (or anything
        ``control.tf`` accepts, such as a ``StateSpace``). Each output's
        entries are put over a common denominator ``A_i``, the product of
        the row's distinct denominators (minimal when they are equal or
        coprime); ``nk`` and ``nb`` per input are read off the numerators
        (leading zeros of ``B`` in powers of ``z^-1`` are the delay). A
        SISO ``G = (b1 z^{n-nk} + ..) / (z^n + a1 z^{n-1} + ..)`` gives
        exactly ``a_ = [a1, ..]``, ``b_ = [b1, ..]`` and that ``nk``.

        Parameters
        ----------
        G : control.TransferFunction or control.StateSpace
            A proper discrete-time system (``dt`` True or a number).

        Returns
        -------
        ARX
            A model usable as if fitted, with ``dt = G.dt``.

        Raises
        ------
        TypeError
            If `G` is not a python-control LTI system.
        ValueError
            If `G` is continuous-time, improper, or has a zero input column.

        Examples
        --------
        A continuous plant sampled with a zero-order hold is ``ARX(2, 2, 1)``:

        >>> import control
        >>> from rlsfilt import ARX
        >>> Gd = control.sample_system(control.tf([1.0], [1.0, 3.0, 2.0]), 0.1)
        >>> model = ARX.from_tf(Gd)
        >>> model.na, model.nb, model.nk
        (2, 2, 1)
        """
        A_rows, B_rows = _conversion.from_tf(G)
        ny, nu = len(B_rows), len(B_rows[0])
        na = max(len(a) for a in A_rows) - 1
        nk, nb = [], []
        for j in range(nu):
            cols = [B_rows[i][j] for i in range(ny)]
            nz = [np.flatnonzero(c) for c in cols]
            if not any(len(z) for z in nz):
                raise ValueError(f"`G` has a zero transfer function from input {j}; an ARX "
                                 "model needs nb >= 1 nonzero input coefficient per input")
            first = min(z[0] for z in nz if len(z))
            last = max(z[-1] for z in nz if len(z))
            nk.append(int(first))
            nb.append(int(last - first + 1))
        s = arx_structure(na, nb, nk, nu, ny)
        theta = np.zeros((s.n_params, ny))
        _, b_sls = s.param_slices()
        for i in range(ny):
            a = A_rows[i][1:]
            theta[i * na:i * na + len(a), i] = a
            for j in range(nu):
                c = np.concatenate([B_rows[i][j], np.zeros(nk[j] + nb[j])])
                theta[b_sls[j], i] = c[nk[j]:nk[j] + nb[j]]
        model = cls(na=na, nb=nb[0] if nu == 1 else nb, nk=nk[0] if nu == 1 else nk, dt=G.dt)
        info = {"u_1d": nu == 1, "y_1d": ny == 1, "u_names": None, "y_names": None}
        model._set_truth(theta, s, info, 0.0)
        return model

    def _set_truth(self, theta, s, info, noise_variance):
        self._store(theta, s, info)
        self._set_operating_point(None, None)
        self.n_experiments_ = 0
        ny = s.n_outputs
        nv = np.broadcast_to(np.asarray(noise_variance, float), (ny,)).copy()
        zero = np.zeros((ny, s.n_params, s.n_params))
        self.theta_cov_ = zero[0] if info["y_1d"] else zero
        self.noise_variance_ = float(nv[0]) if info["y_1d"] else nv
        self.n_samples_ = 0
        self.method_ = "true"

    # ------------------------------------------------------------------
    # display
    # ------------------------------------------------------------------
    def _equation_lines(self, style="text"):
        """The difference equation of each output with +- one standard error.

        `style` is ``"text"``, ``"html"`` (names escaped, ``&plusmn;``) or
        ``"latex"`` (an ``aligned`` row per output).
        """
        s = self.structure_
        se = self.std_errors_.reshape(self.n_params_, -1)
        th = self._theta2()
        _, b_sls = s.param_slices()
        fmt = EQUATION_STYLES[style]
        lines = []
        for i in range(s.n_outputs):
            lhs = [fmt["signal"](self._y_name(i), 0)]
            lhs += [fmt["term"](th[p, i], se[p, i], fmt["signal"](self._y_name(j), k))
                    for j in range(s.n_outputs) for k in range(1, s.na + 1)
                    for p in [j * s.na + k - 1]]
            rhs = [fmt["term"](th[p, i], se[p, i], fmt["signal"](self._u_name(j), s.nk[j] + m))
                   for j in range(s.n_inputs) for m in range(s.nb[j])
                   for p in [b_sls[j].start + m]]
            if self.n_params_ > s.n_params:  # the intercept c, without a signal
                rhs.append(fmt["term"](th[-1, i], se[-1, i], "").rstrip().rstrip("\\,")
                           .rstrip())
            # nb >= 1, so rhs is never empty; its first term carries its sign unspaced
            first = rhs[0][2:] if rhs[0].startswith("+ ") else "-" + rhs[0][2:]
            lines.append(" ".join(lhs) + fmt["equals"] + " ".join([first] + rhs[1:]) + " + e(t)")
        return lines

    def _operating_point_text(self):
        """``flow = 40.08 %, T_out = 96.91 degC`` (empty without an offset)."""
        mode = _offset_mode(self.offset) if "input_offset_" in self.__dict__ else "none"
        if mode == "none":
            return ""
        units = (self._info.get("u_units") or [""] * self.n_inputs_,
                 self._info.get("y_units") or [""] * self.n_outputs_)
        parts = [f"{name} = {v:.6g}" + (f" {unit}" if unit else "")
                 for names, values, unit_list in ((self.input_names_, self.input_offset_,
                                                   units[0]),
                                                  (self.output_names_, self.output_offset_,
                                                   units[1]))
                 for name, v, unit in zip(names, values, unit_list)]
        how = ("equilibrium at the mean input" if mode == "intercept"
               else "means of the estimation record")
        return ", ".join(parts) + f" ({how})"

    def _summary_lines(self, style="text"):
        """Orders, method, noise variance and the difference equation(s) (text or HTML)."""
        s = self.structure_
        nv = ", ".join(f"{v:.4g}" for v in np.atleast_1d(self.noise_variance_))
        op = self._operating_point_text()
        if style == "html":
            esc = html.escape
            return ([f"<p><b>{esc(self._orders_text())}</b>, {self.n_samples_} equations, "
                     f"noise variance {nv}</p>"]
                    + ([f"<p>operating point: {esc(op)}</p>"] if op else [])
                    + [f"<p><code>{line}</code></p>" for line in self._equation_lines("html")])
        how = {"ls": "batch least squares (QR)", "rls": "recursive least squares",
               "iv": "instrumental variables", "riv": "recursive instrumental variables",
               "nlms": "normalized gradient (NLMS)", "lms": "gradient (LMS)",
               "true": "given coefficients (no fit)"}[self.method_]
        if self.method_ == "rls" and self.__dict__.get("form_") == "window":
            how += f" over a window of {self.filter_.window} rows" if "filter_" in \
                self.__dict__ else " over a finite window"
        elif self.method_ == "rls":
            start = (f"batch start on {self.k0_} rows" if self.k0_ else "prior start")
            lam = (np.array2string(np.asarray(self.lam_), precision=4, separator=", ")
                   if np.ndim(self.lam_) else f"{self.lam_:g}")
            how += f" (lam={lam}, {start})"
        n_exp = self.__dict__.get("n_experiments_", 1)
        exps = f" of {n_exp} experiments" if n_exp > 1 else ""
        out = [f"{self._orders_text()}: {s.n_inputs} input(s), {s.n_outputs} output(s), "
               f"{self.n_params_} parameters per output",
               f"  estimated by {how} on {self.n_samples_} equations{exps}",
               f"  noise variance (unbiased): {nv}"]
        if op:
            out.append(f"  operating point: {op}")
        out.append("  difference equation (estimate +/- 1 standard error):")
        out += ["    " + line for line in self._equation_lines()]
        return out

    def summary(self):
        """A printable and notebook-friendly summary: equations and a coefficient table.

        Returns
        -------
        ARXSummary
            ``print`` it for text, or display it in a notebook for HTML;
            the table has statsmodels' columns (``coef``, ``std err``,
            ``t``, ``P>|t|`` and the 95 % interval).
        """
        self._check_fitted("summary")
        return ARXSummary(self)

    def _repr_latex_(self):
        """The difference equation(s) with one standard error, for notebooks."""
        if "theta_" not in self.__dict__:
            return None
        lines = self._equation_lines("latex")
        return "$$\\begin{aligned}" + " \\\\ ".join(lines) + "\\end{aligned}$$"

    def fit_many(self, u, y, method="ls", **options):
        """Fit these orders to every channel of a fleet: :func:`rlsfilt.models.fit_many`."""
        from .fleet import fit_many

        return fit_many(self, u, y, method, **options)


class ARXSummary(ModelSummary):
    """Summary of a fitted `ARX`: ``print`` it, or display it in a notebook.

    The difference equation with one standard error per coefficient, then
    the coefficient table of :class:`~rlsfilt.models.ModelSummary`.

    Attributes
    ----------
    model : ARX
        The summarized model.
    table : dict
        The coefficient table (see :class:`~rlsfilt.models.ModelSummary`).
    """


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _check_filter_options(options):
    """Reject keywords that `RecursiveLeastSquares` does not take, naming the valid ones."""
    if not options:
        return
    params = inspect.signature(RecursiveLeastSquares).parameters
    valid = [name for name, p in params.items()
             if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
             and name not in ("dim_x", "dim_z", "lam", "P0", "x0", "R", "Q")]
    for name in options:
        if name not in valid:
            raise TypeError(f"`{name}` is not an option of ARX.fit or RecursiveLeastSquares; "
                            f"the filter's other options are {valid}")


def _fit_bytes(rows, n, s, method):
    r"""Peak working memory of a fit on `rows` equations with `n` parameters per output
    (measured with tracemalloc, rounded up).

    Batch least squares holds :math:`\Phi`, its scaled copy and the
    orthogonal factor (three ``rows x n`` arrays); the recursive fit adds the
    estimate after every row and the filter's history of means.
    """
    ny, nu = s.n_outputs, s.n_inputs
    per_row = 3 * n + 4 * ny + nu if method in ("ls", "iv") else 4 * n + 3 * n * ny + 6 * ny + nu
    return 8 * rows * per_row


def _fit_rls(rows, s, opts, units):
    """Recursive least squares over the rows: ``(theta, C, filter, history, prior, c, k0)``.

    `rows` is a `LagRows` (the regressor matrix is built only where a path needs it).

    :math:`P / R = C / (c c^T)` as in `_qr_least_squares` (``c`` the powers of two of
    the columns, ones when the recursion ran in the signals' units). ``history``
    (rows, n, ny) is NaN before row ``k0 - 1`` (the batch start's estimate);
    ``prior`` (rows, ny) the a-priori residuals, NaN before row ``k0``.

    The recursion runs on the rows scaled to unit size by `units`, from ``P0``, ``R``,
    ``Q``, ``x0`` mapped into those units: the numbers of the run in the signals' units
    times powers of two wherever both are exact (:mod:`rlsfilt.models._units`), in range
    for records of any size, and with a health check that sees ``P`` of unit-size
    signals. The filter returned, built from the user's options, gets the final state
    in the signals' units (`_hand_over`). Forgetting modes whose constants bound
    ``trace(P)`` or its eigenvalues, and a default prior that outweighs the data (warned
    about), run in the signals' units.
    """
    n, n_rows = rows.shape[1], len(rows)  # an intercept adds a column to the structure's
    prior = opts["P0"] is not None or opts["x0"] is not None
    if opts["k0"] is not None:
        k0 = check_int(opts["k0"], "k0", minimum=0)
    else:  # a given prior means a prior start (MATLAB rarx); else the notes' batch start
        k0 = 0 if prior else _full_rank_rows(rows)
        if k0 is None:  # not even all rows determine theta
            _qr_least_squares(*rows.matrix())  # raises with the rank in the message
    if k0 > n_rows:
        raise ValueError(f"`k0` must be <= the number of regressor rows ({n_rows}); got {k0}")
    if k0 > 0:
        given = [key for key in ("P0", "x0") if opts[key] is not None]
        if given:
            raise ValueError(
                f"`{given[0]}` only applies to a prior start (k0=0); the batch start on "
                f"k0={k0} rows sets both x0 and P0. Pass k0=0 to start from `{given[0]}`.")
    kw = {key: opts[key] for key in ("P0", "R", "Q", "x0") if opts[key] is not None}
    lam = 1.0 if opts["lam"] is None else opts["lam"]
    extra = dict(opts["extra"])
    # (a gate compares every output's residual with one R: outputs in different units
    # keep their own units)
    scaled = equivariant_forgetting(extra.get("forgetting", "exponential"),
                                    extra.get("forgetting_params")) and not (
        extra.get("gate") is not None and len(set(units.output_exponents)) > 1)
    form, cond_raw = _choose_form(rows, opts, -units.column_exponents if scaled else None)
    # cond(P) = cond(Phi)^2 (in the units the recursion runs in) is what the data give (and
    # more on the first rows), and _choose_form has said so: the health check watches for
    # windup beyond
    # (finite: a recursion in the signals' units on columns of very different sizes, an
    # intercept beside signals around 1e-150, has cond_raw^2 beyond the double range)
    with np.errstate(over="ignore"):
        extra.setdefault("cond_max", min(max(1e12, 1e4 * np.float64(cond_raw) ** 2),
                                           np.finfo(float).max))
    cls = SquareRootRLS if form == "square_root" else RecursiveLeastSquares
    user = cls(n, dim_z=s.n_outputs, lam=lam, **kw, **extra)  # validates; becomes filter_
    units.check_ratio()
    x0 = units.start_to_unit(user.x, "x0") if k0 == 0 else None
    # P0, R, Q in the scaled units (see RecordUnits.r_for)
    r = units.r_for(user.R, gate=extra.get("gate") is not None)
    P0 = check_covariance(kw.get("P0", 1e4), n, "P0", definite=True)
    start = units.recursion_start(P0, user.R, user.Q if "Q" in kw else None, r=r,
                                  prior=k0 == 0, default_P0=opts["P0"] is None,
                                  stacklevel=5) if scaled else None
    if start is None:       # the signals' units (a prior the data cannot bear was warned about)
        return (*_run_rls(user, rows, k0), np.ones(n), k0)
    start["x0"] = x0
    if opts.get("Q_scaled") is not None:      # Q="tune": from its value in the record's units
        start["Q"] = np.ldexp(opts["Q_scaled"], r)
    rls = cls(n, dim_z=s.n_outputs, lam=lam, **{k: v for k, v in start.items() if v is not None},
              **extra)
    theta, C, rls, history, prior = _run_rls(rls, rows, k0, units)
    theta = units.estimate_from_unit(theta)
    _hand_over(rls, user, theta, units, r)
    return (theta, C, user, history, prior, np.ldexp(1.0, units.column_exponents), k0)


def _hand_over(rls, user, theta, units, r):
    """Give `user` (the filter built from the user's options) the final state of `rls`,
    which ran in the scaled units with ``R~ = 2^r R``: the estimate `theta` (already
    mapped), ``P`` (over- or underflowing where it is not representable in the signals'
    units), the last step's diagnostics and the counters, so that it continues as the
    filter run in the signals' units would."""
    c = units.column_exponents
    maps = units.diagnostics_from_unit(r)
    state = rls.get_state()                        # the counters and pending decisions
    with np.errstate(over="ignore", under="ignore"):
        if isinstance(rls, SquareRootRLS):
            # the information square root (U^T U = P^-1) maps exactly, U = 2^(r/2) U~ 2^c,
            # and so do its factors U = Delta^-1/2 W: W = 2^-c W~ 2^c,
            # Delta = 2^(-r - 2c) Delta~, and v = W x = 2^(e_y - c) v~
            state["W"] = np.ldexp(state["W"], c[None, :] - c[:, None])
            state["delta"] = np.ldexp(state["delta"], -r - 2 * c)
            state["v"] = np.ldexp(state["v"], units.output_exponents[None, :] - c[:, None])
        else:
            state["P"] = units.P_from_unit(state["P"], r=r)
        state["x"] = theta
        user.set_state(state)
        # the diagnostics are properties over the last update's arrays (RLS) or
        # plain attributes (the square-root form): read them as a user would
        user.set_diagnostics(**{name: f(getattr(rls, name)) for name, f in maps.items()
                                if getattr(rls, name, None) is not None})


def _run_rls(rls, rows, k0, units=None):
    """Run `rls` over `rows` (a `LagRows`): ``(theta, P / R, rls, history, prior)`` (see
    `_fit_rls`).

    With `units` (a `RecordUnits`), `rls` runs in its scaled units and ``history`` and
    ``prior`` come back in the signals' units; ``theta`` and ``P / R`` stay scaled.

    The rows come from validated signals, so the covariance-form filter runs
    them without validating them again, reading them from the signals (with the
    powers of two of the scaled units applied on the fly), writing the
    estimates straight into ``history`` and every residual into ``prior``, in
    the signals' units (no regressor matrix, no copies of the record).
    """
    scales = None if units is None else _scales(units)
    if isinstance(rls, SquareRootRLS) or (units is not None and scales is None):
        return _run_on_copies(rls, *rows.matrix(), k0, units)
    n_rows, n = rows.shape
    ny = rows.n_outputs
    prior = np.empty((n_rows, ny))
    prior[:k0] = np.nan
    if k0 > 0:
        start = (rows[:k0], rows.target(0, k0))
        if units is not None:
            start = units.scale_rows(*start)
        rls.initialize(start[1], start[0])
    if k0 < n_rows:
        Z = rows.target(k0, n_rows)
        Hm, lags = rows.source(k0)
        out = rls.run_record(Z, Hm, lead=max(k0 - 1, 0), residuals=prior[k0:],
                             scales=scales, lags=lags)
        history = out.buffer[1:] if k0 == 0 else out.buffer
    else:                                   # the batch start used every row
        history = np.full((n_rows, n, ny), np.nan)
        history[k0 - 1] = rls.x if units is None else units.theta_from_unit(rls.x)
    return rls.x.copy(), rls.P / rls.R, rls, history, prior


def _scales(units):
    """The powers of two ``(hsc, zsc, msc, ysc)`` that `_kernels.run_batch` applies on the
    fly for a run in the scaled units of `units`, or None where one of them is not a
    double (exponents beyond ``times_pow2``'s multiplication: the run then scales copies)."""
    c, ey = units.column_exponents, units.output_exponents
    scales = [pow2_factors(e) for e in (-c, -ey, ey[None, :] - c[:, None], ey)]
    return None if any(f is None for f in scales) else tuple(scales)


def _run_on_copies(rls, Phi, target, k0, units):
    """`_run_rls` on copies of the rows scaled by `units` (when given), the histories
    mapped back after: the square-root form, and exponents beyond `_scales`."""
    if units is not None:
        Phi, target = units.scale_rows(Phi, target)
    if isinstance(rls, SquareRootRLS):
        theta, C, rls, history, prior = _fit_square_root(rls, Phi, target, k0)
    else:
        theta, C, rls, history, prior = _run_rls(rls, MatrixRows(Phi, target), k0)
    if units is not None:       # history and prior are the run's own arrays: mapped in place
        units.theta_from_unit(history, out=history)
        units.output_from_unit(prior, out=prior)
    return theta, C, rls, history, prior


def _fit_square_root(rls, Phi, target, k0):
    """`_run_rls` with a `SquareRootRLS` (its public ``batch_filter``): the same returns."""
    rows = len(Phi)
    history = np.full((rows, Phi.shape[1], target.shape[1]), np.nan)
    x_start = rls.x.copy()
    if k0 > 0:
        rls.initialize(target[:k0], Phi[:k0])
        history[k0 - 1] = rls.x
    if k0 < rows:
        history[k0:] = rls.batch_filter(target[k0:], Phi[k0:], store_covariances=False)[0]
    # a-priori (recursive) residuals y(t) - phi(t) theta(t-1) after the batch start
    prior = np.full_like(target, np.nan)
    start = k0
    if k0 == 0 and rows:
        prior[0] = target[0] - Phi[0] @ x_start
        start = 1
    prior[start:] = target[start:] - np.einsum("ij,ijk->ik", Phi[start:], history[start - 1:-1])
    return rls.x.copy(), rls.P / rls.R, rls, history, prior


_FORMS = ("auto", "covariance", "square_root")
_SQRT_OPTIONS = {"check_every", "cond_max"}   # what SquareRootRLS takes beyond lam, P0, x0, R
_COND_AUTO = 1e4        # "auto" takes the square-root form above this condition number
_COND_COVARIANCE = 1e6  # the covariance form warns above this
_COND_ANY = 1e10        # any recursion warns above this


def _choose_form(Phi, opts, exponents=None):
    """``(form, cond_raw)``: the recursion to run, and the condition number of the rows in the
    units the recursion runs in, ``Phi`` times ``2^exponents`` column by column (the choice
    itself uses the rows scaled to unit columns).

    The covariance update's round-off grows with cond(P) = cond(Phi)^2, the square-root
    (QR) update's with cond(Phi) (NUMERICS.md; Haykin 2002, ch. 14).
    """
    form = "auto" if opts["form"] is None else opts["form"]
    if not isinstance(form, str) or form not in _FORMS:
        raise ValueError(f"`form` must be 'auto', 'covariance' or 'square_root'; got {form!r}")
    blocked = ["Q"] if opts["Q"] is not None else []
    blocked += [k for k in opts["extra"] if k not in _SQRT_OPTIONS]
    if form == "square_root" and blocked:
        raise TypeError(f"form='square_root' (SquareRootRLS) takes lam, P0, x0, R, check_every "
                        f"and cond_max only; got `{blocked[0]}`")
    cond, cond_raw = _condition_numbers(Phi, exponents)
    if form == "auto":
        form = "square_root" if cond > _COND_AUTO and not blocked else "covariance"
    if form == "covariance" and cond > _COND_COVARIANCE:
        why = (f"`{blocked[0]}` rules out the square-root form" if blocked
               else "form='covariance' was asked for")
        warnings.warn(f"the regressors are ill-conditioned (condition number {cond:.3g}): the "
                      "covariance-form recursion may drift from batch least squares (its "
                      f"round-off grows with {cond:.3g}^2) and {why}; use form='square_root' or "
                      "method='ls'", NumericalWarning, stacklevel=4)
    elif cond > _COND_ANY:
        warnings.warn(f"the regressors are ill-conditioned (condition number {cond:.3g}): even "
                      "the square-root recursion keeps only about "
                      f"{max(0, int(-np.log10(np.finfo(float).eps * cond)))} digits; scale the "
                      "signals, lower the orders or use a richer input", NumericalWarning,
                      stacklevel=4)
    return form, cond_raw


def _condition_numbers(Phi, exponents=None):
    r"""``(cond, cond_raw)``: the condition numbers of `Phi` with its columns scaled to unit
    norm and as it is, or upper bounds of both when those prove ``cond <= _COND_AUTO / 2``
    and ``cond_raw <= 1e4`` (where every decision of `_choose_form` and the health
    check's ``cond_max`` are the same as with the exact values). With `exponents`, those
    of ``Phi 2^exponents`` (column by column), the rows a recursion in scaled units
    runs on, without a scaled copy of the record. `Phi` may be a `LagRows` (the rows
    read from the signals): the Gram matrix of the scaled rows then comes from one
    pass over the signals (`LagRows.gram`), and the exact path builds the matrix.

    The bounds come from the Gram matrix :math:`G = \Phi^T\Phi` (one BLAS call, or one
    pass over the signals, :math:`N n^2` flops): computed in floating point, summed in
    any order, it is :math:`G + E` with
    :math:`|E_{ij}| \le \gamma_N \|\varphi_i\| \|\varphi_j\|` (Higham 2002, ch.
    3; :math:`\gamma_N = N u / (1 - N u)`), so :math:`\|E\|_2 \le \gamma_N
    \operatorname{tr} G` and, by Weyl's theorem, every eigenvalue is within
    :math:`\delta = \gamma_N \operatorname{tr} G` of its exact value;
    :math:`\kappa(\Phi)^2 = \kappa(G) \le (\lambda_{max} + \delta) /
    (\lambda_{min} - \delta)`. Here :math:`\delta` is taken at least 8 times larger, which also
    covers the rounding of the unit scaling, of the eigenvalues and of products in
    the subnormal range. Otherwise (a condition number near or above ``_COND_AUTO``,
    or a Gram matrix that over- or underflows) the exact values come from the QR
    factor of `Phi` with unit columns: the Gram matrix squares the condition number
    and cannot tell 1e6 from 1e7.
    """
    rows, n = Phi.shape
    lagged = isinstance(Phi, LagRows)
    if rows and n:
        with np.errstate(all="ignore"):         # inf or NaN: the exact path below
            # (rows read from the signals: the Gram matrix of the scaled rows at once)
            G = Phi.gram(exponents) if lagged else Phi.T @ Phi
        ok = np.isfinite(G).all() and np.diagonal(G).min() > _GRAM_TINY * rows
        if ok and exponents is not None and not lagged:
            # the Gram matrix of the scaled columns, G_ij 2^(e_i + e_j): exact, but for
            # off-diagonal entries that underflow (errors of 2^-1074, far below the
            # rounding bound while the scaled diagonal passes the same test)
            with np.errstate(under="ignore"):
                G = np.ldexp(G, exponents[:, None] + exponents[None, :])
            ok = np.diagonal(G).min() > _GRAM_TINY * rows
        if ok:
            d = np.diagonal(G)
            s = 1.0 / np.sqrt(d)
            cond, cond_raw = (_cond_bound(M, rows) for M in (G * s[:, None] * s[None, :], G))
            # the form and the warnings read cond, the health check's cond_max =
            # max(1e12, 1e4 cond_raw^2) is 1e12 for any cond_raw <= 1e4
            if cond <= _COND_AUTO / 2 and cond_raw <= _COND_RAW_FAST:
                return cond, cond_raw
    if lagged:
        Phi = Phi.matrix()[0]
    return _exact_condition_numbers(Phi if exponents is None else times_pow2(Phi, exponents))


def _exact_condition_numbers(Phi):
    """`_condition_numbers` from the QR factor of `Phi` with unit columns (the whole
    record read twice more and copied once)."""
    norms = safe_norm(Phi, axis=0)
    R = np.linalg.qr(Phi / np.where(norms > 0, norms, 1.0), mode="r")
    return tuple(_cond(M) for M in (R, R * norms))  # R D is the factor of Phi itself


_GRAM_TINY = 2.0 ** -900   # a Gram column with less than this per row: the exact path
_COND_RAW_FAST = 1e4       # cond_max = max(1e12, 1e4 cond_raw^2) is 1e12 up to here


def _cond_bound(G, rows):
    """An upper bound of the condition number of the matrix whose Gram matrix is `G` (see
    `_condition_numbers`), ``inf`` when the rounding hides its smallest eigenvalue."""
    lam = np.linalg.eigvalsh(G)
    delta = 8.0 * (rows + len(G)) * np.finfo(float).eps * np.trace(G)
    return float(np.sqrt((lam[-1] + delta) / (lam[0] - delta))) if lam[0] > delta else np.inf


def _cond(R):
    sv = np.linalg.svd(R, compute_uv=False)
    return float(sv[0] / sv[-1]) if len(sv) and sv[-1] > 0 else np.inf


def _qr_least_squares(Phi, target, of_output=None):
    r"""Least squares through QR, safe over the whole double range.

    Returns ``(theta, C, c)``: ``theta`` (n, ny) and :math:`(\Phi^T\Phi)^{-1}
    = C / (c c^T)`, with ``c`` the powers of two that scaled the columns. A
    coefficient beyond the largest double (``u`` around 1e-160, ``y`` around
    1e160) is a ValueError naming ``u`` and ``y`` (`of_output` marks the
    ``a`` coefficients, for the message).

    The columns of ``Phi`` (by ``c``) and of the target (by ``t``) are
    divided by powers of two near their largest entries, which is exact, so
    the factorization never squares a number around 1e160 or 1e-160; then
    :math:`\hat\theta_i = t_i \hat\theta^{s}_i / c`. One Householder QR
    (LAPACK ``geqrf``) of the scaled ``[Phi, target]`` gives ``R`` and
    ``Q^T target`` without forming ``Q``; the rank is decided as
    ``_column_rank(Phi)`` decides it, from the singular values of ``R`` with
    its columns scaled to unit norm (those of ``Phi`` with unit columns), so
    the record is read once.
    """
    from scipy.linalg import lapack, solve_triangular  # lazy: keeps `import rlsfilt` light
    rows, n = Phi.shape
    ce, te = pow2_exponent(Phi, axis=0), pow2_exponent(target, axis=0)
    c = np.ldexp(1.0, ce)
    A = np.empty((rows, n + target.shape[1]), order="F")
    times_pow2(Phi, -ce, out=A[:, :n])                  # Phi / c and target / t, exactly
    times_pow2(target, -te, out=A[:, n:])
    qr, _, _, _ = lapack.dgeqrf(A, overwrite_a=True)
    Rf = np.triu(qr[:n, :n])
    rhs = qr[:n, n:]
    norms = np.linalg.norm(Rf, axis=0)                  # the column norms of Phi / c
    sv = np.linalg.svd(Rf / np.where(norms > 0, norms, 1.0), compute_uv=False)
    rank = int(np.sum(sv > sv.max() * max(rows, n) * np.finfo(float).eps)) if n else 0
    if rank < n:
        raise ValueError(
            f"the regressor matrix has rank {rank} < n_params = {n}: the input is not "
            "persistently exciting for these orders (or the orders are too high); use a richer "
            "input, more data or lower orders")
    # back substitution one column at a time, and the triangular inverse from
    # LAPACK's trtri: multi-column triangular solves hit a slow threaded BLAS
    # path for tiny matrices on loaded machines (measured: 2-10 ms per call)
    theta = np.column_stack([solve_triangular(Rf, rhs[:, i]) for i in range(rhs.shape[1])])
    theta = estimate_in_units(theta, te[None, :] - ce[:, None], of_output)  # times t_i / c
    Rinv, info = lapack.dtrtri(Rf, lower=0)
    cov = Rinv @ Rinv.T
    return theta, 0.5 * (cov + cov.T), c


def _noise_and_covariance(resid, dof, inv_scaled, c, top=None):
    r"""Noise variances, parameter covariances and (several outputs) the noise covariance.

    With :math:`(\Phi^T\Phi)^{-1} = C / (c c^T)` and each residual column
    divided by a power of two :math:`t_i` first, :math:`\hat\sigma_i^2 =
    t_i^2 \hat\sigma_{s,i}^2` and ``cov[i] = sigma_s2[i] C (t_i / c)(t_i / c)^T``:
    no intermediate overflows or underflows, so a record in any units gives
    the covariance of its parameters wherever that is representable.
    ``inv_scaled`` None (instrumental variables, whose covariance is their
    own) gives no parameter covariance. `top`: ``max|resid|`` per column, when
    known.

    Where every :math:`t_i` is within :math:`2^{\pm 300}` the products of the
    residuals themselves neither overflow nor leave the normal range (but for
    terms below :math:`2^{-1022}`, negligible next to :math:`t_i t_j`), and are
    those of the divided residuals times :math:`t_i t_j`, exactly: they are
    summed without the divided copy.
    """
    ny, n = resid.shape[1], len(c)
    if dof <= 0:
        nan = np.full(ny, np.nan)
        return nan, np.full((ny, n, n), np.nan), np.full((ny, ny), np.nan)
    te = pow2_exponent(resid, axis=0) if top is None else np.frexp(top)[1]
    t = np.ldexp(1.0, te)
    if np.abs(te).max() <= 300:
        noise_s = np.ldexp(resid.T @ resid, -(te[:, None] + te[None, :])) / dof
    else:
        rs = times_pow2(resid, -te)                      # resid / t, exactly
        noise_s = rs.T @ rs / dof
    sigma2_s = np.diag(noise_s).copy()
    with np.errstate(over="ignore", under="ignore"):
        g = t[:, None] / c[None, :]                      # (ny, n)
        sigma2 = sigma2_s * t * t
        noise_cov = noise_s * np.outer(t, t)
        if inv_scaled is None:
            return sigma2, None, noise_cov
        cov = (sigma2_s[:, None, None] * inv_scaled[None]) * g[:, :, None] * g[:, None, :]
    return sigma2, cov, noise_cov


def _output_lags(s, n):
    """Which of the `n` regressor columns are lags of an output (``a`` coefficients)."""
    return np.arange(n) < s.n_outputs * s.na


def _split(theta, s):
    """The ARX parameter layout, in one place: ``theta`` (n_params, ny) -> ``(A, [B_j])``.

    ``A`` has shape (ny, ny, na) with ``A[i, j, k-1]`` the coefficient of
    ``y_j(t-k)`` in the equation of output ``i``; ``B_j`` has shape
    (ny, nb_j) with ``B_j[i, m]`` multiplying ``u_j(t - nk_j - m)``.
    """
    a_sl, b_sls = s.param_slices()
    A = theta[a_sl].reshape(s.n_outputs, s.na, s.n_outputs).transpose(2, 0, 1)
    return A, [theta[sl].T.copy() for sl in b_sls]


def _fmt(t):
    return t[0] if len(set(t)) == 1 and len(t) == 1 else list(t)


def _means(records):
    """Means of the inputs and outputs over every sample of every experiment."""
    U = np.vstack([U for U, _ in records])
    Y = np.vstack([Y for _, Y in records])
    return record_means(U), record_means(Y)


def _equilibrium(A, B, c, u_bar, y_bar):
    r"""The steady state of :math:`A(q) y = B(q) u + c` nearest the record's means.

    With :math:`A(1) = I + \sum_k A_k` invertible: :math:`u = \bar u`,
    :math:`y = A(1)^{-1}(c + B(1)\bar u)`. For an integrating model
    (singular :math:`A(1)`) the point :math:`(u, y)` with
    :math:`A(1) y - B(1) u = c` closest to :math:`(\bar u, \bar y)` (minimum
    norm correction).
    """
    ny = A.shape[0]
    A1 = np.eye(ny) + A.sum(axis=2)
    B1 = np.hstack([b.sum(axis=1, keepdims=True) for b in B])  # (ny, nu)
    if np.linalg.cond(A1) < 1e10:
        return u_bar, np.linalg.solve(A1, c + B1 @ u_bar)
    M = np.hstack([A1, -B1])
    x_bar = np.concatenate([y_bar, u_bar])
    x = x_bar + np.linalg.pinv(M) @ (c - M @ x_bar)
    return x[ny:], x[:ny]
