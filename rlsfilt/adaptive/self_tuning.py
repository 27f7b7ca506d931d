r"""The indirect self-tuning regulator: identify ``A, B`` online, redesign, control.

At every sample the regulator (Astrom & Wittenmark, *Adaptive Control*,
ch. 3)

1. updates the estimate of the ARX model :math:`A(q^{-1}) y(t) = B(q^{-1})
   u(t) + e(t)` with any rlsfilt filter and the regressor
   :math:`\varphi(t) = [-y(t-1), \dots, -y(t-n_a), u(t-n_k), \dots,
   u(t-n_k-n_b+1)]`;
2. redesigns the controller from the estimated ``A, B`` (every sample, or
   every ``k`` samples) with a design function such as `rst_design`;
3. computes :math:`u(t)` from :math:`R u = T r - S y`.

Safeguards keep the loop sane when the data are poor: a dead zone on the
prediction error, projection of the estimate onto a box, keeping the last
good controller when the estimated ``A`` and ``B`` (nearly) share a factor,
and an excitation monitor that warns when the regressors stop exciting the
parameters or the covariance winds up.
"""

import functools
import math
import warnings

import numpy as np

from .._iosystem import call_capturing, make_iosystem
from .._lazy import lazy_module
from .._validation import check_dt, check_int, check_real, check_scalar
from ..exceptions import ExcitationWarning, RegulatorWarning
from ..filters import _filter_state
from ..filters.contract import restore_filter, snapshot_filter, vector_step_constants
from ._polynomials import coprimeness, degree, fmt_complex, padd, roots, trim
from .rst import RSTController, _prepared_design, rst_design

__all__ = ["SelfTuningRegulator", "STRHistory"]

_kernels = lazy_module("rlsfilt.adaptive._kernels_design")

# names of the scalar bookkeeping entries of the state vector, in order
_SCALARS = ("have_controller", "step", "trace_ref", "warned_excitation", "warned_windup",
            "n_rejected", "rejected_run", "warned_rejected", "warned_reduced",
            "warned_saturation", "size_last", "sat_block", "err2_block", "err2_prev",
            "level_mean", "level_m2", "level_min")
# the operating-point check: without `offset`, warn if over the first _LEVEL_WINDOW samples
# the output stays more than _LEVEL_RATIO of its standard deviations away from zero
_LEVEL_WINDOW, _LEVEL_RATIO = 50, 3.0
_I = {name: i for i, name in enumerate(_SCALARS)}


class SelfTuningRegulator:
    r"""Indirect self-tuning regulator: online ARX identification plus controller redesign.

    Parameters
    ----------
    estimator : RecursiveLeastSquares, SquareRootRLS or SlidingWindowRLS
        The filter that estimates :math:`\theta = [a_1 .. a_{n_a}, b_1 ..
        b_{n_b}]` (``dim_x = na + nb``, ``dim_z = 1``; with `offset`,
        ``[.., c]`` and ``dim_x = na + nb + 1``); its forgetting
        factor, window and prior are the tuning of the estimation. The
        regulator updates it in place.
    design : callable or dict
        ``design(A, B) -> RSTController`` from the estimated polynomials
        (ascending powers of :math:`q^{-1}`, ``B`` with ``nk`` leading
        zeros), for example ``functools.partial(rst_design, Am=Am,
        Ao=Ao)``; a dict is shorthand for that: the keyword arguments of
        `rst_design`. A design that raises `ValueError` is skipped (the last
        controller is kept).
    na, nb : int
        Orders of the estimated model (``na >= 0``, ``nb >= 1``).
    nk : int, default 1
        Delay of the model, ``>= 1`` (``u(t)`` is computed after ``y(t)``
        is measured, so it cannot enter the estimate of ``y(t)``).
    redesign_every : int, default 1
        Redesign at samples ``0, k, 2k, ..``.
    initial : RSTController, optional
        Controller used until the first accepted design. By default the
        design of the estimator's initial estimate, if it is acceptable;
        otherwise ``u = 0`` (plus `dither`) until one is.
    dead_zone : float, default 0.0
        Skip the estimator update when the a-priori prediction error
        :math:`|e(t)| \le` `dead_zone` (robustness to bounded disturbances
        and unmodelled dynamics; Egardt 1979).
    bounds : (lower, upper), optional
        Box for the estimate (scalars or arrays of ``na + nb`` entries,
        ``-inf``/``inf`` allowed): after each update the estimate is
        projected (clipped) onto it, and the projected value replaces the
        estimator's ``x``. Typically used to keep the sign of ``b1``.
    offset : bool, default False
        Estimate a constant ``c`` too, :math:`A y = B u + c + e` (a regressor
        ``1``, as ``ARX(offset=True)``): the model of a plant linearized
        about an operating point far from zero (a tank, a heater). Without
        it the estimate of ``A, B`` is biased by the operating point. The
        control law subtracts the estimated offset's input, :math:`R (u -
        u_c) = T r - S y` with :math:`u_c = -c / B(1)` (with integral action
        ``R(1) = 0`` and the term vanishes: the integrator takes care of
        it). See the guide's tank example. Without it, a `RegulatorWarning`
        (once) says so when every measured output of the first 50 samples
        is more than 3 of their standard deviations away from zero.
    coprime_tol : float, default 1e-4
        The full-order design is not tried when the estimated ``A`` and
        ``B`` nearly share a factor: the smallest singular value
        :math:`\sigma` of their Sylvester matrix (coefficients scaled to
        unit norm) is below this.
    reduce_tol : float, default 1e-2
        Below this :math:`\sigma` the regulator also designs on the reduced
        model: the estimate with its closest pole/zero pair (a conjugate pair
        of each, for complex roots) removed, as a model one order too large
        nearly cancels its extra pole against a zero. The full design is
        used only if it is at most `max_growth` times the size of the reduced
        one; so no single threshold decides between a controller of size
        ``1/sigma`` and a sane one. A `RegulatorWarning` says so the first
        time. ``0`` switches it off.
    max_growth : float, default 10.0
        Every design is verified before it is used: its ``A R + B S`` on the
        model it was designed for equals its ``target`` (``rst_design``
        sets it) to ``1e-8`` relative to the terms; the loop closed around
        the full estimate is stable; and its size :math:`(\|R\|_1 +
        \|S\|_1 + \|T\|_1) / |r_0|` is at most `max_growth` times the size
        of the controller in use. A design that fails is rejected (the
        controller in use is kept), so a controller grows by at most this
        factor per redesign.
    stable_R : bool, default False
        Also reject designs whose ``R`` has a zero outside the closed unit
        disk (an unstable controller).
    patience : int, default 50
        Warn (`~rlsfilt.RegulatorWarning`, once until a design is accepted
        again) when this many redesigns in a row are rejected, or when there
        is still no controller after this many: the loop runs on an old
        controller or open.
    signal_limit : float, default 1e100
        Largest magnitude of ``y``, ``r``, ``dither`` and the computed ``u``
        the regulator accepts; beyond it (or at NaN or inf) :meth:`step`
        raises a `ValueError` that names the signal and the step, and leaves
        the regulator as it was (the estimator's products of signals would
        otherwise overflow a few steps later, in a less clear place).
    u_limits : (float, float), optional
        Saturation of the applied control; the saturated value enters the
        regressor (and the controller's memory), the usual anti-windup of
        RST controllers (see Notes).
    monitor_every : int, default 200
        Length of the blocks of the excitation monitor and of the
        saturation watchdog; ``0`` switches both off. The watchdog warns
        (`~rlsfilt.RegulatorWarning`, once) at the end of a block in which
        ``u`` sat at a limit at least half the time while the RMS tracking
        error ``r - y`` did not fall from the block before.
    excitation_tol : float, default 1e-8
        Warn (`~rlsfilt.ExcitationWarning`) when, over a block, the smallest
        eigenvalue of :math:`\sum \varphi\varphi^T` falls below this
        fraction of the largest: the data carry no information in some
        direction of the parameters.
    windup_ratio : float, default 1e3
        Warn when ``trace(P)`` exceeds this multiple of its reference value:
        ``trace(P)`` at the end of the last monitor block that was well
        excited, or at construction before any (covariance windup under
        forgetting: without excitation ``P`` grows like ``lam**-k``).
    max_order : int, optional
        Largest degree of ``R``, ``S`` and ``T`` the designs may return
        (sets the size of the controller's memory); ``na + nk + nb`` by
        default, enough for `rst_design` with integral action.
    dt : True or float, default True
        Sampling period (python-control's ``dt``).

    Attributes
    ----------
    estimator : filter
        The estimator (updated in place).
    history : STRHistory
        Everything the regulator saw and did, one row per :meth:`step`.
    controller : RSTController or None
        The controller in use.
    theta : ndarray, shape (na + nb,)
        The current estimate (after projection).
    state : ndarray
        The complete internal state as one vector (the state of
        :meth:`as_iosystem`).

    Notes
    -----
    One call of :meth:`step` with measurement :math:`y(t)` and reference
    :math:`r(t)`:

    .. math::

        e(t) &= y(t) - \varphi(t)^T \hat\theta(t-1)
            \qquad \text{(skip the update if } |e| \le \text{dead zone)} \\
        \hat\theta(t) &= \Pi_{box}\big(\text{estimator update with }
            (y(t), \varphi(t))\big) \\
        (R, S, T) &= \text{design}(\hat A, \hat B)
            \qquad \text{(every } k \text{ samples; kept if } \hat A, \hat B
            \text{ nearly share a factor)} \\
        u(t) &= \operatorname{sat}\Big(\big(T r - S y
            - (R - r_0) u\big)(t) / r_0 + \text{dither}(t)\Big)

    With ``lam = 1``, white equation error and enough excitation the
    estimate converges to the true ``A, B`` and the controller to the
    design on the true plant (the certainty-equivalence principle; Astrom &
    Wittenmark 1995, ch. 3 and 6).

    **Anti-windup.** The law above feeds the *applied* (saturated) ``u`` back
    through :math:`R - r_0`. That is Astrom & Wittenmark's anti-windup form
    :math:`A_o u = T r - S y + (A_o - R)\,\mathrm{sat}(u)` (1995, sec.
    11.2; 1997, sec. 9.4) with :math:`A_o = r_0` (a deadbeat observer for
    the controller's state during saturation), not with the design's
    :math:`A_o`. Both are the same controller while ``u`` is inside the
    limits. The regulator keeps this form because it holds for any design
    (also callables without an observer polynomial, and redesigns that change
    ``R`` every sample with no filter state in :math:`1/A_o` to carry over);
    the controller state after saturation is reset in :math:`\deg R`
    samples instead of following the observer's dynamics.

    **What is accepted.** Each due redesign goes through these steps:
    :math:`\sigma` = coprimeness of the estimated ``A, B``; the full design
    if :math:`\sigma \ge` `coprime_tol`; the reduced-model design if
    :math:`\sigma <` `reduce_tol`; the verification of each (`max_growth`);
    then the full design if it verified and is at most `max_growth` times
    the reduced one's size, else the reduced one, else the controller in use
    is kept (``history.rejected``) and, after `patience` such steps, a
    warning. A near-cancelling estimate thus neither leaves the controller
    at a cliff nor installs one with gains of order ``1/sigma``.

    References
    ----------
    .. [1] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 3 and 11.
    .. [2] B. Egardt, *Stability of Adaptive Controllers*, Springer, 1979.
    .. [3] G. C. Goodwin and K. S. Sin, *Adaptive Filtering, Prediction and
       Control*, Prentice Hall, 1984 (parameter projection).

    Examples
    --------
    Regulate ``y(t) - 1.5 y(t-1) + 0.7 y(t-2) = u(t-1) + 0.5 u(t-2) + e(t)``
    without knowing it, tracking a square wave:

    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.adaptive import SelfTuningRegulator
    >>> stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0),
    ...                            design=dict(Am=np.poly([0.5, 0.5]), Ao=np.poly([0.2])),
    ...                            na=2, nb=2, nk=1)
    >>> rng = np.random.default_rng(0)
    >>> y, u = np.zeros(600), np.zeros(600)   # y[-1], u[-1], .. are zero: the plant at rest
    >>> r = np.where(np.arange(600) % 100 < 50, 1.0, -1.0)
    >>> for t in range(600):
    ...     y[t] = (1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2]
    ...             + 0.01 * rng.standard_normal())
    ...     u[t] = stre.step(y[t], r[t], dither=0.01 * rng.choice([-1.0, 1.0]))
    >>> np.round(stre.theta, 2)
    array([-1.5,  0.7,  1. ,  0.5])
    >>> bool(np.sqrt(np.mean((y[-40:] - r[-40:]) ** 2)) < 0.05)     # RMS tracking error
    True
    """

    def __init__(self, estimator, design, *, na, nb, nk=1, redesign_every=1, initial=None,
                 dead_zone=0.0, bounds=None, offset=False, coprime_tol=1e-4, reduce_tol=1e-2,
                 max_growth=10.0, stable_R=False, patience=50, signal_limit=1e100,
                 u_limits=None, monitor_every=200, excitation_tol=1e-8, windup_ratio=1e3,
                 max_order=None, dt=True):
        self.na = check_int(na, "na", minimum=0)
        self.nb = check_int(nb, "nb", minimum=1)
        self.nk = check_int(nk, "nk", minimum=1)
        if not isinstance(offset, (bool, np.bool_)):
            raise TypeError(f"`offset` must be True or False; got {offset!r}")
        self.offset = bool(offset)
        n = self.na + self.nb + self.offset
        for attr in ("predict", "update", "x", "P"):
            if not hasattr(estimator, attr):
                raise TypeError(f"`estimator` must be an rlsfilt filter (predict, update, x, P); "
                                f"got {type(estimator).__name__} without `{attr}`")
        if getattr(estimator, "dim_x", None) != n or getattr(estimator, "dim_z", 1) != 1:
            what = "na + nb + 1 (offset)" if self.offset else "na + nb"
            raise ValueError(f"`estimator` must have dim_x = {what} = {n} and dim_z = 1; got "
                             f"dim_x = {getattr(estimator, 'dim_x', None)}, dim_z = "
                             f"{getattr(estimator, 'dim_z', None)}")
        self.estimator = estimator
        self._design_kwargs = dict(design) if isinstance(design, dict) else None
        if isinstance(design, dict):
            try:                    # the options checked once, not at every sample
                design = _prepared_design(**design)
            except (TypeError, ValueError):     # rst_design raises the same at each design
                design = functools.partial(rst_design, **design)
        if not callable(design):
            raise TypeError(f"`design` must be a callable design(A, B) -> RSTController or a "
                            f"dict of rst_design keywords; got {type(design).__name__}")
        self.design = design
        self._fast = None       # the compiled design's arguments, see _fast_design
        options = getattr(design, "options", None)
        if options is not None and options[3] == 0.0:   # rst_design, no zero cancelled
            Am, Ao, integral, _, tol, _ = options
            Acl = np.convolve(Am, Ao)
            self._fast = (design, np.ascontiguousarray(trim(Acl)), np.array(Ao, dtype=float),
                          float(Am.sum()), bool(integral), float(tol))
        self.redesign_every = check_int(redesign_every, "redesign_every", minimum=1)
        self.dead_zone = check_real(dead_zone, "dead_zone", minimum=0)
        self.bounds = None if bounds is None else _check_bounds(bounds, n)
        self.coprime_tol = check_real(coprime_tol, "coprime_tol", minimum=0)
        self.reduce_tol = check_real(reduce_tol, "reduce_tol", minimum=0)
        self.max_growth = check_real(max_growth, "max_growth", minimum=1)
        if not isinstance(stable_R, (bool, np.bool_)):
            raise TypeError(f"`stable_R` must be True or False; got {stable_R!r}")
        self.stable_R = bool(stable_R)
        self.patience = check_int(patience, "patience", minimum=1)
        self.signal_limit = check_real(signal_limit, "signal_limit", minimum=0, strict=True)
        self.u_limits = None if u_limits is None else _check_limits(u_limits)
        self.monitor_every = check_int(monitor_every, "monitor_every", minimum=0)
        self.excitation_tol = check_real(excitation_tol, "excitation_tol", minimum=0)
        self.windup_ratio = check_real(windup_ratio, "windup_ratio", minimum=1, strict=True)
        self.max_order = (self.na + self.nk + self.nb if max_order is None
                          else check_int(max_order, "max_order", minimum=0))
        self.dt = check_dt(dt)
        L = self.max_order + 1
        self._L = L
        # memories, newest first: y(t-1), .., u(t-1), .., r(t-1), ..
        self._ypast = np.zeros(max(self.na, L - 1))
        self._upast = np.zeros(max(self.nk + self.nb - 1, L - 1))
        self._rpast = np.zeros(L - 1)
        self._ctrl = np.zeros((3, L))      # rows R, S, T, zero-padded
        self._rows_work = np.zeros((3, L))     # scratch of the compiled design
        self._info = np.zeros((n, n))      # sum of phi phi^T over the monitor block
        self._scalars = np.zeros(len(_SCALARS))
        self._scalars[2] = float(np.trace(estimator.P))   # reference trace(P)
        self._records = []
        self._why = "no design was due yet"     # why the last design was rejected (messages)
        self._checked = {}      # id -> (controller, rows, size) of the last verified designs
        if initial is not None:
            self._install(initial, "initial")
        else:
            theta = self.theta
            if np.all(np.isfinite(theta)):
                ctrl, _, _ = self._try_design(*self._polynomials(theta), theta)
                if ctrl is not None:
                    self._install(ctrl, "design")

    # ------------------------------------------------------------------
    # the current estimate and controller
    # ------------------------------------------------------------------
    @property
    def theta(self):
        """The current estimate: the ``a`` coefficients, then the ``b`` (a copy)."""
        return np.array(self.estimator.x, dtype=float).reshape(-1).copy()

    @property
    def controller(self):
        """The controller in use, or None before the first accepted design."""
        if not self._scalars[0]:
            return None
        R, S, T = self._ctrl
        return RSTController(R, S, T, self.dt)

    def polynomials(self):
        """``(A, B)`` of the current estimate, ascending powers of ``q^-1``."""
        return self._polynomials(self.theta)

    def _polynomials(self, theta):
        na, nk = self.na, self.nk
        A = np.empty(na + 1)
        A[0] = 1.0
        A[1:] = theta[:na]
        B = np.zeros(nk + self.nb)
        B[nk:] = theta[na:na + self.nb]
        return A, B

    # ------------------------------------------------------------------
    # one sample
    # ------------------------------------------------------------------
    def step(self, y, r=0.0, dither=0.0):
        """Measure ``y(t)``, update the estimate and the controller, return ``u(t)``.

        Parameters
        ----------
        y : float
            Measured output ``y(t)``.
        r : float, default 0.0
            Reference ``r(t)``.
        dither : float, default 0.0
            Added to the control (probing excitation); the applied value
            enters the regressor.

        Returns
        -------
        float
            The control ``u(t)`` to apply (saturated to `u_limits`).
        """
        y, r, v = (check_scalar(y, "y"), check_scalar(r, "r"), check_scalar(dither, "dither"))
        u, record, messages = self._advance(y, r, v)
        self._records.append(record)
        for message, category in messages:
            warnings.warn(message, category, stacklevel=2)
        return u

    def _advance(self, y, r, v):
        """One sample: returns ``(u, record, messages)``; a failure restores the state."""
        snapshot = self._snapshot()
        try:
            return self._advance_unsafe(y, r, v)
        except BaseException:
            self._restore_snapshot(snapshot)
            raise

    def _advance_unsafe(self, y, r, v):
        """One sample in place, ``(u, record, messages)`` (a failure may leave part of
        it done: `_advance` undoes it)."""
        return self._conclude(self._decide(y, r, v))

    def _decide(self, y, r, v):
        """The part of a sample that sets ``u``: the checks of the signals, the
        estimator's update, the projection, the redesign and the control law.

        Returns ``[k, y, r, phi, e, theta, updated, redesigned, rejected, reduced, u,
        saturated, messages before the estimator's, the estimator's, messages after]``,
        for :meth:`_conclude`.
        """
        na, nb, nk = self.na, self.nb, self.nk
        est = self.estimator
        before = []
        k = int(self._scalars[1])
        lim = self.signal_limit
        if not (math.isfinite(y) and math.isfinite(r) and math.isfinite(v)
                and abs(y) <= lim and abs(r) <= lim and abs(v) <= lim):
            for value, name in ((y, "y"), (r, "r"), (v, "dither")):
                self._check_signal(value, name, k)
        if not self.offset and k < _LEVEL_WINDOW:
            before = self._check_level(y, k)
        # regressor phi(t) = [-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1) (, 1)]
        phi = np.empty(na + nb + self.offset)
        np.negative(self._ypast[:na], out=phi[:na])
        phi[na:na + nb] = self._upast[nk - 1:nk - 1 + nb]
        if self.offset:
            phi[-1] = 1.0
        theta = np.array(est.x, dtype=float).reshape(-1)     # a copy, as self.theta
        e = _kernels().prediction_error(y, phi, theta)      # e = y - phi^T theta, a priori
        updated = self.dead_zone == 0.0 or abs(e) > self.dead_zone
        caught = []
        if updated:
            _, caught = call_capturing(est.predict_update, y, phi)
            theta = np.array(est.x, dtype=float).reshape(-1)
            self._check_estimate(k, y, phi)
        if self.bounds is not None:               # projection onto the box
            clipped = np.empty(len(theta))
            if _kernels().project_box(theta, *self.bounds, clipped):
                est.x = clipped.reshape(-1, 1)
                theta = clipped
        messages = []
        redesigned = k % self.redesign_every == 0
        rejected = reduced = False
        # the common case: the full design accepted and the law, in one compiled call
        u = self._fast_design(theta, y, r) if redesigned else None
        if redesigned and u is None:
            A, B = self._polynomials(theta)
            ctrl, kind, messages = self._try_design(A, B, theta)
            if ctrl is not None:
                self._install(ctrl, "design")
                reduced = kind == "reduced"
                self._scalars[_I["rejected_run"]] = 0.0
                self._scalars[_I["warned_rejected"]] = 0.0
                if reduced and not self._scalars[_I["warned_reduced"]]:
                    self._scalars[_I["warned_reduced"]] = 1.0
                    messages.append((
                        f"SelfTuningRegulator: at step {k} the estimate nearly cancels a pole "
                        f"against a zero ({self._why}); the controller is designed on the model "
                        "with that pair removed (reduce_tol). The model is probably too large "
                        "(by one order for a real pair, two for a complex one): consider "
                        "smaller na, nb", RegulatorWarning))
            else:
                rejected = True
                self._scalars[5] += 1
                self._scalars[_I["rejected_run"]] += 1
        if not self._scalars[0] or rejected:
            run = self._scalars[_I["rejected_run"]] if self._scalars[0] else k + 1
            if run >= self.patience and not self._scalars[_I["warned_rejected"]]:
                self._scalars[_I["warned_rejected"]] = 1.0
                state = ("the controller designed at an earlier step is still in use" if
                         self._scalars[0] else "there is no controller: the loop is open "
                         "(u = dither)")
                messages.append((
                    f"SelfTuningRegulator: {int(run)} redesigns in a row up to step {k} were "
                    f"rejected (the last because {self._why}); {state}. Check the model "
                    "orders, the excitation and the design (Am, Ao)", RegulatorWarning))
        # control law R (u - u_c) = T r - S y, with the past from the memories
        if self._scalars[0]:
            if u is None:           # (the compiled design computed it with the controller)
                u = _kernels().control_law(self._ctrl, self._rpast, self._ypast, self._upast,
                                           y, r)
            if self.offset:         # + u_c R(1) / r0, u_c = -c / B(1) (when B(1) is not 0)
                applies, u_c = _kernels().offset_control(theta, na, nb, self._ctrl[0])
                if applies:
                    u += u_c
        else:
            u = 0.0
        u = u + v
        self._check_signal(u, "u", k, computed=True)
        saturated = False
        if self.u_limits is not None:
            saturated = not self.u_limits[0] < u < self.u_limits[1]
            u = min(max(u, self.u_limits[0]), self.u_limits[1])
        return [k, y, r, phi, e, theta, updated, redesigned, rejected, reduced, float(u),
                saturated, before, caught, messages]

    def _check_estimate(self, k, y, phi):
        """Raise if the estimator's estimate or covariance is not finite."""
        x, P = np.asarray(self.estimator.x), np.asarray(self.estimator.P)
        # a finite sum: every entry is finite (an inf or NaN entry makes it inf or NaN);
        # an overflowing sum of finite entries goes to the entry-wise test. (Python's sum
        # of the entries as floats: a tenth of the cost of NumPy's two reductions here)
        if math.isfinite(sum(x.ravel().tolist()) + sum(P.ravel().tolist())):
            return
        if not (np.isfinite(x).all() and np.isfinite(P).all()):
            raise ValueError(
                f"SelfTuningRegulator: the estimate became non-finite at step {k} (`y` = "
                f"{y:.6g}, largest |phi| = {np.max(np.abs(phi), initial=0.0):.6g}): the "
                "loop or the estimator diverged; the regulator is left as before this step")

    def _conclude(self, decided, record=True):
        """The rest of a sample after :meth:`_decide` and the estimator's step: the
        memories, the monitors, the step count. Returns ``(u, record or None,
        messages)``."""
        (k, y, r, phi, e, theta, updated, redesigned, rejected, reduced, u, saturated,
         before, caught, after) = decided
        messages = before + caught + after
        # the memories, the excitation monitor's sum, the saturation watchdog's block sums
        _kernels().remember(self._ypast, self._upast, self._rpast, self._info, self._scalars,
                            phi, y, u, r, float(saturated), _I["sat_block"], _I["err2_block"])
        # windup check, excitation monitor and saturation watchdog
        trace = _kernels().trace_of(np.ascontiguousarray(self.estimator.P, dtype=float))
        if trace > self.windup_ratio * self._scalars[2]:
            if not self._scalars[4]:
                self._scalars[4] = 1.0
                messages.append((
                    f"SelfTuningRegulator: trace(P) = {trace:.3g} at step {k} is more than "
                    f"windup_ratio = {self.windup_ratio:g} times its value {self._scalars[2]:.3g} "
                    "when the data last excited every parameter: the covariance is winding up "
                    "(forgetting without excitation); add excitation or use a forgetting mode "
                    "that bounds P (RecursiveLeastSquares(forgetting='directional'), ...)",
                    ExcitationWarning))
        else:
            self._scalars[4] = 0.0
        excitation = np.nan
        if self.monitor_every and (k + 1) % self.monitor_every == 0:
            ev = np.linalg.eigvalsh(self._info)
            excitation = float(ev[0] / ev[-1]) if ev[-1] > 0 else 0.0
            if excitation < self.excitation_tol:
                if not self._scalars[3]:
                    self._scalars[3] = 1.0
                    messages.append((
                        f"SelfTuningRegulator: the regressors of steps {k + 1 - self.monitor_every}"
                        f"..{k} do not excite every parameter (smallest / largest eigenvalue of "
                        f"sum phi phi^T = {excitation:.3g} < excitation_tol = "
                        f"{self.excitation_tol:.3g}); the estimate, and the controller designed "
                        "from it, stop improving: add excitation (reference changes or dither)",
                        ExcitationWarning))
            else:
                self._scalars[3] = 0.0
                self._scalars[2] = trace        # a well-excited block: the new reference
            self._info[:] = 0.0
            messages += self._watchdog(k)
        self._scalars[1] = k + 1
        if not record:
            return u, None, messages
        return u, (y, r, u, e, theta.copy(), trace, updated, redesigned, rejected,
                   self._ctrl.copy(), excitation, reduced), messages

    def _check_signal(self, value, name, k, computed=False):
        """Raise a `ValueError` naming the signal if it is not finite or beyond `signal_limit`."""
        if math.isfinite(value) and abs(value) <= self.signal_limit:
            return
        what = f"the computed `{name}`" if computed else f"`{name}`"
        if not np.isfinite(value):
            raise ValueError(f"`{name}` must be finite; got {value} at step {k}"
                             + (" (computed by the controller in use: the loop diverged)"
                                if computed else ""))
        if abs(value) > self.signal_limit:
            raise ValueError(
                f"{what} = {value:.3g} at step {k} exceeds signal_limit = "
                f"{self.signal_limit:.3g}: the loop is diverging (or the signal is in the wrong "
                "units); the regulator is left as before this step")

    def _check_level(self, y, k):
        """The operating-point check of a model without offset, one sample of the first
        window: a warning (once, at the window's end) if the output stayed far from zero.

        Every sample must stay away, not only the mean: a loop started from rest
        that steps to a constant reference also has a mean of several standard
        deviations over its first samples, but it starts at zero."""
        # Welford's running mean and sum of squared deviations of y(0) .. y(k)
        sc = self._scalars
        mean, m2 = sc[_I["level_mean"]], sc[_I["level_m2"]]
        delta = y - mean
        mean += delta / (k + 1)
        m2 += delta * (y - mean)
        low = abs(y) if k == 0 else min(sc[_I["level_min"]], abs(y))
        sc[_I["level_mean"]], sc[_I["level_m2"]], sc[_I["level_min"]] = mean, m2, low
        std = np.sqrt(m2 / (k + 1))
        if k + 1 < _LEVEL_WINDOW or not low > _LEVEL_RATIO * std:
            return []
        return [(f"SelfTuningRegulator: over the first {_LEVEL_WINDOW} samples the output "
                 f"stayed at least {low:.3g} away from zero ({low / std if std else np.inf:.3g} "
                 f"of its standard deviations; mean {mean:.3g}), and the model has no offset "
                 "(offset=False): an ARX model through the origin fitted about an operating "
                 "point biases the estimate and misses the designed poles. Use offset=True "
                 "(estimator dim_x = na + nb + 1) or deviation variables (subtract the operating "
                 "point before step); see 'Operating points: a tank' in the guide "
                 "(docs/guide/control.md)", RegulatorWarning)]

    def _watchdog(self, k):
        """At the end of a monitor block: saturation with an error that does not fall."""
        n = self.monitor_every
        sat = self._scalars[_I["sat_block"]] / n
        err2, prev = self._scalars[_I["err2_block"]], self._scalars[_I["err2_prev"]]
        self._scalars[_I["sat_block"]] = 0.0
        self._scalars[_I["err2_block"]] = 0.0
        self._scalars[_I["err2_prev"]] = err2
        if sat < 0.5 or err2 < prev or self._scalars[_I["warned_saturation"]]:
            return []
        self._scalars[_I["warned_saturation"]] = 1.0
        return [(f"SelfTuningRegulator: in steps {k + 1 - n}..{k} the control sat at a limit "
                 f"{100 * sat:.0f} % of the time and the RMS error r - y grew to "
                 f"{np.sqrt(err2 / n):.3g} (from {np.sqrt(prev / n):.3g} in the block before): "
                 "the controller in use cannot control the plant within u_limits. Check "
                 "history.rejected, the model orders and the design's speed (Am)",
                 RegulatorWarning)]

    def _fast_design(self, theta, y, r):
        """The common case of a redesign in one compiled call: the control ``u(t)``
        (before the offset, the dither and the limits) if the full design of the
        estimate `theta` was accepted and installed, else None.

        The decision, the controller and the law are those of the NumPy path
        (:meth:`_try_design`, then the law), which runs whenever this returns
        None: near a common factor, a design that `rst_design` refuses or that
        fails a check, another design function. Polynomials, design and law in
        one call (`_kernels_design.design_and_law`) instead of three with the
        Python between them: about 3 us less per sample of ``step`` and per
        look-ahead in a python-control diagram (``benchmarks/bench_diagrams.py``).
        """
        fast = self._fast
        if fast is None or self.design is not fast[0] or self.stable_R:
            return None
        try:
            status, u = _kernels().design_and_law(
                theta, self.na, self.nb, self.nk, *fast[1:], self.coprime_tol,
                self.reduce_tol, self.max_growth, self._scalars, _I["size_last"],
                _I["rejected_run"], _I["warned_rejected"], self._rows_work, self._ctrl,
                self._rpast, self._ypast, self._upast, y, r)
        except (ValueError, ZeroDivisionError, np.linalg.LinAlgError):
            return None
        if status != 0:
            return None
        self._checked = {}
        self._why = ""
        return u

    def _try_design(self, A, B, theta):
        """``(controller or None, "full" or "reduced", messages)`` for the estimate ``A, B``.

        A design is used only if it passes :meth:`_verify`; near a common
        factor the design on the reduced model competes (see the class Notes).
        """
        sigma = coprimeness(A, B)
        messages = []
        self._checked = {}
        full = reduced = None
        why = []
        if sigma >= self.coprime_tol:
            full, note = self._candidate(A, B, A, B, messages)
            if full is None:
                why.append(f"the full design {note}")
        else:
            why.append(f"coprimeness of A, B = {sigma:.3g} < coprime_tol = "
                       f"{self.coprime_tol:.3g}")
        if sigma < self.reduce_tol:
            pair = _reduce(A, B)
            if pair is None:
                why.append("no real or conjugate pole/zero pair to remove")
            else:
                reduced, note = self._candidate(*pair[:2], A, B, messages)
                what = f"pole {fmt_complex(pair[2])} / zero {fmt_complex(pair[3])}"
                why.append(f"coprimeness {sigma:.3g}, closest {what}"
                           + ("" if reduced is not None else f"; the reduced design {note}"))
        self._why = "; ".join(why)
        if full is not None and (reduced is None or self._checked[id(full)][2]
                                 <= self.max_growth * self._checked[id(reduced)][2]):
            return full, "full", messages
        if reduced is not None:
            return reduced, "reduced", messages
        return None, None, messages

    def _candidate(self, Ad, Bd, A, B, messages):
        """Design for ``(Ad, Bd)``, verified against the estimate ``(A, B)``: ``(ctrl, why)``."""
        design = self.design
        if self._design_kwargs is not None and Ad is not A:
            design = functools.partial(rst_design, **_fit_observer(self._design_kwargs, Ad, Bd))
        try:
            ctrl, caught = call_capturing(design, Ad, Bd)
        except (ValueError, np.linalg.LinAlgError) as exc:
            return None, f"raised {type(exc).__name__}: {exc}"
        rows = self._rows(ctrl, "design")           # raises for a misfit controller
        Rc, Sc, Tc = rows
        target = getattr(ctrl, "target", None)
        if target is not None:            # A R + B S = target on the model designed for
            char = padd(np.convolve(Ad, Rc), np.convolve(Bd, Sc))
            scale = (np.abs(Ad).sum() * np.abs(Rc).sum() + np.abs(Bd).sum() * np.abs(Sc).sum())
            res = np.abs(padd(char, -np.asarray(target, dtype=float))).max()
            if not res <= 1e-8 * scale:
                return None, (f"misses its characteristic polynomial by {res:.3g} (A R + B S "
                              "against target)")
        poles = roots(trim(padd(np.convolve(A, Rc), np.convolve(B, Sc))))
        rho = float(np.max(np.abs(poles), initial=0.0))
        if not rho < 1.0:
            return None, f"gives an unstable loop on the estimate (largest |pole| = {rho:.4g})"
        if self.stable_R:
            rr = float(np.max(np.abs(roots(Rc)), initial=0.0))
            if rr > 1.0 + 1e-9:
                return None, f"has an unstable R (a zero at |z| = {rr:.4g}; stable_R=True)"
        size, last = _size(ctrl), self._scalars[_I["size_last"]]
        if self._scalars[0] and last > 0 and size > self.max_growth * last:
            return None, (f"has size {size:.3g}, more than max_growth = {self.max_growth:g} "
                          f"times the size {last:.3g} of the controller in use")
        messages += caught
        self._checked[id(ctrl)] = (ctrl, rows, size)     # for _try_design and _install
        return ctrl, ""

    def _install(self, ctrl, what):
        """Store a controller's polynomials in the fixed-size rows of ``_ctrl``."""
        checked = self._checked.get(id(ctrl))
        rows, size = (checked[1:] if checked is not None and checked[0] is ctrl else
                      (self._rows(ctrl, what), _size(ctrl)))
        self._ctrl[:] = rows
        self._scalars[0] = 1.0
        self._scalars[_I["size_last"]] = size

    def _rows(self, ctrl, what):
        """A controller's ``R, S, T`` zero-padded to ``max_order + 1``; checks them."""
        rows = np.zeros((3, self._L))
        for i, name in enumerate(("R", "S", "T")):
            p = getattr(ctrl, name, None)
            if p is None:
                raise TypeError(f"the {what} must be an RSTController (with R, S, T); got "
                                f"{type(ctrl).__name__}")
            p = np.asarray(p, dtype=float).reshape(-1)
            nz = np.flatnonzero(p)
            p = p[:nz[-1] + 1] if len(nz) else p[:1]
            if len(p) > self._L:
                raise ValueError(f"the {what} has deg {name} = {len(p) - 1} > max_order = "
                                 f"{self.max_order}; pass a larger max_order")
            if not np.all(np.isfinite(p)):
                raise ValueError(f"the {what} has non-finite coefficients in {name}")
            rows[i, :len(p)] = p
        if rows[0][0] == 0.0:
            raise ValueError(f"the {what} has R[0] = 0 (not a causal controller)")
        return rows

    # ------------------------------------------------------------------
    # history
    # ------------------------------------------------------------------
    @property
    def history(self):
        """An `STRHistory` of every :meth:`step` so far."""
        return STRHistory(self._records, self.na, self.nb, self._L, self.dt, self.offset)

    # ------------------------------------------------------------------
    # the state as one vector, and python-control
    # ------------------------------------------------------------------
    def _parts(self):
        return [self._ypast, self._upast, self._rpast, self._ctrl, self._scalars, self._info]

    def _layout(self):
        """The estimator's `StateLayout`, worked out once per estimator object."""
        layout = self.__dict__.get("_state_layout")
        if layout is None or layout.owner is not self.estimator:
            layout = self._state_layout = _filter_state.StateLayout(self.estimator)
        return layout

    def _get_state(self):
        layout = self._layout()
        parts = [part.reshape(-1) for part in self._parts()]
        vec = np.empty(layout.size + sum(part.size for part in parts))
        layout.pack(self.estimator, vec[:layout.size])
        np.concatenate(parts, out=vec[layout.size:])
        return vec

    def _set_state(self, vec):
        vec = np.asarray(vec, dtype=float)
        layout = self._layout()
        nf = layout.size
        layout.unpack(self.estimator, vec[:nf])
        i = nf
        for part in self._parts():
            part.reshape(-1)[:] = vec[i:i + part.size]
            i += part.size

    def _snapshot(self):
        """A cheap copy of the state: the estimator's attributes and copies of the
        memories. An estimator not on the filters' shared base is copied through its
        state vector."""
        snap = snapshot_filter(self.estimator)
        if snap is None:                                  # not on the shared base
            return None, self._get_state()
        return snap, [p.copy() for p in self._parts()]

    def _restore_snapshot(self, snap):
        if snap[0] is None:
            self._set_state(snap[1])
            return
        restore_filter(self.estimator, snap[0])
        for part, saved in zip(self._parts(), snap[1]):
            part[...] = saved

    @property
    def state(self):
        """The complete internal state (the estimator's, the memories, the controller)."""
        return self._get_state()

    def _state_labels(self):
        labels = _filter_state.state_labels(self.estimator, "est.")
        labels += [f"y[t-{i + 1}]" for i in range(len(self._ypast))]
        labels += [f"u[t-{i + 1}]" for i in range(len(self._upast))]
        labels += [f"r[t-{i + 1}]" for i in range(len(self._rpast))]
        labels += [f"{p}[{i}]" for p in "RST" for i in range(self._L)]
        labels += list(_SCALARS)
        n = self.na + self.nb + self.offset
        labels += [f"info[{i},{j}]" for i in range(n) for j in range(n)]
        return labels

    def _io_step(self, w):
        y, r, v = (float(x) for x in w)
        # no snapshot to undo a failed step: the system never reuses a working copy
        # whose step raised (it restores the next one from the state vector)
        decided = self._decide(y, r, v)
        return self._io_outputs(decided), self._conclude(decided, record=False)[2]

    def _io_outputs(self, decided):
        """The system's outputs ``[u]`` (with `extra_outputs`: ``[u, e, theta..]``)."""
        if not self._io_extra:
            return np.array([decided[10]])
        theta = decided[5]
        out = np.empty(2 + len(theta))
        out[0], out[1] = decided[10], decided[4]
        out[2:] = theta
        return out

    def _vector_plan(self):
        """The options of the compiled sample on the state vector
        (`_kernels_design.sample`: ``(ints, reals, Q, cfg, Acl, Ao, lo, hi)``), or None
        when every sample needs the regulator's Python: an estimator without a
        compiled step on its state vector (`contract.vector_step_constants`: any but
        `RecursiveLeastSquares`, or a frozen one), a design other than the dict of
        `rst_design` keywords without cancelled zeros, ``stable_R``."""
        constants = vector_step_constants(self.estimator)
        fast = self._fast
        if constants is None or fast is None or self.design is not fast[0] or self.stable_R:
            return None
        il, Q, cfg, R, check_every = constants
        _, Acl, Ao, am_sum, integral, tol = fast
        k = _kernels()
        ints = np.zeros(17, dtype=np.int64)
        ints[[k.I_NF, k.I_NA, k.I_NB, k.I_NK, k.I_L, k.I_LY, k.I_LU, k.I_REDESIGN,
              k.I_PATIENCE, k.I_MONITOR, k.I_CHECK, k.I_INTEGRAL, k.I_BOUNDS, k.I_LIMITS,
              k.I_LEVEL_WINDOW, k.I_SCALARS, k.I_OFFSET]] = [
            self._layout().size, self.na, self.nb, self.nk, self._L, len(self._ypast),
            len(self._upast), self.redesign_every, self.patience, self.monitor_every,
            check_every, integral, self.bounds is not None, self.u_limits is not None,
            _LEVEL_WINDOW, len(_SCALARS), self.offset]
        lo, hi = self.u_limits if self.u_limits is not None else (0.0, 0.0)
        reals = np.zeros(13)
        reals[[k.R_IL, k.R_R, k.R_SIGNAL_LIMIT, k.R_DEAD_ZONE, k.R_U_LO, k.R_U_HI,
               k.R_COPRIME, k.R_REDUCE, k.R_GROWTH, k.R_WINDUP, k.R_AM_SUM, k.R_TOL_DESIGN,
               k.R_LEVEL_RATIO]] = [
            il, R, self.signal_limit, self.dead_zone, lo, hi, self.coprime_tol,
            self.reduce_tol, self.max_growth, self.windup_ratio, am_sum, tol, _LEVEL_RATIO]
        n = self.na + self.nb
        box = self.bounds if self.bounds is not None else (np.zeros(n), np.zeros(n))
        return (ints, reals, Q, cfg, Acl, Ao, *(np.ascontiguousarray(b, dtype=float)
                                                  for b in box))

    def _io_vector_sample(self, x, w):
        """``(outputs, next state vector)`` of one sample from the state vector `x` and
        the inputs `w`, by one compiled call (`_kernels_design.sample`), with nothing
        changed; None when the sample needs the regulator's Python (then `_io_step`
        takes it, with the same results, its messages and errors).

        The regulator in python-control's call pattern: 3.2x the bare filter step per
        simulated step instead of 9.1x with a Python look-ahead per evaluation
        (``benchmarks/bench_diagrams.py``, one session)."""
        plan = self.__dict__.get("_plan")
        if plan is None or len(x) != self._state_size or len(w) != 3:
            return None
        out = np.empty(len(x))
        outputs = np.empty(2 + self.na + self.nb + self.offset if self._io_extra else 1)
        try:
            status = _kernels().sample(x, w, out, outputs, *plan)
        except (ValueError, ZeroDivisionError, np.linalg.LinAlgError):
            return None             # (a singular design: the Python path decides)
        return (outputs, out) if status == 0 else None

    def as_iosystem(self, dt=None, name="str", extra_outputs=False):
        r"""The regulator as a discrete-time python-control `NonlinearIOSystem`.

        Parameters
        ----------
        dt : True or float, optional
            Sampling period; the regulator's `dt` by default.
        name : str, default "str"
            Name of the system in `control.interconnect`.
        extra_outputs : bool, default False
            Also output the a-priori prediction error ``e`` and the
            estimate ``theta[0] ..``.

        Returns
        -------
        control.NonlinearIOSystem
            Inputs ``['y', 'r', 'dither']``; outputs ``['u']`` (with
            `extra_outputs`: ``['u', 'e', 'theta[0]', ..]``); states:
            :attr:`state`, labelled.

        Notes
        -----
        The system steps a private copy of the regulator as it is now;
        the regulator itself is not changed by simulations. Its state
        vector is :attr:`state`; python-control's default initial state,
        all zeros, stands for the regulator's state at this call (a valid
        state is never all zeros: ``P`` is positive definite), so
        ``input_output_response(loop, T, U)`` starts from it. One sample of
        the system is one :meth:`step`, so simulations equal the
        :meth:`step` loop to round-off.

        Examples
        --------
        >>> import control
        >>> import numpy as np
        >>> from rlsfilt import RecursiveLeastSquares
        >>> from rlsfilt.adaptive import SelfTuningRegulator
        >>> stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0),
        ...                            design=dict(Am=np.poly([0.5, 0.5]), Ao=np.poly([0.2])),
        ...                            na=2, nb=2)
        >>> plant = control.tf([0, 1, 0.5], [1, -1.5, 0.7], True, inputs="u", outputs="y")
        >>> loop = control.interconnect([plant, stre.as_iosystem()], inputs=["r", "dither"],
        ...                             outputs=["y", "u"])
        >>> T = np.arange(300)
        >>> r = np.where(T % 100 < 50, 1.0, -1.0)
        >>> dither = 0.01 * np.random.default_rng(0).choice([-1.0, 1.0], 300)
        >>> resp = control.input_output_response(loop, T, [r, dither])
        >>> y = resp.outputs[0]
        >>> bool(np.sqrt(np.mean((y[-40:] - r[-40:]) ** 2)) < 0.05)     # RMS tracking error
        True
        """
        n = self.na + self.nb + self.offset
        outputs = ["u"] + (["e"] + [f"theta[{i}]" for i in range(n)] if extra_outputs else [])
        template = self.__class__.__new__(self.__class__)
        template.__dict__.update(self.__dict__)
        template._io_extra = bool(extra_outputs)
        template._records = []
        template._plan = template._vector_plan()      # None: every sample through Python
        template._state_size = len(self.state)
        return make_iosystem(template, inputs=["y", "r", "dither"], outputs=outputs,
                             states=self._state_labels(),
                             dt=self.dt if dt is None else check_dt(dt), name=name)

    def __repr__(self):
        ctrl = self.controller
        law = ctrl.control_law() if ctrl is not None else "no controller yet (u = dither)"
        return (f"SelfTuningRegulator(na={self.na}, nb={self.nb}, nk={self.nk}, "
                f"estimator={type(self.estimator).__name__}, redesign_every="
                f"{self.redesign_every}, dt={self.dt!r})\n"
                f"  steps: {int(self._scalars[1])}, designs rejected: {int(self._scalars[5])}\n"
                f"  theta = {np.array2string(self.theta, precision=5)}\n"
                f"  {law}")


class STRHistory:
    """What a `SelfTuningRegulator` saw and did, one row per step.

    Attributes
    ----------
    na, nb : int
        Orders of the estimated model.
    dt : True or float
        Sampling period of the regulator.
    t : ndarray, shape (N,)
        Time: step index times ``dt`` (the index when ``dt`` is True).
    y, r, u : ndarray, shape (N,)
        Measured output, reference and applied control.
    e : ndarray, shape (N,)
        A-priori prediction error :math:`y(t) - \\varphi(t)^T\\hat\\theta(t-1)`.
    offset : bool
        Whether the last column of `theta` is the estimated offset ``c``.
    theta : ndarray, shape (N, na + nb) or (N, na + nb + 1)
        Estimate after the step (after projection); with `offset`, ``c``
        last.
    trace_P : ndarray, shape (N,)
        ``trace(P)`` of the estimator after the step.
    updated, redesigned, rejected : ndarray of bool, shape (N,)
        Whether the estimator was updated (outside the dead zone), a
        redesign was due, and the due redesign was rejected (the last
        controller kept).
    reduced : ndarray of bool, shape (N,)
        Whether the controller installed at the step was designed on the
        reduced model (the estimate's closest pole/zero pair removed).
    R, S, T : ndarray, shape (N, max_order + 1)
        Controller in use at each step (zero-padded).
    excitation : ndarray, shape (N,)
        Smallest/largest eigenvalue of :math:`\\sum\\varphi\\varphi^T` at the
        end of each monitor block, NaN elsewhere.
    """

    def __init__(self, records, na, nb, L, dt, offset=False):
        self.na, self.nb, self.dt, self.offset = na, nb, dt, bool(offset)
        n = na + nb + self.offset
        N = len(records)
        cols = list(zip(*records)) if N else [()] * 12
        self.t = np.arange(N) * (1.0 if dt is True else float(dt))
        self.y, self.r, self.u, self.e = (np.array(c, dtype=float) for c in cols[:4])
        self.theta = np.array(cols[4], dtype=float).reshape(N, n)
        self.trace_P = np.array(cols[5], dtype=float)
        self.updated, self.redesigned, self.rejected = (np.array(c, dtype=bool)
                                                        for c in cols[6:9])
        ctrl = np.array(cols[9], dtype=float).reshape(N, 3, L)
        self.R, self.S, self.T = ctrl[:, 0], ctrl[:, 1], ctrl[:, 2]
        self.excitation = np.array(cols[10], dtype=float)
        self.reduced = np.array(cols[11], dtype=bool)

    def __len__(self):
        return len(self.t)

    def plot(self, fig=None, true_theta=None):
        """Reference and output, control, estimates and ``trace(P)`` over time.

        Calls :func:`rlsfilt.plotting.plot_str_history`.

        Parameters
        ----------
        fig : matplotlib.figure.Figure, optional
            Figure to draw in (new if omitted).
        true_theta : array_like, shape (na + nb,) or (N, na + nb), optional
            True parameters, drawn dashed.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from ..plotting import plot_str_history

        return plot_str_history(self, fig, true_theta=true_theta)

    def __repr__(self):
        return (f"STRHistory: {len(self)} steps, {int(self.updated.sum())} estimator updates, "
                f"{int(self.rejected.sum())} designs rejected")



def _size(ctrl):
    """``(|R|_1 + |S|_1 + |T|_1) / |r0|``: how large a controller's gains are."""
    R, S, T = (np.asarray(getattr(ctrl, n), dtype=float) for n in "RST")
    return float((np.abs(R).sum() + np.abs(S).sum() + np.abs(T).sum()) / abs(R[0]))


def _reduce(A, B):
    """``(A', B', pole, zero)``: the estimate without its closest pole/zero pair, or None.

    A complex pole is removed with its conjugate, and then so must the zero
    be (a real pole pairs with a real zero); ``B'`` keeps the delay and the
    leading coefficient of ``B``.
    """
    nz = np.flatnonzero(B)
    if not len(nz):
        return None
    ra, rb = roots(A), roots(B[nz[0]:])
    if not (len(ra) and len(rb)):
        return None
    dist = np.abs(ra[:, None] - rb[None, :])
    i, j = np.unravel_index(int(np.argmin(dist)), dist.shape)
    p, z = ra[i], rb[j]
    complex_p = abs(p.imag) > 1e-9 * max(1.0, abs(p))
    complex_z = abs(z.imag) > 1e-9 * max(1.0, abs(z))
    if complex_p != complex_z:
        return None
    ra, rb = np.delete(ra, i), np.delete(rb, j)
    if complex_p:
        ra = np.delete(ra, int(np.argmin(np.abs(ra - np.conj(p)))))
        rb = np.delete(rb, int(np.argmin(np.abs(rb - np.conj(z)))))
    Ar = np.atleast_1d(np.real(np.poly(ra)))
    Br = np.concatenate([np.zeros(nz[0]), B[nz[0]] * np.atleast_1d(np.real(np.poly(rb)))])
    return Ar, Br, p, z


def _fit_observer(kwargs, A, B):
    """`rst_design` keywords with ``Ao`` of a degree the reduced model can place.

    The reduced model allows ``deg A + integral + deg B - 1`` closed-loop
    poles; ``Am`` keeps all of its own and ``Ao`` keeps its slowest roots
    (dropping a root near ``z = 0`` changes the observer least).
    """
    Ao = kwargs.get("Ao")
    if Ao is None:
        return kwargs
    Ao = trim(np.asarray(Ao, dtype=float))
    room = (degree(A) + int(kwargs.get("integral", True)) + degree(B) - 1
            - degree(np.atleast_1d(np.asarray(kwargs["Am"], dtype=float))))
    if degree(Ao) <= room or room < 0:
        return kwargs
    ro = roots(Ao)
    ro = ro[np.argsort(-np.abs(ro), kind="stable")][:room]
    if room and abs(ro[-1].imag) > 1e-12 and not np.any(np.isclose(ro[:-1], np.conj(ro[-1]))):
        ro = ro[:-1]                      # never split a conjugate pair
    return dict(kwargs, Ao=np.atleast_1d(np.real(np.poly(ro))))


def _check_bounds(bounds, n):
    try:
        lo, hi = bounds
    except (TypeError, ValueError):
        raise TypeError(f"`bounds` must be a pair (lower, upper); got {bounds!r}") from None
    out = []
    for name, b in (("lower", lo), ("upper", hi)):
        arr = np.broadcast_to(np.asarray(b, dtype=float), (n,)).copy() \
            if np.ndim(b) == 0 or np.shape(b) == (n,) else None
        if arr is None:
            raise ValueError(f"`bounds` {name} must be a scalar or have shape ({n},); got shape "
                             f"{np.shape(b)}")
        if np.isnan(arr).any():
            raise ValueError(f"`bounds` {name} must not contain NaN")
        out.append(arr)
    if np.any(out[0] > out[1]):
        i = int(np.argmax(out[0] > out[1]))
        raise ValueError(f"`bounds` must have lower <= upper; got {out[0][i]} > {out[1][i]} "
                         f"for parameter {i}")
    return tuple(out)


def _check_limits(limits):
    try:
        lo, hi = limits
    except (TypeError, ValueError):
        raise TypeError(f"`u_limits` must be a pair (u_min, u_max); got {limits!r}") from None
    lo, hi = check_scalar(lo, "u_limits"), check_scalar(hi, "u_limits")
    if not lo < hi or np.isnan(lo) or np.isnan(hi):
        raise ValueError(f"`u_limits` must have u_min < u_max; got ({lo}, {hi})")
    return (lo, hi)

