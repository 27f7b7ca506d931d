r"""Simulated plants with known truth: the project's embedded example data.

Every generator can be called with no arguments and returns a `Dataset`: the
record (``u``, ``y``), the sampling period, the true discrete plant as a
``control.TransferFunction`` (continuous models are sampled with a zero-order
hold), the true ARX orders and coefficients, and the noise that was added.
The default seed ``0`` makes the default record the same on every call; pass
``rng=None`` for fresh randomness or any seed for another realization.

Noise models (``e`` white Gaussian of standard deviation ``noise_std``):

* ``"white"``: equation error, :math:`A(q) y = B(q) u + e` (the ARX
  assumption: least squares is consistent and its covariance is right);
* ``"colored"``: :math:`A(q) y = B(q) u + e / (1 - 0.9 q^{-1})`
  (correlated equation error: ARX least squares is biased);
* ``"output"``: :math:`y = B(q)/A(q)\, u + e`, white measurement noise (an
  output-error plant; ARX least squares is biased, most at low
  signal-to-noise).
"""

import numpy as np

from .._resources import check_memory
from .._validation import as_float_array, as_generator, check_finite, check_int, check_real
from .dataset import Dataset
from .inputs import multisine, prbs, steps, white_noise

__all__ = [
    "PLANTS",
    "thermal_process",
    "dc_motor",
    "mass_spring_damper",
    "nonminimum_phase",
    "time_varying",
]

_NOISE_KINDS = ("white", "colored", "output")
_COLORED_POLE = 0.9


# ----------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------
def _make_input(spec, n_samples, rng, defaults):
    """An input signal from a name (with per-plant defaults) or an array."""
    if isinstance(spec, str):
        makers = {"prbs": prbs, "white": white_noise, "multisine": multisine, "steps": steps}
        if spec not in makers:
            raise ValueError(f"`input` must be one of {sorted(makers)} or an array; got {spec!r}")
        kwargs = dict(defaults.get(spec, {}))
        n = check_int(n_samples, "n_samples", minimum=1)
        # the input, noise, clean and noisy output and the filters' temporaries
        check_memory(8 * 12 * n, f"a dataset of `n_samples` = {n}")
        return makers[spec](n_samples, rng=rng, **kwargs)
    u = as_float_array(spec, "input")
    if u.ndim != 1:
        raise ValueError(f"`input` must be 1-D (one input signal); got shape {u.shape}")
    if len(u) != n_samples:
        raise ValueError(f"`input` must have n_samples = {n_samples} samples; got {len(u)}")
    return check_finite(u.copy(), "input")


def _check_noise(noise, noise_std):
    if noise not in _NOISE_KINDS:
        raise ValueError(f"`noise` must be one of {list(_NOISE_KINDS)}; got {noise!r}")
    return check_real(noise_std, "noise_std", minimum=0)


def _add_noise(y_clean, A, noise, noise_std, gen):
    from scipy import signal  # lazy: keeps `import rlsfilt` light
    e = noise_std * gen.standard_normal(len(y_clean))
    if noise == "white":
        return y_clean + signal.lfilter([1.0], A, e)
    if noise == "colored":
        v = signal.lfilter([1.0], [1.0, -_COLORED_POLE], e)
        return y_clean + signal.lfilter([1.0], A, v)
    return y_clean + e


def _dataset_from_plant(name, description, plant, dt, n_samples, input, input_defaults, noise,
                        noise_std, rng):
    """Simulate a SISO discrete plant given as a TransferFunction.

    The excitation is `input` (a signal name, made with the plant's
    `input_defaults`, or the record itself), then the noise, both drawn from
    `rng` in that order.
    """
    from scipy import signal  # lazy: keeps `import rlsfilt` light

    from ..models import ARX

    gen = as_generator(rng)
    u = _make_input(input, n_samples, gen, input_defaults)
    truth = ARX.from_tf(plant)
    a, b, nk = truth.a_, truth.b_, truth.structure_.nk[0]
    A = np.concatenate([[1.0], a])
    B = np.concatenate([np.zeros(nk), b])
    y_clean = signal.lfilter(B, A, u)
    y = _add_noise(y_clean, A, noise, noise_std, gen)
    return Dataset(name=name, description=description, u=u, y=y, dt=float(dt), plant=plant,
                   na=len(a), nb=len(b), nk=int(nk), a=a.copy(), b=b.copy(),
                   noise_std=noise_std, noise=noise, y_clean=y_clean)


def _zoh(num, den, dt):
    import control

    return control.sample_system(control.tf(num, den), dt, method="zoh")


# ----------------------------------------------------------------------
# the plants
# ----------------------------------------------------------------------
def thermal_process(n_samples=1000, *, gain=2.0, time_constant=20.0, delay=3, dt=1.0,
                    input="prbs", noise="white", noise_std=0.05, rng=0):
    r"""First-order thermal process with dead time (heater power to temperature).

    .. math:: G(s) = \frac{K}{\tau s + 1} e^{-s\,d\,\Delta t}

    sampled with a zero-order hold: ``y(t) + a1 y(t-1) = b1 u(t-1-delay)``
    with ``a1 = -exp(-dt/tau)``, ``b1 = K (1 - exp(-dt/tau))``, so the true
    structure is ``ARX(na=1, nb=1, nk=1 + delay)``.

    Parameters
    ----------
    n_samples : int, default 1000
        Record length ``N``.
    gain : float, default 2.0
        Static gain ``K`` (kelvin per unit of heater power).
    time_constant : float, default 20.0
        ``tau`` in seconds.
    delay : int, default 3
        Dead time in whole samples (on top of the hold's one-sample delay).
    dt : float, default 1.0
        Sampling period in seconds.
    input : {"prbs", "white", "multisine", "steps"} or array_like, default "prbs"
        Excitation (PRBS held 5 samples per bit by default), or the input
        record itself.
    noise : {"white", "colored", "output"}, default "white"
        Noise model (see the module notes): white equation error (the ARX assumption),
        colored equation error, or white output noise.
    noise_std : float, default 0.05
        Standard deviation of the white noise ``e``.
    rng : int, Generator or None, default 0
        Seed or generator for the input and the noise; the default ``0`` gives the same
        record on every call, ``None`` fresh randomness.

    Returns
    -------
    Dataset
        The record, the true plant and its ARX orders and coefficients.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt import ARX
    >>> from rlsfilt.datasets import thermal_process
    >>> ds = thermal_process()
    >>> ds.orders                                     # 3 samples of dead time + the hold
    (1, 1, 4)
    >>> model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y)
    >>> np.round(ds.theta, 4), np.round(model.theta_, 4)
    (array([-0.9512,  0.0975]), array([-0.9485,  0.0991]))
    """
    n_samples = check_int(n_samples, "n_samples", minimum=1)
    gain = check_real(gain, "gain")
    if gain == 0.0:
        raise ValueError("`gain` must be a finite nonzero number; got 0.0")
    tau = check_real(time_constant, "time_constant", minimum=0, strict=True)
    delay = check_int(delay, "delay", minimum=0)
    dt = check_real(dt, "dt", minimum=0, strict=True)
    noise_std = _check_noise(noise, noise_std)
    import control

    plant = _zoh([gain], [tau, 1.0], dt)
    if delay:
        plant = plant * control.tf([1.0], [1.0] + [0.0] * delay, dt)
    desc = (f"thermal process K={gain:g}/({tau:g} s + 1) with {delay}-sample dead time, "
            f"ZOH at dt={dt:g} s; true ARX(1, 1, {1 + delay})")
    return _dataset_from_plant("thermal_process", desc, plant, dt, n_samples, input,
                               {"prbs": {"hold": 5}, "steps": {"hold": 100}}, noise, noise_std,
                               rng)


def dc_motor(n_samples=2000, *, inertia=0.01, friction=0.1, motor_constant=0.01,
             resistance=1.0, inductance=0.5, dt=0.05, amplitude=12.0, input="prbs",
             noise="white", noise_std=0.002, rng=0):
    r"""Armature-controlled DC motor, voltage to angular speed.

    .. math:: G(s) = \frac{K}{(J s + b)(L s + R) + K^2}

    with the classic parameters of the University of Michigan *Control
    Tutorials* (poles near -2 and -10 rad/s), sampled with a zero-order
    hold: true structure ``ARX(na=2, nb=2, nk=1)``.

    Parameters
    ----------
    n_samples : int, default 2000
        Record length ``N``.
    inertia, friction, motor_constant, resistance, inductance : float
        ``J`` (kg m^2), ``b`` (N m s), ``K`` (V s or N m/A), ``R`` (ohm),
        ``L`` (H).
    dt : float, default 0.05
        Sampling period in seconds.
    amplitude : float, default 12.0
        Input amplitude in volts.
    input : str or array_like, default "prbs"
        PRBS held 2 samples per bit by default.
    noise : {"white", "colored", "output"}, default "white"
        Noise model (see the module notes): white equation error (the ARX assumption),
        colored equation error, or white output noise.
    noise_std : float, default 0.002
        In rad/s.
    rng : int, Generator or None, default 0
        Seed or generator for the input and the noise; the default ``0`` gives the same
        record on every call, ``None`` fresh randomness.

    Returns
    -------
    Dataset
        The record, the true plant and its ARX orders and coefficients.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.datasets import dc_motor
    >>> ds = dc_motor()
    >>> ds.orders, np.round(np.sort(np.abs(ds.plant.poles())), 4)
    ((2, 2, 1), array([0.6066, 0.9047]))
    """
    n_samples = check_int(n_samples, "n_samples", minimum=1)
    J = check_real(inertia, "inertia", minimum=0, strict=True)
    b = check_real(friction, "friction", minimum=0, strict=True)
    K = check_real(motor_constant, "motor_constant", minimum=0, strict=True)
    R = check_real(resistance, "resistance", minimum=0, strict=True)
    L = check_real(inductance, "inductance", minimum=0, strict=True)
    dt = check_real(dt, "dt", minimum=0, strict=True)
    amplitude = check_real(amplitude, "amplitude", minimum=0, strict=True)
    noise_std = _check_noise(noise, noise_std)
    plant = _zoh([K], [J * L, J * R + b * L, b * R + K * K], dt)
    desc = (f"DC motor voltage -> speed, K/((J s + b)(L s + R) + K^2), ZOH at dt={dt:g} s; "
            "true ARX(2, 2, 1)")
    return _dataset_from_plant("dc_motor", desc, plant, dt, n_samples, input, {
        "prbs": {"hold": 2, "amplitude": amplitude}, "white": {"std": amplitude},
        "multisine": {"rms": amplitude}, "steps": {"amplitude": amplitude, "hold": 40}},
        noise, noise_std, rng)


def mass_spring_damper(n_samples=2000, *, mass=1.0, stiffness=4.0, damping=0.1, dt=0.1,
                       input="multisine", noise="white", noise_std=0.002, rng=0):
    r"""Lightly damped mass-spring-damper, force to position.

    .. math:: G(s) = \frac{1}{m s^2 + c s + k}

    By default :math:`\omega_n = 2` rad/s and damping ratio
    :math:`\zeta = c / (2\sqrt{k m}) = 0.025` (a resonance peak of 20 times
    the static gain), sampled with a zero-order hold: true structure
    ``ARX(na=2, nb=2, nk=1)``.

    Parameters
    ----------
    n_samples : int, default 2000
        Record length ``N``.
    mass, stiffness, damping : float
        ``m`` (kg), ``k`` (N/m), ``c`` (N s/m).
    dt : float, default 0.1
        Sampling period in seconds.
    input : str or array_like, default "multisine"
        A Schroeder-phased multisine (50 components, full band) by default.
    noise : {"white", "colored", "output"}, default "white"
        Noise model (see the module notes): white equation error (the ARX assumption),
        colored equation error, or white output noise.
    noise_std : float, default 0.002
        In metres.
    rng : int, Generator or None, default 0
        Seed or generator for the input and the noise; the default ``0`` gives the same
        record on every call, ``None`` fresh randomness.

    Returns
    -------
    Dataset
        The record, the true plant and its ARX orders and coefficients.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.datasets import mass_spring_damper
    >>> ds = mass_spring_damper()
    >>> np.round(np.abs(ds.plant.poles()), 4)        # close to the unit circle
    array([0.995, 0.995])
    """
    n_samples = check_int(n_samples, "n_samples", minimum=1)
    m = check_real(mass, "mass", minimum=0, strict=True)
    k = check_real(stiffness, "stiffness", minimum=0, strict=True)
    c = check_real(damping, "damping", minimum=0)
    dt = check_real(dt, "dt", minimum=0, strict=True)
    noise_std = _check_noise(noise, noise_std)
    plant = _zoh([1.0], [m, c, k], dt)
    zeta = c / (2 * np.sqrt(k * m))
    desc = (f"mass-spring-damper force -> position, wn={np.sqrt(k / m):.3g} rad/s, "
            f"zeta={zeta:.3g}, ZOH at dt={dt:g} s; true ARX(2, 2, 1)")
    return _dataset_from_plant("mass_spring_damper", desc, plant, dt, n_samples, input,
                               {"steps": {"hold": 50}}, noise, noise_std, rng)


def nonminimum_phase(n_samples=1000, *, zero=0.5, dt=0.2, input="white", noise="white",
                     noise_std=0.02, rng=0):
    r"""Non-minimum-phase process with a right-half-plane zero (inverse response).

    .. math:: G(s) = \frac{1 - s / z_0}{(s + 1)(0.5 s + 1)}

    sampled with a zero-order hold; the discrete zero lies outside the unit
    circle (near :math:`e^{z_0 \Delta t}`), so a step response first moves
    the wrong way. True structure ``ARX(na=2, nb=2, nk=1)``.

    Parameters
    ----------
    n_samples : int, default 1000
        Record length ``N``.
    zero : float, default 0.5
        Right-half-plane zero ``z0`` in rad/s (> 0).
    dt : float, default 0.2
        Sampling period in seconds.
    input : str or array_like, default "white"
        Excitation: a signal name (``"prbs"``, ``"white"``, ``"multisine"``, ``"steps"``) or
        the input record itself.
    noise : {"white", "colored", "output"}, default "white"
        Noise model (see the module notes): white equation error (the ARX assumption),
        colored equation error, or white output noise.
    noise_std : float, default 0.02
        Standard deviation of the white noise ``e``.
    rng : int, Generator or None, default 0
        Seed or generator for the input and the noise; the default ``0`` gives the same
        record on every call, ``None`` fresh randomness.

    Returns
    -------
    Dataset
        The record, the true plant and its ARX orders and coefficients.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.datasets import nonminimum_phase
    >>> ds = nonminimum_phase()
    >>> np.round(np.abs(ds.plant.zeros()), 4)        # outside the unit circle
    array([1.1066])
    """
    n_samples = check_int(n_samples, "n_samples", minimum=1)
    z0 = check_real(zero, "zero", minimum=0, strict=True)
    dt = check_real(dt, "dt", minimum=0, strict=True)
    noise_std = _check_noise(noise, noise_std)
    plant = _zoh([-1.0 / z0, 1.0], [0.5, 1.5, 1.0], dt)
    desc = (f"non-minimum-phase process (1 - s/{z0:g})/((s + 1)(0.5 s + 1)), ZOH at "
            f"dt={dt:g} s; true ARX(2, 2, 1)")
    return _dataset_from_plant("nonminimum_phase", desc, plant, dt, n_samples, input,
                               {"prbs": {"hold": 2}, "steps": {"hold": 50}}, noise, noise_std,
                               rng)


def time_varying(n_samples=2000, *, kind="jump", change_time=None, a_before=(-1.5, 0.7),
                 b_before=(1.0, 0.5), a_after=(-1.2, 0.5), b_after=(0.6, 0.9), dt=1.0,
                 input="prbs", noise_std=0.05, rng=0):
    r"""Second-order ARX plant whose parameters change during the record (for tracking).

    .. math:: y(t) + a_1(t) y(t-1) + a_2(t) y(t-2) = b_1(t) u(t-1) + b_2(t) u(t-2) + e(t)

    Parameters
    ----------
    n_samples : int, default 2000
        Record length ``N``.
    kind : {"jump", "drift"}, default "jump"
        ``"jump"``: the parameters switch from the "before" to the "after"
        values at `change_time`. ``"drift"``: they move linearly from one to
        the other over the whole record (every intermediate plant is stable
        when both ends are, because the stability region of
        ``(a1, a2)`` is convex).
    change_time : int, optional
        First sample of the new parameters; ``n_samples // 2`` by default.
    a_before, b_before, a_after, b_after : sequence of float
        ``[a1, a2]`` and ``[b1, b2]`` at the start and the end (the default
        moves the poles from 0.75 +- 0.37j to 0.6 +- 0.37j and changes the
        static gain from 7.5 to 5).
    dt : float, default 1.0
        Sampling period in seconds.
    input : str or array_like, default "prbs"
        Excitation: a signal name (``"prbs"``, ``"white"``, ``"multisine"``, ``"steps"``) or
        the input record itself.
    noise_std : float, default 0.05
        Standard deviation of the white equation error.
    rng : int, Generator or None, default 0
        Seed or generator for the input and the noise; the default ``0`` gives the same
        record on every call, ``None`` fresh randomness.

    Returns
    -------
    Dataset
        The record, the true plant and its ARX orders and coefficients.
        With ``theta_true`` (N, 4), the true ``[a1, a2, b1, b2]`` at each
        sample, ``change_time`` (``kind="jump"``) and ``plant_after``;
        ``a``, ``b`` and ``plant`` are the initial values.

    Examples
    --------
    >>> from rlsfilt.datasets import time_varying
    >>> ds = time_varying()
    >>> ds.change_time, ds.theta_true[0].tolist(), ds.theta_true[-1].tolist()
    (1000, [-1.5, 0.7, 1.0, 0.5], [-1.2, 0.5, 0.6, 0.9])
    """
    import control

    n_samples = check_int(n_samples, "n_samples", minimum=2)
    if kind not in ("jump", "drift"):
        raise ValueError(f"`kind` must be 'jump' or 'drift'; got {kind!r}")
    dt = check_real(dt, "dt", minimum=0, strict=True)
    noise_std = _check_noise("white", noise_std)
    vecs = {}
    for name, val in (("a_before", a_before), ("b_before", b_before), ("a_after", a_after),
                      ("b_after", b_after)):
        arr = as_float_array(val, name).ravel()
        if arr.shape != (2,):
            raise ValueError(f"`{name}` must have 2 entries; got {arr.size}")
        vecs[name] = check_finite(arr, name)
    for when in ("before", "after"):
        poles = np.roots(np.concatenate([[1.0], vecs[f"a_{when}"]]))
        if np.max(np.abs(poles)) >= 1:
            raise ValueError(f"`a_{when}` must give a stable plant (poles inside the unit "
                             f"circle); got poles {np.round(poles, 4).tolist()}")
    th0 = np.concatenate([vecs["a_before"], vecs["b_before"]])
    th1 = np.concatenate([vecs["a_after"], vecs["b_after"]])
    if kind == "jump":
        change_time = n_samples // 2 if change_time is None else check_int(
            change_time, "change_time", minimum=0)
        if change_time > n_samples:
            raise ValueError(f"`change_time` must be <= n_samples = {n_samples}; "
                             f"got {change_time}")
        theta_true = np.where((np.arange(n_samples) >= change_time)[:, None], th1, th0)
    else:
        if change_time is not None:
            raise ValueError("`change_time` only applies to kind='jump'; got kind='drift'")
        w = np.linspace(0.0, 1.0, n_samples)[:, None]
        theta_true = (1 - w) * th0 + w * th1
    gen = as_generator(rng)
    u = _make_input(input, n_samples, gen, {"steps": {"hold": 50}})
    e = noise_std * gen.standard_normal(n_samples)
    y = np.zeros(n_samples)
    y_clean = np.zeros(n_samples)
    up = np.concatenate([[0.0, 0.0], u])
    for t in range(n_samples):
        a1, a2, b1, b2 = theta_true[t]
        ym1 = y[t - 1] if t >= 1 else 0.0
        ym2 = y[t - 2] if t >= 2 else 0.0
        cm1 = y_clean[t - 1] if t >= 1 else 0.0
        cm2 = y_clean[t - 2] if t >= 2 else 0.0
        forced = b1 * up[t + 1] + b2 * up[t]        # u(t-1), u(t-2)
        y[t] = -a1 * ym1 - a2 * ym2 + forced + e[t]
        y_clean[t] = -a1 * cm1 - a2 * cm2 + forced
    plant = control.tf([0.0, *th0[2:]], [1.0, *th0[:2]], dt)
    plant_after = control.tf([0.0, *th1[2:]], [1.0, *th1[:2]], dt)
    when = f"at sample {change_time}" if kind == "jump" else "linearly over the record"
    desc = (f"second-order ARX(2, 2, 1) plant whose parameters change {when} "
            f"from {np.round(th0, 3).tolist()} to {np.round(th1, 3).tolist()}")
    return Dataset(name="time_varying", description=desc, u=u, y=y, dt=dt, plant=plant,
                   na=2, nb=2, nk=1, a=th0[:2].copy(), b=th0[2:].copy(), noise_std=noise_std,
                   noise="white", y_clean=y_clean, theta_true=theta_true,
                   change_time=change_time if kind == "jump" else None,
                   plant_after=plant_after)


PLANTS = {
    "thermal_process": thermal_process,
    "dc_motor": dc_motor,
    "mass_spring_damper": mass_spring_damper,
    "nonminimum_phase": nonminimum_phase,
    "time_varying": time_varying,
}
"""Name -> generator of every simulated plant (for ``rlsfilt demo --plant NAME``)."""
