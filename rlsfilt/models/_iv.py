r"""Instrumental-variable estimates of ARX models, batch and recursive.

With coloured equation error :math:`w(t)` in :math:`y(t) = \varphi(t)^T\theta
+ w(t)`, least squares is biased because :math:`\varphi(t)` (which holds past
outputs) is correlated with :math:`w(t)`. Instrumental variables replace the
normal equations by

.. math::

    \hat\theta = \Big(\sum_t z(t)\varphi(t)^T\Big)^{-1} \sum_t z(t) y(t)
               = (Z^T\Phi)^{-1} Z^T Y,

with instruments :math:`z(t)` correlated with :math:`\varphi(t)` but not with
:math:`w(t)`: functions of the input only (open loop), or of a reference
signal (closed loop). The instruments offered here:

* ``"delayed"``: the ``-y`` block of the regressor replaced by further
  delayed inputs, ``u_1(t - nk_1 - nb_1 - k + 1)``, ``k = 1 .. na`` (Ljung
  1999, ch. 7);
* ``"model"``: the ``-y`` block replaced by the output ``x = \hat B/\hat A
  u`` of an auxiliary model, the ARX estimate itself, iterated; with
  ``prefilter=True`` every signal also passes through :math:`1/\hat A` (the
  simplified refined IV of Young, SRIV), which approaches the optimal
  instruments when the noise is close to AR;
* a user-given array of instrument rows (for example lags of a reference
  signal in closed loop).

The recursive form keeps :math:`P = (\sum z\varphi^T)^{-1}`, which is not
symmetric; with ``lam = 1`` and an exact start it equals the batch estimate
at every step. Its auxiliary model is refreshed from the running estimate
every ``refresh`` rows.

The covariance accounts for the coloured equation error: with ``w`` modelled
by a long AR fit :math:`w = e / A_w(q)` (order by AIC) and
:math:`\tilde z(t) = \sum_{i \ge 0} h_i z(t + i)`, :math:`h` the impulse
response of :math:`1/A_w` (Ljung 1999, ch. 9, with the noise filter :math:`K = 1/A_w`),

.. math::

    \mathrm{Cov}\,\hat\theta = \sigma_e^2\, M^{-1} (\tilde Z^T \tilde Z) M^{-T},
    \qquad M = Z^T\Phi.

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
   Prentice Hall, 1999, ch. 7, 9, 11 and 15.
.. [2] T. Soderstrom and P. Stoica, *Instrumental Variable Methods for
   System Identification*, Springer, 1983.
.. [3] P. C. Young, *Recursive Estimation and Time-Series Analysis*, 2nd ed.,
   Springer, 2011, ch. 6-7 (refined and simplified refined IV).
"""

import warnings

import numpy as np

from .._lazy import lazy_module
from .._lazy_scipy import lfilter
from .._scale import safe_norm
from ..exceptions import NumericalWarning
from ._long_ar import levinson_ar
from ._stability import reflect
from .regressors import _build

__all__ = []

_get_kernels = lazy_module("rlsfilt.models._recursive_kernels")


def _shift(x, k):
    """``x(t - k)`` with zeros before the record (``x`` 1-D)."""
    if k == 0:
        return x
    out = np.zeros_like(x)
    if k < len(x):
        out[k:] = x[:-k]
    return out


# ----------------------------------------------------------------------
# instruments
# ----------------------------------------------------------------------
def delayed_input_instruments(U, s, start=None):
    """Instrument rows from delayed inputs for an ARX structure `s`.

    The ``-y`` lags of output ``j`` are replaced by the lags
    ``nk_1 + nb_1 + j na .. nk_1 + nb_1 + (j + 1) na - 1`` of the first
    input; the input blocks are kept. Rows ``t = start .. N-1`` (default
    ``s.max_lag``), the layout of the ARX regressor.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.models import arx_structure
    >>> from rlsfilt.models._iv import delayed_input_instruments
    >>> s = arx_structure(na=1, nb=2, nk=1)
    >>> delayed_input_instruments(np.arange(6.0)[:, None], s)   # [u(t-3), u(t-1), u(t-2)]
    array([[0., 1., 0.],
           [0., 2., 1.],
           [1., 3., 2.],
           [2., 4., 3.]])
    """
    start = s.max_lag if start is None else start
    N = len(U)
    first = s.nk[0] + s.nb[0]
    cols = []
    for j in range(s.n_outputs):
        cols += [_shift(U[:, 0], first + j * s.na + k) for k in range(s.na)]
    for i in range(s.n_inputs):
        cols += [_shift(U[:, i], s.nk[i] + k) for k in range(s.nb[i])]
    Z = np.column_stack(cols) if cols else np.zeros((N, 0))
    return Z[start:]


def simulate_auxiliary(U, theta, s):
    """Noise-free output ``x = B/A u`` of the ARX estimate `theta` (single output).

    ``A`` is reflected into the unit circle first, so an unstable estimate
    still gives bounded instruments.
    """
    a = reflect(np.concatenate([[1.0], theta[:s.na]]))
    x = np.zeros(len(U))
    start = s.na
    for i in range(s.n_inputs):
        b = np.concatenate([np.zeros(s.nk[i]), theta[start:start + s.nb[i]]])
        start += s.nb[i]
        x += lfilter(b, [1.0], U[:, i])
    return lfilter([1.0], a, x), a


def model_instruments(U, Y, theta, s, prefilter=True):
    """Regressors, instruments and targets of one refined-IV iteration.

    The auxiliary model is the ARX estimate `theta`; with `prefilter` every
    signal is filtered by ``1/A_aux``. Returns ``(Phi, Z, target)`` for rows
    ``t = s.max_lag .. N-1``.
    """
    x, a = simulate_auxiliary(U, theta, s)
    if prefilter:
        Uf = lfilter([1.0], a, U, axis=0)
        Yf = lfilter([1.0], a, Y, axis=0)
        xf = lfilter([1.0], a, x)
    else:
        Uf, Yf, xf = U, Y, x
    Phi = _build(Uf, Yf, s, s.max_lag)
    Z = _build(Uf, xf[:, None], s, s.max_lag)
    return Phi, Z, Yf[s.max_lag:]


# ----------------------------------------------------------------------
# the estimate and its covariance
# ----------------------------------------------------------------------
def iv_solve(Z, Phi, Y):
    r"""``theta = (Z^T Phi)^{-1} Z^T Y`` (extended IV in the least-squares sense
    when `Z` has more columns than `Phi`).

    Raises
    ------
    ValueError
        When :math:`Z^T\Phi` is singular to working precision after column
        scaling (instruments uncorrelated with the regressors).
    """
    M = Z.T @ Phi
    rhs = Z.T @ Y
    # scale rows and columns so the rank decision does not depend on units
    dr = safe_norm(Z, axis=0)
    dc = safe_norm(Phi, axis=0)
    dr[dr == 0] = 1.0
    dc[dc == 0] = 1.0
    Ms = M / dr[:, None] / dc[None, :]
    sv = np.linalg.svd(Ms, compute_uv=False)
    n = Phi.shape[1]
    if n and not sv[-1] > max(Ms.shape) * np.finfo(float).eps * sv[0]:
        raise ValueError(
            "the instruments are not correlated with every regressor (Z^T Phi is singular; "
            f"scaled condition number {sv[0] / max(sv[-1], 1e-300):.3g}): the input is not "
            "persistently exciting, the orders are too high, or the instruments are poor")
    if M.shape[0] == M.shape[1]:
        theta = np.linalg.solve(M, rhs)
        G = np.linalg.inv(M)
    else:
        theta = np.linalg.lstsq(M, rhs, rcond=None)[0]
        G = np.linalg.pinv(M)
    return theta, G, M


def iv_covariance(G, Z, residuals, ar_max=None):
    r"""Covariance of an IV estimate under coloured equation error.

    Parameters
    ----------
    G : ndarray, shape (n, n_z)
        ``(Z^T Phi)^{-1}`` (or its pseudo-inverse for extended IV).
    Z : ndarray, shape (rows, n_z)
        Instrument rows.
    residuals : ndarray, shape (rows,)
        Equation residuals ``y - Phi theta``.
    ar_max : int, optional
        Largest order of the AR noise model (default ``min(64, rows // 20)``).

    Returns
    -------
    cov : ndarray, shape (n, n)
    a_w : ndarray
        The AR noise model ``[1, a_1, ..]`` of the residuals.
    sigma2 : float
        Its innovation variance.
    """
    rows = len(residuals)
    ar_max = min(64, rows // 20) if ar_max is None else ar_max
    a_w, sigma2 = levinson_ar(residuals, ar_max)
    # z~(t) = sum_i h_i z(t + i): filter the time-reversed instruments by 1/A_w
    Zt = lfilter([1.0], a_w, Z[::-1], axis=0)[::-1]
    cov = sigma2 * G @ (Zt.T @ Zt) @ G.T
    return 0.5 * (cov + cov.T), a_w, sigma2


class IVFit:
    """Result of `fit_iv` and `recursive_iv`.

    Attributes
    ----------
    theta : ndarray, shape (n, ny)
    cov : ndarray, shape (n, n) (one output) or (ny, n, n)
    residuals : ndarray
        Equation residuals ``target - Phi theta`` on the rows used.
    Phi, Z, target : ndarray
        Regressor and instrument rows and targets (prefiltered when the
        refined IV prefilter is on).
    n_iter : int
        Refined-IV iterations made.
    noise_ar : ndarray or None
        AR model of the equation error used by the covariance.
    """

    def __init__(self, **kw):
        self.__dict__.update(kw)


def _split_rows(Z, records, s, n_params, what="instruments"):
    """User instrument rows: one array with a row per sample of every experiment (one
    after the other), checked and split; rows ``max_lag ..`` of each experiment kept."""
    Z = np.asarray(Z, dtype=float)
    if Z.ndim == 1:
        Z = Z[:, None]
    N = sum(len(U) for U, _ in records)
    if Z.ndim != 2 or len(Z) != N or Z.shape[1] < n_params:
        per = " of every experiment, one after the other" if len(records) > 1 else ""
        raise ValueError(
            f"`{what}` must have shape (N, n_z) with N = {N} rows (one per sample{per}) and "
            f"n_z >= n_params = {n_params}; got {Z.shape}")
    if not np.isfinite(Z).all():
        raise ValueError(f"`{what}` must be finite")
    ends = np.cumsum([len(U) for U, _ in records])
    return np.vstack([Zi[s.max_lag:] for Zi in np.split(Z, ends[:-1])])


def _stacked_rows(records, s):
    """ARX regressor rows and targets of every experiment (rows never straddle two)."""
    return (np.vstack([_build(U, Y, s, s.max_lag) for U, Y in records]),
            np.vstack([Y[s.max_lag:] for _, Y in records]))


def fit_iv(U, Y, s, instruments="model", *, prefilter=True, n_iter=10, tol=1e-10,
           theta0=None):
    """Batch instrumental-variable estimate of an ARX structure (one record; see
    `fit_iv_records` for several experiments)."""
    return fit_iv_records([(U, Y)], s, instruments, prefilter=prefilter, n_iter=n_iter,
                          tol=tol, theta0=theta0)


def fit_iv_records(records, s, instruments="model", *, prefilter=True, n_iter=10, tol=1e-10,
                   theta0=None):
    r"""Batch instrumental-variable estimate of an ARX structure.

    With several experiments the normal equations sum over them,
    :math:`(\sum_i Z_i^T\Phi_i)^{-1}\sum_i Z_i^T Y_i`: the regressor and
    instrument rows of each experiment are built from its own samples
    (the auxiliary model of ``"model"`` is simulated and prefiltered from rest
    in each experiment).

    Parameters
    ----------
    records : list of (ndarray (N_i, nu), ndarray (N_i, ny))
        The experiments.
    s : ARXStructure
    instruments : {"model", "delayed"} or ndarray, default "model"
        ``"model"``: auxiliary-model instruments, iterated from the least
        squares estimate (single output); ``"delayed"``: delayed inputs;
        an array of shape ``(N, n_z)``, ``n_z >= n_params``: one instrument
        row per sample (of every experiment, one after the other; rows
        before each experiment's ``max_lag`` are dropped).
    prefilter : bool, default True
        ``"model"`` only: filter the signals by ``1/A_aux`` (SRIV).
    n_iter : int, default 10
        ``"model"`` only: largest number of refinements (stops when the
        estimate changes by less than ``tol`` relative).
    theta0 : ndarray, optional
        ``"model"`` only: the first auxiliary model (least squares by default).

    Returns
    -------
    IVFit

    Examples
    --------
    ARX(2, 2) of a plant with coloured (MA) equation error: IV removes the
    bias of least squares.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.models import arx_structure
    >>> from rlsfilt.models._iv import fit_iv_records
    >>> rng = np.random.default_rng(2)
    >>> u, e = rng.standard_normal(50000), rng.standard_normal(50000)
    >>> y = lfilter([0, 1, 0.5], [1, -1.5, 0.7], u) + lfilter([1, -1, 0.2], [1, -1.5, 0.7], e)
    >>> fit = fit_iv_records([(u[:, None], y[:, None])], arx_structure(2, 2, 1))
    >>> np.round(fit.theta[:, 0], 1)
    array([-1.5,  0.7,  1. ,  0.5])
    """
    rows_phi, target = _stacked_rows(records, s)
    n_iter_done = 0
    ny = records[0][1].shape[1]
    if isinstance(instruments, str) and instruments == "model":
        if ny != 1:
            raise ValueError("`instruments='model'` needs a single output; got "
                             f"{ny} outputs (use instruments='delayed' or give Z)")
        if theta0 is None:
            theta = np.linalg.lstsq(rows_phi, target[:, 0], rcond=None)[0]
        else:
            theta = np.asarray(theta0, dtype=float).reshape(-1)
        for n_iter_done in range(1, n_iter + 1):     # noqa: B007 (count kept)
            parts = [model_instruments(U, Y, theta, s, prefilter=prefilter)
                     for U, Y in records]
            Phi, Z, tgt = (np.vstack([p[k] for p in parts]) for k in range(3))
            new, G, M = iv_solve(Z, Phi, tgt[:, 0])
            step = np.max(np.abs(new - theta)) / max(np.max(np.abs(new)), 1e-300)
            theta = new
            if step < tol:
                break
        theta = theta[:, None]
    else:
        if isinstance(instruments, str):
            if instruments != "delayed":
                raise ValueError("`instruments` must be 'model', 'delayed' or an array of "
                                 f"instrument rows; got {instruments!r}")
            Z = np.vstack([delayed_input_instruments(U, s) for U, _ in records])
        else:
            Z = _split_rows(instruments, records, s, s.n_params)
        Phi, tgt = rows_phi, target
        theta, G, M = iv_solve(Z, Phi, tgt)
    resid = tgt - Phi @ theta
    cov, a_w = covariance_per_output(G, Z, resid, s.n_params)
    return IVFit(theta=theta, cov=cov, residuals=resid, Phi=Phi, Z=Z, target=tgt,
                 n_iter=n_iter_done, noise_ar=a_w)


def covariance_per_output(G, Z, resid, n_params):
    """`iv_covariance` of each output column: ``(n, n)`` for one output, else
    ``(ny, n, n)``; NaN when there are too few rows for the noise model.
    Returns ``(cov, a_w)`` with ``a_w`` the AR noise model of the first output."""
    ny = resid.shape[1]
    covs, a_first = [], None
    for j in range(ny):
        if len(resid) > 2 * n_params and np.isfinite(G).all():
            c, a_w, _ = iv_covariance(G, Z, resid[:, j])
            a_first = a_w if j == 0 else a_first
        else:
            c = np.full((G.shape[0], G.shape[0]), np.nan)
        covs.append(c)
    return (covs[0] if ny == 1 else np.array(covs)), a_first


# ----------------------------------------------------------------------
# recursive IV
# ----------------------------------------------------------------------
def recursive_iv(U, Y, s, instruments="model", **options):
    """`recursive_iv_records` on one record ``U (N, nu)``, ``Y (N, ny)``."""
    options.setdefault("stacklevel", 2)
    options["stacklevel"] += 1
    return recursive_iv_records([(U, Y)], s, instruments, **options)


def recursive_iv_records(records, s, instruments="model", *, lam=1.0, Q=None, R=1.0, P0=None,
                         x0=None, k0=None, refresh=None, prefilter=False, theta_aux=None,
                         tol=1e-10, cond_max=1e12, kernels=None, stacklevel=2):
    r"""Recursive instrumental variables over ARX records (one or several experiments).

    The rows of each experiment are built from its own samples (signals
    from rest at each experiment's first sample, so no row straddles two
    experiments); the estimate and ``P`` carry on from one experiment to
    the next, and the histories hold the rows one after the other. The
    exact start takes the first `k0` rows of the first experiment.

    Parameters
    ----------
    records : list of (ndarray (N_i, nu), ndarray (N_i, ny))
    s : ARXStructure
    instruments : {"model", "delayed"} or ndarray, default "model"
        As `fit_iv_records` (an array needs exactly ``n_params`` columns);
        ``"model"`` refreshes its auxiliary model from the running estimate
        every `refresh` rows of each experiment (single output).
    lam : float, default 1.0
        Forgetting factor (``P <- P / lam`` each step).
    Q : ndarray (n, n), optional
        Random walk added to ``P`` each step.
    R : float, default 1.0
        Added to the gain denominator ``R + phi^T P z``.
    P0, x0 :
        Prior start (``k0 = 0``): covariance (scalar means times I; default
        1e4) and estimate (zeros).
    k0 : int, optional
        Rows of the exact start :math:`P = (Z_0^T\Phi_0)^{-1}` (default
        ``n_params``, the fewest possible; ``0`` for the prior start).
    refresh : int, optional
        ``"model"``: rows between refreshes of the auxiliary model (default
        ``max(50, 10 n_params)``; ``0`` never refreshes).
    prefilter : bool, default False
        ``"model"``: filter the signals by ``1/A_aux`` (recursive SRIV).
    theta_aux : ndarray, optional
        ``"model"``: the first auxiliary model (default: least squares on
        the first ``max(k0, 2 n_params)`` rows).
    tol : float, default 1e-10
        Conditioning check: a step whose denominator satisfies
        ``|R + phi^T P z| <= tol (R + |phi| |P z|)`` is skipped (no update)
        and reported.
    cond_max : float, default 1e12
        Largest condition number of the final ``P`` that passes silently.
    kernels : module, optional
        What provides the steps ``riv_model`` and ``riv_rows`` (with the
        signatures of :mod:`rlsfilt.models._recursive_kernels`); the compiled
        kernels by default. The tests pass their NumPy reference
        (``tests/_reference_riv.py``).
    stacklevel : int, default 2
        Of the warnings.

    Returns
    -------
    IVFit
        With ``theta_history`` (rows, n[, ny]) (NaN before the exact
        start), ``eps`` (a-priori residuals), ``P`` and ``bad_step``
        (first row failing the conditioning check, or None).

    Warns
    -----
    NumericalWarning
        When the conditioning check fails (instruments nearly uncorrelated
        with the regressors: the gain denominator nearly vanished), or the
        final ``P`` is not finite or has a condition number above
        `cond_max`.
    """
    n, ny = s.n_params, records[0][1].shape[1]
    counts = [max(len(U) - s.max_lag, 0) for U, _ in records]
    rows = sum(counts)
    given = k0 is not None
    k0 = n if k0 is None else k0
    if k0 > counts[0]:
        first = " of the first experiment" if len(records) > 1 else ""
        hint = ("" if len(records) == 1 else
                " (the exact start is on the first experiment: put a longer one first, or "
                "pass k0=0 for the prior start)")
        raise ValueError(f"`k0` must be <= the number of regressor rows{first} ({counts[0]}); "
                         f"got {k0}{'' if given else ' (the default, n_params)'}{hint}")
    il = 1.0 / lam
    q_zero = Q is None or not np.any(Q)
    Qa = np.zeros((0, 0)) if q_zero else np.ascontiguousarray(Q, dtype=float)
    if P0 is None or np.ndim(P0) == 0:
        P = (1e4 if P0 is None else float(P0)) * np.eye(n)
    else:
        P = np.array(P0, dtype=float)
        if P.shape != (n, n):
            raise ValueError(f"`P0` must be a scalar or have shape ({n}, {n}); got {P.shape}")
    theta = np.zeros((n, ny)) if x0 is None else np.array(x0, dtype=float).reshape(n, ny)
    P = np.ascontiguousarray(P)
    theta = np.ascontiguousarray(theta)
    model = isinstance(instruments, str) and instruments == "model"
    if model:
        if ny != 1:
            raise ValueError("`instruments='model'` needs a single output; got "
                             f"{ny} outputs (use instruments='delayed' or give Z)")
        refresh = max(50, 10 * n) if refresh is None else refresh
        if theta_aux is None:
            U, Y = records[0]
            m = min(counts[0], max(k0, 2 * n))
            Phi0 = _build(U, Y, s, s.max_lag)[:m]
            theta_aux = np.linalg.lstsq(Phi0, Y[s.max_lag:s.max_lag + m, 0], rcond=None)[0]
        theta_aux = np.asarray(theta_aux, dtype=float).reshape(-1)
        alpha = reflect(np.concatenate([[1.0], theta_aux[:s.na]]))[1:].copy()
        beta = theta_aux[s.na:].copy()
        hist = np.empty((rows, n, 1))
        eps = np.empty((rows, 1))
        Phi = np.empty((rows, n))
        Z = np.empty((rows, n))
        target = np.empty(rows)
        bad, singular, first = -1, False, 0
        for i, ((U, Y), count) in enumerate(zip(records, counts)):
            sl = slice(first, first + count)       # this experiment's rows
            k0_i = k0 if i == 0 else 0             # the exact start is in the first
            k = _get_kernels() if kernels is None else kernels
            buf = np.zeros((4 + 2 * s.n_inputs, s.max_lag + 1))     # from rest
            bad_i, singular = k.riv_model(
                theta, P, buf, np.ascontiguousarray(U, dtype=float),
                np.ascontiguousarray(Y[:, 0], dtype=float), s.max_lag, s.na,
                np.array(s.nb, dtype=np.int64), np.array(s.nk, dtype=np.int64), k0_i,
                alpha, beta, refresh, bool(prefilter), il, Qa, float(R), tol,
                hist[sl], eps[sl], Phi[sl], Z[sl], target[sl])
            if singular:
                break
            if bad < 0 and bad_i >= 0:
                bad = first + bad_i
            first += count
        if singular:
            raise ValueError(f"the exact start on the first k0 = {k0} rows is singular "
                             "(Z0^T Phi0 not invertible: the first samples of `u` and `y` do "
                             "not excite every parameter): use a larger `k0`")
        target = target[:, None]
    else:
        Phi, target = _stacked_rows(records, s)
        if isinstance(instruments, str):
            if instruments != "delayed":
                raise ValueError("`instruments` must be 'model', 'delayed' or an array of "
                                 f"instrument rows; got {instruments!r}")
            Z = np.vstack([delayed_input_instruments(U, s) for U, _ in records])
        else:
            N = sum(len(U) for U, _ in records)
            shape = np.shape(instruments)
            if len(shape) not in (1, 2) or (shape + (1,))[:2] != (N, n):
                raise ValueError(f"`instruments` must have shape (N, n_params) = ({N}, {n}) "
                                 f"for the recursive IV; got {shape}")
            Z = _split_rows(instruments, records, s, n)
        Z = np.ascontiguousarray(Z)
        hist = np.full((rows, n, ny), np.nan)
        eps = np.full((rows, ny), np.nan)
        if k0 > 0:
            try:
                theta, G, _ = iv_solve(Z[:k0], Phi[:k0], target[:k0])
            except ValueError:
                raise ValueError(f"the exact start on the first k0 = {k0} rows is singular "
                                 "(Z0^T Phi0 not invertible: the first samples of `u` and `y` "
                                 "do not excite every parameter): use a larger `k0`") from None
            P = np.ascontiguousarray(G)
            theta = np.ascontiguousarray(theta)
            hist[k0 - 1] = theta
        k = _get_kernels() if kernels is None else kernels
        bad = k.riv_rows(theta, P, Phi[k0:], Z[k0:], np.ascontiguousarray(target[k0:]),
                         il, Qa, float(R), tol, hist[k0:], eps[k0:])
        bad = bad + k0 if bad >= 0 else bad
    if bad >= 0:
        warnings.warn(f"recursive IV: the gain denominator R + phi^T P z nearly vanished at row "
                      f"{bad} (instruments nearly uncorrelated with the regressors); that "
                      "update was skipped: use richer instruments or a larger k0",
                      NumericalWarning, stacklevel=stacklevel)
    elif not np.isfinite(P).all():
        warnings.warn("recursive IV: P is not finite at the end of the record",
                      NumericalWarning, stacklevel=stacklevel)
    else:
        cond = np.linalg.cond(P)
        if not cond <= cond_max:
            warnings.warn(f"recursive IV: P is ill-conditioned at the end of the record "
                          f"(condition number {cond:.3g} > {cond_max:.3g}): the instruments "
                          "hardly excite some direction", NumericalWarning, stacklevel=stacklevel)
    resid = target - Phi @ theta
    return IVFit(theta=theta, P=P, theta_history=hist, eps=eps, Phi=Phi, Z=Z, target=target,
                 residuals=resid, bad_step=None if bad < 0 else int(bad), cov=None,
                 n_iter=0, noise_ar=None)
