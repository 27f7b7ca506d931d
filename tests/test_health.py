"""Health of P: long runs stay symmetric positive definite; failures warn once, with the step."""

import re
import warnings

import numpy as np
import pytest
from conftest import arx_record
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import NumericalWarning, RecursiveLeastSquares


@pytest.mark.slow
def test_million_steps_at_lam_095_stay_healthy():
    rng = np.random.default_rng(11)
    N = 1_000_000
    Hs, zs = arx_record(rng, n_samples=N + 2, noise_std=0.05)
    rls = RecursiveLeastSquares(4, lam=0.95, R=0.05**2)
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # the health check (every 100 steps) stays quiet
        means, _, _, _ = rls.batch_filter(zs, Hs, store_covariances=False)
    assert rls.n_updates == N
    P = rls.P
    assert_array_equal(P, P.T)
    w = np.linalg.eigvalsh(P)
    assert w[0] > 0 and w[-1] / w[0] < 1e4
    assert np.all(np.isfinite(means))
    assert_allclose(rls.x[:, 0], [-1.5, 0.7, 1.0, 0.5], atol=0.02)


def _windup(n, lam=0.9):
    """Constant regressor: cond(P) grows like lam**-k."""
    return np.ones(n), np.tile([1.0, 1.0], (n, 1))


def _first_ill_conditioned_update(zs, Hs):
    """The first update at which cond(P) exceeds 1e12, found independently."""
    probe = RecursiveLeastSquares(2, lam=0.9, P0=1.0, check_every=0)
    for k in range(len(zs)):
        probe.predict_update(zs[k], Hs[k])
        w = np.linalg.eigvalsh(probe.P)
        if w[-1] > 1e12 * w[0]:
            return k + 1
    raise AssertionError("no ill-conditioning")


def test_ill_conditioning_warns_once_with_the_step():
    zs, Hs = _windup(400)
    first = _first_ill_conditioned_update(zs, Hs)
    rls = RecursiveLeastSquares(2, lam=0.9, P0=1.0, check_every=1)
    with pytest.warns(NumericalWarning) as record:
        for k in range(len(zs)):
            rls.predict_update(zs[k], Hs[k])
    assert len(record) == 1
    msg = str(record[0].message)
    assert "ill-conditioned" in msg
    assert re.search(rf"at update {first} since reset", msg), msg


def test_batch_filter_reports_the_step():
    zs, Hs = _windup(400)
    first = _first_ill_conditioned_update(zs, Hs)
    detected = -(-first // 10) * 10             # the next multiple of check_every
    k0 = detected - 25                          # it happens in the second call
    rls = RecursiveLeastSquares(2, lam=0.9, P0=1.0, check_every=10)
    with pytest.warns(NumericalWarning) as rec:
        rls.batch_filter(zs[:k0], Hs[:k0])
        rls.batch_filter(zs[k0:], Hs[k0:])
        rls.batch_filter(zs[k0:], Hs[k0:])      # warned already: silent
    assert len(rec) == 1
    assert (f"at step {detected - k0 - 1} of batch_filter (update {detected} since reset)"
            in str(rec[0].message))


def test_loss_of_positive_definiteness_is_caught_by_the_cheap_check():
    rls = RecursiveLeastSquares(2, check_every=1000)
    rls.P = np.array([[1.0, 0.0], [0.0, -1e-3]])   # e.g. a corrupted state
    with pytest.warns(NumericalWarning, match=r"`P` is not positive definite \(smallest "
                                              r"eigenvalue -0.001\) at update 1 since reset"):
        rls.update(1.0, [1.0, 0.0])


def test_indefinite_with_positive_diagonal_is_caught_by_the_periodic_check():
    rls = RecursiveLeastSquares(2, check_every=3)
    rls.P = np.array([[1.0, 2.0], [2.0, 1.0]])
    with pytest.warns(NumericalWarning, match=r"not positive definite.*at update 3 since reset"):
        for _ in range(3):
            rls.update(1.0, [0.0, 0.0])


def test_check_can_be_disabled_and_reset_rearms_it():
    zs, Hs = _windup(400)
    rls = RecursiveLeastSquares(2, lam=0.9, P0=1.0, check_every=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        rls.batch_filter(zs, Hs)
    rls.check_every = 50
    rls.reset()
    with pytest.warns(NumericalWarning):
        rls.batch_filter(zs, Hs)


def test_bad_health_arguments():
    with pytest.raises(ValueError, match=r"`check_every` must be >= 0; got -1"):
        RecursiveLeastSquares(2, check_every=-1)
    with pytest.raises(ValueError, match=r"`cond_max` must be a positive finite number; got -1.0"):
        RecursiveLeastSquares(2, cond_max=-1.0)
