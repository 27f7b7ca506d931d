"""Lazy access to the compiled kernels of the filters.

``import rlsfilt`` does not load numba: the filters reach their kernel
modules through `kernels` and `window_kernels`, which import them on first
use. The streaming ``predict()``/``update()`` of every filter call their
compiled step through numba's ordinary dispatcher, on arrays the step
allocates (see ``RecursiveLeastSquares.update``).

Until version 0.9 this module held a faster streaming machinery for
`RecursiveLeastSquares`: a deferred ``predict()`` fused into the next
``update()``, blocks of arrays recycled by reference count, and direct calls
of the compiled entry points. It was removed because it did not pay its
weight: ``python benchmarks/bench_rls.py --streaming-ablation`` measured the
plain step within 1.5x of it (see ``docs/performance.md``), and it caused
the multi-output streaming bug of issue #26 (an entry point typed for
C-contiguous arrays read an F-ordered estimate with the wrong strides).
"""

import numpy as np

__all__ = []

_kernels = None
_window_kernels = None


def kernels():
    """The compiled kernels of `RecursiveLeastSquares`, imported on first use
    (``import rlsfilt`` does not load numba)."""
    global _kernels
    if _kernels is None:
        from . import _kernels as k
        _kernels = k
    return _kernels


def window_kernels():
    """The compiled kernels of `SlidingWindowRLS` and `SquareRootRLS`, imported on
    first use."""
    global _window_kernels
    if _window_kernels is None:
        from . import _kernels_window as k
        _window_kernels = k
    return _window_kernels


def c_array(a):
    """`a` as a writable C-contiguous float64 array (copied only when needed).

    The kernels are compiled for exactly this layout; a read-only or strided
    input would otherwise compile (and cache) another version.
    """
    if (type(a) is np.ndarray and a.dtype == np.float64 and a.flags.c_contiguous
            and a.flags.writeable):
        return a
    return np.array(a, dtype=np.float64, order="C")
