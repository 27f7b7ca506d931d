r"""The fixed-interval Rauch-Tung-Striebel smoother of a parameter trajectory.

A recursive least-squares run is the Kalman filter of the parameters
:math:`x_t` with the transition :math:`F = I`: the estimate after sample
:math:`t` uses the data up to :math:`t` only. When the parameters drift
(a random walk ``Q``, or exponential forgetting), every estimate can be
improved by the later data too; the fixed-interval smoother of Rauch, Tung &
Striebel (1965) does it in one backward sweep over what ``batch_filter``
stored, and gives the covariances of the smoothed trajectory.

Exponential forgetting is a random walk whose covariance follows the
filter: :math:`P/\lambda = P + Q_t` with :math:`Q_t = (1/\lambda - 1) P`, so
the smoother of a forgetting filter is the smoother of that time-varying
random walk (the stored prior covariances already contain it).

The recursion is written once, in `rts_smoother`, for one filter (estimates
``(N, n)`` or ``(N, n, m)``) and for a bank of channels (``(N, C, n)``), whose
channels are smoothed independently in the same vectorized sweep;
`RecursiveLeastSquares.rts_smoother`, `RecursiveLeastSquares.smooth` and
`RLSBank.smooth` are thin calls into this module.
"""

import warnings

import numpy as np

from .._validation import as_float_array
from ..exceptions import NumericalWarning

__all__ = ["SmoothedTrajectory", "rts_smoother"]


class SmoothedTrajectory:
    r"""What `rts_smoother` returns: the smoothed and the filtered parameter trajectory.

    It unpacks like filterpy's ``KalmanFilter.rts_smoother`` result,
    ``x, P, K, Pp = rts_smoother(...)``.

    Attributes
    ----------
    means : ndarray, shape (N, n), (N, n, m) or (N, C, n)
        Smoothed estimates :math:`\hat x_{t|N}` (the shape of the filtered
        estimates given).
    covariances : ndarray, shape (N, n, n) or (N, C, n, n)
        Their covariances :math:`P_{t|N}`.
    gains : ndarray, shape (N, n, n) or (N, C, n, n)
        Smoother gains :math:`G_t = P_t (P^-_{t+1})^{-1}` (zero at the last step,
        as in filterpy).
    covariances_prior : ndarray, shape (N, n, n) or (N, C, n, n)
        :math:`P^-_{t+1}`, the prior covariance of the step after ``t``, at index
        ``t`` (filterpy's ``Pp``; the last one is the last posterior).
    filtered_means, filtered_covariances : ndarray
        The filtered trajectory the smoother started from (the ``means`` and
        ``covariances`` given).
    """

    def __init__(self, means, covariances, gains, covariances_prior, filtered_means,
                 filtered_covariances):
        self.means = means
        self.covariances = covariances
        self.gains = gains
        self.covariances_prior = covariances_prior
        self.filtered_means = filtered_means
        self.filtered_covariances = filtered_covariances

    def __iter__(self):
        return iter((self.means, self.covariances, self.gains, self.covariances_prior))

    def __len__(self):
        return 4

    def __getitem__(self, index):
        return tuple(self)[index]

    def __repr__(self):
        shape = self.means.shape
        return f"<SmoothedTrajectory: {shape[0]} steps of estimates shaped {shape[1:]}>"

    def plot(self, ax=None, **kwargs):
        """Filtered and smoothed trajectories with bands: `rlsfilt.plotting.plot_smoothed`."""
        from ..plotting import plot_smoothed
        return plot_smoothed(self, ax=ax, **kwargs)


def rts_smoother(means, covariances, means_prior, covariances_prior):
    r"""Rauch-Tung-Striebel smoother of a filtered parameter trajectory (``F = I``).

    Parameters
    ----------
    means : array_like, shape (N, n), (N, n, m) or (N, C, n)
        Filtered estimates :math:`\hat x_t` after each update (``batch_filter``'s
        `means`; a bank's are ``(N, C, n)``).
    covariances : array_like, shape (N, n, n) or (N, C, n, n)
        Their covariances :math:`P_t` (``batch_filter``'s `covariances`; a
        bank's have a channel axis, which tells a bank's ``(N, C, n)`` estimates
        from one filter's ``(N, n, m)``).
    means_prior : array_like, shape of `means`
        Estimates after each predict: ``means_prior[t]`` is the prior
        :math:`\hat x^-_t` of the update of sample ``t`` (``batch_filter``'s
        `means_p` with ``update_first=False``). Index 0 is not used.
    covariances_prior : array_like, shape of `covariances`
        Covariances after each predict, :math:`P^-_t` (``covariances_p``),
        aligned as `means_prior`. Index 0 is not used.

    Returns
    -------
    SmoothedTrajectory
        Unpacks as ``means, covariances, gains, covariances_prior`` (filterpy's
        ``x, P, K, Pp``).

    Notes
    -----
    With :math:`F = I` the backward sweep (Rauch, Tung & Striebel 1965;
    Sarkka 2013, th. 8.2) is, from :math:`\hat x_{N-1|N} = \hat x_{N-1}`,
    :math:`P_{N-1|N} = P_{N-1}` down to :math:`t = 0`,

    .. math::

        G_t &= P_t \, (P^-_{t+1})^{-1} \\
        \hat x_{t|N} &= \hat x_t + G_t (\hat x_{t+1|N} - \hat x^-_{t+1}) \\
        P_{t|N} &= P_t + G_t (P_{t+1|N} - P^-_{t+1}) G_t^T

    The priors are taken as the filter stored them, so the smoother holds for
    any ``Q``, per-step variances ``Rs``, missing or gated samples (whose
    posterior is their prior) and for exponential forgetting, whose prior
    :math:`P^-_{t+1} = P_t / \lambda + Q` is the random walk
    :math:`Q_t = (1/\lambda - 1) P_t + Q`. With ``lam = 1`` and ``Q = 0``
    (constant parameters) :math:`G_t = I` and every smoothed estimate is the
    last filtered one. The priors must be those of a Kalman time update: the
    forgetting modes that forget inside the update (``"directional"``, ...)
    have none, and their smoothed trajectory is not the smoother of a
    state-space model.

    :math:`G_t` is computed by solving with :math:`P^-_{t+1}` (a pseudo-inverse
    when it is singular, as under equality constraints); :math:`P_{t|N}` is
    kept exactly symmetric.

    References
    ----------
    .. [1] H. E. Rauch, F. Tung and C. T. Striebel, "Maximum likelihood
       estimates of linear dynamic systems", *AIAA Journal* 3(8), 1965.
    .. [2] S. Sarkka, *Bayesian Filtering and Smoothing*, Cambridge University
       Press, 2013, ch. 8.

    Examples
    --------
    A slowly drifting gain, filtered and then smoothed:

    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.filters.smoother import rts_smoother
    >>> rng = np.random.default_rng(0)
    >>> H = rng.standard_normal((400, 1))
    >>> gain = 1.0 + np.cumsum(0.02 * rng.standard_normal(400))
    >>> z = H[:, 0] * gain + 0.1 * rng.standard_normal(400)
    >>> rls = RecursiveLeastSquares(1, R=0.01, Q=0.02 ** 2)
    >>> run = rls.batch_filter(z, H)
    >>> smooth = rts_smoother(*run)
    >>> err = lambda a: np.sqrt(np.mean((a[50:, 0, 0] - gain[50:]) ** 2))
    >>> bool(err(smooth.means) < err(run[0]))
    True
    """
    xs_in = as_float_array(means, "means")
    Ps_in = as_float_array(covariances, "covariances")
    xp = as_float_array(means_prior, "means_prior")
    Pp = as_float_array(covariances_prior, "covariances_prior")
    x, P, xp, Pp = _as_channels(xs_in, Ps_in, xp, Pp)
    N, C, n, m = x.shape
    xs, Ps = x.copy(), P.copy()
    G = np.zeros((N, C, n, n))
    Ppk = np.empty((N, C, n, n))
    if N:
        Ppk[N - 1] = P[N - 1]
    for k in range(N - 2, -1, -1):
        prior = Pp[k + 1]
        Ppk[k] = prior
        # G_t = P_t (P^-_{t+1})^-1, as (P^-_{t+1})^-1 P_t transposed (both symmetric)
        Gk = np.swapaxes(_solve(prior, P[k]), -1, -2)
        G[k] = Gk
        # x_{t|N} = x_t + G_t (x_{t+1|N} - x^-_{t+1})
        xs[k] = x[k] + Gk @ (xs[k + 1] - xp[k + 1])
        # P_{t|N} = P_t + G_t (P_{t+1|N} - P^-_{t+1}) G_t^T, kept symmetric
        Pk = P[k] + Gk @ (Ps[k + 1] - prior) @ np.swapaxes(Gk, -1, -2)
        Ps[k] = 0.5 * (Pk + np.swapaxes(Pk, -1, -2))
    shape = xs_in.shape
    cov_shape = Ps_in.shape
    return SmoothedTrajectory(xs.reshape(shape), Ps.reshape(cov_shape),
                              G.reshape(cov_shape), Ppk.reshape(cov_shape),
                              xs_in.copy(), Ps_in.copy())


def filter_rts_smoother(filt, Xs, Ps, Qs=None):
    """`RecursiveLeastSquares.rts_smoother`: filterpy's ``rts_smoother`` with ``F = I``.

    The prior covariances are formed from the posteriors as the filter's time
    update forms them, :math:`P^-_{t+1} = P_t / \\lambda + Q_{t+1}`; returns
    ``(x, P, K, Pp)`` in filterpy's shapes and indexing.
    """
    _check_kalman(filt)
    X = as_float_array(Xs, "Xs")
    P = as_float_array(Ps, "Ps")
    n = filt.dim_x
    if P.ndim != 3 or P.shape[1:] != (n, n):
        raise ValueError(f"`Ps` must have shape (N, {n}, {n}); got {P.shape}")
    N = len(P)
    if X.shape[0] != N or X.shape[1:2] != (n,) or X.ndim not in (2, 3):
        raise ValueError(f"`Xs` must have shape ({N}, {n}) or ({N}, {n}, m) (one estimate "
                         f"per covariance in `Ps`); got {X.shape}")
    if Qs is None:
        Q = np.broadcast_to(filt.Q, (N, n, n))
    else:
        Q = as_float_array(Qs, "Qs")
        if Q.shape == (n, n):
            Q = np.broadcast_to(Q, (N, n, n))
        if Q.shape != (N, n, n):
            raise ValueError(f"`Qs` must have shape ({n}, {n}) or ({N}, {n}, {n}); "
                             f"got {Q.shape}")
    lam = np.asarray(filt.lam, dtype=float)
    if getattr(filt, "forgetting", "exponential") == "diagonal":
        w = 1.0 / np.sqrt(lam)
        il = np.outer(w, w)               # P^-_{t+1} = L^-1/2 P_t L^-1/2 + Q_{t+1}
    else:
        il = 1.0 / lam
    Pp = np.empty_like(P)
    Pp[1:] = P[:-1] * il + Q[1:]          # P^-_{t+1} = P_t / lam + Q_{t+1}
    Pp[:1] = P[:1]
    Xp = np.empty_like(X)
    Xp[1:] = X[:-1]                       # x^-_{t+1} = x_t  (F = I)
    Xp[:1] = X[:1]
    out = rts_smoother(X, P, Xp, Pp)
    return out.means, out.covariances, out.gains, out.covariances_prior


def smooth(filt, zs, Hs, Rs=None):
    """`RecursiveLeastSquares.smooth` and `RLSBank.smooth`: ``batch_filter`` over
    the record, then `rts_smoother` on what it stored."""
    _check_kalman(filt)
    # (a count for a filter, one per channel for a bank)
    capped = np.copy(getattr(filt, "n_capped", 0))
    run = filt.batch_filter(zs, Hs, Rs, store_covariances=True)
    means, covs, means_p, covs_p = tuple(run)
    if np.any(np.asarray(getattr(filt, "n_capped", 0)) != capped):
        warnings.warn("the windup cap of exponential forgetting restricted some updates of "
                      "this run (n_capped grew), so their priors are not P / lam + Q and the "
                      "smoothed trajectory there is approximate", NumericalWarning,
                      stacklevel=3)
    return rts_smoother(means, covs, means_p, covs_p)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _check_kalman(filt):
    """Refuse a filter whose time update is not ``P / lam + Q`` (or the diagonal
    ``L^-1/2 P L^-1/2 + Q``; the forgetting modes that forget inside the update have
    no Kalman prior)."""
    mode = getattr(filt, "forgetting", "exponential")
    if mode not in ("exponential", "diagonal"):
        raise ValueError(f"the smoother needs forgetting='exponential' (a Kalman time update "
                         f"P / lam + Q); this filter forgets with {mode!r} inside its update")


def _as_channels(x, P, xp, Pp):
    """The four histories as ``(N, C, n, m)`` and ``(N, C, n, n)`` (``C = 1`` for one
    filter, ``m = 1`` for a bank), checked against each other."""
    if P.ndim == 3:                                  # one filter: (N, n, n)
        N, n = P.shape[0], P.shape[1]
        if P.shape != (N, n, n):
            raise ValueError(f"`covariances` must have shape (N, n, n) or (N, C, n, n); "
                             f"got {P.shape}")
        if x.ndim == 2:
            x4 = x.reshape(len(x), 1, -1, 1)
        elif x.ndim == 3:
            x4 = x.reshape(len(x), 1, x.shape[1], x.shape[2])
        else:
            x4 = None
        P4 = P.reshape(N, 1, n, n)
    elif P.ndim == 4:                                # a bank: (N, C, n, n)
        N, C, n = P.shape[:3]
        if P.shape != (N, C, n, n):
            raise ValueError(f"`covariances` must have shape (N, n, n) or (N, C, n, n); "
                             f"got {P.shape}")
        x4 = x.reshape(*x.shape, 1) if x.ndim == 3 else None
        P4 = P
    else:
        raise ValueError(f"`covariances` must have shape (N, n, n) or (N, C, n, n); "
                         f"got {P.shape}")
    if x4 is None or x4.shape[:3] != P4.shape[:3]:
        want = f"({N}, {n}) or ({N}, {n}, m)" if P.ndim == 3 else f"({N}, {P.shape[1]}, {n})"
        raise ValueError(f"`means` must have shape {want} to match `covariances` "
                         f"{P.shape}; got {x.shape}")
    if xp.shape != x.shape:
        raise ValueError(f"`means_prior` must have the shape of `means` {x.shape}; "
                         f"got {xp.shape}")
    if Pp.shape != P.shape:
        raise ValueError(f"`covariances_prior` must have the shape of `covariances` "
                         f"{P.shape}; got {Pp.shape}")
    return x4, P4, xp.reshape(x4.shape), Pp.reshape(P4.shape)


def _solve(A, B):
    """``A^-1 B`` for stacks of symmetric ``A`` (a pseudo-inverse where one is singular)."""
    try:
        return np.linalg.solve(A, B)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(A, hermitian=True) @ B
