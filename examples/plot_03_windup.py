"""
Covariance windup and the anti-windup schemes
=============================================

The input is held constant from t = 500 to 2500: only one direction of the
regressor stays excited. Exponential forgetting keeps dividing ``P`` by
``lam`` in the directions that are no longer excited, so
:math:`\\mathrm{tr}\\,P` grows by many orders of magnitude (windup); when the
input becomes rich again the huge gain throws the estimate about. The
anti-windup schemes of ``RecursiveLeastSquares(forgetting=...)`` keep ``P``
bounded. :func:`rlsfilt.plotting.plot_trace` with ``label=`` draws the runs in
one axes, each in the next colour of the colour-blind-safe palette.
"""

import warnings

import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import ARX, RecursiveLeastSquares
from rlsfilt.datasets import prbs
from rlsfilt.plotting import plot_parameters, plot_trace

rng = np.random.default_rng(2)
N1, N2, N3 = 500, 2000, 700
u = np.r_[prbs(N1, rng=1), np.ones(N2), prbs(N3, rng=2)]
before, after = np.array([-1.5, 0.7, 1.0, 0.5]), np.array([-1.2, 0.5, 0.6, 0.9])
y = np.zeros(N1 + N2 + N3)
for t in range(2, len(y)):
    a1, a2, b1, b2 = before if t < N1 + N2 else after
    y[t] = -a1 * y[t - 1] - a2 * y[t - 2] + b1 * u[t - 1] + b2 * u[t - 2] \
        + 0.05 * rng.standard_normal()
Phi, z = ARX(2, 2, 1).regressors(u, y)
t_axis = np.arange(2 + 8, len(y))

runs = {}
for mode in ("exponential", "directional", "constant_trace", "efra"):
    rls = RecursiveLeastSquares(4, lam=0.98, R=0.05 ** 2, forgetting=mode)
    rls.initialize(z[:8], Phi[:8])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")          # exponential forgetting warns about P
        runs[mode] = rls.batch_filter(z[8:], Phi[8:])

fig, (ax_theta, ax_trace) = plt.subplots(2, 1, figsize=(9, 6.5), sharex=True,
                                         layout="constrained")
for mode, (means, covs, _, _) in runs.items():
    plot_trace((means, covs), t=t_axis, label=mode, ax=ax_trace, xlabel="sample $t$")
    ax_theta.plot(t_axis, means[:, 2, 0], lw=1, label=mode,
                  color=ax_trace.get_lines()[-1].get_color())
ax_theta.plot(t_axis, np.where(t_axis < N1 + N2, before[2], after[2]), "k--", lw=1,
              label="true")
ax_theta.set(ylim=(-1, 3), ylabel="$b_1$ estimate", title="held input from t = 500 to 2500")
ax_theta.legend(loc="upper left", bbox_to_anchor=(1.01, 1), frameon=False, fontsize="small")
for ax in (ax_theta, ax_trace):
    ax.axvspan(N1, N1 + N2, color="0.92", zorder=0)

# %%
# EFRA (Salgado, Goodwin & Middleton 1988) with its :math:`\pm 2\sigma` bands:
# bounded ``P``, no overshoot after the hold.
means, covs, _, _ = runs["efra"]
ax = plot_parameters((means, covs), t=t_axis, names=["a1", "a2", "b1", "b2"],
                     true_values=np.where((t_axis < N1 + N2)[:, None], before, after),
                     xlabel="sample $t$")
ax.figure.set_size_inches(9, 4)
plt.show()
