"""`RecursiveLeastSquares`'s compiled step on its state vector == its methods, bit for bit.

`_kernels_vector.vector_step` is what the python-control systems run per sample
(`rlsfilt._iosystem`); it must leave exactly the state vector ``predict();
update(z, H)`` leaves, for every forgetting mode (derived from the registry, so
a new mode joins), with and without the gate, constraints, a random walk,
several outputs and missing samples, and decline (a nonzero status) exactly
the steps with something to decide in Python.
"""

import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal
from test_kernels import MODE_LAM

from rlsfilt import RecursiveLeastSquares, SquareRootRLS
from rlsfilt.adaptive import estimator_iosystem
from rlsfilt.filters import _filter_state, _kernels_vector, forgetting
from rlsfilt.filters.contract import vector_step_constants

MODES = list(forgetting.MODES)


def _filter(mode, gate, constrained, Q, dim_z):
    f = RecursiveLeastSquares(4, dim_z, lam=MODE_LAM.get(mode, 0.95), Q=Q, P0=100.0, R=0.5,
                              forgetting=mode, gate=3.0 if gate else None, check_every=25)
    if constrained:
        f.constrain(np.array([[1.0, 1.0, 0.0, 0.0]]), np.array([-0.8]))
    return f


@pytest.mark.parametrize("dim_z", [1, 2])
@pytest.mark.parametrize("Q", [0.0, 1e-4])
@pytest.mark.parametrize("constrained", [False, True])
@pytest.mark.parametrize("gate", [False, True])
@pytest.mark.parametrize("mode", MODES)
def test_vector_step_equals_predict_update(mode, gate, constrained, Q, dim_z):
    rng = np.random.default_rng(zlib.crc32(repr((mode, gate, constrained, Q, dim_z)).encode()))
    f = _filter(mode, gate, constrained, Q, dim_z)
    constants = vector_step_constants(f)
    theta = rng.standard_normal((4, dim_z))
    statuses = []
    for k in range(150):
        H = rng.standard_normal(4) * (0.01 if 60 <= k < 90 else 1.0)    # poor excitation
        z = H @ theta + 0.1 * rng.standard_normal(dim_z)
        if k % 17 == 5:
            z[0] = np.nan                                       # a missing sample
        if gate and k % 23 == 7:
            z += 50.0                                           # an outlier for the gate
        v = _filter_state.get_state(f)
        out = np.full_like(v, np.nan)
        status = _kernels_vector.vector_step(v, z, H, *constants, out)
        f.predict()
        f.update(z if dim_z > 1 else z[0], H)
        statuses.append(status)
        if status == _kernels_vector.PLAIN:
            assert_array_equal(out, _filter_state.get_state(f), err_msg=f"step {k}")
    statuses = np.array(statuses)
    assert statuses[0] == _kernels_vector.NOT_PLAIN             # a new filter: recheck
    assert statuses[24] == _kernels_vector.HEALTH_DUE           # update 25: check_every
    assert (statuses == _kernels_vector.PLAIN).sum() >= 20, statuses     # compared


def test_the_state_layout_is_get_states():
    f = RecursiveLeastSquares(3)
    assert list(f.get_state())[2:] == list(_kernels_vector.SCALARS)


def test_vector_step_declines_what_python_decides():
    """A gated sample, the windup cap's decision, EFRA's start and a state assigned
    since the last step: the status says so, for the filter's methods to take the step."""
    H, z = np.array([1.0, 0.5]), np.array([1.0])
    gated = RecursiveLeastSquares(2, P0=1.0, gate=3.0)
    gated.predict_update(1.0, H)
    v = _filter_state.get_state(gated)
    out = np.empty(len(v))
    assert _kernels_vector.vector_step(v, z, H, *vector_step_constants(gated), out) == 0
    assert _kernels_vector.vector_step(v, z + 1e3, H, *vector_step_constants(gated),
                                       out) == _kernels_vector.FLAGGED
    capped = RecursiveLeastSquares(2, lam=0.5, P0=1.0, forgetting_params=dict(trace_max=3.0))
    capped.predict_update(1.0, [1.0, 0.0])          # trace(P) / lam would pass 3: held back
    v = _filter_state.get_state(capped)
    assert v[2 + 4 + _kernels_vector.SCALARS.index("cap")] == 1.0
    assert _kernels_vector.vector_step(v, z, H, *vector_step_constants(capped),
                                       out) == _kernels_vector.NOT_PLAIN
    gated.x = np.array([[0.5], [0.5]])      # an assigned estimate is checked first
    v = _filter_state.get_state(gated)
    assert _kernels_vector.vector_step(v, z, H, *vector_step_constants(gated),
                                       out) == _kernels_vector.NOT_PLAIN
    efra = RecursiveLeastSquares(2, forgetting="efra")
    v = _filter_state.get_state(efra)
    v[-1] = 0.0                             # (recheck off: EFRA's pending start alone)
    assert _kernels_vector.vector_step(v, z, H, *vector_step_constants(efra),
                                       out) == _kernels_vector.NOT_PLAIN


def test_only_a_plain_filter_has_vector_step_constants():
    f = RecursiveLeastSquares(2, lam=0.9, Q=1e-3, R=2.0)
    il, Q, cfg, R, every = vector_step_constants(f)
    assert (il, R, every) == (1 / 0.9, 2.0, f.check_every)
    assert_array_equal(Q, f.Q)
    Q[0, 0] = 5.0                           # copies
    assert f.Q[0, 0] == 1e-3
    f.freeze()
    assert vector_step_constants(f) is None

    class Mine(RecursiveLeastSquares):
        pass

    assert vector_step_constants(Mine(2)) is None
    assert vector_step_constants(SquareRootRLS(2)) is None
    assert vector_step_constants(object()) is None


# ----------------------------------------------------------------------
# the estimator system's compiled sample
# ----------------------------------------------------------------------
@pytest.fixture
def estimator_statuses(monkeypatch):
    """The statuses `_kernels_vector.estimator_sample` returned, in order."""
    seen = []
    sample = _kernels_vector.estimator_sample

    def counting(*args):
        seen.append(sample(*args))
        return seen[-1]

    monkeypatch.setattr(_kernels_vector, "estimator_sample", counting)
    return seen


@settings(max_examples=40, deadline=None)
@given(mode=st.sampled_from(MODES), orders=st.sampled_from([(2, 2, 1), (1, 2, 0), (0, 2, 3),
                                                           (2, 1, 2), None]),
       dim_z=st.integers(1, 2), gate=st.booleans(), seed=st.integers(0, 2**16))
def test_estimator_system_equals_the_filter_bit_for_bit(mode, orders, dim_z, gate, seed):
    """The system's outputs and states, in python-control's call pattern (outputs on the
    zero loop signal, twice on the settled inputs, the update), equal the filter's
    ``predict(); update(z, H)`` loop bit for bit, missing samples and outliers included."""
    rng = np.random.default_rng(seed)
    n = 4 if orders is None else orders[0] + orders[1]
    m = dim_z if orders is None else 1
    f = RecursiveLeastSquares(n, m, lam=np.linspace(0.95, 0.99, n) if mode == "diagonal"
                              else 0.95, P0=10.0, forgetting=mode, gate=3.0 if gate else None,
                              check_every=30)
    sys = estimator_iosystem(f, regressor="direct" if orders is None else orders)
    ref = f.copy()
    x = np.zeros(sys.nstates)
    ypast, upast = [0.0] * 8, [0.0] * 8
    for k in range(80):
        u = rng.standard_normal()
        if orders is None:
            H = rng.standard_normal(n)
            z = H @ rng.standard_normal((n, m)) + 0.1 * rng.standard_normal(m)
            if k % 13 == 4:
                z[-1] = np.nan
            w = np.r_[z, H]
        else:
            na, nb, nk = orders
            y = 0.8 * ypast[0] + upast[0] + 0.1 * rng.standard_normal()
            y += 40.0 if gate and k % 19 == 9 else 0.0
            u_all = [u] + upast
            H = np.array([-v for v in ypast[:na]] + u_all[nk:nk + nb])
            z = np.array([y])
            w = np.array([u, y])
            ypast, upast = [y] + ypast[:-1], [u] + upast[:-1]
        zero = w.copy()
        zero[-n - m if orders is None else 1] = 0.0
        sys.outfcn(k, x, zero, {})
        got = sys.outfcn(k, x, w, {})
        assert_array_equal(sys.outfcn(k, x, w, {}), got)
        x = sys.updfcn(k, x, w, {})
        prior = ref.x.copy()
        ref.predict()
        ref.update(z if m > 1 else z[0], H)
        e = z - H @ prior
        assert_array_equal(got[:n * m], ref.x.ravel())
        np.testing.assert_allclose(got[n * m:], e, rtol=0, atol=1e-12)
        assert_array_equal(x[:len(_filter_state.get_state(ref))], _filter_state.get_state(ref))


def test_the_estimator_system_takes_its_samples_in_one_compiled_call(estimator_statuses):
    f = RecursiveLeastSquares(4, lam=0.98, P0=100.0)
    sys = estimator_iosystem(f, regressor=(2, 2, 1))
    x = np.zeros(sys.nstates)
    rng = np.random.default_rng(0)
    for k in range(300):
        w = rng.standard_normal(2)
        sys.outfcn(k, x, w, {})
        x = sys.updfcn(k, x, w, {})
    statuses = np.array(estimator_statuses)
    assert len(statuses) == 300                          # the update reuses the outputs' call
    assert statuses[0] == _kernels_vector.NOT_PLAIN      # a new filter's checked start
    assert statuses[249] == _kernels_vector.HEALTH_DUE   # check_every = 250
    assert (statuses == _kernels_vector.PLAIN).sum() == 298
