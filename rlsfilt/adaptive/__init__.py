r"""From identification to control: controller design, self-tuning regulators, Kalman filters.

* `rst_design`: polynomial pole placement, :math:`A R + B S = A_m A_o`, an
  `RSTController` that converts to python-control (`RSTController.to_tf`,
  `RSTController.to_ss`) and reports its `ClosedLoop`;
* `minimum_variance`, `generalized_minimum_variance`: the designs of
  Astrom & Wittenmark's *Adaptive Control*, ch. 4, for ARMAX plants;
* `SelfTuningRegulator`: online ARX identification with any rlsfilt filter
  plus redesign, with safeguards and a history; also a python-control
  `NonlinearIOSystem` (`SelfTuningRegulator.as_iosystem`);
* `estimator_iosystem`: a filter as a python-control system;
* `to_kalman`, `from_kalman`: identified models as filterpy Kalman filters in
  innovations form, and back.

**Polynomial convention.** Every polynomial is the 1-D array of its
coefficients of *ascending powers of* :math:`q^{-1}` (the backward shift),
as in MATLAB's System Identification Toolbox and ``ARX.polynomials()``:
``A = [1, a1, .., a_na]`` is :math:`1 + a_1 q^{-1} + \dots`, and
``B = [0, b1, b2]`` is :math:`b_1 q^{-1} + b_2 q^{-2}` (a delay of one
sample). Read as descending powers of :math:`z`, the same array is
:math:`z^n P(z^{-1})`, so ``np.roots(P)`` gives zeros and poles in the
z-plane, and ``np.poly(poles)`` a monic polynomial with those zeros.

python-control is imported only when a function needs it, so ``import
rlsfilt`` stays light.
"""

from ..filters._estimator_io import estimator_iosystem
from ..models._kalman import to_kalman
from .innovations import InnovationsModel, from_kalman
from .minimum_variance import (
    MinimumVarianceController,
    generalized_minimum_variance,
    minimum_variance,
)
from .rst import ClosedLoop, RSTController, rst_design
from .self_tuning import SelfTuningRegulator, STRHistory

__all__ = [
    "rst_design",
    "RSTController",
    "ClosedLoop",
    "minimum_variance",
    "generalized_minimum_variance",
    "MinimumVarianceController",
    "SelfTuningRegulator",
    "STRHistory",
    "estimator_iosystem",
    "to_kalman",
    "from_kalman",
    "InnovationsModel",
]
