"""ARX regressor rows read from the signals (`LagRows`, `_kernels_lagged`).

``ARX.fit(method="rls")`` no longer builds the regressor matrix: the fused recursion,
the Gram bound of the form choice and the residuals read the rows from the record's
signals. Oracles: the regressor matrix of `ARX._design` (the rows, bit for bit), its
Gram matrix and residuals in NumPy (to round-off), and the recursion run on that
matrix (bit for bit: the same numbers in the same order).
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import ARX, RecursiveLeastSquares
from rlsfilt.filters._kernels_lagged import lag_rows, lag_rows_numpy
from rlsfilt.models import arx as arx_module
from rlsfilt.models._lag_rows import LagRows, MatrixRows
from rlsfilt.models.regressors import as_records

# (na, nb, nk, n_inputs, n_outputs, offset, experiment lengths)
STRUCTURES = [
    (2, 2, 1, 1, 1, False, (700,)),
    (3, [2, 4], [0, 2], 2, 1, True, (300, 5, 420)),    # a 5-sample experiment has no row
    (1, 2, 3, 1, 2, False, (260, 261)),
    (0, 3, 0, 1, 1, "mean", (513,)),                   # FIR, direct feed-through
]


def _records(rng, nu, ny, lengths):
    return [(rng.standard_normal((N, nu)) * 3.0, rng.standard_normal((N, ny)) + 2.0)
            for N in lengths]


def _rows(rng, structure):
    na, nb, nk, nu, ny, offset, lengths = structure
    model = ARX(na, nb, nk, offset=offset)
    recs = _records(rng, nu, ny, lengths)
    records, _ = as_records([U for U, _ in recs], [Y for _, Y in recs])
    s = model._structure(nu, ny)
    if offset == "mean":
        op = arx_module._means(records)
        records = [(U - op[0], Y - op[1]) for U, Y in records]
    Phi, target = ARX(na, nb, nk, offset=offset is True)._design(records, s)
    rows = LagRows(records, s, offset is True, lambda: (Phi, target))
    return rows, Phi, target


@pytest.mark.parametrize("structure", STRUCTURES)
def test_lag_rows_are_the_regressor_matrix_bit_for_bit(rng, structure):
    """Every row, every leading slice, every tail (the kernel's spec from a row on) and
    every target is the regressor matrix's, bit for bit, across experiment boundaries
    (one of them inside a block), scaled by powers of two or not."""
    rows, Phi, target = _rows(rng, structure)
    assert rows.shape == Phi.shape
    assert_array_equal(rows.rows(0, len(Phi)), Phi)
    for k in (0, 1, Phi.shape[1], 299, len(Phi)):
        assert_array_equal(rows[:k], Phi[:k])
    scale = np.ldexp(1.0, np.arange(Phi.shape[1]) - 3)
    for first in (0, 1, 294, 300, len(Phi) - 1):
        assert_array_equal(rows.rows(first, len(Phi), scale), Phi[first:] * scale)
        for fill in (lag_rows, lag_rows_numpy):              # compiled, and its NumPy twin
            tail = np.empty((len(Phi) - first + 7, Phi.shape[1]))   # room for more: not written
            tail[:] = 7.0
            got = fill(rows.lags(first), 0, np.ones(Phi.shape[1]), tail)
            assert got == len(Phi) - first
            assert_array_equal(tail[:got], Phi[first:])
            assert_array_equal(tail[got:], 7.0)
            few = np.empty((3, Phi.shape[1]))              # from row `first` of the whole spec
            got = fill(rows.lags(), first, scale, few)
            assert got == min(3, len(Phi) - first)
            assert_array_equal(few[:got], Phi[first:first + got] * scale)
        assert_array_equal(rows.target(first, len(Phi)), target[first:])
    assert_array_equal(rows.target(3, 11), target[3:11])
    with pytest.raises(TypeError, match="leading slices"):
        rows[3:]


@pytest.mark.parametrize("structure", STRUCTURES)
def test_lag_gram_and_residuals_against_numpy(rng, structure):
    """The Gram matrix of the scaled rows and the residuals of an estimate against NumPy
    on the matrix: to round-off of their sums (a few ulps of the summed magnitudes),
    and the residuals' largest magnitudes exactly those of the residuals returned."""
    rows, Phi, target = _rows(rng, structure)
    n = Phi.shape[1]
    e = -np.arange(n) % 5
    Ps = np.ldexp(Phi, e)
    G = rows.gram(e)
    assert_array_equal(G, G.T)
    bound = 4 * len(Phi) * np.finfo(float).eps * np.abs(Ps).T @ np.abs(Ps)
    assert np.all(np.abs(G - Ps.T @ Ps) <= bound)
    theta = rng.standard_normal((n, target.shape[1]))
    resid, top = rows.residuals(theta)
    exact = target - Phi @ theta
    tol = 4 * (n + 1) * np.finfo(float).eps * (np.abs(target) + np.abs(Phi) @ np.abs(theta))
    assert np.all(np.abs(resid - exact) <= tol)
    assert_array_equal(top, np.abs(resid).max(axis=0))


@pytest.mark.parametrize("dim_z, options", [(1, {}), (1, dict(lam=0.97, Q=1e-6)),
                                            (1, dict(forgetting="directional", lam=0.98)),
                                            (2, {})])
@pytest.mark.parametrize("scaled", [False, True])
def test_run_on_lagged_signals_equals_run_on_the_matrix_bit_for_bit(rng, dim_z, options,
                                                                    scaled):
    """``_run_batch(lags=...)`` gives the bits of the run on the regressor matrix: the
    fused loop (one output, exponential forgetting) filling its blocks from the
    signals, across blocks and experiment boundaries, and the step loop (other modes,
    several outputs) on the matrix built from them."""
    structure = (2, 2, 1, 1, dim_z, False, (300, 9, 500))
    rows, Phi, target = _rows(rng, structure)
    n, first = Phi.shape[1], 5
    scales = None
    if scaled:
        c, ey = np.arange(n) * 3 % 11 - 4, np.array([-5, 4])[:dim_z]
        scales = (np.ldexp(1.0, -c), np.ldexp(1.0, -ey),
                  np.ldexp(1.0, ey[None, :] - c[:, None]), np.ldexp(1.0, ey))
    a = RecursiveLeastSquares(n, dim_z=dim_z, check_every=7, **options)
    b = a.copy()
    Z = rows.target(first, len(Phi))
    Rv = a._as_batch_variances(None, len(Z))
    resid_a, resid_b = np.empty_like(Z), np.empty_like(Z)
    out = a._run_batch(Z, None, Rv, False, False, lead=2, residuals=resid_a, scales=scales,
                       lags=rows.lags(first))
    ref = b._run_batch(target[first:], Phi[first:], Rv, False, False, lead=2,
                       residuals=resid_b, scales=scales)
    assert_array_equal(out.buffer, ref.buffer)
    assert_array_equal(resid_a, resid_b)
    for name in ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "z", "H"):
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.n_updates == b.n_updates == len(Z)


CASES = {
    "siso": (dict(na=2, nb=2), {}, {}),
    "miso, direct feed-through": (dict(na=2, nb=[2, 3], nk=[0, 2]), {}, {"nu": 2}),
    "intercept": (dict(na=2, nb=2, offset=True), {}, {"shift": 5.0}),
    "operating point": (dict(na=2, nb=2, offset="mean"), {}, {"shift": 5.0}),
    "experiments": (dict(na=2, nb=2), {}, {"split": (400, 7, 600)}),
    "forgetting": (dict(na=2, nb=2), dict(lam=0.99), {}),
    "prior start": (dict(na=2, nb=2), dict(k0=0, P0=100.0), {}),
    "two outputs": (dict(na=1, nb=2), {}, {"ny": 2}),
}


def _io(rng, nu=1, ny=1, shift=0.0, split=None):
    N = 1100
    u = rng.standard_normal((N, nu))
    y = np.zeros((N, ny))
    for t in range(2, N):
        y[t] = 1.2 * y[t - 1] - 0.5 * y[t - 2] + u[t - 1].sum() + 0.1 * rng.standard_normal(ny)
    u, y = u + shift, y + 2 * shift
    u, y = (u[:, 0] if nu == 1 else u), (y[:, 0] if ny == 1 else y)
    if split:
        cuts = np.cumsum(split)[:-1]
        return np.split(u, cuts), np.split(y, cuts)
    return u, y


@pytest.mark.parametrize("case", list(CASES))
def test_rls_fit_on_the_signals_equals_the_fit_on_the_matrix(rng, monkeypatch, case):
    """``ARX.fit(method="rls")`` reading its rows from the signals gives every number of
    the fit run on the regressor matrix, bit for bit (the matrix path forced by giving
    the recursion the matrix's rows)."""
    orders, options, data = CASES[case]
    u, y = _io(rng, **data)
    fast = ARX(**orders).fit(u, y, method="rls", **options)
    monkeypatch.setattr(LagRows, "source",
                        lambda self, first=0: MatrixRows(*self.matrix()).source(first))
    slow = ARX(**orders).fit(u, y, method="rls", **options)
    for name in ("theta_", "theta_history_", "recursive_residuals_", "residuals_",
                 "noise_variance_", "theta_cov_", "k0_"):
        assert_array_equal(getattr(fast, name), getattr(slow, name), err_msg=name)
    for name in ("x", "P", "K", "y", "S", "H", "z"):
        assert_array_equal(getattr(fast.filter_, name), getattr(slow.filter_, name),
                           err_msg=name)


def test_rls_fit_equals_batch_least_squares_on_the_signals(rng):
    """The oracle the rows must serve: with lam = 1 and the batch start the recursive fit
    is batch least squares (`numpy.linalg.lstsq` on the regressor matrix)."""
    u, y = _io(rng, nu=2, split=(500, 600))
    model = ARX(2, [2, 1], [1, 0], offset=True).fit(u, y, method="rls")
    Phi, target = ARX(2, [2, 1], [1, 0], offset=True).regressors(u, y)
    theta = np.linalg.lstsq(Phi, target, rcond=None)[0]
    assert_allclose(model.theta_, theta, rtol=1e-10, atol=1e-12)
    assert_allclose(model.residuals_, target - Phi @ model.theta_, rtol=0, atol=1e-13)


def test_rls_fit_neither_writes_nor_keeps_the_callers_arrays(rng):
    """The record is read in place (no copy), never written, and no fitted attribute
    shares memory with it; read-only arrays fit the same (on copies the kernels'
    compiled layout takes)."""
    u, y = _io(rng)
    u0, y0 = u.copy(), y.copy()
    model = ARX(2, 2).fit(u, y, method="rls")
    assert_array_equal(u, u0)
    assert_array_equal(y, y0)
    for name, value in vars(model).items():
        if isinstance(value, np.ndarray):
            assert not np.shares_memory(value, u) and not np.shares_memory(value, y), name
    u.setflags(write=False)
    y.setflags(write=False)
    again = ARX(2, 2).fit(u, y, method="rls")
    assert_array_equal(again.theta_history_, model.theta_history_)
    assert_array_equal(again.residuals_, model.residuals_)


@pytest.mark.parametrize("scale", [1.0, 2.0 ** -700])
def test_noise_sums_without_the_divided_copy_are_those_with_it(rng, scale):
    """`_noise_and_covariance` given the residuals' largest magnitudes sums the products
    of the residuals themselves where their scale allows (the same bits as those of the
    residuals divided by a power of two, times its square) and divides a copy beyond."""
    resid = rng.standard_normal((500, 2)) * [1e-3, 7.0] * scale
    inv = np.linalg.inv(rng.standard_normal((3, 3)) @ np.diag([1.0, 2.0, 3.0]) @
                        rng.standard_normal((3, 3)).T + 3 * np.eye(3))
    c = np.array([0.5, 2.0, 8.0])
    with_top = arx_module._noise_and_covariance(resid, 497, inv, c,
                                                np.abs(resid).max(axis=0))
    without = arx_module._noise_and_covariance(resid, 497, inv, c)
    for a, b in zip(with_top, without):
        assert_array_equal(a, b)
    assert_allclose(with_top[0], (resid ** 2).sum(axis=0) / 497, rtol=1e-13)

