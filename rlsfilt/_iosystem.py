"""A stepping object as a discrete-time python-control `NonlinearIOSystem`.

python-control evaluates a discrete system through two pure functions of
``(t, x, u)``: the output ``y[k] = h(x[k], u[k])`` and the next state
``x[k+1] = f(x[k], u[k])``. Inside `control.interconnect` the output function
is called several times per sample (to settle feed-through), sometimes with
inputs that are not yet final. So the object's state must be entirely in the
vector ``x``: each evaluation restores a private working copy from ``x``,
takes one step and reads the new state back. The step is computed once per
distinct ``(x, u)``; the output and update functions share it, and warnings
are issued only by the update (the committed step), once per message.

The object provides ``_get_state()``, ``_set_state(vector)`` and
``_io_step(inputs) -> (outputs, messages)``, and optionally
``_snapshot()``/``_restore_snapshot(snap)``: a cheap copy of everything a
step reads, taken after each step under the bytes of the state vector it
left, so that the next sample (whose ``x`` is that vector) restores it
without unpacking the vector. A restored snapshot is the state
``_set_state(vector)`` would give (the vector is read back from it), so
results are the same bit for bit; unpacking stays for any other ``x``.
"""

import copy
import warnings

import numpy as np

__all__ = []

_CACHE_SIZE = 8


def make_iosystem(template, *, inputs, outputs, states, dt, name=None):
    """A `control.NonlinearIOSystem` that steps a copy of `template`.

    An all-zero state vector (python-control's default initial state) stands
    for the state of `template` now; any other vector is restored as is.
    """
    import control

    work = copy.deepcopy(template)
    x_start = np.array(template._get_state(), dtype=float)
    if len(states) != len(x_start):
        raise RuntimeError("internal error: state labels and state size differ")
    cache = {}
    snaps = {}          # state-vector bytes -> snapshot of `work` in that state
    fast = hasattr(work, "_snapshot")
    holds = [None]      # the evaluation whose result `work` holds now
    emitted = set()

    def restore(x):
        snap = snaps.get(x.tobytes()) if fast else None
        if snap is not None:
            work._restore_snapshot(snap)
            return
        work._set_state(x if x.any() else x_start)
        if fast:
            remember(x, work._snapshot())

    def remember(x, snap):
        if len(snaps) >= _CACHE_SIZE:
            snaps.clear()
        snaps[x.tobytes()] = snap

    def evaluate(x, w):
        """``[outputs, messages, snapshot after the step, new state or None]``."""
        x = np.ascontiguousarray(x, dtype=float)
        w = np.ascontiguousarray(w, dtype=float)
        key = (x.tobytes(), w.tobytes())
        hit = cache.get(key)
        if hit is None:
            holds[0] = None
            restore(x)
            out, messages = work._io_step(w)
            if fast:        # the new state is packed only if the update asks for it
                hit = [np.array(out, dtype=float), messages, work._snapshot(), None]
            else:
                hit = [np.array(out, dtype=float), messages, None,
                       np.asarray(work._get_state(), dtype=float)]
            holds[0] = hit
            if len(cache) >= _CACHE_SIZE:
                cache.clear()
            cache[key] = hit
        return hit

    def updfcn(t, x, u, params):
        hit = evaluate(x, u)
        if hit[3] is None:
            if holds[0] is not hit:
                work._restore_snapshot(hit[2])
                holds[0] = hit
            hit[3] = np.asarray(work._get_state(), dtype=float)
            remember(hit[3], hit[2])
        for message, category in hit[1]:
            if message not in emitted:
                emitted.add(message)
                warnings.warn(message, category, stacklevel=2)
        return hit[3].copy()

    def outfcn(t, x, u, params):
        return evaluate(x, u)[0].copy()

    return control.nlsys(updfcn, outfcn, inputs=list(inputs), outputs=list(outputs),
                         states=list(states), dt=dt, name=name)


def snapshot_filter(f):
    """A copy of a filter's attributes (`_shallow_state`) that stays valid.

    A step replaces the arrays it changes, except those the filter lists in
    ``_written_in_place`` (the ring buffer of `SlidingWindowRLS`): only
    these are copied.
    """
    state = f._shallow_state()
    for name in f._written_in_place:
        state[name] = state[name].copy()
    return state


def restore_filter(f, snap):
    """Put back a :func:`snapshot_filter` (copies again: the snapshot stays valid)."""
    if f._written_in_place:
        snap = dict(snap)
        for name in f._written_in_place:
            snap[name] = snap[name].copy()
    f._restore(snap)


def call_capturing(fn, *args):
    """``fn(*args)`` with the warnings it issues returned, not shown: ``(result, messages)``.

    `messages` is a list of ``(text, category)`` for the caller to issue
    when (and if) the step is committed.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args)
    return out, [(str(w.message), w.category) for w in caught]


def push(buf, value):
    """Shift a newest-first memory of past samples by one and store `value` in front."""
    if len(buf):
        buf[1:] = buf[:-1].copy()
        buf[0] = value
