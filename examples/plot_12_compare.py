"""
Simulation against the data: ``compare`` and its initial condition
==================================================================

:func:`rlsfilt.validation.compare` simulates an identified model on a record
and reports MATLAB's fit, ``100 (1 - |y - y_hat| / |y - mean(y)|)``. An
output-error model carries its own past, so the fit depends on where the
simulation starts: from rest (``initial="zero"``), the start of a record
that does not begin at rest fits badly for a while; with the initial state
estimated by least squares over the record (``initial="estimate"``, MATLAB's
default ``'e'``) the model is judged on its dynamics alone. The figure's
title says which start was used.
"""

import matplotlib.pyplot as plt
import numpy as np
from scipy.signal import lfilter

from rlsfilt import OE
from rlsfilt.plotting import plot_compare
from rlsfilt.validation import compare

rng = np.random.default_rng(3)
u = rng.standard_normal(600)
# the record starts in the middle of a transient: the plant was not at rest
y0 = lfilter([0, 0.4, 0.2], [1, -1.5, 0.7], u)
y = y0[100:] + 0.05 * rng.standard_normal(500)
u = u[100:]

model = OE(2, 2, 1).fit(u, y)
fig, axes = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
for ax, initial in zip(axes, ["zero", "estimate"]):
    result = compare(model, u, y, initial=initial)
    plot_compare(result, ax, window=(0, 120))
    ax.set_title(f"initial={initial!r}: fit {result.fit:.1f} %", fontsize=10)
fig.tight_layout()
plt.show()
