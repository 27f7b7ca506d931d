r"""``ARX.fit(method="iv" | "riv")``: the instrumental-variable fits of an ARX model.

The numerics are :mod:`rlsfilt.models._iv`; this module validates the
options of the two methods and returns what `ARX.fit` stores.

An intercept (``ARX(offset=True)``: :math:`A y = B u + c + e`) is one more
input, the constant :math:`u_0(t) = 1` with ``nb = 1``, ``nk = 0``, placed
last so that ``c`` is the last parameter: its regressor column is the
column of ones of the least-squares fit, and the instruments get the same
column (the constant is its own instrument; the auxiliary model of
``"model"`` instruments simulates :math:`x = (\hat B u + \hat c)/\hat A`).

Both fits run in the units of :class:`~rlsfilt.models._units.RecordUnits`:
every signal divided by a power of two near its largest entry (the
intercept's constant input too), user-given instruments by one power of two
near their largest entry. The IV estimate :math:`(Z^T\Phi)^{-1}Z^TY` does
not change when a column of :math:`Z` or the whole of :math:`Y` is
multiplied by a constant, and multiplying a column of :math:`\Phi` by
:math:`2^{-c_k}` multiplies its parameter by :math:`2^{c_k}`: the estimate,
its covariance, the histories and the instrument rows are mapped back
exactly (``ldexp``), and records around :math:`10^{\pm 160}`, whose sums of
products :math:`Z^T\Phi` leave the double range, give the estimate of the
same record at unit size. The recursive fit's options ``P0``, ``R``, ``Q``
and ``x0`` are read in the signals' units and mapped into the scaled units
(:mod:`rlsfilt.models._units`), so the recursion computes the numbers of
the unscaled one times powers of two.
"""

import numpy as np

from .._scale import pow2_exponent
from .._validation import check_covariance, check_int, check_lam, check_variance
from ._iv import covariance_per_output, fit_iv_records, recursive_iv_records
from ._units import RecordUnits
from .regressors import arx_structure

__all__ = []

#: The options each method takes (anything else is a TypeError naming these).
OPTIONS = {"iv": ("instruments", "prefilter", "n_iter"),
           "riv": ("instruments", "k0", "lam", "P0", "R", "Q", "x0", "refresh", "prefilter")}


def check_options(method, options):
    """Reject an option that `method` does not take, naming the ones it does."""
    for key in options:
        if key not in OPTIONS[method]:
            raise TypeError(f"`{key}` is not an option of ARX.fit(method={method!r}); its "
                            f"options are {list(OPTIONS[method])}")


def with_intercept(records, s):
    """The records with a last input column of ones and the structure with that input
    (``nb = 1``, ``nk = 0``): the intercept as an input."""
    records = [(np.hstack([U, np.ones((len(U), 1))]), Y) for U, Y in records]
    s1 = arx_structure(s.na, list(s.nb) + [1], list(s.nk) + [0], s.n_inputs + 1, s.n_outputs)
    return records, s1


def fit_arx_iv(records, s, method, options, y_1d=True, stacklevel=4, intercept=False):
    """Estimate an ARX structure by batch (``"iv"``) or recursive (``"riv"``) IV.

    Parameters
    ----------
    records : list of (ndarray (N_i, nu), ndarray (N_i, ny))
        The experiments (deviations from the operating point for
        ``offset="mean"``).
    s : ARXStructure
    method : {"iv", "riv"}
    options : dict
        Of the method (see `OPTIONS`).
    y_1d : bool
        `y` was 1-D (the history drops its output axis).
    intercept : bool
        Estimate an intercept ``c`` (the last parameter; user-given
        instruments get a column of ones appended).

    Returns
    -------
    theta : ndarray, shape (n_params, ny)
    cov : ndarray, shape (ny, n_params, n_params)
        Covariance accounting for the coloured equation error
        (:func:`rlsfilt.models._iv.iv_covariance`).
    learned : dict
        Extra learned attributes: ``"riv"``: ``theta_history_`` (rows, n), or
        (rows, n, ny) unless `y_1d`,
        ``recursive_residuals_`` and ``k0_``; both: ``instruments_`` (the
        instrument rows used).
    """
    check_options(method, options)
    ny = records[0][1].shape[1]
    instruments = options.get("instruments", "model" if ny == 1 else "delayed")
    if intercept and not isinstance(instruments, str):
        # the user's rows, then the constant as its own instrument
        Z = np.asarray(instruments, dtype=float)
        Z = Z[:, None] if Z.ndim == 1 else Z
        N = sum(len(U) for U, _ in records)
        if Z.ndim != 2 or len(Z) != N or Z.shape[1] < s.n_params:
            per = " of every experiment, one after the other" if len(records) > 1 else ""
            raise ValueError(
                f"`instruments` must have shape (N, n_z) with N = {N} rows (one per "
                f"sample{per}) and n_z >= n_params = {s.n_params} (a column of ones is "
                f"appended for the intercept); got {np.shape(instruments)}")
        instruments = np.hstack([Z, np.ones((N, 1))])
    if intercept:
        records, s = with_intercept(records, s)
    n = s.n_params
    # the fit runs on the record scaled to unit size (see the module notes)
    units = RecordUnits(records, s)
    scaled = units.scale_records(records)
    z_exp, instruments = _instruments_in_units(instruments, units, s)
    prefilter = options.get("prefilter")
    if prefilter is not None and not isinstance(prefilter, (bool, np.bool_)):
        raise TypeError(f"`prefilter` must be True or False; got {prefilter!r}")
    if method == "iv":
        n_iter = check_int(options.get("n_iter", 10), "n_iter", minimum=1)
        fit = fit_iv_records(scaled, s, instruments,
                             prefilter=True if prefilter is None else prefilter, n_iter=n_iter)
        theta = units.estimate_from_unit(fit.theta)
        cov = fit.cov if ny > 1 else fit.cov[None]
        return theta, _cov_from_unit(cov, units), {"instruments_": np.ldexp(fit.Z, z_exp)}
    kw = {}
    if "lam" in options:
        kw["lam"] = check_lam(options["lam"])
    if "R" in options:
        kw["R"] = check_variance(options["R"], "R")
    if "Q" in options:
        Q = check_covariance(options["Q"], n, "Q")
        kw["Q"] = Q if Q.any() else None
    if "P0" in options:
        kw["P0"] = check_covariance(options["P0"], n, "P0", definite=True)
    if "x0" in options:
        x0 = np.asarray(options["x0"], dtype=float)
        if x0.size != n * ny or not np.isfinite(x0).all():
            raise ValueError(f"`x0` must hold n_params * ny = {n * ny} finite values; got "
                             f"shape {x0.shape}")
        kw["x0"] = x0.reshape(n, ny)
    if "k0" in options:
        kw["k0"] = check_int(options["k0"], "k0", minimum=0)
    elif "P0" in kw or "x0" in kw:
        kw["k0"] = 0                # a given prior means a prior start, as for "rls"
    if "k0" in kw and kw["k0"] > 0 and ("P0" in kw or "x0" in kw):
        raise ValueError(f"`P0` and `x0` only apply to a prior start (k0=0); the exact start on "
                         f"k0={kw['k0']} rows sets both")
    if "refresh" in options:
        kw["refresh"] = check_int(options["refresh"], "refresh", minimum=0)
    units.check_ratio()
    if "x0" in kw:
        units.start_to_unit(kw["x0"], "x0")      # a clear error before the prior's
    start = units.recursion_start(kw.get("P0", 1e4 * np.eye(n)), kw.get("R", 1.0), kw.get("Q"),
                                  z=z_exp, prior=kw.get("k0", n) == 0,
                                  default_P0="P0" not in kw, stacklevel=stacklevel)
    if start is None:             # a prior too strong for the data's scale: its own units
        units = units.unscaled()
        scaled = units.scale_records(records)
        z_exp, instruments = _instruments_in_units(instruments, units, s)
        start = {"P0": kw["P0"] if "P0" in kw else 1e4 * np.eye(n), "R": kw.get("R", 1.0),
                 "Q": kw.get("Q")}
    kw.update({k: v for k, v in start.items() if v is not None})
    if "x0" in kw:
        kw["x0"] = units.start_to_unit(kw["x0"], "x0")
    fit = recursive_iv_records(scaled, s, instruments, prefilter=bool(prefilter),
                               stacklevel=stacklevel, **kw)
    resid = fit.target - fit.Phi @ fit.theta
    cov, _ = covariance_per_output(fit.P, fit.Z, resid, n)
    cov = cov if ny > 1 else cov[None]
    hist = units.theta_from_unit(fit.theta_history)
    eps = units.output_from_unit(fit.eps)
    learned = {"theta_history_": hist[:, :, 0] if y_1d else hist,
               "recursive_residuals_": eps[:, 0] if y_1d else eps,
               "k0_": n if "k0" not in kw else kw["k0"],
               "instruments_": np.ldexp(fit.Z, z_exp)}
    return units.estimate_from_unit(fit.theta), _cov_from_unit(cov, units), learned


def _instruments_in_units(instruments, units, s):
    """``(z_exp, instruments)``: the exponents of the instrument columns, and the
    instruments to give the scaled record (a user's array divided by one power of two).

    ``"model"`` instruments have the regressor's layout (the auxiliary output in the
    units of ``y``); ``"delayed"`` ones replace the ``-y`` lags by lags of the first
    input; a user's array keeps its columns' ratios (extended IV weighs its equations
    by them).
    """
    if isinstance(instruments, str):
        z_exp = units.column_exponents.copy()
        if instruments == "delayed":
            z_exp[:s.n_outputs * s.na] = units.input_exponents[0] if s.n_inputs else 0
        return z_exp, instruments
    Z = np.asarray(instruments, dtype=float)
    e = int(pow2_exponent(Z)) if np.isfinite(Z).all() else 0
    width = Z.shape[1] if Z.ndim == 2 else 1
    return np.full(width, e, dtype=int), np.ldexp(Z, -e)


def _cov_from_unit(cov, units):
    """Covariances ``(ny, n, n)`` of the scaled parameters -> the user's units."""
    return np.array([units.cov_from_unit(c, j) for j, c in enumerate(cov)])
