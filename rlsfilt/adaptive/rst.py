r"""Polynomial pole placement: the two-degree-of-freedom RST controller.

The controller :math:`R(q^{-1})\,u(t) = T(q^{-1})\,r(t) - S(q^{-1})\,y(t)`
around the plant :math:`A(q^{-1})\,y(t) = B(q^{-1})\,u(t)` gives the closed
loop

.. math::

    y(t) = \frac{B T}{A R + B S}\, r(t),

so the closed-loop poles are the zeros of :math:`A R + B S`. `rst_design`
chooses ``R`` and ``S`` so that :math:`A R + B S = A_m A_o` (the Diophantine
equation), and ``T`` so that the observer polynomial :math:`A_o` cancels from
the reference: :math:`y = t_0 B / A_m\, r` with unit static gain.

Polynomials are coefficient arrays of ascending powers of :math:`q^{-1}`
(see :mod:`rlsfilt.adaptive`).
"""

import numpy as np

from .._display import Summary
from .._validation import check_dt, check_real
from ..models._polynomials import model_dt, observer_form
from ._polynomials import (
    as_poly,
    check_stable,
    closest_roots,
    coprimeness,
    degree,
    fmt_complex,
    format_poly,
    model_polynomials,
    pad,
    padd,
    roots,
    sylvester,
    tf_pair,
    trim,
)

__all__ = ["RSTController", "ClosedLoop", "rst_design"]

#: Default `coprime_tol` of `rst_design`: the smallest singular value of the
#: unit-norm Sylvester matrix below which A and B count as having a common factor.
COPRIME_TOL = 1e-8


class RSTController:
    r"""A two-degree-of-freedom linear controller :math:`R u = T r - S y`.

    Parameters
    ----------
    R, S, T : array_like
        Coefficients of ascending powers of :math:`q^{-1}`; ``R[0]`` must be
        nonzero (the controller is causal).
    dt : True or float, default True
        Sampling period (python-control's ``dt``).
    Ao : array_like, optional
        The observer polynomial of the design (monic), if known; used by
        the anti-windup form of `SelfTuningRegulator` (Astrom & Wittenmark
        1995, sec. 11.2). `rst_design` sets it.
    target : array_like, optional
        The closed-loop characteristic polynomial :math:`A R + B S` the
        design placed (:math:`A_m A_o`, times :math:`B^+` when zeros are
        cancelled), if known: what a self-tuning regulator checks an
        accepted design against. `rst_design` sets it.

    Attributes
    ----------
    R, S, T : ndarray
        The polynomials (copies of the arguments, trailing zeros removed).
    dt : True or float
    Ao, target : ndarray or None
        As given (trailing zeros removed), or None.

    Notes
    -----
    The control law, one sample at a time:

    .. math::

        u(t) = \frac{1}{r_0}\Big(\sum_i t_i\, r(t-i) - \sum_i s_i\, y(t-i)
               - \sum_{i \ge 1} r_i\, u(t-i)\Big).

    As a python-control system (:meth:`to_tf`, :meth:`to_ss`) it has two
    inputs ``[r, y]`` and one output ``u``: :math:`u = (T/R)\, r - (S/R)\, y`.

    Examples
    --------
    A proportional-integral controller ``u(t) = u(t-1) + 2 e(t) - e(t-1)``
    with ``e = r - y``:

    >>> from rlsfilt.adaptive import RSTController
    >>> pi = RSTController(R=[1, -1], S=[2, -1], T=[2, -1], dt=0.1)
    >>> pi.control_law()
    '(1 - q^-1) u(t) = (2 - q^-1) r(t) - (2 - q^-1) y(t)'
    """

    def __init__(self, R, S, T, dt=True, *, Ao=None, target=None):
        self.R = trim(as_poly(R, "R"))
        self.S = trim(as_poly(S, "S"))
        self.T = trim(as_poly(T, "T"))
        self.Ao = None if Ao is None else trim(as_poly(Ao, "Ao", monic=True))
        self.target = None if target is None else trim(as_poly(target, "target"))
        if self.R[0] == 0.0:
            raise ValueError(f"`R` must have R[0] != 0 (a causal controller: u(t) appears in "
                             f"R(q^-1) u(t)); got R = {self.R.tolist()}")
        self.dt = check_dt(dt)

    def control_law(self):
        """The law ``R(q^-1) u(t) = T(q^-1) r(t) - S(q^-1) y(t)`` as text."""
        return (f"({format_poly(self.R)}) u(t) = ({format_poly(self.T)}) r(t) - "
                f"({format_poly(self.S)}) y(t)")

    def __repr__(self):
        return (f"RSTController(dt={self.dt!r})\n  {self.control_law()}\n"
                f"  R = {self.R.tolist()}\n  S = {self.S.tolist()}\n  T = {self.T.tolist()}")

    def _num_den(self):
        return [tf_pair(self.T, self.R), tf_pair(-self.S, self.R)]

    def to_tf(self):
        """The controller as a 1 x 2 ``control.TransferFunction`` from ``[r, y]`` to ``u``.

        Numerators and denominators are in powers of ``z``, zero-padded so
        that feed-through terms and delays are exact.

        Returns
        -------
        control.TransferFunction
            ``[[T/R, -S/R]]`` with inputs ``['r', 'y']``, output ``['u']``.
        """
        import control

        (nt, dt_), (ns, ds) = self._num_den()
        return control.tf([[nt, ns]], [[dt_, ds]], self.dt, inputs=["r", "y"], outputs=["u"])

    def to_ss(self):
        r"""The controller as a ``control.StateSpace`` (observer canonical form).

        Realizes :math:`R u = T r - S y` with :math:`\max(\deg R, \deg S,
        \deg T)` states; no Slycot needed.

        Returns
        -------
        control.StateSpace
            Inputs ``['r', 'y']``, output ``['u']``.
        """
        import control

        F, G, H, D = self._realization()
        return control.ss(F, G, H, D, self.dt, inputs=["r", "y"], outputs=["u"])

    def _realization(self):
        r0 = self.R[0]
        n = max(len(self.R), len(self.S), len(self.T))
        A = pad(self.R / r0, n).reshape(1, 1, n)
        B = np.stack([pad(self.T / r0, n), pad(-self.S / r0, n)]).reshape(1, 2, n)
        return observer_form(A, B)

    def closed_loop(self, A, B=None):
        """The loop closed around the plant ``A y = B u`` (see `ClosedLoop`).

        Parameters
        ----------
        A : array_like or model
            ``A(q^-1)`` (monic), or a model (then omit `B`): any rlsfilt
            model through ``polydata()`` (the plant ``B / (A F)``), or an
            object with ``polynomials()``.
        B : array_like, optional
            ``B(q^-1)`` including the delay's leading zeros.

        Returns
        -------
        ClosedLoop
        """
        A, B, _ = _plant(A, B)
        return ClosedLoop(self, A, B)


class ClosedLoop:
    r"""An RST controller in closed loop with the plant :math:`A y = B (u + v)`.

    The controller measures :math:`y + n` (an output disturbance ``n``) and
    the plant input carries a load disturbance ``v``.

    Attributes
    ----------
    controller : RSTController
    A, B : ndarray
        The plant.
    characteristic : ndarray
        :math:`A R + B S` in powers of :math:`q^{-1}`.
    poles : ndarray
        Its zeros in the z-plane (the closed-loop poles).
    stable : bool
        Whether every pole is strictly inside the unit circle.

    Notes
    -----
    With :math:`A_{cl} = A R + B S`:

    ============  ==========================  =============================
    attribute     transfer function           from, to
    ============  ==========================  =============================
    ``Gyr``       :math:`B T / A_{cl}`        reference to output
    ``Gur``       :math:`A T / A_{cl}`        reference to control
    ``Gyv``       :math:`B R / A_{cl}`        input load disturbance to output
    ``Gyn``       :math:`A R / A_{cl}`        output disturbance to output
                                              (the sensitivity function)
    ``Gun``       :math:`-A S / A_{cl}`       output disturbance to control
    ============  ==========================  =============================

    Each is a python-control ``TransferFunction`` with the controller's
    ``dt``, built exactly from the polynomials (no ``minreal``): its poles
    are the zeros of :math:`A_{cl}`, plus poles at ``z = 0`` where the
    padding to powers of ``z`` needs them.
    """

    def __init__(self, controller, A, B):
        self.controller = controller
        self.A, self.B = A.copy(), B.copy()
        R, S = controller.R, controller.S
        self.characteristic = trim(padd(np.convolve(A, R), np.convolve(B, S)))
        self.poles = roots(self.characteristic)
        self.stable = bool(np.all(np.abs(self.poles) < 1.0))

    def _tf(self, num):
        import control

        n, d = tf_pair(trim(num), self.characteristic)
        return control.tf(n, d, self.controller.dt)

    @property
    def Gyr(self):
        """Reference to output, ``B T / (A R + B S)``."""
        return self._tf(np.convolve(self.B, self.controller.T))

    @property
    def Gur(self):
        """Reference to control, ``A T / (A R + B S)``."""
        return self._tf(np.convolve(self.A, self.controller.T))

    @property
    def Gyv(self):
        """Input load disturbance to output, ``B R / (A R + B S)``."""
        return self._tf(np.convolve(self.B, self.controller.R))

    @property
    def Gyn(self):
        """Output disturbance to output (sensitivity), ``A R / (A R + B S)``."""
        return self._tf(np.convolve(self.A, self.controller.R))

    @property
    def Gun(self):
        """Output disturbance to control, ``-A S / (A R + B S)``."""
        return self._tf(-np.convolve(self.A, self.controller.S))

    @property
    def dcgain(self):
        """Static gain from reference to output, ``B(1) T(1) / Acl(1)``."""
        return float(self.B.sum() * self.controller.T.sum() / self.characteristic.sum())

    def summary(self):
        """The closed loop: characteristic polynomial, poles, static gain.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook.
        """
        rho = np.max(np.abs(self.poles)) if len(self.poles) else 0.0
        poles = ", ".join(fmt_complex(p) for p in self.poles)
        return Summary("\n".join([
            "Closed loop of " + self.controller.control_law(),
            f"  plant: ({format_poly(self.A)}) y(t) = ({format_poly(self.B)}) u(t)",
            f"  A R + B S = {format_poly(self.characteristic)}",
            f"  poles: {poles}",
            f"  largest |pole| = {rho:.6g} ({'stable' if self.stable else 'UNSTABLE'}); "
            f"static gain r -> y = {self.dcgain:.6g}",
        ]))

    def __repr__(self):
        return self.summary().as_text()


def rst_design(A, B=None, Am=None, Ao=None, *, integral=True, cancel_zeros=False, dt=None,
               coprime_tol=COPRIME_TOL):
    r"""Pole placement: solve :math:`A R + B S = A_m A_o` for an RST controller.

    Parameters
    ----------
    A : array_like or model
        Plant denominator ``[1, a1, .., a_na]`` (monic, ascending powers of
        :math:`q^{-1}`), or a model, then leave `B` out and give `Am` by
        keyword: a fitted `~rlsfilt.ARX` or any rlsfilt model (its plant
        ``B / (A F)`` from ``polydata()``), or an object with
        ``polynomials()`` returning ``(A, B)`` (or ``(A, B, C, D, F)``, as a
        streaming `RecursiveOE` does: the plant ``B / (A F)``).
    B : array_like
        Plant numerator ``[0]*nk + [b1, .., b_nb]`` including the delay's
        leading zeros (``ARX.polynomials()`` returns exactly this). Its
        degree in :math:`q^{-1}` must be at least 1.
    Am : array_like
        Desired closed-loop polynomial from the reference (monic, stable),
        for example ``np.poly(poles)`` for poles in the z-plane.
    Ao : array_like, optional
        Observer polynomial (monic, stable); ``1`` by default.
    integral : bool, default True
        Include the integrator :math:`1 - q^{-1}` in ``R``: zero
        steady-state error to steps in the reference and to constant load
        disturbances, also under model error.
    cancel_zeros : bool or float, default False
        Cancel the zeros of ``B`` strictly inside the circle of this radius
        in the z-plane (``True``: the unit circle; a float in (0, 1]: a
        stricter radius, which keeps poorly damped zeros): they become
        factors :math:`B^+` of ``R`` and closed-loop poles that the
        reference does not excite (Astrom & Wittenmark 1995, sec. 3.2,
        Examples 3.1 and 3.4). Zeros outside, and the delay, stay in
        :math:`B^-`. ``False``: no zero is cancelled.
    dt : True or float, optional
        Sampling period of the controller; the model's ``dt`` or ``True``.
    coprime_tol : float, default 1e-8
        ``A (1 - q^-1)`` (or ``A``) and ``B`` count as having a common factor
        when the smallest singular value of their Sylvester matrix, with
        both coefficient vectors scaled to unit norm, is below this (0 for
        an exact common root; roughly the distance between the closest
        pole and zero otherwise).

    Returns
    -------
    RSTController
        ``R = (1 - q^-1) B+ R'`` (with `integral`; ``B+ = 1`` unless
        `cancel_zeros`), ``S``, ``T = t0 Ao``; its ``Ao`` and ``target``
        (``B+ Am Ao``) are set.

    Raises
    ------
    ValueError
        For a non-monic or unstable `Am` or `Ao`, ``deg(Am Ao)`` too high, a
        `B` of degree 0, or `A` and `B` with a (near-)common factor (a plant
        zero at ``z = 1`` with `integral`); each message names the argument.

    Notes
    -----
    Write :math:`A_1 = A (1 - q^{-1})` with integral action (else
    :math:`A_1 = A`), :math:`n_1 = \deg A_1`, :math:`n_b = \deg B`. The
    minimal-degree solution of

    .. math::

        A_1 R' + B S = A_m A_o, \qquad \deg R' = n_b - 1,\quad \deg S = n_1 - 1,

    is the linear system :math:`M [r'; s] = c` with the
    :math:`(n_1 + n_b)`-square Sylvester matrix ``M`` of :math:`A_1` and
    ``B``, nonsingular exactly when they are coprime. It needs
    :math:`\deg A_m A_o \le n_1 + n_b - 1`; a lower degree places the
    remaining closed-loop poles at ``z = 0`` (a deadbeat observer). With
    ``B(0) = 0`` (a delay) the solution has :math:`R'(0) = 1`. Then ``R =
    (1 - q^{-1}) R'`` and :math:`T = t_0 A_o` with :math:`t_0 = A_m(1) / B(1)`,
    so that :math:`y = t_0 B / A_m\, r` (the observer poles cancel from the
    reference, no plant zero is cancelled, unit static gain). Astrom &
    Wittenmark (1997), ch. 5; (1995), ch. 3.

    With `cancel_zeros`, :math:`B = B^+ B^-` (:math:`B^+` monic, its zeros
    the cancelled ones) and the equation is :math:`A_1 R' + B^- S = A_m
    A_o` with :math:`R = (1 - q^{-1}) B^+ R'`, so that :math:`A R + B S =
    B^+ A_m A_o` and :math:`y = t_0 B^- / A_m\, r` with :math:`t_0 =
    A_m(1) / B^-(1)`. For a plant :math:`b_0 q^{-1} + b_1 q^{-2}` over
    :math:`1 + a_1 q^{-1} + a_2 q^{-2}`, ``Ao = 1``, ``integral=False``,
    this is the controller of Astrom & Wittenmark's Example 3.1, the design
    step of the indirect self-tuner of Example 3.4: :math:`r_1 = b_1/b_0`,
    :math:`s_0 = (a_{m1} - a_1)/b_0`, :math:`s_1 = (a_{m2} - a_2)/b_0`,
    :math:`t_0 = (1 + a_{m1} + a_{m2})/b_0`. Cancelled zeros stay poles of
    the loop from disturbances and of ``u``: a zero near ``z = -1`` makes
    ``u`` ring (their Fig. 3.6), hence the radius.

    References
    ----------
    .. [1] K. J. Astrom and B. Wittenmark, *Computer-Controlled Systems*,
       3rd ed., Prentice Hall, 1997, ch. 5.
    .. [2] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 3.

    Examples
    --------
    Place the closed-loop poles of ``y(t) - 1.5 y(t-1) + 0.7 y(t-2) = u(t-1)
    + 0.5 u(t-2)`` at 0.6 and 0.7, the observer poles at 0.2 and 0.3:

    >>> import numpy as np
    >>> from rlsfilt.adaptive import rst_design
    >>> A, B = [1, -1.5, 0.7], [0, 1, 0.5]
    >>> ctrl = rst_design(A, B, Am=np.poly([0.6, 0.7]), Ao=np.poly([0.2, 0.3]))
    >>> loop = ctrl.closed_loop(A, B)
    >>> np.round(np.sort(loop.poles.real), 6)
    array([0.2, 0.3, 0.6, 0.7])
    >>> round(loop.dcgain, 12)
    1.0
    """
    A, B, model = _plant(A, B)
    Am, Ao, integral, radius, coprime_tol, dt = _design_options(
        Am, Ao, integral, cancel_zeros, coprime_tol,
        model_dt(model) if dt is None and model is not None else dt)
    return _solve_rst(A, B, Am, Ao, integral, radius, coprime_tol, dt)


def _design_options(Am, Ao, integral, cancel_zeros, coprime_tol, dt):
    """`rst_design`'s options checked: ``(Am, Ao, integral, radius, coprime_tol, dt)``."""
    if Am is None:
        raise TypeError("`Am` is required: the desired closed-loop polynomial, e.g. "
                        "Am=np.poly(poles)")
    Am = as_poly(Am, "Am", monic=True)
    check_stable(Am, "Am")
    Ao = np.ones(1) if Ao is None else as_poly(Ao, "Ao", monic=True)
    check_stable(Ao, "Ao")
    if not isinstance(integral, (bool, np.bool_)):
        raise TypeError(f"`integral` must be True or False; got {integral!r}")
    radius = _check_cancel(cancel_zeros)
    coprime_tol = check_real(coprime_tol, "coprime_tol", minimum=0)
    dt = check_dt(True if dt is None else dt)
    return Am, Ao, integral, radius, coprime_tol, dt


def _prepared_design(*, Am=None, Ao=None, integral=True, cancel_zeros=False, dt=None,
                     coprime_tol=COPRIME_TOL):
    """``design(A, B)``, equal to ``rst_design(A, B, **options)``, with the options checked once.

    For a loop that designs at every sample (`SelfTuningRegulator`): the
    checks of `Am` and `Ao` (their roots) and of the other options do not
    change between samples. Raises as `rst_design` would for a bad option.
    """
    options = _design_options(Am, Ao, integral, cancel_zeros, coprime_tol, dt)

    def design(A, B):
        A, B, _ = _plant(A, B)
        return _solve_rst(A, B, *options)

    design.options = options        # (Am, Ao, integral, radius, coprime_tol, dt), checked
    return design


def _solve_rst(A, B, Am, Ao, integral, radius, coprime_tol, dt):
    """The design of `rst_design` for checked ``A, B`` (from `_plant`) and options."""
    A1 = np.convolve(A, [1.0, -1.0]) if integral else A
    if degree(B) < 1:
        raise ValueError(f"`B` must have degree >= 1 in q^-1 (a delay nk >= 1, or nb >= 2 "
                         f"coefficients); got B = {B.tolist()}")
    Bplus, B = _split_zeros(B, radius)
    n1, nb = degree(A1), degree(B)
    Acl = trim(np.convolve(Am, Ao))
    if degree(Acl) > n1 + nb - 1:
        raise ValueError(
            f"`Am` and `Ao` have deg(Am) + deg(Ao) = {degree(Acl)}, more than the "
            f"deg A{' + 1 (integrator)' if integral else ''} + deg B - 1 = {n1 + nb - 1} "
            f"that R and S of minimal degree can place (deg A = {degree(A)}, deg B = {nb}); "
            "lower the degree of Ao")
    _check_coprime(A, B, A1, integral, coprime_tol)
    x = np.linalg.solve(sylvester(A1, B), pad(Acl, n1 + nb))
    R1, S = np.convolve(Bplus, x[:nb]), x[nb:]
    R = np.convolve(R1, [1.0, -1.0]) if integral else R1
    if abs(R[0]) <= 1e-12 * np.max(np.abs(R)):
        raise ValueError(f"`B` has B(0) = {B[0]:.6g} != 0 (no delay) and the design gives "
                         "R(0) = 0: the controller cannot be causal; add a delay to the model "
                         "or change Am, Ao")
    T = Am.sum() / B.sum() * Ao
    return _controller(R, S, T, dt, Ao, np.convolve(Bplus, Acl))


def _controller(R, S, T, dt, Ao, target):
    """``RSTController(R, S, T, dt, Ao=Ao, target=target)`` for the float arrays of a
    design and its checked `dt` and `Ao`: the same object without repeating checks
    that they pass (anything else goes through the constructor, and raises there)."""
    if not all(np.isfinite(p).all() for p in (R, S, T, target)) or R[0] == 0.0:
        return RSTController(R, S, T, dt, Ao=Ao, target=target)
    ctrl = RSTController.__new__(RSTController)
    ctrl.R, ctrl.S, ctrl.T = trim(R), trim(S), trim(T)
    ctrl.Ao, ctrl.target = trim(Ao), trim(target)
    ctrl.dt = dt
    return ctrl


def _check_cancel(cancel_zeros):
    """The radius inside which `rst_design` cancels zeros (0: none)."""
    if isinstance(cancel_zeros, (bool, np.bool_)):
        return 1.0 if cancel_zeros else 0.0
    radius = check_real(cancel_zeros, "cancel_zeros", minimum=0)
    if radius > 1.0:
        raise ValueError(f"`cancel_zeros` must be True, False or a radius in (0, 1] (only "
                         f"stable zeros can be cancelled); got {radius}")
    return radius


def _split_zeros(B, radius):
    """``(B+, B-)``: ``B+`` monic with the zeros of `B` inside `radius`, ``B = B+ B-``."""
    if radius == 0.0:                 # nothing to cancel (the default): no roots needed
        return np.ones(1), B
    nz = np.flatnonzero(B)
    lead = B[nz[0]] if len(nz) else 0.0
    zeros = roots(B[nz[0]:]) if len(nz) else np.zeros(0)
    inside = np.abs(zeros) < radius
    if not inside.any():
        return np.ones(1), B
    Bplus = np.atleast_1d(np.real(np.poly(zeros[inside])))
    kept = np.atleast_1d(np.real(np.poly(zeros[~inside])))
    Bminus = np.concatenate([np.zeros(nz[0]), lead * kept])
    return Bplus, Bminus


def _plant(A, B):
    """``(A, B, model)`` from polynomials or from a model (``polydata()``/``polynomials()``)."""
    model = None
    if B is None:
        if not (hasattr(A, "polydata") or hasattr(A, "polynomials")):
            raise TypeError("`B` is required unless `A` is a model with polynomials() (such "
                            f"as a fitted ARX); got A of type {type(A).__name__}")
        model = A
        A, B = model_polynomials(model, "A", 2)
    A = trim(as_poly(A, "A", monic=True))
    B = as_poly(B, "B")
    if A.ndim != 1 or B.ndim != 1:
        raise ValueError("`A` and `B` must be 1-D (one input, one output)")
    if degree(B) < 0:
        raise ValueError(f"`B` must be a nonzero polynomial; got B = {B.tolist()}")
    return A, trim(B), model


def _check_coprime(A, B, A1, integral, tol):
    if abs(B.sum()) <= tol * np.linalg.norm(B):
        why = ("which cancels the integrator of integral=True (A (1 - q^-1) and B are not "
               "coprime)" if integral else "so no T gives a unit static gain from r to y")
        raise ValueError(f"`B` has B(1) = {B.sum():.3g}: the plant has a zero at z = 1, {why}")
    sigma = coprimeness(A1, B)
    if sigma < tol:
        pair = closest_roots(A1, B)
        where = ""
        if pair is not None:
            where = (f"; closest pole/zero pair: pole z = {fmt_complex(pair[0])}, zero z = "
                     f"{fmt_complex(pair[1])}")
        raise ValueError(
            f"`A` and `B` must be coprime (no common pole/zero); the smallest singular value "
            f"of the Sylvester matrix of A{' (1 - q^-1)' if integral else ''} and B, both "
            f"scaled to unit norm, is {sigma:.3g} < coprime_tol = {tol:.3g}{where}")

