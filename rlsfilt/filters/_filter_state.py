"""The complete state of an rlsfilt filter as one flat float vector, and back.

python-control simulates a system from its state vector alone, so a filter
running inside a `control.NonlinearIOSystem` must be restorable exactly from
the numbers it stores. Every filter declares that state through the filter
contract (`rlsfilt.filters.contract.Filter`: ``get_state()`` and
``set_state(state)``, a dict of arrays and scalars); this module only lays
the dict out as one vector and reads it back. Restoring copies the stored
floats, so a filter restored from its own state continues bit for bit as the
original would. An object without the contract raises a `TypeError` that
names it.
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
