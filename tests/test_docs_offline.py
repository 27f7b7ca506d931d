"""The documentation renders its math with no network: MathJax ships with the docs.

A tiny Sphinx project with the documentation's math extensions is built in a
subprocess and its HTML must load MathJax from ``_static``, never from a
remote address; the real configuration must use the same extension. When the
full documentation has been built (``docs/_build/html``, as in ``.ci/run``),
every page of it is checked too.
"""

import ast
import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
REMOTE_MATHJAX = re.compile(r"""<script[^>]+src=["'](https?:)?//[^"']*mathjax""", re.I)
SCRIPT_SRC = re.compile(r"""<script[^>]+src=["']([^"']+)["']""", re.I)


def _conf_value(name):
    """The literal value assigned to `name` in docs/conf.py (without executing it)."""
    tree = ast.parse((DOCS / "conf.py").read_text())
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", None) == name
                                                for t in node.targets):
            return ast.literal_eval(node.value)
    raise AssertionError(f"docs/conf.py does not set {name}")


def test_conf_uses_the_bundled_mathjax():
    extensions = _conf_value("extensions")
    assert "sphinx.ext.mathjax" in extensions and "sphinx-mathjax-offline" in extensions
    with pytest.raises(AssertionError, match="does not set"):
        _conf_value("mathjax_path")   # the extension sets it; a conf.py value would override it
    # the extension ships the MathJax file it points the pages to
    ext = importlib.import_module("sphinx-mathjax-offline")
    local = Path(ext.__file__).parent / "static" / "mathjax" / "tex-chtml.js"
    assert local.is_file() and local.stat().st_size > 100_000


def test_small_build_has_no_remote_mathjax(tmp_path):
    src, out = tmp_path / "src", tmp_path / "html"
    src.mkdir()
    (src / "conf.py").write_text(
        "extensions = ['sphinx.ext.mathjax', 'sphinx-mathjax-offline']\n")
    (src / "index.rst").write_text("Math\n====\n\n.. math::\n\n   \\hat\\theta_k = P_k "
                                   "\\Phi_k^T Y_k\n\nand :math:`\\lambda \\in (0, 1]`.\n")
    done = subprocess.run([sys.executable, "-m", "sphinx", "-q", "-W", "-b", "html",
                           str(src), str(out)], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    page = (out / "index.html").read_text()
    assert not REMOTE_MATHJAX.search(page), REMOTE_MATHJAX.search(page).group(0)
    scripts = [s for s in SCRIPT_SRC.findall(page) if "mathjax" in s.lower()]
    assert scripts == ["_static/mathjax/tex-chtml.js"]
    assert (out / "_static" / "mathjax" / "tex-chtml.js").is_file()
    # and MathJax finds its fonts and TeX extensions beside it
    assert any((out / "_static" / "mathjax" / "output" / "chtml" / "fonts").rglob("*.woff"))


def test_built_documentation_has_no_remote_script():
    """Every page of a finished full build (CI builds it after the tests; skipped before)."""
    html = DOCS / "_build" / "html"
    pages = sorted(html.rglob("*.html")) if html.is_dir() else []
    if not (html / "_static" / "mathjax" / "tex-chtml.js").is_file() or not pages:
        pytest.skip("no full documentation build with the bundled MathJax in docs/_build/html")
    remote = {}
    for page in pages:
        srcs = [s for s in SCRIPT_SRC.findall(page.read_text(errors="replace"))
                if re.match(r"(https?:)?//", s)]
        if srcs:
            remote[str(page.relative_to(html))] = srcs
    assert not remote, f"pages loading scripts from the network: {remote}"


def test_intersphinx_reads_the_shipped_inventories():
    """Intersphinx links numpy, scipy, python-control, filterpy and matplotlib with no network:
    every project's inventory is a file in docs/_inventories/ that Sphinx can read, and it
    holds the names the pages link to."""
    import posixpath

    from sphinx.util.inventory import InventoryFile

    assert "sphinx.ext.intersphinx" in _conf_value("extensions")
    mapping = _conf_value("intersphinx_mapping")
    assert set(mapping) == {"numpy", "scipy", "control", "matplotlib", "filterpy"}
    wanted = {"numpy": ("py:class", "numpy.ndarray"),
              "scipy": ("py:function", "scipy.signal.lfilter"),
              "control": ("py:class", "control.TransferFunction"),
              "matplotlib": ("py:class", "matplotlib.figure.Figure"),
              "filterpy": ("py:class", "filterpy.kalman.KalmanFilter")}
    for project, (url, inventory) in mapping.items():
        assert url.startswith("https://") and url.endswith("/"), url
        assert isinstance(inventory, str) and not re.match(r"https?:", inventory), (
            f"{project}: the inventory must be a local file, not {inventory!r}")
        path = DOCS / inventory
        assert path.is_file(), f"{path} is missing (run python docs/_make_inventories.py)"
        with path.open("rb") as f:
            inv = InventoryFile.load(f, url, posixpath.join)
        role, name = wanted[project]
        item = inv[role][name]
        uri = getattr(item, "uri", None) or item[2]
        assert uri.startswith(url), uri


def test_copy_button_is_enabled():
    assert "sphinx_copybutton" in _conf_value("extensions")
    # the docs extra installs it (the test extra does not: CI's test run has no Sphinx)
    import configparser

    cfg = configparser.ConfigParser()
    cfg.read(ROOT / "setup.cfg")
    docs_extra = cfg["options.extras_require"]["docs"]
    assert "sphinx-copybutton" in docs_extra
