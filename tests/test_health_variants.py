"""Health of P in SquareRootRLS: windup warns once, with the step, on the compiled
and the NumPy reference paths alike; a benign run stays quiet."""

import re
import warnings

import numpy as np
import pytest
from conftest import arx_record

from rlsfilt import NumericalWarning, SquareRootRLS
from rlsfilt.filters import square_root as sr_module

LAM, P0 = 0.98, 1e4


@pytest.fixture(params=[True, False], ids=["compiled", "reference"])
def path(request, monkeypatch):
    """Run the test on the compiled kernels and on the NumPy reference."""
    monkeypatch.setattr(sr_module, "_COMPILED", request.param)
    return request.param


def _windup(n):
    """Constant regressor [1, 1] (the input stops exciting the direction [1, -1])."""
    return np.ones(n), np.tile([1.0, 1.0], (n, 1))


def _first_ill_conditioned_update(cond_max=1e12, lam=LAM, p0=P0):
    """First update count k at which cond(P) > cond_max, in closed form.

    With ``P0 = p0 I``, ``R = 1`` and a time update before each measurement
    update, the information after k updates is
    ``lam^k / p0 I + sum_{j<k} lam^j h h^T`` with ``h = [1, 1]``: eigenvalue
    ``lam^k / p0`` along [1, -1] and ``lam^k / p0 + 2 (1 - lam^k) / (1 - lam)``
    along [1, 1], so ``cond(P) = 1 + 2 p0 (lam^-k - 1) / (1 - lam)``.
    """
    k = np.arange(1, 5000)
    cond = 1.0 + 2.0 * p0 * (lam ** -k.astype(float) - 1.0) / (1.0 - lam)
    return int(k[np.argmax(cond > cond_max)])


def test_closed_form_condition_number_matches_the_filter():
    # the oracle itself, against eigvalsh of P while P is still well conditioned
    zs, Hs = _windup(300)
    f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=0)
    for k in range(len(zs)):
        f.predict_update(zs[k], Hs[k])
    w = np.linalg.eigvalsh(f.P)
    expected = 1.0 + 2.0 * P0 * (LAM ** -300.0 - 1.0) / (1.0 - LAM)
    assert w[-1] / w[0] == pytest.approx(expected, rel=1e-6)
    assert _first_ill_conditioned_update() == 684


def test_windup_warns_once_with_the_update(path):
    zs, Hs = _windup(2000)
    first = _first_ill_conditioned_update()
    f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=1)
    with pytest.warns(NumericalWarning) as record:
        for k in range(len(zs)):
            f.predict_update(zs[k], Hs[k])
    assert len(record) == 1
    msg = str(record[0].message)
    assert "ill-conditioned" in msg
    assert re.search(rf"at update {first} since reset\.", msg), msg
    assert f.n_updates == 2000
    assert np.trace(f.P) > 1e20                  # the windup went on (the filter only warns)


def test_windup_batch_filter_names_the_step(path):
    zs, Hs = _windup(2000)
    first = _first_ill_conditioned_update()
    detected = -(-first // 100) * 100            # the next multiple of check_every=100
    k0 = detected - 25                           # it happens in the second call
    f = SquareRootRLS(2, lam=LAM, P0=P0)
    with pytest.warns(NumericalWarning) as record:
        f.batch_filter(zs[:k0], Hs[:k0])
        f.batch_filter(zs[k0:], Hs[k0:])
        f.batch_filter(zs[k0:], Hs[k0:])         # warned already: silent
    assert len(record) == 1
    assert (f"at step {detected - k0 - 1} of batch_filter (update {detected} since reset)"
            in str(record[0].message))
    assert record[0].filename == __file__        # points at the caller


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("how", ["batch", "saver", "streaming"])
def test_compiled_and_reference_warn_identically(monkeypatch, how, update_first):
    zs, Hs = _windup(1000)
    messages = []
    for compiled in (True, False):
        monkeypatch.setattr(sr_module, "_COMPILED", compiled)
        f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=7)
        with pytest.warns(NumericalWarning) as record:
            if how == "streaming":
                for k in range(len(zs)):
                    f.predict_update(zs[k], Hs[k])
            else:
                saver = _NullSaver() if how == "saver" else None
                f.batch_filter(zs, Hs, update_first=update_first, saver=saver)
        assert len(record) == 1
        messages.append(str(record[0].message))
    assert messages[0] == messages[1]
    first = _first_ill_conditioned_update()
    detected = -(-first // 7) * 7
    where = (f"at update {detected} since reset" if how == "streaming"
             else f"at step {detected - 1} of batch_filter (update {detected} since reset)")
    assert where in messages[0]


class _NullSaver:
    def save(self):
        pass


def test_benign_run_does_not_warn(path):
    rng = np.random.default_rng(7)
    Hs, zs = arx_record(rng, n_samples=20_002, noise_std=0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = SquareRootRLS(4, lam=0.95, R=0.05**2, check_every=1)
        a.batch_filter(zs, Hs, store_covariances=False)
        b = SquareRootRLS(4, lam=0.95, R=0.05**2, check_every=10)
        for k in range(2000):
            b.predict_update(zs[k], Hs[k])
    assert a.n_updates == 20_000 and b.n_updates == 2000
    w = np.linalg.eigvalsh(a.P)
    assert 0 < w[0] and w[-1] / w[0] < 1e4
    np.testing.assert_allclose(a.x[:, 0], [-1.5, 0.7, 1.0, 0.5], atol=0.02)


def test_lower_threshold_warns_earlier(path):
    zs, Hs = _windup(1000)
    first = _first_ill_conditioned_update(cond_max=1e8)
    f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=1, cond_max=1e8)
    with pytest.warns(NumericalWarning, match=rf"> 1e\+08\) at step {first - 1} of batch_filter"):
        f.batch_filter(zs, Hs)


def test_check_can_be_disabled_and_reset_rearms_it(path):
    zs, Hs = _windup(2000)
    f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f.batch_filter(zs, Hs)
    f.check_every = 50
    f.reset()
    assert f.n_updates == 0
    with pytest.warns(NumericalWarning, match=r"at step 699 of batch_filter \(update 700 "):
        f.batch_filter(zs, Hs)
    with warnings.catch_warnings():             # warned once: silent until reset
        warnings.simplefilter("error")
        f.batch_filter(zs, Hs)
    f.reset()
    with pytest.warns(NumericalWarning, match=r"at update 700 since reset"):
        for k in range(700):
            f.predict_update(zs[k], Hs[k])


def test_end_of_batch_check_catches_a_windup_between_periodic_checks(path):
    zs, Hs = _windup(750)
    f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=1000)
    with pytest.warns(NumericalWarning, match=r"ill-conditioned .* at update 750 since reset"):
        f.batch_filter(zs, Hs)


def test_corrupted_factor_is_caught_by_the_cheap_check(path):
    # e.g. a state corrupted by hand: a NaN on the diagonal of the factor
    f = SquareRootRLS(2, check_every=1000)
    f._U[1, 1] = np.nan
    with pytest.warns(NumericalWarning, match=r"`P` has non-finite entries at update 1 since "
                                              r"reset"):
        f.update(1.0, [1.0, 0.0])


def test_bad_health_arguments():
    with pytest.raises(ValueError, match=r"`check_every` must be >= 0; got -1"):
        SquareRootRLS(2, check_every=-1)
    with pytest.raises(ValueError, match=r"`cond_max` must be a positive finite number; got -1.0"):
        SquareRootRLS(2, cond_max=-1.0)
    with pytest.raises(ValueError, match=r"`cond_max` must be a positive finite number; got inf"):
        SquareRootRLS(2, cond_max=np.inf)
