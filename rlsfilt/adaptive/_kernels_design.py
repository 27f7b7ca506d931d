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
def _coprime_at_least(a, b, tau):
    """``(coprimeness(a, b) >= tau, the coprimeness or NaN when not needed)``.

    ``_polynomials.coprimeness`` for trimmed `a`, `b` (`b` nonzero), computed
    (SVD) only when `_above` cannot certify the decision: the decision is the
    NumPy path's.
    """
    if len(a) + len(b) == 2:
        return True, np.inf
    M = _sylvester(a / np.sqrt(np.dot(a, a)), b / np.sqrt(np.dot(b, b)))
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
