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
