"""rlsfilt runs, uncached and with one warning, when numba cannot write its cache (issue #18).

A read-only installation with an unwritable ``HOME`` leaves numba no cache
directory: ``njit(cache=True)`` then raised ``RuntimeError: cannot cache
function ...`` at import of the kernels, and ``rlsfilt demo`` printed a
39-line traceback. The package is copied to a temporary directory and every
place numba could write is made unwritable: ``NUMBA_CACHE_DIR`` and ``HOME``
point below a regular file (``mkdir`` fails with ``NotADirectoryError``,
for root too, which ``chmod`` would not stop) and every ``__pycache__`` of
the package is a regular file.
"""

import json
import os
import pathlib
import shutil
import subprocess
import sys

import numpy as np
import pytest

from rlsfilt import RecursiveLeastSquares, SquareRootRLS

ROOT = pathlib.Path(__file__).resolve().parents[1]

JOB = r"""
import json, warnings
import numpy as np
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    import rlsfilt
    rls = rlsfilt.RecursiveLeastSquares(2, lam=0.99)
    H = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    rls.batch_filter(H @ [1.0, 2.0], H, store_covariances=False)
    sr = rlsfilt.SquareRootRLS(2)
    sr.batch_filter(H @ [1.0, 2.0], H)
print(json.dumps({"x": rls.x.ravel().tolist(), "x_sr": sr.x.ravel().tolist(),
                  "warnings": [[w.category.__name__, str(w.message)] for w in caught]}))
"""


def _unwritable_copy(tmp_path):
    """A copy of the package where numba finds no writable cache directory; its env."""
    root = tmp_path / "site"
    shutil.copytree(ROOT / "rlsfilt", root / "rlsfilt",
                    ignore=shutil.ignore_patterns("__pycache__"))
    for package in (root / "rlsfilt").rglob("__init__.py"):
        (package.parent / "__pycache__").write_text("not a directory")
    blocker = tmp_path / "blocker"
    blocker.write_text("a file, so nothing can be created below it")
    env = {k: v for k, v in os.environ.items()
           if k not in ("NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "NUMBA_DISABLE_JIT", "MPLCONFIGDIR",
                        "XDG_CONFIG_HOME", "PYTHONPATH")}
    env.update(NUMBA_CACHE_DIR=str(blocker / "numba"), HOME=str(blocker), PYTHONPATH=str(root),
               MPLBACKEND="Agg")
    return root, env


def test_kernels_compile_uncached_with_one_warning(tmp_path):
    root, env = _unwritable_copy(tmp_path)
    proc = subprocess.run([sys.executable, "-c", JOB], env=env, cwd=str(tmp_path),
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    # the same numbers as this process's cached kernels give
    H = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 1.0]])
    rls = RecursiveLeastSquares(2, lam=0.99)
    rls.batch_filter(H @ [1.0, 2.0], H, store_covariances=False)
    sr = SquareRootRLS(2)
    sr.batch_filter(H @ [1.0, 2.0], H)
    assert out["x"] == pytest.approx(rls.x.ravel().tolist(), rel=1e-13)
    assert out["x_sr"] == pytest.approx(sr.x.ravel().tolist(), rel=1e-13)
    numba_warnings = [w for w in out["warnings"] if "cache" in w[1]]
    assert len(numba_warnings) == 1, out["warnings"]
    category, message = numba_warnings[0]
    assert category == "RuntimeWarning"
    assert "NUMBA_CACHE_DIR" in message
    # nothing was written anywhere below the copy (the cache really was unavailable)
    assert not list(root.rglob("*.nbi"))


@pytest.mark.slow
def test_cli_demo_runs_uncached_with_one_warning_line(tmp_path):
    _, env = _unwritable_copy(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "rlsfilt", "demo", "-q", "--samples", "400"],
                          env=env, cwd=str(tmp_path), capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("rlsfilt: warning: numba found no writable cache directory")
    assert "Verdict" in proc.stdout
