r"""An rlsfilt filter as a python-control I/O system: online identification in a diagram.

`estimator_iosystem` wraps a filter (`RecursiveLeastSquares`,
`SquareRootRLS`, `SlidingWindowRLS`) in a discrete-time
`control.NonlinearIOSystem` whose state is the filter's complete state (the
estimate and the covariance, or the square root or window the filter keeps)
and whose outputs are the estimate and the a-priori prediction error. It can
sit beside a plant, a controller and a Kalman filter in one
`control.interconnect`.
"""

import numbers

import numpy as np

from .._iosystem import call_capturing, make_iosystem
from .._validation import check_dt, check_int
from . import _filter_state
from ._streaming import vector_kernels
from .contract import restore_filter, snapshot_filter, vector_step_constants

__all__ = ["estimator_iosystem"]


class _EstimatorStepper:
    """A filter plus the memory its regressor needs; one `_io_step` per sample."""

    def __init__(self, filt, mode, orders=None, fn=None):
        self.filter = filt
        self.mode = mode
        self.fn = fn
        self.n_inputs = self._state_size = 0    # set by estimator_iosystem
        self._plan = None                       # the compiled sample's, set there too
        # the memories, newest first, as tuples of floats: a sample makes new ones, so a
        # snapshot shares them (about 2 us less per sample than pushing into arrays)
        if mode == "arx":
            self.na, self.nb, self.nk = orders
            self._ypast = (0.0,) * self.na                        # y(t-1), ..
            self._upast = (0.0,) * (self.nk + self.nb - 1)        # u(t-1), ..
        else:
            self._ypast = self._upast = ()

    def _measurement(self, w):
        n, m = self.filter.dim_x, self.filter.dim_z
        if self.mode == "arx":
            # phi(t) = [-y(t-1) .. -y(t-na), u(t-nk) .. u(t-nk-nb+1)]
            nk, nb = self.nk, self.nb
            past_u = (self._upast[nk - 1:nk - 1 + nb] if nk
                      else (float(w[0]),) + self._upast[:nb - 1])
            return w[1], np.array([-y for y in self._ypast] + list(past_u))
        if self.mode == "direct":
            return (w[0] if m == 1 else w[:m]), w[m:m + n]
        z, H = self.fn(w)
        return z, np.asarray(H, dtype=float).reshape(-1)

    def _io_step(self, w):
        f = self.filter
        z, H = self._measurement(w)
        x = np.asarray(f.x, dtype=float)
        # predict + update, as predict_update without its undo: a failed step is never
        # reused (each evaluation restores the state from x)
        _, messages = call_capturing(_predict_update, f, z, H)
        self._remember(w)
        return self._outputs(np.asarray(f.x, dtype=float), z, H, x), messages

    def _remember(self, w):
        if self.mode == "arx":
            u, y = w.tolist()
            if self._ypast:
                self._ypast = (y,) + self._ypast[:-1]
            if self._upast:
                self._upast = (u,) + self._upast[:-1]

    def _outputs(self, xn, z, H, x):
        """``[theta after the step, z - H x]`` (`x` the estimate before it)."""
        n, m = xn.size, self.filter.dim_z
        out = np.empty(n + m)
        out[:n] = xn.ravel()
        # the a-priori errors e = z - H x, summed in order as the compiled sample does
        # (new writable arrays: numba would compile a read-only view's call apart)
        z = np.full(m, np.nan) if z is None else np.array(z, dtype=float).reshape(-1)
        vector_kernels().prediction_errors(z, np.ascontiguousarray(H),
                                           np.ascontiguousarray(x.reshape(-1, m)), out[n:])
        return out

    def _vector_plan(self):
        """``(orders, il, Q, cfg, R, check_every)`` of the compiled sample
        (`_kernels_vector.estimator_sample`), or None: a callable regressor, or a
        filter without a compiled step on its state vector (any but
        `RecursiveLeastSquares`, or a frozen one)."""
        constants = vector_step_constants(self.filter)
        if constants is None or self.mode == "callable":
            return None
        f, arx = self.filter, self.mode == "arx"
        orders = np.array([f.dim_x, f.dim_z, arx, *((self.na, self.nb, self.nk) if arx
                                                   else (0, 0, 0))], dtype=np.int64)
        return (orders, *constants)

    def _io_vector_sample(self, x, w):
        """``(outputs, next state vector)`` of one sample by one compiled call
        (`_kernels_vector.estimator_sample`), nothing changed; None when the filter's
        methods must take it (see `rlsfilt._iosystem`)."""
        plan = self._plan
        if plan is None or len(x) != self._state_size or len(w) != self.n_inputs:
            return None
        out = np.empty(len(x))
        outputs = np.empty(self.filter.dim_z * (self.filter.dim_x + 1))
        status = vector_kernels().estimator_sample(x, w, out, outputs, *plan)
        return (outputs, out) if status == 0 else None

    def _get_state(self):
        layout = self._layout()
        nf, memories = layout.size, self._ypast + self._upast
        vec = np.empty(nf + len(memories))
        layout.pack(self.filter, vec[:nf])
        vec[nf:] = memories
        return vec

    def _layout(self):
        layout = self.__dict__.get("_state_layout")
        if layout is None or layout.owner is not self.filter:
            layout = self._state_layout = _filter_state.StateLayout(self.filter)
        return layout

    def _snapshot(self):
        """A cheap copy of the state (see `rlsfilt._iosystem`): the filter's attributes
        and the memories."""
        snap = snapshot_filter(self.filter)
        if snap is None:                               # a filter without the shared base
            return None, self._get_state()
        return snap, self._ypast, self._upast

    def _restore_snapshot(self, snap):
        if snap[0] is None:
            self._set_state(snap[1])
            return
        restore_filter(self.filter, snap[0])
        self._ypast, self._upast = snap[1], snap[2]

    def _set_state(self, vec):
        nf = len(vec) - len(self._ypast) - len(self._upast)
        self._layout().unpack(self.filter, vec[:nf])
        ny = len(self._ypast)
        self._ypast = tuple(vec[nf:nf + ny].tolist())
        self._upast = tuple(vec[nf + ny:].tolist())


def _predict_update(f, z, H):
    f.predict()
    f.update(z, H)


def estimator_iosystem(filter, regressor="direct", dt=True, *, inputs=None, name="estimator"):
    r"""A filter as a discrete-time python-control `NonlinearIOSystem`.

    Parameters
    ----------
    filter : RecursiveLeastSquares, SquareRootRLS or SlidingWindowRLS
        The estimator, in its current state (it is copied: simulations do
        not change it).
    regressor : "direct", tuple, model or callable, default "direct"
        How the measurement ``z`` and the regressor row ``H`` come from the
        inputs at each sample:

        * ``"direct"``: inputs ``z`` (or ``z[0] .. z[m-1]``) and
          ``phi[0] .. phi[n-1]``: the regressor is computed elsewhere in
          the diagram;
        * ``(na, nb, nk)`` or an `~rlsfilt.ARX` model (its orders): an ARX
          model of one input and one output; inputs ``['u', 'y']`` and the
          regressor :math:`[-y(t-1) .. -y(t-n_a), u(t-n_k) .. u(t-n_k-n_b+1)]`
          built from the system's own memory of past samples (zero before
          the start, as in `~rlsfilt.ARX.predict`);
        * a callable ``f(w) -> (z, H)`` of the input vector ``w`` (give
          `inputs`).
    dt : True or float, default True
        Sampling period.
    inputs : int or list of str, optional
        Number or names of the inputs, for a callable `regressor` only.
    name : str, default "estimator"
        System name in `control.interconnect`.

    Returns
    -------
    control.NonlinearIOSystem
        Outputs ``theta[0] .. theta[n-1]`` (``theta[i,j]`` for ``dim_z > 1``),
        the estimate after the sample's update, then ``e`` (``e[j]``), the
        a-priori prediction error :math:`z - H\hat\theta(t-1)`. States: the
        filter's complete state (``x``, ``P`` or the square root ``U``, the
        window of `SlidingWindowRLS`, counters), then the regressor memory.

    Notes
    -----
    One sample of the system is ``filter.predict(); filter.update(z, H)``,
    so a simulation equals the filter run over the same data to round-off.
    python-control's default initial state, all zeros, stands for the
    filter's state at this call; pass another state vector as the initial
    state to start elsewhere. Also available as ``filter.as_iosystem(regressor)``.

    Examples
    --------
    Identify ``y(t) = 0.8 y(t-1) + 0.5 u(t-1)`` from a python-control
    simulation, inside one interconnected system:

    >>> import control
    >>> import numpy as np
    >>> from rlsfilt import RecursiveLeastSquares
    >>> from rlsfilt.adaptive import estimator_iosystem
    >>> plant = control.tf([0, 0.5], [1, -0.8], True, inputs="u", outputs="y")
    >>> est = estimator_iosystem(RecursiveLeastSquares(2), regressor=(1, 1, 1))
    >>> sys = control.interconnect([plant, est], inputs="u",
    ...                            outputs=["y", "theta[0]", "theta[1]", "e"])
    >>> u = np.random.default_rng(0).standard_normal(200)
    >>> resp = control.input_output_response(sys, np.arange(200), u)
    >>> np.round(resp.outputs[1:3, -1], 4)          # [a1, b1]
    array([-0.8,  0.5])
    """
    _filter_state.check_supported(filter, "filter")
    n, m = filter.dim_x, filter.dim_z
    dt = check_dt(dt)
    in_labels = None
    if isinstance(regressor, str):
        if regressor != "direct":
            raise ValueError(f"`regressor` must be 'direct', (na, nb, nk), an ARX model or a "
                             f"callable; got {regressor!r}")
        stepper = _EstimatorStepper(filter.copy(), "direct")
        in_labels = (["z"] if m == 1 else [f"z[{j}]" for j in range(m)]) + \
            [f"phi[{i}]" for i in range(n)]
    elif callable(regressor) and not hasattr(regressor, "na"):
        if inputs is None:
            raise TypeError("`inputs` (a number or a list of names) is required with a callable "
                            "`regressor`")
        in_labels = ([f"w[{i}]" for i in range(check_int(inputs, "inputs", minimum=1))]
                     if isinstance(inputs, numbers.Integral) else [str(s) for s in inputs])
        stepper = _EstimatorStepper(filter.copy(), "callable", fn=regressor)
    else:
        orders = _arx_orders(regressor)
        if m != 1 or orders[0] + orders[1] != n:
            raise ValueError(f"`filter` must have dim_x = na + nb = {orders[0] + orders[1]} and "
                             f"dim_z = 1 for the ARX regressor {orders}; got dim_x = {n}, "
                             f"dim_z = {m}")
        stepper = _EstimatorStepper(filter.copy(), "arx", orders=orders)
        in_labels = ["u", "y"]
    if inputs is not None and not callable(regressor):
        raise TypeError("`inputs` only applies to a callable `regressor`")
    theta = ([f"theta[{i}]" for i in range(n)] if m == 1 else
             [f"theta[{i},{j}]" for i in range(n) for j in range(m)])
    errors = ["e"] if m == 1 else [f"e[{j}]" for j in range(m)]
    states = _filter_state.state_labels(filter) + \
        [f"y[t-{i + 1}]" for i in range(len(stepper._ypast))] + \
        [f"u[t-{i + 1}]" for i in range(len(stepper._upast))]
    stepper.n_inputs, stepper._state_size = len(in_labels), len(states)
    stepper._plan = stepper._vector_plan()          # None: every sample by the methods
    return make_iosystem(stepper, inputs=in_labels, outputs=theta + errors, states=states,
                         dt=dt, name=name)


def _arx_orders(regressor):
    if all(hasattr(regressor, k) for k in ("na", "nb", "nk")):
        vals = (regressor.na, regressor.nb, regressor.nk)
    else:
        try:
            vals = tuple(regressor)
        except TypeError:
            vals = ()
        if len(vals) != 3:
            raise TypeError(f"`regressor` must be 'direct', (na, nb, nk), an ARX model or a "
                            f"callable; got {regressor!r}")
    na = check_int(vals[0], "na", minimum=0)
    nb = check_int(vals[1], "nb", minimum=1)
    nk = check_int(vals[2], "nk", minimum=0)
    return na, nb, nk

