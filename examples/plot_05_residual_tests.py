"""
Residual tests: what a model that is too simple looks like
==========================================================

The residuals of a good model are white and uncorrelated with past inputs.
A first-order model of the lightly damped mass-spring-damper (force in,
position out) misses an oscillation: its residual autocorrelation leaves the
99 % band at many lags and is correlated with the input.
:func:`rlsfilt.plotting.plot_residuals` draws both tests
(MATLAB's ``resid``); the verdict is in the titles in words.
"""

import matplotlib.pyplot as plt

from rlsfilt import ARX
from rlsfilt.datasets import mass_spring_damper
from rlsfilt.plotting import plot_autocorrelation, plot_cross_correlation, plot_residuals
from rlsfilt.validation import residual_analysis

d = mass_spring_damper()
too_simple = residual_analysis(ARX(1, 1, 1, dt=d.dt).fit(d.u, d.y), d.u, d.y)
fig = plot_residuals(too_simple)
fig.suptitle("ARX(1, 1, 1): too simple")
plt.show()

# %%
# The true structure ARX(2, 2, 1) passes both tests.
right = residual_analysis(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), d.u, d.y)
fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
plot_autocorrelation(right, ax1)
plot_cross_correlation(right, ax2)
fig.suptitle("ARX(2, 2, 1): the true structure")
plt.show()
