"""The compiled kernels are cached on disk: a second fresh process does not compile.

Two fresh interpreters run the same small job with ``NUMBA_CACHE_DIR`` set to
a temporary directory. The first compiles and writes the cache index files;
the second must find every kernel there (numba's dispatcher statistics show
cache hits and no misses) and, with a warm cache, import rlsfilt and run its
first steps (the default and a robust variant) in well under 2 s.
"""

import json
import os
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]

JOB = r"""
import json, time
t0 = time.perf_counter()
import numpy as np
import rlsfilt
rls = rlsfilt.RecursiveLeastSquares(3, lam=0.99)
H = np.arange(30.0).reshape(10, 3) % 7
z = H @ np.array([1.0, -2.0, 0.5])
rls.batch_filter(z, H, store_covariances=False)
rls.batch_filter(z, H)
rls.predict()
rls.update(1.0, H[0])
robust = rlsfilt.RecursiveLeastSquares(3, lam=0.99, forgetting="directional", gate=4.0)
robust.constrain([1.0, 1.0, 0.0], -1.0)
robust.batch_filter(z, H, store_covariances=False)
robust.predict()
robust.update(1.0, H[0])
elapsed = time.perf_counter() - t0
from rlsfilt.filters import _kernels as K
stats = {name: (sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values()))
         for name, d in [("batch_filter_kernel", K.batch_filter_kernel),
                         ("_run_single", K._run_single), ("update_kernel", K.update_kernel),
                         ("general_batch_kernel", K.general_batch_kernel),
                         ("general_predict", K.general_predict),
                         ("general_update_kernel", K.general_update_kernel)]}
print(json.dumps({"elapsed": elapsed, "stats": stats}))
"""


def _run(cache_dir):
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(cache_dir)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("NUMBA_DISABLE_JIT", None)
    proc = subprocess.run([sys.executable, "-c", JOB], env=env, cwd=str(ROOT), check=True,
                          capture_output=True, text=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_second_process_loads_kernels_from_disk(tmp_path):
    first = _run(tmp_path)
    # the first process compiled every kernel and wrote its index file
    assert all(hits == 0 and misses >= 1 for hits, misses in first["stats"].values()), first
    index = sorted(p.name for p in tmp_path.rglob("*.nbi"))
    for name in ("batch_filter_kernel", "_run_single", "update_kernel", "general_batch_kernel",
                 "general_predict", "general_update_kernel"):
        assert any(f"_kernels.{name}-" in f for f in index), (name, index)
    assert list(tmp_path.rglob("*.nbc"))

    second = _run(tmp_path)
    # nothing compiled; the entry points were loaded (their callees are linked into them)
    assert all(misses == 0 for _, misses in second["stats"].values()), second
    assert second["stats"]["batch_filter_kernel"][0] >= 1, second
    assert second["stats"]["update_kernel"][0] >= 1, second
    assert second["stats"]["general_batch_kernel"][0] >= 1, second
    assert second["stats"]["general_update_kernel"][0] >= 1, second
    # import plus the first calls, warm cache: the budget is 2 s. Other load on the
    # machine can only add time, so the fastest of up to three warm starts is the measure.
    elapsed = [second["elapsed"]]
    while min(elapsed) >= 2.0 and len(elapsed) < 3:
        elapsed.append(_run(tmp_path)["elapsed"])
    assert min(elapsed) < 2.0, elapsed
