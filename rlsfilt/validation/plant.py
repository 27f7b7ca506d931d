r"""Comparison of an identified model with the true plant, by python-control.

This is what simulated identification studies need and no toolbox offers in
one place: the identified transfer function and the true plant are both
simulated and evaluated by python-control, on the model's sample time, and
their step responses, frequency responses, DC gains and poles are compared.
"""

import html
import math
import warnings

import numpy as np

from .._display import Summary, frame_html, table_html
from .._validation import as_float_array, check_int
from ..exceptions import ConversionWarning
from ..models._base import IdentifiedModel, check_is_fitted
from ..plotting import plot_bode, plot_plant_comparison, plot_step

__all__ = ["PlantComparison"]


class PlantComparison:
    r"""Compare an identified model with the true plant.

    Parameters
    ----------
    model : IdentifiedModel or control.LTI
        A fitted model (its ``to_tf()`` is used) or a discrete-time
        python-control system.
    plant : control.LTI
        The true system, any python-control LTI object (transfer function or
        state space). A continuous-time plant is discretized with a
        zero-order hold at the model's sample time (that is the system an
        identified discrete model estimates, Ljung 1999, sec. 2.1); a
        discrete plant must have the model's sample time.
    n_points : int, default 500
        Number of frequencies on the logarithmic grid.
    omega : array_like, optional
        Frequencies (rad per time unit) to use instead of the default grid,
        for example to stop short of the Nyquist frequency when the plant
        has a zero near :math:`z = -1` (sampled mechanical systems), where
        the relative error is large however good the model.
    n_steps : int, optional
        Length of the step responses in samples. By default about eight
        time constants of the slowest stable plant pole, between 50 and
        5000 samples.

    Attributes
    ----------
    model_tf, plant_tf : control.TransferFunction
        The two discrete systems compared (the plant after sampling).
    dt : float
        Sample time used for the frequency axis (1 when the systems have an
        unspecified sample time ``dt=True``: frequencies are then in
        rad/sample).
    omega : ndarray, shape (n_points,)
        Frequencies in rad per time unit, logarithmic from
        :math:`10^{-3}\,\omega_N` to the Nyquist frequency
        :math:`\omega_N = \pi / dt`.
    response_model, response_plant : ndarray of complex, shape (ny, nu, n_points)
        Frequency responses :math:`G(e^{j \omega dt})`.
    relative_error : ndarray, shape (ny, nu, n_points)
        :math:`|G_\mathrm{model} - G_\mathrm{plant}| / |G_\mathrm{plant}|`.
    frequency_error : float
        Maximum of `relative_error` over the grid (and channels). Near a
        plant zero on the grid this is large for any model; look at
        `relative_error` or pass `omega`.
    dc_gain_model, dc_gain_plant : ndarray, shape (ny, nu)
        Static gains :math:`G(1)`.
    dc_gain_error : float
        Largest relative DC-gain error
        :math:`|K_\mathrm{model} - K_\mathrm{plant}| / |K_\mathrm{plant}|`
        (``inf`` when exactly one of them is zero or infinite, as for a
        plant with an integrator and a model without).
    time : ndarray, shape (n_steps,)
        Time points of the step responses.
    step_model, step_plant : ndarray, shape (ny, nu, n_steps)
        Unit-step responses from ``control.step_response``.
    step_error : float
        Relative error of the step responses,
        :math:`\lVert s_\mathrm{model} - s_\mathrm{plant} \rVert_2 /
        \lVert s_\mathrm{plant} \rVert_2` over all channels.
    poles_model, poles_plant : ndarray of complex
        Poles matched pairwise (same length) by minimum total distance
        (Hungarian assignment).
    pole_distances : ndarray of float
        :math:`|p_\mathrm{model} - p_\mathrm{plant}|` for each matched pair.
    max_pole_distance : float
        Largest of `pole_distances` (0 if there are none).
    unmatched_model_poles, unmatched_plant_poles : ndarray of complex
        Poles left over when the orders differ.

    Notes
    -----
    Everything is evaluated by python-control: frequency responses by
    calling the transfer functions at :math:`z = e^{j \omega dt}`, step
    responses by ``control.step_response`` on the common time grid, DC gains
    at :math:`z = 1`, poles by ``poles()``.

    References
    ----------
    .. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed.,
       Prentice Hall, 1999.

    Examples
    --------
    >>> import control
    >>> from rlsfilt.validation import PlantComparison
    >>> plant = control.tf([0.5], [1, -0.8], 0.1)
    >>> model = control.tf([0.49], [1, -0.81], 0.1)
    >>> cmp = PlantComparison(model, plant)
    >>> bool(cmp.frequency_error < 0.1), round(cmp.max_pole_distance, 3)
    (True, 0.01)
    """

    def __init__(self, model, plant, n_points=500, n_steps=None, omega=None):
        from scipy.optimize import linear_sum_assignment  # lazy: keeps `import rlsfilt` light
        self.model_tf = _model_tf(model)
        self.plant_tf = _plant_tf(plant, self.model_tf)
        n_points = check_int(n_points, "n_points", minimum=2)
        dtm = self.model_tf.dt
        self.dt = 1.0 if dtm is True else float(dtm)
        if self.model_tf.ninputs != self.plant_tf.ninputs or \
                self.model_tf.noutputs != self.plant_tf.noutputs:
            raise ValueError(
                f"`model` and `plant` must have the same numbers of inputs and outputs; got "
                f"{self.model_tf.ninputs}x{self.model_tf.noutputs} (in x out) and "
                f"{self.plant_tf.ninputs}x{self.plant_tf.noutputs}")

        # frequency responses up to Nyquist
        self.omega = frequency_grid(omega, self.dt, n_points)
        z = np.exp(1j * self.omega * self.dt)
        self.response_model = _evaluate(self.model_tf, z)
        self.response_plant = _evaluate(self.plant_tf, z)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.relative_error = (np.abs(self.response_model - self.response_plant)
                                   / np.abs(self.response_plant))
        self.frequency_error = float(np.max(self.relative_error))

        # static gains
        self.dc_gain_model = _dc_gain(self.model_tf)
        self.dc_gain_plant = _dc_gain(self.plant_tf)
        self.dc_gain_error = float(np.max(_relative(self.dc_gain_model, self.dc_gain_plant)))

        # step responses on one time grid
        if n_steps is None:
            n_steps = _default_horizon(self.plant_tf)
        n_steps = check_int(n_steps, "n_steps", minimum=2)
        self.time = np.arange(n_steps) * self.dt
        self.step_model = _step(self.model_tf, self.time)
        self.step_plant = _step(self.plant_tf, self.time)
        den = np.linalg.norm(self.step_plant)
        num = np.linalg.norm(self.step_model - self.step_plant)
        self.step_error = float(num / den) if den > 0 else float(num)

        # poles, matched by minimum total distance
        pm, pp = np.asarray(self.model_tf.poles()), np.asarray(self.plant_tf.poles())
        if pm.size and pp.size:
            rows, cols = linear_sum_assignment(np.abs(pm[:, None] - pp[None, :]))
        else:
            rows = cols = np.array([], dtype=int)
        self.poles_model, self.poles_plant = pm[rows], pp[cols]
        self.pole_distances = np.abs(self.poles_model - self.poles_plant)
        self.max_pole_distance = float(self.pole_distances.max()) if rows.size else 0.0
        self.unmatched_model_poles = np.delete(pm, rows)
        self.unmatched_plant_poles = np.delete(pp, cols)

    def __repr__(self):
        return (f"<PlantComparison: frequency_error={self.frequency_error:.3g}, "
                f"dc_gain_error={self.dc_gain_error:.3g}, step_error={self.step_error:.3g}, "
                f"max_pole_distance={self.max_pole_distance:.3g}>")

    def summary(self):
        """A short table of the comparison: errors, then the matched poles.

        Returns
        -------
        Summary
            ``print`` it, or display it in a notebook (a table).
        """
        lines = [
            "Comparison with the true plant (python-control)",
            f"  max relative frequency-response error : {_pct(self.frequency_error)}"
            f"  (up to Nyquist, {self.omega[-1]:.4g} rad/time unit)",
            f"  relative DC-gain error                : {_pct(self.dc_gain_error)}",
            f"  relative step-response error          : {_pct(self.step_error)}",
            f"  largest matched pole distance         : {self.max_pole_distance:.4g}",
        ]
        for p, q, dist in zip(self.poles_model, self.poles_plant, self.pole_distances):
            lines.append(f"    pole {_fmt_complex(p):>22s}  vs plant {_fmt_complex(q):>22s}"
                         f"  |diff| {dist:.3g}")
        for p in self.unmatched_model_poles:
            lines.append(f"    extra model pole {_fmt_complex(p)}")
        for p in self.unmatched_plant_poles:
            lines.append(f"    plant pole not modelled {_fmt_complex(p)}")
        errors = [["max relative frequency-response error",
                   f"{_pct(self.frequency_error)} (up to Nyquist, {self.omega[-1]:.4g} "
                   f"rad/time unit)"],
                  ["relative DC-gain error", _pct(self.dc_gain_error)],
                  ["relative step-response error", _pct(self.step_error)],
                  ["largest matched pole distance", f"{self.max_pole_distance:.4g}"]]
        poles = [[_fmt_complex(p), _fmt_complex(q), f"{dist:.3g}"]
                 for p, q, dist in zip(self.poles_model, self.poles_plant, self.pole_distances)]
        poles += [[_fmt_complex(p), "none (extra model pole)", ""]
                  for p in self.unmatched_model_poles]
        poles += [["none (plant pole not modelled)", _fmt_complex(q), ""]
                  for q in self.unmatched_plant_poles]
        page = frame_html(html.escape(lines[0]), table_html(["quantity", "value"], errors),
                          table_html(["model pole", "plant pole", "|diff|"], poles))
        return Summary("\n".join(lines), page)

    # the figures: each method is its plotting function applied to this comparison, which
    # documents the arguments (passed on) and the return value
    def plot(self, fig=None, **kwargs):
        """Bode diagram and step responses, model over plant.

        Refer to :func:`rlsfilt.plotting.plot_plant_comparison` for full documentation.
        """
        return plot_plant_comparison(self, fig, **kwargs)

    def plot_bode(self, ax_mag=None, ax_phase=None, **kwargs):
        """Bode magnitude (dB) and phase (deg) of model and plant.

        Refer to :func:`rlsfilt.plotting.plot_bode` for full documentation.
        """
        return plot_bode(self, ax_mag, ax_phase, **kwargs)

    def plot_step(self, ax=None, **kwargs):
        """Unit-step responses of model and plant.

        Refer to :func:`rlsfilt.plotting.plot_step` for full documentation.
        """
        return plot_step(self, ax, **kwargs)


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _pct(fraction):
    """A relative error as a percentage with 4 significant digits (``0.01439 -> 1.439%``)."""
    return f"{100 * fraction:.4g}%"


def frequency_grid(omega, dt, n_points):
    r"""Validated frequencies in rad per time unit, or the default grid.

    The default is `n_points` logarithmically spaced frequencies from
    :math:`10^{-3}\,\omega_N` to the Nyquist frequency
    :math:`\omega_N = \pi / dt`; given frequencies must be finite and in
    :math:`[0, \omega_N]` (a discrete frequency response is periodic beyond).
    """
    nyquist = math.pi / dt
    if omega is None:
        return np.logspace(math.log10(nyquist) - 3.0, math.log10(nyquist), n_points)
    omega = as_float_array(omega, "omega").ravel()
    if omega.size == 0 or not np.all(np.isfinite(omega)) or np.any(omega < 0) \
            or np.any(omega > nyquist * (1 + 1e-12)):
        raise ValueError(f"`omega` must hold finite frequencies in [0, {nyquist:.6g}] "
                         "(up to Nyquist)")
    return omega


def _model_tf(model):
    import control  # lazily: python-control imports matplotlib.pyplot

    if isinstance(model, control.LTI):
        sys = model
    elif isinstance(model, IdentifiedModel):
        check_is_fitted(model, "PlantComparison")
        with warnings.catch_warnings():   # its frequency response needs no Slycot
            warnings.simplefilter("ignore", ConversionWarning)
            sys = model.to_tf()
    else:
        raise TypeError("`model` must be a fitted ARX model or a python-control LTI system "
                        f"(or another rlsfilt IdentifiedModel); got {type(model).__name__}")
    if not sys.isdtime():
        raise ValueError("`model` must be a discrete-time system (an identified model); got a "
                         "continuous-time one")
    return control.tf(sys)


def _plant_tf(plant, model_tf):
    import control

    if not isinstance(plant, control.LTI):
        raise TypeError(f"`plant` must be a python-control LTI system (control.tf, control.ss); "
                        f"got {type(plant).__name__}")
    dtm = model_tf.dt
    if plant.isctime(strict=True):
        if dtm is True:
            raise ValueError("`plant` is continuous-time but `model` has an unspecified sample "
                             "time (dt=True); give the model a numeric dt to sample the plant")
        plant = plant.sample(dtm, method="zoh")
    elif plant.dt is None:  # python-control's "either" timebase
        plant = control.tf(plant)
        plant.dt = dtm
    else:
        dtp = plant.dt
        if dtm is True or dtp is True:
            pass  # one side unspecified: accept, as python-control does
        elif not math.isclose(float(dtp), float(dtm), rel_tol=1e-9):
            raise ValueError(f"`plant` must have the model's sample time {dtm}; got dt={dtp}")
    tf = control.tf(plant)
    tf.dt = dtm
    return tf


def _evaluate(sys, z):
    """Frequency response at points `z`, shape (ny, nu, len(z))."""
    with np.errstate(divide="ignore", invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return np.asarray(sys(z, squeeze=False), dtype=complex)


def _step(sys, time):
    import control

    resp = control.step_response(sys, T=time, squeeze=False)
    return np.asarray(resp.outputs, dtype=float).reshape(sys.noutputs, sys.ninputs, len(time))


def _dc_gain(sys):
    """``num(1) / den(1)`` per channel: ``inf`` for an integrator, as a limit."""
    out = np.empty((sys.noutputs, sys.ninputs))
    with np.errstate(divide="ignore", invalid="ignore"):
        for i in range(sys.noutputs):
            for j in range(sys.ninputs):
                n = np.polyval(np.asarray(sys.num[i][j], dtype=float), 1.0)
                d = np.polyval(np.asarray(sys.den[i][j], dtype=float), 1.0)
                out[i, j] = n / d if d != 0.0 else math.copysign(math.inf, n) if n else math.nan
    return out


def _relative(a, b):
    """``|a - b| / |b|``, 0 where ``a == b`` (also both infinite), inf for b = 0 != a."""
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.abs(a - b) / np.abs(b)
    same = a == b
    err = np.where(same, 0.0, err)
    return np.where(np.isinf(b) & ~same, np.inf, err)


def _default_horizon(sys):
    p = np.abs(np.asarray(sys.poles()))
    p = p[(p > 0) & (p < 1)]
    if p.size == 0:
        return 100
    tau = -1.0 / np.log(p.max())
    return int(np.clip(math.ceil(8 * tau), 50, 5000))


def _channels(shape):
    ny, nu = shape
    for i in range(ny):
        for j in range(nu):
            yield (i, j), ("" if ny * nu == 1 else f" (u{j} to y{i})")


def _fmt_complex(p):
    p = complex(p)
    if abs(p.imag) < 1e-12:
        return f"{p.real:.6g}"
    return f"{p.real:.6g}{p.imag:+.6g}j"
