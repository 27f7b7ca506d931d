"""
Validating an identified model: ``report.plot()``
=================================================

The main workflow: identify an ARX model of a DC motor (voltage in, speed
out) on one experiment and validate it on another. ``report.plot()`` (that is
:func:`rlsfilt.plotting.plot_report`) draws, from top to bottom,

* the simulated and one-step-predicted speed against the measured one, in a
  readable window of the last 400 samples, above an overview of the whole
  record with the simulation error;
* the residual autocorrelation (lags from 1: lag 0 is always 1) and the
  cross-correlation with the input, each with its band under the hypothesis;
* the Bode diagram of the model with its 95 % uncertainty band
  (:func:`rlsfilt.validation.frequency_response_band`) over the true plant,
  and both step responses.
"""

import matplotlib.pyplot as plt

from rlsfilt import ARX, validate
from rlsfilt.datasets import dc_motor

est, val = dc_motor(rng=0), dc_motor(rng=1)        # estimation and validation experiments
model = ARX(*est.orders, dt=est.dt).fit(est.u, est.y)
report = validate(model, val.u, val.y, plant=val.plant)
print(report.summary())

fig = report.plot()
fig.axes[0].set_ylabel("speed (rad/s)")
plt.show()
