"""
Choosing the model orders
=========================

:func:`rlsfilt.select_order` fits every ARX structure ``(na, nb, nk)`` in a
grid from one QR factorization and scores it by an information criterion
(MATLAB's ``arxstruc`` / ``selstruc``). :func:`rlsfilt.plotting.plot_order_selection`
draws the criterion against the number of parameters: every candidate is a
dot, the line joins the best of each size and the star is the selected
structure. BIC finds the true ARX(2, 2, 1) of the non-minimum-phase plant.
"""

import matplotlib.pyplot as plt

from rlsfilt import select_order
from rlsfilt.datasets import nonminimum_phase
from rlsfilt.plotting import plot_order_selection

est, val = nonminimum_phase(rng=0), nonminimum_phase(rng=1)
sel = select_order(est.u, est.y, na=range(1, 5), nb=range(1, 5), nk=range(0, 4), dt=est.dt)
print(sel.summary(top=5))
ax = plot_order_selection(sel)

# %%
# On validation data the plain loss has a minimum too (larger models fit the
# noise of the estimation record, not the new one).
sel_val = select_order(est.u, est.y, na=range(1, 5), nb=range(1, 5), nk=range(0, 4),
                       criterion="loss", validation=(val.u, val.y), dt=est.dt)
ax = plot_order_selection(sel_val)
ax.set_yscale("log")
plt.show()
