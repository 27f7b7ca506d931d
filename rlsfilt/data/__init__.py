"""Input/output records and their pretreatment.

`IOData` holds the samples of one or several experiments with the sampling
period and the names and units of the signals (MATLAB's ``iddata``);
`detrend` and `retrend` remove and restore the operating point.
"""

from .iodata import IOData
from .trend import Trend, detrend, retrend

__all__ = ["IOData", "Trend", "detrend", "retrend"]
