r"""The compiled (numba) per-sample work of `SelfTuningRegulator`: design, law, memories.

`design_full` does, for the estimate ``A, B``, what the regulator's NumPy
path does on its common branch (an estimate far from a common factor, the
default `rst_design` with no cancelled zero): the coprimeness of ``A, B``,
`rst_design`'s checks and Sylvester solve, the padding of ``R, S, T`` to the
regulator's rows, the verification ``A R + B S = target``, the stability of
the loop on the estimate and the size bound. It either accepts the design
(status 0: the rows are written, and the size returned) or
returns another status, and the regulator then runs its NumPy path, which
takes the same decision and words the reason (so every message, the reduced
design and every error stay in one place).

The coprimeness decisions are certified by a Cholesky test of
:math:`M^T M - \tau'^2 I` (`_above`); the SVD runs only when that cannot
decide, so the decision is the NumPy path's. The stability of the loop on the
estimate is the Schur-Cohn recursion on the coefficients of ``A R + B S``
(no roots; the roots are computed only by the NumPy path, which reports them).

`control_law` and `remember` are the rest of a sample's arithmetic (the law
``R u = T r - S y`` and the end-of-sample memories and sums); `design_and_law`
is a sample's common case in one call (the estimate's polynomials, the design,
the law).

Measured with ``benchmarks/bench_diagrams.py`` (N = 1000, thread CPU time,
the main branch and this one in one session): the design call takes about
5 us against 126 us for the NumPy design and install; ``SelfTuningRegulator.step``
went from 187 us to 33 us per sample (5.6x the bare filter step of 5.9 us),
the regulator inside ``control.interconnect``, python-control's overhead
aside, from 443 us to 109 us.

Every function is ``njit(cache=True)``.
"""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable
from ..filters._kernels_vector import PLAIN, vector_assign_x, vector_step, vector_x_P

__all__ = []

#: statuses of `design_full`: 0 accepted; anything else: run the NumPy path
ACCEPTED, NEAR_FACTOR, NOT_DESIGNABLE, NOT_VERIFIED = 0, 1, 2, 3


@njit(cache=True, error_model="numpy")
def _degree(p):
    """Index of the last nonzero coefficient (-1 for zero), as ``_polynomials.degree``."""
    for i in range(len(p) - 1, -1, -1):
        if p[i] != 0.0:
            return i
    return -1


@njit(cache=True, error_model="numpy")
def _sylvester(a, b):
    """``_polynomials.sylvester(a, b)`` for trimmed `a`, `b` (``len = degree + 1``)."""
    na, nb = len(a) - 1, len(b) - 1
    n = na + nb
    M = np.zeros((n, n))
    for j in range(nb):                 # x_j q^-j a
        for i in range(na + 1):
            M[j + i, j] = a[i]
    for j in range(na):                 # y_j q^-j b
        for i in range(nb + 1):
            M[j + i, nb + j] = b[i]
    return M


@njit(cache=True, error_model="numpy")
def _above(M, tau):
    r"""Whether :math:`\sigma_{min}(M) > \tau` is certain: the Cholesky factorization of
    :math:`M^T M - \tau'^2 I` succeeds, with :math:`\tau' = \tau (1 + 10^{-6}) +
    10^{-6}` (a margin far above the round-off of :math:`M^T M`, about
    :math:`10^{-15}` for the unit-norm columns of a coprimeness matrix).

    A sufficient test, some 20 times cheaper than the SVD: False means "not
    certain", and the caller then computes the singular value.
    """
    n = M.shape[0]
    t = tau * (1.0 + 1e-6) + 1e-6
    G = M.T @ M
    for i in range(n):
        G[i, i] -= t * t
    for j in range(n):                  # in-place Cholesky, lower triangle
        d = G[j, j]
        for k in range(j):
            d -= G[j, k] * G[j, k]
        if not d > 0.0:
            return False
        d = np.sqrt(d)
        G[j, j] = d
        for i in range(j + 1, n):
            v = G[i, j]
            for k in range(j):
                v -= G[i, k] * G[j, k]
            G[i, j] = v / d
    return True


@njit(cache=True, error_model="numpy")
def _unit(p):
    """`p` scaled to unit 2-norm, by its largest magnitude first, as ``_polynomials``'
    (the norm of coefficients around 1e155 overflows, of subnormal ones underflows)."""
    p = p / np.max(np.abs(p))
    return p / np.sqrt(np.dot(p, p))


@njit(cache=True, error_model="numpy")
def _coprime_at_least(a, b, tau):
    """``(coprimeness(a, b) >= tau, the coprimeness or NaN when not needed)``.

    ``_polynomials.coprimeness`` for trimmed `a`, `b` (`b` nonzero), computed
    (SVD) only when `_above` cannot certify the decision: the decision is the
    NumPy path's.
    """
    if len(a) + len(b) == 2:
        return True, np.inf
    M = _sylvester(_unit(a), _unit(b))
    if _above(M, tau):
        return True, np.nan
    sigma = np.linalg.svd(M, full_matrices=False)[1][-1]
    return sigma >= tau, sigma


@njit(cache=True, error_model="numpy")
def _add_product(out, a, b):
    """``out[:len(a) + len(b) - 1] += a * b`` (the polynomial product, ``np.convolve``;
    a loop: numba's ``np.convolve`` costs some 2 us a call at these sizes)."""
    for i in range(len(a)):
        ai = a[i]
        for j in range(len(b)):
            out[i + j] += ai * b[j]


@njit(cache=True, error_model="numpy")
def _schur_stable(p):
    r"""Whether every zero of ``z^n p(z^-1)`` is strictly inside the unit circle.

    The Schur-Cohn (step-down) recursion on the coefficients, no roots:
    with :math:`k = p_n / p_0`, the polynomial is stable iff :math:`|k| < 1`
    and :math:`(p_i - k\, p_{n-i}) / (1 - k^2)`, ``i < n``, is stable.
    """
    n = len(p) - 1
    a = p.copy()
    for m in range(n, 0, -1):
        k = a[m] / a[0]
        if not abs(k) < 1.0:
            return False
        c = 1.0 - k * k
        b = a[:m].copy()
        for i in range(m):
            b[i] = (a[i] - k * a[m - i]) / c
        a[:m] = b
    return True


@njit(cache=True, error_model="numpy")
def design_full(A, B, Acl, Ao, am_sum, integral, tol_design, tol_reg, reduce_tol,
                max_growth, have_ctrl, size_last, rows):
    r"""The regulator's full design for ``A, B``: ``(status, size)``, `rows` written.

    Parameters: `A`, `B` as the regulator forms them (``A`` monic, ``B``
    with its ``nk`` leading zeros, untrimmed); `Acl` ``= trim(Am Ao)``, `Ao`,
    `am_sum` ``= Am.sum()``, `integral` and `tol_design` (`coprime_tol`) of
    the design; `tol_reg`, `reduce_tol`, `max_growth` of the regulator and
    its state `have_ctrl`, `size_last`; `rows` ``(3, L)`` receives ``R, S,
    T`` zero-padded when the status is `ACCEPTED` (a scratch array: it may be
    written also when the design is not accepted).

    In the equations of `rst_design` (no zero cancelled, ``B+ = 1``):

    .. math::

        \sigma = \sigma_{min}(\mathrm{Syl}(A/\|A\|, B/\|B\|)) \ge
            \max(\tau_{\mathrm{coprime}}, \tau_{\mathrm{reduce}}), \quad
        A_1 = A (1 - q^{-1}), \quad
        \mathrm{Syl}(A_1, B) [r'; s] = A_m A_o, \quad
        R = (1 - q^{-1}) R', \quad T = \frac{A_m(1)}{B(1)} A_o,

    (the thresholds :math:`\tau` are `coprime_tol` and `reduce_tol`), then
    :math:`|A R + B S - A_m A_o|_\infty \le 10^{-8} (|A|_1 |R|_1 +
    |B|_1 |S|_1)`, :math:`A R + B S` stable (Schur-Cohn) and the size
    :math:`(|R|_1 + |S|_1 + |T|_1) / |r_0| \le` `max_growth` times the
    previous one.
    """
    # coprimeness of the estimate (the regulator's graded test)
    da, db = _degree(A), _degree(B)
    if db < 0:
        return NEAR_FACTOR, 0.0
    a = A[:da + 1].copy()
    b = B[:db + 1].copy()
    ok, sigma = _coprime_at_least(a, b, max(tol_reg, reduce_tol))
    if not ok:
        return NEAR_FACTOR, 0.0
    # rst_design: A1 = A (1 - q^-1), the checks, the Sylvester solve
    if db < 1:
        return NOT_DESIGNABLE, 0.0
    if integral:
        a1 = np.zeros(da + 2)
        a1[:da + 1] += a
        a1[1:] -= a
    else:
        a1 = a
    n1 = _degree(a1)
    if len(Acl) - 1 > n1 + db - 1:
        return NOT_DESIGNABLE, 0.0
    bsum = 0.0
    for i in range(len(b)):
        bsum += b[i]
    if not abs(bsum) > tol_design * np.sqrt(np.dot(b, b)):
        return NOT_DESIGNABLE, 0.0
    a1 = a1[:n1 + 1].copy()
    ok, sigma1 = _coprime_at_least(a1, b, tol_design)
    if not (ok and sigma1 != 0.0):
        return NOT_DESIGNABLE, 0.0
    n = n1 + db
    rhs = np.zeros(n)
    rhs[:len(Acl)] = Acl
    x = np.linalg.solve(_sylvester(a1, b), rhs)
    if integral:
        R = np.zeros(db + 1)
        R[:db] += x[:db]
        R[1:] -= x[:db]
    else:
        R = x[:db].copy()
    S = x[db:]
    T = am_sum / bsum * Ao
    rmax = 0.0
    for v in R:
        rmax = max(rmax, abs(v))
    if abs(R[0]) <= 1e-12 * rmax or not (np.all(np.isfinite(R)) and np.all(np.isfinite(S))
                                         and np.all(np.isfinite(T))):
        return NOT_DESIGNABLE, 0.0
    # the rows (trimmed, zero-padded to L), as _rows; longer than L: the NumPy path raises
    L = rows.shape[1]
    dR, dS, dT = _degree(R), _degree(S), _degree(T)
    if dR >= L or dS >= L or dT >= L:
        return NOT_DESIGNABLE, 0.0
    rows[:] = 0.0
    rows[0, :dR + 1] = R[:dR + 1]
    rows[1, :max(dS, 0) + 1] = S[:max(dS, 0) + 1]
    rows[2, :max(dT, 0) + 1] = T[:max(dT, 0) + 1]
    Rc, Sc = rows[0], rows[1]
    # the verification: A R + B S against the target, on the estimate itself
    char = np.zeros(max(len(A) + L - 1, len(B) + L - 1))
    _add_product(char, A, Rc)
    _add_product(char, B, Sc)
    res = 0.0
    for i in range(max(len(char), len(Acl))):
        c = char[i] if i < len(char) else 0.0
        t = Acl[i] if i < len(Acl) else 0.0
        res = max(res, abs(c - t))
    scale = np.abs(A).sum() * np.abs(Rc).sum() + np.abs(B).sum() * np.abs(Sc).sum()
    if not res <= 1e-8 * scale:
        return NOT_VERIFIED, 0.0
    dc = _degree(char)
    if dc > 0 and not _schur_stable(char[:dc + 1]):
        return NOT_VERIFIED, 0.0
    size = (np.abs(rows[0]).sum() + np.abs(rows[1]).sum() + np.abs(rows[2]).sum()) / abs(R[0])
    if have_ctrl and size_last > 0 and size > max_growth * size_last:
        return NOT_VERIFIED, 0.0
    return ACCEPTED, size


@njit(cache=True, error_model="numpy")
def control_law(ctrl, rpast, ypast, upast, y, r):
    r"""``u(t)`` of :math:`R u = T r - S y` before the offset, the dither and the limits.

    .. math::

        u(t) = \big(t_0 r(t) + \sum_{i \ge 1} t_i r(t-i) - s_0 y(t)
               - \sum_{i \ge 1} s_i y(t-i) - \sum_{i \ge 1} r_i u(t-i)\big) / r_0

    with the rows ``R, S, T`` of `ctrl` (length ``L``) and the newest-first
    memories.
    """
    m = ctrl.shape[1] - 1
    R, S, T = ctrl[0], ctrl[1], ctrl[2]
    return (T[0] * r + np.dot(T[1:], rpast[:m]) - S[0] * y - np.dot(S[1:], ypast[:m])
            - np.dot(R[1:], upast[:m])) / R[0]


@njit(cache=True, error_model="numpy")
def design_and_law(theta, na, nb, nk, Acl, Ao, am_sum, integral, tol_design, tol_reg,
                   reduce_tol, max_growth, scalars, i_size, i_run, i_warned, rows, ctrl,
                   rpast, ypast, upast, y, r):
    r"""One sample's common case in one call: the estimate's ``A, B``, `design_full`
    and, if it accepts, the controller installed and ``u(t)`` of `control_law`.

    .. math::

        A = 1 + \theta_1 q^{-1} + \dots + \theta_{n_a} q^{-n_a}, \quad
        B = q^{-n_k} (\theta_{n_a+1} + \dots + \theta_{n_a+n_b} q^{-n_b+1})

    Returns ``(status, u)``. With status `ACCEPTED` the rows of `rows` are
    copied into `ctrl`, ``scalars[0]`` (a controller is in use) is 1,
    ``scalars[i_size]`` the new size and the run of rejected designs
    (``scalars[i_run]``, ``scalars[i_warned]``) is reset, as the regulator's
    Python does after an accepted design; otherwise nothing but the scratch
    `rows` is written and ``u`` is 0. One call instead of three (the
    polynomials, the design, the law) and the bookkeeping between them: about
    3 us less per sample of ``step`` and per look-ahead in a python-control
    diagram (``benchmarks/bench_diagrams.py``, the regulator in python-control's
    call pattern 70.5 to 64.2 us per sample against the previous version in one
    session).
    """
    A = np.empty(na + 1)
    A[0] = 1.0
    A[1:] = theta[:na]
    B = np.zeros(nk + nb)
    B[nk:] = theta[na:na + nb]
    status, size = design_full(A, B, Acl, Ao, am_sum, integral, tol_design, tol_reg,
                               reduce_tol, max_growth, scalars[0] != 0.0, scalars[i_size],
                               rows)
    if status != ACCEPTED:
        return status, 0.0
    ctrl[:] = rows
    scalars[0] = 1.0
    scalars[i_size] = size
    scalars[i_run] = 0.0
    scalars[i_warned] = 0.0
    return status, control_law(ctrl, rpast, ypast, upast, y, r)


@njit(cache=True, error_model="numpy")
def remember(ypast, upast, rpast, info, scalars, phi, y, u, r, saturated, i_sat, i_err2):
    r"""The end of a sample: push ``y, u, r`` into their newest-first memories,
    :math:`\sum \varphi\varphi^T` += :math:`\varphi\varphi^T`, and the watchdog's
    block sums: ``scalars[i_sat]`` += `saturated`, ``scalars[i_err2]`` +=
    :math:`(r - y)^2`."""
    for buf, value in ((ypast, y), (upast, u), (rpast, r)):
        for i in range(len(buf) - 1, 0, -1):
            buf[i] = buf[i - 1]
        if len(buf):
            buf[0] = value
    n = len(phi)
    for i in range(n):
        for j in range(n):
            info[i, j] += phi[i] * phi[j]
    scalars[i_sat] += saturated
    scalars[i_err2] += (r - y) ** 2


@njit(cache=True, error_model="numpy")
def prediction_error(y, phi, theta):
    r"""The a-priori prediction error :math:`e = y - \varphi^T \theta`, summed in order
    (the same number on the regulator's Python path and in `sample`)."""
    s = 0.0
    for i in range(len(phi)):
        s += phi[i] * theta[i]
    return y - s


@njit(cache=True, error_model="numpy")
def offset_control(theta, na, nb, R):
    r"""The control that holds the estimated offset ``c`` (last in `theta`):
    ``(applies, u_c R(1) / r_0)`` with :math:`u_c = -c / B(1)`, summed in order; it
    does not apply when :math:`|B(1)| \le 10^{-12} \sum |b_i|` (no gain to offset)."""
    bsum = babs = 0.0
    for i in range(nb):
        bsum += theta[na + i]
        babs += abs(theta[na + i])
    if not abs(bsum) > 1e-12 * babs:
        return False, 0.0
    rsum = 0.0
    for i in range(len(R)):
        rsum += R[i]
    return True, -theta[na + nb] / bsum * rsum / R[0]


@njit(cache=True, error_model="numpy")
def project_box(theta, lo, hi, out):
    """``out = clip(theta, lo, hi)`` entry by entry; returns whether an entry moved."""
    moved = False
    for i in range(len(theta)):
        t = theta[i]
        out[i] = lo[i] if t < lo[i] else (hi[i] if t > hi[i] else t)
        moved = moved or t < lo[i] or t > hi[i]
    return moved


@njit(cache=True, error_model="numpy")
def trace_of(P):
    """``trace(P)``, summed in order (the windup check's number on both paths)."""
    s = 0.0
    for i in range(P.shape[0]):
        s += P[i, i]
    return s


# ----------------------------------------------------------------------
# a whole sample on the state vector (the python-control system)
# ----------------------------------------------------------------------
#: Entries of the regulator's bookkeeping scalars (`self_tuning._SCALARS`) that `sample`
#: reads and writes.
(S_HAVE, S_STEP, S_TRACE_REF, S_WARNED_WINDUP, S_SIZE, S_RUN, S_WARNED_REJECTED, S_SAT,
 S_ERR2, S_LEVEL_MEAN, S_LEVEL_M2, S_LEVEL_MIN) = 0, 1, 2, 4, 10, 6, 7, 11, 12, 14, 15, 16
#: Entries of `sample`'s integer options.
(I_NF, I_NA, I_NB, I_NK, I_L, I_LY, I_LU, I_REDESIGN, I_PATIENCE, I_MONITOR, I_CHECK,
 I_INTEGRAL, I_BOUNDS, I_LIMITS, I_LEVEL_WINDOW, I_SCALARS, I_OFFSET) = range(17)
#: Entries of `sample`'s real options.
(R_IL, R_R, R_SIGNAL_LIMIT, R_DEAD_ZONE, R_U_LO, R_U_HI, R_COPRIME, R_REDUCE, R_GROWTH,
 R_WINDUP, R_AM_SUM, R_TOL_DESIGN, R_LEVEL_RATIO) = range(13)
#: Statuses of `sample`: 0 the sample is done; anything else, the regulator's Python
#: takes it (a message, an error, a design or a filter step the compiled path leaves).
(DONE, BAD_SIGNAL, LEVEL_MESSAGE, FILTER_STEP, NOT_FINITE, DESIGN, PATIENCE_MESSAGE,
 BAD_CONTROL, WINDUP_MESSAGE, MONITOR_DUE) = range(10)


@njit(cache=True, error_model="numpy")
def sample(v, w, out, outputs, ints, reals, Q, cfg, Acl, Ao, lo, hi):
    r"""One sample of the regulator on its state vector: ``out``, the state after it.

    `v` is the regulator's state vector (the estimator's state, then the
    memories ``y``, ``u``, ``r`` newest first, the rows ``R, S, T``, the
    scalars, :math:`\sum\varphi\varphi^T`); `w` the inputs ``[y, r, dither]``.
    The options: `ints` and `reals` (entries ``I_*`` and ``R_*``), the
    estimator's constants (`Q`, `cfg`, and ``il``, ``R``, ``check_every`` in the
    options: `rlsfilt.filters.contract.vector_step_constants`), the design's
    `Acl` ``= A_m A_o`` and `Ao`, the box `lo`, `hi`. Writes ``[u]`` (or ``[u, e,
    theta..]``) into `outputs`.

    The regulator's sample (`SelfTuningRegulator.step`) on its common branch, the
    same operations on the same numbers as its Python path:

    .. math::

        \varphi(t) = [-y(t-1) .. -y(t-n_a), u(t-n_k) .. u(t-n_k-n_b+1)], \quad
        e = y - \varphi^T \hat\theta,

    the estimator's plain step (`_kernels_vector.vector_step`) unless the dead
    zone skips it, the projection onto the box, the verified redesign
    (`design_and_law`) when due, else the law :math:`R u = T r - S y` with the
    controller in use, with an offset ``c`` (last in :math:`\varphi`, a 1) the
    control that holds it (`offset_control`), :math:`u \leftarrow \mathrm{sat}(u
    + v)`, then the
    memories and sums (`remember`), the windup check on
    :math:`\mathrm{tr}\,P` and the step count.

    Returns `DONE` (0), or the first reason the regulator's Python must take
    the sample (a signal to reject, a message to issue, a design it does not
    accept here, a filter step with something to decide, the monitor's block
    end): `out` and `outputs` are then unspecified. No option of the
    regulator's that this does not take (``stable_R``, another design) ever
    reaches it (`SelfTuningRegulator._vector_plan`).
    """
    nf, na, nb, nk, L = ints[I_NF], ints[I_NA], ints[I_NB], ints[I_NK], ints[I_L]
    offset = ints[I_OFFSET] != 0
    n = na + nb + offset
    y, r, dv = w[0], w[1], w[2]
    lim = reals[R_SIGNAL_LIMIT]
    if not (np.isfinite(y) and np.isfinite(r) and np.isfinite(dv) and abs(y) <= lim
            and abs(r) <= lim and abs(dv) <= lim):
        return BAD_SIGNAL
    out[:] = v
    oy = nf
    ou = oy + ints[I_LY]
    orr = ou + ints[I_LU]
    oc = orr + L - 1
    osc = oc + 3 * L
    oi = osc + ints[I_SCALARS]
    ypast, upast, rpast = out[oy:ou], out[ou:orr], out[orr:oc]
    ctrl = out[oc:osc].reshape((3, L))
    sc = out[osc:oi]
    info = out[oi:oi + n * n].reshape((n, n))
    k = int(sc[S_STEP])
    if not offset and k < ints[I_LEVEL_WINDOW]:
        # the operating-point check's running mean and squared deviations (Welford)
        mean, m2 = sc[S_LEVEL_MEAN], sc[S_LEVEL_M2]
        delta = y - mean
        mean += delta / (k + 1)
        m2 += delta * (y - mean)
        low = abs(y) if k == 0 else (abs(y) if abs(y) < sc[S_LEVEL_MIN] else sc[S_LEVEL_MIN])
        sc[S_LEVEL_MEAN], sc[S_LEVEL_M2], sc[S_LEVEL_MIN] = mean, m2, low
        if k + 1 >= ints[I_LEVEL_WINDOW] and low > reals[R_LEVEL_RATIO] * np.sqrt(m2 / (k + 1)):
            return LEVEL_MESSAGE
    # phi(t) = [-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1) (, 1)];  e = y - phi theta
    phi = np.empty(n)
    for i in range(na):
        phi[i] = -ypast[i]
    for i in range(nb):
        phi[na + i] = upast[nk - 1 + i]
    if offset:
        phi[n - 1] = 1.0
    x, P = vector_x_P(out[:nf], n)         # the estimator's, in the new state
    theta = x.copy()
    e = prediction_error(y, phi, theta)
    dead_zone = reals[R_DEAD_ZONE]
    if dead_zone == 0.0 or abs(e) > dead_zone:
        status = vector_step(v[:nf], w[:1], phi, reals[R_IL], Q, cfg, reals[R_R], ints[I_CHECK],
                             out[:nf])
        if status != PLAIN:
            return FILTER_STEP
        if not (np.all(np.isfinite(x)) and np.all(np.isfinite(P))):
            return NOT_FINITE               # (the Python path raises)
        theta = x.copy()
    if ints[I_BOUNDS]:                      # projection onto the box
        clipped = np.empty(n)
        if project_box(theta, lo, hi, clipped):
            vector_assign_x(out[:nf], clipped)
            theta = clipped
    u = 0.0
    designed = False
    if k % ints[I_REDESIGN] == 0:
        status, u = design_and_law(theta, na, nb, nk, Acl, Ao, reals[R_AM_SUM],
                                   ints[I_INTEGRAL] != 0, reals[R_TOL_DESIGN],
                                   reals[R_COPRIME], reals[R_REDUCE], reals[R_GROWTH], sc,
                                   S_SIZE, S_RUN, S_WARNED_REJECTED, np.empty((3, L)), ctrl,
                                   rpast, ypast, upast, y, r)
        if status != ACCEPTED:
            return DESIGN
        designed = True
    if sc[S_HAVE] == 0.0:                   # no controller yet: the loop is open
        if k + 1 >= ints[I_PATIENCE] and sc[S_WARNED_REJECTED] == 0.0:
            return PATIENCE_MESSAGE
    else:                                   # R (u - u_c) = T r - S y, the controller in use
        if not designed:
            u = control_law(ctrl, rpast, ypast, upast, y, r)
        if offset:
            applies, u_c = offset_control(theta, na, nb, ctrl[0])
            if applies:
                u += u_c
    u = u + dv
    if not (np.isfinite(u) and abs(u) <= lim):
        return BAD_CONTROL
    saturated = False
    if ints[I_LIMITS]:                      # u = min(max(u, lo), hi)
        u_lo, u_hi = reals[R_U_LO], reals[R_U_HI]
        saturated = not u_lo < u < u_hi
        u = u_lo if u_lo > u else u
        u = u_hi if u_hi < u else u
    remember(ypast, upast, rpast, info, sc, phi, y, u, r, 1.0 if saturated else 0.0, S_SAT,
             S_ERR2)
    trace = trace_of(P)
    if trace > reals[R_WINDUP] * sc[S_TRACE_REF]:
        if sc[S_WARNED_WINDUP] == 0.0:
            return WINDUP_MESSAGE
    else:
        sc[S_WARNED_WINDUP] = 0.0
    if ints[I_MONITOR] != 0 and (k + 1) % ints[I_MONITOR] == 0:
        return MONITOR_DUE
    sc[S_STEP] = k + 1
    outputs[0] = u
    if len(outputs) > 1:
        outputs[1] = e
        outputs[2:] = theta
    return DONE
