"""Equality constraints (against KKT-solved least squares) and the outlier gate."""

import pickle

import numpy as np
import pytest
from conftest import arx_record
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import RecursiveLeastSquares


def _kkt(Hm, Z, A, b, prior=None):
    """Equality-constrained least squares from the KKT system.

    minimize ||H x - z||^2 (+ (x - x0)' P0^-1 (x - x0)) subject to A x = b.
    """
    n, p = Hm.shape[1], A.shape[0]
    G, rhs = Hm.T @ Hm, Hm.T @ Z
    if prior is not None:
        x0, P0 = prior
        Pi = np.linalg.inv(P0)
        G, rhs = G + Pi, rhs + Pi @ x0
    K = np.block([[G, A.T], [A, np.zeros((p, p))]])
    return np.linalg.solve(K, np.concatenate([rhs, b]))[:n]


A2 = np.array([[0.0, 0.0, 1.0, 1.0],       # b1 + b2 = 1.5 (a known static gain)
               [1.0, -1.0, 0.0, 0.0]])     # a1 - a2 = -2.2
B2 = np.array([1.5, -2.2])


def test_constrained_rls_equals_kkt_at_every_step(rng):
    Hs, zs = arx_record(rng, n_samples=302, noise_std=0.3)
    k0 = 8
    rls = RecursiveLeastSquares(4)
    rls.initialize(zs[:k0], Hs[:k0])
    assert rls.constrain(A2, B2) is rls
    assert_allclose(rls.x[:, 0], _kkt(Hs[:k0], zs[:k0], A2, B2), rtol=1e-9)
    for t in range(k0, len(zs)):
        rls.predict_update(zs[t], Hs[t])
        x = _kkt(Hs[:t + 1], zs[:t + 1], A2, B2)
        assert_allclose(rls.x[:, 0], x, rtol=1e-8, atol=1e-10)
        assert_allclose(A2 @ rls.x[:, 0], B2, rtol=0, atol=1e-10)
    # the constrained fit differs from the free one (the constraint is active)
    free = np.linalg.lstsq(Hs, zs, rcond=None)[0]
    assert np.abs(A2 @ free - B2).max() > 0.01


def test_constrained_from_prior_is_constrained_ridge(rng):
    Hs, zs = arx_record(rng, n_samples=102)
    rls = RecursiveLeastSquares(4, P0=3.0, x0=[0.1, 0.2, 0.3, 0.4], R=1.0)
    rls.constrain([1.0, 1.0, 1.0, 1.0], 2.0)
    means, covs, _, _ = rls.batch_filter(zs, Hs)
    A, b = np.ones((1, 4)), np.array([2.0])
    prior = (np.array([0.1, 0.2, 0.3, 0.4]), 3.0 * np.eye(4))
    for t in (0, 10, 99):
        assert_allclose(means[t, :, 0], _kkt(Hs[:t + 1], zs[:t + 1], A, b, prior), rtol=1e-8)
    assert_allclose(covs @ A.T, 0.0, atol=1e-12)                 # A P = 0 throughout


def test_constrained_multi_output(rng):
    Hs, z1 = arx_record(rng, n_samples=202)
    zs = np.column_stack([z1, 0.5 * z1 + 0.1 * rng.standard_normal(len(z1))])
    bb = np.array([[1.5, 0.7], [-2.2, -1.1]])          # one column of b per output
    rls = RecursiveLeastSquares(4, dim_z=2)
    rls.initialize(zs[:6], Hs[:6])
    rls.constrain(A2, bb)
    rls.batch_filter(zs[6:], Hs[6:])
    for j in range(2):
        assert_allclose(rls.x[:, j], _kkt(Hs, zs[:, j], A2, bb[:, j]), rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("mode, q", [("exponential", 1e-4), ("directional", 0.0),
                                     ("constant_trace", 0.0), ("efra", 1e-5),
                                     ("variable", 0.0)])
def test_every_mode_keeps_the_constraint(rng, mode, q):
    Hs, zs = arx_record(rng, n_samples=1002)
    rls = RecursiveLeastSquares(4, lam=0.95, Q=q, R=0.01, forgetting=mode, gate=6.0)
    rls.constrain(A2, B2)
    means, covs, _, _ = rls.batch_filter(zs, Hs)    # also: no NumericalWarning for singular P
    assert_allclose(means[:, :, 0] @ A2.T, np.broadcast_to(B2, (len(zs), 2)), atol=1e-9)
    assert np.abs(covs @ A2.T).max() < 1e-10 * np.abs(covs).max()
    assert_allclose(means[-1, :, 0], [-1.5, 0.7, 1.0, 0.5], atol=0.1)


def test_initialize_and_reset_keep_constraints(rng):
    Hs, zs = arx_record(rng, n_samples=50)
    rls = RecursiveLeastSquares(4).constrain(A2, B2)
    A, b = rls.constraints
    assert_array_equal(A, A2)
    assert_allclose(A2 @ rls.x[:, 0], B2)
    rls.initialize(zs[:10], Hs[:10])
    assert_allclose(rls.x[:, 0], _kkt(Hs[:10], zs[:10], A2, B2), rtol=1e-9)
    rls.reset()
    assert_allclose(A2 @ rls.x[:, 0], B2, atol=1e-12)


def test_constraints_accumulate_and_stay_the_kkt_answer(rng):
    """Three constraints added one call at a time (one, two, then one more row), updates
    between them, reset() and initialize() after: at every step the estimate is the
    equality-constrained least-squares answer under all constraints given so far (KKT)."""
    n = 6
    H = rng.standard_normal((260, n))
    z = H @ rng.standard_normal(n) + 0.3 * rng.standard_normal(260)
    blocks = [(np.array([[1.0, 1.0, 0.0, 0.0, 0.0, 0.0]]), np.array([0.5])),
              (np.array([[0.0, 0.0, 1.0, -1.0, 0.0, 0.0],
                         [0.0, 1.0, 0.0, 0.0, 2.0, 0.0]]), np.array([0.2, -0.4])),
              (np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 3.0]]), np.array([1.0]))]
    rls = RecursiveLeastSquares(n)
    rls.initialize(z[:10], H[:10])
    A, b = np.zeros((0, n)), np.zeros(0)
    t = 10
    for Ak, bk in blocks:
        rls.constrain(Ak, bk)
        A, b = np.vstack([A, Ak]), np.concatenate([b, bk])
        assert_array_equal(rls.constraints.A, A)
        assert_allclose(rls.x[:, 0], _kkt(H[:t], z[:t], A, b), rtol=1e-8, atol=1e-10)
        for _ in range(60):
            rls.predict_update(z[t], H[t])
            t += 1
            assert_allclose(rls.x[:, 0], _kkt(H[:t], z[:t], A, b), rtol=1e-8, atol=1e-10)
        assert_allclose(A @ rls.x[:, 0], b, atol=1e-10)
    # every constraint is active: the unconstrained answer violates each block
    free = np.linalg.lstsq(H[:t], z[:t], rcond=None)[0]
    assert all(np.abs(Ak @ free - bk).max() > 1e-3 for Ak, bk in blocks)
    # configuration, not state: reset() and initialize() keep all of them
    rls.reset()
    assert_allclose(A @ rls.x[:, 0], b, atol=1e-10)
    rls.initialize(z[:40], H[:40])
    assert_allclose(rls.x[:, 0], _kkt(H[:40], z[:40], A, b), rtol=1e-8, atol=1e-10)
    rls.batch_filter(z[40:], H[40:])
    assert_allclose(rls.x[:, 0], _kkt(H, z, A, b), rtol=1e-8, atol=1e-10)


def test_redundant_or_conflicting_constraints_are_refused_atomically(rng):
    """The audit's case: a second constraint on a constrained direction raised
    LinAlgError or gave an estimate far from the constrained answer."""
    Hs, zs = arx_record(rng, n_samples=60)
    rls = RecursiveLeastSquares(4)
    rls.initialize(zs[:8], Hs[:8])
    rls.constrain(A2, B2)
    for A, b, what in ((A2[0], B2[0], "redundant"),                       # the same again
                       (2.0 * A2[1], 2.0 * B2[1], "redundant"),           # a multiple
                       (A2[0] + A2[1], B2[0] + B2[1], "redundant"),       # a combination
                       (A2[0], B2[0] + 0.1, "conflict"),                  # another value
                       (A2[0] - A2[1], 0.0, "conflict")):
        before = pickle.dumps(rls)
        with pytest.raises(ValueError, match=f"`A`, `b` (are {what}|{what})"):
            rls.constrain(A, b)
        assert pickle.dumps(rls) == before
    with pytest.raises(ValueError, match="4 constraints would fix all dim_x = 4 parameters"):
        rls.constrain([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]], [0.0, 0.0])


def test_constraints_survive_reset_with_efra(rng):
    """EFRA's start is clipped before the constraints are imposed again (the projection
    must not meet a covariance already singular in their directions)."""
    Hs, zs = arx_record(rng, n_samples=300)
    rls = RecursiveLeastSquares(4, lam=0.95, forgetting="efra", R=0.01)
    rls.constrain(A2[:1], B2[:1]).constrain(A2[1:], B2[1:])
    rls.batch_filter(zs, Hs)
    rls.reset()
    means, *_ = rls.batch_filter(zs, Hs)
    assert_allclose(means[:, :, 0] @ A2.T, np.broadcast_to(B2, (len(zs), 2)), atol=1e-9)


def test_constrain_bad_arguments():
    rls = RecursiveLeastSquares(3)
    with pytest.raises(ValueError, match=r"`A` must have shape \(p, 3\) \(dim_x = 3 columns\); "
                                         r"got \(1, 2\)"):
        rls.constrain([[1.0, 2.0]], 1.0)
    with pytest.raises(ValueError, match=r"`A` must have full row rank p < dim_x = 3; got 2 "
                                         r"rows of rank 1"):
        rls.constrain([[1.0, 1.0, 0.0], [2.0, 2.0, 0.0]], [1.0, 2.0])
    with pytest.raises(ValueError, match=r"`b` must have shape \(1,\) or \(1, 1\); got \(2,\)"):
        rls.constrain([1.0, 1.0, 0.0], [1.0, 2.0])
    with pytest.raises(ValueError, match=r"`A` must be finite"):
        rls.constrain([1.0, np.nan, 0.0], 1.0)


# ----------------------------------------------------------------------
# outlier gate
# ----------------------------------------------------------------------
def _regression(rng, N=3000, sigma=0.1):
    Hs = np.column_stack([np.ones(N), rng.standard_normal((N, 2))])
    theta = np.array([0.5, -1.0, 2.0])
    return Hs, Hs @ theta + sigma * rng.standard_normal(N), theta


def test_gate_rejects_gross_outliers(rng):
    Hs, clean, theta = _regression(rng)
    bad = np.sort(rng.choice(np.arange(200, 3000), size=12, replace=False))
    dirty = clean.copy()
    dirty[bad] += rng.choice([-1.0, 1.0], size=12) * rng.uniform(5.0, 50.0, size=12)
    kw = dict(R=0.01, lam=0.999)
    gated = RecursiveLeastSquares(3, gate=5.0, **kw)
    gated.batch_filter(dirty, Hs)
    assert gated.n_gated == 12
    # exactly the same as marking the outliers missing
    missing = clean.copy()
    missing[bad] = np.nan
    ref = RecursiveLeastSquares(3, **kw)
    ref.batch_filter(missing, Hs)
    # the gated run takes the NumPy path, the plain one the compiled kernel:
    # equal to round-off
    assert_allclose(gated.x, ref.x, rtol=1e-12, atol=1e-14)
    assert_allclose(gated.P, ref.P, rtol=1e-12, atol=1e-12 * np.abs(ref.P).max())
    # as good as the clean record; without the gate the outliers ruin it
    plain_clean = RecursiveLeastSquares(3, **kw)
    plain_clean.batch_filter(clean, Hs)
    plain_dirty = RecursiveLeastSquares(3, **kw)
    plain_dirty.batch_filter(dirty, Hs)
    err = lambda f: np.abs(f.x[:, 0] - theta).max()   # noqa: E731
    assert err(gated) < 1.5 * err(plain_clean) + 1e-3
    assert err(plain_dirty) > 10 * err(plain_clean)


def test_gated_step_state(rng):
    rls = RecursiveLeastSquares(2, R=0.01, gate=3.0, P0=1e-2, x0=[1.0, 1.0])
    rls.predict_update(2.05, [1.0, 1.0])
    assert not rls.gated and rls.n_gated == 0
    x, P = rls.x.copy(), rls.P.copy()
    rls.predict_update(10.0, [1.0, 1.0])
    assert rls.gated and rls.n_gated == 1
    assert_array_equal(rls.x, x)
    assert_array_equal(rls.P, P)
    assert_array_equal(rls.K, np.zeros((2, 1)))
    s = 0.01 + np.array([1.0, 1.0]) @ P @ [1.0, 1.0]
    assert_allclose(rls.S, [[s]])
    assert_allclose(rls.y, 10.0 - x.sum())
    assert rls.mahalanobis > 3.0
    rls.predict_update(2.0, [1.0, 1.0])
    assert not rls.gated and rls.n_gated == 1
    rls.reset()
    assert rls.n_gated == 0 and not rls.gated


def test_gate_multi_output_uses_the_norm(rng):
    rls = RecursiveLeastSquares(1, dim_z=2, R=1.0, P0=1e-12, gate=2.0)
    rls.update([1.5, 1.5], [1.0])          # sqrt((1.5^2 + 1.5^2) / 1) = 2.12 > 2
    assert rls.gated
    rls.update([1.4, 0.0], [1.0])
    assert not rls.gated
