r"""The textbook recursion of `RLSBank` in NumPy, vectorized over channels.

The reference the tests hold the compiled kernels of
:mod:`rlsfilt.filters._kernels_bank` against (to 1e-12): each line is one
equation of the recursion, applied to every channel at once, with missing
samples handled by masks rather than branches. Not used by the library.
"""

import numpy as np

__all__ = []


def bank_batch_reference(x, P, Z, H, R, lam, Q, mode="exponential", params=None,
                         update_first=False):
    r"""Run every channel over a record.

    Parameters
    ----------
    x : (C, n), P : (C, n, n)
        Initial estimates and covariances (not modified).
    Z : (N, C), H : (N, C, n)
        Measurements and regressors; NaN in ``Z[k, c]`` or in ``H[k, c]``
        skips the update of channel ``c`` at step ``k``.
    R, lam : (C,)
        Noise variances and forgetting factors.
    Q : (C, n, n)
        Random walks.
    mode : {"exponential", "directional", "constant_trace"}
    params : (C, 2), optional
        Directional: ``eps`` in column 0; constant trace: ``trace``,
        ``ratio``.
    update_first : bool
        Update before predict in each step.

    Returns
    -------
    means : (N, C, n)
    covariances : (N, C, n, n)
    residuals : (N, C)
        A-priori residuals, NaN where skipped.
    x, P : the final state
    """
    N, C = Z.shape
    n = x.shape[1]
    x, P = x.copy(), P.copy()
    # the exponential mode forgets in the time update, the others in the measurement update
    il = 1.0 / lam if mode == "exponential" else np.ones(C)
    means = np.empty((N, C, n))
    covs = np.empty((N, C, n, n))
    ys = np.full((N, C), np.nan)
    for k in range(N):
        if not update_first:
            P = P * il[:, None, None] + Q                      # P^- = P / lam + Q
        ok = ~(np.isnan(Z[k]) | np.isnan(H[k]).any(axis=1))
        h = np.where(ok[:, None], H[k], 0.0)                   # (C, n)
        z = np.where(ok, Z[k], 0.0)
        g = np.einsum("cij,cj->ci", P, h)                      # g = P^- H^T
        s = np.einsum("ci,ci->c", h, g) + R                    # S = H P^- H^T + R
        y = z - np.einsum("ci,ci->c", h, x)                    # y = z - H x^-
        gg = g[:, :, None] * g[:, None, :]                     # g g^T
        if mode == "exponential":
            K = g / s[:, None]                                 # K = g / S
            P_new = P - gg / s[:, None, None]                  # P = P^- - g g^T / S
        elif mode == "directional":
            rho = (s - R) / R                                  # H P H^T / R
            with np.errstate(divide="ignore", invalid="ignore"):
                e = np.where(rho > params[:, 0], lam - (1.0 - lam) / rho, 1.0)
            d = R * (1.0 + e * rho)
            K = g / d[:, None]                                 # K = g / (R (1 + e rho))
            P_new = P - (e / d)[:, None, None] * gg            # P^-1 += e H^T H / R
        else:
            K = g / s[:, None]
            Pb = P - gg / s[:, None, None]                     # P_bar = P^- - g g^T / S
            trace, ratio = params[:, 0], params[:, 1]
            c2 = trace / (ratio + n)
            c1 = trace - n * c2
            tb = np.trace(Pb, axis1=1, axis2=2)
            P_new = (c1 / tb)[:, None, None] * Pb + c2[:, None, None] * np.eye(n)
        x = np.where(ok[:, None], x + K * y[:, None], x)       # x = x^- + K y
        P = np.where(ok[:, None, None], P_new, P)
        ys[k] = np.where(ok, y, np.nan)
        means[k] = x
        covs[k] = P
        if update_first:
            P = P * il[:, None, None] + Q
    return means, covs, ys, x, P
