r"""From a model's polynomials to python-control, scipy and frequency responses.

Every model of rlsfilt describes itself by MATLAB's general polynomial form
(:class:`~rlsfilt.models.Polynomials`, Ljung 1999, sec. 4.2)

.. math::

    A(q)\, y(t) = \sum_j \frac{B_j(q)}{F_j(q)} u_j(t) + \frac{C(q)}{D(q)} e(t),

and this module turns that form into transfer functions, state-space
realizations and frequency responses without knowing which model it came
from. The rational form is first brought to an equivalent difference
equation :math:`\tilde A(q) y(t) = \tilde B(q) u(t)` by multiplying output
row :math:`i` with the denominators of that row,

.. math::

    \tilde A_{i\cdot} = A_{i\cdot} \prod_j F_{ij}, \qquad
    \tilde B_{ij} = B_{ij} \prod_{l \ne j} F_{il}
    \qquad\text{(noise model: } \tilde A_{i\cdot} = A_{i\cdot} D_i,\;
    \tilde B_{ii} = C_i\text{)},

which is exact (for an ARX model, whose ``F``, ``C``, ``D`` are 1, nothing
changes). Then :math:`G = \tilde A^{-1} \tilde B = \operatorname{adj}
\tilde A\, \tilde B / \det \tilde A` gives the transfer functions, and the
observer canonical form of the difference equation gives the state-space
realization.
"""

import numpy as np

from ._polynomials import (
    equalize,
    evaluate,
    padd,
    poly_adj,
    poly_det,
    poly_product,
    same_poly,
    trim,
)

__all__ = []


def arx_form(polys, noise=False):
    r"""The equivalent difference equation ``(A_t, B_t)`` of a polynomial model.

    Parameters
    ----------
    polys : Polynomials
        ``A (ny, ny, la)``, ``B (ny, nu, lb)``, ``C (ny, lc)``, ``D (ny, ld)``,
        ``F (ny, nu, lf)``.
    noise : bool, default False
        The noise model :math:`A^{-1} C / D` instead of the input model.

    Returns
    -------
    A_t : ndarray, shape (ny, ny, L)
        Matrix polynomial, ``A_t[:, :, 0]`` the identity.
    B_t : ndarray, shape (ny, m, M)
        ``m = nu`` (input model) or ``ny`` (noise model).
    """
    A, B, C, D, F = polys
    ny = A.shape[0]
    if noise:
        rows_a = [[np.convolve(A[i, j], D[i]) for j in range(ny)] for i in range(ny)]
        rows_b = [[np.asarray(C[i], float) if i == j else np.zeros(1) for j in range(ny)]
                  for i in range(ny)]
    else:
        nu = B.shape[1]
        rows_a, rows_b = [], []
        for i in range(ny):
            f_row = poly_product(F[i, j] for j in range(nu))
            rows_a.append([np.convolve(A[i, j], f_row) for j in range(ny)])
            rows_b.append([np.convolve(B[i, j], poly_product(F[i, k] for k in range(nu)
                                                             if k != j))
                           for j in range(nu)])
    return _stack(rows_a), _stack(rows_b)


def tf_data(A_t, B_t):
    """Numerators and denominators ``[i][j]`` of ``A_t^-1 B_t``, padded for powers of ``z``."""
    ny = A_t.shape[0]
    Am = [[trim(A_t[i, j]) for j in range(ny)] for i in range(ny)]
    det = trim(poly_det(Am))
    adj = poly_adj(Am)
    nums, dens = [], []
    for i in range(ny):
        row_n, row_d = [], []
        for j in range(B_t.shape[1]):
            num = np.zeros(1)
            for k in range(ny):
                num = padd(num, np.convolve(adj[i][k], B_t[k, j]))
            num, den = equalize(num, det)
            row_n.append(num)
            row_d.append(den)
        nums.append(row_n)
        dens.append(row_d)
    return nums, dens


def ss_matrices(A_t, B_t):
    """Observer-form realization ``(A, B, C, D)`` of ``A_t(q) y = B_t(q) u``."""
    ny, nu, lb = B_t.shape
    na = A_t.shape[2] - 1
    Bt = B_t.transpose(2, 0, 1)  # Bt[k] multiplies u(t-k), (ny, nu)
    n = max(na, lb - 1)
    Ak = [A_t[:, :, k] if k <= na else np.zeros((ny, ny)) for k in range(1, n + 1)]
    Bk = [Bt[k] if k < lb else np.zeros((ny, nu)) for k in range(n + 1)]
    D = Bk[0]
    Am = np.zeros((n * ny, n * ny))
    Bm = np.zeros((n * ny, nu))
    for i in range(n):
        blk = slice(i * ny, (i + 1) * ny)
        Am[blk, 0:ny] = -Ak[i]                 # x_i(t+1) = x_{i+1}(t) - A_i y(t) + B_i u(t)
        if i + 1 < n:
            Am[blk, (i + 1) * ny:(i + 2) * ny] = np.eye(ny)
        Bm[blk] = Bk[i + 1] - Ak[i] @ D        # y(t) = x_1(t) + D u(t)
    Cm = np.zeros((ny, n * ny))
    if n:  # a static gain (no dynamics) has no state
        Cm[:, :ny] = np.eye(ny)
    return Am, Bm, Cm, D.copy()


def to_tf(polys, dt, noise=False):
    """``control.TransferFunction`` of the input (or noise) model."""
    import control  # lazily: python-control imports matplotlib

    nums, dens = tf_data(*arx_form(polys, noise))
    if len(nums) == 1 and len(nums[0]) == 1:
        return control.tf(nums[0][0], dens[0][0], dt)
    return control.tf(nums, dens, dt)


def to_ss(polys, dt, noise=False):
    """``control.StateSpace`` (observer canonical form) of the input (or noise) model."""
    import control

    return control.ss(*ss_matrices(*arx_form(polys, noise)), dt)


def to_dlti(polys, dt, noise=False):
    """``scipy.signal.dlti``: a transfer function for SISO, the realization otherwise."""
    from scipy import signal  # lazy: keeps `import rlsfilt` light
    A_t, B_t = arx_form(polys, noise)
    if A_t.shape[0] == 1 and B_t.shape[1] == 1:
        nums, dens = tf_data(A_t, B_t)
        num = nums[0][0]
        lead = np.flatnonzero(num)
        num = num[lead[0]:] if len(lead) else np.zeros(1)  # exact: z^k factors, den kept
        return signal.dlti(num, dens[0][0], dt=dt)
    return signal.dlti(*ss_matrices(A_t, B_t), dt=dt)


def frequency_response(polys, omega, dt, noise=False):
    r"""``G(e^{j omega dt})`` of every channel, shape ``(ny, m, len(omega))``.

    Evaluated from the polynomials directly: :math:`A(z^{-1})^{-1}
    B_j(z^{-1}) / F_j(z^{-1})` (or :math:`A^{-1} C / D` for the noise
    model), a ratio for one output and a small linear solve per frequency
    otherwise.
    """
    A, B, C, D, F = polys
    ny = A.shape[0]
    zinv = np.exp(-1j * np.asarray(omega, dtype=float) * dt)
    if noise:
        num = np.zeros((ny, ny, zinv.size), dtype=complex)
        for i in range(ny):
            num[i, i] = evaluate(C[i], zinv) / evaluate(D[i], zinv)
    else:
        nu = B.shape[1]
        num = np.empty((ny, nu, zinv.size), dtype=complex)
        for i in range(ny):
            for j in range(nu):
                num[i, j] = evaluate(B[i, j], zinv) / evaluate(F[i, j], zinv)
    with np.errstate(divide="ignore", invalid="ignore"):
        if ny == 1:
            return num / evaluate(A[0, 0], zinv)
        Az = np.empty((ny, ny, zinv.size), dtype=complex)
        for i in range(ny):
            for j in range(ny):
                Az[i, j] = evaluate(A[i, j], zinv)
        G = np.linalg.solve(Az.transpose(2, 0, 1), num.transpose(2, 0, 1))
    return G.transpose(1, 2, 0)


def from_tf(G):
    """A discrete python-control system as one difference equation per output.

    Each output's entries are put over a common denominator ``A_i``, the
    product of the row's distinct denominators (minimal when they are equal
    or coprime), in powers of ``q^-1``.

    Parameters
    ----------
    G : control.LTI
        A proper discrete-time system (converted with ``control.tf``).

    Returns
    -------
    A_rows : list of ndarray
        ``A_i = [1, a1, ..]`` per output (trailing zeros dropped).
    B_rows : list of list of ndarray
        ``B_rows[i][j]``, the numerator of entry (i, j) over ``A_i`` in
        powers of ``q^-1`` (leading zeros are the delay).
    """
    import control

    if not isinstance(G, control.LTI):
        raise TypeError(f"`G` must be a discrete python-control LTI system (control.tf, "
                        f"control.ss); got {type(G).__name__}")
    if not isinstance(G, control.TransferFunction):
        G = control.tf(G)
    if not G.isdtime(strict=True):
        raise ValueError(f"`G` must be a discrete-time transfer function; got dt={G.dt!r}")
    A_rows, B_rows = [], []
    for i in range(G.noutputs):
        # each entry in powers of q^-1: den_q = [1, a1, ..] (trailing zeros, i.e. poles
        # at z = 0, dropped), num_q = numerator shifted by the relative degree
        ents = []
        for j in range(G.ninputs):
            den = np.trim_zeros(np.asarray(G.den[i][j], float), "f")
            num = np.trim_zeros(np.asarray(G.num[i][j], float), "f")
            for what, coef in (("numerator", num), ("denominator", den)):
                if not np.all(np.isfinite(coef)):
                    raise ValueError(f"`G` must have finite coefficients; got {coef.tolist()} in "
                                     f"the {what} of entry ({i}, {j})")
            if len(den) == 0:
                raise ValueError(f"`G` must have a nonzero denominator; entry ({i}, {j}) has "
                                 "a zero denominator")
            if len(num) > len(den):
                raise ValueError(f"`G` must be proper (causal); entry ({i}, {j}) has a "
                                 f"numerator of degree {len(num) - 1} over a denominator "
                                 f"of degree {len(den) - 1}")
            num_q = np.concatenate([np.zeros(len(den) - len(num)), num]) / den[0]
            ents.append((num_q if len(num) else np.zeros(1), trim(den / den[0])))
        common = []  # distinct denominators of the row; their product is A_i
        for _, d in ents:
            if not any(same_poly(c, d) for c in common):
                common.append(d)
        row = []
        for num, d in ents:
            for c in common:
                if not same_poly(c, d):
                    num = np.convolve(num, c)
            row.append(trim(num))
        A_rows.append(trim(poly_product(common)))
        B_rows.append(row)
    return A_rows, B_rows


def _stack(rows):
    """Nested lists ``[i][j]`` of polynomials as one zero-padded array (n_rows, n_cols, L)."""
    L = max(len(p) for row in rows for p in row)
    out = np.zeros((len(rows), len(rows[0]), L))
    for i, row in enumerate(rows):
        for j, p in enumerate(row):
            out[i, j, :len(p)] = p
    return out
