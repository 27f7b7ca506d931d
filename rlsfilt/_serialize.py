"""Plain-Python, JSON-ready copies of results (one rule for every ``to_dict``).

``json.dumps(jsonable(x), allow_nan=False)`` always works: numpy arrays and
tuples become lists, numpy scalars Python numbers, complex numbers
``[real, imag]`` pairs, and non-finite floats (NaN, +-inf) become ``None``
(JSON ``null``), because JSON has no representation for them.
"""

import math
import numbers

import numpy as np

__all__ = []


def jsonable(value):
    """A JSON-ready copy of `value` (see the module docstring for the rules)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return [jsonable(v) for v in value.tolist()] if value.ndim else jsonable(value.item())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        value = float(value)
        return value if math.isfinite(value) else None
    if isinstance(value, numbers.Complex):
        return [jsonable(value.real), jsonable(value.imag)]
    raise TypeError(f"cannot represent a {type(value).__name__} in JSON")
