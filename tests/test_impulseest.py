"""impulseest (MATLAB's impulseest): prewhitened FIR least squares with standard errors.

Oracles: the true impulse response of a generated plant (scipy's lfilter of a unit
impulse) lies inside the 99 % bands; without prewhitening the estimate is ordinary
least squares (numpy lstsq) with its textbook covariance."""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.signal import chirp, lfilter

from rlsfilt import IOData
from rlsfilt.validation import impulseest

B, A = [0] * 5 + [0.3, 0.6, 0.2], [1, -1.2, 0.5]


def _truth(n):
    return lfilter(B, A, np.r_[1.0, np.zeros(n - 1)])


def test_true_response_inside_its_bands_with_colored_noise():
    rng = np.random.default_rng(11)
    N, n = 4000, 40
    u = rng.standard_normal(N)
    v = lfilter([1], [1, -0.9], 0.1 * rng.standard_normal(N))      # colored noise
    y = lfilter(B, A, u) + v
    g = impulseest(u, y, n_coeffs=n)
    lo, hi = g.band(0.99)
    inside = (lo[:, 0] <= _truth(n)) & (_truth(n) <= hi[:, 0])
    assert inside.mean() >= 0.95           # about 1 % of 40 may fall outside by chance
    assert g.delay() == 5 and g.delay(familywise=True) == 5
    assert not g.significant()[:5, 0].any()
    assert g.noise_order == 10 and g.noise_ar[0] == 1.0
    assert g.noise_ar[1] == pytest.approx(-0.9, abs=0.05)   # the noise pole was found
    assert "first significant lag 5" in str(g.summary())


def test_without_prewhitening_it_is_least_squares():
    rng = np.random.default_rng(2)
    u, e = rng.standard_normal((600, 2)), 0.1 * rng.standard_normal(600)
    y = lfilter(B, A, u[:, 0]) - lfilter([0, 0.5], [1], u[:, 1]) + e
    n = 12
    g = impulseest(u, y, n_coeffs=n, noise_order=0)
    uc, yc = u - u.mean(axis=0), y - y.mean()
    t = np.arange(n - 1, 600)
    Phi = np.column_stack([uc[t - k, j] for j in range(2) for k in range(n)])
    theta, res, *_ = np.linalg.lstsq(Phi, yc[t], rcond=None)
    sigma2 = res[0] / (len(t) - 2 * n)
    se = np.sqrt(np.diag(sigma2 * np.linalg.inv(Phi.T @ Phi)))
    assert_allclose(g.coefficients, theta.reshape(2, n).T, rtol=1e-9, atol=1e-12)
    assert_allclose(g.stderr, se.reshape(2, n).T, rtol=1e-8)
    assert g.delay() == (5, 1)
    # an IOData of the same samples gives the same numbers
    h = impulseest(IOData(u, y), n_coeffs=n, noise_order=0)
    assert_allclose(h.coefficients, g.coefficients, rtol=1e-12)


def test_a_swept_sine_shows_the_delay():
    """A chirp (swept sine) input: the impulse estimate's first significant lag is the
    dead time."""
    N = 3000
    u = chirp(np.arange(N), f0=0.001, t1=N, f1=0.45, method="linear")
    rng = np.random.default_rng(5)
    y = lfilter(B, A, u) + 0.02 * rng.standard_normal(N)
    g = impulseest(u, y, n_coeffs=50)
    assert g.delay(familywise=True) == 5
    lo, hi = g.band(0.99)
    assert np.mean((lo[:, 0] <= _truth(50)) & (_truth(50) <= hi[:, 0])) >= 0.9


def test_plot_and_errors():
    import matplotlib.pyplot as plt

    rng = np.random.default_rng(3)
    u = rng.standard_normal((800, 2))
    y = lfilter(B, A, u[:, 0]) + lfilter([0, 0, 1.0], [1], u[:, 1]) \
        + 0.1 * rng.standard_normal(800)
    g = impulseest(IOData(u, y, dt=0.5, input_names=["heater", "fan"]), n_coeffs=15)
    fig = g.plot()
    assert len(fig.axes) == 2
    assert "heater to y" in fig.axes[0].get_title()
    assert "first significant lag 2" in fig.axes[1].get_title()
    assert "99% band per lag" in fig.axes[0].get_title()
    assert fig.axes[1].get_xlabel() == "lag (s)"
    plt.close(fig)
    with pytest.raises(ValueError, match="`level` must be in"):
        g.band(1.5)
    with pytest.raises(ValueError, match="too short for n_coeffs=500"):
        impulseest(u, y, n_coeffs=500)
    with pytest.raises(ValueError, match="`y` must hold one output"):
        impulseest(u, np.column_stack([y, y]))
