"""The STR and the filters as python-control systems: interconnect == the step loop."""

import copy
import warnings

import control
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import RecursiveLeastSquares, SlidingWindowRLS, SquareRootRLS
from rlsfilt.adaptive import SelfTuningRegulator, estimator_iosystem
from rlsfilt.filters import _filter_state

A = np.array([1.0, -1.5, 0.7])
B = np.array([0.0, 1.0, 0.5])
DESIGN = dict(Am=np.poly([0.5, 0.6]), Ao=np.poly([0.2, 0.3]))
FILTERS = {
    "RecursiveLeastSquares": lambda n: RecursiveLeastSquares(n, lam=0.98, P0=100.0),
    "SquareRootRLS": lambda n: SquareRootRLS(n, lam=0.98, P0=100.0),
    "SlidingWindowRLS": lambda n: SlidingWindowRLS(n, window=60, P0=100.0),
}


def _signals(N, seed=0):
    rng = np.random.default_rng(seed)
    r = np.where(np.arange(N) % 80 < 40, 1.0, -1.0)
    return r, 0.1 * rng.choice([-1.0, 1.0], N)


@pytest.mark.parametrize("name", FILTERS)
def test_str_inside_interconnect_equals_its_own_step_loop(name):
    N = 200
    stre = SelfTuningRegulator(FILTERS[name](4), DESIGN, na=2, nb=2, monitor_every=50)
    plant = control.ss(control.tf(B, A, True), inputs="u", outputs="y", name="plant")
    r, d = _signals(N)
    # the step loop, with the plant stepped by python-control's own functions
    ref = copy.deepcopy(stre)
    x = np.zeros(plant.nstates)
    y_ref, u_ref = np.zeros(N), np.zeros(N)
    for k in range(N):
        y_ref[k] = plant.output(k, x, [0.0])[0]
        u_ref[k] = ref.step(y_ref[k], r[k], d[k])
        x = plant.dynamics(k, x, [u_ref[k]])
    before = stre.state
    loop = control.interconnect([plant, stre.as_iosystem(extra_outputs=True)],
                                inputs=["r", "dither"], outputs=["y", "u", "e", "theta[0]",
                                                                 "theta[1]", "theta[2]",
                                                                 "theta[3]"])
    resp = control.input_output_response(loop, np.arange(N), [r, d], return_states=True)
    assert_allclose(resp.outputs[0], y_ref, rtol=0, atol=1e-12)
    assert_allclose(resp.outputs[1], u_ref, rtol=0, atol=1e-12)
    h = ref.history
    assert_allclose(resp.outputs[2], h.e, rtol=0, atol=1e-12)
    assert_allclose(resp.outputs[3:].T, h.theta, rtol=0, atol=1e-12)
    # the state after the last sample is the regulator's state after its last step
    last = control.input_output_response(loop, np.arange(N + 1), [np.r_[r, 0.0], np.r_[d, 0.0]],
                                         return_states=True).states[plant.nstates:, -1]
    assert_allclose(last, ref.state, rtol=1e-12, atol=1e-12)
    # an explicit initial state gives the same run; the regulator itself is untouched
    again = control.input_output_response(loop, np.arange(N), [r, d],
                                          X0=[np.zeros(plant.nstates), before])
    assert_array_equal(again.outputs, resp.outputs)
    assert_array_equal(stre.state, before)
    assert len(stre.history) == 0


def test_str_system_signals_and_states():
    stre = SelfTuningRegulator(RecursiveLeastSquares(4), DESIGN, na=2, nb=2, dt=0.1)
    sys = stre.as_iosystem()
    assert sys.input_labels == ["y", "r", "dither"] and sys.output_labels == ["u"]
    assert sys.dt == 0.1 and sys.nstates == len(stre.state)
    assert sys.state_labels[:2] == ["est.x[0,0]", "est.x[1,0]"]
    assert "info[3,3]" in sys.state_labels


def test_a_filter_restored_from_its_state_continues_bit_for_bit():
    rng = np.random.default_rng(4)
    for make in FILTERS.values():
        f = make(3)
        Hs, zs = rng.standard_normal((90, 3)), rng.standard_normal(90)
        for k in range(70):
            f.predict_update(zs[k], Hs[k])
        g = make(3)
        _filter_state.set_state(g, _filter_state.get_state(f))
        for k in range(70, 90):
            f.predict_update(zs[k], Hs[k])
            g.predict_update(zs[k], Hs[k])
        assert_array_equal(g.x, f.x)
        assert_array_equal(g.P, f.P)
        assert_array_equal(_filter_state.get_state(g), _filter_state.get_state(f))


def test_the_layout_packs_as_get_state_and_snapshots_stay_valid():
    # what the python-control systems use at every sample instead of get_state/set_state
    from rlsfilt.filters.contract import restore_filter, snapshot_filter

    rng = np.random.default_rng(5)
    Hs, zs = rng.standard_normal((150, 3)), rng.standard_normal(150)
    for make in FILTERS.values():
        f = make(3)
        layout = _filter_state.StateLayout(f)
        for k in range(70):
            f.predict_update(zs[k], Hs[k])
        vec = layout.pack(f, np.empty(layout.size))
        assert_array_equal(vec, _filter_state.get_state(f))
        g = make(3)
        layout.unpack(g, vec)
        assert_array_equal(_filter_state.get_state(g), vec)
        snap = snapshot_filter(f)
        for _ in range(2):          # the snapshot survives the steps after its restore
            for k in range(70, 150):        # past the window: the ring buffer is rewritten
                f.predict_update(zs[k], Hs[k])
            restore_filter(f, snap)
            assert_array_equal(_filter_state.get_state(f), vec)


@pytest.mark.parametrize("name", FILTERS)
def test_estimator_system_equals_batch_filter(name):
    rng = np.random.default_rng(1)
    N, n = 150, 3
    Hs, zs = rng.standard_normal((N, n)), rng.standard_normal(N)
    f = FILTERS[name](n)
    saved = _filter_state.get_state(f)
    sys = estimator_iosystem(f)
    assert sys.input_labels == ["z", "phi[0]", "phi[1]", "phi[2]"]
    assert sys.output_labels == ["theta[0]", "theta[1]", "theta[2]", "e"]
    resp = control.input_output_response(sys, np.arange(N), np.vstack([zs, Hs.T]))
    ref = FILTERS[name](n)
    means = np.empty((N, n))
    errors = np.empty(N)
    for k in range(N):
        errors[k] = zs[k] - Hs[k] @ ref.x[:, 0]
        ref.predict_update(zs[k], Hs[k])
        means[k] = ref.x[:, 0]
    assert_allclose(resp.outputs[:n].T, means, rtol=0, atol=1e-12)
    assert_allclose(resp.outputs[n], errors, rtol=0, atol=1e-12)
    batch = FILTERS[name](n).batch_filter(zs, Hs)[0][:, :, 0]
    assert_allclose(resp.outputs[:n].T, batch, rtol=0, atol=1e-10)
    assert_array_equal(_filter_state.get_state(f), saved)      # the filter is untouched


def test_arx_estimator_beside_a_plant_is_ridge_regression():
    """lam = 1, P0 = d I, x0 = 0: the estimate is (Phi'Phi + I/d)^-1 Phi'Y on zero-padded rows."""
    N, d = 300, 100.0
    plant = control.tf(B, A, True, inputs="u", outputs="y")
    est = RecursiveLeastSquares(4, P0=d).as_iosystem((2, 2, 1))      # the filter's method
    sys = control.interconnect([plant, est], inputs="u",
                               outputs=["y", "theta[0]", "theta[1]", "theta[2]", "theta[3]", "e"])
    u = np.random.default_rng(2).standard_normal(N)
    resp = control.input_output_response(sys, np.arange(N), u)
    y = resp.outputs[0]
    yp, up = np.r_[0.0, 0.0, y], np.r_[0.0, 0.0, u]
    Phi = np.column_stack([-yp[1:-1], -yp[:-2], up[1:-1], up[:-2]])
    ridge = np.linalg.solve(Phi.T @ Phi + np.eye(4) / d, Phi.T @ y)
    assert_allclose(resp.outputs[1:5, -1], ridge, rtol=1e-9)
    assert_allclose(resp.outputs[1:5, -1], [-1.5, 0.7, 1.0, 0.5], atol=1e-4)  # prior bias


def test_estimator_with_two_outputs_and_a_callable_regressor():
    rng = np.random.default_rng(3)
    N = 80
    Hs, Zs = rng.standard_normal((N, 2)), rng.standard_normal((N, 2))
    sys = estimator_iosystem(RecursiveLeastSquares(2, dim_z=2))
    assert sys.input_labels[:2] == ["z[0]", "z[1]"]
    assert sys.output_labels == ["theta[0,0]", "theta[0,1]", "theta[1,0]", "theta[1,1]", "e[0]",
                                 "e[1]"]
    resp = control.input_output_response(sys, np.arange(N), np.vstack([Zs.T, Hs.T]))
    ref = RecursiveLeastSquares(2, dim_z=2)
    ref.batch_filter(Zs, Hs)
    assert_allclose(resp.outputs[:4, -1], ref.x.reshape(-1), rtol=0, atol=1e-12)
    # a callable regressor: z = w0, H = [w1, w1 * w2]
    call = estimator_iosystem(RecursiveLeastSquares(2),
                              regressor=lambda w: (w[0], [w[1], w[1] * w[2]]), inputs=3)
    W = rng.standard_normal((3, N))
    out = control.input_output_response(call, np.arange(N), W).outputs
    ref2 = RecursiveLeastSquares(2)
    ref2.batch_filter(W[0], np.column_stack([W[1], W[1] * W[2]]))
    assert_allclose(out[:2, -1], ref2.x[:, 0], rtol=0, atol=1e-12)


@pytest.mark.parametrize("kwargs, exc, match", [
    (dict(filter=object()), TypeError, r"`filter` must be an rlsfilt filter"),
    (dict(regressor="arx"), ValueError, r"`regressor` must be 'direct', \(na, nb, nk\)"),
    (dict(regressor=(1, 1)), TypeError, r"`regressor` must be 'direct'"),
    (dict(regressor=(2, 2, 1)), ValueError, r"`filter` must have dim_x = na \+ nb = 4"),
    (dict(regressor=lambda w: (w[0], w[1:])), TypeError, r"`inputs` .* is required"),
    (dict(inputs=2), TypeError, r"`inputs` only applies to a callable"),
    (dict(dt=0), ValueError, r"`dt` must be True"),
])
def test_estimator_system_errors(kwargs, exc, match):
    args = dict(filter=RecursiveLeastSquares(3))
    args.update(kwargs)
    with pytest.raises(exc, match=match):
        estimator_iosystem(**args)


@pytest.mark.parametrize("name", FILTERS)
def test_every_filter_has_as_iosystem(name):
    f = FILTERS[name](3)
    sys = f.as_iosystem("direct", dt=0.5)
    assert sys.dt == 0.5 and sys.nstates == len(_filter_state.get_state(f))
    assert sys.output_labels[-1] == "e"


# the estimator system takes a plain sample in one compiled call, any other by the methods
CONFIGS = {
    "exponential": lambda: RecursiveLeastSquares(3, lam=0.97, P0=100.0),
    "random walk Q": lambda: RecursiveLeastSquares(3, P0=10.0, Q=1e-3),
    "directional": lambda: RecursiveLeastSquares(3, lam=0.95, forgetting="directional"),
    "efra": lambda: RecursiveLeastSquares(3, lam=0.95, forgetting="efra"),
    "gate": lambda: RecursiveLeastSquares(3, lam=0.98, P0=100.0, gate=3.0),
    "two outputs": lambda: RecursiveLeastSquares(3, dim_z=2, lam=0.98),
    "health check": lambda: RecursiveLeastSquares(3, lam=0.7, check_every=5, cond_max=1e3),
    "SquareRootRLS": lambda: SquareRootRLS(3, lam=0.97, P0=100.0, check_every=5),
}


@pytest.mark.parametrize("name", CONFIGS)
def test_estimator_system_equals_predict_update_with_its_warnings(name):
    """Outputs, states and warnings of the system (outputs on other inputs first, as
    python-control's first pass) equal ``predict(); update(z, H)`` bit for bit, the
    warnings included (issued by the update, once per message)."""
    rng = np.random.default_rng(6)
    f = CONFIGS[name]()
    m = f.dim_z
    sys = estimator_iosystem(f, "direct")
    Hs = rng.standard_normal((60, 3))
    Hs[30:, 1:] = 0.0                     # one direction excited: forgetting decisions, windup
    Zs = rng.standard_normal((60, m)) + 5.0 * (rng.random((60, 1)) < 0.1)   # outliers: gate
    x, ours, theirs = np.zeros(sys.nstates), set(), set()
    for k in range(60):
        z = float(Zs[k, 0]) if m == 1 else Zs[k]
        w = np.r_[Zs[k], Hs[k]]
        sys.outfcn(k, x, np.r_[-Zs[k], Hs[k]], {})
        got = sys.outfcn(k, x, w, {})
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            x = sys.updfcn(k, x, w, {})
        ours |= {str(c.message) for c in caught}
        e = Zs[k] - Hs[k] @ f.x
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            f.predict()
            f.update(z, Hs[k])
        theirs |= {str(c.message) for c in caught}
        assert_array_equal(got[:3 * m], f.x.ravel())
        assert_allclose(got[3 * m:], e, rtol=0, atol=1e-12)
        assert_array_equal(x, _filter_state.get_state(f))
    assert ours == theirs
    if name == "health check":                        # the warning path was exercised
        assert any("ill-conditioned" in message for message in ours)


def test_estimator_system_in_any_call_order_equals_the_filter():
    """Outputs and updates on other states and inputs in between (restores)."""
    rng = np.random.default_rng(8)
    sys = estimator_iosystem(RecursiveLeastSquares(2, lam=0.98, P0=10.0), regressor=(1, 1, 1))
    upd, out = sys.updfcn, sys.outfcn
    W = rng.standard_normal((40, 2))
    ref = RecursiveLeastSquares(2, lam=0.98, P0=10.0)
    x, states, past = np.zeros(sys.nstates), [], (0.0, 0.0)
    for k in range(40):
        states.append(x)
        if k >= 2:                                     # visit an older state in between
            out(k, states[k - 2], W[k], {})
            upd(k, states[k - 1], -W[k], {})
        y_out = out(k, x, W[k], {})
        if k % 3 == 0:
            out(k, x, W[k] + 1.0, {})                  # other inputs on the same state
        x = upd(k, x, W[k], {})
        H = np.array([-past[1], past[0]])
        e = W[k, 1] - H @ ref.x[:, 0]
        ref.predict_update(W[k, 1], H)
        past = (W[k, 0], W[k, 1])
        assert_allclose(y_out, np.r_[ref.x[:, 0], e], rtol=0, atol=1e-13)
        assert_array_equal(x[:len(_filter_state.get_state(ref))], _filter_state.get_state(ref))


@pytest.mark.parametrize("name", FILTERS)
def test_str_system_in_any_call_order_equals_the_step_loop_bit_for_bit(name):
    """The regulator's system remembers each sample on the bytes of ``(x, u)``: outputs on
    other inputs (the zero loop signal python-control starts each sample with), on older
    states and updates from them in between change nothing; every output and state
    equals the step loop's bit for bit."""
    N = 120
    kw = dict(na=2, nb=2, monitor_every=40, u_limits=(-3.0, 3.0), bounds=(-5.0, 5.0))
    ref = SelfTuningRegulator(FILTERS[name](4), DESIGN, **kw)
    sys = SelfTuningRegulator(FILTERS[name](4), DESIGN, **kw).as_iosystem(extra_outputs=True)
    upd, out = sys.updfcn, sys.outfcn
    plant = control.ss(control.tf(B, A, True), inputs="u", outputs="y")
    r, d = _signals(N, seed=3)
    x, xp, states = np.zeros(sys.nstates), np.zeros(plant.nstates), []
    for k in range(N):
        y = plant.output(k, xp, [0.0])[0]
        w = np.array([y, r[k], d[k]])
        states.append(x)
        if k >= 2:                                      # an older state in between
            out(k, states[k - 2], w, {})
            upd(k, states[k - 1], w + 0.5, {})
        out(k, x, np.array([0.0, r[k], d[k]]), {})      # python-control's first pass
        got = out(k, x, w, {})
        assert_array_equal(out(k, x, w, {}), got)        # a repeated evaluation
        if k % 7 == 0:
            out(k, x, w + 1.0, {})                      # other inputs on the same state
        x = upd(k, x, w, {})
        u = ref.step(y, r[k], d[k])
        h = ref.history
        assert_array_equal(got, np.r_[u, h.e[-1], h.theta[-1]])
        assert_array_equal(x, ref.state)
        xp = plant.dynamics(k, xp, [u])
    # and python-control's own simulation, from the start, bit for bit
    fresh = SelfTuningRegulator(FILTERS[name](4), DESIGN, **kw)
    loop = control.interconnect([plant, fresh.as_iosystem()], inputs=["r", "dither"],
                                outputs=["y", "u"])
    resp = control.input_output_response(loop, np.arange(N), [r, d])
    assert_array_equal(resp.outputs[1], ref.history.u)
    assert_array_equal(resp.outputs[0], ref.history.y)


def test_str_system_output_that_raises_changes_nothing():
    """An output evaluation that raises (a measurement beyond signal_limit) leaves the
    system's working copy as it was: the next sample continues as the step loop."""
    stre = SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), DESIGN, na=2, nb=2)
    sys = stre.as_iosystem()
    x = np.zeros(sys.nstates)
    for k in range(5):
        w = np.array([0.1 * k, 1.0, 0.1])
        sys.outfcn(k, x, w, {})
        x = sys.updfcn(k, x, w, {})
    bad = np.array([1e200, 1.0, 0.1])        # beyond signal_limit: a clear error
    with pytest.raises(ValueError, match="signal_limit"):
        sys.outfcn(5, x, bad, {})
    ref = copy.deepcopy(stre)
    for k in range(5):
        ref.step(0.1 * k, 1.0, 0.1)
    w = np.array([0.5, 1.0, 0.1])
    assert_array_equal(sys.outfcn(5, x, w, {}), [ref.step(*w)])
    assert_array_equal(sys.updfcn(5, x, w, {}), ref.state)
