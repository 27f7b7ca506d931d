"""The one lazy loader of the compiled kernel modules.

``import rlsfilt`` does not load numba: a module that calls compiled kernels
holds ``kernels = lazy_module("rlsfilt.filters._kernels")`` and calls
``kernels()`` where it needs them; the first call imports the module (and
compiles or loads its cache; when nothing of it is cached yet, one message on
the ``rlsfilt`` logger says that kernels are being compiled, see
:mod:`rlsfilt._warmup`), later calls return it. The import-graph tests
read the string argument as an import of that module
(``tests/test_import_graph.py``), so a lazy kernel import counts for the
layering like any other.
"""

import importlib

__all__ = []


def lazy_module(name):
    """A function returning the module `name` (absolute), imported on its first call."""
    loaded = []

    def load():
        if not loaded:
            module = importlib.import_module(name)
            from . import _warmup

            _warmup.announce_cold(module)     # one message when its cache is empty
            loaded.append(module)
        return loaded[0]

    load.__doc__ = f"The module `{name}`, imported on first use (numba stays unloaded until then)."
    return load
