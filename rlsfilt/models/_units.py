r"""The units the fits run in: every signal divided by a power of two near its largest entry.

A fit's sums of squares leave the double range for records around
:math:`10^{\pm 160}` (:mod:`rlsfilt._scale`). Every model of rlsfilt is
linear in its signals, so it is fitted to the record scaled to unit size
and its results are mapped back: with :math:`u_i = 2^{e_i}\tilde u_i` and
:math:`y_j = 2^{e_{y,j}}\tilde y_j`, a regressor column :math:`k` (a lag of
a signal with exponent :math:`c_k`, or the column of ones of an intercept,
:math:`c_k = 0`) is :math:`2^{c_k}` times its scaled self, and the
parameter :math:`\theta_{kj}` of output :math:`j` is
:math:`2^{g_{kj}}\tilde\theta_{kj}` with :math:`g_{kj} = e_{y,j} - c_k`
(``a``, ``c``, ``d``, ``f`` coefficients of a single output have no
units, :math:`g = 0`; ``b`` coefficients :math:`g = e_y - e_i`).

A recursion (RLS, RPEM, recursive IV) carries the covariance ``P`` and the
noise variance ``R``. With regressor exponents :math:`c` and instrument
exponents :math:`z` (:math:`z = c` but for instrumental variables), the
recursion on the scaled record started from

.. math::

    \tilde R = 2^{r} R,\qquad \tilde P_{kl} = 2^{c_k + z_l + r} P_{kl},
    \qquad \tilde Q_{kl} = 2^{c_k + z_l + r} Q_{kl},\qquad
    \tilde\theta_{kj} = 2^{-g_{kj}}\theta_{kj}

computes, operation for operation, the numbers of the recursion in the
user's units times powers of two: every sum in it adds terms of the same
units (the gain denominator :math:`R + \varphi^T P z` is :math:`2^r` times
its unscaled value, the gain :math:`P z / (R + \varphi^T P z)` has the units
of :math:`\theta / y`). Multiplying by a power of two is exact, so the two
runs give the same bits wherever the user's run stays inside the normal range
of doubles, and the scaled run stays inside it for records of any size as
long as the options suit the data. Any integer :math:`r` will do where ``P``
is proportional to ``R`` (a prior start, or the exact start
:math:`R (\Phi_0^T\Phi_0)^{-1}` of RLS): :math:`\tilde R \approx 1` keeps
both in range. The exact start :math:`(Z_0^T\Phi_0)^{-1}` of recursive IV
does not carry ``R``: there :math:`r = 0`. A step that compares a residual
with ``R`` (the outlier gate :math:`|\varepsilon| / \sqrt{R + \varphi^T
P\varphi}`) needs :math:`r = -2 e_y` (:math:`e_y` of the first output),
under which the residuals and the gain denominator scale alike. Constants
that bound ``trace(P)`` or its eigenvalues are not of this form: the
constant-trace, EFRA and variable forgetting modes (and an explicit
``trace_max``) run in the signals' units; the default trace limit of the
exponential mode's windup cap applies in the scaled units (it acts only on a
``P`` wound up by about 1e12); and the filters' health checks (the condition number of ``P``)
judge ``P`` of unit-size signals, so a well-posed record whose inputs and
outputs have very different units is no longer called ill-conditioned.

``P0``, ``R`` and ``Q`` are the user's, in the signals' units, and so are
their defaults (``P0 = 1e4 I``, ``R = 1``: MATLAB's convention, and that of
the streaming estimators, which cannot know the scale of the data in
advance). A prior start whose ``P0`` outweighs the data (the default for
signals far below unit size) is reported by a NumericalWarning naming
``P0`` (`RecordUnits.recursion_start`); one that no double can carry in
the scaled units (the default for signals around 1e160, about 1e320 times
too diffuse: the first update would lose every digit of ``P`` in any units)
is a ValueError naming it.

Every conversion is an ``ldexp`` (on long records `times_pow2`, the same
bits): exact unless its result over- or underflows (then ``inf`` or a
subnormal number, as the product in exact arithmetic would round).
"""

import math
import warnings

import numpy as np

from .._scale import pow2_exponent, times_pow2
from .._validation import COVARIANCE_MAX, VARIANCE_RANGE
from ..exceptions import NumericalWarning

__all__ = []


def _column_exponents(s, input_exponents, output_exponents, intercept):
    """Exponent of every regressor column, its signal's (0 for the intercept's ones), and
    which columns are lags of an output.

    The general family (one output, ``s.slices()``) has the blocks ``a, b_i, c, d, f_i``:
    lags of ``y``, ``u_i`` and of ``eps``, ``v``, ``w_i`` (all in the units of ``y``).
    ARX (``s.param_slices()``) has one ``-y`` block of ``na`` lags per output, then one
    block per input.
    """
    c = _column_values(s, input_exponents, output_exponents, 0, intercept).astype(int)
    of_output = _column_values(s, np.zeros(s.n_inputs), np.ones(len(output_exponents)), 0,
                               intercept) == 1
    return c, of_output


def equivariant_forgetting(forgetting, params):
    """Whether a recursion with this forgetting mode gives the same numbers in scaled
    units (see the notes): exponential and diagonal forgetting (unless
    ``forgetting_params`` holds an absolute ``trace_max``; ``L^-1/2 P L^-1/2`` commutes
    with the diagonal scaling of the columns) and directional forgetting."""
    return (forgetting in ("exponential", "diagonal", "directional")
            and "trace_max" not in (params if isinstance(params, dict) else {}))


def estimate_in_units(theta, g, of_output=None):
    r"""An estimate computed in scaled units -> the user's units, ``ldexp(theta, g)``; a
    ValueError naming `u` and `y` when a coefficient is beyond the largest double there.

    A ``b`` coefficient is :math:`2^{e_y - e_u}` times its scaled value: ``u`` around
    1e-160 and ``y`` around 1e160 give coefficients around 1e320, which no double holds
    (an ``a`` coefficient between two outputs in such units likewise).

    Parameters
    ----------
    theta : ndarray, shape (n,) or (n, ny)
    g : ndarray of int, broadcastable to `theta`
        The exponents :math:`g_{kj}`.
    of_output : ndarray of bool, shape (n,), optional
        Which parameters multiply lags of an output (``a`` coefficients).
    """
    with np.errstate(over="ignore", under="ignore"):
        out = np.ldexp(theta, g)
    if np.isfinite(out).all():
        return out
    with np.errstate(divide="ignore"):       # log2|theta| in the user's units
        log2 = np.log2(np.abs(np.asarray(theta, dtype=float))) + g
    log2 = np.where(np.isfinite(out), -np.inf, log2)
    k = np.unravel_index(int(np.argmax(log2)), log2.shape)[0]     # the parameter
    if of_output is not None and of_output[k]:
        raise ValueError("`y` must have outputs in units whose ratios double precision can "
                         f"hold; got a coefficients of about 2^{log2.max():.0f} (above the "
                         "largest double, 2^1024): scale the outputs to similar units")
    raise ValueError("`u` and `y` must have units whose ratio double precision can hold; got "
                     f"b coefficients of about 2^{log2.max():.0f} (above the largest double, "
                     "2^1024): scale `y` down or `u` up")


def _sum_squares(X, e):
    """``sum((X 2^-e)^2, axis=0)``: the sum of squares of each column in the scaled units."""
    Xs = times_pow2(X, -e)
    return np.sum(np.square(Xs, out=Xs), axis=0)


def _column_values(s, per_input, per_output, ones, intercept):
    """A value per regressor column from one per signal (`ones` for the intercept)."""
    v = np.full(s.n_params, per_output[0], dtype=float)
    if hasattr(s, "slices"):
        b_slices = s.slices()["b"]
    else:
        for j in range(s.n_outputs):
            v[j * s.na:(j + 1) * s.na] = per_output[j]
        b_slices = s.param_slices()[1]
    for i, sl in enumerate(b_slices):
        v[sl] = per_input[i]
    return np.append(v, ones) if intercept else v


class RecordUnits:
    r"""Powers of two that bring a record to unit size, and the map of the results back.

    ``2^{e_i}`` for input ``i`` and ``2^{e_{y,j}}`` for output ``j`` are the
    `pow2_exponent` of each signal over every experiment; in the scaled
    units every entry of the record is in ``[-1, 1]``.

    Parameters
    ----------
    records : list of (ndarray (N_i, nu), ndarray (N_i,) or (N_i, ny))
        The experiments (1-D outputs: the single-output family, whose
        parameters are 1-D too).
    s : FamilyStructure or ARXStructure
    intercept : bool, default False
        ARX with ``offset=True``: a last regressor column of ones.

    Attributes
    ----------
    input_exponents : ndarray of int, shape (nu,)
    output_exponents : ndarray of int, shape (ny,)
    output_exponent : int
        The first output's (the only one of the family).
    column_exponents : ndarray of int, shape (n_params,)
        :math:`c_k`, the exponent of each regressor column.
    theta_exponents : ndarray of int, shape (n_params,) or (n_params, ny)
        :math:`g_{kj} = e_{y,j} - c_k`; 1-D for 1-D outputs.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.models._family import family_structure
    >>> from rlsfilt.models._units import RecordUnits
    >>> units = RecordUnits([(np.array([[3.0], [-1.0]]), np.array([1e-3, 0.0]))],
    ...                     family_structure(na=1, nb=1, nk=1))
    >>> int(units.input_exponents[0]), units.output_exponent, units.theta_exponents
    (2, -9, array([  0, -11]))
    """

    def __init__(self, records, s, intercept=False):
        U = records[0][0] if len(records) == 1 else np.vstack([U for U, _ in records])
        Ys = [np.asarray(Y).reshape(len(Y), -1) for _, Y in records]
        Y = Ys[0] if len(Ys) == 1 else np.concatenate(Ys)
        self._y_1d = np.ndim(records[0][1]) == 1
        self.input_exponents = (np.asarray(pow2_exponent(U, axis=0), dtype=int) if U.shape[1]
                                else np.zeros(0, dtype=int))
        self.output_exponents = np.asarray(pow2_exponent(Y, axis=0), dtype=int).reshape(-1)
        self.output_exponent = int(self.output_exponents[0])
        self.column_exponents, self._of_output = _column_exponents(
            s, self.input_exponents, self.output_exponents, intercept)
        g = self.output_exponents[None, :] - self.column_exponents[:, None]
        self.theta_exponents = g[:, 0] if self._y_1d else g
        self._signals = (U, Y, s, intercept)       # read (not copied) by `_energy`

    def _energy(self):
        """The sum of squares of each regressor column's signal in the scaled units (the
        ones of an intercept: the number of samples): a bound of the information the data
        carry. Only a prior start from the default ``P0`` needs it."""
        U, Y, s, intercept = self._signals
        return _column_values(s, _sum_squares(U, self.input_exponents),
                              _sum_squares(Y, self.output_exponents), float(len(Y)), intercept)

    def unscaled(self):
        """The same record in its own units (every exponent 0): the identity map, for a
        recursion that runs in the signals' units."""
        import copy

        out = copy.copy(self)
        out.input_exponents = np.zeros_like(self.input_exponents)
        out.output_exponents = np.zeros_like(self.output_exponents)
        out.output_exponent = 0
        out.column_exponents = np.zeros_like(self.column_exponents)
        out.theta_exponents = np.zeros_like(self.theta_exponents)
        return out

    # ------------------------------------------------------------------
    # signals
    # ------------------------------------------------------------------
    def scale_records(self, records):
        """The records in the scaled units (new arrays; the caller's are not touched)."""
        ey = self.output_exponent if self._y_1d else self.output_exponents
        return [(times_pow2(U, -self.input_exponents), times_pow2(Y, -ey)) for U, Y in records]

    def scale_rows(self, Phi, target):
        """Regressor rows ``(rows, n)`` and targets ``(rows, ny)`` in the scaled units."""
        return (times_pow2(Phi, -self.column_exponents),
                times_pow2(target, -self.output_exponents))

    def output_from_unit(self, x, power=1, out=None):
        """Outputs (``power=1``; time on axis 0, one column per output, or 1-D for one)
        or variances of them (``power=2``) -> the user's units (into `out`, which may be
        `x`, when given)."""
        ey = self.output_exponent if np.ndim(x) < 2 else self.output_exponents
        with np.errstate(over="ignore", under="ignore"):
            return times_pow2(x, power * ey, out=out)

    # ------------------------------------------------------------------
    # parameters and their covariance
    # ------------------------------------------------------------------
    def _g(self, theta):
        g = self.theta_exponents
        return g[:, 0] if (g.ndim == 2 and np.ndim(theta) == 1) else g

    def theta_to_unit(self, theta):
        """Parameters ``(n,)`` or ``(n, ny)`` (or histories ``(..., n[, ny])``) in the user's
        units -> the scaled units."""
        with np.errstate(over="ignore", under="ignore"):
            return times_pow2(theta, -self._g(theta))

    def theta_from_unit(self, theta, out=None):
        """Parameters (or histories of them) in the scaled units -> the user's units (into
        `out`, which may be `theta`, when given)."""
        with np.errstate(over="ignore", under="ignore"):
            return times_pow2(theta, self._g(theta), out=out)

    def estimate_from_unit(self, theta):
        """`theta_from_unit` of an estimate, or a ValueError naming `u` and `y` when a
        coefficient is beyond the largest double in the user's units (see
        `estimate_in_units`)."""
        return estimate_in_units(theta, self._g(theta), self._of_output)

    def cov_from_unit(self, cov, output=0):
        """Covariance of the parameters of one output -> the user's units: :math:`G P G`."""
        g = self.theta_exponents
        g = g if g.ndim == 1 else g[:, output]
        with np.errstate(over="ignore", under="ignore"):
            return np.ldexp(cov, g[:, None] + g[None, :])

    # ------------------------------------------------------------------
    # the options of a recursion
    # ------------------------------------------------------------------
    @property
    def gate_shift(self):
        """``r = -2 e_y`` (first output): the shift of ``R`` under which a residual's ratio
        to the gain denominator's square root is unchanged (see the module notes)."""
        return -2 * self.output_exponent

    def r_for(self, R, gate=False):
        """The shift ``r`` of a recursion whose ``P`` is proportional to ``R`` (a prior start,
        or the batch start ``R (Phi_0^T Phi_0)^-1``): `gate_shift` with an outlier gate,
        else the even one that brings ``R`` to within a factor 2 of 1 (any even ``r`` gives
        the same numbers: ``sqrt(2^r R) = 2^(r/2) sqrt(R)`` is exact, and the window's QR
        refit and the square-root form whiten the rows by ``sqrt(R)``; an odd ``r`` made
        ``window`` with ``R = 2`` differ from the filter in the signals' units)."""
        return self.gate_shift if gate else -2 * int(np.round(np.log2(R) / 2))

    def P_exponents(self, z=None, r=0):
        """Exponents of ``P``: :math:`c_k + z_l + r` (`z` the instrument columns'
        exponents, the regressors' by default)."""
        c = self.column_exponents
        z = c if z is None else np.asarray(z, dtype=int)
        return c[:, None] + z[None, :] + r

    def diagnostics_from_unit(self, r=0):
        r"""The maps of a filter's last-update diagnostics (``x_prior``, ``x_post``,
        ``P_prior``, ``P_post``, ``H``, ``K``, ``S``, ``SI``, ``z``, ``y``) from a run in the
        scaled units with ``R~ = 2^r R`` to the signals' units, by name: the regressor row
        :math:`\varphi = 2^c\tilde\varphi`, the gain :math:`K = 2^{-c}\tilde K`,
        :math:`S = 2^{-r}\tilde S`, outputs and residuals :math:`2^{e_y}`."""
        c, ey = self.column_exponents, self.output_exponents[:, None]

        def cols(H):                                   # a regressor row: phi = 2^c phi~
            return np.ldexp(H, c)

        def gain(K):                                   # K = P phi / S = 2^-c K~
            return np.ldexp(K, -c[:, None] if np.ndim(K) == 2 else -c)

        return {"x_prior": self.theta_from_unit, "x_post": self.theta_from_unit,
                "P_prior": lambda P: self.P_from_unit(P, r=r),
                "P_post": lambda P: self.P_from_unit(P, r=r), "H": cols, "K": gain,
                "S": lambda S: np.ldexp(S, -r), "SI": lambda S: np.ldexp(S, r),
                "z": lambda z: np.ldexp(z, ey), "y": lambda y: np.ldexp(y, ey)}

    def R_to_unit(self, R, r=0):
        """The noise variance ``R`` -> the scaled units: :math:`2^r R`."""
        with np.errstate(over="ignore", under="ignore"):
            return float(np.ldexp(R, r))

    def P_to_unit(self, P, z=None, r=0):
        """``P0`` (or ``Q``) ``(n, n)`` in the user's units -> the scaled units."""
        with np.errstate(over="ignore", under="ignore"):
            return np.ldexp(P, self.P_exponents(z, r))

    def P_from_unit(self, P, z=None, r=0):
        """``P`` in the scaled units -> the user's units (``inf`` or subnormal where it
        does not fit)."""
        with np.errstate(over="ignore", under="ignore"):
            return np.ldexp(P, -self.P_exponents(z, r))

    def check_ratio(self):
        """The ValueError of `estimate_from_unit`, up front, when a coefficient of unit
        size in the scaled units is already beyond the largest double in the user's units
        (``u`` around 1e-160 and ``y`` around 1e160): checked before a recursion, whose
        options would otherwise be reported first."""
        g = self.theta_exponents
        if np.max(g, initial=0) >= 1024:
            estimate_in_units(np.ones(g.shape), g, self._of_output)

    def start_to_unit(self, theta, name):
        """A start ``x0`` or ``theta0`` in the user's units -> the scaled units, or a
        ValueError naming it when a coefficient overflows there."""
        out = self.theta_to_unit(theta)
        if not np.isfinite(out).all():
            raise ValueError(f"`{name}` must have b coefficients of the size the record's units "
                             "allow (|b| up to about max|y| / max|u| times 1e300); got "
                             "coefficients that overflow")
        return out

    def recursion_start(self, P0, R, Q=None, *, z=None, r=0, prior=True, default_P0=False,
                        stacklevel=2):
        r"""A recursion's ``P0``, ``R`` and ``Q`` (validated, in the signals' units) in
        the scaled units, checked against the range the filters take.

        Parameters
        ----------
        P0 : ndarray (n, n)
            Used when `prior` (a prior start); else only ``R`` and ``Q`` are mapped.
        R : float
        Q : ndarray (n, n), optional
        z, r
            As `P_exponents`.
        default_P0 : bool
            `P0` is the default ``1e4 I``: warn when it outweighs the data.

        Returns
        -------
        dict or None
            ``{"P0", "R", "Q"}`` in the scaled units, or None when they leave the
            filters' range there (a prior far stronger than the data can bear, e.g.
            the default ``1e4 I`` for signals around 1e-160): then a
            NumericalWarning naming `P0` has been issued, and the recursion is to run
            in the signals' units.

        Raises
        ------
        ValueError
            When ``P0`` (or ``Q``, ``R``) is so large for the scale of the data that the
            scaled recursion would overflow: the covariance update loses every digit
            of ``P`` in any units.

        Warns
        -----
        NumericalWarning
            When the default ``P0`` outweighs the data (its information
            :math:`R / P_{0,kk}` exceeds 1 % of the energy of parameter ``k``'s signal,
            all in the scaled units), or `P0` does not fit the scaled units (above).
        """
        out = {"R": self.R_to_unit(R, r)}
        lo, hi = VARIANCE_RANGE
        if not lo <= out["R"] <= hi:
            raise ValueError(f"`R` must suit the scale of the data ({self._scale_text()}): "
                             f"R = {R:.3g} in the signals' units is {out['R']:.3g} for the "
                             "record scaled to unit size, outside the range of the recursion "
                             f"[{lo:.0e}, {hi:.0e}]; pass R of the size of the noise variance "
                             "of `y`")
        if Q is not None:
            out["Q"] = self.P_to_unit(Q, z, r)
            if not np.max(np.abs(out["Q"]), initial=0.0) <= COVARIANCE_MAX:
                raise ValueError(f"`Q` must suit the scale of the data ({self._scale_text()}): "
                                 "read in the signals' units it is beyond the range of the "
                                 "recursion for the record scaled to unit size; pass a smaller "
                                 "Q or scale the signals")
        if not prior:
            return out
        P = self.P_to_unit(P0, z, r)
        d = np.abs(np.diagonal(P))
        # log10 of (P0_kk / R) 2^(c_k + z_k) / 1e4: the prior variance relative to the
        # default 1e4 of the record scaled to unit size
        with np.errstate(divide="ignore"):
            rel = (np.log10(np.diagonal(P0) / R)
                   + (np.diagonal(self.P_exponents(z, r)) - r) * math.log10(2.0) - 4.0)
        what = "P0 = 1e4 I (the default; P0 and R are in the signals' units)" if default_P0 \
            else "P0 (in the signals' units, as R)"
        if not np.max(np.abs(P), initial=0.0) <= COVARIANCE_MAX:
            raise ValueError(
                f"`P0` must suit the scale of the data ({self._scale_text()}): {what} is "
                f"{_times(rel.max())} the prior variance 1e4 of the record scaled "
                "to unit size, too diffuse for double precision (the first update would "
                "lose every digit of P); pass P0 and R in the signals' units (P0 about 1e4 * "
                "R / max|phi_k|^2 for parameter k), or scale the signals")
        if np.all(d >= np.finfo(float).tiny):
            out["P0"] = P
            info = out["R"] / d                          # the prior's information, scaled
            if default_P0 and np.any(info > 1e-2 * self._energy()):
                _warn_prior(what, rel, self._scale_text(), stacklevel + 1)
            return out
        _warn_prior(what, rel, self._scale_text(), stacklevel + 1)
        return None

    def _scale_text(self):
        """``"`u` up to 4e+160, `y` up to 2e-160"`` (the powers of two of the signals)."""
        def around(e):
            x = float(e) * math.log10(2.0)
            m, k = round(10.0 ** (x - math.floor(x))), math.floor(x)
            return f"1e{k + 1:+d}" if m == 10 else f"{m}e{k:+d}"
        us = ", ".join(around(e) for e in self.input_exponents)
        ys = ", ".join(around(e) for e in self.output_exponents)
        return (f"`u` up to {us}, " if us else "") + f"`y` up to {ys}"


def _times(log10):
    """``"about 1e+320 times"`` from a base-10 logarithm."""
    return f"about 1e{round(float(log10)):+d} times" if np.isfinite(log10) else "far from"


def _warn_prior(what, rel, scale, stacklevel):
    warnings.warn(
        f"{what} is {_times(rel.min())} the prior variance 1e4 of the record scaled "
        f"to unit size ({scale}): the prior outweighs the data and holds the estimate toward "
        "`x0`. Pass P0 and R in the signals' units (P0 about 1e4 * R / max|phi_k|^2 for "
        "parameter k), or scale the signals to unit size", NumericalWarning,
        stacklevel=stacklevel)


#: The tune's prior without a given ``P0``: ``P0 / R = 1e4 I`` of the record scaled to unit
#: size (the fit's default ``1e4 I``, read in the record's units: diffuse for a record of
#: any size, where ``1e4 I`` in the signals' units holds the estimate or overflows).
TUNE_P0 = 1e4


def tune_start(c, P_rel, Q_rel, given_P0):
    r"""The ``P / R`` and ``Q / R`` that ``lam="tune"`` / ``Q="tune"`` start from in the
    record's units (:math:`R = 1` there): the exact images
    :math:`2^{c_k + c_l} P_{kl} / R` and :math:`2^{c_k + c_l} Q_{kl} / R` of the options in
    the signals' units (as `RecordUnits.recursion_start` maps them, the likelihood being
    free of the scale of ``R``), or `TUNE_P0` times the identity without a given ``P0``.
    `c` is ``(n,)`` or ``(C, n)`` (a channel axis, `P_rel` and `Q_rel` ``(C, n, n)``).
    A ValueError names ``P0`` or ``Q`` when the image leaves the filters' range."""
    cc = c[..., :, None] + c[..., None, :]
    with np.errstate(over="ignore", under="ignore"):
        P = (np.ldexp(P_rel, cc) if given_P0
             else np.broadcast_to(TUNE_P0 * np.eye(c.shape[-1]), cc.shape).copy())
        Q = np.ldexp(Q_rel, cc)
    if not np.max(np.abs(P), initial=0.0) <= COVARIANCE_MAX:
        raise ValueError("`P0` must suit the scale of the data for lam/Q='tune': P0 / R (in the "
                         "signals' units) is too diffuse for double precision for the record "
                         "scaled to unit size; pass P0 and R in the signals' units (P0 about "
                         "1e4 * R / max|phi_k|^2 for parameter k), or leave P0 out")
    if not np.max(np.abs(Q), initial=0.0) <= COVARIANCE_MAX:
        raise ValueError("`Q` must suit the scale of the data for lam='tune': Q / R (in the "
                         "signals' units) is beyond the range of the recursion for the record "
                         "scaled to unit size; pass a smaller Q or scale the signals")
    return P, Q


def tuned_random_walk(q, R, c):
    r"""``Q="tune"``'s random walk from its estimate `q`: :math:`\tilde Q = q R I` in the
    record's units (isotropic there; ``R`` the option in the signals' units, :math:`r = 0`)
    and its image :math:`Q_{kl} = 2^{-c_k - c_l}\tilde Q_{kl}` in the signals' units
    (``0`` or subnormal where it underflows). `q`, `R` scalars, `c` ``(n,)``; or arrays
    ``(C,)`` and ``(C, n)``. A ValueError names ``Q`` and ``R`` where the image is beyond
    the filters' range (``COVARIANCE_MAX``: a filter in the signals' units cannot hold it).
    """
    q, R = np.asarray(q, dtype=float), np.asarray(R, dtype=float)
    Qs = (q * R)[..., None, None] * np.eye(c.shape[-1])
    with np.errstate(over="ignore", under="ignore"):
        Q = np.ldexp(Qs, -(c[..., :, None] + c[..., None, :]))
    if not np.max(Q, initial=0.0) <= COVARIANCE_MAX:
        raise ValueError("`Q='tune'` estimated a random walk q R I of the record scaled to unit "
                         f"size that is beyond the filters' range ({COVARIANCE_MAX:.0e}) in the "
                         f"signals' units (`R` given in them, {float(np.max(R)):.3g}; a "
                         "coefficient's random walk there is about q R / max|phi_k|^2, large "
                         "for `u` or `y` far below unit size): pass `R` of about the noise "
                         "variance of `y`, or scale the signals")
    return Qs, Q
