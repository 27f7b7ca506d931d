"""The `offset` parameter of `ARX` (and so of `fit_many`): its three modes, validated.

One home for the rule, shared by the single model and the fleet.
"""

import numpy as np

__all__ = []


def offset_mode(offset):
    """``"none"``, ``"intercept"`` or ``"mean"`` for the `offset` parameter (validated)."""
    if isinstance(offset, str):
        if offset == "mean":
            return "mean"
    elif isinstance(offset, (bool, np.bool_)):
        return "intercept" if offset else "none"
    raise ValueError(f"`offset` must be False, True (estimate an intercept) or 'mean' (remove "
                     f"the means of the estimation record); got {offset!r}")
