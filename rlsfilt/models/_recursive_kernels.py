r"""Compiled (numba) recursions of the model family: RPEM, RPLR and recursive IV.

Every function is ``njit(cache=True)``; the module is imported on first use
(``import rlsfilt`` stays light). The readable NumPy reference of the same
arithmetic is in the tests (``tests/_reference_rpem.py``,
``tests/_reference_riv.py``; not installed), which hold the two equal to
round-off. The covariance updates are not written here: they
are the compiled updates of `RecursiveLeastSquares`
(:func:`rlsfilt.filters._kernels.time_update` and ``measurement_update``,
called through `forget` and `rls_update`), so every forgetting mode and the
gate behave as the filter's.

**One step of RPEM / RPLR** (Ljung 1999, ch. 11; Ljung & Soderstrom
1983), for the general model :math:`A y = \sum_i B_i/F_i\, u_i + C/D\, e`
written in pseudo-linear form :math:`\hat y(t) = \varphi(t)^T\theta` with

.. math::

    \varphi(t) = [-y(t-k)]_{k \le n_a},\ [u_i(t-n_{k,i}-k)]_{k < n_{b,i}},\
                 [\bar\varepsilon(t-k)]_{k \le n_c},\ [-v(t-k)]_{k \le n_d},\
                 [-w_i(t-k)]_{k \le n_{f,i}},

where :math:`w_i = B_i/F_i\, u_i`, :math:`v = A y - \sum_i w_i` and
:math:`\bar\varepsilon = D/C\, v` are computed with the latest estimate
(a-posteriori values). The gain uses :math:`\psi = \varphi` (RPLR: extended
least squares for ARMAX, the output-error PLR for OE) or the gradient
(RPEM)

.. math::

    \psi(t) = [-\tfrac{D}{C} y(t-k)],\ [\tfrac{D}{C F_i} u_i(t-n_{k,i}-k)],\
              [\tfrac{1}{C}\bar\varepsilon(t-k)],\ [-\tfrac{1}{C} v(t-k)],\
              [-\tfrac{D}{C F_i} w_i(t-k)],

filtered with the current estimate. Measured signals (``y``, ``u``) are
filtered with :math:`\theta(t-1)` at the start of the step; the model's own
signals with :math:`\theta(t)` after the update. Then the step of
`RecursiveLeastSquares` (its own kernels) with regressor :math:`\psi` (the
same forgetting modes, random walk ``Q`` and noise variance ``R``)::

    P <- P / lam + Q                    (time update; lam only when exponential)
    eps = y(t) - phi^T theta            a-priori prediction error
    g = P psi,  s = psi^T g + R
    K = g / s,  theta <- theta + K eps
    P <- P - g g^T / s                  (or the update of the forgetting mode)

followed by the projection of ``C``, ``D``, ``F_i`` into the stability
region (reflection of unstable zeros, `_stability.reflect`). The forgetting
factor of each step follows the start-up profile of `next_lam` (constant
when it starts at ``lam``).

**Recursive IV** (Ljung 1999, ch. 11; Soderstrom & Stoica 1983):
with instrument ``z`` and regressor ``phi``::

    P <- P / lam + Q
    g = P z,  h = P^T phi,  d = R + phi^T g
    K = g / d,  theta <- theta + K (y - phi^T theta)
    P <- P - K h^T                      (not symmetric)

``P`` is :math:`(\sum \lambda^{t-k} z \varphi^T)^{-1}`; a denominator ``d``
near zero relative to ``R + |phi| |g|`` means instruments almost
uncorrelated with the regressors (the conditioning check): that update is
skipped and reported.
"""

import numpy as np

from .._numba import njit  # numba.njit, uncached where no cache directory is writable
from ..filters._kernels import measurement_update, time_update
from ..filters.forgetting import CFG_LAM, CFG_MODE, EXPONENTIAL

__all__ = []

RPEM, RPLR = 0, 1

# rows of the signal buffer `buf` (lag k of signal s is buf[s, k]; k = 0 is time t)
SIG_Y, SIG_YF, SIG_E, SIG_EF, SIG_V, SIG_VF = 0, 1, 2, 3, 4, 5
# per input i, rows 6 + 6 i + ...
SIG_U, SIG_P, SIG_UF, SIG_W, SIG_S, SIG_WF = 0, 1, 2, 3, 4, 5
N_SIG_BASE, N_SIG_INPUT = 6, 6

RADIUS_MAX = 1.0 - 1e-8          # as _stability.RADIUS_MAX


# ----------------------------------------------------------------------
# stability of monic polynomials (the compiled _stability.is_stable / reflect)
# ----------------------------------------------------------------------
@njit(cache=True)
def is_stable(p):
    """Schur-Cohn step-down test of the monic ``p`` (all zeros in ``|z| < 1``)."""
    n = p.shape[0] - 1
    a = p.copy()
    b = np.empty(n + 1)
    for m in range(n, 0, -1):
        k = a[m]
        if not abs(k) < 1.0:
            return False
        den = 1.0 - k * k
        for j in range(m):
            b[j] = (a[j] - k * a[m - j]) / den
        for j in range(m):
            a[j] = b[j]
    return True


@njit(cache=True)
def reflect(p):
    """Monic ``p`` with its zeros outside the unit circle reflected to ``1/conj(z)``."""
    n = p.shape[0] - 1
    if n < 1 or is_stable(p):
        return p.copy()
    for j in range(n + 1):
        if not np.isfinite(p[j]):                      # a diverged estimate: leave it to the
            return p.copy()                            # caller's finiteness check
    comp = np.zeros((n, n), dtype=np.complex128)      # companion matrix
    for j in range(n):
        comp[0, j] = -p[j + 1]
    for i in range(1, n):
        comp[i, i - 1] = 1.0
    roots = np.linalg.eigvals(comp)
    for i in range(n):
        r = roots[i]
        if abs(r) > 1.0:
            r = 1.0 / np.conj(r)
        if abs(r) > RADIUS_MAX:
            r = r * (RADIUS_MAX / abs(r))
        roots[i] = r
    c = np.zeros(n + 1, dtype=np.complex128)           # prod (1 - r q^-1)
    c[0] = 1.0
    for i in range(n):
        for j in range(i + 1, 0, -1):
            c[j] = c[j] - roots[i] * c[j - 1]
    out = np.empty(n + 1)
    for j in range(n + 1):
        out[j] = c[j].real
    return out


@njit(cache=True)
def _stabilize_block(theta, start, n):
    """Reflect the monic polynomial ``[1, theta[start:start+n]]`` in place; True if changed."""
    if n == 0:
        return False
    p = np.empty(n + 1)
    p[0] = 1.0
    for k in range(n):
        p[k + 1] = theta[start + k]
    if is_stable(p):
        return False
    q = reflect(p)
    if not is_stable(q):                     # non-finite: nothing to project
        return False
    for k in range(n):
        theta[start + k] = q[k + 1]
    return True


@njit(cache=True)
def stabilize(theta, nc, nd, nf, off_c, off_d, off_f):
    """Reflect ``C``, ``D`` and every ``F_i`` of ``theta`` into the unit circle, in place.

    Returns the number of polynomials changed.
    """
    changed = 0
    if _stabilize_block(theta, off_c, nc):
        changed += 1
    if _stabilize_block(theta, off_d, nd):
        changed += 1
    for i in range(nf.shape[0]):
        if _stabilize_block(theta, off_f[i], nf[i]):
            changed += 1
    return changed


# ----------------------------------------------------------------------
# the covariance update: RecursiveLeastSquares' own, with a given residual
# ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def forget(P, il, Q):
    """``P <- P il + Q`` in place (``il = 1/lam`` when exponential, else 1; ``Q`` (0, 0)
    when absent): `filters._kernels.time_update` without constraints."""
    none = P[:0, :0]                         # no projector, so no work space either
    time_update(P, il, Q, none, none, P)


@njit(cache=True, inline="always")
def rls_update(theta, P, psi, eps, r, cfg, g, K, T, dx, zy):
    """One measurement update of any forgetting mode, with the residual `eps` given.

    `filters._kernels.measurement_update` (``RecursiveLeastSquares``' update:
    every forgetting mode of `cfg`, ``forgetting.kernel_config`` without
    constraints, and its gate) for one output with the regressor ``psi``.
    That update computes its residual as ``z - psi . x``: run on the zero
    state ``x = 0`` (``dx``, (n, 1)) with ``z = eps`` it sees exactly `eps`,
    and its new state is the step ``K eps``, added to ``theta`` (n,) here.
    ``P`` is updated in place; ``g = P psi`` and ``K`` (n,) are written;
    ``T`` is (n, n) work and ``zy`` (2,) holds ``z`` and the update's residual.
    The windup cap's decision is not used: the recursions forget in every
    step.

    Returns
    -------
    s : float
        ``psi^T P psi + r``.
    lam_t : float
        Forgetting factor the step applied.
    gated : bool
        Whether the gate rejected the sample (then nothing changed).
    """
    n = theta.shape[0]
    for i in range(n):
        dx[i, 0] = 0.0
    zy[0] = eps
    # T as an 'A' view, as `forget` passes it: `project` (never run here: no constraints,
    # but typed) then compiles once, not once per layout
    s, lam_t, gated, _ = measurement_update(dx, P, psi, zy[:1], False, r, cfg, P[:0, :0], g,
                                            zy[1:], K, T[:, :], 1.0, dx, P)
    for i in range(n):                       # theta = theta + K eps
        theta[i] = theta[i] + dx[i, 0]
    return s, lam_t, gated


# ----------------------------------------------------------------------
# the signal buffers
# ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def shift(buf):
    """Move every signal (row) of `buf` one lag back: ``buf[:, k] <- buf[:, k - 1]``,
    and lag 0 to zero (the step then writes it)."""
    n_sig, M = buf.shape
    for sg in range(n_sig):
        for k in range(M - 1, 0, -1):
            buf[sg, k] = buf[sg, k - 1]
        buf[sg, 0] = 0.0


@njit(cache=True, inline="always")
def through_ar(v, alpha, buf, row, na):
    """Lag 0 of ``1/A`` applied to a signal whose new sample is `v`:
    ``v - sum_{k=1..na} alpha[k-1] buf[row, k]`` (``buf[row]`` the past of the
    output; the terms subtracted one at a time, in order of lag)."""
    for k in range(1, na + 1):
        v -= alpha[k - 1] * buf[row, k]
    return v


@njit(cache=True, inline="always")
def take_lags(a, b, j, buf, ra, rb, first, count, sign):
    """One block of two rows (regressor and gradient, or regressor and instrument):
    ``a[j + k] = sign buf[ra, first + k]``, ``b[j + k] = sign buf[rb, first + k]``
    for ``k < count``, `sign` 1 or -1. Returns ``j + count``, where the next block
    starts."""
    for k in range(count):
        a[j + k] = sign * buf[ra, first + k]
        b[j + k] = sign * buf[rb, first + k]
    return j + count


# ----------------------------------------------------------------------
# RPEM / RPLR
# ----------------------------------------------------------------------
@njit(cache=True, inline="always")
def _lagged_sum(theta, start, n, buf, sig, first_lag):
    """``sum_{k<n} theta[start + k] * buf[sig, first_lag + k]`` (inlined: called with
    constant rows and lags, a separate function was compiled once per constant, nine
    times for `rpem_step`)."""
    acc = 0.0
    for k in range(n):
        acc += theta[start + k] * buf[sig, first_lag + k]
    return acc


@njit(cache=True)
def rpem_step(theta, P, buf, y, u, na, nb, nc, nd, nf, nk, off_b, off_c, off_d, off_f,
              method, cfg, lam, Q, r, project, phi, psi, g, K, T, dx, zy, adapt=True):
    """One step of RPEM (``method`` 0) or RPLR (1), in place on ``theta``, ``P``, ``buf``.

    ``adapt=False`` (the estimator frozen): no covariance or estimate update,
    ``theta`` and ``P`` untouched (``s`` NaN, ``lam_t`` 1, no gate, no
    projection); the signals move on through the filters of ``theta``.

    ``lam`` is this step's forgetting factor (see `next_lam`); `cfg` the
    filters' configuration (``forgetting.kernel_config``: the forgetting
    mode, its parameters and the gate, ``inf`` without one), into which the
    step writes ``lam``; ``Q`` the random walk ((0, 0) without one).

    ``buf`` (6 + 6 nu, M) holds the lags ``0 .. M-1`` of the signals (rows
    ``SIG_*``); ``u`` (nu,) is the input sample. ``phi``, ``psi``, ``g``,
    ``K`` (n,), ``T`` (n, n), ``dx`` (n, 1) and ``zy`` (2,) are work arrays
    (``phi`` and ``psi`` hold the step's regressor and gradient on return).

    Returns
    -------
    yhat : float
        One-step prediction :math:`\\varphi^T\\theta(t-1)`.
    eps : float
        A-priori prediction error ``y - yhat``.
    s : float
        ``psi^T P psi + r``.
    lam_t : float
        Forgetting factor applied.
    gated : bool
    reflected : int
        Number of polynomials projected into the stability region.
    """
    n = theta.shape[0]
    nu = nb.shape[0]
    shift(buf)
    buf[SIG_Y, 0] = y
    for i in range(nu):
        buf[N_SIG_BASE + N_SIG_INPUT * i + SIG_U, 0] = u[i]
    rpem = method == RPEM
    # measured signals through the filters of theta(t-1): D/C y, D/(C F_i) u_i
    if rpem:
        buf[SIG_YF, 0] = (y + _lagged_sum(theta, off_d, nd, buf, SIG_Y, 1)
                          - _lagged_sum(theta, off_c, nc, buf, SIG_YF, 1))
        for i in range(nu):
            base = N_SIG_BASE + N_SIG_INPUT * i
            p = u[i] - _lagged_sum(theta, off_f[i], nf[i], buf, base + SIG_P, 1)
            buf[base + SIG_P, 0] = p
            buf[base + SIG_UF, 0] = (p + _lagged_sum(theta, off_d, nd, buf, base + SIG_P, 1)
                                     - _lagged_sum(theta, off_c, nc, buf, base + SIG_UF, 1))
    # regressor phi and gradient psi, block by block
    j = take_lags(phi, psi, 0, buf, SIG_Y, SIG_YF, 1, na, -1.0)
    for i in range(nu):
        base = N_SIG_BASE + N_SIG_INPUT * i
        j = take_lags(phi, psi, j, buf, base + SIG_U, base + SIG_UF, nk[i], nb[i], 1.0)
    j = take_lags(phi, psi, j, buf, SIG_E, SIG_EF, 1, nc, 1.0)
    j = take_lags(phi, psi, j, buf, SIG_V, SIG_VF, 1, nd, -1.0)
    for i in range(nu):
        base = N_SIG_BASE + N_SIG_INPUT * i
        j = take_lags(phi, psi, j, buf, base + SIG_W, base + SIG_WF, 1, nf[i], -1.0)
    if not rpem:
        for i in range(n):
            psi[i] = phi[i]
    # prediction and prediction error with theta(t-1)
    yhat = 0.0
    for i in range(n):
        yhat += phi[i] * theta[i]
    eps = y - yhat
    # covariance and estimate update (RecursiveLeastSquares with regressor psi)
    if adapt:
        cfg[CFG_LAM] = lam
        forget(P, 1.0 / lam if int(cfg[CFG_MODE]) == EXPONENTIAL else 1.0, Q)
        s, lam_t, gated = rls_update(theta, P, psi, eps, r, cfg, g, K, T, dx, zy)
        reflected = stabilize(theta, nc, nd, nf, off_c, off_d, off_f) if project else 0
    else:                                # frozen: theta(t) = theta(t-1), P unchanged
        s, lam_t, gated, reflected = np.nan, 1.0, False, 0
    # the model's own signals with theta(t): w_i = B_i/F_i u_i, v = A y - sum w_i, e = D/C v
    wsum = 0.0
    for i in range(nu):
        base = N_SIG_BASE + N_SIG_INPUT * i
        w = (_lagged_sum(theta, off_b[i], nb[i], buf, base + SIG_U, nk[i])
             - _lagged_sum(theta, off_f[i], nf[i], buf, base + SIG_W, 1))
        buf[base + SIG_W, 0] = w
        wsum += w
    v = y + _lagged_sum(theta, 0, na, buf, SIG_Y, 1) - wsum
    buf[SIG_V, 0] = v
    e = (v + _lagged_sum(theta, off_d, nd, buf, SIG_V, 1)
         - _lagged_sum(theta, off_c, nc, buf, SIG_E, 1))
    buf[SIG_E, 0] = e
    if rpem:                             # 1/C e, 1/C v, D/(C F_i) w_i with theta(t)
        buf[SIG_EF, 0] = e - _lagged_sum(theta, off_c, nc, buf, SIG_EF, 1)
        buf[SIG_VF, 0] = v - _lagged_sum(theta, off_c, nc, buf, SIG_VF, 1)
        for i in range(nu):
            base = N_SIG_BASE + N_SIG_INPUT * i
            sv = buf[base + SIG_W, 0] - _lagged_sum(theta, off_f[i], nf[i], buf, base + SIG_S, 1)
            buf[base + SIG_S, 0] = sv
            buf[base + SIG_WF, 0] = (sv + _lagged_sum(theta, off_d, nd, buf, base + SIG_S, 1)
                                     - _lagged_sum(theta, off_c, nc, buf, base + SIG_WF, 1))
    return yhat, eps, s, lam_t, gated, reflected


@njit(cache=True)
def next_lam(lam_now, lam, rate):
    """Forgetting profile ``lam(t+1) = rate lam(t) + (1 - rate) lam``, written so
    that ``lam(t) = lam`` stays exactly ``lam``."""
    return lam - (lam - lam_now) * rate


@njit(cache=True)
def rpem_batch(theta, P, buf, y, U, na, nb, nc, nd, nf, nk, off_b, off_c, off_d, off_f,
               method, cfg, lam, lam_now, lam_rate, Q, r, project, theta_hist, yhat, eps,
               gated):
    """`rpem_step` over a record, in place on ``theta``, ``P``, ``buf``.

    The forgetting factor of each step follows the profile of `next_lam`
    from ``lam_now`` towards ``lam``. Writes ``theta_hist`` (N, n) (the
    estimate after each sample), ``yhat``, ``eps`` (N,) and ``gated`` (N,).
    Returns ``(lam_now, lam_t, n_reflections)``: the factor of the next step,
    the factor the last step applied, and the projections made.
    """
    n = theta.shape[0]
    phi = np.empty(n)
    psi = np.empty(n)
    g = np.empty(n)
    K = np.empty(n)
    T = np.empty((n, n))
    dx = np.empty((n, 1))
    zy = np.empty(2)
    lam_t = lam_now
    n_refl = 0
    for t in range(y.shape[0]):
        yh, ep, s, lam_t, gt, refl = rpem_step(
            theta, P, buf, y[t], U[t], na, nb, nc, nd, nf, nk, off_b, off_c, off_d, off_f,
            method, cfg, lam_now, Q, r, project, phi, psi, g, K, T, dx, zy)
        lam_now = next_lam(lam_now, lam, lam_rate)
        yhat[t] = yh
        eps[t] = ep
        gated[t] = gt
        n_refl += refl
        for i in range(n):
            theta_hist[t, i] = theta[i]
    return lam_now, lam_t, n_refl


# layout of the packed arguments of `rpem_stream` (one call per sample from Python: a
# numba call costs about 0.1 us per array argument, so the structure and the scalars
# travel in two arrays instead of some thirty arguments)
# spec (int64): the orders and flags, then the per-input blocks of length nu each
SPEC_NA, SPEC_NC, SPEC_ND, SPEC_OFF_C, SPEC_OFF_D, SPEC_METHOD = range(6)
SPEC_PROJECT, SPEC_NU, SPEC_BLOCKS = range(6, 9)
# fpar (float64): inputs lam, lam_rate, r; state lam_now; outputs of the last step; the
# work of `rls_update` (its measurement and residual)
# then F_FROZEN: 1.0 while the estimator is frozen (no update, the profile held)
F_LAM, F_LAM_RATE, F_R, F_LAM_NOW, F_LAM_T, F_GATED, F_REFL, F_Z, F_Y, F_FROZEN, F_SIZE = range(11)


@njit(cache=True)
def rpem_stream(theta, P, buf, y, u, spec, fpar, cfg, Q, W, T):
    """One streaming step: `rpem_step` and `next_lam` exactly as `rpem_batch` runs them.

    The arguments are packed (see ``SPEC_*`` and ``F_*``): `spec` holds the
    orders, offsets and flags, `fpar` the scalars, with ``fpar[F_LAM_NOW]``
    (the factor of this step) advanced in place, and the step's ``lam_t``,
    ``gated`` and number of reflections written to ``F_LAM_T``, ``F_GATED``,
    ``F_REFL``. `cfg` and `Q` as in `rpem_step`. ``W`` (5, n) holds the work
    rows ``phi``, ``psi``, ``g``, ``K`` and ``dx``; ``T`` (n, n). Returns
    ``(yhat, eps)``.
    """
    nu = spec[SPEC_NU]
    b = SPEC_BLOCKS
    nb = spec[b:b + nu]
    nf = spec[b + nu:b + 2 * nu]
    nk = spec[b + 2 * nu:b + 3 * nu]
    off_b = spec[b + 3 * nu:b + 4 * nu]
    off_f = spec[b + 4 * nu:b + 5 * nu]
    lam_now = fpar[F_LAM_NOW]
    yh, ep, s, lam_t, gt, refl = rpem_step(
        theta, P, buf, y, u, spec[SPEC_NA], nb, spec[SPEC_NC], spec[SPEC_ND], nf, nk, off_b,
        spec[SPEC_OFF_C], spec[SPEC_OFF_D], off_f, spec[SPEC_METHOD], cfg, lam_now, Q, fpar[F_R],
        spec[SPEC_PROJECT] != 0, W[0], W[1], W[2], W[3], T, W[4].reshape((W.shape[1], 1)),
        fpar[F_Z:F_Z + 2], fpar[F_FROZEN] == 0.0)
    if fpar[F_FROZEN] != 0.0:            # frozen: the forgetting profile waits
        fpar[F_GATED] = 0.0
        fpar[F_REFL] = 0.0
        return yh, ep
    fpar[F_LAM_NOW] = next_lam(lam_now, fpar[F_LAM], fpar[F_LAM_RATE])
    fpar[F_LAM_T] = lam_t
    fpar[F_GATED] = 1.0 if gt else 0.0
    fpar[F_REFL] = refl
    return yh, ep


# ----------------------------------------------------------------------
# recursive instrumental variables
# ----------------------------------------------------------------------
@njit(cache=True)
def riv_update(theta, P, phi, z, y, r, tol, g, h, K, eps):
    """One RIV measurement update in place on ``theta`` (n, m) and ``P`` (n, n).

    Writes ``g = P z``, ``h = P^T phi``, ``K = g / d`` and the a-priori
    residuals ``eps`` (m,), with ``d = r + phi^T P z``. When ``|d| <= tol
    (r + |phi| |P z|)`` (instruments nearly uncorrelated with the regressor
    in the metric of ``P``) the update is skipped: ``K = 0``, ``theta`` and
    ``P`` unchanged. Returns whether it was skipped.
    """
    n, m = theta.shape
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += P[i, j] * z[j]
        g[i] = acc
    for j in range(n):
        acc = 0.0
        for i in range(n):
            acc += phi[i] * P[i, j]
        h[j] = acc
    acc = 0.0
    nphi = 0.0
    ng = 0.0
    for i in range(n):
        acc += phi[i] * g[i]
        nphi += phi[i] * phi[i]
        ng += g[i] * g[i]
    d = r + acc
    for c in range(m):
        pred = 0.0
        for i in range(n):
            pred += phi[i] * theta[i, c]
        eps[c] = y[c] - pred
    if not abs(d) > tol * (r + np.sqrt(nphi * ng)):
        for i in range(n):
            K[i] = 0.0
        return True
    for i in range(n):
        K[i] = g[i] / d
    for i in range(n):
        ki = K[i]
        for c in range(m):
            theta[i, c] = theta[i, c] + ki * eps[c]
    for i in range(n):
        ki = K[i]
        for j in range(n):
            P[i, j] = P[i, j] - ki * h[j]
    return False


@njit(cache=True)
def riv_rows(theta, P, Phi, Z, Y, il, Q, r, tol, theta_hist, eps_hist):
    """Recursive IV over given regressor rows ``Phi``, instruments ``Z`` and targets ``Y``.

    Writes ``theta_hist`` (N, n, m) and ``eps_hist`` (N, m). Returns the
    first row whose update `riv_update` skipped (conditioning check), or -1.
    """
    n, m = theta.shape
    g = np.empty(n)
    h = np.empty(n)
    K = np.empty(n)
    eps = np.empty(m)
    bad = -1
    for t in range(Phi.shape[0]):
        forget(P, il, Q)
        skipped = riv_update(theta, P, Phi[t], Z[t], Y[t], r, tol, g, h, K, eps)
        if bad < 0 and skipped:
            bad = t
        for i in range(n):
            for c in range(m):
                theta_hist[t, i, c] = theta[i, c]
        for c in range(m):
            eps_hist[t, c] = eps[c]
    return bad


# rows of the RIV signal buffer: y, prefiltered y, auxiliary output x, prefiltered x,
# then per input i: u_i (row 4 + 2 i) and prefiltered u_i (row 5 + 2 i)
RIV_Y, RIV_YF, RIV_X, RIV_XF = 0, 1, 2, 3


@njit(cache=True)
def riv_signals(buf, y, u, na, nb, nk, alpha, beta, prefilter, phi, z):
    r"""Take one sample into the RIV signal buffer; build the regressor and instrument rows.

    Shifts ``buf`` (4 + 2 nu, M) one lag, stores ``y``, ``u``, the
    prefiltered signals (through :math:`1/\hat A`, ``alpha``, when
    `prefilter`) and the auxiliary output :math:`\hat A x = \sum_i \hat
    B_i u_i` (``beta`` the ``b`` blocks), then writes ``phi`` = ``[-yf(t-k),
    uf_i(t - nk_i - k)]`` and ``z`` = ``[-xf(t-k), uf_i(t - nk_i - k)]``
    (signals before the record are zero). Returns the (prefiltered) target
    ``yf(t)``.
    """
    nu = nb.shape[0]
    n_pre = na if prefilter else 0           # the order of the prefilter 1/A
    shift(buf)
    buf[RIV_Y, 0] = y
    yf = through_ar(y, alpha, buf, RIV_YF, n_pre)
    buf[RIV_YF, 0] = yf
    x = 0.0
    off = 0
    for i in range(nu):
        ru = 4 + 2 * i
        buf[ru, 0] = u[i]
        buf[ru + 1, 0] = through_ar(u[i], alpha, buf, ru + 1, n_pre)
        for k in range(nb[i]):
            x += beta[off + k] * buf[ru, nk[i] + k]
        off += nb[i]
    x = through_ar(x, alpha, buf, RIV_X, na)
    buf[RIV_X, 0] = x
    buf[RIV_XF, 0] = through_ar(x, alpha, buf, RIV_XF, n_pre)
    j = take_lags(phi, z, 0, buf, RIV_YF, RIV_XF, 1, na, -1.0)
    for i in range(nu):
        ru = 4 + 2 * i
        j = take_lags(phi, z, j, buf, ru + 1, ru + 1, nk[i], nb[i], 1.0)
    return yf


@njit(cache=True)
def riv_exact_start(Z0, Phi0, Y0, theta, P):
    """``P = (Z0^T Phi0)^-1``, ``theta = P Z0^T Y0`` in place; False when singular."""
    k0, n = Phi0.shape
    M = np.zeros((n, n))
    rhs = np.zeros(n)
    for q in range(k0):
        for a in range(n):
            za = Z0[q, a]
            rhs[a] += za * Y0[q]
            for b in range(n):
                M[a, b] += za * Phi0[q, b]
    if not np.linalg.cond(M) < 1e15:       # also NaN: no exact start possible
        return False
    Pm = np.linalg.inv(M)
    for a in range(n):
        acc = 0.0
        for b in range(n):
            P[a, b] = Pm[a, b]
            acc += Pm[a, b] * rhs[b]
        theta[a, 0] = acc
    return True


@njit(cache=True)
def riv_refresh(theta, na, alpha, beta):
    """The auxiliary model takes the current estimate (``A`` reflected into the unit circle)."""
    n = theta.shape[0]
    a = np.empty(na + 1)
    a[0] = 1.0
    for k in range(na):
        a[k + 1] = theta[k, 0]
    a = reflect(a)
    for k in range(na):
        alpha[k] = a[k + 1]
    for k in range(n - na):
        beta[k] = theta[na + k, 0]


@njit(cache=True)
def riv_model_step(theta, P, buf, y, u, z_given, use_given, row, na, nb, nk, k0, alpha, beta,
                   refresh, prefilter, il, Q, r, tol, Phi0, Z0, Y0, phi, z, g, h, K, eps):
    """One sample of recursive IV with auxiliary-model instruments (batch and streaming).

    `row` is the index of this sample's regressor row (negative before the
    first complete row: the signals are only recorded). Rows ``0 .. k0-1``
    are stored in ``Phi0``, ``Z0``, ``Y0`` and make the exact start at row
    ``k0 - 1``; later rows update ``theta`` and ``P``. Every `refresh` rows
    the auxiliary model takes the estimate. With `use_given` the instrument
    row is ``z_given`` instead (instruments supplied sample by sample).
    ``phi``, ``z`` hold the rows on return.

    Returns
    -------
    status : int
        -1 before the first row, 0 a start row, 1 an update, 2 a skipped
        update (conditioning check), 3 a singular exact start.
    target : float
        The (prefiltered) output ``yf(t)``.
    """
    target = riv_signals(buf, y, u, na, nb, nk, alpha, beta, prefilter, phi, z)
    n = phi.shape[0]
    if use_given:
        for j in range(n):
            z[j] = z_given[j]
    if row < 0:
        return -1, target
    status = 1
    if row < k0:
        for j in range(n):
            Phi0[row, j] = phi[j]
            Z0[row, j] = z[j]
        Y0[row] = target
        eps[0] = np.nan
        status = 0
        if row == k0 - 1 and not riv_exact_start(Z0, Phi0, Y0, theta, P):
            return 3, target
    else:
        forget(P, il, Q)
        yv = np.empty(1)
        yv[0] = target
        if riv_update(theta, P, phi, z, yv, r, tol, g, h, K, eps):
            status = 2
    if refresh > 0 and (row + 1) % refresh == 0 and row + 1 >= k0:
        riv_refresh(theta, na, alpha, beta)
    return status, target


@njit(cache=True)
def riv_model(theta, P, buf, U, y, t0, na, nb, nk, k0, alpha, beta, refresh, prefilter,
              il, Q, r, tol, theta_hist, eps_hist, Phi_out, Z_out, Y_out):
    r"""Recursive IV with instruments from an auxiliary model refreshed every `refresh` rows.

    The auxiliary model :math:`\hat A x = \sum_i \hat B_i u_i` (``alpha``
    = its ``a`` coefficients, ``beta`` its ``b`` blocks) simulates the
    noise-free output ``x``; the instrument row is the ARX regressor with
    ``-y`` replaced by ``-x``. With `prefilter`, ``y``, ``u`` and ``x`` pass
    through :math:`1/\hat A` first (Young's simplified refined IV). Every
    `refresh` rows the auxiliary model takes the current estimate (its
    ``A`` reflected into the unit circle). The first `k0` rows (``k0 > 0``)
    make an exact start, :math:`P = (Z_0^T\Phi_0)^{-1}`,
    :math:`\theta = P Z_0^T y_0`; with ``k0 = 0`` the given ``theta``,
    ``P`` are the prior. Each sample is one `riv_model_step` (the step the
    streaming estimator runs), on the signal buffer ``buf``.

    Writes ``theta_hist`` (rows, n, 1) (NaN before the start), ``eps_hist``
    (rows, 1), and the rows actually used, ``Phi_out``, ``Z_out`` (rows, n)
    and the (prefiltered) targets ``Y_out`` (rows,). Returns ``(bad,
    singular)``: the first row whose update the conditioning check skipped
    (or -1), and whether the exact start was singular.
    """
    N = y.shape[0]
    n = theta.shape[0]
    phi = np.empty(n)
    z = np.empty(n)
    g = np.empty(n)
    h = np.empty(n)
    K = np.empty(n)
    eps = np.empty(1)
    Phi0 = np.empty((max(k0, 1), n))
    Z0 = np.empty((max(k0, 1), n))
    Y0 = np.empty(max(k0, 1))
    bad = -1
    for t in range(N):
        row = t - t0
        status, target = riv_model_step(theta, P, buf, y[t], U[t], z, False, row, na, nb, nk,
                                        k0, alpha, beta, refresh, prefilter, il, Q, r,
                                        tol, Phi0, Z0, Y0, phi, z, g, h, K, eps)
        if status < 0:
            continue
        if status == 3:
            return bad, True
        for j in range(n):
            Phi_out[row, j] = phi[j]
            Z_out[row, j] = z[j]
        Y_out[row] = target
        if status == 2 and bad < 0:
            bad = row
        eps_hist[row, 0] = eps[0]
        if status == 0 and row < k0 - 1:
            for i in range(n):
                theta_hist[row, i, 0] = np.nan
        else:
            for i in range(n):
                theta_hist[row, i, 0] = theta[i, 0]
    return bad, False


# packed arguments of `riv_stream` (as for `rpem_stream`)
RSPEC_NA, RSPEC_K0, RSPEC_REFRESH, RSPEC_PREFILTER, RSPEC_GIVEN, RSPEC_NU = range(6)
RSPEC_BLOCKS = 6
RF_IL, RF_R, RF_TOL, RF_FROZEN, RF_SIZE = range(5)   # RF_FROZEN: 1.0 while frozen
# rows of the work array W (7, n): phi, z, g, h, K, theta before the step, eps (W[6, 0])
W_PHI, W_Z, W_G, W_H, W_K, W_THETA, W_EPS = range(7)


@njit(cache=True)
def riv_stream(theta, P, buf, y, u, z_given, row, spec, fpar, alpha, beta, Q, S0, Y0, W):
    r"""One streaming sample: `riv_model_step` (the batch arithmetic) on packed arguments.

    `spec` holds ``na, k0, refresh, prefilter, use_given, nu`` and the
    ``nb``, ``nk`` blocks; `fpar` ``1/lam, R, tol``; `Q` (0, 0) without a
    random walk; ``S0`` (2, m, n)
    the start rows ``Phi0``, ``Z0``; ``W`` (7, n) the work rows (``W[6,
    0]`` the residual). Returns ``(status, yhat)`` with ``yhat`` the
    prediction :math:`\varphi^T\hat\theta(t-1)` of the (prefiltered) output
    (NaN while the exact start collects its rows).
    """
    n = theta.shape[0]
    nu = spec[RSPEC_NU]
    nb = spec[RSPEC_BLOCKS:RSPEC_BLOCKS + nu]
    nk = spec[RSPEC_BLOCKS + nu:RSPEC_BLOCKS + 2 * nu]
    prev = W[W_THETA]
    for i in range(n):
        prev[i] = theta[i, 0]
    if fpar[RF_FROZEN] != 0.0:
        # frozen (status 4): the signals and rows move on through the held auxiliary
        # model; no start row, update or refresh; theta and P untouched
        riv_signals(buf, y, u, spec[RSPEC_NA], nb, nk, alpha, beta,
                    spec[RSPEC_PREFILTER] != 0, W[W_PHI], W[W_Z])
        if spec[RSPEC_GIVEN] != 0:
            for j in range(n):
                W[W_Z, j] = z_given[j]
        if 0 <= row < spec[RSPEC_K0]:
            return 4, np.nan                 # the exact start is not made yet
        yhat = 0.0
        for i in range(n):
            yhat += W[W_PHI, i] * prev[i]
        return 4, yhat
    status, _ = riv_model_step(
        theta, P, buf, y, u, z_given, spec[RSPEC_GIVEN] != 0, row, spec[RSPEC_NA], nb, nk,
        spec[RSPEC_K0], alpha, beta, spec[RSPEC_REFRESH], spec[RSPEC_PREFILTER] != 0,
        fpar[RF_IL], Q, fpar[RF_R], fpar[RF_TOL], S0[0], S0[1], Y0,
        W[W_PHI], W[W_Z], W[W_G], W[W_H], W[W_K], W[W_EPS, :1])
    yhat = np.nan
    if status == 1 or status == 2 or status == -1:
        yhat = 0.0
        for i in range(n):
            yhat += W[W_PHI, i] * prev[i]
    return status, yhat
