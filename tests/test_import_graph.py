"""The package has no import cycle.

Every module of rlsfilt is parsed with ``ast``; each ``import`` and ``from ...
import`` of an rlsfilt module, at module level or inside a function (a lazy
import is still a dependency), becomes an edge of the intra-package import
graph, which must be acyclic. A call ``lazy_module("rlsfilt.x.y")`` (the one
lazy kernel loader, ``rlsfilt/_lazy.py``) is an import of ``rlsfilt.x.y`` too.
The cycle finder itself is checked on graphs with and without a cycle, so the
test can fail.
"""

import ast
import pathlib

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGE = "rlsfilt"


def module_name(path):
    """``rlsfilt/filters/rls.py`` -> ``rlsfilt.filters.rls`` (a package is its ``__init__``)."""
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _resolve(name, level, current, is_package):
    """The absolute module of ``from <level dots><name> import ...`` in `current`."""
    if level == 0:
        return name
    base = current.split(".")
    if not is_package:
        base = base[:-1]
    base = base[:len(base) - (level - 1)]
    return ".".join(base + ([name] if name else []))


def imports_of(path, modules):
    """The rlsfilt modules that the module at `path` imports, anywhere in its body."""
    current = module_name(path)
    is_package = path.name == "__init__.py"
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif (isinstance(node, ast.Call) and getattr(node.func, "id", None) == "lazy_module"
              and node.args and isinstance(node.args[0], ast.Constant)):
            targets = [node.args[0].value]
        elif isinstance(node, ast.ImportFrom):
            base = _resolve(node.module, node.level, current, is_package)
            # `from . import x` imports the submodule x when there is one
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                       for a in node.names]
        else:
            continue
        for target in targets:
            while target and target not in modules:     # `import a.b.c` also imports a.b
                target = target.rpartition(".")[0]
            if target and target != current:
                found.add(target)
    return found


def import_graph():
    paths = sorted((ROOT / PACKAGE).rglob("*.py"))
    modules = {module_name(p) for p in paths}
    return {module_name(p): imports_of(p, modules) for p in paths}


def find_cycle(graph):
    """A list of modules forming a cycle (first == last), or None (depth-first search)."""
    state, stack = {}, []

    def visit(node):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == "open":
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                cycle = visit(nxt)
                if cycle:
                    return cycle
        state[node] = "done"
        stack.pop()
        return None

    for node in sorted(graph):
        if node not in state:
            cycle = visit(node)
            if cycle:
                return cycle
    return None


def test_cycle_finder_detects_a_synthetic_cycle():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"a"}}) == ["a", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


def test_import_resolution_sees_function_level_and_relative_imports(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    for name in ("__init__.py", "a.py", "sub/__init__.py", "sub/b.py"):
        (pkg / name).write_text("")
    (pkg / "a.py").write_text("def f():\n    from .sub import b\n\n"
                              "late = lazy_module('pkg.sub')\n")
    (pkg / "sub" / "b.py").write_text("from .. import a\nimport pkg.sub\n")
    modules = {"pkg", "pkg.a", "pkg.sub", "pkg.sub.b"}
    global ROOT
    saved, ROOT = ROOT, tmp_path
    try:
        graph = {module_name(p): imports_of(p, modules) for p in sorted(pkg.rglob("*.py"))}
    finally:
        ROOT = saved
    assert graph["pkg.a"] == {"pkg.sub.b", "pkg.sub"}
    assert graph["pkg.sub.b"] == {"pkg.a", "pkg.sub"}
    assert find_cycle(graph) == ["pkg.a", "pkg.sub.b", "pkg.a"]


def test_rlsfilt_import_graph_is_acyclic():
    graph = import_graph()
    assert "rlsfilt.filters.rls" in graph and "rlsfilt.filters._kernels" in graph
    # the lazy import of the kernels is an edge too
    assert "rlsfilt.filters._kernels" in graph["rlsfilt.filters._streaming"]
    cycle = find_cycle(graph)
    assert cycle is None, " -> ".join(cycle)
