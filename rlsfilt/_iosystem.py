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
The system also remembers which state vector the working copy is in (after
an update: the vector it returned), so a sequential simulation restores
nothing.

An object that can take a whole sample as one compiled call on the state
vector also provides ``_io_vector_sample(x, inputs) -> (outputs, next
state)`` (or None: that sample needs its Python). Both functions then try it
first and remember its result on the bytes of ``(x, u)`` (the update returns
the next state the outputs' evaluation computed), without touching the
working copy; a sample it declines is stepped as above, with the same
results, its warnings and its errors. (Until #29 a sample's outputs were a
look-ahead at the step, committed by the update; with the compiled sample
it paid 1.1x to 1.4x on the samples left to Python, so it went.)

python-control (``control.nlsys``, 0.10) computes a sample's outputs and then
its update, each by passes over every subsystem's output function until the
loop's signals settle, the first pass with those signals at zero: an output
function sees each sample's inputs two or three times, first on inputs the
loop discards. The outputs are remembered on the bytes of ``(x, u)``, so a
repeated evaluation is one dictionary look-up.
"""

import copy
import warnings

import numpy as np

__all__ = []

_CACHE_SIZE = 8
_F8 = np.dtype(float)


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
    outs = {}           # (state bytes, input bytes) -> outputs
    cache = {}          # (state bytes, input bytes) -> a step, see `evaluate`
    snaps = {}          # state-vector bytes -> snapshot of `work` in that state
    samples = {}        # (state bytes, input bytes) -> (outputs, next state) or None
    fast = hasattr(work, "_snapshot")
    vector = getattr(work, "_io_vector_sample", None)
    zero = bytes(8 * len(x_start))      # the all-zero state vector: `template` now
    at = [None]         # the bytes of the state vector `work` is in now (None: unknown)
    holds = [None]      # the step whose result `work` holds now
    emitted = set()

    def remember(xb, snap):
        if len(snaps) >= _CACHE_SIZE:
            snaps.clear()
        snaps[xb] = snap

    def goto(x, xb):
        """Put `work` in the state of vector `x` (bytes `xb`)."""
        if at[0] == xb:
            return
        at[0] = holds[0] = None
        snap = snaps.get(xb) if fast else None
        if snap is not None:
            work._restore_snapshot(snap)
        else:
            work._set_state(x_start if xb == zero else x)
            if fast:
                remember(xb, work._snapshot())
        at[0] = xb

    def evaluate(x, xb, w, key, keep):
        """``[outputs, messages, snapshot after the step or None, new state or None]``;
        the snapshot is taken if `keep` (an output evaluation, which the update may
        have to go back to)."""
        hit = cache.get(key)
        if hit is None:
            goto(x, xb)
            at[0] = holds[0] = None
            out, messages = work._io_step(w)
            if fast:        # the new state is packed only if the update asks for it
                hit = [np.array(out, dtype=float), messages,
                       work._snapshot() if keep else None, None]
            else:
                hit = [np.array(out, dtype=float), messages, None,
                       np.asarray(work._get_state(), dtype=float)]
            holds[0] = hit
            if len(cache) >= _CACHE_SIZE:
                cache.clear()
            cache[key] = hit
        return hit

    def sample(x, w, key):
        """The compiled sample on ``(x, w)``: ``(outputs, next state)``, remembered,
        or None (the object's Python takes it)."""
        if key in samples:
            return samples[key]
        got = vector(x_start if key[0] == zero else x, w)
        if len(samples) >= _CACHE_SIZE:
            samples.clear()
        samples[key] = got
        return got

    def arrays(x, u):
        """``(x, w, key)``: `x` and `u` as C-contiguous float arrays and the key
        ``(bytes of x, bytes of u)`` (C order whatever the layout)."""
        if not (type(x) is np.ndarray and type(u) is np.ndarray and x.dtype is _F8
                and u.dtype is _F8):
            x, u = np.asarray(x, dtype=float), np.asarray(u, dtype=float)
        key = (x.tobytes(), u.tobytes())
        return np.ascontiguousarray(x), np.ascontiguousarray(u), key

    def updfcn(t, x, u, params):
        x, w, key = arrays(x, u)
        if vector is not None:
            got = sample(x, w, key)
            if got is not None:
                return got[1].copy()
        xb = key[0]
        hit = evaluate(x, xb, w, key, False)
        if hit[3] is None:
            if holds[0] is not hit:
                work._restore_snapshot(hit[2])
                holds[0] = hit
            hit[3] = np.asarray(work._get_state(), dtype=float)
            if hit[2] is not None:
                remember(hit[3].tobytes(), hit[2])
        if holds[0] is hit:         # `work` is in the new state: the next sample's
            at[0] = hit[3].tobytes()
        for message, category in hit[1]:
            if message not in emitted:
                emitted.add(message)
                warnings.warn(message, category, stacklevel=2)
        return hit[3].copy()

    def outfcn(t, x, u, params):
        x, w, key = arrays(x, u)
        out = outs.get(key)                 # a repeated evaluation: one look-up
        if out is None:
            got = sample(x, w, key) if vector is not None else None
            # one compiled call, else the object's step (or the one already taken)
            out = got[0] if got is not None else evaluate(x, key[0], w, key, True)[0]
            if len(outs) >= _CACHE_SIZE:
                del outs[next(iter(outs))]      # the oldest: this sample's stay
            outs[key] = out
        return out.copy()

    return control.nlsys(updfcn, outfcn, inputs=list(inputs), outputs=list(outputs),
                         states=list(states), dt=dt, name=name)


def call_capturing(fn, *args):
    """``fn(*args)`` with the warnings it issues returned, not shown: ``(result, messages)``.

    `messages` is a list of ``(text, category)`` for the caller to issue
    when (and if) the step is committed.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn(*args)
    return out, [(str(w.message), w.category) for w in caught]
