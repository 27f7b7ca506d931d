"""SquareRootRLS: equal to the covariance form on benign data, more accurate on Longley."""

import numpy as np
import pytest
from conftest import arx_record
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import RecursiveLeastSquares, SquareRootRLS

# NIST StRD "Longley" (public domain; https://www.itl.nist.gov/div898/strd/lls/data/Longley.shtml):
# y = TOTEMP; x1..x6 = GNP deflator, GNP, unemployed, armed forces, population, year.
LONGLEY = np.array([
    [60323, 83.0, 234289, 2356, 1590, 107608, 1947],
    [61122, 88.5, 259426, 2325, 1456, 108632, 1948],
    [60171, 88.2, 258054, 3682, 1616, 109773, 1949],
    [61187, 89.5, 284599, 3351, 1650, 110929, 1950],
    [63221, 96.2, 328975, 2099, 3099, 112075, 1951],
    [63639, 98.1, 346999, 1932, 3594, 113270, 1952],
    [64989, 99.0, 365385, 1870, 3547, 115094, 1953],
    [63761, 100.0, 363112, 3578, 3350, 116219, 1954],
    [66019, 101.2, 397469, 2904, 3048, 117388, 1955],
    [67857, 104.6, 419180, 2822, 2857, 118734, 1956],
    [68169, 108.4, 442769, 2936, 2798, 120445, 1957],
    [66513, 110.8, 444546, 4681, 2637, 121950, 1958],
    [68655, 112.6, 482704, 3813, 2552, 123366, 1959],
    [69564, 114.2, 502601, 3931, 2514, 125368, 1960],
    [69331, 115.7, 518173, 4806, 2572, 127852, 1961],
    [70551, 116.9, 554894, 4007, 2827, 130081, 1962],
])
# Certified coefficients b0 (intercept) .. b6.
LONGLEY_CERTIFIED = np.array([
    -3482258.63459582, 15.0618722713733, -0.358191792925910e-01, -2.02022980381683,
    -1.03322686717359, -0.511041056535807e-01, 1829.15146461355,
])


def _correct_digits(b, certified):
    """Log relative error (LRE), the smallest over the coefficients, as NIST reports it."""
    return float(np.min(-np.log10(np.abs(b - certified) / np.abs(certified))))


@pytest.mark.parametrize("lam, R", [(1.0, 1.0), (0.97, 0.3), (0.9, 2.0)])
def test_equals_covariance_form_on_benign_data(rng, lam, R):
    Hs, zs = arx_record(rng, n_samples=602)
    zs[[10, 300]] = np.nan
    cov = RecursiveLeastSquares(4, lam=lam, R=R)
    sq = SquareRootRLS(4, lam=lam, R=R)
    for z, h in zip(zs, Hs):
        cov.predict_update(z, h)
        sq.predict_update(z, h)
        assert_allclose(sq.x, cov.x, rtol=1e-9, atol=1e-9)
        assert_allclose(sq.P, cov.P, rtol=1e-9, atol=1e-9 * np.abs(cov.P).max())
        for name in ("y", "K", "S", "P_prior", "x_prior"):
            assert_allclose(getattr(sq, name), getattr(cov, name), rtol=1e-9,
                            atol=1e-9 * max(1.0, np.abs(getattr(cov, name)).max()), err_msg=name)
        assert sq.log_likelihood == pytest.approx(cov.log_likelihood, rel=1e-9)


def test_multi_output_and_batch_equal_covariance_form(rng):
    Hs, z1 = arx_record(rng, n_samples=300)
    zs = np.column_stack([z1, -z1 + rng.standard_normal(len(z1))])
    cov = RecursiveLeastSquares(4, dim_z=2, lam=0.98, P0=50.0)
    sq = SquareRootRLS(4, dim_z=2, lam=0.98, P0=50.0)
    m1, c1, mp1, cp1 = cov.batch_filter(zs, Hs)
    m2, c2, mp2, cp2 = sq.batch_filter(zs, Hs)
    assert_allclose(m2, m1, rtol=1e-9, atol=1e-10)
    assert_allclose(c2, c1, rtol=1e-9, atol=1e-12)
    assert_allclose(cp2, cp1, rtol=1e-9, atol=1e-12)
    # batch_filter leaves the same state as the stepwise loop
    loop = SquareRootRLS(4, dim_z=2, lam=0.98, P0=50.0)
    for z, h in zip(zs, Hs):
        loop.predict_update(z, h)
    assert_array_equal(loop.x, sq.x)
    assert_array_equal(loop.U, sq.U)


def test_longley_correct_digits():
    """Started on the first 7 rows (exactly determined) and updated through the other 9."""
    y = LONGLEY[:, 0]
    X = np.column_stack([np.ones(16), LONGLEY[:, 1:]])
    assert np.linalg.cond(X) > 1e9
    k0 = 7
    sq = SquareRootRLS(7)
    cov = RecursiveLeastSquares(7)
    sq.initialize(y[:k0], X[:k0])
    cov.initialize(y[:k0], X[:k0])
    for k in range(k0, 16):
        sq.predict_update(y[k], X[k])
        cov.predict_update(y[k], X[k])
    digits_sq = _correct_digits(sq.x[:, 0], LONGLEY_CERTIFIED)
    digits_cov = _correct_digits(cov.x[:, 0], LONGLEY_CERTIFIED)
    assert digits_sq >= 10.0                  # numpy lstsq on all rows: about 13
    assert digits_sq >= digits_cov + 1.5      # the covariance form keeps about 9
    assert np.all(np.linalg.eigvalsh(sq.P) > 0)


def test_initialize_is_lstsq_and_P_is_inverse_information(rng):
    Hs, zs = arx_record(rng, n_samples=102)
    sq = SquareRootRLS(4, R=0.5)
    sq.initialize(zs[:10], Hs[:10])
    assert_allclose(sq.x[:, 0], np.linalg.lstsq(Hs[:10], zs[:10], rcond=None)[0], rtol=1e-10)
    assert_allclose(sq.P, 0.5 * np.linalg.inv(Hs[:10].T @ Hs[:10]), rtol=1e-9)
    U = sq.U
    assert_array_equal(U, np.triu(U))
    assert np.all(np.diag(U) > 0)
    assert_allclose(U.T @ U, np.linalg.inv(sq.P), rtol=1e-9)
    for t in range(10, 100):
        sq.update(zs[t], Hs[t])
        assert_allclose(sq.x[:, 0], np.linalg.lstsq(Hs[:t + 1], zs[:t + 1], rcond=None)[0],
                        rtol=1e-9, atol=1e-12)


def test_assigning_state_and_helpers(rng):
    sq = SquareRootRLS(2, lam=0.9)
    sq.P = [[2.0, 0.5], [0.5, 1.0]]
    sq.x = [1.0, -1.0]
    assert_allclose(sq.P, [[2.0, 0.5], [0.5, 1.0]], rtol=1e-13)
    assert_allclose(sq.x, [[1.0], [-1.0]])
    x, P = sq.get_prediction()
    assert_allclose(P, np.array([[2.0, 0.5], [0.5, 1.0]]) / 0.9, rtol=1e-13)
    cov = RecursiveLeastSquares(2, lam=0.9, P0=[[2.0, 0.5], [0.5, 1.0]], x0=[1.0, -1.0])
    sq.predict_update(0.3, [1.0, 2.0])
    cov.predict_update(0.3, [1.0, 2.0])
    assert_allclose(sq.x, cov.x, rtol=1e-12)
    assert_allclose(sq.residual_of(1.0, [1, 1]), cov.residual_of(1.0, [1, 1]), rtol=1e-12)
    assert "SquareRootRLS" in repr(sq)
    sq.reset()
    assert_allclose(sq.P, 1e4 * np.eye(2), rtol=1e-13)
    assert_array_equal(sq.x, np.zeros((2, 1)))


def test_bad_arguments():
    with pytest.raises(ValueError, match=r"`lam` must be in \(0, 1\]; got 0.0"):
        SquareRootRLS(2, lam=0.0)
    sq = SquareRootRLS(2)
    with pytest.raises(ValueError, match=r"`P` must be positive definite"):
        sq.P = [[1.0, 0.0], [0.0, 0.0]]
    with pytest.raises(ValueError, match=r"`x` must have shape \(2, 1\); got \(3, 1\)"):
        sq.x = np.zeros((3, 1))
    with pytest.raises(ValueError, match=r"`Hs` is rank-deficient: found 1 linearly independent"):
        sq.initialize([1.0, 2.0, 3.0], [[1.0, 1.0]] * 3)


def test_saver_round_trip(rng):
    from filterpy.common import Saver

    Hs, zs = arx_record(rng, n_samples=42)
    sq = SquareRootRLS(4, lam=0.95)
    saver = Saver(sq)
    means, covs, _, _ = sq.batch_filter(zs, Hs, saver=saver)
    saver.to_array()
    assert_array_equal(saver.x, means)
    assert_array_equal(saver.P, covs)
