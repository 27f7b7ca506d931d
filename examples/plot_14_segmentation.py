"""
Where did the plant change? Segmenting a record
===============================================

:func:`rlsfilt.validation.segment` (MATLAB's ``segment``) cuts a record into
pieces with constant ARX parameters: among all segmentations it finds, by
dynamic programming, the one that minimizes the segments' least-squares losses
plus a price per change. :func:`rlsfilt.plotting.plot_segmentation` draws the
parameters of every segment (solid) over the true ones (dashed), the change
times dotted.
"""

import matplotlib.pyplot as plt

from rlsfilt.datasets import time_varying
from rlsfilt.plotting import plot_segmentation
from rlsfilt.validation import segment

ds = time_varying(rng=0)                       # an ARX(2, 2, 1) plant jumping at t = 1000
na, nb, nk = ds.orders
seg = segment(ds.y[:1500], ds.u[:1500], na=na, nb=nb, nk=nk, R2=ds.noise_variance)
print(seg.summary())
fig, ax = plt.subplots(figsize=(10, 4), layout="constrained")
plot_segmentation(seg, ax, names=["a1", "a2", "b1", "b2"], true_values=ds.theta_true[:1500])
plt.show()
