"""The one place where rlsfilt asks numba to compile: `njit` with a disk cache when it can.

The compiled kernels are declared ``njit(cache=True)`` so that their machine
code is written to disk once and loaded by later processes. numba looks for a
writable cache directory (``NUMBA_CACHE_DIR``, the ``__pycache__`` beside the
source, then the user's cache directory under ``HOME``); on a read-only
installation with an unwritable ``HOME`` it finds none and raises
``RuntimeError: cannot cache function ...: no locator available`` while the
module is being imported. Here that case compiles the function without a
disk cache instead (correct, only slower at first use in each process) and
says so in one warning, once per process.

A cached kernel is valid only while every rlsfilt file it may call into is
unchanged: numba compiles a called kernel into its caller's machine code but
stamps the caller's cache with the caller's own source file alone, so after an
edit of ``filters/_kernels_shared.py`` (or a ``git pull`` that changes only that
file) the cached callers in other modules kept running the old code. The disk
cache of a kernel here is stamped with numba's stamp of its own file *and* a
hash of the files its module imports from rlsfilt, followed through their
imports (the static import graph, read from the sources: ``from ._kernels
import ...``, ``from .forgetting import CFG_LAM``, ``from .._numba import
njit``), so that any change there is a cache miss and a recompile. The
locations of the cache are numba's own (the same locators, in the same order);
files outside the package, and a numba whose private caching classes differ
from what this expects, get numba's default cache, as does every function when
the user names numba's locators (``NUMBA_CACHE_LOCATOR_CLASSES``). The digest is
computed once per execution of a module, from files read once (about 2 ms for
all the kernel modules), then looked up.
"""

import hashlib
import os
import re
import types
import warnings

import numba

__all__ = []

_warned = False

# The threading layer of the parallel kernels (``RLSBank(parallel=True)``): numba's
# default picks GNU OpenMP where it is installed, after which a fork-based
# ``multiprocessing`` worker aborts ("fork() called from a process already using GNU
# OpenMP") and its pool never returns. "forksafe" picks TBB, a non-GNU OpenMP or numba's
# own work queue; a layer the user chose (NUMBA_THREADING_LAYER) is kept.
if "NUMBA_THREADING_LAYER" not in os.environ and numba.config.THREADING_LAYER == "default":
    numba.config.THREADING_LAYER = "forksafe"


def njit(*args, **options):
    """``numba.njit`` that falls back to ``cache=False`` when no cache directory is writable.

    Used exactly like ``numba.njit``: ``@njit``, ``@njit(cache=True)``,
    ``@njit(cache=True, inline="always")``. The kernels are compiled without numba's
    C-callable wrapper (``no_cfunc_wrapper``): rlsfilt calls them from Python and from
    each other, never through a C function pointer, and the wrappers were about 5 % of
    a first run's compile work. With ``cache=True`` the disk cache is stamped with the
    rlsfilt files the function's module imports (see the module's docstring).
    """
    options.setdefault("no_cfunc_wrapper", True)
    if args and callable(args[0]) and len(args) == 1:
        return numba.njit(**options)(args[0])

    def decorate(func):
        if not options.get("cache"):
            return numba.njit(*args, **options)(func)
        try:
            if args:        # signatures compile at once, with numba's own cache
                return numba.njit(*args, **options)(func)
            dispatcher = numba.njit(**{**options, "cache": False})(func)
            _enable_cache(dispatcher)
            return dispatcher
        except RuntimeError as exc:     # numba found no writable cache directory
            if "cannot cache function" not in str(exc):
                raise
            _warn_uncached(func)
            return numba.njit(*args, **{**options, "cache": False})(func)

    return decorate


def _warn_uncached(func):
    global _warned
    if _warned:
        return
    _warned = True
    warnings.warn(
        f"numba found no writable cache directory for {func.__module__} (set NUMBA_CACHE_DIR "
        "to a writable directory); the kernels are compiled in memory, again in every process",
        RuntimeWarning, stacklevel=3)


# ----------------------------------------------------------------------
# the disk cache stamped with the files a kernel may call into
# ----------------------------------------------------------------------
#: The directory of the rlsfilt package (the one holding this file).
_ROOT = os.path.dirname(os.path.abspath(__file__))

# ``from <base> import <names>`` (a parenthesized list may span lines and hold comments)
# or ``import <modules>``, matched at the start of a line holding "import"
_IMPORT = re.compile(r"[ \t]*(?:from[ \t]+(?P<base>[.\w]+)[ \t]+import[ \t]+"
                     r"(?P<names>\((?:[^)#]|#[^\n]*)*\)|[^\n]*)|import[ \t]+(?P<modules>[^\n]*))")
_COMMENT = re.compile(r"#[^\n]*")

_inside = {}        # file -> whether it is a source file of this package
_files = {}         # file -> ((mtime_ns, size), the rlsfilt files it imports, its contents' hash)
_stamps = {}        # file -> (the module's spec when computed, the digest of its closure)
_cache_class = []   # [the FunctionCache subclass, or None where numba's API differs]


def _enable_cache(dispatcher):
    """Give `dispatcher` the dependency-stamped disk cache, else numba's default one.

    Raises numba's ``RuntimeError("cannot cache function ...")`` when no cache
    directory is writable; anything else going wrong here (numba's private
    caching API changed, a file that cannot be read) leaves numba's default.
    """
    if not _cache_class:
        try:
            from numba.core import caching
        except ImportError:
            caching = None
        _cache_class.append(_dependency_cache_class(caching))
    if _cache_class[0] is not None:
        try:
            dispatcher._cache = _cache_class[0](dispatcher.py_func)
            return
        except RuntimeError as exc:
            if "cannot cache function" in str(exc):
                raise
        except Exception:       # noqa: BLE001  (numba's internals differ: its default cache)
            pass
    dispatcher.enable_caching()


class _DependencyStamp:
    """Mixin for numba's cache locators: the files of rlsfilt only, stamped with their imports."""

    @classmethod
    def from_function(cls, py_func, py_file):
        if not _in_package(py_file):
            return None             # not rlsfilt's: the next locator (numba's own) decides
        locator = super().from_function(py_func, py_file)
        if locator is not None:
            locator._rlsfilt_file = os.path.abspath(py_file)
            # the module's spec: the same object for every function of one execution
            # of the module (a reload makes a new one)
            locator._rlsfilt_token = getattr(py_func, "__globals__", {}).get("__spec__")
        return locator

    def get_source_stamp(self):
        own = super().get_source_stamp()
        return own, _dependency_stamp(self._rlsfilt_file, self._rlsfilt_token)


def _dependency_cache_class(caching):
    """numba's ``FunctionCache`` with `_DependencyStamp` locators first; None if its API differs.

    The locators are numba's own, in numba's order, each with the mixin (so the
    cache lives where numba would put it), followed by numba's unchanged list.
    """
    try:
        base = caching.FunctionCache
        impl = base._impl_class
        stock = list(impl._locator_classes)
        if not stock or not all(callable(getattr(c, "from_function", None)) and
                                callable(getattr(c, "get_source_stamp", None)) for c in stock):
            return None
        ours = [_subclass("Rlsfilt" + c.__name__.lstrip("_"), (_DependencyStamp, c))
                for c in stock]
        impl_class = _subclass("RlsfiltCacheImpl", (impl,), _locator_classes=ours + stock)
        return _subclass("RlsfiltFunctionCache", (base,), _impl_class=impl_class)
    except Exception:           # noqa: BLE001  (any other layout: numba's default cache)
        return None


def _subclass(name, bases, **attributes):
    """A class `name` of this module deriving from `bases` (numba's use ``ABCMeta``)."""
    return types.new_class(name, bases, exec_body=lambda ns: ns.update(
        __module__=__name__, __qualname__=name, **attributes))


def _in_package(py_file):
    """Whether `py_file` is a source file of this rlsfilt package (not a zip member)."""
    inside = _inside.get(py_file)
    if inside is None:
        path = os.path.abspath(py_file)
        inside = _inside[py_file] = path.startswith(_ROOT + os.sep) and os.path.isfile(path)
    return inside


def _dependency_stamp(path, token=None):
    """The digest of `path` and every rlsfilt file it imports, directly or not.

    The digest is of the files' contents (like numba's own stamp since 0.61). It
    is computed once per execution of the module: `token` (the module's
    ``__spec__``, one object for all its functions, a new one after a reload)
    finds the digest of the module's first function. Without a token, or with a
    new one, the files are looked at again; a file is read again only when its
    ``mtime`` or size changed.
    """
    known = _stamps.get(path)
    if token is not None and known is not None and known[0] is token:
        return known[1]
    h = hashlib.sha256()
    for f in _closure(path):
        h.update(os.path.relpath(f, _ROOT).replace(os.sep, "/").encode() + b"\0")
        h.update(_file(f)[1])
    _stamps[path] = token, h.hexdigest()
    return _stamps[path][1]


def _closure(path):
    """`path` and the rlsfilt files it imports, followed through their imports (sorted)."""
    seen = {path}
    todo = [path]
    while todo:
        for dep in _file(todo.pop())[0]:
            if dep not in seen:
                seen.add(dep)
                todo.append(dep)
    return sorted(seen)


def _file(path):
    """(the rlsfilt files `path` imports, the hash of its contents), read once per version."""
    st = os.stat(path)
    stat = st.st_mtime_ns, st.st_size
    known = _files.get(path)
    if known is None or known[0] != stat:
        with open(path, "rb") as fh:
            data = fh.read()
        imports = _imported_files(path, data.decode("utf-8", "replace"))
        known = _files[path] = stat, imports, hashlib.sha256(data).digest()
    return known[1:]


def _imported_files(path, source):
    """The rlsfilt files `source` (of the file `path`) imports: relative or ``rlsfilt.``."""
    package = [p for p in os.path.relpath(os.path.dirname(path), _ROOT).split(os.sep)
               if p != "."]
    top = os.path.basename(_ROOT)
    found = set()
    for match in _import_statements(source):
        if match["modules"] is not None:        # import rlsfilt.filters._kernels as k
            for item in _COMMENT.sub("", match["modules"]).split(","):
                name = item.split()[0] if item.split() else ""
                if name.startswith(top + "."):
                    found.add(_module_file(name.split(".")[1:]))
            continue
        base = match["base"]
        dots = len(base) - len(base.lstrip("."))
        rest = [p for p in base[dots:].split(".") if p]
        if dots:                                # from ..filters._kernels import gain
            if dots - 1 > len(package):
                continue
            parts = package[:len(package) - (dots - 1)] + rest
        elif rest and rest[0] == top:           # from rlsfilt.filters import _kernels
            parts = rest[1:]
        else:
            continue
        for item in _COMMENT.sub("", match["names"]).strip("() \t\n").split(","):
            name = item.split()[0] if item.split() else ""
            # a submodule is imported as itself; any other name from the module `parts`
            submodule = _module_file(parts + [name]) if name.isidentifier() else None
            found.add(submodule or _module_file(parts))
    found.discard(None)
    return sorted(found)


def _import_statements(source):
    """The `_IMPORT` matches of `source`, found from its occurrences of "import"."""
    pos = 0
    while (i := source.find("import", pos)) >= 0:
        match = _IMPORT.match(source, source.rfind("\n", 0, i) + 1)
        if match and match.end() > i:
            yield match
            pos = match.end()
        else:
            pos = i + 6


def _module_file(parts):
    """The file of the module ``rlsfilt.<parts>`` (a package's ``__init__.py``), or None."""
    if not parts:
        path = os.path.join(_ROOT, "__init__.py")
        return path if os.path.isfile(path) else None
    path = os.path.join(_ROOT, *parts)
    if os.path.isfile(path + ".py"):
        return path + ".py"
    init = os.path.join(path, "__init__.py")
    return init if os.path.isfile(init) else None
