"""Simulated plants with known truth, and excitation signals.

The project's embedded example data: every generator runs with no arguments
and returns a reproducible `Dataset` (``u``, ``y``, ``dt``, the true
``plant`` as a python-control transfer function, the true ARX orders and
coefficients, and the noise level).

>>> from rlsfilt import ARX
>>> from rlsfilt.datasets import dc_motor
>>> ds = dc_motor()
>>> model = ARX(*ds.orders, dt=ds.dt).fit(ds.u, ds.y)
"""

from .dataset import Dataset
from .inputs import multisine, prbs, steps, white_noise
from .plants import (
    PLANTS,
    dc_motor,
    mass_spring_damper,
    nonminimum_phase,
    thermal_process,
    time_varying,
)
from .records import heat_exchanger

__all__ = [
    "Dataset",
    "PLANTS",
    "thermal_process",
    "dc_motor",
    "mass_spring_damper",
    "nonminimum_phase",
    "time_varying",
    "heat_exchanger",
    "prbs",
    "white_noise",
    "multisine",
    "steps",
]
