"""
Model against the true plant: Bode and step
===========================================

With simulated data the identified model can be compared with the system
that made the data. :class:`rlsfilt.validation.PlantComparison` computes the
frequency-response, DC-gain and step-response errors through python-control;
:func:`rlsfilt.plotting.plot_plant_comparison` draws the model dashed over
the plant (black). The non-minimum-phase plant's step response first moves
the wrong way, and the model keeps that.
"""

import matplotlib.pyplot as plt

from rlsfilt import ARX
from rlsfilt.datasets import nonminimum_phase
from rlsfilt.plotting import plot_plant_comparison, plot_step
from rlsfilt.validation import PlantComparison, frequency_response_band

d = nonminimum_phase()
model = ARX(*d.orders, dt=d.dt).fit(d.u, d.y)
comparison = PlantComparison(model, d.plant)
print(comparison.summary())
band = frequency_response_band(model, omega=comparison.omega, rng=0)
fig = plot_plant_comparison(comparison, band=band)

# %%
# A model of too low an order, ARX(1, 1, 1), misses the undershoot.
coarse = PlantComparison(ARX(1, 1, 1, dt=d.dt).fit(d.u, d.y), d.plant)
ax = plot_step(coarse)
ax.figure.set_size_inches(7, 3.5)
plt.show()
