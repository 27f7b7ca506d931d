r"""Consistent starting values for the prediction-error search.

The criterion of the model family has local minima; a start that is already
consistent (close to the truth for long records) puts the search in the
right basin. The recipe is a multistep method (Ljung 1999, ch. 10):

1. **Deterministic part.** With no ``F`` polynomials (ARX, ARMAX, AR, ARMA,
   ``A y = B u + C/D e``): the Hannan-Rissanen regression. A long ARX model
   estimates the innovations :math:`\hat e(t)`; then
   :math:`y(t) = -\sum a_k y(t-k) + \sum b u + \sum c_k \hat e(t-k) + e(t)`
   is linear in ``a, b, c`` and least squares on it is consistent
   (with ``D``, ``nc + L`` lags of :math:`\hat e` absorb the AR part of the
   disturbance). With ``F`` polynomials (OE, BJ): each path
   :math:`B_i/F_i` by the simplified refined instrumental-variable method
   (`_iv.fit_iv`, consistent whatever the noise colour), inputs in turn
   against the output with the other paths removed (two sweeps).
2. **Noise part** ``C/D``: the Hannan-Rissanen ARMA(``nd``, ``nc``) fit of
   the disturbance estimate :math:`\hat v = A y - \sum_i B_i/F_i u_i`.
3. ``C``, ``D``, ``F_i`` are reflected into the unit circle.

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
   Prentice Hall, 1999, ch. 10.
.. [2] E. J. Hannan and J. Rissanen, "Recursive estimation of mixed
   autoregressive-moving average order", *Biometrika* 69(1), 81-94, 1982.
.. [3] P. C. Young, *Recursive Estimation and Time-Series Analysis*, 2nd ed.,
   Springer, 2011, ch. 7.
"""

import numpy as np

from .._lazy_scipy import lfilter
from ._family import join_theta
from ._iv import fit_iv
from ._long_ar import long_arx_residuals
from ._stability import reflect, stabilize_theta
from .regressors import arx_structure

__all__ = []


def _lags(x, lags):
    """Columns ``x(t - k)`` for ``k`` in `lags`, zero before the record."""
    N = len(x)
    out = np.zeros((N, len(lags)))
    for j, k in enumerate(lags):
        if k < N:
            out[k:, j] = x[:N - k]
    return out


def long_order(N, s):
    """Order of the long ARX/AR model: enough lags to whiten a slowly decaying ``1/C``."""
    return int(min(max(20, 3 * (s.na + s.nc + s.nd + max(s.nf, default=0))), max(N // 20, 1)))


def hannan_rissanen(y, na, nc, U=None, nb=(), nk=(), order=None, extra_e_lags=0):
    r"""Two-stage least-squares estimate of ``A y = B u + C e`` (Hannan-Rissanen).

    Returns ``(a, b_list, c, e_hat)``: the ``a`` and ``c`` coefficients
    (without the leading 1), the ``b`` blocks, and the innovation estimates
    of the long model. `extra_e_lags` adds lags of :math:`\hat e` beyond
    ``nc`` to the regression (they absorb an AR noise part; their
    coefficients are dropped).
    """
    N = len(y)
    U = np.zeros((N, 0)) if U is None else U
    nu = U.shape[1]
    L = order if order is not None else max(20, 3 * (na + nc))
    e_hat = long_arx_residuals(U, y, L, nk if nu else None)
    n_e = nc + extra_e_lags
    cols = [-_lags(y, range(1, na + 1))]
    for i in range(nu):
        cols.append(_lags(U[:, i], range(nk[i], nk[i] + nb[i])))
    cols.append(_lags(e_hat, range(1, n_e + 1)))
    Phi = np.hstack(cols)
    t0 = L + (max(nk) if nu else 0) + max([na, n_e] + [k + b for k, b in zip(nk, nb)])
    t0 = min(t0, N - Phi.shape[1] - 1)
    theta = np.linalg.lstsq(Phi[t0:], y[t0:], rcond=None)[0]
    a = theta[:na]
    b, start = [], na
    for i in range(nu):
        b.append(theta[start:start + nb[i]])
        start += nb[i]
    c = theta[start:start + nc]
    return a, b, c, e_hat


def arma_start(v, nd, nc, N_order=None):
    """Hannan-Rissanen ARMA(``nd``, ``nc``) of a disturbance ``v``: returns stable ``(C, D)``."""
    if nd == 0 and nc == 0:
        return np.ones(1), np.ones(1)
    L = N_order if N_order is not None else max(20, 3 * (nd + nc))
    L = int(min(L, max(len(v) // 20, 1)))
    d, _, c, _ = hannan_rissanen(v, nd, nc, order=L)
    C = reflect(np.concatenate([[1.0], c]))
    D = reflect(np.concatenate([[1.0], d]))
    return C, D


def _oe_path(u, y, nb, nf, nk):
    """``(B, F)`` of one path ``y = B/F u + v`` by simplified refined IV."""
    s1 = arx_structure(nf, nb, nk)
    if nf == 0:
        Phi = _lags(u, range(nk, nk + nb))
        b = np.linalg.lstsq(Phi[s1.max_lag:], y[s1.max_lag:], rcond=None)[0]
        return np.concatenate([np.zeros(nk), b]), np.ones(1)
    try:
        theta = fit_iv(u[:, None], y[:, None], s1, "model", prefilter=True, n_iter=6).theta[:, 0]
    except ValueError:          # IV singular (a poor first model): least squares instead
        Phi = np.hstack([-_lags(y, range(1, nf + 1)), _lags(u, range(nk, nk + nb))])
        theta = np.linalg.lstsq(Phi[s1.max_lag:], y[s1.max_lag:], rcond=None)[0]
    F = reflect(np.concatenate([[1.0], theta[:nf]]))
    B = np.concatenate([np.zeros(nk), theta[nf:]])
    return B, F


def initial_estimate(U, y, s):
    """A consistent start for `pem` (see the module notes), with stable ``C``, ``D``, ``F_i``.

    Parameters
    ----------
    U : ndarray, shape (N, nu)
    y : ndarray, shape (N,)
    s : FamilyStructure

    Returns
    -------
    theta0 : ndarray, shape (n_params,)

    Examples
    --------
    The start of an ARMAX(1, 1, 1, 1) fit is already close to the truth:

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt.models._family import family_structure
    >>> from rlsfilt.models._initial import initial_estimate
    >>> rng = np.random.default_rng(4)
    >>> u, e = rng.standard_normal(20000), rng.standard_normal(20000)
    >>> y = lfilter([0, 1.0], [1, -0.8], u) + lfilter([1, 0.5], [1, -0.8], e)
    >>> np.round(initial_estimate(u[:, None], y, family_structure(1, 1, 1, nk=1)), 1)
    array([-0.8,  1. ,  0.5])
    """
    N = len(y)
    nu = s.n_inputs
    L = long_order(N, s)
    if not any(s.nf):
        if s.is_arx:
            extra = 0
        else:
            extra = 0 if s.nd == 0 else L // 2
        a, b, c, _ = hannan_rissanen(y, s.na, s.nc, U, s.nb, s.nk, order=L, extra_e_lags=extra)
        A = np.concatenate([[1.0], a])
        B = [np.concatenate([np.zeros(k), bi]) for k, bi in zip(s.nk, b)]
        F = [np.ones(1)] * nu
        if s.nd == 0:
            theta = join_theta(s, A=A, B=B, C=np.concatenate([[1.0], c]), F=F)
            return stabilize_theta(theta, s)[0]
        v = lfilter(A, [1.0], y) - sum((lfilter(B[i], [1.0], U[:, i]) for i in range(nu)),
                                       np.zeros(N))
    else:
        if s.na:
            # A and F together (rare): A, B from IV on the ARX part, F = 1 to start
            s1 = arx_structure(s.na, s.nb, s.nk, nu, 1)
            theta1 = fit_iv(U, y[:, None], s1, "model", prefilter=True, n_iter=6).theta[:, 0]
            A = np.concatenate([[1.0], theta1[:s.na]])
            B, start = [], s.na
            for i in range(nu):
                B.append(np.concatenate([np.zeros(s.nk[i]), theta1[start:start + s.nb[i]]]))
                start += s.nb[i]
            F = [np.ones(1)] * nu
        else:
            A = np.ones(1)
            B = [np.zeros(s.nk[i] + s.nb[i]) for i in range(nu)]
            F = [np.ones(1)] * nu
            paths = [np.zeros(N) for _ in range(nu)]
            for _sweep in range(2 if nu > 1 else 1):
                for i in range(nu):
                    others = sum((paths[j] for j in range(nu) if j != i), np.zeros(N))
                    B[i], F[i] = _oe_path(U[:, i], y - others, s.nb[i], s.nf[i], s.nk[i])
                    paths[i] = lfilter(B[i], F[i], U[:, i])
        v = lfilter(A, [1.0], y) - sum((lfilter(B[i], F[i], U[:, i]) for i in range(nu)),
                                       np.zeros(N))
    C, D = arma_start(v, s.nd, s.nc, L)
    theta = join_theta(s, A=A, B=B, C=C, D=D, F=F)
    return stabilize_theta(theta, s)[0]


def _pad(p, n):
    """``p`` cut or zero-padded to ``n + 1`` coefficients."""
    out = np.zeros(n + 1)
    p = np.asarray(p, dtype=float)[:n + 1]
    out[:len(p)] = p
    return out


def _arx_least_squares(U, y, na, nb, nk):
    """``(A, B list)`` of the least-squares ARX(``na``, ``nb``, ``nk``) on the rows ``t >= t0``."""
    nu = U.shape[1]
    cols = [-_lags(y, range(1, na + 1))]
    for i in range(nu):
        cols.append(_lags(U[:, i], range(nk[i], nk[i] + nb[i])))
    Phi = np.hstack(cols)
    t0 = max([na] + [k + b - 1 for k, b in zip(nk, nb)])
    theta = np.linalg.lstsq(Phi[t0:], y[t0:], rcond=None)[0]
    A = np.concatenate([[1.0], theta[:na]])
    B, start = [], na
    for i in range(nu):
        B.append(np.concatenate([np.zeros(nk[i]), theta[start:start + nb[i]]]))
        start += nb[i]
    return A, B


def _noise_part(U, y, s, A, B, F, L):
    """``theta`` of the structure with the deterministic part given and ``C, D`` by
    Hannan-Rissanen on the disturbance estimate (stabilized)."""
    N = len(y)
    v = lfilter(A, [1.0], y) - sum((lfilter(B[i], F[i], U[:, i]) for i in range(s.n_inputs)),
                                   np.zeros(N))
    C, D = arma_start(v, s.nd, s.nc, L)
    theta = join_theta(s, A=_pad(A, s.na), B=B, C=_pad(C, s.nc), D=_pad(D, s.nd),
                       F=[_pad(F[i], s.nf[i]) for i in range(s.n_inputs)])
    return stabilize_theta(theta, s)[0]


def arx_in_structure(U, y, s):
    """The least-squares ARX of the same orders written as a point of the structure `s`.

    ``A y = B u + e`` is the structure's predictor when ``F_i = A`` (OE, BJ:
    ``na = 0``, every ``nf_i`` equal) with ``D = A``, ``C = 1`` (BJ with
    ``nd >= nf``, ``D`` padded with zeros), or when there are no ``F_i``
    (ARMAX, ARMA: ``C = D = 1``).
    Returns ``(theta, exact)``: ``exact`` when the structure's criterion at
    ``theta`` is the ARX loss (the noise part is otherwise the Hannan-Rissanen
    fit of the ARX's output error), or ``(None, False)`` when the ARX does not
    fit into `s` (``A`` and ``F`` both estimated, or unequal ``nf_i``).
    """
    nu = s.n_inputs
    if not any(s.nf):
        if s.na == 0:
            return None, False
        A, B = _arx_least_squares(U, y, s.na, s.nb, s.nk)
        theta = join_theta(s, A=A, B=B, F=[np.ones(1)] * nu)
        return stabilize_theta(theta, s)[0], True
    if s.na or len(set(s.nf)) != 1:
        return None, False
    m = s.nf[0]
    A, B = _arx_least_squares(U, y, m, s.nb, s.nk)
    F = [reflect(A)] * nu
    if s.nd >= m:               # D = A (padded with zeros), C = 1
        theta = join_theta(s, B=B, D=_pad(F[0], s.nd), F=F)
        return theta, bool(np.array_equal(F[0], A))
    if not s.has_noise_model:
        return join_theta(s, B=B, F=F), bool(np.array_equal(F[0], A))
    return _noise_part(U, y, s, np.ones(1), B, F, long_order(len(y), s)), False


def arx_reduced(U, y, s):
    """Start of a structure with ``F_i`` (and no ``A``): a high-order ARX, each input's path
    ``B_i^L/A^L u_i`` simulated from it, then reduced to ``B_i/F_i`` by simplified refined
    IV on that (nearly noise-free) path, so that correlated inputs do not bias each other's
    start; ``C, D`` from the disturbance left. ``None`` for other structures."""
    if not any(s.nf) or s.na:
        return None
    N, nu = len(y), s.n_inputs
    L = int(min(max(10, 2 * max(s.nf) + 4, max(s.nb) + 2), max((N // 10) // (nu + 1), 1)))
    if L < max(s.nf):
        return None
    nb_long = [max(L, b) for b in s.nb]
    A_L, B_L = _arx_least_squares(U, y, L, nb_long, s.nk)
    A_L = reflect(A_L)
    B, F = [], []
    for i in range(nu):
        w = lfilter(B_L[i], A_L, U[:, i])
        Bi, Fi = _oe_path(U[:, i], w, s.nb[i], s.nf[i], s.nk[i])
        B.append(Bi)
        F.append(Fi)
    return _noise_part(U, y, s, np.ones(1), B, F, long_order(N, s))


def random_start(U, y, s, theta_ref, rng):
    """A random stable start for a multistart search.

    With ``F_i``: random stable ``F_i`` (zeros of radius 0.2 to 0.97, real or in
    conjugate pairs), then ``A`` and ``B_i`` by least squares on the inputs
    filtered by ``1/F_i`` (the criterion is quadratic in them for fixed ``F_i``),
    and ``C, D`` by Hannan-Rissanen. Without: `theta_ref` perturbed by 30 %
    (``C``, ``D`` reflected).
    """
    nu, N = s.n_inputs, len(y)
    if not any(s.nf):
        theta = theta_ref * (1.0 + 0.3 * rng.standard_normal(theta_ref.shape))
        theta += 0.05 * rng.standard_normal(theta_ref.shape)
        return stabilize_theta(theta, s)[0]
    F = []
    for i in range(nu):
        roots, n = [], s.nf[i]
        while len(roots) < n:
            r = rng.uniform(0.2, 0.97)
            if n - len(roots) >= 2 and rng.random() < 0.5:
                phi = rng.uniform(0.05, np.pi - 0.05)
                roots += [r * np.exp(1j * phi), r * np.exp(-1j * phi)]
            else:
                roots.append(r * rng.choice([-1.0, 1.0]) if rng.random() < 0.2 else r)
        F.append(np.real(np.poly(roots)) if n else np.ones(1))
    cols = [-_lags(y, range(1, s.na + 1))]
    for i in range(nu):
        uf = lfilter([1.0], F[i], U[:, i])
        cols.append(_lags(uf, range(s.nk[i], s.nk[i] + s.nb[i])))
    Phi = np.hstack(cols)
    t0 = s.t0
    theta = np.linalg.lstsq(Phi[t0:], y[t0:], rcond=None)[0]
    A = np.concatenate([[1.0], theta[:s.na]])
    B, start = [], s.na
    for i in range(nu):
        B.append(np.concatenate([np.zeros(s.nk[i]), theta[start:start + s.nb[i]]]))
        start += s.nb[i]
    return _noise_part(U, y, s, A, B, F, long_order(N, s))
