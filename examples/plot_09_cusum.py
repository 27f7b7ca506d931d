"""
Has the plant changed? CUSUM tests
==================================

The CUSUM and CUSUM-of-squares tests of Brown, Durbin & Evans (1975) run on
the recursive residuals of RLS. Under constant parameters their paths stay
inside the significance lines; a parameter change drives them out.
:func:`rlsfilt.plotting.plot_cusum` marks, when a test rejects constancy, the
path outside the lines and the sample where it departs furthest from its
expected course (an estimate of when the plant changed); a test that does not
reject gets no marks. Pass ``t`` so the marks are in the record's samples: row
``r`` of an ARX regression is sample ``r + max_lag``.
"""

import matplotlib.pyplot as plt
import numpy as np

from rlsfilt import ARX
from rlsfilt.datasets import nonminimum_phase, time_varying
from rlsfilt.plotting import plot_cusum
from rlsfilt.validation import cusum, cusum_squares

fig, axes = plt.subplots(2, 2, figsize=(12, 7), layout="constrained")
for col, (ds, title) in enumerate(((nonminimum_phase(rng=1), "constant plant"),
                                   (time_varying(rng=0), "parameters jump at t = 1000"))):
    Phi, z = ARX(*ds.orders).regressors(ds.u, ds.y)
    t = np.arange(len(ds.y) - len(z), len(ds.y))      # the sample of each regression row
    plot_cusum(cusum(z, Phi), axes[0, col], t=t)
    plot_cusum(cusum_squares(z, Phi), axes[1, col], t=t)
    axes[0, col].set_title(f"{title}\n" + axes[0, col].get_title())
plt.show()
