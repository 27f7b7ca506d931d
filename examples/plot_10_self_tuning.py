"""
A self-tuning regulator on a plant that changes
===============================================

:class:`rlsfilt.adaptive.SelfTuningRegulator` estimates an ARX model of the
plant with recursive least squares (forgetting factor 0.98 here) and redesigns
a pole-placement controller (:func:`rlsfilt.adaptive.rst_design`, integral
action) at every sample. Halfway through, the plant's gain and damping change;
the estimates follow within a few memory lengths and the output keeps tracking
the square-wave reference. The control is limited to +-2 (`u_limits`, the
saturated value enters the regressor) and a small dither keeps the loop
exciting. :func:`rlsfilt.plotting.plot_str_history` (what
``history.plot()`` calls) draws the reference and output, the control, the
estimates against the truth (dashed) and :math:`\\mathrm{tr}\\,P`.
"""

import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import RecursiveLeastSquares
from rlsfilt.adaptive import SelfTuningRegulator
from rlsfilt.plotting import plot_str_history

before = np.array([-1.5, 0.7, 1.0, 0.5])          # [a1, a2, b1, b2]
after = np.array([-1.3, 0.6, 0.6, 0.4])           # lower gain, more damping
N, change = 1200, 600
truth = np.where(np.arange(N)[:, None] < change, before, after)

stre = SelfTuningRegulator(RecursiveLeastSquares(4, lam=0.98, P0=100.0),
                           design=dict(Am=np.poly([0.6, 0.6]), Ao=np.poly([0.2])),
                           na=2, nb=2, nk=1, dt=0.1, u_limits=(-2.0, 2.0))
rng = np.random.default_rng(0)
r = np.where(np.arange(N) % 200 < 100, 1.0, -1.0)
y, u = np.zeros(N), np.zeros(N)                   # y[-1], u[-1], ..: the plant at rest
for t in range(N):
    a1, a2, b1, b2 = truth[t]
    y[t] = -a1 * y[t - 1] - a2 * y[t - 2] + b1 * u[t - 1] + b2 * u[t - 2] \
        + 0.01 * rng.standard_normal()
    u[t] = stre.step(y[t], r[t], dither=0.05 * rng.choice([-1.0, 1.0]))

fig = plot_str_history(stre.history, true_theta=truth)
err = np.abs(stre.history.theta[-1] - after).max()
print(f"largest estimate error at the end: {err:.3f}")
plt.show()
