"""The regulator's compiled sample on its state vector == its step loop, across options.

Inside python-control the regulator's system takes a common sample as one
compiled call on the state vector (`_kernels_design.sample`) and every other
sample through the regulator's Python. Whatever the options (orders, delay,
forgetting mode, dead zone, box, limits, redesign period, monitor, patience,
outputs), every output and every state vector must equal the step loop's bit
for bit, with the same warnings and the same errors, in python-control's call
pattern (outputs on the zero loop signal first, then twice on the settled
one, then the update).
"""

import warnings

import control
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_array_equal

from rlsfilt import RecursiveLeastSquares
from rlsfilt.adaptive import SelfTuningRegulator, _kernels_design
from rlsfilt.adaptive.self_tuning import _I
from rlsfilt.filters import forgetting

A = np.array([1.0, -1.5, 0.7])
B = np.array([0.0, 1.0, 0.5])
DESIGN = dict(Am=np.poly([0.5, 0.6]), Ao=np.poly([0.2, 0.3]))


@pytest.fixture
def statuses(monkeypatch):
    """The statuses `_kernels_design.sample` returned, in order."""
    seen = []
    sample = _kernels_design.sample

    def counting(*args):
        status = sample(*args)
        seen.append(status)
        return status

    monkeypatch.setattr(_kernels_design, "sample", counting)
    return seen


def _regulator(opts):
    n = opts["na"] + opts["nb"] + opts["offset"]
    mode = opts["mode"]
    lam = np.linspace(0.95, 0.99, n) if mode == "diagonal" else 0.97
    est = RecursiveLeastSquares(n, lam=lam, P0=100.0, forgetting=mode, check_every=opts["every"])
    kw = {k: opts[k] for k in ("na", "nb", "nk", "dead_zone", "bounds", "u_limits",
                               "redesign_every", "monitor_every", "patience", "windup_ratio",
                               "offset")}
    return SelfTuningRegulator(est, dict(DESIGN, integral=opts["integral"]), **kw)


def _caught(fn, *args):
    """``fn(*args)`` and the regulator's warnings it issued."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args)
    return out, {str(m.message) for m in caught if "SelfTuningRegulator" in str(m.message)}


def _run(opts, N, extra=False):
    """The step loop and the system's functions side by side: asserts equality at every
    sample; returns the warnings of each."""
    ref = _regulator(opts)
    sys = _regulator(opts).as_iosystem(extra_outputs=extra)
    plant = control.ss(control.tf(B, A, True), inputs="u", outputs="y")
    rng = np.random.default_rng(opts["seed"])
    r = np.where(np.arange(N) % 60 < 30, 1.0, -1.0) * opts["r_scale"] + opts.get("level", 0)
    d = 0.05 * rng.choice([-1.0, 1.0], N)
    x, xp = np.zeros(sys.nstates), np.zeros(plant.nstates)
    w_ref, w_sys = set(), set()
    for k in range(N):
        y = plant.output(k, xp, [0.0])[0] + 0.01 * rng.standard_normal() + opts.get("level", 0)
        w = np.array([y, r[k], d[k]])
        try:
            u, caught = _caught(ref.step, y, r[k], d[k])
        except ValueError as exc:
            with pytest.raises(ValueError) as raised:
                sys.outfcn(k, x, w, {})
                sys.updfcn(k, x, w, {})
            assert str(raised.value) == str(exc)
            break
        w_ref |= caught
        sys.outfcn(k, x, np.array([0.0, r[k], d[k]]), {})   # python-control's first pass
        got = sys.outfcn(k, x, w, {})
        assert_array_equal(sys.outfcn(k, x, w, {}), got)
        x, caught = _caught(sys.updfcn, k, x, w, {})
        w_sys |= caught
        h = ref.history
        want = np.r_[u, h.e[-1], h.theta[-1]] if extra else [u]
        assert_array_equal(got, want, err_msg=f"sample {k}")
        assert_array_equal(x, ref.state, err_msg=f"sample {k}")
        xp = plant.dynamics(k, xp, [u])
    return w_ref, w_sys


OPTIONS = st.fixed_dictionaries({
    "na": st.integers(1, 2), "nb": st.integers(1, 2), "nk": st.integers(1, 2),
    "mode": st.sampled_from(list(forgetting.MODES)),
    "every": st.sampled_from([0, 30, 250]),
    "dead_zone": st.sampled_from([0.0, 0.02]),
    "bounds": st.sampled_from([None, (-3.0, 3.0), (-1.2, 1.2)]),
    "u_limits": st.sampled_from([None, (-2.0, 2.0), (-0.4, 0.4)]),
    "redesign_every": st.sampled_from([1, 3]),
    "monitor_every": st.sampled_from([0, 40]),
    "patience": st.sampled_from([3, 50]),
    "windup_ratio": st.sampled_from([1e3, 2.0]),
    "integral": st.booleans(),
    "offset": st.booleans(),
    "level": st.sampled_from([0.0, 20.0]),          # an operating point
    "r_scale": st.sampled_from([1.0, 5.0]),
    "seed": st.integers(0, 2**16),
})


@settings(max_examples=30, deadline=None)
@given(opts=OPTIONS, extra=st.booleans())
def test_compiled_samples_equal_the_step_loop(opts, extra):
    ref_warnings, sys_warnings = _run(opts, 90, extra)
    assert sys_warnings == ref_warnings


def test_the_common_sample_is_one_compiled_call(statuses):
    """The default regulator in python-control: every sample is one compiled call but
    the first (the new filter's checked start), the health check (update 250), the
    monitor's block ends (samples 199, 399) and, while the estimate settles, a design
    the compiled path leaves to Python; the update reuses the outputs' call."""
    opts = dict(na=2, nb=2, nk=1, mode="exponential", every=250, dead_zone=0.0, bounds=None,
                u_limits=None, redesign_every=1, monitor_every=200, patience=50,
                windup_ratio=1e3, integral=True, offset=False, r_scale=1.0, seed=0)
    _run(opts, 400)
    k = _kernels_design
    # two distinct inputs per sample (y = 0, then the settled y): two calls
    assert len(statuses) == 2 * 400
    per_sample = np.array(statuses).reshape(400, 2)
    expected = {0: k.FILTER_STEP, 199: k.MONITOR_DUE, 249: k.FILTER_STEP, 399: k.MONITOR_DUE}
    for calls in per_sample.T:          # the zero loop signal's, then the settled one's
        declined = {int(t): int(calls[t]) for t in np.flatnonzero(calls)}
        assert {t: declined[t] for t in expected if t in declined} == expected
        start = {t: s for t, s in declined.items() if t not in expected}
        assert set(start.values()) <= {k.DESIGN} and max(start, default=0) < 20, start


def test_declined_samples_give_the_regulators_messages(statuses):
    """Samples with a message (the saturation watchdog, the covariance windup, the
    operating point) go through the regulator's Python: the system issues the step
    loop's warnings."""
    base = dict(na=2, nb=2, nk=1, mode="exponential", every=250, dead_zone=0.0, bounds=None,
                u_limits=None, redesign_every=1, monitor_every=40, patience=50,
                windup_ratio=1e3, integral=True, offset=False, r_scale=1.0, seed=1)
    messages = set()
    for change in (dict(u_limits=(-0.4, 0.4), r_scale=5.0), dict(windup_ratio=1.01),
                   dict(level=20.0, u_limits=(-0.4, 0.4))):     # (y and r about 20)
        ref_warnings, sys_warnings = _run(dict(base, **change), 160)
        assert sys_warnings == ref_warnings
        messages |= ref_warnings
    for words in ("sat at a limit", "trace(P)", "away from zero", "nearly cancels"):
        assert any(words in m for m in messages), words
    assert {_kernels_design.DONE, _kernels_design.MONITOR_DUE, _kernels_design.WINDUP_MESSAGE,
            _kernels_design.LEVEL_MESSAGE} <= set(statuses)


def test_the_scalar_entries_are_the_regulators():
    k = _kernels_design
    assert (k.S_HAVE, k.S_STEP, k.S_TRACE_REF, k.S_WARNED_WINDUP, k.S_SIZE, k.S_RUN,
            k.S_WARNED_REJECTED, k.S_SAT, k.S_ERR2, k.S_LEVEL_MEAN, k.S_LEVEL_M2,
            k.S_LEVEL_MIN) == tuple(_I[name] for name in (
                "have_controller", "step", "trace_ref", "warned_windup", "size_last",
                "rejected_run", "warned_rejected", "sat_block", "err2_block", "level_mean",
                "level_m2", "level_min"))


def test_options_the_compiled_sample_leaves_run_through_python(statuses):
    """stable_R, cancelled zeros, a design callable or a filter without a compiled step
    on its state vector: no compiled sample, the same results."""
    from rlsfilt import SquareRootRLS
    from rlsfilt.adaptive import rst_design

    cases = [
        (RecursiveLeastSquares(4, P0=100.0), DESIGN, dict(stable_R=True)),
        (RecursiveLeastSquares(4, P0=100.0), dict(DESIGN, cancel_zeros=True), {}),
        (RecursiveLeastSquares(4, P0=100.0), lambda A, B: rst_design(A, B, **DESIGN), {}),
        (SquareRootRLS(4, P0=100.0), DESIGN, {}),
    ]
    for est, design, kw in cases:
        stre = SelfTuningRegulator(est, design, na=2, nb=2, **kw)
        sys = stre.as_iosystem()
        x = np.zeros(sys.nstates)
        for k in range(20):
            w = np.array([np.sin(0.3 * k), 1.0, 0.05 * (-1) ** k])
            got = sys.outfcn(k, x, w, {})
            x = sys.updfcn(k, x, w, {})
            assert_array_equal(got, [stre.step(*w)])
            assert_array_equal(x, stre.state)
    assert statuses == []
