"""Operating points: the `offset` parameter of `ARX` (and so of `fit_many`), and the rule
that says a record needs one.

One home for both: the modes of ``offset`` (validated), shared by the single model and the
fleet; and the rule "this record sits far from zero and the model ignores it", which the
fits of the model family (`ARX` without ``offset``, `ARMAX`, `OE`, `BJ`, `AR`, `ARMA`)
warn about at fit time and :func:`rlsfilt.validation.validate` at validation time.
"""

import warnings

import numpy as np

from .._scale import pow2_scale
from ..exceptions import OperatingPointWarning

__all__ = []

#: A signal sits far from zero when its mean exceeds this many standard deviations ...
OFFSET_RATIO = 5.0
#: ... over at least this many samples (fewer do not tell an operating point from a drift).
OFFSET_MIN_SAMPLES = 20


def offset_mode(offset):
    """``"none"``, ``"intercept"`` or ``"mean"`` for the `offset` parameter (validated)."""
    if isinstance(offset, str):
        if offset == "mean":
            return "mean"
    elif isinstance(offset, (bool, np.bool_)):
        return "intercept" if offset else "none"
    raise ValueError(f"`offset` must be False, True (estimate an intercept) or 'mean' (remove "
                     f"the means of the estimation record); got {offset!r}")


def model_offset_mode(model):
    """The operating-point handling of `model`: ``"none"`` unless it has an ``offset``
    parameter that is set (``"intercept"`` or ``"mean"``)."""
    offset = model.get_params().get("offset", False)
    return offset_mode(offset) if isinstance(offset, (str, bool, np.bool_)) else "none"


def record_means(X):
    """The means over time (axis 0) of the signals of `X`, shape ``X.shape[1:]``.

    Each signal is summed as one contiguous row (NumPy's pairwise summation), so that a
    signal's mean has the same bits whichever record holds it: `ARX` (``offset="mean"``)
    on one channel and `fit_many` on a fleet whose column it is remove the same means. (A
    mean over axis 0 of a 2-D array adds the rows in turn instead, and a fleet's column
    then gets other roundings than the channel on its own.)
    """
    X = np.asarray(X, dtype=float)
    # (signals, time): one contiguous row per signal
    return np.ascontiguousarray(np.moveaxis(X, 0, -1)).mean(axis=-1)


def far_from_zero(X, ratio=OFFSET_RATIO):
    """``(flagged, mean, std)`` of each column of `X` (time on axis 0): the rule of
    :func:`offset_messages`, for many signals at once (the channels of a fleet).
    Nothing is flagged with fewer than ``OFFSET_MIN_SAMPLES`` rows. `mean` and `std`
    are computed for the one-sided columns only (NaN for the others, which the rule
    never flags): a zero-mean record costs its minimum and maximum, not two more passes
    and a scaled copy (a fifth of ``ARX(2, 2).fit(method="rls")`` on 10^6 samples)."""
    X = np.asarray(X, dtype=float)
    X = X.reshape(len(X), -1)
    k = X.shape[1]
    mean, std = np.full(k, np.nan), np.full(k, np.nan)
    if k == 0 or X.shape[0] < OFFSET_MIN_SAMPLES:
        return np.zeros(k, dtype=bool), mean, std
    # every sample strictly on one side of zero: zero lies outside the record's range
    one_sided = (X.min(axis=0) > 0) | (X.max(axis=0) < 0)
    if one_sided.any():
        Y = X[:, one_sided]
        c = pow2_scale(Y, axis=0)       # mean and std in range for a record in any units
        Ys = Y / c
        mean[one_sided], std[one_sided] = Ys.mean(axis=0) * c, Ys.std(axis=0) * c
    # a constant signal (std 0) is unexciting, not an operating point: the rank checks of
    # the fits speak of it
    flagged = one_sided & (np.abs(mean) > ratio * std) & (std > 0)
    return flagged, mean, std


def offset_messages(records, names, ratio=OFFSET_RATIO):
    """One message per signal of `records` that sits far from zero.

    `records` is ``[(U, Y), ...]`` (per experiment, 2-D arrays, or a 1-D `Y`), `names`
    ``(input_names, output_names)`` (either may be None). A signal of at least
    ``OFFSET_MIN_SAMPLES`` samples (over all experiments) is flagged when

    * its mean is large against its variation, ``|mean| > ratio * std`` over all its
      samples (a record centred by `detrend` never is: ``mean = 0``; zero-mean data has
      ``|mean| / std`` of order ``1 / sqrt(N_eff)``), and
    * none of its samples reaches zero (every sample on the side of the mean): a record
      that starts from rest at the origin (a step test from zero) is a record of the
      deviations already, and a model without an offset describes it;

    a constant signal is not flagged (it is unexciting, which the fits' rank checks report).

    The ratio 5 (with the zero crossing and 20 samples) flagged none of 2,000 zero-mean
    records per case, white or coloured up to a pole at 0.99, of 20 to 3,000 samples
    (``tests/test_fit_operating_point.py``), while the operating points of measured
    records sit at ratios of 10 to 50 (a heater at 97 degC varying by 2 degC).
    """
    out = []
    for k, (kind, label) in enumerate((("input", "u"), ("output", "y"))):
        parts = [np.reshape(r[k], (len(r[k]), -1)) for r in records]
        X = parts[0] if len(parts) == 1 else np.vstack(parts)
        flagged, mean, std = far_from_zero(X, ratio)
        for j in np.flatnonzero(flagged):
            default = label if X.shape[1] == 1 else f"{label}{j + 1}"
            name = names[k][j] if names and names[k] else default
            out.append(f"{kind} {name!r} has mean {mean[j]:.4g} against a standard "
                       f"deviation of {std[j]:.3g}")
    return out


def operating_point_remedy(model):
    """What to do about an ignored operating point, for the class of `model`: an ``offset``
    where the class has one (ARX), else detrending the record."""
    name = type(model).__name__
    detrend = ("the record first: rlsfilt.detrend(u) and rlsfilt.detrend(y), or "
               "rlsfilt.detrend(data) of an IOData (remove the same operating point from the "
               "validation data)")
    if "offset" in model.get_params():
        return (f"Fit {name}(..., offset=True) (an intercept) or offset='mean', or detrend "
                + detrend)
    return "Detrend " + detrend


def warn_fit_operating_point(model, records, names, stacklevel):
    """Warn (`OperatingPointWarning`) once, at fit time, when `records` sit far from zero
    (:func:`offset_messages`) and `model` has no operating-point handling; the message
    names the remedy for its class (:func:`operating_point_remedy`). `stacklevel` points
    at the user's ``fit`` call."""
    if model_offset_mode(model) != "none":
        return
    msgs = offset_messages(records, names)
    if not msgs:
        return
    warnings.warn(f"{type(model).__name__}.fit: " + "; ".join(msgs) + ", and the model has no "
                  "offset handling: the fit mostly describes the operating point, not the "
                  "dynamics. " + operating_point_remedy(model), OperatingPointWarning,
                  stacklevel=stacklevel + 1)
