"""
A long record: a readable window and an overview
================================================

Drawn in full, 100,000 samples of model output against data are a solid
block. :func:`rlsfilt.plotting.plot_comparison` shows a window (by default
the last 400 samples, or ``window=(start, stop)``) above an overview of the
whole record. The overview draws the measured output and the simulation
error through their per-bin minima and maxima, so a single outlier stays
visible and no line carries more than ``rlsfilt.plotting.MAX_POINTS`` points.
"""

import matplotlib.pyplot as plt

from rlsfilt import ARX, validate
from rlsfilt.datasets import thermal_process

d = thermal_process(n_samples=100_000)                # dt = 1 s: almost 28 hours
model = ARX(*d.orders, dt=d.dt).fit(d.u, d.y)
report = validate(model, d.u, d.y)

ax = report.plot_comparison(window=(50_000, 50_300))
ax.set_ylabel("temperature deviation (K)")
plt.show()
