r"""Stability of monic polynomials in :math:`q^{-1}`, and its enforcement by reflection.

The predictors of the model family filter data through :math:`1/C` and
:math:`1/F_i` (and their gradients through :math:`D/(C F_i)`), so these
polynomials must have every zero strictly inside the unit circle; ``D`` must
too, for the noise model :math:`C/D` to describe a stationary disturbance
(and to be the unique, minimum-phase spectral factor). A polynomial that has
left the stability region is brought back by *reflecting* its zeros outside
the circle to
:math:`1/\bar z`: this keeps the magnitude of its frequency response up to a
constant (the spectrum of the noise model is unchanged in shape); it is the
usual projection into the stability region of prediction-error methods
(Ljung 1999, ch. 10-11).

A compiled copy of `is_stable` and `reflect` lives in
:mod:`rlsfilt.models._recursive_kernels` for the recursions; the tests hold
the two equal.

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
   Prentice Hall, 1999, ch. 10 and 11.
.. [2] K. J. Astrom and B. Wittenmark, *Computer-Controlled Systems*, 3rd
   ed., Prentice Hall, 1997, ch. 3 (the Schur-Cohn-Jury test).
"""

import numpy as np

from ._family import split_theta

__all__ = []

#: Largest root radius that counts as stable after a reflection (a zero on
#: the unit circle is pulled just inside it, where 1/C still decays).
RADIUS_MAX = 1.0 - 1e-8


def is_stable(p):
    r"""Whether the monic ``p = [1, p_1, .., p_n]`` has all zeros in ``|z| < 1``.

    The Schur-Cohn (Levinson step-down) recursion: with
    :math:`k_m = p^{(m)}_m`, step down
    :math:`p^{(m-1)}_j = (p^{(m)}_j - k_m p^{(m)}_{m-j}) / (1 - k_m^2)`;
    the polynomial is stable if and only if every :math:`|k_m| < 1`. About
    :math:`n^2` operations and no root finding.

    Examples
    --------
    >>> from rlsfilt.models._stability import is_stable
    >>> is_stable([1.0, 1.6, 0.8]), is_stable([1.0, -2.5, 1.0])
    (True, False)
    """
    a = np.array(p, dtype=float)
    for m in range(len(a) - 1, 0, -1):
        k = a[m]
        if not abs(k) < 1.0:             # also catches NaN
            return False
        a = (a[:m] - k * a[m:0:-1]) / (1.0 - k * k)
    return True


def reflect(p):
    r"""``p`` with its zeros outside the unit circle reflected to ``1/conj(z)``.

    Zeros on (or, after reflection, within round-off of) the circle are
    pulled in to radius `RADIUS_MAX`. The result is monic and real: the
    product of :math:`(1 - r q^{-1})` over the (reflected) zeros. A stable
    ``p`` is returned unchanged (as a new array).

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.models._stability import reflect
    >>> np.round(reflect([1.0, -2.5, 1.0]), 12)      # zeros 2 and 0.5 -> 0.5 (double)
    array([ 1.  , -1.  ,  0.25])
    """
    p = np.array(p, dtype=float)
    if len(p) <= 1 or is_stable(p) or not np.isfinite(p).all():
        return p
    roots = np.roots(p)
    r = np.abs(roots)
    out = np.where(r > 1.0, 1.0 / np.conj(roots), roots)
    r = np.abs(out)
    out = np.where(r > RADIUS_MAX, out * (RADIUS_MAX / np.maximum(r, 1e-300)), out)
    return np.real(np.poly(out))


def stabilize_theta(theta, s):
    """``theta`` with ``C``, ``D`` and every ``F_i`` reflected into the unit circle.

    ``A`` is left alone: the predictor never divides by it (an unstable
    plant can be identified). Returns ``(theta, changed)``.
    """
    from ._family import join_theta

    A, B, C, D, F = split_theta(theta, s)
    C2, D2 = reflect(C), reflect(D)
    F2 = [reflect(f) for f in F]
    changed = (not np.array_equal(C2, C) or not np.array_equal(D2, D)
               or any(not np.array_equal(a, b) for a, b in zip(F, F2)))
    if not changed:
        return np.array(theta, dtype=float), False
    return join_theta(s, A=A, B=B, C=C2, D=D2, F=F2), True


def predictor_is_stable(theta, s):
    """Whether ``C``, ``D`` and every ``F_i`` of ``theta`` are stable."""
    _, _, C, D, F = split_theta(theta, s)
    return is_stable(C) and is_stable(D) and all(is_stable(f) for f in F)
