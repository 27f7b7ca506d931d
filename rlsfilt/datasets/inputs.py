"""Excitation signals for identification experiments.

Each generator returns a 1-D float array of ``n_samples`` values and takes an
``rng`` argument (a seed, a ``numpy.random.Generator`` or None); the default
seed ``0`` makes the default signal the same on every call.
"""

import math

import numpy as np

from .._validation import (
    as_float_array,
    as_generator,
    check_finite,
    check_int,
    check_length,
    check_real,
)

__all__ = ["prbs", "white_noise", "multisine", "steps"]


def prbs(n_samples=1000, *, amplitude=1.0, hold=1, nbits=None, offset=0.0, rng=0):
    """Pseudo-random binary sequence (a maximum-length sequence, MATLAB ``idinput('prbs')``).

    Parameters
    ----------
    n_samples : int, default 1000
        Length of the signal.
    amplitude : float, default 1.0
        The signal switches between ``offset - amplitude`` and
        ``offset + amplitude``.
    hold : int, default 1
        Samples per bit (clock period): larger values put the power at lower
        frequencies (band about ``1 / hold`` of the Nyquist frequency).
    nbits : int, optional
        Shift-register length; the sequence repeats every ``2**nbits - 1``
        bits. By default the smallest length (at least 3) whose period
        covers the signal, so that it does not repeat.
    offset : float, default 0.0
        Mean level.
    rng : int, Generator or None, default 0
        Picks the (nonzero) initial register state.

    Returns
    -------
    u : ndarray, shape (n_samples,)

    Notes
    -----
    A maximum-length sequence of period ``M = 2**nbits - 1`` has a two-level
    periodic autocorrelation (``1`` at lag 0, ``-1/M`` elsewhere): it is
    persistently exciting of order ``M`` (Ljung 1999, sec. 13.3), so it
    identifies any ARX model with fewer than ``M`` input parameters.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.datasets import prbs
    >>> u = prbs(8, amplitude=2.0)
    >>> np.unique(u)
    array([-2.,  2.])
    """
    from scipy import signal  # lazy: keeps `import rlsfilt` light
    n_samples = check_length(n_samples, "n_samples")
    hold = check_int(hold, "hold", minimum=1)
    amplitude = check_real(amplitude, "amplitude")
    offset = check_real(offset, "offset")
    n_bits_needed = math.ceil(n_samples / hold)
    if nbits is None:
        nbits = max(3, math.ceil(math.log2(n_bits_needed + 1)))
        nbits = min(nbits, 32)
    else:
        nbits = check_int(nbits, "nbits", minimum=2)
        if nbits > 32:
            raise ValueError(f"`nbits` must be <= 32; got {nbits}")
    gen = as_generator(rng)
    state = gen.integers(0, 2, nbits)
    if not state.any():
        state[gen.integers(nbits)] = 1
    seq = signal.max_len_seq(nbits, state=state, length=n_bits_needed)[0]
    u = offset + amplitude * (2.0 * seq.astype(float) - 1.0)
    return np.repeat(u, hold)[:n_samples]


def white_noise(n_samples=1000, *, std=1.0, mean=0.0, rng=0):
    """Gaussian white noise of standard deviation `std`.

    Parameters
    ----------
    n_samples : int, default 1000
        Record length ``N``.
    std : float, default 1.0
        Standard deviation.
    mean : float, default 0.0
        Mean value.
    rng : int, Generator or None, default 0
        Seed or generator; the default ``0`` gives the same signal on every
        call, ``None`` fresh randomness.

    Returns
    -------
    u : ndarray, shape (n_samples,)

    Examples
    --------
    >>> from rlsfilt.datasets import white_noise
    >>> white_noise(5, std=2.0, rng=1).round(3)
    array([ 0.691,  1.643,  0.661, -2.606,  1.811])
    """
    n_samples = check_length(n_samples, "n_samples")
    std = check_real(std, "std", minimum=0)
    mean = check_real(mean, "mean")
    return mean + std * as_generator(rng).standard_normal(n_samples)


def multisine(n_samples=1000, *, n_components=None, band=(0.0, 1.0), rms=1.0,
              phases="schroeder", rng=0):
    r"""Sum of sinusoids on the DFT grid (a periodic multisine).

    Parameters
    ----------
    n_samples : int, default 1000
        Length (and period) of the signal.
    n_components : int, optional
        Number of sinusoids, spread evenly over the band; all available
        frequencies up to 50 by default.
    band : (float, float), default (0.0, 1.0)
        Frequency band as fractions of the Nyquist frequency, as in MATLAB's
        ``idinput``. DC and Nyquist are excluded.
    rms : float, default 1.0
        Root-mean-square value of the signal.
    phases : {"schroeder", "random"}, default "schroeder"
        Schroeder phases :math:`\phi_k = -\pi k (k-1) / K` give a low crest
        factor; ``"random"`` draws them uniformly from `rng`.
    rng : int, Generator or None, default 0
        Seed or generator; the default ``0`` gives the same signal on every
        call, ``None`` fresh randomness.

    Returns
    -------
    u : ndarray, shape (n_samples,)

    Notes
    -----
    Each component completes an integer number of periods in ``n_samples``
    samples, so the spectrum has no leakage. ``K`` components excite an ARX
    model with up to ``2 K`` input parameters.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.datasets import multisine
    >>> u = multisine(256, n_components=8, rms=2.0)
    >>> round(float(np.sqrt(np.mean(u ** 2))), 6)                # the requested RMS
    2.0
    >>> int(np.count_nonzero(np.abs(np.fft.rfft(u)) > 1e-9))     # eight spectral lines
    8
    """
    n_samples = check_length(n_samples, "n_samples", minimum=4)
    rms = check_real(rms, "rms", minimum=0)
    gen = as_generator(rng)
    try:
        lo, hi = (float(b) for b in band)
    except (TypeError, ValueError):
        raise ValueError(f"`band` must be a pair (low, high); got {band!r}") from None
    if not 0.0 <= lo < hi <= 1.0:
        raise ValueError(f"`band` must satisfy 0 <= low < high <= 1; got ({lo}, {hi})")
    kmax_all = (n_samples - 1) // 2  # highest bin strictly below Nyquist
    k_lo = max(1, math.ceil(lo * n_samples / 2))
    k_hi = min(kmax_all, math.floor(hi * n_samples / 2))
    available = np.arange(k_lo, k_hi + 1)
    if len(available) == 0:
        raise ValueError(f"`band` ({lo}, {hi}) holds no frequency of the {n_samples}-point "
                         "DFT grid; widen it or use more samples")
    if n_components is None:
        n_components = min(50, len(available))
    n_components = check_int(n_components, "n_components", minimum=1)
    if n_components > len(available):
        raise ValueError(f"`n_components` must be <= {len(available)} (frequencies in the band); "
                         f"got {n_components}")
    idx = np.unique(np.round(np.linspace(0, len(available) - 1, n_components)).astype(int))
    k = available[idx]
    K = len(k)
    if phases == "schroeder":
        ph = -np.pi * np.arange(1, K + 1) * np.arange(K) / K
    elif phases == "random":
        ph = gen.uniform(0, 2 * np.pi, K)
    else:
        raise ValueError(f"`phases` must be 'schroeder' or 'random'; got {phases!r}")
    t = np.arange(n_samples)
    u = np.cos(2 * np.pi * np.outer(t, k) / n_samples + ph).sum(axis=1)
    return u * (rms / np.sqrt(np.mean(u ** 2)))


def steps(n_samples=1000, *, hold=100, amplitude=1.0, levels=None, rng=0):
    """Piecewise-constant steps: a staircase held for `hold` samples per level.

    Parameters
    ----------
    n_samples : int, default 1000
        Record length ``N``.
    hold : int, default 100
        Samples per level.
    amplitude : float, default 1.0
        Random levels are uniform in ``[-amplitude, amplitude]``.
    levels : sequence of float, optional
        Explicit levels, repeated cyclically (for example ``[0, 1]`` for a
        square wave starting at 0); overrides the random levels.
    rng : int, Generator or None, default 0
        Seed or generator; the default ``0`` gives the same signal on every
        call, ``None`` fresh randomness.

    Returns
    -------
    u : ndarray, shape (n_samples,)

    Examples
    --------
    >>> from rlsfilt.datasets import steps
    >>> steps(6, hold=2, levels=[0, 1])
    array([0., 0., 1., 1., 0., 0.])
    """
    n_samples = check_length(n_samples, "n_samples")
    hold = check_int(hold, "hold", minimum=1)
    n_levels = math.ceil(n_samples / hold)
    gen = as_generator(rng)
    if levels is None:
        amplitude = check_real(amplitude, "amplitude", minimum=0)
        lv = gen.uniform(-amplitude, amplitude, n_levels)
    else:
        lv = check_finite(as_float_array(levels, "levels").ravel(), "levels")
        if lv.size == 0:
            raise ValueError("`levels` must hold at least one value; got an empty sequence")
        lv = np.resize(lv, n_levels)
    return np.repeat(lv, hold)[:n_samples]
