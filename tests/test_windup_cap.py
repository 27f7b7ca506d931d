"""The windup cap of exponential forgetting: the default filter survives lost excitation.

Without it (``spread_max = trace_max = inf``) exponential forgetting keeps
dividing ``P`` by ``lam`` in the directions a held input no longer excites,
until ``P`` overflows and the estimate is NaN for good. With it (the default)
``P`` stays finite and positive definite, the health check warns once per
episode of lost excitation, the estimate recovers when excitation returns,
and ordinary runs give the same bits as without it.
"""

import re
import warnings

import numpy as np
import pytest
from conftest import arx_record
from conftest import assert_close_steps as _close
from numpy.testing import assert_allclose, assert_array_equal
from reference_runs import rls_run

from rlsfilt import NumericalWarning, RecursiveLeastSquares

THETA = np.array([0.5, 2.0, -1.0])
OFF = {"spread_max": np.inf, "trace_max": np.inf}
STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H")


def held_record(periods=3, period=20000, held=19600, tail=400, seed=0):
    """Regressor ``[1, u_k, u_k-1]``; the input is white noise for ``period - held``
    samples, then held at its last value for `held` samples, `periods` times, then
    white again for `tail` samples."""
    rng = np.random.default_rng(seed)
    N = periods * period + tail + 1
    u = rng.standard_normal(N)
    for p in range(periods):
        s = p * period + (period - held)
        u[s:s + held] = u[s - 1]
    Hs = np.column_stack([np.ones(N - 1), u[1:], u[:-1]])
    zs = Hs @ THETA + 0.1 * rng.standard_normal(N - 1)
    return Hs, zs


def _updates(messages):
    return [int(re.search(r"update (\d+) since reset", m).group(1)) for m in messages]


# ----------------------------------------------------------------------
# the long windup run (shortened from 1e6 samples)
# ----------------------------------------------------------------------
def test_lost_excitation_stays_finite_warns_once_per_episode_and_recovers():
    period, held = 20000, 19600
    Hs, zs = held_record(period=period, held=held)
    rls = RecursiveLeastSquares(3, lam=0.95)
    smallest = []
    with pytest.warns(NumericalWarning) as record:
        for k in range(0, len(zs), 1000):             # in chunks, to look at P on the way
            rls.batch_filter(zs[k:k + 1000], Hs[k:k + 1000], store_covariances=False)
            assert np.isfinite(rls.P).all() and np.isfinite(rls.x).all(), k
            smallest.append(np.linalg.eigvalsh(rls.P)[0])
    assert min(smallest) > 0.0                         # positive definite throughout
    messages = [str(w.message) for w in record]
    assert len(messages) == 3, messages                # one warning per episode
    assert all("ill-conditioned" in m for m in messages)
    for p, u in enumerate(_updates(messages)):         # each inside its hold
        assert p * period + period - held < u <= (p + 1) * period, (p, u)
    assert rls.n_capped > 0
    # the estimate recovers each time the input is rich again
    check = RecursiveLeastSquares(3, lam=0.95)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        means = check.batch_filter(zs, Hs, store_covariances=False)[0][:, :, 0]
    assert_array_equal(means[-1], rls.x[:, 0])        # chunks give the bits of one run
    for p in range(1, 3):
        end = p * period + period - held - 1           # the last rich sample after hold p
        assert_allclose(means[end], THETA, atol=0.05, err_msg=f"after hold {p}")
    assert_allclose(means[-1], THETA, atol=0.05)


def test_without_the_cap_the_default_filter_goes_nan_for_good():
    """The failure the cap prevents (the audit's run): P overflows, x is NaN after it."""
    Hs, zs = held_record(periods=1, period=14000, held=13600, tail=400)
    rls = RecursiveLeastSquares(3, lam=0.95, forgetting_params=OFF)
    with pytest.warns(NumericalWarning, match="ill-conditioned") as record:
        means = rls.batch_filter(zs, Hs, store_covariances=False)[0]
    assert len(record) == 1
    assert np.isnan(means[-1]).all() and not np.isfinite(rls.P).all()
    capped = RecursiveLeastSquares(3, lam=0.95)
    with pytest.warns(NumericalWarning, match="ill-conditioned"):
        capped.batch_filter(zs, Hs, store_covariances=False)
    assert_allclose(capped.x[:, 0], THETA, atol=0.05)


def test_zero_regressors_stop_at_trace_max_and_recover():
    """With nothing excited at all (h = 0) P grows uniformly: the trace cap holds it."""
    rng = np.random.default_rng(3)
    Hs = np.r_[rng.standard_normal((100, 2)), np.zeros((5000, 2)), rng.standard_normal((200, 2))]
    zs = Hs @ np.array([1.0, -2.0]) + 0.01 * rng.standard_normal(len(Hs))
    rls = RecursiveLeastSquares(2, lam=0.9, P0=1.0)
    trace_max = rls.forgetting_params["trace_max"]
    assert trace_max == 1e12 * 2.0                     # tied to trace(P0)
    _, covs, _, covs_p = rls.batch_filter(zs, Hs)
    traces = np.trace(covs_p, axis1=1, axis2=2)
    assert traces.max() <= trace_max
    assert traces[5000] > 1e-3 * trace_max             # it did wind up to the cap
    assert np.all(np.linalg.eigvalsh(covs)[:, 0] > 0)
    # after the hold: exponentially weighted least squares on the rows since
    # (the prior and the rows before the hold weigh 1e-12 and 0.9**5200)
    w = np.sqrt(0.9 ** np.arange(199, -1, -1.0))
    ewls = np.linalg.lstsq(Hs[-200:] * w[:, None], zs[-200:] * w, rcond=None)[0]
    assert_allclose(rls.x[:, 0], ewls, rtol=1e-8, atol=1e-9)


def test_health_warning_rearms_in_streaming_as_in_batch():
    """The streaming steps warn at the same updates as batch_filter, once per episode."""
    Hs, zs = held_record(periods=2, period=3000, held=2700, tail=300, seed=1)
    messages = []
    for stream in (False, True):
        rls = RecursiveLeastSquares(3, lam=0.9, check_every=50)
        with pytest.warns(NumericalWarning) as record:
            if stream:
                for k in range(len(zs)):
                    rls.predict_update(zs[k], Hs[k])
            else:
                rls.batch_filter(zs, Hs, store_covariances=False)
        messages.append(_updates([str(w.message) for w in record]))
    assert len(messages[0]) == 2 and messages[0] == messages[1]


# ----------------------------------------------------------------------
# the capped steps are the reference's, and every path gives the same bits
# ----------------------------------------------------------------------
def _stream(f, zs, Hs, update_first):
    """Stream the record through `f` sample by sample (``update`` then ``predict`` with
    `update_first`, else ``predict_update``); the estimate after each sample."""
    means = []
    for k in range(len(zs)):
        if update_first:
            f.update(zs[k], Hs[k])
            f.predict()
        else:
            f.predict_update(zs[k], Hs[k])
        means.append(f.x)
    return means


def _capped_filter(**kw):
    # a low spread_max engages the cap at a moderate condition number
    return RecursiveLeastSquares(3, lam=0.9, P0=10.0, R=0.01, check_every=0,
                                 forgetting_params={"spread_max": 1e4}, **kw)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("Q", [0.0, 1e-6])
def test_capped_steps_equal_the_reference(update_first, Q):
    Hs, zs = held_record(periods=2, period=400, held=300, tail=100, seed=2)
    zs[[5, 150, 420]] = np.nan                          # missing samples, some in a hold
    f = _capped_filter(Q=Q)
    ref = rls_run(f, zs, Hs, None, update_first)
    means, covs, means_p, covs_p = f.batch_filter(zs, Hs, update_first=update_first)
    assert ref.capped.sum() > 100 and f.n_capped == ref.capped.sum()
    # the capped stretches are ill-conditioned by design (P spread up to 1e4 times
    # more off the regressor than along it): round-off grows with that
    for label, a, b in (("means", means, ref.means), ("covs", covs, ref.covs),
                        ("means_p", means_p, ref.means_p), ("covs_p", covs_p, ref.covs_p)):
        _close(a, b, label, rtol=1e-11)


@pytest.mark.parametrize("update_first", [False, True])
def test_capped_run_gives_the_same_bits_in_every_path(update_first):
    """Fused loop, step loop (a gate that never fires), streaming and chunks agree."""
    Hs, zs = held_record(periods=2, period=400, held=300, tail=100, seed=4)
    zs[[7, 250]] = np.nan
    fused = _capped_filter()
    m_fused = fused.batch_filter(zs, Hs, update_first=update_first, store_covariances=False)[0]
    step = _capped_filter(gate=1e300)
    m_step = step.batch_filter(zs, Hs, update_first=update_first)[0]
    stream = _capped_filter()
    m_stream = _stream(stream, zs, Hs, update_first)
    chunks = _capped_filter()
    m_chunks = np.concatenate([chunks.batch_filter(zs[a:b], Hs[a:b], update_first=update_first,
                                                   store_covariances=False)[0]
                               for a, b in [(0, 97), (97, 98), (98, 450), (450, len(zs))]])
    assert fused.n_capped > 100
    for name, m, f in (("step", m_step, step), ("stream", np.array(m_stream), stream),
                       ("chunks", m_chunks, chunks)):
        assert_array_equal(m, m_fused, err_msg=name)
        for attr in STATE:
            assert_array_equal(getattr(f, attr), getattr(fused, attr), err_msg=f"{name} {attr}")
        assert f.n_capped == fused.n_capped, name


# ----------------------------------------------------------------------
# ordinary runs: the cap never acts, the bits are those without it
# ----------------------------------------------------------------------
@pytest.mark.parametrize("lam", [0.9, 0.99, 1.0])
@pytest.mark.parametrize("P0", [1e-2, 1.0, 1e4, 1e8])
def test_ordinary_runs_are_bitwise_unchanged(rng, lam, P0):
    Hs, zs = arx_record(rng, n_samples=3000)
    zs = zs.astype(float)
    zs[[10, 2000]] = np.nan
    for Q in (0.0, 1e-6):
        runs = []
        for params in (None, OFF):
            f = RecursiveLeastSquares(4, lam=lam, P0=P0, Q=Q, forgetting_params=params)
            with warnings.catch_warnings():
                warnings.simplefilter("error")           # healthy: no warning either
                means = f.batch_filter(zs, Hs, store_covariances=False)[0]
                for k in range(50):
                    f.predict_update(zs[k], Hs[k])
            runs.append((means, f))
        (m_on, on), (m_off, off) = runs
        assert on.n_capped == 0
        assert_array_equal(m_on, m_off)
        for attr in STATE:
            assert_array_equal(getattr(on, attr), getattr(off, attr), err_msg=attr)


def test_windup_cap_parameters():
    rls = RecursiveLeastSquares(3, lam=0.95, P0=[[2.0, 0, 0], [0, 3.0, 0], [0, 0, 5.0]])
    assert rls.forgetting_params == {"spread_max": 1e15, "trace_max": 1e13}
    rls = RecursiveLeastSquares(3, lam=0.95, forgetting_params={"trace_max": 7.0})
    assert rls.forgetting_params == {"spread_max": 1e15, "trace_max": 7.0}
    with pytest.raises(TypeError, match=r"unknown keys \['P_max'\] for forgetting='exponential'"):
        RecursiveLeastSquares(3, lam=0.95, forgetting_params={"P_max": 1.0})


@pytest.mark.parametrize("after_predict", [False, True])
def test_a_state_restored_while_capped_continues_bit_for_bit(after_predict):
    """The cap's pending decision is part of the flat state python-control simulates
    (``rlsfilt.adaptive``): a filter restored after an ``update`` that set the cap
    (or after the ``predict`` that held the forgetting back) forgets as the original
    does."""
    from rlsfilt.filters import _filter_state
    rng = np.random.default_rng(3)
    Hs = np.r_[rng.standard_normal((100, 2)), np.zeros((3000, 2)), rng.standard_normal((50, 2))]
    zs = Hs @ np.array([1.0, -2.0]) + 0.01 * rng.standard_normal(len(Hs))
    f = RecursiveLeastSquares(2, lam=0.9, P0=1.0)
    k = 0
    while not f._cap:                                  # run until the cap holds back
        f.predict()
        f.update(zs[k], Hs[k:k + 1])
        k += 1
    assert 100 < k < 3100
    if after_predict:
        f.predict()
        assert f._w == 1.0 / 0.9                       # the next update forgets along H only
    g = RecursiveLeastSquares(2, lam=0.9, P0=1.0)
    _filter_state.set_state(g, _filter_state.get_state(f))
    assert (g._cap, g._w, g.n_capped) == (f._cap, f._w, f.n_capped)
    for j in range(k, len(zs)):
        for h in (f, g):
            if j > k or not after_predict:
                h.predict()
            h.update(zs[j], Hs[j:j + 1])
    assert f.n_capped > 0
    assert_array_equal(g.x, f.x)
    assert_array_equal(g.P, f.P)
    assert g.n_capped == f.n_capped


# ----------------------------------------------------------------------
# long intermittent excitation (#27; benchmarks/bench_intermittent.py runs the
# audit's full 4e6 samples)
# ----------------------------------------------------------------------
def _intermittent(n_blocks, block, excited, seed=0):
    """Regressor ``[1, u_k, u_k-1]``; the input white for the first `excited` samples
    of each block, then held (the audit's record, with shorter blocks)."""
    rng = np.random.default_rng(seed)
    N = n_blocks * block + 1
    u = rng.standard_normal(N)
    for b in range(n_blocks):
        u[b * block + excited:(b + 1) * block] = u[b * block + excited - 1]
    Hs = np.column_stack([np.ones(N - 1), u[1:], u[:-1]])
    return Hs, Hs @ THETA + 0.1 * rng.standard_normal(N - 1)


def test_streaming_equals_batch_through_intermittent_excitation():
    """Where excitation returns after a capped hold, round-off can make ``S``
    negative for a step (``P`` spread 1e15 loses a little definiteness). The
    streaming update then rejected the sample with the default gate (``y'y >
    inf * S`` is ``y'y > -inf``), and every later one: the estimate ran away for
    good while batch_filter recovered. Without a gate nothing is gated."""
    Hs, zs = _intermittent(30, 3000, 60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        batch = RecursiveLeastSquares(3, lam=0.95)
        means = batch.batch_filter(zs, Hs, store_covariances=False)[0][:, :, 0]
        stream = RecursiveLeastSquares(3, lam=0.95)
        xs, S = np.empty((len(zs), 3)), np.empty(len(zs))
        for k in range(len(zs)):
            stream.predict_update(zs[k], Hs[k])
            xs[k], S[k] = stream.x[:, 0], stream.S[0, 0]
    assert (S < 0).any()                      # the mechanism is there (before: from 60003)
    assert stream.n_gated == 0
    assert_array_equal(xs, means)             # bit for bit, at every sample
    assert stream.n_capped == batch.n_capped
    # back on the plant at the end of every excited stretch (the first excited
    # sample after a hold may burst: exponential forgetting's known transient)
    ends = np.arange(30) * 3000 + 58
    assert_allclose(xs[ends], np.broadcast_to(THETA, (30, 3)), atol=0.05)
    assert_allclose(xs[-1], THETA, atol=0.05)


def test_infinite_gate_never_gates_a_negative_innovation_variance():
    """The kernel's gate test alone: ``S < 0`` with ``gate = inf`` updates (as the
    NumPy reference, whose ``gate=None`` never gates); a finite gate still rejects."""
    P = np.array([[1.0, 0.0], [0.0, -3.0]])        # indefinite on purpose
    for gate, gated in ((None, False), (1.0, True)):
        rls = RecursiveLeastSquares(2, R=1.0, check_every=0, gate=gate)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NumericalWarning)
            rls.P = P
            rls.update(1.0, [0.0, 1.0])
        assert rls.S[0, 0] == -2.0 and rls.gated == gated
        assert rls.n_gated == int(gated)


# ----------------------------------------------------------------------
# RLSBank has the same cap (#27): each channel is its own RecursiveLeastSquares
# ----------------------------------------------------------------------
def _bank_record(C=4, seed=0):
    """Channels that lose and regain excitation at different times (one stays rich)."""
    recs = [held_record(periods=2, period=3000, held=2700 - 300 * c, tail=300, seed=seed + c)
            for c in range(C - 1)]
    rng = np.random.default_rng(seed + 99)
    Hr = np.column_stack([np.ones(len(recs[0][0])), rng.standard_normal((len(recs[0][0]), 2))])
    recs.append((Hr, Hr @ THETA + 0.1 * rng.standard_normal(len(Hr))))
    return np.stack([r[0] for r in recs], axis=1), np.stack([r[1] for r in recs], axis=1)


@pytest.mark.parametrize("update_first", [False, True])
def test_bank_channels_equal_capped_filters_through_lost_excitation(update_first):
    from rlsfilt import RLSBank

    Hs, zs = _bank_record()
    zs[[10, 1500, 4000], [0, 1, 2]] = np.nan                 # missing samples, some in a hold
    lams = np.array([0.95, 0.9, 0.99, 0.95])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        bank = RLSBank(4, 3, lam=lams, Q=1e-9)
        means, covs, _, covs_p = bank.batch_filter(zs, Hs, update_first=update_first)
        assert np.isfinite(bank.x).all() and np.isfinite(bank.P).all()
        for c in range(4):
            f = RecursiveLeastSquares(3, lam=lams[c], Q=1e-9)
            mf, cf, _, cpf = f.batch_filter(zs[:, c], Hs[:, c], update_first=update_first)
            assert_array_equal(means[:, c], mf[:, :, 0], err_msg=f"channel {c}")
            assert_array_equal(covs[:, c], cf, err_msg=f"channel {c}")
            assert_array_equal(covs_p[:, c], cpf, err_msg=f"channel {c}")
            assert bank.n_capped[c] == f.n_capped
    assert (bank.n_capped[:2] > 1000).all() and bank.n_capped[3] == 0   # (0.99: no cap)
    assert_allclose(bank.x, np.broadcast_to(THETA, (4, 3)), atol=0.05)   # recovered


def test_bank_without_the_cap_goes_nan_and_with_it_recovers():
    """The audit's case: the bank had no cap, the channel went NaN for good."""
    from rlsfilt import RLSBank

    Hs, zs = held_record(periods=1, period=14000, held=13600, tail=400)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        off = RLSBank(1, 3, lam=0.95, forgetting_params=OFF)
        off.batch_filter(zs[:, None], Hs[:, None], store_covariances=False)
        capped = RLSBank(1, 3, lam=0.95)
        capped.batch_filter(zs[:, None], Hs[:, None], store_covariances=False)
    assert np.isnan(off.x).all()
    assert_allclose(capped.x[0], THETA, atol=0.05)


def test_bank_streaming_chunks_and_channel_continue_the_same_bits():
    """predict/update, batch_filter in chunks, and channel(i) midway (inside a hold,
    with the cap engaged) all continue as one batch run."""
    from rlsfilt import RLSBank

    Hs, zs = _bank_record(seed=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        whole = RLSBank(4, 3, lam=0.9)
        whole.batch_filter(zs, Hs, store_covariances=False)
        chunks = RLSBank(4, 3, lam=0.9)
        for k in range(0, len(zs), 777):
            chunks.batch_filter(zs[k:k + 777], Hs[k:k + 777], store_covariances=False)
        stream = RLSBank(4, 3, lam=0.9)
        mid = 2000                                       # inside the first holds
        for k in range(mid):
            stream.predict_update(zs[k], Hs[k])
        assert stream._cap[:3].all()
        singles = [stream.channel(c) for c in range(4)]
        for k in range(mid, len(zs)):
            stream.predict_update(zs[k], Hs[k])
            for c, f in enumerate(singles):
                f.predict_update(zs[k, c], Hs[k, c])
    for other in (chunks, stream):
        assert_array_equal(other.x, whole.x)
        assert_array_equal(other.P, whole.P)
        assert_array_equal(other.n_capped, whole.n_capped)
    for c, f in enumerate(singles):
        assert_array_equal(f.x[:, 0], whole.x[c])
        assert_array_equal(f.P, whole.P[c])
        assert f.n_capped == whole.n_capped[c]


def test_fit_many_rls_with_forgetting_survives_lost_excitation():
    """fit_many(method="rls", lam < 1) runs the bank: a channel whose input is held
    stays finite, as ARX.fit on it does."""
    from rlsfilt import ARX, fit_many

    rng = np.random.default_rng(4)
    N, C = 6000, 3
    u = rng.standard_normal((N, C))
    u[1000:5800, 0] = u[999, 0]                          # channel 0: held for 4800 samples
    y = np.zeros((N, C))
    for t in range(1, N):
        y[t] = 0.5 * y[t - 1] + u[t - 1] + 0.05 * rng.standard_normal(C)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        bank = fit_many(ARX(1, 1), u, y, "rls", lam=0.95, residual_tests=False)
        single = ARX(1, 1).fit(u[:, 0], y[:, 0], "rls", lam=0.95)
    assert np.isfinite(bank.theta_).all()
    assert_allclose(bank.theta_[0], single.theta_, rtol=1e-9)
    assert_allclose(bank.theta_, np.broadcast_to([-0.5, 1.0], (C, 2)), atol=0.05)


# ----------------------------------------------------------------------
# diagonal forgetting (#30): the same cap, its trace after P^- = L^-1/2 P L^-1/2
# ----------------------------------------------------------------------
LAM_DIAG = np.array([0.9, 0.95, 0.99])


def test_diagonal_forgetting_without_the_cap_goes_nan_and_with_it_recovers():
    """Diagonal forgetting winds up as exponential forgetting does when the regressor
    stays on a coordinate axis (the input held at 0: ``P_ii`` of the unexcited
    parameters grows like ``lam_i**-k``): without the cap P overflows and x is NaN;
    with it (the default) P stays finite and positive definite and the estimate
    recovers. (A regressor held off the axes does not wind up with distinct factors:
    the forgetting turns its information into every direction.)"""
    Hs, zs = held_record(periods=1, period=14000, held=13600, tail=400)
    Hs[400:14000, 1:] = 0.0                            # u held at 0: h = [1, 0, 0]
    zs[400:14000] = Hs[400:14000] @ THETA
    off = RecursiveLeastSquares(3, lam=LAM_DIAG, forgetting="diagonal", forgetting_params=OFF)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        means = off.batch_filter(zs, Hs, store_covariances=False)[0]
    assert np.isnan(means[-1]).all() and not np.isfinite(off.P).all()
    capped = RecursiveLeastSquares(3, lam=LAM_DIAG, forgetting="diagonal")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        for k in range(0, len(zs), 1000):
            capped.batch_filter(zs[k:k + 1000], Hs[k:k + 1000], store_covariances=False)
            assert np.isfinite(capped.P).all() and np.linalg.eigvalsh(capped.P)[0] > 0.0, k
    assert capped.n_capped > 1000
    assert_allclose(capped.x[:, 0], THETA, atol=0.05)


def test_diagonal_zero_regressors_stop_at_trace_max():
    """Nothing excited (h = 0): the trace after the diagonal time update, sum P_ii / lam_i,
    is held at trace_max, as the exponential mode's trace / lam."""
    rng = np.random.default_rng(3)
    Hs = np.r_[rng.standard_normal((100, 2)), np.zeros((3000, 2)), rng.standard_normal((200, 2))]
    zs = Hs @ np.array([1.0, -2.0]) + 0.01 * rng.standard_normal(len(Hs))
    rls = RecursiveLeastSquares(2, lam=[0.9, 0.97], forgetting="diagonal", P0=1.0)
    trace_max = rls.forgetting_params["trace_max"]
    assert trace_max == 1e12 * 2.0
    _, covs, _, covs_p = rls.batch_filter(zs, Hs)
    traces = np.trace(covs_p, axis1=1, axis2=2)
    assert traces.max() <= trace_max and traces[3000] > 1e-3 * trace_max
    assert np.all(np.linalg.eigvalsh(covs)[:, 0] > 0)
    assert_allclose(rls.x[:, 0], [1.0, -2.0], atol=0.02)      # (a memory of 10 to 33 samples)


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("Q", [0.0, 1e-6])
def test_diagonal_capped_steps_equal_the_reference_and_every_path_the_same_bits(update_first,
                                                                              Q):
    """Held back, the diagonal mode forgets along the regressor by the growth its time
    update would give phi P phi^T (``_reference.forget_along``): the kernels equal the
    reference step by step; batch (the step loop), streaming and chunks give the same
    bits."""
    Hs, zs = held_record(periods=2, period=400, held=300, tail=100, seed=2)
    Hs[100:400, 1:] = 0.0                              # the first hold at 0 (on an axis)
    zs[100:400] = Hs[100:400] @ THETA
    zs[[5, 150, 420]] = np.nan

    def make():       # a low trace_max: the cap holds back in both holds (about 250 each)
        return RecursiveLeastSquares(3, lam=LAM_DIAG, forgetting="diagonal", P0=10.0, R=0.01,
                                     Q=Q, check_every=0,
                                     forgetting_params={"spread_max": 1e4, "trace_max": 1e-2})

    f = make()
    ref = rls_run(f, zs, Hs, None, update_first)
    out = f.batch_filter(zs, Hs, update_first=update_first)
    assert ref.capped.sum() > 400 and f.n_capped == ref.capped.sum()
    for label, a, b in zip(("means", "covs", "means_p", "covs_p"), out,
                           (ref.means, ref.covs, ref.means_p, ref.covs_p)):
        _close(a, b, label, rtol=1e-11)
    stream = make()
    _stream(stream, zs, Hs, update_first)
    chunks = make()
    for a, b in [(0, 97), (97, 98), (98, 450), (450, len(zs))]:
        chunks.batch_filter(zs[a:b], Hs[a:b], update_first=update_first,
                            store_covariances=False)
    for name, g in (("stream", stream), ("chunks", chunks)):
        for attr in STATE:
            assert_array_equal(getattr(g, attr), getattr(f, attr), err_msg=f"{name} {attr}")
        assert g.n_capped == f.n_capped, name
