"""The deferred ``predict()`` of `RecursiveLeastSquares` (issue #12, streaming target).

``predict()`` records its time update and the next ``update()`` runs it in the
same compiled call; anything that reads or replaces the state first
(``P``, ``x_prior``, ``P_prior``, an assignment, ``batch_filter``, a copy,
``get_state``) sees exactly what an eager ``predict()`` leaves. The oracle is
the eager path itself: a filter that reads ``P`` right after every
``predict()`` runs the time update at once (``predict_kernel``, as before the
deferral), and every filterpy attribute of the two filters must be equal bit
for bit, after every call, for every forgetting mode, ``Q``, the gate, the
constraints, several outputs, missing samples and the windup cap. The
textbook reference (``_reference``) holds for the time update itself.
"""

import copy
import pickle
import warnings

import _reference as ref
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import ForgettingSkippedWarning, RecursiveLeastSquares
from rlsfilt.filters import _filter_state

STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H")
COUNTERS = ("n_updates", "n_gated", "n_capped", "gated", "lam_t")
N = 80


def _constrained(**kw):
    return RecursiveLeastSquares(4, lam=0.97, Q=1e-6, **kw).constrain([1.0, 0.0, 1.0, 0.0], 0.5)


CONFIGS = {
    "exponential": lambda: RecursiveLeastSquares(4, lam=0.95),
    "lam1": lambda: RecursiveLeastSquares(4),
    "Q": lambda: RecursiveLeastSquares(4, lam=0.98, Q=1e-4),
    "directional-gate": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="directional",
                                                      gate=3.0),
    "constant_trace": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="constant_trace"),
    "efra": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="efra"),
    "variable": lambda: RecursiveLeastSquares(4, lam=0.95, forgetting="variable"),
    "two-outputs": lambda: RecursiveLeastSquares(4, dim_z=2, lam=0.97),
    "constrained": _constrained,
    "windup-cap": lambda: RecursiveLeastSquares(4, lam=0.9, P0=1.0,
                                                forgetting_params={"spread_max": 10.0}),
}


def _record(rng, dim_z=1):
    """Regressors with a held stretch (the windup cap acts there), an outlier and
    missing samples."""
    Hs = rng.standard_normal((N, 4))
    Hs[30:50] = Hs[29]
    zs = Hs @ rng.standard_normal((4, dim_z)) + 0.05 * rng.standard_normal((N, dim_z))
    zs[60] += 50.0
    zs[[10, 45]] = np.nan
    return Hs, (zs[:, 0] if dim_z == 1 else zs)


def _z(zs, k):
    return float(zs[k]) if np.ndim(zs) == 1 else zs[k]


def _same(a, b, names=STATE):
    for name in names:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    for name in COUNTERS:
        assert getattr(a, name) == getattr(b, name), name


def _eager_predict(f, **kw):
    """``predict()`` whose time update runs at once (reading ``P`` runs it)."""
    f.predict(**kw)
    _ = f.P                                    # reading P runs the pending time update
    assert f._pending is None


@pytest.fixture(params=sorted(CONFIGS))
def config(request):
    return request.param


def test_deferred_steps_equal_eager_steps_bit_for_bit(config, rng):
    make = CONFIGS[config]
    Hs, zs = _record(rng, dim_z=make().dim_z)
    lazy, eager = make(), make()
    for k in range(N):
        lazy.predict()
        assert lazy._pending is not None or k == 0   # the first predict checks the state
        _eager_predict(eager)
        lazy.update(_z(zs, k), Hs[k])
        eager.update(_z(zs, k), Hs[k])
        _same(lazy, eager)
        assert lazy.log_likelihood == eager.log_likelihood or (
            np.isnan(lazy.mahalanobis) and np.isnan(eager.mahalanobis))
    if config == "windup-cap":
        assert lazy.n_capped > 0                       # the held-back forgetting was deferred
    if config == "directional-gate":
        assert lazy.n_gated > 0


def test_attributes_read_after_predict_are_the_eager_ones(config, rng):
    """``P``, ``x_prior``, ``P_prior`` (and everything else) right after ``predict()``."""
    make = CONFIGS[config]
    Hs, zs = _record(rng, dim_z=make().dim_z)
    lazy, eager = make(), make()
    for k in range(N):
        lazy.predict()
        _eager_predict(eager)
        if k % 3 == 0:                                 # sometimes read, sometimes not
            order = STATE[::-1] if k % 2 else STATE
            for name in order:
                assert_array_equal(getattr(lazy, name), getattr(eager, name), err_msg=name)
        lazy.update(_z(zs, k), Hs[k])
        eager.update(_z(zs, k), Hs[k])
    _same(lazy, eager)


def test_the_deferred_time_update_is_the_textbook_one(rng):
    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, lam=0.95, Q=1e-3)
    for k in range(20):
        f.predict_update(zs[k], Hs[k])
    P, x = f.P.copy(), f.x.copy()
    f.predict()
    assert f._pending is not None
    assert_allclose(f.P, ref.rls_predict(P, 0.95, f.Q), rtol=1e-14)
    assert_array_equal(f.x_prior, x)
    assert_array_equal(f.P_prior, f.P)
    assert f.P_prior is not f.P and f.x_prior is not f.x


def test_predict_twice(config, rng):
    make = CONFIGS[config]
    Hs, zs = _record(rng, dim_z=make().dim_z)
    lazy, eager = make(), make()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForgettingSkippedWarning)
        for k in range(N):
            for _ in range(1 + k % 3):                 # one, two or three predicts
                lazy.predict()
                _eager_predict(eager)
            lazy.update(_z(zs, k), Hs[k])
            eager.update(_z(zs, k), Hs[k])
            _same(lazy, eager)


def test_predict_with_a_random_walk_of_its_own(rng):
    Hs, zs = _record(rng)
    lazy, eager = RecursiveLeastSquares(4, lam=0.97), RecursiveLeastSquares(4, lam=0.97)
    for k in range(N):
        Q = 1e-4 * (k % 3) * np.eye(4)                 # zero too: the kernels take no Q then
        lazy.predict(Q=Q)
        _eager_predict(eager, Q=Q)
        lazy.update(zs[k], Hs[k])
        eager.update(zs[k], Hs[k])
        _same(lazy, eager)


@pytest.mark.parametrize("update_first", [False, True])
def test_predict_then_batch_filter(config, rng, update_first):
    make = CONFIGS[config]
    Hs, zs = _record(rng, dim_z=make().dim_z)
    lazy, eager = make(), make()
    for k in range(20):
        lazy.predict_update(_z(zs, k), Hs[k])
        eager.predict_update(_z(zs, k), Hs[k])
    lazy.predict()
    _eager_predict(eager)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ForgettingSkippedWarning)
        a = lazy.batch_filter(zs[20:], Hs[20:], update_first=update_first)
        b = eager.batch_filter(zs[20:], Hs[20:], update_first=update_first)
    for u, v in zip(a, b, strict=True):
        assert_array_equal(u, v)
    _same(lazy, eager)


@pytest.mark.parametrize("copier", [copy.copy, copy.deepcopy,
                                    lambda f: pickle.loads(pickle.dumps(f)),
                                    lambda f: f.copy()],
                         ids=["copy", "deepcopy", "pickle", "method"])
def test_copies_carry_the_deferred_predict(config, rng, copier):
    make = CONFIGS[config]
    Hs, zs = _record(rng, dim_z=make().dim_z)
    f, eager = make(), make()
    for k in range(30):
        f.predict_update(_z(zs, k), Hs[k])
        eager.predict_update(_z(zs, k), Hs[k])
    f.predict()
    _eager_predict(eager)
    assert f._pending is not None
    g = copier(f)
    assert g._pending is not None
    for other in (f, g):                               # interleaved: shared arrays would show
        other.update(_z(zs, 30), Hs[30])
    eager.update(_z(zs, 30), Hs[30])
    _same(f, eager)
    _same(g, eager)
    for k in range(31, N):
        for other in (f, g, eager):
            other.predict()
            other.update(_z(zs, k), Hs[k])
    _same(f, g)
    _same(f, eager)


def test_a_copy_made_after_predict_reads_the_eager_prior(rng):
    Hs, zs = _record(rng)
    f, eager = RecursiveLeastSquares(4, lam=0.9), RecursiveLeastSquares(4, lam=0.9)
    for k in range(10):
        f.predict_update(zs[k], Hs[k])
        eager.predict_update(zs[k], Hs[k])
    f.predict()
    _eager_predict(eager)
    g = pickle.loads(pickle.dumps(f))
    _same(g, eager)                                    # g runs its deferred predict on reading
    assert f._pending is not None                      # pickling changed nothing in f
    _same(f, eager)


@pytest.mark.parametrize("what", ["P", "x", "x_prior", "P_prior"])
def test_assignment_after_predict(rng, what):
    """An assignment after ``predict()`` keeps the predict's priors, as an eager predict
    does, and the next update starts from the assigned value."""
    Hs, zs = _record(rng)
    lazy, eager = RecursiveLeastSquares(4, lam=0.95), RecursiveLeastSquares(4, lam=0.95)
    for k in range(20):
        lazy.predict_update(zs[k], Hs[k])
        eager.predict_update(zs[k], Hs[k])
    value = {"P": 3.0 * np.eye(4), "x": np.ones((4, 1)), "x_prior": np.zeros((4, 1)),
             "P_prior": np.eye(4)}[what]
    lazy.predict()
    _eager_predict(eager)
    setattr(lazy, what, value)
    setattr(eager, what, value)
    _same(lazy, eager)
    for k in range(20, N):
        lazy.predict()
        eager.predict()
        lazy.update(zs[k], Hs[k])
        eager.update(zs[k], Hs[k])
        _same(lazy, eager)


def test_a_failed_update_leaves_the_predict_deferred(rng):
    Hs, zs = _record(rng)
    f, eager = RecursiveLeastSquares(4, lam=0.95), RecursiveLeastSquares(4, lam=0.95)
    for k in range(10):
        f.predict_update(zs[k], Hs[k])
        eager.predict_update(zs[k], Hs[k])
    f.predict()
    _eager_predict(eager)
    before = pickle.dumps(f)
    bad = Hs[10].copy()
    bad[2] = np.nan
    for call in (lambda: f.update(1.0, bad), lambda: f.update(np.inf, Hs[10]),
                 lambda: f.update(1.0, Hs[10], R=-1.0), lambda: f.update(1.0, Hs[10][:3])):
        with pytest.raises(ValueError):
            call()
        assert pickle.dumps(f) == before
    assert f._pending is not None
    f.update(zs[10], Hs[10])
    eager.update(zs[10], Hs[10])
    _same(f, eager)


def test_reading_without_changing_the_deferred_state(rng):
    """``get_prediction``, ``log_likelihood_of``, ``residual_of`` and ``repr`` see the
    predicted state (as after an eager predict); only ``repr`` reads ``P`` itself."""
    Hs, zs = _record(rng)
    f, eager = RecursiveLeastSquares(4, lam=0.9), RecursiveLeastSquares(4, lam=0.9)
    for k in range(10):
        f.predict_update(zs[k], Hs[k])
        eager.predict_update(zs[k], Hs[k])
    f.predict()
    _eager_predict(eager)
    before = pickle.dumps(f)
    for u, v in zip(f.get_prediction(), eager.get_prediction(), strict=True):
        assert_array_equal(u, v)
    assert f.log_likelihood_of(zs[11], Hs[11]) == eager.log_likelihood_of(zs[11], Hs[11])
    assert_array_equal(f.residual_of(zs[11], Hs[11]), eager.residual_of(zs[11], Hs[11]))
    assert pickle.dumps(f) == before
    assert repr(f) == repr(eager)


def test_flat_state_of_a_filter_with_a_deferred_predict(rng):
    """The adaptive systems' flat state (``get_state``/``set_state``) of a filter
    between ``predict()`` and ``update()``: the predicted ``P``, and a filter
    restored from it continues bit for bit."""
    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, lam=0.9, P0=1.0, forgetting_params={"spread_max": 10.0})
    eager = RecursiveLeastSquares(4, lam=0.9, P0=1.0, forgetting_params={"spread_max": 10.0})
    for k in range(40):                                # into the held stretch: the cap acts
        f.predict_update(zs[k], Hs[k])
        eager.predict_update(zs[k], Hs[k])
    f.predict()
    _eager_predict(eager)
    state = _filter_state.get_state(f)
    assert_array_equal(state, _filter_state.get_state(eager))
    g = RecursiveLeastSquares(4, lam=0.9, P0=1.0, forgetting_params={"spread_max": 10.0})
    _filter_state.set_state(g, state)
    for k in range(40, N):
        for other in (f, g):
            other.update(zs[k], Hs[k])
            other.predict()
    assert_array_equal(f.x, g.x)
    assert_array_equal(f.P, g.P)


def test_strided_and_read_only_rows_take_the_fast_path(rng):
    """A row of any layout, or a read-only one, goes to the kernel as it is and gives
    the bits of a contiguous copy."""
    Hs, zs = _record(rng)
    columns = np.asfortranarray(Hs)                    # its rows are strided in memory
    frozen = Hs.copy()
    frozen.setflags(write=False)
    a, b, c = (RecursiveLeastSquares(4, lam=0.95) for _ in range(3))
    for k in range(N):
        for f, row in ((a, Hs[k].copy()), (b, columns[k]), (c, frozen[k])):
            f.predict()
            f.update(zs[k], row)
    assert not columns[0].flags.c_contiguous and not frozen[0].flags.writeable
    _same(a, b)
    _same(a, c)
    assert_array_equal(frozen, Hs)


def test_updates_without_predict_never_recycle_the_priors(rng):
    """After an update that ran a deferred predict, ``x_prior`` and ``P_prior`` live in
    that update's arrays; updates without a predict must not recycle them."""
    Hs, zs = _record(rng)
    lazy, eager = RecursiveLeastSquares(4), RecursiveLeastSquares(4)  # lam = 1: no warning
    for k in range(N):
        if k % 4 == 0:
            lazy.predict()
            _eager_predict(eager)
        lazy.update(zs[k], Hs[k])
        eager.update(zs[k], Hs[k])
        if k % 4 == 3:
            _same(lazy, eager)
    _same(lazy, eager)


def test_held_diagnostics_are_never_overwritten(rng):
    """Every diagnostic read after a step keeps its values while the filter runs on."""
    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, lam=0.95)
    kept = []
    for k in range(N):
        f.predict()
        f.update(zs[k], Hs[k])
        if k % 5 == 0:
            name = STATE[(k // 5) % len(STATE)]
            value = getattr(f, name)
            kept.append((name, value, value.copy()))
    for name, value, snapshot in kept:
        assert_array_equal(value, snapshot, err_msg=name)


def test_a_failing_step_never_writes_the_priors_the_filter_holds(rng):
    """An update without predict leaves ``x_prior``, ``P_prior`` in the arrays of the
    update before; the next deferred step, whose health warning is turned into an
    error, must not have recycled those arrays (the filter is left as it was)."""
    from rlsfilt import NumericalWarning

    Hs, zs = _record(rng)
    f = RecursiveLeastSquares(4, check_every=4, cond_max=1.0 + 1e-9)   # lam = 1: no skip
    f.predict()
    f.update(zs[0], Hs[0])                    # the first predict checks the state at once
    f.predict()
    f.update(zs[1], Hs[1])                    # deferred: the priors in this step's arrays
    f.update(zs[2], Hs[2])                    # no predict: those arrays become the spare
    f.predict()
    before = pickle.dumps(f)
    with warnings.catch_warnings():
        warnings.simplefilter("error", NumericalWarning)
        with pytest.raises(NumericalWarning):
            f.update(zs[3], Hs[3])            # update 4: the periodic check fails
    assert f._pending is not None
    assert pickle.dumps(f) == before
