r"""Recursive prediction-error (RPEM) and pseudo-linear regression (RPLR) fits.

Both run the covariance update of `RecursiveLeastSquares` (the same
forgetting factor ``lam``, random walk ``Q``, noise variance ``R``, the
anti-windup forgetting modes and the outlier gate), with the regressor of
the gain replaced by the gradient of the predictor (RPEM) or by the
pseudo-linear regressor itself (RPLR); see
:mod:`rlsfilt.models._recursive_kernels` for the equations.

`RecursionState` is the one engine: :meth:`RecursionState.run` runs a
record through the compiled batch loop and :meth:`RecursionState.step` one
sample through the same compiled step (the streaming objects), so the two
agree bit for bit. `recursive_pem` is the batch fit of a record.

RPLR converges to the prediction-error estimate only when a
positive-realness condition holds (Ljung 1977; Ljung & Soderstrom 1983):
for ARMAX, :math:`\mathrm{Re}\{1/C(e^{i\omega})\} > 1/2` at every
frequency; for OE, the same with ``F``. In general each block of the
regressor must satisfy it with the filter that turns its pseudo-linear
regressor into the gradient (``D/C`` for ``a``, ``D/(C F_i)`` for ``b_i``
and ``f_i``, ``1/C`` for ``c`` and ``d``). `positive_real_margins` checks it
on a frequency grid at the final estimate, and `recursive_pem` warns with
:class:`~rlsfilt.NumericalWarning` when it fails, pointing to ``"rpem"``.

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
   Prentice Hall, 1999, ch. 11.
.. [2] L. Ljung and T. Soderstrom, *Theory and Practice of Recursive
   Identification*, MIT Press, 1983.
.. [3] L. Ljung, "On positive real transfer functions and the convergence of
   some recursive schemes", *IEEE Trans. Automatic Control* 22(4), 539-551,
   1977.
"""

import math
import warnings

import numpy as np

from .._lazy import lazy_module
from .._validation import check_covariance, check_int, check_lam, check_scalar, check_variance
from ..exceptions import NumericalWarning
from ..filters import _health
from ..filters import forgetting as _fg
from ._family import split_theta
from ._stability import stabilize_theta

__all__ = []

METHODS = ("rpem", "rplr")
_get_kernels = lazy_module("rlsfilt.models._recursive_kernels")


def _check_positive(value, name):
    value = check_scalar(value, name)
    if not (math.isfinite(value) and value > 0.0):
        raise ValueError(f"`{name}` must be a positive finite number; got {value}")
    return value


class RecursionState:
    r"""State of an RPEM/RPLR recursion: estimate, covariance and signal lags.

    Parameters
    ----------
    s : FamilyStructure
        Model orders.
    method : {"rpem", "rplr"}
        Gradient (``"rpem"``) or pseudo-linear regressor (``"rplr"``) in
        the gain.
    lam : float, default 1.0
        Forgetting factor in (0, 1] (its final value; see `lam_start`).
    lam_start, lam_rate : float, default 0.97 and 0.998
        Forgetting profile of the start-up (Ljung & Soderstrom 1983; Ljung
        1999, ch. 11): the factor of step ``t`` is
        :math:`\lambda(t) = r\,\lambda(t-1) + (1 - r)\,\lambda`,
        :math:`\lambda(0) = \min(\lambda_{start}, \lambda)`, so the early
        estimates, made with poor filters ``1/C``, ``1/F``, are forgotten
        (after ``3 / (1 - lam_rate)`` = 1500 steps the factor is within 5 %
        of ``lam - lam_start`` from `lam`). Without it, RPEM from a zero
        start with lam = 1 often stays trapped for tens of thousands of
        samples (measured on ARMAX, OE and BJ records of 20000 samples:
        up to 85 standard errors from the batch estimate without the
        profile, at most 0.7 with it). ``lam_start = 1`` switches the
        profile off.
    P0 : float or array_like, default 1e4
        Initial covariance (``P0 * I`` for a scalar), as `RecursiveLeastSquares`,
        in the units of the signals the recursion runs on (the model fits give
        it the image of the user's ``P0`` in their scaled units:
        :mod:`rlsfilt.models._units`).
    x0 : array_like, optional
        Initial estimate (zeros: ``A = C = D = F = 1``, ``B = 0``).
    R : float, default 1.0
        Noise variance in the gain denominator ``psi^T P psi + R``.
    Q : float or array_like, default 0.0
        Parameter random-walk covariance added in each time update.
    forgetting : str, default "exponential"
        One of the modes of `RecursiveLeastSquares` but ``"diagonal"``.
    forgetting_params : dict, optional
        Its constants (defaults as in `RecursiveLeastSquares`).
    gate : float, optional
        Skip the update when ``|eps| / sqrt(s)`` exceeds it.
    project : bool, default True
        Reflect ``C``, ``D``, ``F_i`` into the unit circle whenever an update
        leaves the stability region.
    check_every : int, default 100
        Health check period, as `RecursiveLeastSquares` (0 disables it):
        every `check_every` streaming steps, and at the end of :meth:`run`,
        ``P`` is tested for positive definiteness and its condition number;
        a failure issues one :class:`~rlsfilt.NumericalWarning`.
    cond_max : float, default 1e12
        Condition number of ``P`` beyond which the health check warns.
    """

    def __init__(self, s, method="rpem", *, lam=1.0, lam_start=0.97, lam_rate=0.998, P0=1e4,
                 x0=None, R=1.0, Q=0.0, forgetting="exponential", forgetting_params=None,
                 gate=None, project=True, check_every=100, cond_max=1e12):
        if method not in METHODS:
            raise ValueError(f"`method` must be 'rpem' or 'rplr'; got {method!r}")
        n = s.n_params
        k = _get_kernels()
        # the scalars the compiled step reads and writes (lam_now, lam_t: properties)
        self._fpar = np.zeros(k.F_SIZE)
        self.s = s
        self.method = method
        self.mode = _fg.mode_code(forgetting)
        if self.mode == _fg.DIAGONAL:
            raise ValueError("`forgetting` must not be 'diagonal' for the recursive "
                             f"prediction-error fits ({method!r}: one `lam`, with its start-up "
                             "profile); a factor per parameter is a mode of "
                             "RecursiveLeastSquares (ARX.fit(method='rls'))")
        self.R = check_variance(R, "R")
        self.lam = check_lam(lam)
        self.lam_now = min(check_lam(lam_start, "lam_start"), self.lam)
        self.lam_rate = check_scalar(lam_rate, "lam_rate")
        if not 0.0 <= self.lam_rate < 1.0:
            raise ValueError(f"`lam_rate` must be in [0, 1); got {self.lam_rate}")
        self.params = np.array(_fg.mode_params(self.mode, forgetting_params, n, self.lam, self.R),
                               dtype=np.float64)
        Qm = check_covariance(Q, n, "Q")
        self.q_zero = not Qm.any()
        self.Q = np.ascontiguousarray(Qm) if not self.q_zero else np.zeros((0, 0))
        self.gate = None if gate is None else _check_positive(gate, "gate")
        # the filters' configuration (its lam is written by each step: the start-up profile)
        self._cfg = _fg.kernel_config(self.mode, self.lam, self.params, self.gate)
        self.project = bool(project)
        self.check_every = check_int(check_every, "check_every", minimum=0)
        self.cond_max = _check_positive(cond_max, "cond_max")
        self._since_check = 0
        self._warned_health = False
        P = check_covariance(P0, n, "P0", definite=True)
        if x0 is None:
            theta = np.zeros(n)
        else:
            theta = np.array(x0, dtype=float).reshape(-1)
            if theta.shape != (n,):
                raise ValueError(f"`x0` must have n_params = {n} entries; got {theta.size}")
            if not np.isfinite(theta).all():
                raise ValueError("`x0` must be finite")
            if self.project:
                theta, _ = stabilize_theta(theta, s)
        if self.mode == _fg.EFRA:          # start inside EFRA's invariant set
            lo, hi = _fg.efra_bounds(self.lam, *self.params)
            P = _fg.clip_eigenvalues(P, lo * self.R, hi * self.R)
        self.theta = np.ascontiguousarray(theta, dtype=np.float64)
        self.P = np.ascontiguousarray(P, dtype=np.float64)
        nu = s.n_inputs
        self.buf = np.zeros((6 + 6 * nu, s.max_lag + 1))
        sl = s.slices()
        self._ints = dict(
            na=s.na, nb=np.array(s.nb, dtype=np.int64), nc=s.nc, nd=s.nd,
            nf=np.array(s.nf, dtype=np.int64), nk=np.array(s.nk, dtype=np.int64),
            off_b=np.array([b.start for b in sl["b"]], dtype=np.int64),
            off_c=sl["c"].start, off_d=sl["d"].start,
            off_f=np.array([f.start for f in sl["f"]], dtype=np.int64))
        self.n_reflections = 0
        self.n_steps = 0
        self.lam_t = self.lam
        self._work = None
        # the packed arguments of the streaming step (see _recursive_kernels.rpem_stream)
        i = self._ints
        self._spec = np.array(
            [s.na, s.nc, s.nd, i["off_c"], i["off_d"], 0 if method == "rpem" else 1,
             self.project, nu]
            + [int(v) for key in ("nb", "nf", "nk", "off_b", "off_f") for v in i[key]],
            dtype=np.int64)
        f = self._fpar
        f[k.F_LAM], f[k.F_LAM_RATE], f[k.F_R] = self.lam, self.lam_rate, self.R

    @property
    def lam_now(self):
        """Forgetting factor of the next step (the start-up profile)."""
        return float(self._fpar[_get_kernels().F_LAM_NOW])

    @lam_now.setter
    def lam_now(self, value):
        self._fpar[_get_kernels().F_LAM_NOW] = value

    @property
    def lam_t(self):
        """Forgetting factor the last step applied."""
        return float(self._fpar[_get_kernels().F_LAM_T])

    @lam_t.setter
    def lam_t(self, value):
        self._fpar[_get_kernels().F_LAM_T] = value

    @property
    def frozen(self):
        """Whether adaptation is off: a step moves the signals through the filters of
        the held ``theta`` but leaves ``theta``, ``P`` and the forgetting profile as
        they are."""
        return bool(self._fpar[_get_kernels().F_FROZEN])

    @frozen.setter
    def frozen(self, value):
        self._fpar[_get_kernels().F_FROZEN] = 1.0 if value else 0.0

    def _common(self):
        i = self._ints
        return (i["na"], i["nb"], i["nc"], i["nd"], i["nf"], i["nk"], i["off_b"], i["off_c"],
                i["off_d"], i["off_f"], 0 if self.method == "rpem" else 1, self._cfg,
                self.lam, self.lam_now, self.lam_rate, self.Q, self.R, self.project)

    def run(self, y, U):
        """Run the compiled recursion over ``y`` (N,) and ``U`` (N, nu); returns histories.

        Returns
        -------
        dict
            ``theta_history`` (N, n), ``yhat`` and ``eps`` (N,), ``gated``
            (N,) bool.
        """
        y = np.ascontiguousarray(y, dtype=np.float64)
        U = np.ascontiguousarray(U, dtype=np.float64).reshape(len(y), self.s.n_inputs)
        N, n = len(y), self.s.n_params
        out = {"theta_history": np.empty((N, n)), "yhat": np.empty(N), "eps": np.empty(N),
               "gated": np.zeros(N, dtype=np.bool_)}
        if self.frozen:                    # the streaming step, sample by sample
            for t in range(N):
                out["yhat"][t], out["eps"][t], out["gated"][t] = self.step(float(y[t]), U[t])
                out["theta_history"][t] = self.theta
            return out
        k = _get_kernels()
        lam_now, lam_t, n_refl = k.rpem_batch(self.theta, self.P, self.buf, y, U,
                                              *self._common(), out["theta_history"],
                                              out["yhat"], out["eps"], out["gated"])
        if N:
            self.lam_now, self.lam_t = lam_now, lam_t
        self.n_reflections += n_refl
        self.n_steps += N
        if N and self.check_every and np.isfinite(self.P).all():   # (non-finite: the caller)
            self._check_health()
        return out

    def _check_health(self):
        """One warning when ``P`` stops being a healthy covariance (see `check_every`)."""
        self._since_check = 0
        if self._warned_health:
            return
        problem = _health.symmetric_problem(self.P, self.cond_max)
        if problem is not None:
            self._warned_health = True
            _health.warn(f"{self.method}: {problem} after sample {self.n_steps}",
                         "Lower P0, use forgetting that bounds P (directional, constant_trace, "
                         "efra) or a random walk Q, or check the scaling and excitation of "
                         "the data")

    def restart(self):
        """A new experiment: the signal lags start from rest again (zero), while the
        estimate, ``P`` and the forgetting profile carry on."""
        self.buf[:] = 0.0

    def step(self, y, u):
        """One sample through the compiled step; returns ``(yhat, eps, gated)``.

        `y` is a float and `u` a float64 array of shape (nu,) (validated by
        the caller): the work arrays are allocated on the first call, then
        every call is one compiled call on preallocated arrays.
        """
        if self._work is None:
            n = self.s.n_params
            self._work = (np.empty((5, n)), np.empty((n, n)))
            k = _get_kernels()
            self._kernel, self._out = k.rpem_stream, (k.F_GATED, k.F_REFL)
        f = self._fpar
        yhat, eps = self._kernel(self.theta, self.P, self.buf, y, u, self._spec, f,
                                 self._cfg, self.Q, *self._work)
        gated, refl = self._out
        self.n_reflections += int(f[refl])
        self.n_steps += 1
        self._since_check += 1
        if self._since_check == self.check_every:
            self._check_health()
        return yhat, eps, f[gated] != 0.0

    def adopt(self, other, theta, P, input_exponents, output_exponent):
        """Take the state of `other`, the same recursion run on the record with input ``i``
        divided by ``2^input_exponents[i]`` and the output by ``2^output_exponent``: the
        estimate `theta` and covariance `P` (already in this recursion's units), the
        signal lags (mapped back exactly: ``y``, ``eps``, ``v``, ``w_i`` and their filtered
        forms in the units of ``y``, ``u_i`` and its filtered forms in those of ``u_i``),
        the forgetting profile and the counters. ``R``, ``Q`` and the options stay this
        recursion's own."""
        k = _get_kernels()
        e = np.full(self.buf.shape[0], output_exponent, dtype=int)
        for i, ei in enumerate(input_exponents):
            base = k.N_SIG_BASE + k.N_SIG_INPUT * i
            e[base + k.SIG_U] = e[base + k.SIG_P] = e[base + k.SIG_UF] = ei
        with np.errstate(over="ignore", under="ignore"):
            self.buf = np.ldexp(other.buf, e[:, None])
        self.theta = np.ascontiguousarray(theta, dtype=np.float64)
        self.P = np.ascontiguousarray(P, dtype=np.float64)
        R = self._fpar[k.F_R]
        self._fpar[:] = other._fpar
        self._fpar[k.F_R] = R
        self.n_reflections, self.n_steps = other.n_reflections, other.n_steps
        self._since_check, self._warned_health = other._since_check, other._warned_health
        self._work = None

    @property
    def phi(self):
        """Regressor of the last step (after :meth:`step`)."""
        return None if self._work is None else self._work[0][0].copy()

    def copy(self):
        """An independent copy: the arrays a step writes (``theta``, ``P``, the signal
        buffer, the scalars, the filters' configuration and the work rows) are copied,
        the read-only configuration is shared (a tenth of the cost of a deep copy:
        every `batch` of the streaming objects runs on a copy)."""
        import copy

        new = copy.copy(self)
        for name in ("theta", "P", "buf", "_fpar", "_cfg"):
            setattr(new, name, getattr(self, name).copy())
        if self._work is not None:
            new._work = tuple(a.copy() for a in self._work)
        return new


def positive_real_margins(theta, s, n_grid=1024):
    r"""Smallest :math:`\mathrm{Re}\,L(e^{i\omega}) - 1/2` of each RPLR filter on a grid.

    The filters are those that turn the pseudo-linear regressor of a block
    into its gradient: ``D/C`` for block ``a``, ``D/(C F_i)`` for blocks
    ``b_i`` and ``f_i``, ``1/C`` for blocks ``c`` and ``d``, each written
    with only the polynomials the structure estimates (``"1/C"`` for ARMAX,
    ``"1/F"`` for OE, ``"D/(C F)"`` for BJ). Structural identities (ARX)
    are not listed.

    Parameters
    ----------
    theta : ndarray, shape (n_params,)
    s : FamilyStructure
    n_grid : int, default 1024
        Frequencies ``0 .. pi``.

    Returns
    -------
    dict
        Filter name to ``(margin, omega)``: the smallest value of
        :math:`\mathrm{Re}\,L - 1/2` and where it occurs. A negative margin
        means the condition fails.

    Examples
    --------
    Ljung's example ``C = 1 + 1.6 q^-1 + 0.8 q^-2`` fails the condition,
    ``C = 1 + 0.5 q^-1 + 0.2 q^-2`` meets it:

    >>> import numpy as np
    >>> from rlsfilt.models._family import family_structure
    >>> from rlsfilt.models._recursive_pem import positive_real_margins
    >>> s = family_structure(nc=2, n_inputs=0)
    >>> positive_real_margins(np.array([1.6, 0.8]), s)["1/C"][0] < 0
    True
    >>> positive_real_margins(np.array([0.5, 0.2]), s)["1/C"][0] > 0
    True
    """
    _, _, C, D, F = split_theta(theta, s)
    w = np.linspace(0.0, np.pi, n_grid)
    z1 = np.exp(-1j * w)

    def freq(p):
        return np.polyval(np.asarray(p, dtype=float)[::-1], z1)

    Cw, Dw = freq(C), freq(D)
    filters = {}

    def add(with_d, with_c, f_index):
        """Record the filter D^with_d / (C^with_c F_i); identity filters are skipped."""
        den = ["C"] if with_c else []
        L = (Dw if with_d else np.ones_like(Cw)) / (Cw if with_c else 1.0)
        if f_index is not None:
            den.append("F" if s.n_inputs == 1 else f"F_{f_index + 1}")
            L = L / freq(F[f_index])
        if not with_d and not den:
            return
        if not den:
            name = "D"
        else:
            name = ("D/" if with_d else "1/") + (den[0] if len(den) == 1
                                                 else "(" + " ".join(den) + ")")
        filters[name] = L

    if s.na:
        add(s.nd > 0, s.nc > 0, None)
    for i in range(s.n_inputs):
        add(s.nd > 0, s.nc > 0, i if s.nf[i] else None)
    if s.nc or s.nd:
        add(False, s.nc > 0, None)
    out = {}
    for name, L in filters.items():
        m = np.real(L) - 0.5
        k = int(np.argmin(m))
        out[name] = (float(m[k]), float(w[k]))
    return out


class RecursiveFit:
    """Result of `recursive_pem`: final estimate and histories.

    Attributes
    ----------
    theta : ndarray, shape (n_params,)
        Estimate after the last sample.
    P : ndarray, shape (n_params, n_params)
        Final covariance matrix of the recursion (``R`` times the scaled
        inverse information; with ``lam = 1`` and ``R = 1``,
        ``noise_variance * P`` estimates the covariance of ``theta``).
    theta_history : ndarray, shape (N, n_params)
        Estimate after each sample.
    yhat, eps : ndarray, shape (N,)
        One-step predictions and a-priori prediction errors of the run.
    gated : ndarray of bool, shape (N,)
    noise_variance : float
        Mean square of ``eps`` over the second half of the record (where
        the recursion has converged).
    state : RecursionState
        The recursion after the last sample, ready for more.
    margins : dict or None
        ``"rplr"``: `positive_real_margins` at the final estimate.
    """

    def __init__(self, **kw):
        self.__dict__.update(kw)


def recursive_pem(U, y, s, method="rpem", *, stacklevel=2, **options):
    """Fit the model family recursively (RPEM or RPLR) over a record.

    Parameters
    ----------
    U : ndarray, shape (N, nu)
        Inputs (``nu = 0`` for a time series).
    y : ndarray, shape (N,)
        Output.
    s : FamilyStructure
    method : {"rpem", "rplr"}
    stacklevel : int, default 2
        Of the positive-realness warning.
    **options
        Of `RecursionState`: ``lam``, ``lam_start``, ``lam_rate``, ``P0``,
        ``x0``, ``R``, ``Q``, ``forgetting``, ``forgetting_params``, ``gate``,
        ``project``, ``check_every``, ``cond_max``.

    Returns
    -------
    RecursiveFit

    Warns
    -----
    NumericalWarning
        ``"rplr"`` whose final estimate fails the positive-realness
        condition (the pseudo-linear regression may have converged to a
        wrong point; use ``"rpem"``), or a final ``P`` that is not finite.

    Examples
    --------
    Extended least squares (RPLR) of an ARMAX(1, 1, 1, 1) system:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.models._family import family_structure
    >>> from rlsfilt.models._recursive_pem import recursive_pem
    >>> rng = np.random.default_rng(1)
    >>> u, e = rng.standard_normal(20000), 0.5 * rng.standard_normal(20000)
    >>> y = lfilter([0, 1.0], [1, -0.7], u) + lfilter([1, 0.4], [1, -0.7], e)
    >>> s = family_structure(na=1, nb=1, nc=1, nk=1)
    >>> fit = recursive_pem(u[:, None], y, s, method="rplr")
    >>> np.round(fit.theta, 1)
    array([-0.7,  1. ,  0.4])
    """
    return recursive_pem_records([(U, y)], s, method, stacklevel=stacklevel + 1, **options)


def recursive_pem_records(records, s, method="rpem", *, stacklevel=2, **options):
    """`recursive_pem` over several experiments, one after the other.

    At each experiment boundary the recursion restarts its regressor and
    filter signals from rest (`RecursionState.restart`), so no regressor
    pairs samples of two experiments, while the estimate, ``P`` and the
    forgetting profile carry on. The histories hold every experiment's
    samples one after the other.

    Parameters
    ----------
    records : list of (ndarray (N_i, nu), ndarray (N_i,))
    s, method, stacklevel, **options
        As `recursive_pem`.

    Returns
    -------
    RecursiveFit
    """
    state = RecursionState(s, method, **options)
    runs = []
    for i, (U, y) in enumerate(records):
        if i:
            state.restart()
        runs.append(state.run(y, U))
    out = {k: np.concatenate([r[k] for r in runs]) for k in runs[0]}
    N = len(out["eps"])
    tail = out["eps"][N // 2:]
    fit = RecursiveFit(theta=state.theta.copy(), P=state.P.copy(),
                       theta_history=out["theta_history"], yhat=out["yhat"], eps=out["eps"],
                       gated=out["gated"],
                       noise_variance=float(np.mean(tail ** 2)) if len(tail) else math.nan,
                       state=state, margins=None, n_reflections=state.n_reflections)
    if not np.isfinite(state.P).all() or not np.isfinite(state.theta).all():
        warnings.warn(f"{method}: the recursion diverged (non-finite estimate or covariance); "
                      "lower P0, use forgetting that bounds P, or check the data scaling",
                      NumericalWarning, stacklevel=stacklevel)
    elif method == "rplr":
        fit.margins = positive_real_margins(state.theta, s)
        failing = {k: v for k, v in fit.margins.items() if v[0] <= 0.0}
        if failing:
            name, (margin, omega) = min(failing.items(), key=lambda kv: kv[1][0])
            warnings.warn(
                f"rplr: the positive-real condition Re{{{name}}} > 1/2 fails at the final "
                f"estimate (Re{{{name}}} - 1/2 = {margin:.3g} at omega = {omega:.3g} rad/sample): "
                "the pseudo-linear regression need not converge to the prediction-error "
                "estimate; use method='rpem' (gradient-filtered regressors) instead",
                NumericalWarning, stacklevel=stacklevel)
    return fit
