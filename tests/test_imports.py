"""``import rlsfilt`` stays light: pandas, matplotlib and python-control are
imported only when a function needs them (the issues ask for no pandas
dependency at import time, and lazy matplotlib)."""

import json
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]


def test_import_does_not_pull_optional_heavy_modules():
    code = ("import json, sys, rlsfilt, rlsfilt.datasets, rlsfilt.validation, rlsfilt.models; "
            "print(json.dumps({m: m in sys.modules for m in "
            "('pandas', 'matplotlib', 'control', 'statsmodels')}))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    assert json.loads(out.stdout) == {"pandas": False, "matplotlib": False, "control": False,
                                      "statsmodels": False}


def test_import_does_not_pull_scipy_signal_control_or_filterpy():
    """``import rlsfilt`` loads none of SciPy's submodules, python-control, filterpy or
    numba: each is imported by the first function that needs it (the mechanism that
    keeps a fresh process's start short; how short is measured by
    ``benchmarks/bench_targets.py``, not tested)."""
    heavy = ("scipy.signal", "scipy.stats", "scipy.optimize", "scipy.linalg", "control",
             "filterpy", "numba")
    code = ("import json, sys, rlsfilt; "
            f"print(json.dumps({{m: m in sys.modules for m in {heavy!r}}}))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True,
                         check=True)
    assert json.loads(out.stdout) == dict.fromkeys(heavy, False)
