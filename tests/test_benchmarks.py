"""The benchmark script runs (smoke mode: tiny sizes, seconds).

Benchmarks are not timed tests: this only checks that the script runs end
to end, that every contender it times computes the same estimate, and that
it prints the ratio table and writes the plot. Peers that are not installed
(the ``bench`` extra) are skipped by the script.
"""

import importlib.util
import os
import pathlib
import subprocess
import sys

import numpy as np
from numpy.testing import assert_allclose

ROOT = pathlib.Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "bench_rls.py"


def _load_script():
    spec = importlib.util.spec_from_file_location("bench_rls", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_benchmark_script_runs_in_smoke_mode(tmp_path):
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    plot = tmp_path / "bench.png"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--smoke", "--plot", str(plot)],
                          env=env, cwd=str(tmp_path), capture_output=True, text=True,
                          timeout=300, check=True)
    out = proc.stdout
    assert "ratio to the hand-written compiled loop" in out
    header = next(line for line in out.splitlines() if line.lstrip().startswith("dim_x"))
    for name in ("batch_filter", "kernel", "predict+update", "numpy loop", "filterpy"):
        assert name in header
    rows = [line.split() for line in out.splitlines() if line.split()[:1] in (["2"], ["5"])]
    assert [r[0] for r in rows] == ["2", "5"]
    assert all(float(v) > 0 for r in rows for v in r[1:] if v != "-")
    assert plot.exists() and plot.stat().st_size > 1000


def test_contenders_compute_the_same_estimate():
    """Every timed implementation solves the same problem (lam = 0.99, P0 = 1e4 I)."""
    bench = _load_script()
    Hs, zs = bench.arx_data(5, 400, np.random.default_rng(1))
    assert Hs.shape == (400, 5) and zs.shape == (400,)
    ref = bench.run_batch(Hs, zs)
    for name, (fn, _, module) in bench.CONTENDERS.items():
        if name in ("statsmodels", "write 2 N n^2") or not bench._available(module):
            continue                  # statsmodels has no forgetting: a different estimate
        assert_allclose(fn(Hs, zs), ref, rtol=1e-6, atol=1e-8, err_msg=name)


def test_plot_gives_every_contender_its_own_colour(tmp_path):
    """The docs figure is redrawn from its saved times (--replot): one distinct colour per line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    bench = _load_script()
    saved = ROOT / "docs" / "images" / "bench_rls.json"
    results = bench.main(["--replot", str(saved), "--plot", str(tmp_path / "b.png")])
    assert (tmp_path / "b.png").stat().st_size > 1000
    ax = bench.plot(results)
    lines = ax.get_lines()
    assert len(lines) == len(bench.COLUMNS)
    colours = [to_hex(ln.get_color()) for ln in lines]
    assert len(set(colours)) == len(colours), colours
    assert set(bench.STYLES) == set(bench.COLUMNS)
    plt.close("all")


def test_streaming_ablation_runs():
    """The ablation behind the streaming numbers of ``docs/performance.md`` runs."""
    bench = _load_script()
    results = bench.streaming_ablation([2], n_samples=60, rounds=1, log=lambda *a: None)
    assert set(results[2]) == {"as shipped", "kernels + arrays", "kernels alone",
                               "entry points"}
    assert all(v > 0 for v in results[2].values())


def test_lock_cost_runs():
    """The measurement of the filter's lock behind ``docs/performance.md`` runs."""
    bench = _load_script()
    results = bench.lock_cost([2], n_samples=60, rounds=1, log=lambda *a: None)
    assert set(results[2]) == {"predict+update", "lock"}
    assert results[2]["predict+update"] > 0 and results[2]["lock"] >= 0



def test_gradient_benchmark_runs_in_smoke_mode(tmp_path):
    """``benchmarks/bench_gradient.py --smoke`` (the numbers of docs/performance.md's
    gradient table) runs and prints one positive row per filter."""
    env = dict(os.environ, MPLBACKEND="Agg")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_gradient.py"),
                           "--smoke"], env=env, cwd=str(tmp_path), capture_output=True,
                          text=True, timeout=300, check=True)
    single, bank = proc.stdout.split("\n\n", 1)        # the filters, then the bank
    rows = {line.split()[0]: line.split()[-4:] for line in single.splitlines()
            if line.endswith("x")}
    assert set(rows) == {"LMS", "NLMS", "SignSignLMS", "APA(order=4)"}
    assert [line for line in bank.splitlines() if line.endswith("x")]
    assert all(float(v.rstrip("x")) > 0 for r in rows.values() for v in r)
