r"""The filter contract: what every rlsfilt filter provides, declared once.

A filter is an object with the filterpy interface of a recursive estimator
(``predict``, ``update(z, H, R=None)``, ``predict_update``, ``batch_filter``,
``initialize``, ``reset``; the estimate ``x`` of shape ``(dim_x, dim_z)``)
plus three things the rest of the package relies on instead of private
members:

- **state export and import**: :meth:`Filter.get_state` returns a dict of
  *copies* of everything a resumed run needs (``x`` first, then ``P`` or the
  factor the filter keeps instead, then the counters and pending decisions);
  :meth:`Filter.set_state` takes such a dict back (the same keys and shapes)
  and the filter then continues bit for bit as the one it came from would.
  The models hand a run in scaled units over to the user's filter through it,
  and `rlsfilt.adaptive` flattens it into a python-control state vector
  (`rlsfilt.filters._filter_state`), so a new filter runs there unchanged;
- **the step**: ``_batch_compiled(Z, H, R, update_first, store_covariances)``,
  the batch loop behind ``batch_filter`` (compiled for the production
  filters; a plain loop is allowed) that the shared base
  (`rlsfilt.filters._base._FilterBase`) calls after validating the record;
- **an optional compiled step on the state vector** for the python-control
  systems, which take a whole sample as one compiled call:
  ``_vector_step_constants()`` returns the constants with which
  `rlsfilt.filters._kernels_vector.vector_step` steps the filter's
  :meth:`Filter.get_state` vector as ``predict(); update(z, H)`` would
  (`RecursiveLeastSquares`); the default is None, and the systems then call the
  filter's methods (`rlsfilt.filters._estimator_io`);
- **an optional cheap snapshot** for the same systems, which step one
  object back and forth between states: ``_shallow_state()`` (the attributes
  as a new dict), ``_restore(state)`` and ``_written_in_place`` (the arrays a
  step writes into, which a snapshot must copy); the shared base provides
  them. `snapshot_filter` and `restore_filter` use them, and a filter without
  them is copied through ``get_state``/``set_state``;
- **capabilities**, class attributes (or properties) that tests and callers
  consult instead of asking for a class:

  ``has_covariance``
      the filter keeps a covariance ``P`` (readable, assignable, ``P0`` at
      construction) and checks its health (``check_every``, ``cond_max``);
  ``least_squares``
      the estimate is (weighted) least squares on the data, so ``lstsq`` is
      its oracle;
  ``forgets``
      the time update changes the state (forgetting or a random walk), so an
      ``update`` without ``predict`` skips something (and warns);
  ``supports_constraints``
      ``constrain(A, b)`` keeps the estimate on ``A x = b``.

A new filter subclasses `_FilterBase` (the validation, the diagnostics and the
atomic ``batch_filter``/``predict_update`` come with it), implements the
abstract members below and sets its capabilities; one line in the registry of
``tests/test_contract_filters.py`` then runs the whole contract on it
(``tests/example_filter.py`` is the smallest such filter).
"""

import abc

import numpy as np

__all__ = ["Filter", "check_state", "snapshot_filter", "restore_filter"]


class Filter(abc.ABC):
    """Abstract base of the rlsfilt filters (see the module docstring)."""

    #: The filter keeps a covariance ``P`` and checks its health.
    has_covariance = True
    #: The estimate is (weighted) least squares on the data seen.
    least_squares = True
    #: ``constrain(A, b)`` is available.
    supports_constraints = False

    @property
    def forgets(self):
        """Whether :meth:`predict` changes the state (so an ``update`` without it skips
        a time update). False unless a filter says otherwise."""
        return False

    @abc.abstractmethod
    def predict(self):
        """Time update."""

    @abc.abstractmethod
    def update(self, z, H, R=None):
        """Measurement update with measurement `z` and regressor row `H`."""

    @abc.abstractmethod
    def initialize(self, zs, Hs):
        """Start from least squares on the samples `zs`, `Hs`."""

    @abc.abstractmethod
    def reset(self):
        """Return to the state given at construction."""

    @abc.abstractmethod
    def get_state(self):
        """Copies of everything a resumed run needs, as a dict (``x`` first).

        Values are float64 arrays or Python scalars (``float``, ``int``,
        ``bool``); the keys and shapes depend only on the configuration
        (``dim_x``, ``dim_z``, a window length), never on the data.
        """

    @abc.abstractmethod
    def set_state(self, state):
        """Continue from `state` (a dict as :meth:`get_state` returns; copied)."""

    @abc.abstractmethod
    def _batch_compiled(self, Z, Hm, Rv, update_first, store_covariances):
        """The batch loop behind ``batch_filter`` on a validated record: ``Z`` (N,
        dim_z) with NaN for missing samples, ``Hm`` (N, dim_x), ``Rv`` (N,).
        Returns ``(means, covariances, means_p, covariances_p)``; leaves the
        filter unchanged if it raises."""

    def _vector_step_constants(self):
        """The constants with which `rlsfilt.filters._kernels_vector.vector_step` takes
        this filter's plain step on its state vector: ``(il, Q, cfg, R,
        check_every)``; None when the filter has no compiled step on its state
        vector (the default)."""
        return None

    #: The arrays a step writes into in place, which a snapshot must copy to stay
    #: valid (the others are replaced, not written).
    _written_in_place = ()

    def _shallow_state(self):
        """The attributes as a new dict, for a cheap snapshot; None: no snapshot (the
        default), the filter is copied through :meth:`get_state`."""
        return None

    def _restore(self, state):
        """Put back a dict of :meth:`_shallow_state`."""
        raise NotImplementedError("this filter takes no snapshot (_shallow_state is None)")


def snapshot_filter(f):
    """A copy of filter `f`'s attributes that stays valid, for the python-control
    systems (`rlsfilt._iosystem`), which step one object back and forth between
    states; None when `f` takes no snapshot (the caller then copies through
    ``get_state``).

    A step replaces the arrays it changes, except those the filter lists in
    ``_written_in_place`` (the ring buffer of `SlidingWindowRLS`): only these are
    copied.
    """
    state = f._shallow_state() if isinstance(f, Filter) else None
    if state is None:
        return None
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


def vector_step_constants(f):
    """The constants ``(il, Q, cfg, R, check_every)`` with which
    `rlsfilt.filters._kernels_vector.vector_step` takes the plain step of filter `f`
    on its state vector (``predict(); update(z, H)`` as one compiled call on the
    numbers of :meth:`Filter.get_state`); None when `f` has no such step (the
    python-control systems then step the filter's methods). Copies: changing them
    changes nothing."""
    return f._vector_step_constants() if isinstance(f, Filter) else None


def check_state(filt, state):
    """`state` checked against ``filt.get_state()``: the same keys, in order, and
    the same shapes; returns the values as ``{key: array or scalar}`` copies.

    Raises
    ------
    TypeError
        If `state` is not a mapping.
    ValueError
        If a key is missing or extra, or an entry has the wrong shape.
    """
    if not hasattr(state, "keys"):
        raise TypeError(f"`state` must be a dict from get_state(); got {type(state).__name__}")
    template = filt.get_state()
    if list(state.keys()) != list(template.keys()):
        raise ValueError(f"`state` must have the keys {list(template)} (from get_state() of "
                         f"this filter); got {list(state)}")
    out = {}
    for key, like in template.items():
        value = state[key]
        if isinstance(like, np.ndarray):
            value = np.array(value, dtype=np.float64, order="C")
            if value.shape != like.shape:
                raise ValueError(f"`state['{key}']` must have shape {like.shape}; got "
                                 f"{value.shape}")
        else:
            value = type(like)(value)
        out[key] = value
    return out
