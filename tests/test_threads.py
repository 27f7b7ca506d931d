"""A filter shared by threads applies every call whole (#27 item 6).

Each public call that changes a filter's state holds the filter's lock, so
N threads making M updates each on one filter leave ``n_updates == N M`` and,
with ``lam = 1`` (an estimate that does not depend on the order of the rows,
up to round-off), the batch least-squares estimate of all the rows. The lock
is the filter's own: copies and pickles get a new one.
"""

import copy
import pickle
import sys
import threading

import numpy as np
import pytest
from numpy.testing import assert_allclose

from rlsfilt import RecursiveLeastSquares, SlidingWindowRLS, SquareRootRLS
from rlsfilt.filters.forgetting import MODES

N_THREADS, M_UPDATES, DIM = 4, 300, 3


def _rows(rng):
    Phi = rng.standard_normal((N_THREADS * M_UPDATES, DIM))
    z = Phi @ np.array([0.5, -1.0, 2.0]) + 0.01 * rng.standard_normal(len(Phi))
    return Phi, z


def _hammer(step, Phi, z):
    """`step(z_k, H_k)` from N_THREADS threads, each over its own block of rows."""
    start = threading.Barrier(N_THREADS)
    errors = []

    def work(block):
        start.wait()
        try:
            for k in range(block * M_UPDATES, (block + 1) * M_UPDATES):
                step(z[k], Phi[k])
        except Exception as exc:            # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(b,)) for b in range(N_THREADS)]
    switch = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)             # switch threads as often as possible
    try:
        for t in threads:
            t.start()
        for t in threads:
            t.join()
    finally:
        sys.setswitchinterval(switch)
    assert not errors, errors


def _exact_start(filt, Phi, z):
    filt.initialize(z[:DIM + 2], Phi[:DIM + 2])
    return Phi[DIM + 2:], z[DIM + 2:]


@pytest.mark.parametrize("forgetting", MODES)
def test_shared_filter_loses_no_update(forgetting, rng):
    Phi, z = _rows(rng)
    rls = RecursiveLeastSquares(DIM, lam=0.99, forgetting=forgetting)
    _hammer(rls.predict_update, Phi, z)
    assert rls.n_updates == N_THREADS * M_UPDATES
    assert np.isfinite(rls.x).all()


@pytest.mark.parametrize("make", [lambda: RecursiveLeastSquares(DIM),
                                  lambda: SquareRootRLS(DIM)], ids=["rls", "square_root"])
@pytest.mark.parametrize("pattern", ["predict_update", "predict then update"])
def test_shared_filter_gives_least_squares_of_all_rows(make, pattern, rng):
    Phi, z = _rows(rng)
    filt = make()
    Phi_all, z_all = Phi, z
    Phi, z = _exact_start(filt, Phi, z)

    def two_calls(zk, Hk):       # the pair is not atomic: a predict may land between them
        filt.predict()
        filt.update(zk, Hk)

    step = filt.predict_update if pattern == "predict_update" else two_calls
    _hammer(step, np.vstack([Phi, Phi[:DIM + 2]]), np.concatenate([z, z[:DIM + 2]]))
    assert filt.n_updates == N_THREADS * M_UPDATES
    expected = np.linalg.lstsq(np.vstack([Phi_all, Phi_all[DIM + 2:2 * DIM + 4]]),
                               np.concatenate([z_all, z_all[DIM + 2:2 * DIM + 4]]),
                               rcond=None)[0]
    assert_allclose(filt.x.ravel(), expected, rtol=0, atol=1e-10)


def test_shared_sliding_window_counts_every_update(rng):
    Phi, z = _rows(rng)
    sw = SlidingWindowRLS(DIM, window=50)
    _hammer(sw.update, Phi, z)
    assert sw.n_updates == N_THREADS * M_UPDATES


@pytest.mark.parametrize("make", [lambda: RecursiveLeastSquares(DIM, lam=0.98),
                                  lambda: SquareRootRLS(DIM, lam=0.98),
                                  lambda: SlidingWindowRLS(DIM, window=20)],
                         ids=["rls", "square_root", "sliding_window"])
@pytest.mark.parametrize("duplicate", [copy.copy, copy.deepcopy,
                                       lambda f: pickle.loads(pickle.dumps(f)),
                                       lambda f: f.copy()],
                         ids=["copy", "deepcopy", "pickle", "method"])
def test_copies_have_their_own_lock_and_state(make, duplicate, rng):
    Phi, z = _rows(rng)
    filt = make()
    for k in range(30):
        filt.predict_update(z[k], Phi[k])
    twin = duplicate(filt)
    assert twin._lock is not filt._lock
    with filt._lock:                        # the original held: the copy is not blocked
        twin.predict_update(z[30], Phi[30])
    filt.predict_update(z[30], Phi[30])
    assert_allclose(twin.x, filt.x, rtol=0, atol=0)
    assert twin.n_updates == filt.n_updates == 31


def test_lock_is_reentrant_and_released_after_an_error():
    rls = RecursiveLeastSquares(2)
    with pytest.raises(ValueError):
        rls.update(1.0, H=[1.0, 2.0, 3.0])
    assert rls._lock.acquire(blocking=False)   # released by the failed call
    rls._lock.release()
    with rls._lock:                             # held by the caller: the calls still run
        rls.predict_update(1.0, H=[1.0, 2.0])
    assert rls.n_updates == 1


# ----------------------------------------------------------------------
# the bank and the streaming estimators of the model family
# ----------------------------------------------------------------------
def test_shared_bank_loses_no_update(rng):
    from rlsfilt import RLSBank

    C = 3
    Phi = rng.standard_normal((N_THREADS * M_UPDATES, C, DIM))
    Z = Phi @ np.array([0.5, -1.0, 2.0]) + 0.01 * rng.standard_normal((len(Phi), C))
    bank = RLSBank(C, DIM, lam=0.99)
    _hammer(bank.predict_update, Phi, Z)
    assert bank.n_updates == N_THREADS * M_UPDATES


def _armax_record(rng, N=N_THREADS * M_UPDATES):
    from scipy.signal import lfilter

    u, e = rng.standard_normal(N), 0.1 * rng.standard_normal(N)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1, 0.4], [1, -1.5, 0.7], e)
    return y, u


def test_shared_recursive_model_counts_every_step(rng):
    from rlsfilt import RecursiveARMAX, RecursiveIV

    y, u = _armax_record(rng)
    for model in (RecursiveARMAX(2, 2, 1, 1), RecursiveIV(2, 2, 1)):
        _hammer(lambda yk, uk, m=model: m.step(float(yk), float(uk)), u, y)
        if hasattr(model, "n_steps"):
            assert model.n_steps == N_THREADS * M_UPDATES
        assert np.isfinite(model.theta).all()


@pytest.mark.parametrize("name", ["RecursiveARMAX", "RecursiveOE", "RecursiveBJ",
                                  "RecursiveARX", "RecursiveAR", "RecursiveARMA",
                                  "RecursiveIV", "RecursiveARX-window", "RecursiveOE-window",
                                  "RecursiveAR-nlms"])
def test_copy_copy_of_a_recursive_model_is_independent(name, rng):
    """#27 item 8: copy.copy shared the recursion state, so stepping the copy
    moved the original."""
    import rlsfilt

    make = {"RecursiveARMAX": lambda: rlsfilt.RecursiveARMAX(2, 2, 1, 1),
            "RecursiveOE": lambda: rlsfilt.RecursiveOE(2, 2, 1),
            "RecursiveBJ": lambda: rlsfilt.RecursiveBJ(2, 1, 1, 2, 1),
            "RecursiveARX": lambda: rlsfilt.RecursiveARX(2, 2, 1),
            "RecursiveAR": lambda: rlsfilt.RecursiveAR(2),
            "RecursiveARMA": lambda: rlsfilt.RecursiveARMA(2, 1),
            "RecursiveIV": lambda: rlsfilt.RecursiveIV(2, 2, 1),
            # (#31: the engines of window= and of the gradient methods)
            "RecursiveARX-window": lambda: rlsfilt.RecursiveARX(2, 2, 1, window=30),
            "RecursiveOE-window": lambda: rlsfilt.RecursiveOE(2, 2, 1, window=60),
            "RecursiveAR-nlms": lambda: rlsfilt.RecursiveAR(2, method="nlms", mu=0.2)}[name]
    y, u = _armax_record(rng, 200)
    no_input = name in ("RecursiveAR", "RecursiveARMA", "RecursiveAR-nlms")

    def step(m, k):
        return m.step(float(y[k])) if no_input else m.step(float(y[k]), float(u[k]))

    original, reference = make(), make()
    for k in range(100):
        step(original, k)
        step(reference, k)
    twin = copy.copy(original)
    assert twin._lock is not original._lock
    for k in range(100, 200):                 # the copy runs on alone
        step(twin, k)
    assert_allclose(original.theta, reference.theta, rtol=0, atol=0)
    if not name.endswith("-nlms"):                # (a gradient method has no P)
        assert_allclose(original.P, reference.P, rtol=0, atol=0)
    for k in range(100, 200):                 # and the original, after it, gives the same
        step(reference, k)
        step(original, k)
    assert_allclose(twin.theta, reference.theta, rtol=0, atol=0)
    assert_allclose(original.theta, reference.theta, rtol=0, atol=0)
    again = pickle.loads(pickle.dumps(original))
    assert_allclose(again.theta, original.theta, rtol=0, atol=0)
