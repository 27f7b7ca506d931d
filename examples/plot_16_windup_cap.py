"""
Lost excitation under exponential forgetting: the windup cap
============================================================

``RecursiveLeastSquares(3, lam=0.95)`` with the regressor
:math:`[1, u_k, u_{k-1}]` and an input that is rich for 400 samples and then
held for 19,600, three times over. While the input is held, the data excite
one direction of the parameter space only, and plain exponential forgetting
keeps dividing ``P`` by ``lam`` in the two others: :math:`\\mathrm{tr}\\,P`
grows like :math:`0.95^{-k}`, the estimate leaves the plot within a thousand
samples (the gain's round-off grows with ``P``), ``P`` overflows after about
9,000 held samples, and from then on the estimate is NaN for good, also when
the input is rich again. The default filter caps the windup: when ``P`` is more than
``spread_max`` (``1e15``) times larger off the regressor's direction than
along it, or its trace would pass ``trace_max`` (``1e12 trace(P0)``), the
step forgets along the regressor only. ``P`` stays finite and positive
definite, the health check warns once at the start of each hold, and the
estimate recovers as soon as the input is rich again. In ordinary runs the
cap never acts (the results are bitwise those without it).
"""

import warnings

import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import NumericalWarning, RecursiveLeastSquares
from rlsfilt.plotting import plot_trace

PERIOD, HELD, TAIL = 20000, 19600, 400
rng = np.random.default_rng(0)
N = 3 * PERIOD + TAIL + 1
u = rng.standard_normal(N)
for p in range(3):                                   # rich for 400 samples, then held
    s = p * PERIOD + PERIOD - HELD
    u[s:s + HELD] = u[s - 1]
theta = np.array([0.5, 2.0, -1.0])
Hs = np.column_stack([np.ones(N - 1), u[1:], u[:-1]])
zs = Hs @ theta + 0.1 * rng.standard_normal(N - 1)
t = np.arange(len(zs))

runs = {}
for name, params in (("capped (default)", None),
                     ("no cap", {"spread_max": np.inf, "trace_max": np.inf})):
    rls = RecursiveLeastSquares(3, lam=0.95, forgetting_params=params)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", NumericalWarning)
        runs[name] = rls.batch_filter(zs, Hs)
    print(f"{name}: {len(caught)} health warning(s), final estimate {rls.x.ravel()}")

fig, (ax_theta, ax_trace) = plt.subplots(2, 1, figsize=(9, 6), sharex=True,
                                         layout="constrained")
for (name, (means, covs, _, _)), style in zip(runs.items(), ("-", "--")):
    with np.errstate(invalid="ignore", over="ignore"):
        plot_trace((means, covs), t=t, label=name, ax=ax_trace, xlabel="sample $k$")
    ax_theta.plot(t, means[:, 1, 0], style, lw=1, label=name,
                  color=ax_trace.get_lines()[-1].get_color())
ax_theta.axhline(theta[1], color="k", lw=0.8, ls=":", label="true")
ax_theta.set(ylim=(0, 4), ylabel=r"estimate of $b_1$ (coefficient of $u_k$)",
             title="input held for 19,600 of every 20,000 samples, lam = 0.95")
ax_theta.legend(loc="upper right", frameon=False, fontsize="small")
for ax in (ax_theta, ax_trace):
    for p in range(3):
        ax.axvspan(p * PERIOD + PERIOD - HELD, (p + 1) * PERIOD, color="0.92", zorder=0)
plt.show()
