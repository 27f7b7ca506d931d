"""
Bode diagram with parameter uncertainty
=======================================

:func:`rlsfilt.validation.frequency_response_band` draws parameter vectors
from the estimate's asymptotic distribution and returns the pointwise 95 %
band of the frequency response; :func:`rlsfilt.plotting.plot_frequency_band`
draws it with the true plant on top. A short record gives a wide band, a long
one a narrow band around the plant.
"""

import matplotlib.pyplot as plt

from rlsfilt import ARX
from rlsfilt.datasets import nonminimum_phase
from rlsfilt.plotting import plot_bode, plot_frequency_band
from rlsfilt.validation import frequency_response_band

short = nonminimum_phase(n_samples=150, noise_std=0.1, rng=0)
model = ARX(*short.orders, dt=short.dt).fit(short.u, short.y)
band = frequency_response_band(model, rng=0)
fig = plot_frequency_band(band, plant=short.plant)
fig.suptitle("150 samples, noise std 0.1")
plt.show()

# %%
# Ten times more data: the band narrows by about :math:`\sqrt{10}`.
long = nonminimum_phase(n_samples=1500, noise_std=0.1, rng=0)
band_long = frequency_response_band(ARX(*long.orders, dt=long.dt).fit(long.u, long.y), rng=0)
fig, (ax_mag, ax_phase) = plt.subplots(2, 1, figsize=(8, 6), sharex=True, layout="constrained")
plot_bode(band_long, ax_mag, ax_phase, plant=long.plant)
fig.suptitle("1500 samples, noise std 0.1")
plt.show()
