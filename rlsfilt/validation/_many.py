r"""The residual tests of :func:`residual_analysis`, vectorized over many channels.

`rlsfilt.models.fit_many` fits one model per channel and reports, for
each, the two tests of :func:`~rlsfilt.validation.residual_analysis`: the
Ljung-Box whiteness test and the F (Lagrange-multiplier) test that lagged
inputs do not explain the residuals. The statistics here are those of
``residual_analysis`` with the channel as a leading axis (the tests hold the
two equal channel by channel); every reduction runs along the last,
contiguous axis of an array with one row per channel, so the number of a
channel does not depend on which other channels are computed with it.
"""

import numpy as np

from .residuals import _input_lag_test

__all__ = []


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

    The test of ``residual_analysis`` (its ``_input_lag_test``): the
    residuals on the rows where every lag exists are projected off the
    model's regressors and a constant, and the part the lagged inputs still
    explain is tested. Channels are batched through NumPy's stacked QR; a
    channel whose lagged inputs are rank-deficient in a way the others are
    not runs ``_input_lag_test`` itself.

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
            # rank, as _orthonormal_basis does) and Q1^T e0, whose squares are the gain
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
    """``_input_lag_test`` of single channels (the exact code of residual_analysis)."""
    for c in channels:
        F[c], q[c], p[c] = _input_lag_test(E[c], Phi[c], U[c], t0, M)
    return F, q, p


def _unit_columns(X):
    """Columns of each matrix of the stack scaled to unit norm (zero columns kept)."""
    norms = np.linalg.norm(X, axis=1, keepdims=True)
    return X / np.where(norms > 0, norms, 1.0)


def _orthonormal_bases(X):
    """Orthonormal bases of the column spaces of a stack of matrices, or None
    when a matrix is rank-deficient (``_orthonormal_basis`` would drop columns)."""
    if X.shape[2] == 0:
        return np.zeros(X.shape[:2] + (0,))
    Qf, R = np.linalg.qr(X)
    d = np.abs(np.diagonal(R, axis1=1, axis2=2))
    tol = max(X.shape[1:]) * np.finfo(float).eps * np.maximum(d.max(axis=1),
                                                               np.finfo(float).tiny)
    if not (d > tol[:, None]).all():
        return None
    return Qf
