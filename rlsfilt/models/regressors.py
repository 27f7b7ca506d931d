r"""ARX structure and regressor matrices.

One convention for the whole package, the one of MATLAB's System
Identification Toolbox (``arx(data, [na nb nk])``):

.. math::

    y(t) + a_1 y(t-1) + \dots + a_{n_a} y(t-n_a)
        = b_1 u(t-n_k) + \dots + b_{n_b} u(t-n_k-n_b+1) + e(t),

so that :math:`y(t) = \varphi(t)\,\theta + e(t)` with the regressor row,
per-signal blocks each ordered by increasing lag,

.. math::

    \varphi(t) = [-y(t-1), \dots, -y(t-n_a),\;
                  u(t-n_k), \dots, u(t-n_k-n_b+1)],
    \qquad \theta = [a_1, \dots, a_{n_a}, b_1, \dots, b_{n_b}]^T,

stacked for :math:`t = t_0, \dots, N-1` with
:math:`t_0 = \max(n_a, n_k + n_b - 1)`, the first sample whose regressor is
complete. With several inputs there is one ``u`` block per input (``nb`` and
``nk`` per input); with several outputs the ``-y`` blocks of every output come
first, and every output is regressed on the same row.
"""

import numbers

import numpy as np

from .._validation import as_float_array, check_finite, check_int

__all__ = ["arx_regressors", "arx_structure", "ARXStructure"]


class ARXStructure:
    """Validated orders of an ARX model with a known number of signals.

    Attributes
    ----------
    na : int
        Number of past outputs of each output signal.
    nb, nk : tuple of int
        Number of input coefficients and input delay, one per input.
    n_inputs, n_outputs : int
        Number of input and output signals.
    max_lag : int
        ``t0 = max(na, max(nk + nb - 1))``: the first sample with a complete
        regressor, and the number of samples lost at the start.
    n_params : int
        Length of the regressor row, ``n_outputs * na + sum(nb)``.
    """

    __slots__ = ("na", "nb", "nk", "n_inputs", "n_outputs", "max_lag", "n_params")

    def __init__(self, na, nb, nk, n_inputs, n_outputs):
        self.na, self.nb, self.nk = na, nb, nk
        self.n_inputs, self.n_outputs = n_inputs, n_outputs
        self.max_lag = max([na] + [k + b - 1 for b, k in zip(nb, nk)])
        self.n_params = n_outputs * na + sum(nb)

    def param_slices(self):
        """``(a_slice, [b_slice per input])`` into the regressor row."""
        na_tot = self.n_outputs * self.na
        b_slices, start = [], na_tot
        for b in self.nb:
            b_slices.append(slice(start, start + b))
            start += b
        return slice(0, na_tot), b_slices

    def __repr__(self):
        return (f"ARXStructure(na={self.na}, nb={self.nb}, nk={self.nk}, "
                f"n_inputs={self.n_inputs}, n_outputs={self.n_outputs})")


def _per_input(value, name, n_inputs, minimum):
    """A scalar order or one per input, as a tuple of validated ints."""
    if isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, bool):
        return (check_int(value, name, minimum=minimum),) * n_inputs
    if isinstance(value, (str, bytes)) or not hasattr(value, "__len__"):
        check_int(value, name, minimum=minimum)  # raises the TypeError
    values = list(value)
    if len(values) != n_inputs:
        raise ValueError(
            f"`{name}` must be an integer or have one entry per input ({n_inputs}); "
            f"got {len(values)} entries")
    return tuple(check_int(v, f"{name}[{i}]", minimum=minimum) for i, v in enumerate(values))


def arx_structure(na, nb, nk=1, n_inputs=1, n_outputs=1):
    """Validate ARX orders and return an `ARXStructure`.

    Parameters
    ----------
    na : int
        Number of past outputs, ``>= 0`` (``0`` is an FIR model).
    nb : int or sequence of int
        Number of input coefficients, ``>= 1``; one per input or a scalar
        for all.
    nk : int or sequence of int, default 1
        Input delay in samples, ``>= 0`` (``0``: direct feed-through).
    n_inputs, n_outputs : int, default 1
        Number of input and output signals.

    Raises
    ------
    ValueError
        For negative orders, ``nb < 1``, or a list of the wrong length.
    TypeError
        For non-integer orders.
    """
    n_inputs = check_int(n_inputs, "n_inputs", minimum=1)
    n_outputs = check_int(n_outputs, "n_outputs", minimum=1)
    na = check_int(na, "na", minimum=0)
    nb = _per_input(nb, "nb", n_inputs, minimum=1)
    nk = _per_input(nk, "nk", n_inputs, minimum=0)
    return ARXStructure(na, nb, nk, n_inputs, n_outputs)


def _as_signal(x, name):
    """Return ``(array of shape (N, n), was_1d, names)`` from array-like or pandas."""
    names = None
    cols = getattr(x, "columns", None)
    if cols is not None:  # pandas DataFrame
        names = [str(c) for c in cols]
    elif getattr(x, "name", None) is not None and hasattr(x, "index"):  # pandas Series
        names = [str(x.name)]
    if hasattr(x, "to_numpy"):
        try:
            x = x.to_numpy(dtype=float)
        except (TypeError, ValueError) as exc:
            raise TypeError(f"`{name}` must be numeric; got {exc}") from None
    arr = as_float_array(x, name)
    if arr.ndim == 1:
        was_1d = True
        arr = arr.reshape(-1, 1)
    elif arr.ndim == 2:
        was_1d = False
    else:
        raise ValueError(f"`{name}` must have shape (N,) or (N, n_signals); got {arr.shape}")
    if arr.shape[1] == 0:
        raise ValueError(f"`{name}` must have at least one column; got shape {arr.shape}")
    check_finite(arr if not was_1d else arr[:, 0], name)
    return arr.copy(), was_1d, names


def as_io_data(u, y):
    """Validate an input/output record: ``U (N, nu)``, ``Y (N, ny)`` and metadata.

    Returns ``(U, Y, info)`` with ``info`` a dict holding ``u_1d``, ``y_1d``,
    ``u_names`` and ``y_names`` (from pandas, or None).
    """
    U, u_1d, u_names = _as_signal(u, "u")
    Y, y_1d, y_names = _as_signal(y, "y")
    if len(U) != len(Y):
        raise ValueError(f"`u` and `y` must have the same length; got {len(U)} input samples "
                         f"and {len(Y)} output samples")
    return U, Y, {"u_1d": u_1d, "y_1d": y_1d, "u_names": u_names, "y_names": y_names}


def _build(U, Y, s, start):
    """Regressor matrix for rows ``t = start .. N-1`` with zero past before t = 0."""
    N = len(U)
    pad = s.max_lag
    Up = np.vstack([np.zeros((pad, U.shape[1])), U])
    Yp = np.vstack([np.zeros((pad, Y.shape[1])), Y])
    t = np.arange(start, N) + pad  # row index into the padded arrays
    cols = []
    for i in range(s.n_outputs):
        for k in range(1, s.na + 1):
            cols.append(-Yp[t - k, i])
    for j in range(s.n_inputs):
        for k in range(s.nk[j], s.nk[j] + s.nb[j]):
            cols.append(Up[t - k, j])
    if not cols:
        return np.zeros((len(t), 0))
    return np.column_stack(cols)


def arx_regressors(u, y, na, nb, nk=1, *, start=None):
    r"""Regressor matrix and target of an ARX model.

    Parameters
    ----------
    u : array_like, shape (N,) or (N, nu)
        Input record (time on axis 0); pandas objects work too.
    y : array_like, shape (N,) or (N, ny)
        Output record.
    na, nb, nk
        Orders as in :func:`arx_structure`.
    start : int, optional
        First row. Defaults to ``max_lag``, the first sample whose regressor
        is complete; a smaller ``start`` (``0`` gives one row per sample)
        takes inputs and outputs before ``t = 0`` as zero.

    Returns
    -------
    Phi : ndarray, shape (N - start, n_params)
        Rows :math:`\varphi(t)`, blocks ``-y_1, ..., -y_ny, u_1, ..., u_nu``,
        each by increasing lag: ``[-y(t-1) ... -y(t-na), u(t-nk) ...
        u(t-nk-nb+1)]``.
    target : ndarray, shape (N - start,) or (N - start, ny)
        ``y(t)`` for the same rows (1-D when `y` is 1-D).

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.models import arx_regressors
    >>> u = np.arange(5.0)
    >>> y = 10 * np.arange(5.0)
    >>> Phi, target = arx_regressors(u, y, na=1, nb=2, nk=1)
    >>> Phi            # rows t = 2, 3, 4: [-y(t-1), u(t-1), u(t-2)]
    array([[-10.,   1.,   0.],
           [-20.,   2.,   1.],
           [-30.,   3.,   2.]])
    >>> target
    array([20., 30., 40.])
    """
    U, Y, info = as_io_data(u, y)
    s = arx_structure(na, nb, nk, U.shape[1], Y.shape[1])
    start = s.max_lag if start is None else check_int(start, "start", minimum=0)
    if start > len(U):
        raise ValueError(f"`start` must be <= N = {len(U)}; got {start}")
    Phi = _build(U, Y, s, start)
    target = Y[start:, 0].copy() if info["y_1d"] else Y[start:].copy()
    return Phi, target
