r"""The residual tests of :func:`residual_analysis`: the lagged-input F test of one
channel (`input_lag_test`) and both tests vectorized over many channels.

`rlsfilt.models.fit_many` fits one model per channel and reports, for
each, the two tests of :func:`~rlsfilt.validation.residual_analysis`: the
Ljung-Box whiteness test and the F (Lagrange-multiplier) test that lagged
inputs do not explain the residuals. The statistics here are those of
``residual_analysis`` with the channel as a leading axis (the tests hold the
two equal channel by channel); every reduction runs along the last,
contiguous axis of an array with one row per channel, so the number of a
channel does not depend on which other channels are computed with it.

They live in the models layer because ``fit_many`` reports them and models
never import `rlsfilt.validation`; ``residual_analysis`` imports them from here.
"""

import numpy as np

from .._resources import check_memory
from .._scale import pow2_scale
from ..exceptions import InsufficientDataError

__all__ = []


def auto_max_lag(n):
    """The first lag ``max_lag="auto"`` tries for `n` residuals: ``min(25, n // 4)``, at
    least 1 (25 is MATLAB ``resid``'s default); `residual_analysis` and `validate` halve it
    while the record is too short for the tests at that lag."""
    return max(1, min(25, n // 4))


def fleet_max_lag(rows, n_params, n_inputs):
    """``max_lag="auto"`` of `fit_many`: `auto_max_lag` halved until the tests are sure to
    be defined on `rows` residuals: more than ``2 M + 2`` residuals (Ljung-Box) and, on the
    ``rows - 2 M`` rows where every lag exists, more rows than the independence test's
    regressors can number (``n_params + 1 + n_inputs (2 M + 1)``)."""
    M = auto_max_lag(rows)
    while M > 1 and (rows <= 2 * M + 2
                     or rows - 2 * M <= n_params + 1 + n_inputs * (2 * M + 1)):
        M //= 2
    return M


def ljung_box_many(E, max_lag, model_df=0):
    r"""Ljung-Box statistics of the residuals of each channel.

    Parameters
    ----------
    E : ndarray, shape (C, n)
        One-step residuals, one row per channel.
    max_lag : int
        Largest lag :math:`M`.
    model_df : int, default 0
        Degrees of freedom subtracted.

    Returns
    -------
    Q : ndarray, shape (C,)
        :math:`n (n + 2) \sum_{k=1}^{M} \hat\rho(k)^2 / (n - k)` (NaN for a
        channel with constant residuals).
    df : int
    pvalue : ndarray, shape (C,)
    """
    n = E.shape[1]
    Ec = E - E.mean(axis=1, keepdims=True)
    r0 = (Ec * Ec).sum(axis=1) / n
    ok = r0 > 0.0
    acf2 = np.zeros(E.shape[0])
    for k in range(1, max_lag + 1):
        with np.errstate(invalid="ignore", divide="ignore"):
            rho = (Ec[:, k:] * Ec[:, :n - k]).sum(axis=1) / (n * r0)
        acf2 = acf2 + rho ** 2 / (n - k)
    Q = np.where(ok, n * (n + 2) * acf2, np.nan)
    df = max_lag - model_df
    from scipy.stats import chi2  # lazy: keeps `import rlsfilt` light
    return Q, df, chi2.sf(Q, df)


def input_lag_test_many(E, Phi, U, t0, max_lag):
    r"""The F test that lagged inputs :math:`u(t - \tau)`, :math:`|\tau| \le M`,
    do not explain the residuals, for each channel.

    The test of ``residual_analysis`` (its ``input_lag_test``): the
    residuals on the rows where every lag exists are projected off the
    model's regressors and a constant, and the part the lagged inputs still
    explain is tested. Channels are batched through NumPy's stacked QR; a
    channel whose lagged inputs are rank-deficient in a way the others are
    not runs ``input_lag_test`` itself.

    Parameters
    ----------
    E : ndarray, shape (C, n)
        Residuals on the rows ``t = t0 .. t0 + n - 1``.
    Phi : ndarray, shape (C, n, p)
        The model's regressors on the same rows.
    U : ndarray, shape (C, N, nu)
        Inputs of each channel.
    t0 : int
        First row.
    max_lag : int
        Largest lag :math:`M`.

    Returns
    -------
    F : ndarray, shape (C,)
    q : ndarray of int, shape (C,)
        Numerator degrees of freedom (lagged-input directions tested).
    pvalue : ndarray, shape (C,)
    """
    from scipy.stats import f  # lazy: keeps `import rlsfilt` light
    C, n = E.shape
    N, nu = U.shape[1], U.shape[2]
    M = max_lag
    t = t0 + np.arange(n)
    rows = (t - M >= 0) & (t + M <= N - 1)
    tr = t[rows]
    m = len(tr)
    er = E[:, rows]                                                   # (C, m)
    X0 = _unit_columns(np.concatenate([np.ones((C, m, 1)), Phi[:, rows]], axis=2))
    L = np.stack([U[:, tr - tau, j] for j in range(nu) for tau in range(-M, M + 1)], axis=2)
    L = _unit_columns(L)                                              # (C, m, nu (2M + 1))
    Q0 = _orthonormal_bases(X0)
    F = np.full(C, np.nan)
    q = np.zeros(C, dtype=int)
    p = np.full(C, np.nan)
    if Q0 is None:                                  # collinear regressors somewhere
        return _each(E, Phi, U, t0, M, range(C), F, q, p)
    e0 = er - (Q0 @ (Q0.transpose(0, 2, 1) @ er[:, :, None]))[:, :, 0]
    L0 = L - Q0 @ (Q0.transpose(0, 2, 1) @ L)
    col = np.linalg.norm(L, axis=1)
    keep = np.linalg.norm(L0, axis=1) > 1e-8 * np.where(col > 0, col, 1.0)    # (C, cols)
    same = (keep == keep[0]).all(axis=1)
    odd = np.flatnonzero(~same)
    common = np.flatnonzero(same)
    if common.size:
        k = keep[0]
        qq = int(k.sum())
        ec = e0[common]
        rss0 = (ec * ec).sum(axis=1)
        if qq:
            # one QR of [L0, e0]: its R holds the R of L0 (whose diagonal decides the
            # rank, as orthonormal_basis does) and Q1^T e0, whose squares are the gain
            R = np.linalg.qr(np.concatenate([L0[common][:, :, k], ec[:, :, None]], axis=2),
                             mode="r")
            d = np.abs(np.diagonal(R, axis1=1, axis2=2))[:, :qq]
            tol = max(m, qq) * np.finfo(float).eps * np.maximum(d.max(axis=1),
                                                                np.finfo(float).tiny)
            if not (d > tol[:, None]).all():        # rank-deficient lagged inputs
                return _each(E, Phi, U, t0, M, range(C), F, q, p)
            gain = (R[:, :qq, qq] ** 2).sum(axis=1)
        else:
            gain = np.zeros(common.size)
        rss1 = rss0 - gain
        dfd = m - Q0.shape[2] - qq
        if qq == 0:
            F[common], q[common], p[common] = 0.0, 0, 1.0
        else:
            if dfd <= 0:
                raise ValueError(f"`max_lag` = {M} leaves too few rows ({m}) for the "
                                 f"independence test with {Q0.shape[2] + qq} regressors; use a "
                                 "smaller max_lag or more data")
            with np.errstate(divide="ignore", invalid="ignore"):
                Fc = (gain / qq) / (rss1 / dfd)
            Fc = np.where(rss1 <= 0.0, np.inf, Fc)
            F[common], q[common] = Fc, qq
            p[common] = np.where(rss1 <= 0.0, 0.0, f.sf(Fc, qq, dfd))
    return _each(E, Phi, U, t0, M, odd, F, q, p)


def _each(E, Phi, U, t0, M, channels, F, q, p):
    """``input_lag_test`` of single channels (the exact code of residual_analysis)."""
    for c in channels:
        F[c], q[c], p[c] = input_lag_test(E[c], Phi[c], U[c], t0, M)
    return F, q, p


def _unit_columns(X):
    """Columns of each matrix of the stack scaled to unit norm (zero columns kept)."""
    norms = np.linalg.norm(X, axis=1, keepdims=True)
    return X / np.where(norms > 0, norms, 1.0)


def _orthonormal_bases(X):
    """Orthonormal bases of the column spaces of a stack of matrices, or None
    when a matrix is rank-deficient (``orthonormal_basis`` would drop columns)."""
    if X.shape[2] == 0:
        return np.zeros(X.shape[:2] + (0,))
    Qf, R = np.linalg.qr(X)
    d = np.abs(np.diagonal(R, axis1=1, axis2=2))
    tol = max(X.shape[1:]) * np.finfo(float).eps * np.maximum(d.max(axis=1),
                                                               np.finfo(float).tiny)
    if not (d > tol[:, None]).all():
        return None
    return Qf

def input_lag_test(e, Phi, U, t0, M, block=8192):
    r"""F test that lagged inputs u(t - tau), |tau| <= M, do not explain `e`.

    The regression of `e` on ``X0 = [1, Phi]`` and on ``[X0, L]`` (``L`` the
    lagged inputs) needs only the inner products of the columns of
    ``A = [X0, L, e]``. They are taken from the triangular factor ``R`` of
    ``A = Q R``, accumulated over blocks of `block` rows (tall-skinny QR:
    the ``R`` so far stacked on the next block is factored again), so the
    memory is ``O(block * cols)`` instead of a dense ``(n, cols)`` matrix and
    its orthogonal factor (Golub & Van Loan 2013, sec. 5.2; Demmel et al.
    2012). Since ``A^T A = R^T R``, every projection below is computed on the
    columns of ``R`` exactly as it would be on the columns of ``A``.
    """
    from scipy.stats import f  # lazy: keeps `import rlsfilt` light
    n = len(e)
    N = len(U)
    nu = U.shape[1]
    lo, hi = max(0, M - t0), min(n, N - M - t0)   # rows where every lag u(t -+ M) exists
    n_rows = max(hi - lo, 0)
    p = Phi.shape[1]
    n_x0 = 1 + p
    n_l = nu * (2 * M + 1)
    K = n_x0 + n_l + 1
    block = max(block, K)
    # R stacked on a block, and LAPACK's copy of it
    check_memory(16 * (block + K) * K, f"the independence test with `max_lag` = {M} "
                 f"({K} columns: {nu} input(s) at {2 * M + 1} lags and {n_x0} regressors)")
    # powers of two per column keep the squares of any record in range (exact)
    phi_scale = pow2_scale(Phi[lo:hi], axis=0) if n_rows else np.ones(p)
    R = np.zeros((0, K))
    for b0 in range(lo, hi, block):
        b1 = min(b0 + block, hi)
        t = t0 + np.arange(b0, b1)
        A = np.empty((b1 - b0, K))
        A[:, 0] = 1.0
        A[:, 1:n_x0] = Phi[b0:b1] / phi_scale
        col = n_x0
        for j in range(nu):
            for tau in range(-M, M + 1):
                A[:, col] = U[t[0] - tau:t[-1] - tau + 1, j]
                col += 1
        A[:, -1] = e[b0:b1]
        R = np.linalg.qr(np.vstack([R, A]), mode="r")
    # unit columns, so that which directions count as "already a regressor" does not
    # depend on the units of u and y (the F statistic itself is scale-invariant)
    X0 = unit_norm(R[:, :n_x0])
    L = unit_norm(R[:, n_x0:n_x0 + n_l])
    er = R[:, -1]
    Q0 = orthonormal_basis(X0, n_rows)
    e0 = er - Q0 @ (Q0.T @ er)              # residual of the restricted regression
    L0 = L - Q0 @ (Q0.T @ L)                # lagged inputs orthogonal to the regressors
    col = np.linalg.norm(L, axis=0)
    keep = np.linalg.norm(L0, axis=0) > 1e-8 * np.where(col > 0, col, 1.0)
    Q1 = orthonormal_basis(L0[:, keep], n_rows) if keep.any() else np.zeros((len(er), 0))
    q = Q1.shape[1]
    rss0 = float(er @ er) if Q0.shape[1] == 0 else float(e0 @ e0)
    gain = float(np.sum((Q1.T @ e0) ** 2))
    rss1 = rss0 - gain
    dfd = n_rows - Q0.shape[1] - q
    if q == 0:  # every lagged input is already a regressor: nothing left to test
        return 0.0, 0, 1.0
    if dfd <= 0:
        raise InsufficientDataError(f"`max_lag` = {M} leaves too few rows ({n_rows}) for the "
                         f"independence test with {Q0.shape[1] + q} regressors; use a "
                         "smaller max_lag or more data")
    if rss1 <= 0.0:
        return np.inf, q, 0.0
    F = (gain / q) / (rss1 / dfd)
    return float(F), q, float(f.sf(F, q, dfd))


def unit_norm(X):
    """Columns of a small matrix scaled to unit 2-norm (zero columns left as they are)."""
    norms = np.linalg.norm(X, axis=0)
    return X / np.where(norms > 0, norms, 1.0)


def orthonormal_basis(X, n_rows=None):
    """Orthonormal basis of the column space of `X` (Householder QR), with rank detection.

    Columns whose diagonal entry of ``R`` is negligible against the largest
    are dropped (the tolerance counts `n_rows`, the rows of the tall matrix
    that `X` stands for, when given); the callers pass matrices whose
    dependent columns were already removed, so this only guards against
    exact collinearity.
    """
    if X.shape[1] == 0:
        return np.zeros((X.shape[0], 0))
    Qf, R = np.linalg.qr(X)
    d = np.abs(np.diag(R))
    rows = max(X.shape[0] if n_rows is None else n_rows, X.shape[1])
    tol = rows * np.finfo(float).eps * max(float(d.max()), np.finfo(float).tiny)
    return Qf[:, d > tol]
