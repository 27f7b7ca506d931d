"""Recursive least-squares filters, the gradient family, their smoother and their tuning."""

from .bank import RLSBank
from .gradient import APA, LMS, NLMS, SignDataLMS, SignErrorLMS, SignSignLMS
from .gradient_bank import GradientBank
from .rls import RecursiveLeastSquares
from .sliding_window import SlidingWindowRLS
from .smoother import SmoothedTrajectory, rts_smoother
from .square_root import SquareRootRLS
from .tuning import BankTuneResult, TuneResult, tune, tune_bank

__all__ = ["RecursiveLeastSquares", "SlidingWindowRLS", "SquareRootRLS", "RLSBank",
           "rts_smoother", "SmoothedTrajectory", "tune", "TuneResult", "tune_bank",
           "BankTuneResult", "LMS", "NLMS", "SignErrorLMS", "SignDataLMS", "SignSignLMS", "APA",
           "GradientBank"]
