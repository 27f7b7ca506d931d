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
               "rlsfilt.plotting", "rlsfilt.exceptions", "rlsfilt.cli",
               "rlsfilt.river", "rlsfilt.sklearn"]
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


# ----------------------------------------------------------------------
# the numbers a page shows in its comments are the numbers its code prints
# ----------------------------------------------------------------------
_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?(?![\w])")
# the first value a comment shows: a number, or a bracketed list of numbers, with an
# optional "~" (approximately) or "close to" before it and a "%" after it
_SHOWN = re.compile(r"(?P<approx>~|close to )?\s*(?P<value>[\[(][-+\d.,\s\[\]()eE]*[\])]"
                    r"|(?<![\w.])[-+]?\d+(?:\.\d+)?(?![\w]))\s*(?P<pct>%)?")


def _comments(code):
    """``{line number: comment text}`` of a block of Python source."""
    import io
    import tokenize

    return {tok.start[0]: tok.string.lstrip("#").strip()
            for tok in tokenize.generate_tokens(io.StringIO(code).readline)
            if tok.type == tokenize.COMMENT}


def _shown(comment, at_start=False):
    """``(numbers, approximate, percent)`` of the first value a comment shows (only at its
    start with `at_start`), or None."""
    matches = [_SHOWN.match(comment)] if at_start else _SHOWN.finditer(comment)
    for m in matches:
        numbers = _NUMBER.findall(m.group("value")) if m else []
        if numbers:
            return numbers, bool(m.group("approx")), bool(m.group("pct"))
    return None


def _matches(expected, got, approx, percent):
    """True when the numbers `expected` (text, as the comment shows them) appear one after
    the other in `got` (floats), each within one unit of its last shown digit (10 % for
    an approximate value); a percentage may be printed as a fraction."""
    want = [float(x) for x in expected]
    tols = [10.0 ** -len(x.split(".")[1]) if "." in x.split("e")[0] else 0.5 for x in expected]
    if approx:
        tols = [max(t, 0.1 * abs(w)) for t, w in zip(tols, want)]
    scales = (1.0, 100.0) if percent else (1.0,)
    for scale in scales:
        vals = [scale * g for g in got]
        for i in range(len(vals) - len(want) + 1):
            if all(abs(v - w) <= t * (1 + 1e-9)
                   for v, w, t in zip(vals[i:], want, tols)):
                return True
    return False


def _check_statement(stmt, comment, namespace, printed, where):
    """Compare one top-level statement's comment with what it printed (a ``print(...)``) or
    with the value it assigned (``name = ...``: a number, a tuple, or an array's shape).
    Returns True when something was compared."""
    import ast

    import numpy as np

    is_print = (isinstance(stmt, ast.Expr) and isinstance(stmt.value, ast.Call)
                and getattr(stmt.value.func, "id", None) == "print")
    if is_print:
        for quoted in re.findall(r'"([^"]+)"', comment):   # quoted text is printed as is
            pattern = ".*?".join(re.escape(part.strip()) for part in quoted.split("..."))
            assert re.search(pattern, printed), f"{where}: {quoted!r} not in the output"
        shown = _shown(re.sub(r'"[^"]*"', "", comment))
        if shown is None:
            return '"' in comment
        got = [float(x) for x in _NUMBER.findall(printed)]
    elif (isinstance(stmt, ast.Assign) and len(stmt.targets) == 1
          and isinstance(stmt.targets[0], ast.Name)):
        shown = _shown(comment, at_start=True)   # "x = f()  # 8 = ...", not prose
        if shown is None:
            return False
        value = namespace[stmt.targets[0].id]
        if isinstance(value, np.ndarray) and comment.startswith("("):
            got = [float(n) for n in value.shape]
        elif isinstance(value, (int, float, np.number, tuple, list, np.ndarray)):
            got = [float(v) for v in np.ravel(value)]
        else:
            return False
    else:
        return False
    numbers, approx, percent = shown
    assert _matches(numbers, got, approx, percent), (
        f"{where}: the comment shows {' '.join(numbers)}"
        f"{' (approximately)' if approx else ''}; the code gives {got[:12]}")
    return True


@pytest.mark.parametrize("page", ["README.md", "docs/quickstart.md"])
def test_printed_numbers_match_their_comments(page, monkeypatch, tmp_path):
    """Every ```python block of the README and the quick start runs as written, statement
    by statement in one namespace, and where a comment beside a ``print`` (or an
    assignment) shows a value, the code gives that value: numbers loosely (to the last
    shown digit, 10 % after "~" or "close to", a percentage also as a fraction), quoted
    text literally ("..." standing for anything)."""
    import ast
    import contextlib
    import io

    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": "__docs__"}
    checked = 0
    for i, (code, skip) in enumerate(_python_blocks(ROOT / page)):
        if skip:
            continue
        comments = _comments(code)
        for stmt in ast.parse(code).body:
            out = io.StringIO()
            with contextlib.redirect_stdout(out):
                exec(compile(ast.Module([stmt], type_ignores=[]), f"{page} block {i}", "exec"),
                     namespace)
            comment = comments.get(stmt.lineno, "")
            if comment:
                checked += _check_statement(stmt, comment, namespace, out.getvalue(),
                                            f"{page} block {i} line {stmt.lineno}")
    assert checked >= 4, f"{page}: only {checked} comments were compared with the output"


def test_notebook_mentions_link_to_the_notebooks():
    """"Notebook N" in a documentation page or a notebook's text is a link to that notebook
    ({doc}`Notebook N </notebooks/0N_...>` in the pages, [Notebook N](0N_....ipynb) in the
    notebooks); the changelog, which records history, is left as written."""
    import json

    names = {p.name[:2]: p.stem for p in (ROOT / "notebooks").glob("0*.ipynb")}
    mention = re.compile(r"(?P<pre>\[|`)?[Nn]otebook (?P<n>\d)\b(?P<post>\]\((?P<target>[^)]+)\)"
                         r"| </notebooks/(?P<doc>[^>]+)>`)?")
    texts = [(str(p.relative_to(ROOT)), p.read_text()) for p in PAGES if p.name != "changelog.md"]
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(nb.read_text())["cells"]
        texts += [(f"{nb.name} cell {i}", "".join(c["source"])) for i, c in enumerate(cells)
                  if c["cell_type"] == "markdown"]
    bad = []
    for where, text in texts:
        for m in mention.finditer(text):
            stem = names.get(f"0{m.group('n')}")
            target = m.group("target") or m.group("doc") or ""
            if not m.group("post") or stem is None or not target.startswith(stem):
                bad.append(f"{where}: {text[max(0, m.start() - 20):m.end() + 20]!r}")
    assert not bad, "unlinked notebook mentions:\n" + "\n".join(bad)


def _unnamed_modules(doc, package=ROOT / "rlsfilt"):
    """The module files of `package` that `doc` does not name: by their path inside the
    package (``filters/rls.py``) or, when no other module has that file name, by the name
    alone (``rls.py``, as the tables of a subpackage write it). A package is named by its
    directory (``filters/``)."""
    files = sorted(package.rglob("*.py"))
    count = {}
    for p in files:
        count[p.name] = count.get(p.name, 0) + 1
    missing = []
    for p in files:
        rel = p.relative_to(package).as_posix()
        if p.name == "__init__.py":
            named = rel == "__init__.py" or f"{p.parent.name}/" in doc
        else:
            bare = re.search(rf"(?<![\w/.]){re.escape(p.name)}", doc) and count[p.name] == 1
            named = re.search(rf"(?<![\w.]){re.escape(rel)}", doc) or bare
        if not named:
            missing.append(rel)
    return missing


def test_develop_md_names_every_module():
    """docs/develop.md is the package map: every module of rlsfilt/ is in it."""
    missing = _unnamed_modules((DOCS / "develop.md").read_text())
    assert not missing, f"modules docs/develop.md does not name: {missing}"


def test_unnamed_modules_finds_a_missing_module(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "a").mkdir(parents=True)
    (pkg / "b").mkdir()
    for name in ("__init__.py", "a/__init__.py", "a/x.py", "a/_base.py", "b/__init__.py",
                 "b/_base.py", "b/y.py"):
        (pkg / name).write_text("")
    doc = "`a/` holds `x.py`, `a/_base.py`; `b/`: `_base.py`"
    assert _unnamed_modules(doc, pkg) == ["b/_base.py", "b/y.py"]


# ----------------------------------------------------------------------
# every public method of every public class is on the class's API page
# ----------------------------------------------------------------------
def _public_methods(cls):
    """The public methods of `cls`, inherited ones included, that rlsfilt defines (not those
    only a builtin base such as ``tuple`` or ``BaseException`` provides)."""
    import inspect

    names = set()
    for name in dir(cls):
        if name.startswith("_"):
            continue
        owner = next((k for k in cls.__mro__ if name in vars(k)), None)
        if owner is None or owner.__module__ == "builtins":
            continue
        raw = vars(owner)[name]
        if isinstance(raw, (staticmethod, classmethod)) or inspect.isfunction(raw):
            names.add(name)
    return names


def _class_pages(tmp_path):
    """``{fully qualified name: generated rst}`` of the classes in docs/api/index.rst, made by
    autosummary with the documentation's templates (as the HTML build does, without it)."""
    from sphinx.ext.autosummary.generate import main as autogen

    out = tmp_path / "generated"
    autogen(["-t", str(DOCS / "_templates"), "-o", str(out),
             str(DOCS / "api" / "index.rst")])
    return {full: (out / f"{full}.rst").read_text() for full in _documented_names()
            if isinstance(_resolve(full), type)}


def _missing_methods(full, page):
    """The public methods of the class `full` that its generated page leaves out."""
    cls = _resolve(full)
    methods = _public_methods(cls)
    if not methods:
        return []
    option = re.search(r"^   :inherited-members:(.*)$", page, re.M)
    excluded = {n.strip() for n in option.group(1).split(",")} if option else None
    missing = []
    for name in sorted(methods):
        owner = next(k for k in cls.__mro__ if name in vars(k))
        # autodoc documents it: defined on the class, or inherited from a base not excluded
        documented = owner is cls or (excluded is not None and owner.__name__ not in excluded)
        listed = re.search(rf"^      ~{re.escape(cls.__qualname__)}\.{name}$", page, re.M)
        if not (documented and listed):
            missing.append(name)
    return missing


def test_api_pages_list_every_public_method(tmp_path):
    """Each public class's API page documents and lists (in its Methods table) every public
    method, inherited ones included (issue #32: ``predict_update`` of the filters, ``fit`` and
    ``predict`` of the model family were missing)."""
    pages = _class_pages(tmp_path)
    assert len(pages) > 40 and "rlsfilt.RecursiveLeastSquares" in pages
    gaps = {full: m for full, page in pages.items() if (m := _missing_methods(full, page))}
    assert not gaps, f"public methods missing from their API pages: {gaps}"
    assert "predict_update" in _public_methods(_resolve("rlsfilt.RecursiveLeastSquares"))


def test_missing_methods_finds_a_gap():
    """The check fails on a page without inherited members or without a listed method."""
    page = ".. autoclass:: ARMAX\n   :members:\n\n      ~ARMAX.fit\n"
    missing = _missing_methods("rlsfilt.ARMAX", page)
    assert "fit" in missing or "predict" in missing
    assert "predict" in missing and "summary" in missing


# ----------------------------------------------------------------------
# markup that renders: MyST roles on MyST pages, no escaped underscores in math text
# ----------------------------------------------------------------------
_RST_ROLE = re.compile(r"(?<![`\w}]):(func|class|meth|mod|attr|obj|doc|ref|data|exc):`")
_MATH_TEXT_ESCAPE = re.compile(r"\\(?:text|texttt|textrm|mbox)\{[^}]*\\_")


def _prose(text):
    """`text` without its fenced code blocks (a role inside code is shown as written)."""
    return re.sub(r"^```(?!\{)[^\n]*\n.*?^```$", "", text, flags=re.M | re.S)


def test_myst_pages_use_myst_roles():
    """An rST role (``:func:`x```) on a MyST page prints as raw text: use ``{func}`x```."""
    bad = [f"{p.relative_to(DOCS)}: {m.group(0)}" for p in PAGES if p.name != "changelog.md"
           for m in _RST_ROLE.finditer(_prose(p.read_text()))]
    assert not bad, bad


def test_math_text_has_no_escaped_underscores():
    """MathJax prints ``\\_`` inside ``\\text{}`` literally (``spread\\_max``): use
    ``\\mathtt{spread\\_max}``, where it is an underscore."""
    files = ([p for p in PAGES if p.name != "changelog.md"]
             + sorted((ROOT / "rlsfilt").rglob("*.py")))
    bad = [f"{p.relative_to(ROOT)}: {m.group(0)}" for p in files
           for m in _MATH_TEXT_ESCAPE.finditer(p.read_text())]
    assert not bad, bad
    assert _MATH_TEXT_ESCAPE.search(r"$\texttt{spread\_max}$")


@pytest.mark.parametrize("page", ["quickstart.md", "theory.md"]
                         + [f"guide/{p.name}" for p in sorted((DOCS / "guide").glob("*.md"))])
def test_pages_link_to_the_api(page):
    """The quick start, the theory and every guide page link API names (MyST roles)."""
    assert re.search(r"\{(class|func|meth)\}`[~]?rlsfilt\.", (DOCS / page).read_text()), (
        f"{page} links no API name: write {{class}}`~rlsfilt.Name` for the main ones")


# ----------------------------------------------------------------------
# the hand-kept lists of the forgetting modes (docs/develop.md, "Adding a forgetting mode")
# ----------------------------------------------------------------------
_MODE_ROW = re.compile(r'^\| `"(?P<mode>\w+)"` \|.*\| (?P<ref>[^|]+) \|$', re.M)


def mode_list_gaps(modes, docstring, robust, theory):
    """What the hand-kept lists of the forgetting modes miss: a mode not in the
    ``forgetting`` parameter of the docstring, not in the table of ``robust.md``, or
    whose reference there (first author) is not among ``theory.md``'s references."""
    gaps = []
    param = re.search(r"^    forgetting : [^\n]*\n        One of \{(.*?)\}", docstring,
                      re.M | re.S)                      # the set may wrap
    listed = re.findall(r'"(\w+)"', param.group(1)) if param else []
    rows = {m.group("mode"): m.group("ref") for m in _MODE_ROW.finditer(robust)}
    references = theory.split("## References", 1)[-1]
    for mode in modes:
        if mode not in listed:
            gaps.append(f"{mode}: not in RecursiveLeastSquares' `forgetting` parameter")
        if mode not in rows:
            gaps.append(f"{mode}: no row in docs/guide/robust.md's table of modes")
        elif re.match(r"\s*([^\W\d]+)", rows[mode]).group(1) not in references:
            gaps.append(f"{mode}: its reference ({rows[mode].strip()}) not in docs/theory.md")
    return gaps


def test_every_forgetting_mode_is_in_the_hand_kept_lists():
    from rlsfilt import RecursiveLeastSquares
    from rlsfilt.filters.forgetting import MODES

    assert mode_list_gaps(MODES, RecursiveLeastSquares.__doc__,
                          (DOCS / "guide" / "robust.md").read_text(),
                          (DOCS / "theory.md").read_text()) == []


def test_mode_list_gaps_finds_a_missing_mode():
    doc = ('    forgetting : str, default "exponential"\n'
           '        One of {"exponential",\n        "efra"}: how old data is forgotten.\n')
    robust = ('| `"exponential"` | all | Ljung (1999) |\n'
              '| `"regularized"` | some | Nobody (2030) |\n')
    theory = "## References\n- L. Ljung, ...\n"
    assert mode_list_gaps(("exponential", "regularized", "efra"), doc, robust, theory) == [
        "regularized: not in RecursiveLeastSquares' `forgetting` parameter",
        "regularized: its reference (Nobody (2030)) not in docs/theory.md",
        "efra: no row in docs/guide/robust.md's table of modes"]
