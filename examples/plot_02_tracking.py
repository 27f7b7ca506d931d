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
is 0.05, so ``R = 0.05**2``. At the scale of all four parameters the bands
(about :math:`\\pm 0.015`) hide under the lines, and the title says so; the
inset zooms on ``b1`` after the jump, where the estimate converges to the new
value inside its band.
"""

import matplotlib.pyplot as plt
import numpy as np

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

# a zoom on b1 after the jump: the +-2 sigma band at a scale where it shows
t_f, b1, sd = ds.t[lag + 8:], means[:, 2, 0], np.sqrt(covs[:, 2, 2])
near = (t_f >= 1100) & (t_f <= 1400)
inset = fig.axes[0].inset_axes([0.42, 0.25, 0.4, 0.4])
inset.fill_between(t_f[near], (b1 - 2 * sd)[near], (b1 + 2 * sd)[near], color="C2", alpha=0.3,
                   linewidth=0, label=r"$\pm 2\sigma$")
inset.plot(t_f[near], b1[near], color="C2", lw=1.0, label="b1")
inset.plot(t_f[near], ds.theta_true[lag + 8:, 2][near], "k--", lw=0.8, label="true")
inset.set_title("zoom: b1 after the jump", fontsize=8)
inset.tick_params(labelsize=7)
inset.legend(fontsize=7, loc="upper right")
plt.show()

# %%
# An ``ARX`` model fitted with ``method="rls"`` keeps the estimate after every
# sample (``theta_history_``) but no covariance history; ``plot_tracking`` then
# shows the filter's a-priori errors below the estimates. They jump when the
# plant changes and settle as the estimate catches up.

model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y, method="rls", lam=0.98)
fig = plot_tracking(model, t=ds.t[model.max_lag:], true_values=ds.theta_true[model.max_lag:],
                    xlabel="time (s)")
plt.show()
