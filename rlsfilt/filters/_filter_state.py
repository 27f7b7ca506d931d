"""The complete state of an rlsfilt filter as one flat float vector, and back.

python-control simulates a system from its state vector alone, so a filter
running inside a `control.NonlinearIOSystem` must be restorable exactly from
the numbers it stores. Every filter declares that state through the filter
contract (`rlsfilt.filters.contract.Filter`: ``get_state()`` and
``set_state(state)``, a dict of arrays and scalars); this module only lays
the dict out as one vector and reads it back. Restoring copies the stored
floats, so a filter restored from its own state continues bit for bit as the
original would. An object without the contract raises a `TypeError` that
names it. `StateLayout` does the same with the layout worked out once, for
the python-control systems that pack and unpack at every sample.
"""

import numpy as np

from .contract import Filter

__all__ = []


def check_supported(f, name="estimator"):
    """Raise a `TypeError` naming `name` unless `f` keeps the filter contract."""
    if not isinstance(f, Filter):
        raise TypeError(f"`{name}` must be an rlsfilt filter (a subclass of "
                        f"rlsfilt.filters.contract.Filter, such as RecursiveLeastSquares) "
                        f"to run as a python-control system; got {type(f).__name__}")


def state_labels(f, prefix=""):
    """One label per entry of :func:`get_state`, e.g. ``P[0,1]``."""
    check_supported(f)
    labels = []
    for name, value in f.get_state().items():
        shape = np.shape(value)
        if shape == ():
            labels.append(prefix + name)
        else:
            labels += [f"{prefix}{name}[{','.join(map(str, idx))}]" for idx in np.ndindex(*shape)]
    return labels


def get_state(f):
    """The filter's complete state as a new 1-D float array."""
    check_supported(f)
    return np.concatenate([np.asarray(v, dtype=float).reshape(-1)
                           for v in f.get_state().values()])


def set_state(f, vec):
    """Restore the filter from a vector made by :func:`get_state` (exact copies)."""
    check_supported(f)
    state, i = {}, 0
    for name, like in f.get_state().items():
        shape = np.shape(like)
        size = int(np.prod(shape)) if shape else 1
        block = vec[i:i + size]
        state[name] = block.reshape(shape) if shape else float(block[0])
        i += size
    if i != len(vec):
        raise ValueError(f"the filter state must have {i} entries; got {len(vec)}")
    f.set_state(state)


class StateLayout:
    """Where each entry of a filter's :meth:`get_state` lies in the flat vector.

    Worked out once from `f` (a filter's state has fixed keys and shapes);
    :meth:`pack` and :meth:`unpack` then equal :func:`get_state` and
    :func:`set_state` without rebuilding the layout at every call.
    """

    def __init__(self, f):
        check_supported(f)
        self.owner = f
        self.entries, i = [], 0
        for name, value in f.get_state().items():
            shape = np.shape(value)
            size = int(np.prod(shape)) if shape else 1
            self.entries.append((name, shape, i, i + size))
            i += size
        self.size = i
        self._arrays = [(name, a, b) for name, shape, a, b in self.entries if shape]
        # the scalars in runs of consecutive entries, each written as one slice
        # (a slice from a list: about 1 us less than one scattered index assignment)
        self._runs = []
        for name, shape, a, b in self.entries:
            if shape:
                continue
            if self._runs and self._runs[-1][1] == a:
                self._runs[-1][1] = b
                self._runs[-1][2].append(name)
            else:
                self._runs.append([a, b, [name]])

    def pack(self, f, out):
        """Write the state of `f` into `out` (length :attr:`size`), as :func:`get_state`."""
        state = f.get_state()
        for name, a, b in self._arrays:
            out[a:b] = np.asarray(state[name]).ravel()
        for a, b, names in self._runs:
            out[a:b] = [state[name] for name in names]
        return out

    def unpack(self, f, vec):
        """Restore `f` from `vec`, as :func:`set_state`."""
        if len(vec) != self.size:
            raise ValueError(f"the filter state must have {self.size} entries; got {len(vec)}")
        f.set_state({name: vec[a:b].reshape(shape) if shape else float(vec[a])
                     for name, shape, a, b in self.entries})
