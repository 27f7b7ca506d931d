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
"""

import os
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
    a first run's compile work.
    """
    options.setdefault("no_cfunc_wrapper", True)
    if args and callable(args[0]) and len(args) == 1:
        return numba.njit(**options)(args[0])

    def decorate(func):
        if not options.get("cache"):
            return numba.njit(*args, **options)(func)
        try:
            return numba.njit(*args, **options)(func)
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
