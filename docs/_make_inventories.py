"""Write the intersphinx inventories in ``docs/_inventories/`` from the installed packages.

The documentation links ``numpy.ndarray``, ``scipy.signal.lfilter``, ``control.TransferFunction``,
``filterpy.kalman.KalmanFilter`` and ``matplotlib.figure.Figure`` to their projects' pages with
``sphinx.ext.intersphinx``. The build must work offline, so ``docs/conf.py`` reads each
project's ``objects.inv`` from ``docs/_inventories/`` instead of fetching it. The projects'
own inventories cannot be downloaded where the documentation is built, so this script makes
equivalent ones: it walks the public names of the installed packages and writes, for each, the
address of its page in that project's documentation (the URL patterns of each project's Sphinx
site, as of the versions named in ``setup.cfg``'s extras).

Run it again after upgrading one of these packages (the files are committed)::

    python docs/_make_inventories.py            # all five
    python docs/_make_inventories.py numpy      # one

An inventory is Sphinx's format version 2: four header lines, then zlib-compressed lines
``name domain:role priority uri dispname`` (``$`` in the uri stands for the name, ``-`` for
a display name equal to the name). A project's real ``objects.inv`` can replace a generated
one at any time (same file name), e.g. ``curl -o docs/_inventories/numpy.inv
https://numpy.org/doc/stable/objects.inv`` where the network allows it.
"""

import importlib
import inspect
import sys
import zlib
from pathlib import Path

OUT = Path(__file__).resolve().parent / "_inventories"

# the documentation address of each project (docs/conf.py's intersphinx_mapping uses the same)
URLS = {
    "numpy": "https://numpy.org/doc/stable/",
    "scipy": "https://docs.scipy.org/doc/scipy/",
    "control": "https://python-control.readthedocs.io/en/stable/",
    "matplotlib": "https://matplotlib.org/stable/",
    "filterpy": "https://filterpy.readthedocs.io/en/latest/",
}


def _public(module):
    names = getattr(module, "__all__", None)
    # filterpy.common's __all__ lists its submodules, not the names it imports from them
    if names is None or all(inspect.ismodule(getattr(module, n, None)) for n in names):
        names = [n for n in dir(module) if not n.startswith("_")]
    return [n for n in names if not n.startswith("_") and hasattr(module, n)]


def _role(obj):
    if inspect.ismodule(obj):
        return "module"
    if inspect.isclass(obj):
        return "exception" if issubclass(obj, BaseException) else "class"
    if callable(obj):
        return "function"
    return "data"


def _methods(cls):
    for name, value in vars(cls).items():
        if name.startswith("_"):
            continue
        if isinstance(value, property) or inspect.isgetsetdescriptor(value) \
                or inspect.ismemberdescriptor(value):
            yield name, "attribute"
        elif callable(value) or isinstance(value, (staticmethod, classmethod)):
            yield name, "method"


def _walk(modules, page, own_module=None, methods_page=None):
    """``(name, role, uri)`` of the public names of `modules`: `page(full name, role)` gives
    a name's uri; the methods of a class are on `methods_page(class name, method)` (default:
    the class's page). `own_module(obj)` says whether an object belongs to the project (names
    a module re-exports from elsewhere, such as ``numpy.linalg.norm`` in scipy, are skipped)."""
    seen = set()
    for modname in modules:
        module = importlib.import_module(modname)
        yield modname, "module", page(modname, "module")
        for n in _public(module):
            obj = getattr(module, n)
            full = f"{modname}.{n}"
            if inspect.ismodule(obj) or full in seen:
                continue
            if own_module and not own_module(obj):
                continue
            seen.add(full)
            role = _role(obj)
            yield full, role, page(full, role)
            if inspect.isclass(obj):
                for m, mrole in _methods(obj):
                    uri = (methods_page(full, m) if methods_page
                           else page(full, role).split("#")[0] + f"#{full}.{m}")
                    yield f"{full}.{m}", mrole, uri


def _belongs(package):
    def own(obj):
        mod = getattr(obj, "__module__", None)
        return mod is None or not isinstance(mod, str) or mod.split(".")[0] == package \
            or mod == "builtins"
    return own


def numpy_entries():
    def page(full, role):
        if role == "module":
            return f"reference/routines.html#module-{full}"
        if role == "data":
            return f"reference/constants.html#{full}"
        where = "reference/random/generated" if full.startswith("numpy.random.") \
            else "reference/generated"
        return f"{where}/{full}.html#{full}"

    def methods_page(cls, m):
        where = "reference/random/generated" if cls.startswith("numpy.random.") \
            else "reference/generated"
        return f"{where}/{cls}.{m}.html#{cls}.{m}"

    return _walk(["numpy", "numpy.linalg", "numpy.random", "numpy.fft", "numpy.testing",
                  "numpy.polynomial"], page, methods_page=methods_page)


def scipy_entries():
    def page(full, role):
        if role == "module":
            return f"reference/{full.split('.', 1)[1]}.html#module-{full}"
        return f"reference/generated/{full}.html#{full}"

    return _walk(["scipy.signal", "scipy.linalg", "scipy.stats", "scipy.optimize",
                  "scipy.interpolate", "scipy.special"], page, own_module=_belongs("scipy"))


def control_entries():
    def page(full, role):
        if role == "module":
            return "index.html#module-control"
        return f"generated/{full}.html#{full}"

    return _walk(["control"], page, own_module=_belongs("control"))


def matplotlib_entries():
    def page(full, role):
        if role == "module":
            return f"api/{full.split('.')[-1]}_api.html#module-{full}"
        return f"api/_as_gen/{full}.html#{full}"

    def methods_page(cls, m):
        if cls == "matplotlib.axes.Axes":
            return f"api/_as_gen/{cls}.{m}.html#{cls}.{m}"
        return f"api/_as_gen/{cls}.html#{cls}.{m}"

    entries = list(_walk(["matplotlib.pyplot", "matplotlib.figure", "matplotlib.axes",
                          "matplotlib.lines", "matplotlib.colors"], page,
                         own_module=_belongs("matplotlib"), methods_page=methods_page))
    # the Axes class has its own page (the methods one page each, above)
    return [(n, r, "api/axes_api.html#matplotlib.axes.Axes" if n == "matplotlib.axes.Axes"
             else u) for n, r, u in entries]


def filterpy_entries():
    def page(full, role):
        if role == "module":
            return f"{full.split('.')[1]}/{full.split('.')[1]}.html#module-{full}"
        sub, name = full.split(".")[1], full.split(".")[-1]
        if role == "class" and sub == "kalman":
            return f"{sub}/{name}.html#{full}"
        return f"{sub}/{sub}.html#{full}"

    return _walk(["filterpy.kalman", "filterpy.common"], page, own_module=_belongs("filterpy"))


PROJECTS = {
    "numpy": numpy_entries,
    "scipy": scipy_entries,
    "control": control_entries,
    "matplotlib": matplotlib_entries,
    "filterpy": filterpy_entries,
}


def write(project):
    """Write ``docs/_inventories/<project>.inv``; returns its path and number of entries."""
    package = importlib.import_module(project)
    version = getattr(package, "__version__", "")
    lines, seen = [], set()
    for name, role, uri in PROJECTS[project]():
        if name in seen:
            continue
        seen.add(name)
        if uri.endswith(f"#{name}"):
            uri = uri[: -len(name)] + "$"
        lines.append(f"{name} py:{role} 1 {uri} -")
    header = (f"# Sphinx inventory version 2\n# Project: {project}\n# Version: {version}\n"
              "# The remainder of this file is compressed using zlib.\n")
    body = zlib.compress(("\n".join(sorted(lines)) + "\n").encode())
    OUT.mkdir(exist_ok=True)
    path = OUT / f"{project}.inv"
    path.write_bytes(header.encode() + body)
    return path, len(lines)


if __name__ == "__main__":
    for project in sys.argv[1:] or PROJECTS:
        path, n = write(project)
        print(f"{path.relative_to(OUT.parent.parent)}: {n} names")
