"""The streaming estimators' per-sample fast path (float samples) and its benchmark.

The fast path skips the full argument validation for float samples; it must
still reject non-finite samples with the usual messages, leave the estimator
unchanged when it does, and give exactly what the validated path gives.
No timing here: benchmarks/bench_streaming.py times it (its smoke run is
checked below, with the agreement of every contender).
"""

import os
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import RecursiveARMA, RecursiveARMAX, RecursiveIV, RecursiveOE

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _record(rng, N=300):
    u, e = rng.standard_normal(N), 0.3 * rng.standard_normal(N)
    return lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1, 0.4], [1, -1.5, 0.7], e), u


@pytest.mark.parametrize("make", [lambda: RecursiveARMAX(2, 2, 1, 1),
                                  lambda: RecursiveOE(2, 2, 1, method="rplr"),
                                  lambda: RecursiveIV(2, 2, 1),
                                  lambda: RecursiveIV(2, 2, 1, instruments="delayed")],
                         ids=["ARMAX", "OE-rplr", "IV-model", "IV-delayed"])
def test_fast_and_validated_paths_agree_bit_for_bit(make, rng):
    y, u = _record(rng)
    fast, full, mixed = make(), make(), make()
    for t in range(len(y)):
        a = fast.step(float(y[t]), float(u[t]))             # Python floats
        b = full.step(np.array([y[t]]), [u[t]])              # arrays: the full validation
        c = mixed.step(y[t], np.float64(u[t]))               # NumPy scalars
        assert a[0] == b[0] == c[0] or np.isnan([a[0], b[0], c[0]]).all()
        np.testing.assert_array_equal(a[1], b[1])
        np.testing.assert_array_equal(a[1], c[1])
    np.testing.assert_array_equal(fast.P, full.P)


@pytest.mark.parametrize("make", [lambda: RecursiveARMAX(1, 1, 1), lambda: RecursiveIV(1, 1)],
                         ids=["ARMAX", "IV"])
@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_fast_path_rejects_non_finite_samples(make, bad, rng):
    est = make()
    for _ in range(5):
        est.step(float(rng.standard_normal()), float(rng.standard_normal()))
    theta, P, steps = est.theta, est.P, est.n_steps
    with pytest.raises(ValueError, match="`y` must be finite"):
        est.step(bad, 0.5)
    with pytest.raises(ValueError, match="`u` must be finite"):
        est.step(0.5, bad)
    np.testing.assert_array_equal(est.theta, theta)
    np.testing.assert_array_equal(est.P, P)
    assert est.n_steps == steps


def test_time_series_fast_path(rng):
    y, _ = _record(rng)
    a, b = RecursiveARMA(2, 1), RecursiveARMA(2, 1)
    for t in range(len(y)):
        np.testing.assert_array_equal(a.step(float(y[t]))[1], b.step(np.array(y[t]))[1])
    with pytest.raises(ValueError, match="`u` must be omitted: RecursiveARMA has no input"):
        a.step(0.1, 0.2)


def test_streaming_benchmark_runs_in_smoke_mode(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_streaming.py"),
                           "--smoke"], env=env, cwd=str(tmp_path), capture_output=True,
                          text=True, timeout=600, check=True)
    assert "every contender ends at the same estimate" in proc.stdout
    for name in ("RecursiveARMAX", "RecursiveOE", "RecursiveBJ", "RecursiveARMA",
                 "RecursiveIV"):
        assert name in proc.stdout
