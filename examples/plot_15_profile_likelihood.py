"""
How sure is the tuned forgetting factor? ``TuneResult.plot_profile()``
======================================================================

Two coefficients drift as random walks; ``RecursiveLeastSquares.tune`` finds
the forgetting factor and, on a second panel, the random walk ``Q = q R`` by
maximum likelihood. :func:`rlsfilt.plotting.plot_profile_likelihood` draws the
profile log-likelihood (``R`` concentrated out) around each estimate: the 95 %
likelihood-ratio interval is where the curve stays within 1.92 of its
maximum. The Wald interval from the observed information (green) agrees where
the curve is close to a parabola, as for ``q`` on its log scale.
"""

import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import RecursiveLeastSquares

rng = np.random.default_rng(3)
N = 1500
H = rng.standard_normal((N, 2))
x_true = np.array([1.0, -0.5]) + np.cumsum(0.01 * rng.standard_normal((N, 2)), axis=0)
z = np.sum(H * x_true, axis=1) + 0.1 * rng.standard_normal(N)

rls = RecursiveLeastSquares(2, P0=100.0)
fit_lam = rls.tune(z, H, "lam")
fit_q = rls.tune(z, H, "q")
print(fit_lam.summary())
print(fit_q.summary())

fig, (ax_lam, ax_q) = plt.subplots(1, 2, figsize=(10, 4.5), layout="constrained")
fit_lam.plot_profile(ax_lam)
fit_q.plot_profile(ax_q)
plt.show()
