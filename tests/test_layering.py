"""The package is layered: no import runs back up a layer, lazy imports included.

Layers, bottom to top (``docs/develop.md``, "Layers"): the support modules
(argument checks, exceptions, scaling, plotting, the data containers, ...),
``filters``, ``models``, ``validation`` (with ``datasets``, which fits models
to describe its plants), then the applications (``adaptive``, the command
line, ``dask``) and the package's ``__init__`` that exports them all. A
module may import its own layer and the layers below. Every import counts:
at module level, inside a function, and the lazy kernel loader's
``lazy_module("...")`` (the import graph of ``tests/test_import_graph.py``).
Every module must belong to a layer, so a new top-level module has to be
placed here. The checker is run on synthetic module maps too, so the test can
fail.
"""

import ast

from test_import_graph import import_graph

#: Module prefixes of each layer, bottom first (the longest matching prefix wins).
LAYERS = [
    ("support", ["rlsfilt.exceptions", "rlsfilt._version", "rlsfilt._validation",
                 "rlsfilt._resources", "rlsfilt._display", "rlsfilt._scale", "rlsfilt._numba",
                 "rlsfilt._serialize", "rlsfilt._lazy_scipy", "rlsfilt._lazy", "rlsfilt._warmup",
                 "rlsfilt._locking", "rlsfilt._progress",
                 "rlsfilt._iosystem", "rlsfilt.plotting", "rlsfilt.continuous", "rlsfilt.data",
                 "rlsfilt._atomic", "rlsfilt._model_file"]),
    ("filters", ["rlsfilt.filters"]),
    ("models", ["rlsfilt.models", "rlsfilt.persistence"]),
    ("validation", ["rlsfilt.validation", "rlsfilt.datasets"]),
    ("applications", ["rlsfilt.adaptive", "rlsfilt.cli", "rlsfilt._cli_args",
                      "rlsfilt._cli_fleet", "rlsfilt.dask", "rlsfilt.river", "rlsfilt.sklearn",
                      "rlsfilt.__main__"]),
    ("package", ["rlsfilt"]),
]


def layer_of(module, layers=LAYERS):
    """The index of `module`'s layer (longest matching prefix), or None. The package
    itself (a prefix without a dot) is only its ``__init__``, never its submodules."""
    best, best_len = None, -1
    for i, (_, prefixes) in enumerate(layers):
        for prefix in prefixes:
            inside = "." in prefix and module.startswith(prefix + ".")
            if (module == prefix or inside) and len(prefix) > best_len:
                best, best_len = i, len(prefix)
    return best


def layering_violations(graph, layers=LAYERS):
    """``(unplaced modules, upward imports)``: the modules of `graph` in no layer, and
    every edge ``(importer, imported)`` whose target lies in a higher layer."""
    unplaced = sorted(m for m in graph if layer_of(m, layers) is None)
    upward = sorted((m, d) for m, deps in graph.items() for d in deps
                    if None not in (layer_of(m, layers), layer_of(d, layers))
                    and layer_of(d, layers) > layer_of(m, layers))
    return unplaced, upward


def test_checker_finds_upward_and_unplaced_modules():
    layers = [("low", ["p.low"]), ("high", ["p.high"]), ("top", ["p"])]
    good = {"p": {"p.high"}, "p.high": {"p.low", "p.high.x"}, "p.high.x": set(),
            "p.low": set()}
    assert layering_violations(good, layers) == ([], [])
    bad = {**good, "p.low": {"p.high.x"}, "p.stray": set()}
    assert layering_violations(bad, layers) == (["p.stray"], [("p.low", "p.high.x")])
    # the longest prefix decides: p.high.x is "high", not "top"
    assert layer_of("p.high.x", layers) == 1 and layer_of("p", layers) == 2


def test_checker_sees_a_lazy_upward_import(tmp_path, monkeypatch):
    """A violation written as a function-level import, and as a lazy kernel load, fails."""
    import test_import_graph as g
    pkg = tmp_path / "p"
    (pkg / "low").mkdir(parents=True)
    (pkg / "high").mkdir()
    for name in ("__init__.py", "low/__init__.py", "high/__init__.py", "high/k.py"):
        (pkg / name).write_text("")
    (pkg / "low" / "a.py").write_text("def f():\n    from ..high import k\n")
    (pkg / "low" / "b.py").write_text("k = lazy_module('p.high.k')\n")
    monkeypatch.setattr(g, "ROOT", tmp_path)
    modules = {g.module_name(p) for p in pkg.rglob("*.py")}
    graph = {g.module_name(p): g.imports_of(p, modules) for p in sorted(pkg.rglob("*.py"))}
    layers = [("low", ["p.low"]), ("high", ["p.high"]), ("top", ["p"])]
    assert layering_violations(graph, layers)[1] == [("p.low.a", "p.high.k"),
                                                     ("p.low.b", "p.high.k")]


def test_rlsfilt_imports_never_go_up_a_layer():
    graph = import_graph()
    unplaced, upward = layering_violations(graph)
    assert not unplaced, f"modules in no layer (add them to LAYERS): {unplaced}"
    assert not upward, "imports up a layer: " + "; ".join(f"{a} -> {b}" for a, b in upward)


# ----------------------------------------------------------------------
# no module outside rlsfilt/filters reaches into a filter's private members
# ----------------------------------------------------------------------
#: The modules that define the filters and banks (their classes' private members).
FILTER_MODULES = ("_base", "contract", "rls", "sliding_window", "square_root", "gradient",
                  "bank", "gradient_bank")
#: Private names that outside code may use on its *own* objects (a same-named member
#: of its own class, not a filter's), by module: each with its reason.
OWN_MEMBERS = {
    # RecursivePEM copies itself (`other`, `new` are RecursivePEM objects)
    "rlsfilt/models/_recursive_pem.py": {"_warned_health", "_work"},
    # the stepping protocol of python-control systems (`_get_state`, `_set_state`, ...)
    # is the objects' own (rlsfilt._iosystem's docstring)
    "rlsfilt/_iosystem.py": {"_get_state", "_set_state"},
}


def _private(name):
    """``_x``, not ``__init__`` nor a display protocol such as IPython's ``_repr_html_``."""
    return name.startswith("_") and not name.startswith("__") and not name.endswith("_")


def filter_private_members(paths):
    """The private methods and attributes the classes of the modules `paths` define."""
    names = set()
    for path in paths:
        tree = ast.parse(path.read_text())
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            for node in ast.walk(cls):
                if isinstance(node, ast.FunctionDef) and _private(node.name):
                    names.add(node.name)
                elif isinstance(node, ast.Assign):              # class attributes
                    names.update(t.id for t in node.targets
                                 if isinstance(t, ast.Name) and _private(t.id))
                elif (isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store)
                      and getattr(node.value, "id", None) == "self" and _private(node.attr)):
                    names.add(node.attr)
    return names


def private_reaches(path, members, filters_dir, allowed=frozenset()):
    """``(line, text)`` of each use in the module at `path` of a filter's private member
    (`members`) on an object other than ``self``/``cls``/``super()``, and of each
    private name imported from the filters package that is not a module of it."""
    found = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Attribute) and node.attr in members - allowed:
            owner = node.value
            if getattr(owner, "id", None) in ("self", "cls") or (
                    isinstance(owner, ast.Call) and getattr(owner.func, "id", None) == "super"):
                continue
            found.append((node.lineno, ast.unparse(node)))
        elif isinstance(node, ast.ImportFrom) and "filters" in (node.module or "").split("."):
            found += [(node.lineno, f"from {node.module} import {a.name}") for a in node.names
                      if _private(a.name) and not (filters_dir / f"{a.name}.py").exists()]
    return found


def test_no_module_reaches_into_a_filters_private_members():
    """The models, validation, the applications and the support modules use the filters'
    public API and contract (``get_state``/``set_state``, ...), never their private
    members (#26: ``models/arx.py`` used 12 of them, ``adaptive`` 12 more)."""
    import test_import_graph as g

    filters_dir = g.ROOT / "rlsfilt" / "filters"
    members = filter_private_members(filters_dir / f"{m}.py" for m in FILTER_MODULES)
    assert {"_x", "_P", "_shallow_state", "_restore", "_written_in_place"} <= members
    bad = []
    for path in sorted((g.ROOT / "rlsfilt").rglob("*.py")):
        rel = path.relative_to(g.ROOT).as_posix()
        if rel.startswith("rlsfilt/filters/"):
            continue
        bad += [f"{rel}:{line}: {text}" for line, text in
                private_reaches(path, members, filters_dir, OWN_MEMBERS.get(rel, frozenset()))]
    assert not bad, "private members of the filters used outside them:\n" + "\n".join(bad)


def test_the_private_member_scan_can_fail(tmp_path):
    code = ("from rlsfilt.filters.bank import _full_rank\n"
            "from rlsfilt.filters import _health\n"
            "def f(bank, self):\n"
            "    self._x = bank._P0\n"
            "    return super()._x, bank.P\n")
    (tmp_path / "m.py").write_text(code)
    (tmp_path / "_health.py").write_text("")
    found = private_reaches(tmp_path / "m.py", {"_x", "_P0", "_full_rank"}, tmp_path)
    assert sorted(found) == [(1, "from rlsfilt.filters.bank import _full_rank"),
                             (4, "bank._P0")]


# ----------------------------------------------------------------------
# one lazy kernel loader
# ----------------------------------------------------------------------
def kernel_imports_in_functions(path):
    """``(line, module)`` of each import of a compiled kernel module (``*_kernels*``)
    written inside a function of the module at `path`: a lazy import by hand, past
    the one loader (`rlsfilt._lazy.lazy_module`, which also says when a cold first
    use compiles)."""
    found = []
    for fn in ast.walk(ast.parse(path.read_text())):
        if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
            continue
        for node in ast.walk(fn):
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            if any("_kernels" in n.rpartition(".")[2] for n in names):
                found.append((node.lineno, ast.unparse(node)))
    return found


def test_kernel_modules_load_through_the_one_lazy_loader():
    import test_import_graph as g

    bad = [f"{p.relative_to(g.ROOT)}:{line}: {text}"
           for p in sorted((g.ROOT / "rlsfilt").rglob("*.py"))
           for line, text in kernel_imports_in_functions(p)]
    assert not bad, "kernel modules imported by hand (use lazy_module):\n" + "\n".join(bad)


def test_the_kernel_import_scan_can_fail(tmp_path):
    (tmp_path / "m.py").write_text(
        "from .filters import _kernels_x\n"
        "def f():\n    from ..filters._kernels_lagged import lag_gram\n"
        "    from . import _kernels_fleet\n    import numpy\n")
    assert [line for line, _ in kernel_imports_in_functions(tmp_path / "m.py")] == [3, 4]
