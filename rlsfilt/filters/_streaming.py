"""The streaming ``predict()``/``update()`` of `RecursiveLeastSquares`: argument
packing and array reuse around its compiled steps.

A streaming step is one Python call, so at small ``dim_x`` its cost is the
call overhead, not the arithmetic: validating the inputs, handing arrays to
the compiled ``update_kernel`` (:mod:`rlsfilt.filters._kernels`) and
allocating the arrays a step produces (``x, P, y, K, S, SI, H, z, x_post,
P_post, x_prior, P_prior``). Four things keep that small:

**One compiled call per step.** ``predict()`` only records its time update;
the next ``update()`` runs it and the measurement update in one call of
``update_kernel`` (the same operations as ``predict_kernel`` then the
update, so the same bits), which writes ``x_prior`` and ``P_prior`` too.
Reading ``P``, ``x_prior`` or ``P_prior`` in between runs the time update at
once with ``predict_kernel`` (see `RecursiveLeastSquares.predict`). The
kernel returns one integer of flags and is compiled without numba's
reference counting (it allocates nothing; the counting of its views cost
more than a small step's arithmetic).

**Blocks.** The diagnostics of a step are views of one buffer (a *block*,
made by `_block`), so the kernel takes the buffer as one argument, not
ten; the new ``x`` and ``P`` are arrays of their own, because callers keep
them (a list of estimates, filterpy's ``Saver``) and that should not cost
the rest.

**Reuse.** Every step writes arrays that nobody can see yet and then makes
them the filter's attributes, so a step never changes an array a caller
holds (``history.append(rls.x)`` works as with filterpy), and a step that
raises, or whose warning is turned into an error, leaves the filter as it
was. The arrays a step replaced become the spares of the step after next.
The filter records which of its arrays it handed out while they were
current (its properties do: nothing, ``x`` or ``P``, or a view of the
block); a step recycles the spares without a test when nothing was handed
out, when only ``x`` or ``P`` was and their reference counts show nobody
else holds them (`quick_count`), and otherwise after testing every array
(`renew`: ``sys.getrefcount`` shows only the filter's tuple; the buffer's
count also shows any view of a view), making anew any part someone holds.
Reuse is off where counts cannot be trusted (no ``sys.getrefcount``,
free-threaded builds).

**Entry points.** Calling a numba dispatcher first types every argument to
choose the compiled version. The steps here always pass the same types
(C-contiguous float64 arrays, floats, ints; the regressor row of any
layout: the update kernel is compiled for it), so after the first call they
call the compiled version's entry point (numba's
``overloads[signature].entry_point``) directly; the dispatcher serves if
numba does not expose it.

The reuse and the entry points pay (``python benchmarks/bench_rls.py
--streaming-ablation``, CPU time per ``predict()`` + ``update()``, measured
on a shared 2-core machine): at ``dim_x = 5`` 1.5 us as shipped, 6.5 us
with fresh arrays every step, 1.8 us through the dispatcher; at ``dim_x =
20`` 1.9, 7.3 and 2.2 us.
"""

import sys
import sysconfig

import numpy as np

from .._lazy import lazy_module

__all__ = []

#: The compiled kernels of `RecursiveLeastSquares`, imported on first use.
kernels = lazy_module("rlsfilt.filters._kernels")
#: The compiled kernels of `SlidingWindowRLS` and `SquareRootRLS`, imported on first use.
window_kernels = lazy_module("rlsfilt.filters._kernels_window")


def c_array(a):
    """`a` as a writable C-contiguous float64 array (copied only when needed).

    The kernels are compiled for exactly this layout; a read-only or strided
    input would otherwise compile (and cache) another version.
    """
    if (type(a) is np.ndarray and a.dtype == np.float64 and a.flags.c_contiguous
            and a.flags.writeable):
        return a
    return np.array(a, dtype=np.float64, order="C")


# ----------------------------------------------------------------------
# blocks and their reuse
# ----------------------------------------------------------------------
def update_shapes(n, m):
    """Shapes of the arrays an update writes, in the order of its block (the
    layout ``_kernels.update_kernel`` writes; then its work space, `update_work`):
    ``y, K, S, SI, H, z, x_post, P_post, x_prior, P_prior`` (the last two only
    when the update runs a pending predict). The new ``x`` and ``P`` are
    arrays of their own."""
    return ((m, 1), (n, 1), (m, m), (m, m), (1, n), (m, 1), (n, m), (n, n), (n, m), (n, n))


def lam_t_at(n, m):
    """Where in an update's buffer ``update_kernel`` writes ``lam_t`` (after the
    arrays and the gain)."""
    return sum(r * c for r, c in update_shapes(n, m)) + n


def update_work(n):
    """The work space at the end of an update's block: the gain, ``lam_t`` and an
    (n, n) matrix (constraints, EFRA)."""
    return n + 1 + n * n


def predict_shapes(n, m):
    """Shapes of the arrays a predict writes: ``P^-``, ``x_prior``, ``P_prior``
    (then its work space)."""
    return ((n, n), (n, m), (n, n))


def _block(shapes, work=0):
    """A new block: a buffer, then one C-contiguous view of it per shape; the
    buffer ends with `work` numbers of work space for the kernel."""
    buf = np.empty(sum(r * c for r, c in shapes) + work)
    views, o = [buf], 0
    for r, c in shapes:
        views.append(buf[o:o + r * c].reshape(r, c))
        o += r * c
    return tuple(views)


def _sample(views, arrays=0):
    """A tuple of `arrays` separate arrays and a block of `views` views, as the
    steps hold them."""
    return tuple(np.empty((1, 1)) for _ in range(arrays)) + _block(((1, 1),) * views)


def _free_sum(views, arrays=0):
    """What ``sum(map(sys.getrefcount, spare))`` gives for such a tuple when nobody
    but the tuple holds its arrays (every count is then at its least, so the sum
    tests them all); -1 where counts cannot be trusted (no ``sys.getrefcount``,
    free-threaded builds): reuse is then off."""
    if not hasattr(sys, "getrefcount") or sysconfig.get_config_var("Py_GIL_DISABLED"):
        return -1
    return sum(map(sys.getrefcount, _sample(views, arrays)))


def _counts(spare):
    """The reference count of every array of `spare`, one by one."""
    return [sys.getrefcount(a) for a in spare]


_getrefcount = getattr(sys, "getrefcount", lambda a: 0)


# ----------------------------------------------------------------------
# the steps
# ----------------------------------------------------------------------
#: The empty (0, 0) array the kernels take for an absent ``Q`` or projector.
EMPTY = np.zeros((0, 0))

#: What a filter handed out of the arrays of an update while they were current (its
#: properties record it): nothing (they are recycled without a test), ``x`` or ``P``
#: (their reference counts decide, `quick_count`), a view of the block (every array
#: is tested, `renew`).
NOTHING, STATE, VIEWS = 0, 1, 2


def quick_count(spare):
    """The reference counts of ``x`` and ``P`` of an update's `spare`, summed: the
    quick test of `update` (written out the same way in
    ``RecursiveLeastSquares.update``). Enough while no view of the block was handed
    out: the filter reads its views only through properties that mark the block
    (``handed``), so the buffer and the views are then held by the block alone."""
    return _getrefcount(spare[0]) + _getrefcount(spare[1])


_N_UPDATE = len(update_shapes(1, 1))            # the views of an update's block
_FREE_PREDICT = _free_sum(3)
_FREE_EACH = _counts(_sample(_N_UPDATE, arrays=2)) if _free_sum(1) > 0 else None
#: What `quick_count` gives when nobody else holds ``x`` or ``P`` of an update's arrays.
_FREE_UPDATE = quick_count(_sample(_N_UPDATE, arrays=2)) if _FREE_EACH is not None else -1


def predict(x, P, il, Q, cfg, spare):
    """The block ``(buffer, P^-, x_prior, P_prior)`` of a time update (`spare` if free;
    the buffer ends with ``n^2`` numbers of work space).

    ``P^- = P il + Q`` (`Q` (0, 0) when absent) then ``Pi P^- Pi`` with the
    projector of the configuration `cfg` (``forgetting.kernel_config``).
    """
    if spare is not None and sum(map(_getrefcount, spare)) == _FREE_PREDICT:
        out = spare                                   # nobody else holds it: reuse
    else:
        out = _block(predict_shapes(*x.shape), P.size)
    _predict_kernel(x, P, il, Q, cfg, out[0])
    return out


def measurement(z):
    """``(z0, zmode)`` of `update_kernel` for `z`: a float, None (missing) or a
    validated column (written into the block by `update`)."""
    if z is None:
        return 0.0, 2
    if type(z) is np.ndarray:
        return 0.0, 0
    return z, 1


def update(x, P, phi, z, r, cfg, w, spare, handed=VIEWS, il=0.0, Q=EMPTY):
    """One measurement update into new arrays (those of `spare` where they are free).

    `phi` is the regressor row, a float64 array (n,) of any layout (the kernel
    checks that it is finite), `z` a float, a validated column
    (m, 1) or None (missing); `w` is ``1 / lam`` when the last predict held
    the forgetting back (the windup cap) and 1 otherwise; ``il > 0`` (with
    `Q`) runs a pending predict first (``update_kernel``). `spare` is None or
    the ``arrays`` of an earlier call; `handed` what of them was handed out
    (`NOTHING`, `STATE`, `VIEWS`: the test they need before they are
    recycled). ``RecursiveLeastSquares.update`` runs the same steps written
    out (its hot path). Returns ``flags, arrays``: ``flags`` as ``update_kernel``'s,
    ``arrays = (x, P, buffer, y, K, S, SI, H, z, x_post, P_post, x_prior,
    P_prior)``, the new estimate and covariance (arrays of their own: a caller
    who keeps them, as a list of estimates or a ``Saver`` does, leaves the
    rest reusable) and the block of the diagnostics.
    """
    if spare is None or _FREE_UPDATE < 0 or (handed and (
            handed == VIEWS or quick_count(spare) != _FREE_UPDATE)):
        spare = renew(spare, *x.shape)
    z0, zmode = measurement(z)
    if zmode == 0:
        spare[8][:] = z                                # the block's z
    return _update_kernel(x, P, phi, z0, zmode, r, cfg, w, il, Q, spare[0], spare[1],
                          spare[2]), spare


def renew(spare, n, m):
    """`spare` with its held parts made anew: the pair ``x, P`` and the block."""
    counts = None if spare is None or _FREE_EACH is None else _counts(spare)
    if counts is not None and counts[:2] == _FREE_EACH[:2]:
        state = spare[:2]
    else:
        state = (np.empty((n, m)), np.empty((n, n)))
    if counts is not None and counts[2:] == _FREE_EACH[2:]:
        return state + spare[2:]
    return state + _block(update_shapes(n, m), update_work(n))


def _entry_point(dispatcher, args, strided=()):
    """The compiled function of `dispatcher` for exactly the types of `args` (the
    dispatcher itself if numba does not expose it); the arrays at the positions
    `strided` are typed with any layout (compiled for them if needed), so that
    the caller need not test them for contiguity."""
    try:
        from numba import typeof

        sig = [typeof(a) for a in args]
        for i in strided:
            sig[i] = sig[i].copy(layout="A", readonly=False)
        sig = tuple(sig)
        if sig not in dispatcher.overloads:
            dispatcher.compile(sig)
        return dispatcher.overloads[sig].entry_point
    except Exception:       # pragma: no cover - numba internals changed
        return dispatcher


def _predict_kernel(*args):
    """The first call: run ``predict_kernel``, then call its entry point directly."""
    global _predict_kernel
    kernels().predict_kernel(*args)
    _predict_kernel = _entry_point(kernels().predict_kernel, args)


def _update_kernel(x, P, phi, z0, zmode, r, cfg, w, il, Q, xn, Pn, out):
    """The first call: find ``update_kernel``'s entry point (the regressor row `phi`
    of any layout: ``update`` tests its type, dtype and shape only), then call it
    directly."""
    global _update_kernel
    args = (x, P, phi, float(z0), zmode, float(r), cfg, float(w), float(il), Q, xn, Pn, out)
    _update_kernel = _entry_point(kernels().update_kernel, args, strided=(2,))
    return _update_kernel(*args)
