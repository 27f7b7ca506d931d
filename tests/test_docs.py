"""The documentation: its code runs, and its API reference lists every public name.

The HTML build itself (``python -m sphinx -W --keep-going -b html docs
docs/_build/html``) runs as a separate step in ``.ci/run``.
"""

import importlib
import re
import types
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
PAGES = sorted(p for p in DOCS.rglob("*.md")
               if "_build" not in p.parts and "notebooks" not in p.parts)
# public modules whose __all__ the API reference must cover (the command line's `main` and the
# exceptions too: a name dropped from any of their lists in docs/api/index.rst must fail the test)
SUBPACKAGES = ["rlsfilt.filters", "rlsfilt.models", "rlsfilt.datasets", "rlsfilt.validation",
               "rlsfilt.adaptive", "rlsfilt.data",
               "rlsfilt.plotting", "rlsfilt.exceptions", "rlsfilt.cli"]
_FENCE = re.compile(r"^(?P<skip>% skip-test\n)?```python\n(?P<code>.*?)^```$", re.M | re.S)


def _python_blocks(page):
    return [(m.group("code"), bool(m.group("skip"))) for m in _FENCE.finditer(page.read_text())]


def test_pages_have_code():
    assert any(_python_blocks(p) for p in PAGES)


@pytest.mark.parametrize("page", [p for p in PAGES if _python_blocks(p)],
                         ids=lambda p: str(p.relative_to(DOCS)))
def test_code_blocks_run(page, tmp_path, monkeypatch, capsys):
    """Every ```python block of a page runs, in order, in one namespace per page."""
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__docs__"}
    for i, (code, skip) in enumerate(_python_blocks(page)):
        if skip:
            compile(code, f"{page.name} block {i}", "exec")  # still valid Python
            continue
        exec(compile(code, f"{page.name} block {i}", "exec"), namespace)
    capsys.readouterr()


def test_readme_code_runs(monkeypatch, capsys, tmp_path):
    """The README's ```python blocks run, in order, in one namespace."""
    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__readme__"}
    blocks = _python_blocks(ROOT / "README.md")
    assert blocks
    for i, (code, _) in enumerate(blocks):
        exec(compile(code, f"README.md block {i}", "exec"), namespace)
    out = capsys.readouterr().out
    assert "[0.8007" in out and "(2, 2, 1)" in out


def _documented_names():
    """Fully qualified names listed in the autosummary tables of docs/api/index.rst."""
    names, module, in_table = set(), None, False
    for line in (DOCS / "api" / "index.rst").read_text().splitlines():
        m = re.match(r"\.\. currentmodule:: (\S+)", line)
        if m:
            module = m.group(1)
            continue
        if line.startswith(".. autosummary::"):
            in_table = True
            continue
        if in_table:
            stripped = line.strip()
            if not stripped or stripped.startswith(":"):
                continue
            if not line.startswith("   "):
                in_table = False
                continue
            names.add(f"{module}.{stripped.lstrip('~')}")
    return names


def _resolve(full):
    module, _, name = full.rpartition(".")
    return getattr(importlib.import_module(module), name)


def test_api_reference_lists_every_public_name():
    """Every name in ``__all__`` is documented, under its own path or another one."""
    import rlsfilt

    documented = {id(_resolve(full)) for full in _documented_names()}
    missing = []
    for module in [rlsfilt] + [importlib.import_module(sub) for sub in SUBPACKAGES]:
        assert module.__all__, f"{module.__name__}.__all__ is empty"
        for n in module.__all__:
            obj = getattr(module, n)
            if n.startswith("__") or isinstance(obj, types.ModuleType):
                continue
            if id(obj) not in documented and f"rlsfilt.{n}" not in missing:
                missing.append(f"{module.__name__}.{n}")
    assert not missing, ("add these public names to an autosummary list in "
                         f"docs/api/index.rst: {', '.join(missing)}")


def test_api_reference_entries_exist():
    for full in _documented_names():
        module, _, name = full.rpartition(".")
        assert hasattr(importlib.import_module(module), name), f"{full} does not exist"


def test_readme_quick_start_is_two_commands_and_ci_runs_the_test_line():
    """Issue contract: the Quick start's first fenced block holds exactly two command lines
    (install + demo, install + tests), and .ci/run runs the test line verbatim."""
    readme = (ROOT / "README.md").read_text()
    section = readme.split("\n## Quick start\n", 1)[1].split("\n## ", 1)[0]
    block = re.search(r"^```[a-z]*\n(.*?)^```$", section, re.M | re.S)
    assert block, "no fenced block in the Quick start section"
    lines = [ln for ln in block.group(1).splitlines() if ln.strip()]
    assert len(lines) == 2, lines
    install, tests = lines
    assert "pip install" in install and install.rstrip().endswith("rlsfilt demo"), install
    assert "pip install" in tests and "pytest" in tests, tests
    ci = (ROOT / ".ci" / "run").read_text().splitlines()
    assert tests in ci, f".ci/run does not run the README's test line verbatim: {tests!r}"
