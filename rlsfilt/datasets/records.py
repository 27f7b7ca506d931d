r"""Measured-like records: operating points, dead time, colored disturbances, several runs.

The plants of :mod:`rlsfilt.datasets.plants` are ideal textbook
experiments (signals around zero, one run). The records here look like what
comes out of a plant historian, and need the whole workflow: remove the
operating point, estimate the delay, choose the orders, validate on a fresh
run. They are still simulated, so the truth is known.
"""

import numpy as np

from .._validation import as_generator, check_int, check_real
from .dataset import Dataset
from .inputs import prbs
from .plants import _add_noise, _check_noise, _zoh

__all__ = ["heat_exchanger"]


def heat_exchanger(n_samples=(1200, 800), *, delay=7, gain=-0.6, time_constants=(15.0, 4.0),
                   dt=1.0, u0=40.0, y0=97.0, amplitude=4.0, noise_std=0.002, rng=0):
    r"""Steam-heated exchanger: liquid flow (%) to outlet temperature (degC), two runs.

    The deviations from the operating point :math:`(u_0, y_0)` follow

    .. math::

        G(s) = \frac{K}{(\tau_1 s + 1)(\tau_2 s + 1)}\, e^{-s\,d\,\Delta t},

    sampled with a zero-order hold (true structure ``ARX(2, 2, 1 + delay)``
    for ``y - y0`` and ``u - u0``); more flow means a cooler outlet, so the
    gain is negative. A colored disturbance (the ``"colored"`` noise of
    :mod:`rlsfilt.datasets`: :math:`A(q)\, v = e / (1 - 0.9 q^{-1})`)
    drifts the temperature by about 0.2 degC. Each run is a PRBS of
    ``+-amplitude`` around ``u0`` held 6 samples per bit, starting from the
    steady state.

    Parameters
    ----------
    n_samples : int or sequence of int, default (1200, 800)
        Samples of each run (one entry per experiment).
    delay : int, default 7
        Dead time in whole samples (transport delay of the pipe), on top of
        the hold's one sample.
    gain : float, default -0.6
        Static gain ``K`` in degC per % of flow.
    time_constants : (float, float), default (15.0, 4.0)
        ``tau_1, tau_2`` in seconds.
    dt : float, default 1.0
        Sampling period in seconds.
    u0, y0 : float, default 40.0 and 97.0
        Operating point: flow in % and outlet temperature in degC.
    amplitude : float, default 4.0
        PRBS amplitude in % of flow.
    noise_std : float, default 0.002
        Standard deviation of the white noise ``e`` driving the disturbance.
    rng : int, Generator or None, default 0
        Seed or generator; the default gives the same record on every call.

    Returns
    -------
    Dataset
        An `IOData` with input ``flow`` [%] and output ``T_out`` [degC],
        experiments ``run1``, ``run2``, ..., the true deviation plant
        (``plant``, ``a``, ``b``, ``nk = 1 + delay``) and the operating point
        (``u0``, ``y0``).

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.datasets import heat_exchanger
    >>> ds = heat_exchanger()
    >>> ds.n_experiments, ds.lengths, ds.orders
    (2, (1200, 800), (2, 2, 8))
    >>> ds.input_names, ds.output_units, (ds.u0, ds.y0)
    (('flow',), ('degC',), (40.0, 97.0))
    >>> round(float(ds.getexp(0).y.mean()), 1)       # far from zero: remove the offset first
    96.9
    """
    import control

    if isinstance(n_samples, (list, tuple, np.ndarray)):
        lengths = [check_int(n, f"n_samples[{i}]", minimum=50) for i, n in enumerate(n_samples)]
        if not lengths:
            raise ValueError("`n_samples` must hold at least one run length; got none")
    else:
        lengths = [check_int(n_samples, "n_samples", minimum=50)]
    delay = check_int(delay, "delay", minimum=0)
    gain = check_real(gain, "gain")
    if gain == 0.0:
        raise ValueError("`gain` must be a finite nonzero number; got 0.0")
    try:
        tau1, tau2 = time_constants
    except (TypeError, ValueError):
        raise ValueError("`time_constants` must be a pair (tau_1, tau_2); got "
                         f"{time_constants!r}") from None
    tau1 = check_real(tau1, "time_constants[0]", minimum=0, strict=True)
    tau2 = check_real(tau2, "time_constants[1]", minimum=0, strict=True)
    dt = check_real(dt, "dt", minimum=0, strict=True)
    u0, y0 = check_real(u0, "u0"), check_real(y0, "y0")
    amplitude = check_real(amplitude, "amplitude", minimum=0, strict=True)
    noise_std = _check_noise("colored", noise_std)
    gen = as_generator(rng)
    from ..models import ARX

    plant = _zoh([gain], [tau1 * tau2, tau1 + tau2, 1.0], dt)
    if delay:
        plant = plant * control.tf([1.0], [1.0] + [0.0] * delay, dt)
    truth = ARX.from_tf(plant)
    a, b, nk = truth.a_, truth.b_, int(truth.structure_.nk[0])
    A = np.concatenate([[1.0], a])
    B = np.concatenate([np.zeros(nk), b])
    from scipy import signal  # lazy: keeps `import rlsfilt` light
    us, ys, cleans = [], [], []
    for n in lengths:
        du = prbs(n, amplitude=amplitude, hold=6, rng=gen)
        dy = signal.lfilter(B, A, du)
        us.append(u0 + du)
        cleans.append(y0 + dy)
        ys.append(y0 + _add_noise(dy, A, "colored", noise_std, gen))
    desc = (f"heat exchanger flow [%] -> outlet temperature [degC], K={gain:g}/(({tau1:g} s + 1)"
            f"({tau2:g} s + 1)) with {delay}-sample dead time, ZOH at dt={dt:g} s, "
            f"{len(lengths)} run(s) around ({u0:g} %, {y0:g} degC); true ARX(2, 2, {nk}) of "
            "the deviations")
    return Dataset(name="heat_exchanger", description=desc, u=us, y=ys, dt=float(dt),
                   plant=plant, na=len(a), nb=len(b), nk=nk, a=a.copy(), b=b.copy(),
                   noise_std=noise_std, noise="colored", y_clean=cleans, u0=u0, y0=y0,
                   input_names=["flow"], output_names=["T_out"], input_units=["%"],
                   output_units=["degC"],
                   experiment_names=[f"run{i + 1}" for i in range(len(lengths))])
