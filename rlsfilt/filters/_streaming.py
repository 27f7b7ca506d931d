"""Lazy access to the compiled kernels of the filters.

``import rlsfilt`` does not load numba: the filters reach their kernel
modules through `kernels` and `window_kernels`, which import them on first
use. The streaming ``predict()``/``update()`` of every filter call their
compiled step through numba's ordinary dispatcher, on arrays the step
allocates (see ``RecursiveLeastSquares.update``).

Until issue #26 this module also held a faster streaming machinery for
`RecursiveLeastSquares`: a deferred ``predict()`` fused into the next
``update()``, blocks of arrays recycled by reference count, and direct calls
of the compiled entry points. Together they made a ``predict()`` +
``update()`` pair cost 1.1 us instead of the plain step's 4.7 us at
``dim_x = 5`` (thread CPU time, shared 2-core machine); they went because
they made the filter unreadable (59 lines of ``update``, 13 slots, a deferred
state behind every property) and caused the multi-output streaming bug of
#26 (an entry point typed for C-contiguous arrays read an F-ordered estimate
with the wrong strides). What one of them alone would bring to the plain
step, measured by ``python benchmarks/bench_rls.py --streaming-ablation``:
the entry points 0.3 us of 4.7 (1.06x; not kept), the reuse and the
deferral at most the Python work outside the compiled calls, which is
mostly validation and the filterpy attributes every step must produce.
Who needs more streams many filters through `RLSBank` or a record through
``batch_filter``.
"""

import numpy as np

from .._lazy import lazy_module

__all__ = []

#: The compiled kernels of `RecursiveLeastSquares`, imported on first use.
kernels = lazy_module("rlsfilt.filters._kernels")
#: The compiled kernels of `SlidingWindowRLS` and `SquareRootRLS`, imported on first use.
window_kernels = lazy_module("rlsfilt.filters._kernels_window")
#: The compiled samples of the python-control systems on their state vectors.
vector_kernels = lazy_module("rlsfilt.filters._kernels_vector")


def c_array(a):
    """`a` as a writable C-contiguous float64 array (copied only when needed).

    The kernels are compiled for exactly this layout; a read-only or strided
    input would otherwise compile (and cache) another version.
    """
    if (type(a) is np.ndarray and a.dtype == np.float64 and a.flags.c_contiguous
            and a.flags.writeable):
        return a
    return np.array(a, dtype=np.float64, order="C")
