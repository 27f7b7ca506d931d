"""Health of P in SquareRootRLS and SlidingWindowRLS: windup (or a window that stops
exciting a direction) warns once, with the step, in batch_filter, with a Saver and when
streaming alike; a benign run stays quiet."""

import re
import warnings

import numpy as np
import pytest
from conftest import arx_record

from rlsfilt import NumericalWarning, SlidingWindowRLS, SquareRootRLS

LAM, P0 = 0.98, 1e4


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


def test_windup_warns_once_with_the_update():
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


def test_windup_batch_filter_names_the_step():
    zs, Hs = _windup(2000)
    first = _first_ill_conditioned_update()
    f = SquareRootRLS(2, lam=LAM, P0=P0)
    every = f.check_every                        # the default, max(250, 32 dim_x)
    assert every == 250
    detected = -(-first // every) * every        # the next multiple of check_every
    k0 = first - 9                               # it happens in the second call
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
def test_every_path_names_the_oracle_update(how, update_first):
    zs, Hs = _windup(1000)
    messages = []
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
    first = _first_ill_conditioned_update()
    detected = -(-first // 7) * 7
    where = (f"at update {detected} since reset" if how == "streaming"
             else f"at step {detected - 1} of batch_filter (update {detected} since reset)")
    assert where in messages[0]


class _NullSaver:
    def save(self):
        pass


def test_benign_run_does_not_warn():
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


def test_lower_threshold_warns_earlier():
    zs, Hs = _windup(1000)
    first = _first_ill_conditioned_update(cond_max=1e8)
    f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=1, cond_max=1e8)
    with pytest.warns(NumericalWarning, match=rf"> 1e\+08\) at step {first - 1} of batch_filter"):
        f.batch_filter(zs, Hs)


def test_check_can_be_disabled_and_reset_rearms_it():
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


def test_end_of_batch_check_catches_a_windup_between_periodic_checks():
    zs, Hs = _windup(750)
    f = SquareRootRLS(2, lam=LAM, P0=P0, check_every=1000)
    with pytest.warns(NumericalWarning, match=r"ill-conditioned .* at update 750 since reset"):
        f.batch_filter(zs, Hs)


def test_corrupted_factor_is_caught_by_the_cheap_check():
    # e.g. a state corrupted by hand: a NaN on the diagonal of the factor
    f = SquareRootRLS(2, check_every=1000)
    f._delta[1] = np.nan
    with pytest.warns(NumericalWarning, match=r"`P` has non-finite entries at update 1 since "
                                              r"reset"):
        f.update(1.0, [1.0, 0.0])


@pytest.mark.parametrize("make", [lambda **kw: SquareRootRLS(2, **kw),
                                  lambda **kw: SlidingWindowRLS(2, 10, **kw)],
                         ids=["square_root", "sliding_window"])
def test_bad_health_arguments(make):
    with pytest.raises(ValueError, match=r"`check_every` must be >= 0; got -1"):
        make(check_every=-1)
    with pytest.raises(ValueError, match=r"`cond_max` must be a positive finite number; got -1.0"):
        make(cond_max=-1.0)
    with pytest.raises(ValueError, match=r"`cond_max` must be a positive finite number; got inf"):
        make(cond_max=np.inf)


# ----------------------------------------------------------------------
# SlidingWindowRLS: a window whose rows stop exciting a direction
# ----------------------------------------------------------------------
WINDOW, N_EXCITING = 50, 137


def _collinear_record(n=400):
    """Random rows, then rows [1, 1 + 1e-7 e]: nearly collinear once the
    exciting rows have left the window."""
    rng = np.random.default_rng(3)
    Hs = np.tile([1.0, 1.0], (n, 1))
    Hs[:N_EXCITING] = rng.standard_normal((N_EXCITING, 2))
    Hs[N_EXCITING:, 1] += 1e-7 * rng.standard_normal(n - N_EXCITING)
    zs = Hs @ [0.5, -0.3] + 0.01 * rng.standard_normal(n)
    return zs, Hs


def _first_ill_conditioned_window(Hs, cond_max=1e12):
    """First update count at which the window's cond(P) = cond(H_window)^2
    exceeds `cond_max` (SVD of the stored rows: the filter is exact by then)."""
    for k in range(WINDOW - 1, len(Hs)):
        if np.linalg.cond(Hs[k + 1 - WINDOW:k + 1]) ** 2 > cond_max:
            return k + 1
    raise AssertionError("no ill-conditioning")


def test_sliding_window_oracle_step():
    zs, Hs = _collinear_record()
    assert _first_ill_conditioned_window(Hs) == N_EXCITING + WINDOW   # the last random row left


def test_sliding_window_warns_once_with_the_update():
    zs, Hs = _collinear_record()
    first = _first_ill_conditioned_window(Hs)
    f = SlidingWindowRLS(2, WINDOW, check_every=1)
    with pytest.warns(NumericalWarning) as record:
        for k in range(len(zs)):
            f.predict_update(zs[k], Hs[k])
    assert len(record) == 1
    msg = str(record[0].message)
    assert "ill-conditioned" in msg and f"at update {first} since reset." in msg, msg
    assert f.n_updates == len(zs)


def test_sliding_window_batch_filter_names_the_step():
    zs, Hs = _collinear_record()
    first = _first_ill_conditioned_window(Hs)
    f = SlidingWindowRLS(2, WINDOW)
    every = f.check_every                        # the default, max(250, 32 dim_x)
    detected = -(-first // every) * every
    k0 = 120
    with pytest.warns(NumericalWarning) as record:
        f.batch_filter(zs[:k0], Hs[:k0])
        f.batch_filter(zs[k0:], Hs[k0:])
        f.batch_filter(zs[k0:], Hs[k0:])         # warned already: silent
    assert len(record) == 1
    assert (f"at step {detected - k0 - 1} of batch_filter (update {detected} since reset)"
            in str(record[0].message))
    assert record[0].filename == __file__


@pytest.mark.parametrize("how", ["batch", "saver", "streaming"])
def test_sliding_window_every_path_names_the_oracle_update(how):
    zs, Hs = _collinear_record()
    messages = []
    f = SlidingWindowRLS(2, WINDOW, check_every=9)
    with pytest.warns(NumericalWarning) as record:
        if how == "streaming":
            for k in range(len(zs)):
                f.update(zs[k], Hs[k])
        else:
            f.batch_filter(zs, Hs, saver=_NullSaver() if how == "saver" else None)
    assert len(record) == 1
    messages.append(str(record[0].message))
    assert "ill-conditioned" in messages[0]
    detected = -(-_first_ill_conditioned_window(Hs) // 9) * 9
    assert f"update {detected} since reset" in messages[0]


def test_sliding_window_benign_run_does_not_warn():
    rng = np.random.default_rng(8)
    Hs, zs = arx_record(rng, n_samples=3002, noise_std=0.05)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        a = SlidingWindowRLS(4, 40, R=0.05**2, check_every=1)
        a.batch_filter(zs, Hs)
        b = SlidingWindowRLS(4, 40, R=0.05**2, check_every=1)
        for k in range(500):
            b.update(zs[k], Hs[k])
    assert a.n_updates == 3000 and b.n_updates == 500


def test_sliding_window_check_can_be_disabled_and_reset_rearms_it():
    zs, Hs = _collinear_record()
    f = SlidingWindowRLS(2, WINDOW, check_every=0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        f.batch_filter(zs, Hs)
    f.check_every = 1
    f.reset()
    assert f.n_updates == 0
    with pytest.warns(NumericalWarning, match=rf"update {N_EXCITING + WINDOW} since reset"):
        f.batch_filter(zs, Hs)


def test_sliding_window_indefinite_P_is_caught_by_the_cheap_check():
    f = SlidingWindowRLS(2, 10, check_every=1000)
    f.P = np.array([[1.0, 0.0], [0.0, -1e-3]])      # e.g. a corrupted state
    with pytest.warns(NumericalWarning, match=r"`P` is not positive definite \(smallest "
                                              r"eigenvalue -0.001\) at update 1 since reset"):
        f.update(1.0, [1.0, 0.0])


def test_compiled_factor_decision_equals_factor_problem():
    """The square root's compiled check (trace bound, then singular values) decides as
    ``_health.factor_problem`` (the NumPy SVD) does."""
    from rlsfilt.filters import _health, _kernels_shared

    rng = np.random.default_rng(9)
    decided = {True: 0, False: 0}
    for _ in range(1500):
        n = int(rng.integers(1, 8))
        Qo, _ = np.linalg.qr(rng.standard_normal((n, n)))
        w = 10.0 ** rng.uniform(-7, 2, n)
        U = np.linalg.qr((Qo * w) @ Qo.T)[1]
        U *= np.sign(np.diagonal(U))[:, None]             # a positive diagonal
        if rng.random() < 0.05:
            U[-1, -1] = -abs(U[-1, -1])
        cond_max = 10.0 ** rng.uniform(2, 13)
        expected = _health.factor_problem(U, cond_max) is not None
        assert _kernels_shared.factor_unhealthy(U, cond_max) == expected
        decided[expected] += 1
    assert min(decided.values()) > 200
