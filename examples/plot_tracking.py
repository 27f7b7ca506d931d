"""
Tracking a parameter jump
=========================

Exponentially forgetting RLS (``lam = 0.98``, a memory of about 50 samples)
follows the ARX(2, 2, 1) plant of :func:`rlsfilt.datasets.time_varying`, whose
parameters jump at t = 1000. :func:`rlsfilt.plotting.plot_tracking` draws the
estimates with their :math:`\\pm 2\\sigma` bands above :math:`\\mathrm{tr}\\,P`.
The bands are a covariance in the units of the parameters because ``R`` is the
noise variance (the data's noise standard deviation is 0.05).
"""

import matplotlib.pyplot as plt

from rlsfilt import ARX
from rlsfilt.datasets import time_varying
from rlsfilt.plotting import plot_tracking

ds = time_varying(rng=0)
model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y, method="rls", lam=0.98,
                                      R=ds.noise_std ** 2)
lag = model.max_lag
fig = plot_tracking(model, t=ds.t[lag:], true_values=ds.theta_true[lag:])
plt.show()
