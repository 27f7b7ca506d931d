"""
Tuned, filtered and smoothed: ``smooth().plot()``
=================================================

A bias that drifts as a random walk and a gain that jumps at sample 800. The
random walk ``Q = q R`` and the noise variance ``R`` are estimated by maximum
likelihood on the first 700 samples (``RecursiveLeastSquares.tune``), the
tuned filter runs over the record, and the Rauch-Tung-Striebel smoother uses
the data after each sample too (``RecursiveLeastSquares.smooth``).
:func:`rlsfilt.plotting.plot_smoothed` draws the smoothed trajectories with
their 2-sigma bands over the filtered ones (dotted, fainter bands): the
smoothed bands are narrower, and the smoothed gain's transition is centred on
the jump instead of lagging behind it.
"""

import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import RecursiveLeastSquares

rng = np.random.default_rng(7)
N = 1500
H = np.column_stack([np.ones(N), rng.standard_normal(N)])       # a bias and an input
x_true = np.empty((N, 2))
x_true[:, 0] = 1.0 + np.cumsum(0.01 * rng.standard_normal(N))   # the bias drifts
x_true[:, 1] = np.where(np.arange(N) < 800, 0.5, 0.9)          # the gain jumps
z = np.sum(H * x_true, axis=1) + 0.1 * rng.standard_normal(N)

fit = RecursiveLeastSquares(2, P0=100.0).tune(z[:700], H[:700], "q")
print(fit.summary())
rls = fit.apply(RecursiveLeastSquares(2, P0=100.0))
smoothed = rls.smooth(z, H)

ax = smoothed.plot(names=["bias", "gain"], true_values=x_true)
ax.set_xlim(600, 1000)
plt.show()
