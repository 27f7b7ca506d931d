"""A kernel's disk cache goes stale when an rlsfilt file it may call into changes.

numba stamps a function's cache with its own source file only, while it
compiles the kernels a function calls (from other modules too) into that
function's machine code: after an edit of ``filters/_kernels_shared.py`` the
cached callers in ``filters/_kernels_window.py`` kept running the old code.
``rlsfilt._numba`` adds to the stamp a digest of the rlsfilt files the
function's module imports, followed through their imports. Tested here: the
import graph it reads (against :mod:`ast`), the stamp's response to edits,
numba's default cache where the mechanism cannot apply (other files, a numba
with other internals), and, in a copy of the package with its own
``NUMBA_CACHE_DIR``, that an edited callee makes its caller recompile and
return the new answer while an unrelated edit keeps the cache.
"""

import ast
import json
import os
import pathlib
import shutil
import subprocess
import sys
import types
import warnings

import numba
import numpy as np
import pytest
from numba.core import caching

from rlsfilt import _numba

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = pathlib.Path(_numba._ROOT)


def _ast_imports(path):
    """The rlsfilt files `path` imports, read with :mod:`ast` (the oracle of the regex)."""
    tree = ast.parse(path.read_text())
    package = path.parent.relative_to(PACKAGE).parts
    found = set()

    def module(parts):
        base = PACKAGE.joinpath(*parts)
        for candidate in (base.with_name(base.name + ".py"), base / "__init__.py"):
            if parts and candidate.is_file():
                return candidate
        return None if parts else PACKAGE / "__init__.py"

    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("rlsfilt."):
                    found.add(module(alias.name.split(".")[1:]))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = list(package[:len(package) - (node.level - 1)])
            elif (node.module or "").split(".")[0] == "rlsfilt":
                parts = []
                node.module = node.module[len("rlsfilt"):].lstrip(".") or None
            else:
                continue
            parts += node.module.split(".") if node.module else []
            for alias in node.names:
                found.add(module(parts + [alias.name]) or module(parts))
    found.discard(None)
    return {str(p) for p in found}


def _kernel_modules():
    return sorted(p for p in PACKAGE.rglob("*.py")
                  if "_numba import" in p.read_text() and p.name != "_numba.py")


def test_the_import_graph_is_read_as_python_reads_it():
    modules = _kernel_modules()
    assert len(modules) >= 10, modules            # every module with compiled kernels
    for path in modules + [PACKAGE / "filters" / "forgetting.py", PACKAGE / "_validation.py"]:
        assert set(_numba._file(str(path))[0]) == _ast_imports(path), path


def test_a_kernel_depends_on_the_modules_it_calls_into_and_no_others():
    design = PACKAGE / "adaptive" / "_kernels_design.py"
    closure = {pathlib.Path(p).relative_to(PACKAGE).as_posix()
               for p in _numba._closure(str(design))}
    # _kernels_design -> _kernels_vector -> _kernels -> _kernels_shared, _kernels_lagged,
    # forgetting (its constants) -> _validation -> _resources; every kernel -> _numba
    assert {"adaptive/_kernels_design.py", "filters/_kernels_vector.py", "filters/_kernels.py",
            "filters/_kernels_shared.py", "filters/_kernels_lagged.py", "filters/forgetting.py",
            "_numba.py"} <= closure
    assert not closure & {"cli.py", "__init__.py", "filters/__init__.py",
                          "filters/_kernels_bank.py", "adaptive/__init__.py"}
    for path in _kernel_modules():
        assert str(PACKAGE / "_numba.py") in _numba._closure(str(path)), path


def _fake_package(tmp_path, monkeypatch):
    root = tmp_path / "rlsfilt"
    (root / "sub").mkdir(parents=True)
    (root / "__init__.py").write_text("from .sub import a\n")
    (root / "sub" / "__init__.py").write_text("")
    (root / "sub" / "a.py").write_text("from .b import (\n    f,  # (a comment)\n    g,\n)\n")
    (root / "sub" / "b.py").write_text("from ..c import K\n\ndef f():\n    return K\n")
    (root / "c.py").write_text("K = 1\n")
    (root / "d.py").write_text("K = 2\n")
    monkeypatch.setattr(_numba, "_ROOT", str(root))
    return root


def test_the_stamp_follows_the_contents_of_the_imported_files(tmp_path, monkeypatch):
    root = _fake_package(tmp_path, monkeypatch)
    a = str(root / "sub" / "a.py")
    assert _numba._closure(a) == sorted(str(root / p) for p in ("sub/a.py", "sub/b.py", "c.py"))
    first = _numba._dependency_stamp(a)
    assert _numba._dependency_stamp(a) == first
    (root / "d.py").write_text("K = 3\n")                  # not imported: same stamp
    assert _numba._dependency_stamp(a) == first
    (root / "c.py").write_text("K = 5\n")                  # imported by an import: new stamp
    os.utime(root / "c.py", ns=(1, 1))
    second = _numba._dependency_stamp(a)
    assert second != first
    (root / "c.py").write_text("K = 1\n")                  # the old contents: the old stamp
    os.utime(root / "c.py", ns=(2, 2))
    assert _numba._dependency_stamp(a) == first
    (root / "sub" / "b.py").write_text("from ..d import K\n")   # a new import is followed
    os.utime(root / "sub" / "b.py", ns=(3, 3))
    assert str(root / "d.py") in _numba._closure(a)
    assert _numba._dependency_stamp(a) not in (first, second)


def test_the_stamp_is_computed_once_per_execution_of_a_module(tmp_path, monkeypatch):
    root = _fake_package(tmp_path, monkeypatch)
    a = str(root / "sub" / "a.py")
    spec = object()                               # the module's __spec__: one per execution
    first = _numba._dependency_stamp(a, spec)
    (root / "c.py").write_text("K = 5\n")
    os.utime(root / "c.py", ns=(1, 1))
    assert _numba._dependency_stamp(a, spec) == first          # the module's next function
    assert _numba._dependency_stamp(a, object()) != first      # reloaded: looked at again


def test_an_rlsfilt_kernel_has_the_dependency_stamp():
    from rlsfilt.filters import _kernels_shared

    cache = _kernels_shared.copy2._cache
    assert isinstance(cache._impl.locator, _numba._DependencyStamp)
    own, deps = cache._cache_file._source_stamp
    assert deps == _numba._dependency_stamp(_kernels_shared.__file__)


def _square(x):
    return x * x


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setattr(numba.config, "CACHE_DIR", str(tmp_path))
    return tmp_path


def test_a_function_outside_rlsfilt_gets_numbas_own_locator(cache_dir):
    d = _numba.njit(cache=True)(_square)
    locator = d._cache._impl.locator
    assert not isinstance(locator, _numba._DependencyStamp)
    assert type(locator) in caching.FunctionCache._impl_class._locator_classes
    assert d(3.0) == 9.0
    assert list(cache_dir.rglob("*.nbi"))


@pytest.mark.parametrize("caching_module", [
    None,
    types.SimpleNamespace(),
    types.SimpleNamespace(FunctionCache=types.SimpleNamespace(_impl_class=object)),
    types.SimpleNamespace(FunctionCache=types.SimpleNamespace(
        _impl_class=types.SimpleNamespace(_locator_classes=[object]))),
])
def test_a_numba_with_other_internals_is_recognized(caching_module):
    assert _numba._dependency_cache_class(caching_module) is None
    assert _numba._dependency_cache_class(caching) is not None


class _BrokenCache:
    def __init__(self, py_func):
        raise TypeError("FunctionCache() takes other arguments in this numba")


@pytest.mark.parametrize("cache_class", [None, _BrokenCache])
def test_numbas_default_cache_when_the_mechanism_cannot_apply(cache_dir, monkeypatch,
                                                              cache_class):
    monkeypatch.setattr(_numba, "_cache_class", [cache_class])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d = _numba.njit(cache=True, error_model="numpy")(_square)
        assert d(4.0) == 16.0
    assert type(d._cache) is caching.FunctionCache
    assert sum(d.stats.cache_misses.values()) == 1
    assert list(cache_dir.rglob("*.nbi"))


# ----------------------------------------------------------------------
# a copy of the package: an edited callee recompiles its caller
# ----------------------------------------------------------------------
# `sr_unhealthy` (filters/_kernels_window.py) calls `factor_unhealthy`
# (filters/_kernels_shared.py), compiled into it; numba alone stamped its cache
# with _kernels_window.py only.
JOB = r"""
import json
import numpy as np
from rlsfilt.filters import _kernels_window
d = _kernels_window.sr_unhealthy
bad = bool(d(np.eye(3), np.ones(3), 1e8, np.zeros((3, 3))))
print(json.dumps([bad, sum(d.stats.cache_hits.values()), sum(d.stats.cache_misses.values())]))
"""

EDIT = '''

@njit(cache=True, error_model="numpy")
def _edited(U, cond_max):
    """The edit of the test: every factor is unhealthy."""
    return True


factor_unhealthy = _edited
'''


def _copied_package(tmp_path):
    """``(site, env)``: a copy of the package under ``site`` (no caches) and the environment
    of a process that imports it, with a numba cache of its own."""
    site = tmp_path / "site"
    shutil.copytree(PACKAGE, site / "rlsfilt", ignore=shutil.ignore_patterns("__pycache__"))
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_DISABLE_JIT", "PYTHONPATH")}
    env.update(NUMBA_CACHE_DIR=str(tmp_path / "cache"), PYTHONPATH=str(site))
    return site, env


@pytest.mark.slow
def test_an_edited_callee_recompiles_its_callers_and_nothing_else_does(tmp_path):
    site, env = _copied_package(tmp_path)

    def run():
        proc = subprocess.run([sys.executable, "-c", JOB], env=env, cwd=str(tmp_path),
                              capture_output=True, text=True, timeout=900)
        assert proc.returncode == 0, proc.stderr
        return tuple(json.loads(proc.stdout.strip().splitlines()[-1]))

    # (unhealthy, cache hits, cache misses) of sr_unhealthy
    assert run() == (False, 0, 1)                   # compiled and written
    assert run() == (False, 1, 0)                   # loaded
    with open(site / "rlsfilt" / "cli.py", "a") as f:
        f.write("# an edit of a module no kernel imports\n")
    assert run() == (False, 1, 0)                   # still loaded
    with open(site / "rlsfilt" / "filters" / "_kernels_shared.py", "a") as f:
        f.write(EDIT)
    assert run() == (True, 0, 1)                    # recompiled with the edited callee
    assert run() == (True, 1, 0)                    # and that is cached in turn


def test_the_job_answers_as_the_kernel_does():
    """The healthy answer the copy's first runs must give (this process's kernel)."""
    from rlsfilt.filters import _kernels_window

    assert not _kernels_window.sr_unhealthy(np.eye(3), np.ones(3), 1e8, np.zeros((3, 3)))


RELOAD = r"""
import importlib, json, sys
import numpy as np
from rlsfilt.filters import _kernels_shared, _kernels_window
args = np.eye(3), np.ones(3), 1e8, np.zeros((3, 3))
before = bool(_kernels_window.sr_unhealthy(*args))
with open(_kernels_shared.__file__, "a") as f:
    f.write(sys.argv[1])
importlib.reload(_kernels_shared)
importlib.reload(_kernels_window)                 # its own file unchanged
d = _kernels_window.sr_unhealthy
after = bool(d(*args))
print(json.dumps([before, after, sum(d.stats.cache_hits.values()),
                  sum(d.stats.cache_misses.values())]))
"""


@pytest.mark.slow
def test_a_module_reloaded_after_an_edit_of_its_callee_recompiles(tmp_path):
    site, env = _copied_package(tmp_path)
    proc = subprocess.run([sys.executable, "-c", RELOAD, EDIT], env=env, cwd=str(tmp_path),
                          capture_output=True, text=True, timeout=900)
    assert proc.returncode == 0, proc.stderr
    # the reloaded caller is compiled anew (not loaded from the cache of before the edit)
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == [False, True, 0, 1]
