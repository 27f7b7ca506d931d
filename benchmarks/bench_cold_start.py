"""Time a cold and a warm start: import rlsfilt and run the first steps, cache empty or full.

The compiled kernels are cached on disk (``njit(cache=True)``); the first
process after an install compiles them, every later one loads them. This
script measures both: it runs one job in fresh interpreters with
``NUMBA_CACHE_DIR`` set to a temporary directory, first with an empty cache
(the cold start: compilation) and then several times with the full cache (the
warm start), and prints the times. That the second process compiles nothing
is a test (``tests/test_kernel_cache.py``, numba's dispatcher statistics);
the time it takes depends on the machine and is measured here only.

It then measures the first minute of a user, as the CPU time of a whole fresh
process (interpreter, imports and compilation; ``resource.getrusage`` of the
child) with an empty cache and with the cache the first run filled:
``rlsfilt demo``, a first ``ARX.fit(method="rls")`` and a first
``ARMAX.fit(method="rpem")`` (each in its own empty cache).

Measured on the 2-core development machine (busy: load 5 to 10; the numbers
move with the load, compare them in one run), before #32, after its first
round (the fused loop compiled once for every size but 5, its rare steps
sharing one compiled sweep, no duplicate variants) and after its last (the
``Q`` loops compiled only for a ``Q``, lean rare steps; two runs, load 6-7,
against 10.3-10.4 / 9.0 / 12.1-12.5 s cold for the round before):

=================================  ============  ============  ===============
CPU seconds, cold / warm           before #32    first round   last round
=================================  ============  ============  ===============
``rlsfilt demo``                   23.4 / 2.5    12.8 / 2.4    7.2-7.6 / 1.9
first ``ARX.fit(method="rls")``    21.6 / 1.1    11.1 / 1.1    6.0-6.5 / 1.0
first ``fit(method="rpem")``       13.2 / 1.6    13.5 / 1.7    11.9-12.1 / 1.5
=================================  ============  ============  ===============

Usage::

    python benchmarks/bench_cold_start.py            # one cold, five warm starts
    python benchmarks/bench_cold_start.py --warm 10
    python benchmarks/bench_cold_start.py --only first-minute
"""

import argparse
import json
import os
import pathlib
import resource
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]

JOB = r"""
import json, time
t0 = time.perf_counter()
import numpy as np
import rlsfilt
H = np.arange(60.0).reshape(20, 3) % 7 + np.eye(20, 3)
z = H @ np.array([1.0, -2.0, 0.5])
rls = rlsfilt.RecursiveLeastSquares(3, lam=0.99)
rls.batch_filter(z, H, store_covariances=False)
rls.batch_filter(z, H)
rls.predict()
rls.update(1.0, H[0])
robust = rlsfilt.RecursiveLeastSquares(3, lam=0.99, forgetting="directional", gate=4.0)
robust.constrain([1.0, 1.0, 0.0], -1.0)
robust.batch_filter(z, H, store_covariances=False)
robust.predict()
robust.update(1.0, H[0])
sw = rlsfilt.SlidingWindowRLS(3, 8, check_every=7)
sw.batch_filter(z, H)
sw.update(1.0, H[0])
sq = rlsfilt.SquareRootRLS(3, lam=0.99, check_every=7)
sq.batch_filter(z, H)
sq.predict()
sq.update(1.0, H[0])
print(json.dumps({"elapsed": time.perf_counter() - t0}))
"""


def run_once(cache_dir):
    """Seconds for the job (import plus first calls) in a fresh interpreter."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir))
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("NUMBA_DISABLE_JIT", None)
    proc = subprocess.run([sys.executable, "-c", JOB], env=env, cwd=str(ROOT), check=True,
                          capture_output=True, text=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])["elapsed"]


_FIT_PRELUDE = """
import numpy as np
import rlsfilt
rng = np.random.default_rng(0)
u = rng.standard_normal(2000)
e = 0.1 * rng.standard_normal(2000)
y = np.zeros(2000)
for t in range(2, 2000):
    y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2] + e[t] + 0.3 * e[t - 1]
"""

#: the first minute of a user: (label, argv of ``python``)
FIRST_MINUTE = (
    ("rlsfilt demo", ["-m", "rlsfilt", "demo"]),
    ("first ARX.fit(method='rls')",
     ["-c", _FIT_PRELUDE + "rlsfilt.ARX(2, 2, 1).fit(u, y, method='rls')"]),
    ("first ARMAX.fit(method='rpem')",
     ["-c", _FIT_PRELUDE + "rlsfilt.ARMAX(2, 2, 1, 1).fit(u, y, method='rpem')"]),
)


def process_cpu(argv, cache_dir):
    """CPU seconds (user + system) of a whole fresh ``python argv`` process."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache_dir), MPLBACKEND="Agg")
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("NUMBA_DISABLE_JIT", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, *argv], env=env, cwd=str(ROOT), check=True,
                   capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def first_minute():
    """``{label: (cold, warm)}`` CPU seconds of `FIRST_MINUTE`, each in its own empty cache."""
    out = {}
    print("first minute, CPU of a whole process: empty cache (cold), then warm")
    for label, argv in FIRST_MINUTE:
        with tempfile.TemporaryDirectory() as cache:
            cold = process_cpu(argv, cache)
            warm = process_cpu(argv, cache)
        out[label] = (cold, warm)
        print(f"  {label:32s} cold {cold:6.1f} s   warm {warm:5.1f} s")
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--warm", type=int, default=5, help="warm starts (default 5)")
    parser.add_argument("--only", choices=("filters", "first-minute"),
                        help="the filters' cold and warm starts, or the first minute only")
    args = parser.parse_args(argv)
    result = {}
    if args.only != "first-minute":
        with tempfile.TemporaryDirectory() as cache:
            cold = run_once(cache)
            warm = [run_once(cache) for _ in range(args.warm)]
        print(f"cold start (compiles every kernel): {cold:.2f} s")
        print(f"warm start (loads the disk cache): best {min(warm):.2f} s, "
              f"median {sorted(warm)[len(warm) // 2]:.2f} s over {len(warm)} runs")
        result["filters"] = (cold, warm)
    if args.only != "filters":
        result["first minute"] = first_minute()
    return result


if __name__ == "__main__":
    main()
