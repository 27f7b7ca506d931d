"""Saving fitted models to JSON and loading them back.

A model file is plain JSON (no pickle: loading never runs code from the
file): the model's class, its constructor parameters (``get_params()``), and
its learned attributes, the public attributes whose names end in ``_``
(parameters, covariance, noise variance, operating point, ...). Floats are
written with Python's shortest round-tripping representation, so a loaded
model holds bit-for-bit the numbers of the saved one.

Any model class can be saved if it follows the estimator conventions of
rlsfilt (``get_params()``, learned attributes ending in ``_``). A class whose
learned state needs more than its public attributes to be usable (derived
private caches) defines ``_restore_fitted(self, fitted)``, which receives the
decoded attributes as a dict; otherwise they are set with ``setattr``.

The pretreatment a model was fitted under travels with it: ``save_model(model,
path, trend=trend)`` stores the `rlsfilt.Trend` that :func:`rlsfilt.detrend`
removed from the estimation record (constant or piecewise linear) as the
learned attribute ``trend_``, and :func:`load_model` restores it, so
``trend_.remove(new_data)`` and ``retrend`` put predictions in the units of
the data exactly as before saving. A model that already holds a ``trend_``
(a loaded one) keeps it when saved again; ``fit`` drops it.
"""

import importlib
import json
import math
import numbers
import os

import numpy as np

__all__ = ["save_model", "load_model"]

FORMAT = "rlsfilt.model"
FORMAT_VERSION = 1
# per-sample diagnostics of a fit: as long as the record, left out unless asked for
_PER_SAMPLE_SUFFIXES = ("residuals_", "_history_")
_FLOAT_NAMES = {"NaN": math.nan, "Infinity": math.inf, "-Infinity": -math.inf}


def save_model(model, path, *, include_data=False, trend=None):
    """Write a fitted model to a JSON file.

    Parameters
    ----------
    model : estimator
        A fitted rlsfilt model (any class with ``get_params()`` whose
        learned attributes end in ``_``).
    path : str or os.PathLike
        File to write (overwritten).
    include_data : bool, default False
        Also write the per-sample diagnostics of the fit (attributes named
        ``*residuals_`` and ``*_history_``, as long as the record).
    trend : Trend, optional
        The trend :func:`rlsfilt.detrend` removed from the estimation record
        (``detrend(IOData(u, y, dt), type="linear")``), written as the
        learned attribute ``trend_`` that :func:`load_model` restores. It
        must be the trend of an `IOData` with the model's numbers of inputs
        and outputs (for a time-series model, also the trend of its output
        array). By default the model's own ``trend_``, if it has one.

    Returns
    -------
    dict
        The document written (``"class"``, ``"params"``, ``"fitted"``,
        ``"omitted"``: names of learned attributes that were not written,
        such as a live filter object, and the version tags).

    Raises
    ------
    TypeError
        If `model` has no ``get_params``, a constructor parameter cannot be
        written as JSON, or `trend` is not a `Trend`.
    ValueError
        If `model` has no learned attributes (it was not fitted), or
        `trend` describes other signals than the model's.

    Examples
    --------
    >>> import numpy as np, os, tempfile
    >>> from rlsfilt.persistence import load_model, save_model
    >>> class Mean:                                   # a minimal estimator
    ...     def __init__(self, scale=1.0):
    ...         self.scale = scale
    ...     def get_params(self, deep=True):
    ...         return {"scale": self.scale}
    ...     def fit(self, x):
    ...         self.mean_ = self.scale * np.mean(x)
    ...         return self
    >>> path = os.path.join(tempfile.mkdtemp(), "mean.json")
    >>> _ = save_model(Mean(2.0).fit([1.0, 2.0]), path)
    >>> load_model(path, cls=Mean).mean_
    3.0

    An ARX model fitted on linearly detrended data keeps its trend:

    >>> from rlsfilt import ARX, IOData, detrend, retrend
    >>> rng = np.random.default_rng(0)
    >>> u = rng.standard_normal(200)
    >>> y = np.convolve(u, [0.0, 1.0, 0.5])[:200] + 0.02 * np.arange(200) + 50.0
    >>> data_d, trend = detrend(IOData(u, y, dt=0.1), type="linear")
    >>> model = ARX(0, 2, 1, dt=0.1).fit(data_d)
    >>> _ = model.save(path, trend=trend)
    >>> loaded = ARX.load(path)
    >>> loaded.trend_.type, bool(np.array_equal(loaded.trend_.slope[0], trend.slope[0]))
    ('linear', True)
    >>> def in_units(m, trend):                       # one-step predictions, data units
    ...     return retrend(IOData(data_d.u, m.predict(data_d), dt=0.1), trend).y
    >>> bool(np.array_equal(in_units(loaded, loaded.trend_), in_units(model, trend)))
    True
    >>> bool(np.max(np.abs(in_units(loaded, loaded.trend_)[2:] - y[2:])) < 0.05)
    True
    """
    doc = _document(model, include_data=include_data, trend=trend)
    text = _dumps(doc)
    with open(os.fspath(path), "w", encoding="utf-8") as fh:
        fh.write(text + "\n")
    return doc


def load_model(path, cls=None):
    """Read a model written by :func:`save_model`.

    Parameters
    ----------
    path : str or os.PathLike
        The JSON file.
    cls : type, optional
        The model class to build. By default the class named in the file,
        which must be an rlsfilt class (found in its module or in
        ``rlsfilt``); with `cls`, the file must hold a model of that class
        (or of a class with the same name).

    Returns
    -------
    model
        A fitted model, usable as the saved one.

    Raises
    ------
    ValueError
        Not an rlsfilt model file, a newer format version, a class that is
        not part of rlsfilt, or a file holding another class than `cls`.
    """
    with open(os.fspath(path), encoding="utf-8") as fh:
        try:
            doc = json.load(fh)
        except json.JSONDecodeError as exc:
            raise ValueError(f"`path` is not a JSON file ({exc})") from None
    return _from_document(doc, cls=cls, source=os.fspath(path))


# ----------------------------------------------------------------------
# private helpers
# ----------------------------------------------------------------------
def _document(model, *, include_data=False, trend=None):
    """The JSON-ready dict that :func:`save_model` writes."""
    if not callable(getattr(model, "get_params", None)):
        raise TypeError(f"`model` must be an estimator with get_params(); got "
                        f"{type(model).__name__}")
    params = {}
    for name, value in model.get_params().items():
        try:
            params[name] = _encode(value)
        except TypeError as exc:
            raise TypeError(f"the parameter `{name}` of {type(model).__name__} cannot be saved "
                            f"as JSON: {exc}") from None
    fitted, omitted = {}, []
    for name, value in vars(model).items():
        if name.startswith("_") or not name.endswith("_"):
            continue
        if not include_data and name.endswith(_PER_SAMPLE_SUFFIXES):
            omitted.append(name)
            continue
        try:
            fitted[name] = _encode(value)
        except TypeError:
            omitted.append(name)
    if not fitted:
        raise ValueError(f"`model` has no learned attributes to save; call fit() on the "
                         f"{type(model).__name__} first")
    if trend is not None:
        _check_trend(trend, model)
        fitted["trend_"] = _encode(trend)
        if "trend_" in omitted:
            omitted.remove("trend_")
    from ._version import __version__

    return {"format": FORMAT, "format_version": FORMAT_VERSION, "rlsfilt_version": __version__,
            "class": type(model).__name__, "module": type(model).__module__,
            "params": params, "fitted": fitted, "omitted": sorted(omitted)}


def _from_document(doc, cls=None, source="the document"):
    """The model described by a dict from :func:`_document`."""
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"{source} is not an rlsfilt model file (no \"format\": "
                         f"\"{FORMAT}\" entry)")
    version = doc.get("format_version")
    if not isinstance(version, int) or version > FORMAT_VERSION:
        raise ValueError(f"{source} has model format version {version!r}; this rlsfilt reads "
                         f"versions up to {FORMAT_VERSION} (upgrade rlsfilt)")
    name, module = doc.get("class"), doc.get("module", "")
    if cls is None:
        cls = _find_class(name, module, source)
    elif not isinstance(cls, type) or cls.__name__ != name:
        raise ValueError(f"{source} holds a {name} model; load it with {name}.load or "
                         f"load_model(path) (asked for {getattr(cls, '__name__', cls)!r})")
    params = {k: _decode(v) for k, v in doc["params"].items()}
    fitted = {k: _decode(v) for k, v in doc["fitted"].items()}
    model = cls(**params)
    restore = getattr(model, "_restore_fitted", None)
    if callable(restore):
        restore(fitted)
    else:
        for key, value in fitted.items():
            setattr(model, key, value)
    return model


def _check_trend(trend, model):
    """TypeError/ValueError unless `trend` can be the pretreatment of `model`'s data."""
    from .data.trend import Trend

    if not isinstance(trend, Trend):
        raise TypeError(f"`trend` must be a Trend (from rlsfilt.detrend); got "
                        f"{type(trend).__name__}")
    nu, ny = getattr(model, "n_inputs_", None), getattr(model, "n_outputs_", None)
    if nu is None or ny is None:
        return
    if trend.n_inputs is not None:
        if (trend.n_inputs, trend.n_outputs) != (nu, ny):
            raise ValueError(f"`trend` must describe {nu} input(s) and {ny} output(s) like the "
                             f"model; got {trend.n_inputs} and {trend.n_outputs}")
    elif nu != 0 or trend.n_columns != ny:
        raise ValueError(f"`trend` must be the trend of an IOData with {nu} input(s) and {ny} "
                         f"output(s) (detrend(IOData(u, y, dt))); got the trend of an array "
                         f"with {trend.n_columns} column(s)")


def _find_class(name, module, source):
    if not isinstance(name, str) or not name.isidentifier():
        raise ValueError(f"{source} names no valid model class; got {name!r}")
    candidates = []
    if isinstance(module, str) and (module == "rlsfilt" or module.startswith("rlsfilt.")):
        candidates.append(module)
    candidates += ["rlsfilt", "rlsfilt.models"]
    for mod in candidates:
        try:
            found = getattr(importlib.import_module(mod), name, None)
        except ImportError:
            continue
        if isinstance(found, type):
            return found
    raise ValueError(f"{source} holds a model of class {name!r} from {module!r}, which is not "
                     "an rlsfilt class; pass `cls=` to load it")


def _encode(value):
    """JSON-ready form of `value`; TypeError for what cannot be written exactly."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, numbers.Integral):
        return int(value)
    if isinstance(value, numbers.Real):
        v = float(value)
        return v if math.isfinite(v) else {"__float__": _float_name(v)}
    if isinstance(value, np.ndarray):
        return _encode_array(value)
    if isinstance(value, tuple):
        return {"__tuple__": [_encode(v) for v in value]}
    if isinstance(value, list):
        return [_encode(v) for v in value]
    if isinstance(value, range):
        return {"__range__": [value.start, value.stop, value.step]}
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError("dict keys must be strings")
        return {"__dict__": {k: _encode(v) for k, v in value.items()}}
    to_dict = getattr(value, "to_dict", None)
    from_dict = getattr(type(value), "from_dict", None)
    module = type(value).__module__
    if callable(to_dict) and callable(from_dict) and module.startswith("rlsfilt."):
        return {"__object__": f"{module}:{type(value).__qualname__}",
                "state": _encode(to_dict())}
    raise TypeError(f"a {type(value).__name__} has no JSON form")


def _float_name(v):
    return "NaN" if math.isnan(v) else ("Infinity" if v > 0 else "-Infinity")


def _encode_array(arr):
    kind = arr.dtype.kind
    if kind == "b":
        data = arr.ravel().tolist()
    elif kind in "iu":
        data = [int(v) for v in arr.ravel()]
    elif kind == "f":
        data = [v if math.isfinite(v) else _float_name(v) for v in arr.astype(float).ravel()]
    elif kind == "c":
        flat = arr.astype(complex).ravel()
        data = [[_encode(float(v.real)), _encode(float(v.imag))] for v in flat]
    else:
        raise TypeError(f"an array of dtype {arr.dtype} has no JSON form")
    return {"__ndarray__": {"dtype": arr.dtype.str, "shape": list(arr.shape), "data": data}}


def _decode(value):
    if isinstance(value, list):
        return [_decode(v) for v in value]
    if not isinstance(value, dict):
        return value
    if "__float__" in value:
        return _FLOAT_NAMES[value["__float__"]]
    if "__tuple__" in value:
        return tuple(_decode(v) for v in value["__tuple__"])
    if "__range__" in value:
        return range(*value["__range__"])
    if "__dict__" in value:
        return {k: _decode(v) for k, v in value["__dict__"].items()}
    if "__ndarray__" in value:
        spec = value["__ndarray__"]
        dtype = np.dtype(spec["dtype"])
        if dtype.kind == "c":
            flat = [complex(_decode(re), _decode(im)) for re, im in spec["data"]]
        elif dtype.kind == "f":
            flat = [_FLOAT_NAMES[v] if isinstance(v, str) else v for v in spec["data"]]
        else:
            flat = spec["data"]
        return np.array(flat, dtype=dtype).reshape(spec["shape"])
    if "__object__" in value:
        module, _, qualname = value["__object__"].partition(":")
        if not module.startswith("rlsfilt."):
            raise ValueError(f"a stored object of {module!r} is not an rlsfilt object")
        obj = importlib.import_module(module)
        for part in qualname.split("."):
            obj = getattr(obj, part)
        return obj.from_dict(_decode(value["state"]))
    raise ValueError(f"unknown entry in a model file: keys {sorted(value)}")


def _dumps(doc):
    """JSON with one line per top-level entry and per parameter/attribute (arrays compact)."""
    lines = ["{"]
    items = list(doc.items())
    for i, (key, value) in enumerate(items):
        comma = "," if i < len(items) - 1 else ""
        if isinstance(value, dict) and key in ("params", "fitted") and value:
            inner = [f"    {json.dumps(k)}: {json.dumps(v, allow_nan=False)}"
                     for k, v in value.items()]
            lines.append(f"  {json.dumps(key)}: {{\n" + ",\n".join(inner) + f"\n  }}{comma}")
        else:
            lines.append(f"  {json.dumps(key)}: {json.dumps(value, allow_nan=False)}{comma}")
    lines.append("}")
    return "\n".join(lines)
