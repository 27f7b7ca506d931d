r"""Model output against measured data, from a stated initial state (MATLAB ``compare``).

The simulated and the ``k``-step predicted output of a linear model are
responses of a linear system, so they are affine in the system's initial
state :math:`x_0`:

.. math::

    \hat y(t) = \underbrace{C A^t}_{O(t)}\, x_0 + \hat y_{\mathrm{forced}}(t).

``initial="estimate"`` (MATLAB's default ``'e'``) chooses the :math:`x_0`
that minimizes :math:`\sum_t \lVert y(t) - \hat y(t) \rVert^2` over the record,
one linear least-squares solve with the free-response matrix :math:`O`;
``"zero"`` starts from rest; ``"measured"`` builds the state from the
measured past where that past defines it (equation-error structures).

The system is the model's own: for the simulation (an infinite horizon) the
observer-form realization of :meth:`~rlsfilt.models.IdentifiedModel.to_ss`,
so that :math:`x_0` is a state of ``model.to_ss()`` and
``control.forced_response(model.to_ss(), T, u, X0=x0)`` reproduces the
result; for a finite horizon ``k`` the ``k``-step predictor of Ljung (1999,
sec. 3.2), a system with inputs ``u`` and ``y``:

.. math::

    \hat y(t \mid t-k) = \bar H_k H^{-1} G\, u(t) + (1 - \bar H_k H^{-1})\, y(t),
    \qquad \bar H_k(q) = \sum_{i<k} h_i q^{-i},

with :math:`G = B/(A F)` and :math:`H = C/(A D)`, realized from the
difference equation :math:`C \prod_j F_j\, \hat y = \bar H_k D \sum_j B_j
\prod_{l \ne j} F_l\, u_j + (C - \bar H_k A D) \prod_j F_j\, y` (for several
outputs, ARX only: :math:`\hat y = \bar H_k B u + (I - \bar H_k A) y`).
"""

import html

import numpy as np

from .._display import Summary
from .._serialize import jsonable
from .._validation import check_int
from ..models._base import check_is_fitted
from ..models._conversion import arx_form, ss_matrices
from ..models._polynomials import poly_product
from ..models.regressors import _as_signal, as_records, is_listed
from .metrics import fit_percent

__all__ = ["Comparison", "compare"]

_INITIAL = ("estimate", "zero", "measured")


class Comparison:
    """What :func:`compare` computed: the model output, its fit and the initial state.

    Attributes
    ----------
    model : IdentifiedModel
        The compared model.
    y : ndarray, shape (N,) or (N, ny)
        Measured output (experiments one after the other).
    y_hat : ndarray, the shape of `y`
        Simulated (``horizon`` infinite) or ``horizon``-step predicted output.
    fit : float or ndarray of shape (ny,)
        :func:`fit_percent` of `y_hat` on the samples from `start` on (of
        every experiment): MATLAB's NRMSE fit,
        ``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` per output.
    initial : str
        ``"estimate"``, ``"zero"`` or ``"measured"``.
    horizon : int or float
        The prediction horizon (``np.inf``: simulation).
    x0 : tuple of ndarray
        The initial state of each experiment, in the coordinates of the
        realization (``model.to_ss()`` for the simulation), at sample
        `start` of that experiment.
    start : int
        First sample of each experiment the fit covers: 0, or for
        ``"measured"`` the number of measured samples that set the state
        (there ``y_hat`` repeats the measured output).
    experiment_lengths : tuple of int
        Samples per experiment.
    """

    def __init__(self, **fields):
        for key, value in fields.items():
            setattr(self, key, value)

    @property
    def is_simulation(self):
        """True for an infinite horizon (MATLAB ``compare(data, sys)``)."""
        return not np.isfinite(self.horizon)

    @property
    def initial_text(self):
        """The initial condition in words (what the reports and figures say)."""
        return initial_text(self.initial, self.start)

    @property
    def what(self):
        """``"simulation"`` or ``"3-step prediction"``."""
        return "simulation" if self.is_simulation else f"{int(self.horizon)}-step prediction"

    def summary(self):
        """One line: the fit of each output and the initial condition.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook.
        """
        fits = ", ".join(f"{v:.2f}%" for v in np.atleast_1d(self.fit))
        text = (f"{self.what} of {type(self.model).__name__} on {len(self.y)} samples: fit "
                f"{fits} ({self.initial_text})")
        return Summary(text, f"<p>{html.escape(text)}</p>")

    def __repr__(self):
        return self.summary().as_text()

    def _repr_html_(self):
        return self.summary().as_html()

    def to_dict(self):
        """JSON-ready: ``fit``, ``initial``, ``initial_text``, ``horizon`` (None for a
        simulation), ``x0`` (one list per experiment), ``start``, ``experiment_lengths``."""
        return jsonable({"fit": self.fit, "initial": self.initial,
                         "initial_text": self.initial_text,
                         "horizon": None if self.is_simulation else int(self.horizon),
                         "x0": [np.asarray(x) for x in self.x0], "start": self.start,
                         "experiment_lengths": list(self.experiment_lengths)})

    def plot(self, ax=None, window=None):
        """Measured against model output (:func:`rlsfilt.plotting.plot_compare`)."""
        from ..plotting import plot_compare
        return plot_compare(self, ax, window=window)


def compare(model, u, y=None, *, initial="estimate", horizon=np.inf):
    r"""Simulated or ``k``-step predicted output of a model against a record (MATLAB ``compare``).

    Parameters
    ----------
    model : IdentifiedModel
        A fitted model (any class of rlsfilt: its :meth:`polydata` is all
        that is used, and its operating point when it has one).
    u : array_like, shape (N,) or (N, nu), or IOData, or None
        Input record, or an `IOData` (then `y` is omitted); None for a
        time-series model (`AR`, `ARMA`), whose simulation is the free
        response of its noise model.
    y : array_like, shape (N,) or (N, ny), or a list of them
        Measured output (a list: one per experiment, each with its own
        initial state).
    initial : {"estimate", "zero", "measured"}, default "estimate"
        The initial state of every experiment. ``"estimate"`` (MATLAB's
        default ``'e'``): the state that minimizes the squared error of the
        model output over the record (linear least squares). ``"zero"``:
        from rest, everything before ``t = 0`` zero (at the operating point
        of a model with an offset); equals ``model.simulate(u)`` and
        ``model.predict(u, y, horizon)``. ``"measured"``: the state the
        measured past defines, for the samples after the first ``n`` (the
        state dimension); only for models whose simulated output is the
        measured output up to an equation error (no ``F``: ARX, ARMAX) and,
        for a finite horizon, whose predictor uses measured data only
        (no ``C``, no ``F``: ARX).
    horizon : int or np.inf, default np.inf
        ``np.inf`` (or ``>= N``): simulation. ``k >= 1``: the ``k``-step
        ahead prediction.

    Returns
    -------
    Comparison
        ``y_hat``, ``fit``, ``x0``, ``initial_text``, ``summary()``, ``plot()``.

    Raises
    ------
    ValueError
        An unknown `initial`, ``initial="measured"`` for a model whose
        measured past does not define the state (the message says why and
        what to use), or a record shorter than that state.

    Notes
    -----
    The fit is MATLAB's (``100 (1 - ||y - y_hat|| / ||y - mean(y)||)`` per
    output, over every sample of every experiment from `start` on), so with
    the default ``initial="estimate"`` it is the number MATLAB's
    ``compare(data, sys)`` prints for the same model. For an output-error
    model (noise model 1) every ``k``-step prediction is the simulation, and
    so are their fits (the predictor's state has no lags beyond its last
    nonzero coefficient).

    The least-squares problem is :math:`\min_{x_0} \lVert y - \hat
    y_{\mathrm{forced}} - O x_0 \rVert` with the free-response matrix
    :math:`O = [C; CA; CA^2; \dots]` of the realization, solved by SVD with
    the columns scaled to unit norm (Ljung 1999, sec. 10.5 on the initial
    state as a parameter).

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999, sec. 3.2, 10.5 and 16.6.

    Examples
    --------
    An output-error model of a plant that was not at rest when the record
    started (its output decays from 2): from rest the simulation misses that
    transient, the estimated initial state starts where the plant was.

    >>> import numpy as np
    >>> from scipy.signal import lfilter
    >>> from rlsfilt import OE, compare
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = lfilter([0, 0.1], [1, -0.95], u, zi=[2.0])[0] + 0.02 * rng.standard_normal(200)
    >>> model = OE(1, 1, 1).fit(u, y)
    >>> c = compare(model, u, y)
    >>> bool(c.fit > 90), bool(compare(model, u, y, initial="zero").fit < 10)
    (True, True)
    >>> c.initial_text
    'initial state estimated (least squares over the record)'
    """
    check_is_fitted(model, "compare")
    if not isinstance(initial, str) or initial not in _INITIAL:
        raise ValueError(f"`initial` must be 'estimate', 'zero' or 'measured'; got {initial!r}")
    if not (isinstance(horizon, (int, float, np.integer, np.floating)) and horizon == np.inf):
        horizon = check_int(horizon, "horizon", minimum=1)
    records, one_d = _records(model, u, y)
    polys = model.polydata()
    u_op = np.asarray(getattr(model, "input_offset_", None)
                      if getattr(model, "input_offset_", None) is not None
                      else np.zeros(records[0][0].shape[1]), dtype=float).reshape(-1)
    y_op = np.asarray(getattr(model, "output_offset_", None)
                      if getattr(model, "output_offset_", None) is not None
                      else np.zeros(records[0][1].shape[1]), dtype=float).reshape(-1)
    Ys, Yhats, x0s, starts = [], [], [], []
    for U, Y in records:
        N = len(Y)
        k = np.inf if horizon >= N else horizon
        A_p, B_p = _system(polys, k, model)
        if np.isfinite(k):      # the simulation's zero columns are a realization's placeholders
            A_p, B_p = _trim_lags(A_p, B_p)
        if initial == "measured":
            _check_measured(model, polys, A_p, k)
        W = np.hstack([U - u_op, Y - y_op])
        Yhat, x0, s = _response(A_p, B_p, W, Y - y_op, initial)
        Ys.append(Y)
        Yhats.append(Yhat + y_op)
        x0s.append(x0)
        starts.append(s)
    Y, Yhat = np.vstack(Ys), np.vstack(Yhats)
    offsets = np.cumsum([0] + [len(v) for v in Ys])[:-1]
    rows = np.concatenate([o + np.arange(s, len(v)) for o, s, v in zip(offsets, starts, Ys)])
    fit = fit_percent(Y[rows], Yhat[rows])
    if one_d:
        Y, Yhat = Y[:, 0], Yhat[:, 0]
        fit = float(np.atleast_1d(fit)[0])
    return Comparison(model=model, y=Y, y_hat=Yhat, fit=fit, initial=initial,
                      horizon=horizon if np.isfinite(horizon) else np.inf, x0=tuple(x0s),
                      start=starts[0], experiment_lengths=tuple(len(v) for v in Ys))


def initial_text(initial, start=0):
    """The initial condition in words, for reports and figure labels."""
    if initial == "estimate":
        return "initial state estimated (least squares over the record)"
    if initial == "zero":
        return "zero initial state (from rest)"
    return f"initial state from the measured first {start} samples"


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _records(model, u, y):
    """``([(U (N, nu), Y (N, ny)), ...], one_d)``; a time series has ``U`` of 0 columns."""
    if getattr(model, "n_inputs_", None) == 0:
        records, _ = _time_series_records(model, u, y)
        return records, True
    records, info = as_records(u, y)
    nu, ny = model.n_inputs_, model.n_outputs_
    for U, Y in records:
        if U.shape[1] != nu or Y.shape[1] != ny:
            raise ValueError(f"`u` and `y` must have the {nu} input and {ny} output column(s) "
                             f"the model was fitted with; got {U.shape[1]} and {Y.shape[1]}")
    return records, bool(info.get("y_1d", ny == 1)) and ny == 1


def _time_series_records(model, u, y):
    """``([(U (N_i, 0), Y (N_i, 1)), ...], info)`` of a time series (`u` None; `y` one
    signal or a list of them, one per experiment)."""
    name = type(model).__name__
    if u is not None:
        raise ValueError(f"`u` must be None for the time-series model {name} (it has no "
                         f"input): call validate(model, None, y); got {type(u).__name__}")
    if y is None:
        raise TypeError(f"`y` is required: validate(model, None, y) for the time-series "
                        f"model {name}")
    listed = is_listed(y)
    records = []
    for i, yi in enumerate(y if listed else [y]):
        label = f"y[{i}]" if listed else "y"
        Y, _, names = _as_signal(yi, label)
        if Y.shape[1] != 1:
            raise ValueError(f"`{label}` must have shape (N,) (one signal, as in fit); got "
                             f"{Y.shape}")
        records.append((np.zeros((len(Y), 0)), Y))
    info = {"u_1d": True, "y_1d": True, "u_names": [], "y_names": names,
            "n_experiments": len(records)}
    return records, info


def _system(polys, horizon, model):
    """``(A_p (ny, ny, L), B_p (ny, nu + ny, M))`` with ``A_p(q) yhat = B_p(q) [u; y]``.

    The simulation (``horizon`` infinite) is the difference equation of
    :func:`arx_form`, realized by ``to_ss`` (the columns of ``y`` are zero); a
    time series' is its noise model ``A D yhat = C e`` with ``e = 0``.
    """
    A, B, C, D, F = polys
    ny, nu = A.shape[0], B.shape[1]
    time_series = getattr(model, "n_inputs_", nu) == 0
    if not np.isfinite(horizon):
        A_t, B_t = arx_form(polys, noise=time_series)
        zeros = np.zeros((ny, ny if time_series else nu + ny, B_t.shape[2]))
        if not time_series:
            zeros[:, :nu] = B_t
        return A_t, zeros
    if ny == 1:
        a, c, d = np.asarray(A[0, 0], float), np.asarray(C[0], float), np.asarray(D[0], float)
        f = [np.asarray(F[0, j], float) for j in range(nu)]
        f_all = poly_product(f) if nu else np.ones(1)
        ad = np.convolve(a, d)
        h = _impulse(c, ad, horizon)                       # h_0 .. h_{k-1} of H = C/(A D)
        cols = [np.convolve(np.convolve(h, d), np.convolve(
            B[0, j], poly_product(f[i] for i in range(nu) if i != j))) for j in range(nu)]
        b_y = _sub(c, np.convolve(h, ad))
        b_y[0] = 0.0                                        # C(0) = h_0 A(0) D(0) = 1 exactly
        cols.append(np.convolve(b_y, f_all))
        M = max(len(p) for p in cols)
        B_p = np.zeros((1, nu + 1, M))
        for j, p in enumerate(cols):
            B_p[0, j, :len(p)] = p
        return np.convolve(c, f_all).reshape(1, 1, -1), B_p
    if not (np.all(C[:, 1:] == 0) and np.all(D[:, 1:] == 0) and np.all(F[:, :, 1:] == 0)):
        raise ValueError(f"a {horizon}-step prediction of several outputs needs an ARX "
                         f"structure (C, D, F equal to 1); use horizon=np.inf")
    # H = A^-1: its impulse response H_0 = I, H_j = -sum_i A_i H_{j-i}
    na = A.shape[2] - 1
    Hk = np.zeros((ny, ny, horizon))
    for j in range(horizon):
        Hk[:, :, j] = np.eye(ny) if j == 0 else -sum(
            A[:, :, i] @ Hk[:, :, j - i] for i in range(1, min(j, na) + 1))
    b_u = _matconv(Hk, B)
    b_y = -_matconv(Hk, A)
    b_y[:, :, 0] = 0.0                                      # I - H_0 A_0 = 0 exactly
    M = max(b_u.shape[2], b_y.shape[2])
    B_p = np.zeros((ny, nu + ny, M))
    B_p[:, :nu, :b_u.shape[2]] = b_u
    B_p[:, nu:, :b_y.shape[2]] = b_y
    A_p = np.zeros((ny, ny, 1))
    A_p[:, :, 0] = np.eye(ny)
    return A_p, B_p


def _trim_lags(A_p, B_p):
    """`A_p`, `B_p` without the lags beyond the last nonzero coefficient of either.

    The k-step predictor of a model whose noise-model impulse response ends early (an
    output-error model: ``H = 1``, so ``h = [1, 0, .., 0]``) carries trailing zero
    coefficients; each would add a state, a free response of ``initial="estimate"``
    that the predictor does not have (the k-step fit of OE came out above its
    simulation fit, for the same predictions).
    """
    used = np.flatnonzero(np.any(A_p != 0, axis=(0, 1))[:A_p.shape[2]])
    last = max(int(used[-1]) if used.size else 0,
               int(np.flatnonzero(np.any(B_p != 0, axis=(0, 1)))[-1])
               if np.any(B_p) else 0)
    return A_p[:, :, :last + 1], B_p[:, :, :last + 1]


def _check_measured(model, polys, A_p, horizon):
    """``initial="measured"`` only where the measured past defines the state."""
    name = type(model).__name__
    if not np.isfinite(horizon):
        if getattr(model, "n_inputs_", None) == 0 and np.any(polys.C[:, 1:] != 0):
            raise ValueError(
                f"initial='measured' does not apply to the free response of {name}: the state "
                f"of its noise model C/(A D) holds past noise values (C is not 1) that the "
                f"measured data do not give; use initial='estimate' (MATLAB compare's "
                f"default) or initial='zero'")
        if np.any(polys.F[..., 1:] != 0):
            raise ValueError(
                f"initial='measured' does not apply to the simulation of {name}: its output "
                f"B/F u is not the measured output (the noise enters after F), so the measured "
                f"past does not define its state (MATLAB has no such option either); use "
                f"initial='estimate' (MATLAB compare's default) or initial='zero'")
        return
    if np.any(A_p[:, :, 1:] != 0):
        raise ValueError(
            f"initial='measured' does not apply to the {horizon}-step prediction of {name}: "
            f"its predictor filters by C F (a state of past prediction errors the measured "
            f"data do not give); use initial='estimate' (MATLAB compare's default) or "
            f"initial='zero'")


def _response(A_p, B_p, W, Y, initial):
    """``(Yhat (N, ny), x0, start)`` of ``A_p yhat = B_p w`` from the chosen initial state."""
    Am, Bm, Cm, Dm = ss_matrices(A_p, B_p)
    N, ny, n = len(W), A_p.shape[0], Am.shape[0]
    if initial == "measured":
        if N <= n // ny:
            raise ValueError(f"initial='measured' needs more than the {n // ny} samples that "
                             f"set the state; got {N}")
        s = n // ny                         # the state holds s past samples of ny outputs
        x0 = _state_from_past(A_p, B_p, Y, W, s)
        Yhat = Y.copy()                     # the first s samples: the measured output
        Yhat[s:] = _forced(Am, Bm, Cm, Dm, A_p, B_p, W[s:]) + _free(Am, Cm, A_p, N - s) @ x0
        return Yhat, x0, s
    forced = _forced(Am, Bm, Cm, Dm, A_p, B_p, W)
    if initial == "zero" or n == 0:
        return forced, np.zeros(n), 0
    Ob = _free(Am, Cm, A_p, N)          # the free-response matrix O, (N, ny, n)
    Ob2 = Ob.reshape(N * ny, n)
    with np.errstate(over="ignore", invalid="ignore"):
        scale = np.sqrt(np.nansum(np.where(np.isfinite(Ob2), Ob2, np.nan) ** 2, axis=0))
    scale[~np.isfinite(scale) | (scale == 0)] = 1.0
    rhs = (Y - forced).reshape(-1)
    ok = np.all(np.isfinite(Ob2), axis=1) & np.isfinite(rhs)   # a diverging (unstable) response
    z = np.linalg.lstsq(Ob2[ok] / scale, rhs[ok], rcond=None)[0]
    x0 = z / scale
    return forced + Ob @ x0, x0, 0


def _forced(Am, Bm, Cm, Dm, A_p, B_p, W):
    """Response from rest, ``(N, ny)``: lfilter per input for one output, the state
    recursion otherwise."""
    from scipy.signal import lfilter

    N, ny, n = len(W), A_p.shape[0], Am.shape[0]
    out = np.zeros((N, ny))
    if ny == 1:
        a = np.zeros(n + 1)
        a[:A_p.shape[2]] = A_p[0, 0]
        for j in range(W.shape[1]):
            b = np.zeros(n + 1)
            b[:B_p.shape[2]] = B_p[0, j]
            if np.any(b):
                out[:, 0] += lfilter(b, a, W[:, j])
        return out
    x = np.zeros(n)
    for t in range(N):
        out[t] = Cm @ x + Dm @ W[t]
        x = Am @ x + Bm @ W[t]
    return out


def _free(Am, Cm, A_p, N):
    """Free response ``O[t] = C A^t``, shape ``(N, ny, n)``."""
    from scipy.signal import lfilter

    ny, n = Cm.shape
    Ob = np.zeros((N, ny, n))
    if ny == 1:
        a = np.zeros(n + 1)
        a[:A_p.shape[2]] = A_p[0, 0]
        for i in range(n):     # lfilter's state is the observer-form state (transposed DF II)
            zi = np.zeros(n)
            zi[i] = 1.0
            Ob[:, 0, i] = lfilter(np.zeros(n + 1), a, np.zeros(N), zi=zi)[0]
        return Ob
    M = Cm.copy()
    for t in range(N):
        Ob[t] = M
        M = M @ Am
    return Ob


def _state_from_past(A_p, B_p, Y, W, s):
    r"""The observer-form state at sample `s` from measured outputs and inputs before it:
    :math:`x_i(s) = \sum_{k=i}^{n} B_k w(s+i-1-k) - A_k y(s+i-1-k)`, ``i = 1 .. n``."""
    ny = A_p.shape[0]
    n = s
    x = np.zeros((n, ny))
    for i in range(1, n + 1):
        for k in range(i, n + 1):
            t = s + i - 1 - k
            if k < B_p.shape[2]:
                x[i - 1] += B_p[:, :, k] @ W[t]
            if k < A_p.shape[2]:
                x[i - 1] -= A_p[:, :, k] @ Y[t]
    return x.reshape(-1)


def _impulse(num, den, k):
    """First `k` samples of the impulse response of ``num/den`` (powers of q^-1)."""
    from scipy.signal import lfilter

    pulse = np.zeros(k)
    pulse[0] = 1.0
    return lfilter(num, den, pulse)


def _sub(p, q):
    out = np.zeros(max(len(p), len(q)))
    out[:len(p)] += p
    out[:len(q)] -= q
    return out


def _matconv(P, Q):
    """Product of matrix polynomials ``P (a, b, lp)`` and ``Q (b, c, lq)``."""
    out = np.zeros((P.shape[0], Q.shape[1], P.shape[2] + Q.shape[2] - 1))
    for i in range(P.shape[2]):
        for j in range(Q.shape[2]):
            out[:, :, i + j] += P[:, :, i] @ Q[:, :, j]
    return out
