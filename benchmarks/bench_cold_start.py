"""Time a warm start: import rlsfilt and run the first steps with the disk cache full.

The compiled kernels are cached on disk (``njit(cache=True)``); the first
process after an install compiles them, every later one loads them. This
script measures both: it runs one job in fresh interpreters with
``NUMBA_CACHE_DIR`` set to a temporary directory, first with an empty cache
(the cold start: compilation) and then several times with the full cache (the
warm start), and prints the times. That the second process compiles nothing
is a test (``tests/test_kernel_cache.py``, numba's dispatcher statistics);
the time it takes depends on the machine and is measured here only.

Usage::

    python benchmarks/bench_cold_start.py            # one cold, five warm starts
    python benchmarks/bench_cold_start.py --warm 10
"""

import argparse
import json
import os
import pathlib
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


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--warm", type=int, default=5, help="warm starts (default 5)")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as cache:
        cold = run_once(cache)
        warm = [run_once(cache) for _ in range(args.warm)]
    print(f"cold start (compiles every kernel): {cold:.2f} s")
    print(f"warm start (loads the disk cache): best {min(warm):.2f} s, "
          f"median {sorted(warm)[len(warm) // 2]:.2f} s over {len(warm)} runs")
    return cold, warm


if __name__ == "__main__":
    main()
