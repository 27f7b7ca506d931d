"""Sphinx configuration for the rlsfilt documentation.

Build with ``python -m sphinx -W --keep-going -b html docs docs/_build/html``.
The notebooks live in ``notebooks/`` (committed without outputs); they are
copied into ``docs/notebooks/`` at build time and executed by myst-nb, with
results cached in ``docs/_build/.jupyter_cache`` so a rebuild only reruns a
notebook that changed.
"""

import os
import re
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS))  # _gallery.py: the gallery's scraper and matplotlib reset
# the notebook kernels are subprocesses: let them import this checkout too
os.environ["PYTHONPATH"] = os.pathsep.join(
    [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
# figures in the executed notebooks: the inline backend, even when the caller
# (CI) exported MPLBACKEND=Agg for the test suite
os.environ["MPLBACKEND"] = "module://matplotlib_inline.backend_inline"
# ... at 150 dpi (docs/_static/matplotlibrc; the inline backend keeps the rc file's dpi)
os.environ["MATPLOTLIBRC"] = str(DOCS / "_static" / "matplotlibrc")

import rlsfilt  # noqa: E402

# The "download / open in Binder" line of each rendered notebook: plain links, nothing is
# fetched at build time. RLSFILT_REPO (owner/name on GitHub) and RLSFILT_BRANCH name the public
# repository Binder starts from.
REPO = os.environ.get("RLSFILT_REPO", "rlsfilt/rlsfilt")
BRANCH = os.environ.get("RLSFILT_BRANCH", "main")


def _with_links(raw, name):
    """The notebook `raw` (JSON text) with a markdown cell of links after its title cell."""
    import json

    nb = json.loads(raw)
    binder = f"https://mybinder.org/v2/gh/{REPO}/{BRANCH}?labpath=notebooks%2F{name}"
    links = (f"{{download}}`Download this notebook <../../notebooks/{name}>` (`{name}`, no "
             f"outputs) · [open it in Binder]({binder}) · run it locally with "
             f"`python -m pip install -e \".[notebooks]\" && jupyter lab notebooks/{name}`")
    cell = {"cell_type": "markdown", "id": "rlsfilt-links", "metadata": {},
            "source": ["```{container} rlsfilt-nb-links\n", links + "\n", "```"]}
    nb["cells"].insert(1 if nb["cells"] else 0, cell)
    return json.dumps(nb, indent=1, ensure_ascii=False) + "\n"


def _copy_notebooks():
    """Mirror ``notebooks/*.ipynb`` into ``docs/notebooks/`` (git-ignored), each with its
    download and Binder links; outputs are added when myst-nb executes them."""
    src, dst = ROOT / "notebooks", DOCS / "notebooks"
    dst.mkdir(exist_ok=True)
    wanted = {p.name for p in src.glob("*.ipynb")}
    for old in dst.glob("*.ipynb"):
        if old.name not in wanted:
            old.unlink()
    for nb in src.glob("*.ipynb"):
        target = dst / nb.name
        text = _with_links(nb.read_text(encoding="utf-8"), nb.name)
        if not target.exists() or target.read_text(encoding="utf-8") != text:
            target.write_text(text, encoding="utf-8")


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
    # MathJax 3 shipped in the package and copied into _static/mathjax: the pages render
    # their math with no network (it sets mathjax_path to the local tex-chtml.js)
    "sphinx-mathjax-offline",
    "sphinx.ext.viewcode",
    "sphinx.ext.intersphinx",
    "sphinx_copybutton",
    "numpydoc",
    "matplotlib.sphinxext.plot_directive",
    "myst_nb",
    "sphinx_gallery.gen_gallery",
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
# the gallery writes a notebook beside each example for download: not a page to build
exclude_patterns = ["_build", "**.ipynb_checkpoints", "Thumbs.db", ".DS_Store",
                    "auto_examples/*.ipynb", "auto_examples/**/*.ipynb"]
templates_path = ["_templates"]

# API reference: one generated page per public name (see docs/api/index.rst)
autosummary_generate = True
autosummary_imported_members = True
autodoc_default_options = {"members": True, "inherited-members": False}
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
# an Examples section that imports matplotlib runs through the plot directive: the API pages of
# the plotting functions show the figure their example draws
numpydoc_use_plots = True

# Links to numpy, scipy, python-control, filterpy and matplotlib, made offline: each project's
# inventory is read from docs/_inventories/ (written by docs/_make_inventories.py from the
# installed packages; a project's real objects.inv can replace its file), never fetched.
intersphinx_mapping = {
    "numpy": ("https://numpy.org/doc/stable/", "_inventories/numpy.inv"),
    "scipy": ("https://docs.scipy.org/doc/scipy/", "_inventories/scipy.inv"),
    "control": ("https://python-control.readthedocs.io/en/stable/", "_inventories/control.inv"),
    "matplotlib": ("https://matplotlib.org/stable/", "_inventories/matplotlib.inv"),
    "filterpy": ("https://filterpy.readthedocs.io/en/latest/", "_inventories/filterpy.inv"),
}

# a copy button on every code block; prompts ($, >>>, ...) and outputs are not copied
copybutton_prompt_text = r">>> |\.\.\. |\$ "
copybutton_prompt_is_regexp = True
copybutton_exclude = ".linenos, .gp, .go"

# MyST and the notebooks
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
nb_execution_mode = "cache"
nb_execution_cache_path = str(DOCS / "_build" / ".jupyter_cache")
nb_execution_timeout = 180
nb_execution_raise_on_error = True
nb_execution_show_tb = True
nb_merge_streams = True
# no widget JavaScript from a CDN: the slider cell of the tracking notebook hides its output in
# the docs (tag remove-output) and the static figure before it stands in
nb_ipywidgets_js = {}

html_theme = "sphinx_rtd_theme"
html_title = f"rlsfilt {release}"
html_static_path = ["_static"]
html_css_files = ["rlsfilt.css"]   # wide tables scroll in their own box, figures fit the column
html_theme_options = {"navigation_depth": 3}

# ----------------------------------------------------------------------
# the gallery: examples/plot_*.py run at build time (sphinx-gallery), one page and a
# thumbnail each; the API pages of the functions they call list them (minigallery)
# ----------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"plot_",
    "doc_module": ("rlsfilt",),
    "backreferences_dir": "api/generated/backreferences",
    "reset_modules": ("matplotlib", "_gallery.reset_matplotlib"),
    "image_scrapers": ("_gallery.scraper",),
    "abort_on_example_error": True,
    "download_all_examples": False,
    "write_computation_times": False,
    "remove_config_comments": True,
    "thumbnail_size": (400, 280),
    "within_subsection_order": "FileNameSortKey",
    "matplotlib_animations": False,
}

# matplotlib's plot directive (figures inside docstrings and pages) at the same resolution
plot_formats = [("png", 150)]
plot_include_source = True
plot_html_show_formats = False
plot_html_show_source_link = False


# The adapters' classes inherit methods from river and scikit-learn (``score``,
# ``set_fit_request``, ...), whose docstrings point into those projects' own
# documentation (``:ref:``, ``:term:`` labels we have no inventory for, offline).
# Their cross-references are shown as plain text on our pages.
_FOREIGN_ROLE = re.compile(r":(?:ref|term|doc):`([^`<]*?)\s*(?:<[^>]*>)?`")


def _plain_foreign_references(app, what, name, obj, options, lines):
    module = getattr(obj, "__module__", None) or ""
    if name.startswith("rlsfilt.") and module.split(".")[0] in ("sklearn", "river"):
        lines[:] = [_FOREIGN_ROLE.sub(lambda m: f"*{m.group(1).strip()}*", line)
                    for line in lines]


def setup(app):
    app.connect("autodoc-process-docstring", _plain_foreign_references)
