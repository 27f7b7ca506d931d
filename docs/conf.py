"""Sphinx configuration for the rlsfilt documentation.

Build with ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
The notebooks live in ``notebooks/`` (committed without outputs); they are
copied into ``docs/notebooks/`` at build time and executed by myst-nb, with
results cached in ``docs/_build/.jupyter_cache`` so a rebuild only reruns a
notebook that changed.
"""

import os
import shutil
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))
# the notebook kernels are subprocesses: let them import this checkout too
os.environ["PYTHONPATH"] = os.pathsep.join(
    [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
# figures in the executed notebooks: the inline backend, even when the caller
# (CI) exported MPLBACKEND=Agg for the test suite
os.environ["MPLBACKEND"] = "module://matplotlib_inline.backend_inline"

import rlsfilt  # noqa: E402


def _copy_notebooks():
    """Mirror ``notebooks/*.ipynb`` into ``docs/notebooks/`` (git-ignored)."""
    src, dst = ROOT / "notebooks", DOCS / "notebooks"
    dst.mkdir(exist_ok=True)
    wanted = {p.name for p in src.glob("*.ipynb")}
    for old in dst.glob("*.ipynb"):
        if old.name not in wanted:
            old.unlink()
    for nb in src.glob("*.ipynb"):
        target = dst / nb.name
        if not target.exists() or target.read_bytes() != nb.read_bytes():
            shutil.copyfile(nb, target)


_copy_notebooks()

project = "rlsfilt"
author = "rlsfilt developers"
copyright = "2026, rlsfilt developers"
release = rlsfilt.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_nb",
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
exclude_patterns = ["_build", "**.ipynb_checkpoints", "Thumbs.db", ".DS_Store"]
templates_path = ["_templates"]

# API reference: one generated page per public name (see docs/api/index.rst)
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": True, "inherited-members": False}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# MyST and the notebooks
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
nb_execution_mode = "cache"
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_timeout = 180
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True

html_theme = "sphinx_rtd_theme"
html_title = f"rlsfilt {release}"
html_static_path = []
html_theme_options = {"navigation_depth": 3}
