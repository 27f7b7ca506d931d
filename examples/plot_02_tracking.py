"""
Tracking a parameter jump
=========================

The ARX(2, 2, 1) plant of :func:`rlsfilt.datasets.time_varying` changes its
four parameters at t = 1000. Exponentially forgetting RLS (``lam = 0.98``, a
memory of about :math:`1/(1-\\lambda) = 50` samples) follows the jump.

:func:`rlsfilt.plotting.plot_tracking` draws the estimates with their
:math:`\\pm 2\\sigma` bands over :math:`\\mathrm{tr}\\,P`. The bands have the
right width only when ``P`` is a covariance in the units of the parameters,
that is when ``R`` is the noise variance: here the noise standard deviation
is 0.05, so ``R = 0.05**2``.
"""

import matplotlib.pyplot as plt

from rlsfilt import ARX, RecursiveLeastSquares
from rlsfilt.datasets import time_varying
from rlsfilt.plotting import plot_tracking

ds = time_varying(rng=0)
Phi, z = ARX(*ds.orders).regressors(ds.u, ds.y)       # rows phi(t) for t = 2 .. N-1
lag = 2

rls = RecursiveLeastSquares(dim_x=4, lam=0.98, R=ds.noise_std ** 2)
rls.initialize(z[:8], Phi[:8])                        # batch start on the first 8 rows
means, covs, _, _ = rls.batch_filter(z[8:], Phi[8:])

fig = plot_tracking((means, covs), t=ds.t[lag + 8:], names=["a1", "a2", "b1", "b2"],
                    true_values=ds.theta_true[lag + 8:], xlabel="sample $t$")
fig.suptitle("RLS with forgetting, lam = 0.98, R = noise variance")

# %%
# An ``ARX`` model fitted with ``method="rls"`` keeps the estimate after every
# sample (``theta_history_``) but no covariance history; ``plot_tracking`` then
# shows the filter's a-priori errors below the estimates. They jump when the
# plant changes and settle as the estimate catches up.

model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y, method="rls", lam=0.98)
fig = plot_tracking(model, t=ds.t[model.max_lag:], true_values=ds.theta_true[model.max_lag:],
                    xlabel="time (s)")
plt.show()
