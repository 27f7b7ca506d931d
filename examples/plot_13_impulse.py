"""
Impulse response and dead time: ``impulseest``
==============================================

:func:`rlsfilt.validation.impulseest` with ``regularization=None`` fits a
finite impulse response by least squares after prewhitening the noise with a
long autoregression, so that its confidence band holds under coloured noise
(MATLAB's ``impulseest`` with ``showConfidence`` and no regularization).
Coefficients inside the shaded 99 % band do not differ significantly from
zero: the first one outside it is the dead time, which
:func:`rlsfilt.delayest` estimates from ARX losses. (By default, as in
MATLAB, the estimate is regularized by the TC kernel instead, which sees a
response through inputs that least squares cannot use, such as a
logarithmic sweep.)
"""

import matplotlib.pyplot as plt
import numpy as np
from scipy.signal import lfilter

from rlsfilt import delayest
from rlsfilt.plotting import plot_impulse
from rlsfilt.validation import impulseest

rng = np.random.default_rng(5)
u = rng.standard_normal(2000)
noise = lfilter([1.0], [1, -0.9], 0.2 * rng.standard_normal(2000))   # coloured
y = lfilter([0] * 6 + [0.5, 0.3], [1, -1.2, 0.5], u) + noise

estimate = impulseest(u, y, n_coeffs=40, regularization=None)
print("first significant lag:", estimate.delay(), "  delayest:", delayest(u, y))
ax = plot_impulse(estimate)
ax.figure.set_size_inches(7, 3.5)
plt.show()
