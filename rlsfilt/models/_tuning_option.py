"""The ``lam="tune"`` / ``Q="tune"`` option of `ARX.fit` and `fit_many`, validated.

One home for the rule, shared by the single model and the fleet.
"""

__all__ = []


def tuning_param(method, lam, Q, where):
    """``"lam"``, ``"q"`` or None: what ``lam="tune"`` / ``Q="tune"`` ask to estimate
    (checked: one of them, with ``method="rls"``)."""
    asked = [name for name, value in (("lam", lam), ("Q", Q)) if isinstance(value, str)]
    for name in asked:
        value = lam if name == "lam" else Q
        if value != "tune":
            raise ValueError(f"`{name}` must be a number or 'tune'; got {value!r}")
    if not asked:
        return None
    if method != "rls":
        raise ValueError(f"`{asked[0]}='tune'` only applies to method='rls' in {where}; got "
                         f"method={method!r}")
    if len(asked) == 2:
        raise ValueError("tune one of `lam` and `Q` at a time (the other stays as given); got "
                         "lam='tune' and Q='tune'")
    return "lam" if asked[0] == "lam" else "q"
