r"""Discrete-to-continuous conversion of python-control systems (MATLAB's ``d2c``).

python-control samples continuous systems (``control.sample_system``) but
offers no inverse. `d2c` inverts the two samplings an identified model is
usually read through:

* zero-order hold: :math:`\exp\left(T \begin{bmatrix} A_c & B_c \\ 0 & 0
  \end{bmatrix}\right) = \begin{bmatrix} A_d & B_d \\ 0 & I \end{bmatrix}`,
  so the principal matrix logarithm of the right-hand side, divided by
  :math:`T`, gives :math:`A_c, B_c` (:math:`C, D` are unchanged);
* Tustin (bilinear): :math:`z = (1 + sT/2)/(1 - sT/2)`, inverted in closed
  form on the state-space matrices.

Whole-sample delays (poles of a transfer function at :math:`z = 0` that
only delay the input) become explicit time delays.
"""

import numbers

import numpy as np

__all__ = ["d2c"]

_METHODS = ("zoh", "tustin")
# |z| below this (relative to the largest pole, at least 1) counts as a pole at the origin
_ORIGIN_TOL = 1e-8
# a pole within this angle of the negative real axis has no real ZOH preimage
_NEGATIVE_AXIS_TOL = 1e-8


def d2c(sys, method="zoh", *, pade=None):
    r"""Continuous-time equivalent of a discrete-time system (MATLAB ``d2c``).

    Parameters
    ----------
    sys : control.TransferFunction or control.StateSpace
        Discrete-time system with a numeric sampling period ``sys.dt``
        (SISO or MIMO).
    method : {"zoh", "tustin"}, default "zoh"
        The sampling to invert: zero-order hold (what ``sample_system(Gc,
        T)`` does, and how a plant driven through a DAC is sampled), or the
        bilinear transform (``sample_system(Gc, T, "tustin")``).
    pade : int, optional
        Replace the time delays by Pade approximations of this order
        (``control.pade``), so that the result is a delay-free rational
        system usable in further design.

    Returns
    -------
    control.TransferFunction or control.StateSpace
        The continuous system, of the kind of `sys`, with its signal
        labels. Attributes ``input_delay`` (seconds, shape ``(nu,)``) and
        ``io_delay`` (seconds, shape ``(ny, nu)``, the extra delay of each
        entry beyond its input's) hold the explicit delays, as MATLAB's
        ``InputDelay`` and ``IODelay`` properties; they are zero with
        `pade` (and python-control's own operations do not carry them).

    Raises
    ------
    TypeError
        If `sys` is not a python-control transfer function or state-space
        system.
    ValueError
        Continuous `sys` or unspecified sampling period; unknown method;
        for ``"zoh"``, poles at or near ``z = 0`` that are not whole-sample
        delays, or real negative poles (neither has a real continuous
        preimage under a zero-order hold; MATLAB raises for the first and
        raises the model order for the second); for ``"tustin"``, poles at
        ``z = -1``; for a state-space `sys`, poles at the origin (delays are
        extracted from transfer functions: convert with ``control.tf``).

    Notes
    -----
    **Zero-order hold.** With :math:`M = \begin{bmatrix} A_d & B_d \\ 0 & I
    \end{bmatrix}`, :math:`\begin{bmatrix} A_c & B_c \\ 0 & 0 \end{bmatrix}
    = \log(M) / T` (``scipy.linalg.logm``). The principal logarithm is the
    sampled system's preimage whose poles satisfy
    :math:`|\mathrm{Im}\, s| < \pi / T` (no aliasing); it is real exactly
    when no eigenvalue of :math:`A_d` lies on the closed negative real axis.

    **Tustin.** With :math:`h = T/2`, the inverse of ``scipy``'s bilinear
    map (:math:`A_d = (I - hA)^{-1}(I + hA)`, :math:`B_d = (I - hA)^{-1} T
    B`, :math:`C_d = C (I - hA)^{-1}`, :math:`D_d = D + C B_d / 2`) is

    .. math::

        A = \tfrac{1}{h} (A_d - I)(A_d + I)^{-1},\quad
        B = \tfrac{2}{T} (A_d + I)^{-1} B_d,\quad
        C = 2\, C_d (A_d + I)^{-1},\quad D = D_d - \tfrac12 C B_d.

    **Delays.** For a transfer function each entry :math:`G_{ij}(z) = z^{-d}
    N(z)/D'(z)` with :math:`d` poles at the origin and :math:`N/D'` proper
    is the sampled delay :math:`e^{-s d T}` in series with the continuous
    equivalent of :math:`N/D'`; the smallest :math:`d` of each input column
    is its ``input_delay``. Transfer-function entries are converted one by
    one (a sampling is linear in the system, so this equals converting the
    whole matrix).

    References
    ----------
    .. [1] G. F. Franklin, J. D. Powell and M. L. Workman, *Digital Control
       of Dynamic Systems*, 3rd ed., Addison-Wesley, 1998, sec. 4.3 and 6.3.
    .. [2] MATLAB Control System Toolbox, ``d2c``.

    Examples
    --------
    MATLAB's example, ``H(z) = (z - 1)/(z^2 + z + 0.3)`` at ``Ts = 0.1``:

    >>> import control
    >>> import numpy as np
    >>> from rlsfilt.continuous import d2c
    >>> Hc = d2c(control.tf([1, -1], [1, 1, 0.3], 0.1))
    >>> np.round(Hc.num[0][0], 1), np.round(Hc.den[0][0], 2)
    (array([121.7,   0. ]), array([  1.  ,  12.04, 776.65]))

    A first-order lag with three samples of dead time keeps its delay:

    >>> Gd = control.tf([0.5], [1, -0.5, 0, 0, 0], 0.2)   # 0.5 z^-3 / (z - 0.5)
    >>> Gc = d2c(Gd)
    >>> Gc.input_delay
    array([0.6])
    """
    import control

    if not isinstance(sys, (control.TransferFunction, control.StateSpace)):
        raise TypeError(f"`sys` must be a discrete control.TransferFunction or "
                        f"control.StateSpace; got {type(sys).__name__}")
    if not isinstance(method, str) or method not in _METHODS:
        raise ValueError(f"`method` must be 'zoh' or 'tustin'; got {method!r}")
    dt = sys.dt
    if dt is None or dt is True or isinstance(dt, bool) or not isinstance(dt, numbers.Real) \
            or dt <= 0:
        what = ("continuous-time (dt=0)" if dt in (0, None) else
                "discrete with an unspecified sampling period (dt=True)")
        raise ValueError(f"`sys` must be discrete-time with a numeric sampling period; got a "
                         f"system that is {what}")
    if pade is not None:
        if isinstance(pade, bool) or not isinstance(pade, numbers.Integral) or pade < 1:
            raise ValueError(f"`pade` must be None or an integer order >= 1; got {pade!r}")
    labels = {"inputs": list(sys.input_labels), "outputs": list(sys.output_labels)}
    ny, nu = sys.noutputs, sys.ninputs
    if isinstance(sys, control.StateSpace):
        A, B, C, D = (np.asarray(M, dtype=float) for M in (sys.A, sys.B, sys.C, sys.D))
        _check_poles(np.linalg.eigvals(A) if A.size else np.zeros(0), method, state_space=True)
        Ac, Bc, Cc, Dc = _ss_d2c(A, B, C, D, float(dt), method)
        out = control.ss(Ac, Bc, Cc, Dc, **labels)
        delays_in, delays_io = np.zeros(nu), np.zeros((ny, nu))
    else:
        d_samples = np.zeros((ny, nu), dtype=int)
        entries = [[None] * nu for _ in range(ny)]
        for i in range(ny):
            for j in range(nu):
                num = np.trim_zeros(np.asarray(sys.num[i][j], dtype=float), "f")
                den = np.trim_zeros(np.asarray(sys.den[i][j], dtype=float), "f")
                entries[i][j], d_samples[i, j] = _entry_d2c(num, den, float(dt), method, (i, j),
                                                            (ny, nu))
        d_in = np.array([min((d_samples[i, j] for i in range(ny) if entries[i][j] is not None),
                             default=0) for j in range(nu)])
        delays_in = d_in * float(dt)
        delays_io = (d_samples - d_in[None, :]) * float(dt)
        delays_io[np.array([[e is None for e in row] for row in entries])] = 0.0
        nums = [[e[0] if e is not None else np.zeros(1) for e in row] for row in entries]
        dens = [[e[1] if e is not None else np.ones(1) for e in row] for row in entries]
        if pade is not None:
            for i in range(ny):
                for j in range(nu):
                    if entries[i][j] is not None and d_samples[i, j] > 0:
                        pn, pd = control.pade(d_samples[i, j] * float(dt), pade)
                        nums[i][j] = np.polymul(nums[i][j], pn)
                        dens[i][j] = np.polymul(dens[i][j], pd)
            delays_in, delays_io = np.zeros(nu), np.zeros((ny, nu))
        if ny == 1 and nu == 1:
            out = control.tf(nums[0][0], dens[0][0], **labels)
        else:
            out = control.tf(nums, dens, **labels)
    out.input_delay = delays_in
    out.io_delay = delays_io
    return out


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _check_poles(poles, method, state_space=False, where=""):
    if not len(poles):
        return
    scale = max(1.0, float(np.max(np.abs(poles))))
    if method == "zoh":
        near0 = np.abs(poles) <= _ORIGIN_TOL * scale
        if near0.any():
            hint = (" (whole-sample delays are extracted from transfer functions: convert with "
                    "control.tf(sys) first)" if state_space else
                    "; they are not whole-sample delays of the input")
            raise ValueError(f"the 'zoh' method cannot be used for discrete models with poles "
                             f"near z=0{where}{hint}; use method='tustin'")
        neg = (poles.real < 0) & (np.abs(poles.imag) <= _NEGATIVE_AXIS_TOL * np.abs(poles))
        if neg.any():
            p = poles[neg][0].real
            raise ValueError(
                f"the 'zoh' method cannot convert a discrete model with real negative poles "
                f"(z = {p:.6g}{where}): no real continuous system sampled with a zero-order "
                f"hold has them (MATLAB raises the model order with complex pole pairs); use "
                f"method='tustin' or identify a model without them")
    else:
        at_m1 = np.abs(poles + 1.0) <= 1e-10 * scale
        if at_m1.any():
            raise ValueError(f"the 'tustin' method cannot convert poles at z = -1{where} (the "
                             "Nyquist frequency maps to s = infinity)")


def _ss_d2c(A, B, C, D, dt, method):
    n, m = A.shape[0], B.shape[1]
    if n == 0:
        return A.copy(), B.copy(), C.copy(), D.copy()
    if method == "zoh":
        # log([[Ad, Bd], [0, I]]) / T = [[Ac, Bc], [0, 0]]
        M = np.zeros((n + m, n + m))
        M[:n, :n], M[:n, n:], M[n:, n:] = A, B, np.eye(m)
        from scipy import linalg  # lazy: keeps `import rlsfilt` light
        L = linalg.logm(M)
        if np.iscomplexobj(L):
            if np.max(np.abs(L.imag)) > 1e-8 * max(1.0, np.max(np.abs(L.real))):
                raise ValueError("the matrix logarithm of the sampled system is not real: "
                                 "the 'zoh' method has no real continuous equivalent")
            L = L.real
        L = L / dt
        return L[:n, :n], L[:n, n:], C.copy(), D.copy()
    # Tustin: the closed-form inverse of scipy's bilinear map (see d2c's Notes)
    F = A + np.eye(n)
    Finv = np.linalg.inv(F)
    Ac = (2.0 / dt) * (A - np.eye(n)) @ Finv
    Bc = (2.0 / dt) * Finv @ B
    Cc = 2.0 * C @ Finv
    Dc = D - 0.5 * Cc @ B
    return Ac, Bc, Cc, Dc


def _entry_d2c(num, den, dt, method, ij, shape):
    """One SISO entry: ``((num_c, den_c), delay in samples)`` or ``(None, 0)`` for a zero."""
    where = f" in entry {ij}" if shape != (1, 1) else ""
    if not len(num) or not np.any(num):
        return None, 0
    # poles at the origin that only delay: z^-d N(z)/D'(z) with N/D' proper
    zeros_at_origin = len(den) - len(np.trim_zeros(den, "b"))
    den_q = np.trim_zeros(den, "b")
    rel = (len(den) - 1) - (len(num) - 1)  # relative degree of the whole entry
    d = min(zeros_at_origin, max(rel, 0))
    if d < zeros_at_origin:  # put the remaining origin poles back: they are not delays
        den_q = np.concatenate([den_q, np.zeros(zeros_at_origin - d)])
    _check_poles(np.roots(den_q) if len(den_q) > 1 else np.zeros(0), method, where=where)
    gain = den_q[0]
    num, den_q = num / gain, den_q / gain
    n = len(den_q) - 1
    if n == 0:  # a static gain
        return (np.array([num[-1]]), np.array([1.0])), d
    # controllable canonical realization of N/D' (N padded to degree n)
    num_p = np.concatenate([np.zeros(n + 1 - len(num)), num])
    A = np.zeros((n, n))
    A[0, :] = -den_q[1:]
    A[1:, :-1] = np.eye(n - 1)
    B = np.zeros((n, 1))
    B[0, 0] = 1.0
    D = np.array([[num_p[0]]])
    C = (num_p[1:] - num_p[0] * den_q[1:]).reshape(1, n)
    Ac, Bc, Cc, Dc = _ss_d2c(A, B, C, D, dt, method)
    return _ss_to_tf(Ac, Bc, Cc, Dc), d


def _ss_to_tf(A, B, C, D):
    """Numerator and monic denominator of a SISO realization.

    ``den = det(sI - A)`` and ``num = det(sI - A + B C) - den + D den``; the
    ``s^n`` coefficient of ``num`` is exactly ``D`` (set so, not left to
    round-off), and leading coefficients below ``1e-12`` of the largest are
    round-off of a higher relative degree and are dropped.
    """
    den = np.real(np.poly(A))
    num = np.real(np.poly(A - B @ C)) - den + D[0, 0] * den
    num[0] = D[0, 0]
    big = np.max(np.abs(num)) if num.size else 0.0
    k = 0
    while k < len(num) - 1 and abs(num[k]) <= 1e-12 * big:
        k += 1
    return num[k:], den
