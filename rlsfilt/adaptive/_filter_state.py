"""The complete state of an rlsfilt filter as one flat float vector, and back.

python-control simulates a system from its state vector alone, so a filter
running inside a `control.NonlinearIOSystem` must be restorable exactly from
the numbers it stores: the estimate, the covariance (or the square root that
the filter keeps instead), the counters and, for `SlidingWindowRLS`, the
window itself. Restoring copies the stored floats, so a filter restored from
its own state continues bit for bit as the original would.

One adapter per filter class; an unknown filter raises a `TypeError` that
names it.
"""

import numpy as np

__all__ = []


def _rls_fields(f):
    n, m = f.dim_x, f.dim_z
    # the windup cap's decision for the next time update and the pending w belong to
    # the state: a filter restored between update() and predict() forgets as the
    # original would
    return [("x", (n, m)), ("P", (n, n)), ("n_updates", ()), ("efra_pending", ()),
            ("n_capped", ()), ("cap", ()), ("w", ())]


def _rls_get(f):
    return [f.x, f.P, f.n_updates, float(f._efra_pending), f.n_capped, float(f._cap), f._w]


def _rls_set(f, parts):
    x, P, nu, efra, n_capped, cap, w = parts
    f.x = x.copy()
    f.P = P.copy()
    f.n_updates = int(nu)
    f._efra_pending = bool(efra)
    f.n_capped = int(n_capped)
    f._cap, f._w = bool(cap), float(w)


def _sr_fields(f):
    # the square-root-free factors U = Delta^-1/2 W and v = W x, as the filter keeps them
    n, m = f.dim_x, f.dim_z
    return [("x", (n, m)), ("W", (n, n)), ("delta", (n,)), ("v", (n, m)), ("n_updates", ())]


def _sr_get(f):
    n, m = f.dim_x, f.dim_z
    return [f._x, f._Wv[:, :n], f._delta, f._Wv[:, n:n + m], f.n_updates]


def _sr_set(f, parts):
    x, W, delta, v, nu = parts
    f._set_factors(W, delta, v=v, x=x)
    f.n_updates = int(nu)


def _sw_fields(f):
    n, m, w = f.dim_x, f.dim_z, f.window
    return [("x", (n, m)), ("P", (n, n)), ("window_H", (w, n)), ("window_z", (w, m)),
            ("window_R", (w,)), ("counters", (5,))]


def _sw_get(f):
    return [f.x, f.P, f._wH, f._wZ, f._wR, f._int_state().astype(float)]


def _sw_set(f, parts):
    x, P, wH, wZ, wR, ist = parts
    f.x, f.P = x.copy(), P.copy()
    f._wH, f._wZ, f._wR = wH.copy(), wZ.copy(), wR.copy()
    f._set_int_state(ist.astype(np.int64))


# keyed by class name, looked up along the MRO (subclasses included): the filters
# call into this module (``as_iosystem``), so it must not import them
_ADAPTERS = {
    "SlidingWindowRLS": (_sw_fields, _sw_get, _sw_set),
    "SquareRootRLS": (_sr_fields, _sr_get, _sr_set),
    "RecursiveLeastSquares": (_rls_fields, _rls_get, _rls_set),
}


def _adapter(f, name="estimator"):
    for cls in type(f).__mro__:
        if cls.__module__.startswith("rlsfilt.filters") and cls.__name__ in _ADAPTERS:
            return _ADAPTERS[cls.__name__]
    known = ", ".join(_ADAPTERS)
    raise TypeError(f"`{name}` must be an rlsfilt filter ({known}) to run as a python-control "
                    f"system; got {type(f).__name__}")


def check_supported(f, name="estimator"):
    """Raise a `TypeError` naming `name` unless `f`'s state can be flattened."""
    _adapter(f, name)


def state_labels(f, prefix=""):
    """One label per entry of :func:`get_state`, e.g. ``P[0,1]``."""
    fields, _, _ = _adapter(f)
    labels = []
    for name, shape in fields(f):
        if shape == ():
            labels.append(prefix + name)
        else:
            labels += [f"{prefix}{name}[{','.join(map(str, idx))}]" for idx in np.ndindex(*shape)]
    return labels


def get_state(f):
    """The filter's complete state as a new 1-D float array."""
    _, get, _ = _adapter(f)
    return np.concatenate([np.asarray(v, dtype=float).reshape(-1) for v in get(f)])


def set_state(f, vec):
    """Restore the filter from a vector made by :func:`get_state` (exact copies)."""
    fields, _, put = _adapter(f)
    parts, i = [], 0
    for _, shape in fields(f):
        size = int(np.prod(shape)) if shape else 1
        block = vec[i:i + size]
        parts.append(block.reshape(shape) if shape else float(block[0]))
        i += size
    if i != len(vec):
        raise ValueError(f"the filter state must have {i} entries; got {len(vec)}")
    put(f, parts)
