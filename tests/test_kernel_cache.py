"""The compiled kernels are cached on disk: a second fresh process compiles nothing.

Two fresh interpreters run the same small job (every filter, batch and
streaming, the default and the robust variants, the periodic health check)
with ``NUMBA_CACHE_DIR`` set to a temporary directory. The first compiles and
writes the cache index files; the second must find every kernel there:
numba's dispatcher statistics show cache hits and no cache misses, i.e. no
compilation. The mechanism is tested, not a time: how long a warm start takes
is measured by ``benchmarks/bench_cold_start.py``.
"""

import json
import logging
import os
import pathlib
import subprocess
import sys
import types

import pytest

from rlsfilt import _warmup
from rlsfilt._warmup import JOBS, job_code

ROOT = pathlib.Path(__file__).resolve().parents[1]

# the entry points called from Python (their callees are compiled into them)
RLS = ("predict_kernel", "update_kernel", "step_batch", "exponential_batch", "project")
WINDOW = ("sw_batch_kernel", "sw_update_kernel", "window_lstsq", "sr_batch_kernel",
          "sr_update_kernel", "sr_predict", "sr_covariance", "sr_factor", "sr_unhealthy")
SHARED = ("unhealthy_on", "unhealthy")

JOB = r"""
import json
import numpy as np
import rlsfilt
H = np.arange(60.0).reshape(20, 3) % 7 + np.eye(20, 3)
z = H @ np.array([1.0, -2.0, 0.5])
rls = rlsfilt.RecursiveLeastSquares(3, lam=0.99, check_every=7)
rls.batch_filter(z, H, store_covariances=False)
rls.batch_filter(z, H)
for k in range(14):                                     # update 14: the periodic check
    rls.predict()
    rls.update(1.0, H[k])
rls.predict()
rls.P
robust = rlsfilt.RecursiveLeastSquares(3, lam=0.99, forgetting="directional", gate=4.0)
robust.constrain([1.0, 1.0, 0.0], -1.0)
robust.batch_filter(z, H, store_covariances=False)
robust.predict()
robust.update(1.0, H[0])
diagonal = rlsfilt.RecursiveLeastSquares(3, lam=[0.99, 0.98, 1.0], forgetting="diagonal")
diagonal.batch_filter(z, H, store_covariances=False)    # step_batch with its factors
diagonal.predict()
diagonal.update(1.0, H[0])
sw = rlsfilt.SlidingWindowRLS(3, 8, check_every=7)
sw.initialize(z[:8], H[:8])
sw.batch_filter(z, H)
sw.update(1.0, H[0])                                    # update 21: the periodic check
sq = rlsfilt.SquareRootRLS(3, lam=0.99, check_every=7)
sq.batch_filter(z, H)
sq.predict()
sq.update(1.0, H[0])                                    # update 21: the periodic check
sq.U
from rlsfilt.filters import _kernels, _kernels_shared, _kernels_window
stats = {}
for module, names in ((_kernels, RLS), (_kernels_window, WINDOW), (_kernels_shared, SHARED)):
    for name in names:
        d = getattr(module, name)
        stats[name] = (sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values()))
print(json.dumps(stats))
"""


def _run(cache_dir):
    env = dict(os.environ)
    env["NUMBA_CACHE_DIR"] = str(cache_dir)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("NUMBA_DISABLE_JIT", None)
    code = f"RLS, WINDOW, SHARED = {RLS!r}, {WINDOW!r}, {SHARED!r}\n" + JOB
    proc = subprocess.run([sys.executable, "-c", code], env=env, cwd=str(ROOT), check=True,
                          capture_output=True, text=True)
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_second_process_loads_every_kernel_from_disk(tmp_path):
    first = _run(tmp_path)
    # the first process compiled every entry point and wrote its index file
    assert all(hits == 0 and misses >= 1 for hits, misses in first.values()), first
    index = sorted(p.name for p in tmp_path.rglob("*.nbi"))
    for module, names in (("_kernels", RLS), ("_kernels_window", WINDOW),
                          ("_kernels_shared", SHARED)):
        for name in names:
            assert any(f"{module}.{name}-" in f for f in index), (name, index)
    assert list(tmp_path.rglob("*.nbc"))

    second = _run(tmp_path)
    # nothing compiled: every entry point was loaded from the cache
    assert all(hits >= 1 and misses == 0 for hits, misses in second.values()), second


# ----------------------------------------------------------------------
# every public class: a second process compiles nothing (#32)
# ----------------------------------------------------------------------
# The jobs are the registry `rlsfilt warmup` runs (rlsfilt._warmup.JOBS: one per
# public class, the filters, RLSBank, the model family and the Recursive* objects);
# a class added there is tested here. The processes use the run's kernel cache (the
# one beside the sources, or NUMBA_CACHE_DIR when set): the first compiles what is
# missing and writes it, the second must load every kernel it calls.
STATS = r"""
import json, sys
stats = {}
for modname, mod in list(sys.modules.items()):
    if modname.startswith("rlsfilt.") and "_kernels" in modname:
        for attr, d in vars(mod).items():
            s = getattr(d, "stats", None)
            if getattr(d, "__module__", None) == modname and hasattr(s, "cache_misses"):
                stats[modname + "." + attr] = (sum(s.cache_hits.values()),
                                               sum(s.cache_misses.values()))
print(json.dumps(stats))
"""


def _run_shared(code):
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("NUMBA_DISABLE_JIT", None)
    proc = subprocess.run([sys.executable, "-W", "ignore", "-c", code], env=env, cwd=str(ROOT),
                          check=True, capture_output=True, text=True)
    return json.loads(proc.stdout.strip().splitlines()[-1]), proc.stderr


@pytest.mark.slow
@pytest.mark.parametrize("name", [name for name, _ in JOBS])
def test_a_second_process_compiles_nothing(name):
    code = job_code(name) + STATS
    _run_shared(code)
    second, stderr = _run_shared(code)
    assert any(hits for hits, _ in second.values()), second       # kernels were called
    compiled = {k: misses for k, (hits, misses) in second.items() if misses}
    assert not compiled, compiled
    assert "compiling kernels" not in stderr                       # a warm start is silent


def test_a_cold_start_says_so_once_and_passes_under_W_error(tmp_path):
    """An empty cache: one line on stderr when the kernel modules load (through
    logging, so ``-W error`` does not turn it into a failure)."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    code = ("from rlsfilt.filters import _streaming\n"
            "_streaming.kernels(); _streaming.window_kernels()\n"
            "from rlsfilt.models import _recursive_pem\n_recursive_pem._get_kernels()\n")
    proc = subprocess.run([sys.executable, "-W", "error", "-c", code], env=env, cwd=str(ROOT),
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr[-2000:]
    lines = [line for line in proc.stderr.splitlines() if "compiling kernels" in line]
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("rlsfilt: compiling kernels, about ")
    assert "once per machine" in lines[0]


def test_no_message_when_the_cache_has_the_kernels(tmp_path, caplog):
    index = tmp_path / "k.nbi"
    index.write_bytes(b"")

    class Dispatcher:                         # the attributes numba's dispatcher has
        __module__ = "fake_kernels"

        class _cache:
            class _cache_file:
                _index_path = str(index)

    module = types.ModuleType("fake_kernels")
    module.kernel = Dispatcher()
    _warmup._announced.clear()
    with caplog.at_level(logging.INFO, logger="rlsfilt"):
        _warmup.announce_cold(module)
        assert not caplog.records
        index.unlink()                        # now cold: said once, not twice
        _warmup.announce_cold(module)
        _warmup.announce_cold(module)
    assert [r.getMessage()[:34] for r in caplog.records] == ["rlsfilt: compiling kernels, about "]
    _warmup._announced.clear()
