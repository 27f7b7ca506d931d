r"""Minimum-variance and generalized minimum-variance control of ARMAX plants.

For the plant :math:`A(q^{-1}) y(t) = q^{-d} B'(q^{-1}) u(t) + C(q^{-1}) e(t)`
with white :math:`e` of variance :math:`\sigma^2`, the ``d``-step predictor
follows from the identity (Astrom & Wittenmark, *Adaptive Control*, ch. 4)

.. math::

    P C = A F + q^{-d} G, \qquad \deg F = d - 1,

whose ``F`` holds the first ``d`` coefficients of the impulse response of
:math:`P C / A`. Minimum-variance control cancels everything predictable and
leaves :math:`y(t) = F e(t)` (for ``P = 1``), the smallest output variance any
causal controller can reach, :math:`\sigma^2 \sum_{i<d} f_i^2`.

Polynomials are coefficient arrays of ascending powers of :math:`q^{-1}`
(see :mod:`rlsfilt.adaptive`).
"""

import numpy as np

from .._validation import check_dt, check_int
from ..models._polynomials import model_dt
from ._polynomials import (
    as_poly,
    check_stable,
    fmt_complex,
    format_poly,
    model_polynomials,
    padd,
    roots,
    trim,
)
from .rst import RSTController

__all__ = ["MinimumVarianceController", "minimum_variance", "generalized_minimum_variance"]


class MinimumVarianceController(RSTController):
    r"""The RST controller of a (generalized) minimum-variance design, with its predictor.

    An `RSTController` (``R u = T r - S y``) that also keeps the
    polynomials of the design.

    Attributes
    ----------
    F, G : ndarray
        Solution of :math:`P C = A F + q^{-d} G` (``deg F = d - 1``).
    d : int
        The delay.
    P, Q : ndarray
        Weights of the generalized design (``[1.]`` and ``[0.]`` for
        minimum variance).
    """

    def __init__(self, R, S, T, dt, *, F, G, d, P, Q):
        super().__init__(R, S, T, dt)
        self.F, self.G, self.d = F.copy(), G.copy(), d
        self.P, self.Q = P.copy(), Q.copy()

    def output_variance(self, noise_variance=1.0):
        r"""Variance of the controlled output, :math:`\sigma^2 \sum_{i<d} f_i^2`.

        For minimum variance this is the variance of :math:`y(t)` in closed
        loop; for the generalized design, of the auxiliary output
        :math:`P y(t+d) + (q_0/b_0) Q u(t) - r(t)`.

        Parameters
        ----------
        noise_variance : float, default 1.0
            Variance :math:`\sigma^2` of ``e``.
        """
        return float(noise_variance) * float(self.F @ self.F)

    def __repr__(self):
        return (super().__repr__().replace("RSTController", type(self).__name__, 1)
                + f"\n  d = {self.d}, F = {self.F.tolist()}, G = {self.G.tolist()}")


def minimum_variance(A, B=None, C=None, d=None, *, dt=None):
    r"""Minimum-variance controller of the ARMAX plant :math:`A y = q^{-d} B' u + C e`.

    Parameters
    ----------
    A : array_like or model
        ``[1, a1, ..]`` (monic), or a model (then omit `B` and `C`): any
        rlsfilt model through ``polydata()`` (ARX, ARMAX, and OE or BJ over
        the common denominator ``A F D``), or an object whose
        ``polynomials()`` gives ``A, B`` and optionally ``C``, or
        ``A, B, C, D, F`` (a streaming `RecursiveOE`, `RecursiveBJ`, ...).
    B : array_like
        ``q^-d B'``: ``d`` leading zeros, then ``B'`` with ``B'(0) != 0``.
        ``B'`` must be stable (minimum phase): the design cancels it.
    C : array_like, optional
        Noise polynomial (monic, stable); ``1`` (an ARX plant) by default.
    d : int, optional
        The delay, ``>= 1``; the number of leading zeros of `B` by default
        (if given it must match).
    dt : True or float, optional
        Sampling period; the model's ``dt`` or ``True``.

    Returns
    -------
    MinimumVarianceController
        ``R = B' F``, ``S = G``, ``T = C``: :math:`y(t+d) = r(t) + F e(t+d)`.

    Raises
    ------
    ValueError
        For a non-monic `A` or `C`, an unstable `C`, a non-minimum-phase
        ``B'``, or a `d` that does not match `B`.

    Notes
    -----
    From :math:`C = A F + q^{-d} G` the output ``d`` steps ahead is

    .. math::

        y(t+d) = \frac{G\, y(t) + B' F\, u(t)}{C} + F e(t+d),

    whose first term is known at time ``t`` and the second is not. The law
    :math:`B' F u(t) = C r(t) - G y(t)` sets the first to :math:`r(t)`, so
    that in closed loop :math:`y(t) = r(t-d) + F e(t)`: the output variance
    about the reference is :math:`\sigma^2 (1 + f_1^2 + \dots + f_{d-1}^2)`.
    The closed-loop characteristic polynomial is :math:`B' C`, hence the
    requirement that ``B'`` and ``C`` be stable. Astrom & Wittenmark
    (1995), ch. 4.

    References
    ----------
    .. [1] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 4.
    .. [2] K. J. Astrom and B. Wittenmark, *Computer-Controlled Systems*,
       3rd ed., Prentice Hall, 1997 (optimal design, input-output approach).

    Examples
    --------
    ``y(t) - 0.9 y(t-1) = u(t-2) + e(t) + 0.5 e(t-1)``: with ``d = 2`` the
    best achievable output variance is ``(1 + f1^2) sigma^2``, ``f1 = 1.4``:

    >>> from rlsfilt.adaptive import minimum_variance
    >>> mv = minimum_variance([1, -0.9], [0, 0, 1], [1, 0.5])
    >>> mv.F, round(mv.output_variance(), 12)
    (array([1. , 1.4]), 2.96)
    """
    A, B, C, dt = _armax(A, B, C, dt, "minimum_variance")
    d, Bp = _delay(B, d)
    Bs = trim(Bp)
    if len(Bs) > 1 and np.max(np.abs(roots(Bs))) >= 1.0:
        z = roots(Bs)[np.argmax(np.abs(roots(Bs)))]
        raise ValueError(
            f"`B` must be minimum phase for minimum-variance control (it cancels the zeros of "
            f"B'); got a zero at z = {fmt_complex(z)} (|z| = {abs(z):.6g}); use "
            "generalized_minimum_variance with a weight Q on u, or rst_design")
    return _gmv(A, Bs, C, d, np.ones(1), np.zeros(1), dt)


def generalized_minimum_variance(A, B=None, C=None, d=None, *, P=1.0, Q=0.0, dt=None):
    r"""Generalized minimum-variance controller (Clarke & Gawthrop) of an ARMAX plant.

    Minimizes, at every step, the expected one-step cost

    .. math::

        J = E\big[(P(q^{-1})\, y(t+d) - r(t))^2 + (Q(q^{-1})\, u(t))^2 \,\big|\, t\big].

    Parameters
    ----------
    A, B, C, d, dt
        As in `minimum_variance` (``B'`` need not be minimum phase here).
    P : array_like or float, default 1.0
        Weight on the output (``P(0) != 0``); a scalar is a constant.
    Q : array_like or float, default 0.0
        Weight on the control, with ``Q(0) >= 0`` (the cost has
        :math:`(Q u)^2`: ``-Q`` is the same weight, so a negative ``Q(0)`` is
        refused as a slip). ``P = 1, Q = 0`` is minimum variance.

    Returns
    -------
    MinimumVarianceController
        :math:`R = B' F + (q_0 / b_0)\, C Q`, ``S = G``, ``T = C``, with
        :math:`P C = A F + q^{-d} G`, :math:`q_0 = Q(0)`, :math:`b_0 = B'(0)`.

    Raises
    ------
    ValueError
        For bad polynomials, ``P(0) = 0`` or ``Q(0) < 0``, or weights that make
        the closed loop unstable (the message names `P` and `Q` and the
        offending pole).

    Notes
    -----
    With :math:`\hat\phi = (G y(t) + B' F u(t)) / C`, the prediction of
    :math:`P y(t+d)`, the cost is :math:`(\hat\phi - r)^2 + (Q u)^2` plus a
    term ``u(t)`` cannot change; ``u(t)`` enters :math:`\hat\phi` with
    weight :math:`b_0` and :math:`Q u` with weight :math:`q_0`, so the
    minimum is at :math:`b_0 (\hat\phi - r) + q_0 (Q u)(t) = 0`:

    .. math::

        \big(B' F + \tfrac{q_0}{b_0} C Q\big)\, u(t) = C\, r(t) - G\, y(t).

    The closed-loop characteristic polynomial is
    :math:`C\,(P B' + \tfrac{q_0}{b_0} Q A)`: the weights move the poles
    away from the zeros of ``B'``, which is how the design copes with a
    non-minimum-phase plant. With :math:`Q \ne 0` the static gain from
    ``r`` to ``y`` is not 1 (use integral action in ``Q``, e.g.
    :math:`Q = \lambda (1 - q^{-1})`, to remove the offset). Clarke &
    Gawthrop (1975); Astrom & Wittenmark (1995), ch. 4.

    References
    ----------
    .. [1] D. W. Clarke and P. J. Gawthrop, "Self-tuning controller", *Proc.
       IEE* 122(9), 1975.
    .. [2] K. J. Astrom and B. Wittenmark, *Adaptive Control*, 2nd ed.,
       Addison-Wesley, 1995, ch. 4.

    Examples
    --------
    A non-minimum-phase plant (zero at z = -1.5) that minimum variance
    cannot control; a weight on ``u`` stabilizes the loop:

    >>> import numpy as np
    >>> from rlsfilt.adaptive import generalized_minimum_variance
    >>> A, B = [1, -0.9], [0, 1, 1.5]
    >>> gmv = generalized_minimum_variance(A, B, Q=1.0)
    >>> gmv.closed_loop(A, B).stable
    True
    """
    A, B, C, dt = _armax(A, B, C, dt, "generalized_minimum_variance")
    d, Bp = _delay(B, d)
    P = trim(as_poly(P, "P"))
    if P[0] == 0.0:
        raise ValueError(f"`P` must have P(0) != 0; got P = {P.tolist()}")
    Q = trim(as_poly(Q, "Q"))
    if Q[0] < 0.0:      # the cost weighs (Q u)^2: -Q is the same weight, so a sign is a slip
        raise ValueError(f"`Q` must have Q(0) >= 0 (a weight on u: the cost has (Q u)^2, "
                         f"so -Q weighs as Q); got Q = {Q.tolist()}")
    return _gmv(A, trim(Bp), C, d, P, Q, dt)


def _gmv(A, Bp, C, d, P, Q, dt):
    PC = np.convolve(P, C)
    # F: the first d coefficients of the series P C / A (A monic):
    #   f_k = (PC)_k - sum_{i=1..k} a_i f_{k-i}
    F = np.zeros(d)
    for k in range(d):
        acc = PC[k] if k < len(PC) else 0.0
        for i in range(1, min(k, len(A) - 1) + 1):
            acc -= A[i] * F[k - i]
        F[k] = acc
    rest = padd(PC, -np.convolve(A, F))    # = q^-d G: its first d coefficients vanish
    G = trim(rest[d:]) if len(rest) > d else np.zeros(1)
    b0, q0 = Bp[0], Q[0]
    R = padd(np.convolve(Bp, F), (q0 / b0) * np.convolve(C, Q))
    ctrl = MinimumVarianceController(R, G, C, dt, F=F, G=G, d=d, P=P, Q=Q)
    char = trim(padd(np.convolve(P, Bp), (q0 / b0) * np.convolve(Q, A)))
    if len(char) > 1:
        r = roots(char)
        if np.max(np.abs(r)) >= 1.0:
            z = r[np.argmax(np.abs(r))]
            raise ValueError(
                f"`P` and `Q` give an unstable closed loop: P B' + (q0/b0) Q A = "
                f"{format_poly(char)} has a zero at z = {fmt_complex(z)} (|z| = {abs(z):.6g}); "
                "increase the weight Q on u or change P")
    return ctrl


def _armax(A, B, C, dt, who):
    model = None
    if B is None:
        if not (hasattr(A, "polydata") or hasattr(A, "polynomials")):
            raise TypeError(f"{who}: `B` is required unless `A` is a model with polynomials(); "
                            f"got A of type {type(A).__name__}")
        model = A
        A, B, Cm = model_polynomials(model, "A", 3)
        if C is None:
            C = Cm
    A = trim(as_poly(A, "A", monic=True))
    B = as_poly(B, "B")
    C = np.ones(1) if C is None else trim(as_poly(C, "C", monic=True))
    check_stable(C, "C")
    dt = check_dt(model_dt(model) if dt is None and model is not None else
                  (True if dt is None else dt))
    return A, B, C, dt


def _delay(B, d):
    nz = np.flatnonzero(B)
    if not len(nz):
        raise ValueError(f"`B` must be a nonzero polynomial; got B = {B.tolist()}")
    lead = int(nz[0])
    if d is None:
        d = lead
        if d < 1:
            raise ValueError(f"`B` must start with at least one zero (a delay d >= 1); got "
                             f"B = {B.tolist()}")
    else:
        d = check_int(d, "d", minimum=1)
        if d != lead:
            raise ValueError(f"`d` must equal the number of leading zeros of B ({lead}, "
                             f"B = {B.tolist()}); got d = {d}")
    return d, B[d:]
