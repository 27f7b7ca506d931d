"""The model file of :mod:`rlsfilt.persistence`: its declared schema, writer and reader.

Nothing here imports the model classes (``models._base`` calls it for ``save``/``load``);
the closed set is named in :data:`MODEL_CLASSES`, each class of it declares its own
``_FILE_NAME``, and :mod:`rlsfilt.persistence` passes the dict of the classes themselves.
"""

import json
import math
import numbers
import os

import numpy as np

from ._atomic import atomic_write

__all__ = []

FORMAT = "rlsfilt.model"
#: The version of the model file format written by :func:`save_model`.
FORMAT_VERSION = 2
_READABLE = (1, 2)
#: The classes a model file can hold (the closed set :func:`load_model` builds).
MODEL_CLASSES = ("ARX", "ARMAX", "OE", "BJ", "AR", "ARMA")
# per-sample diagnostics of a fit: as long as the record, left out unless asked for
_PER_SAMPLE = ("residuals_", "theta_history_", "recursive_residuals_")
# the most numbers one stored array may declare (its data must be in the file anyway)
_MAX_ELEMENTS = 10**8
# version 1 stored these objects by module path; they are matched as text, never imported
_V1_OBJECTS = {"ARXStructure": "rlsfilt.models.regressors:ARXStructure",
               "FamilyStructure": "rlsfilt.models._family:FamilyStructure",
               "Trend": "rlsfilt.data.trend:Trend"}
_TOP = {"format", "format_version", "rlsfilt_version", "class", "params", "fitted", "omitted"}
_TOP_V1 = _TOP | {"module"}

# constructor parameters: orders with their minimum ("per input": an int or one per input)
_ORDERS = {"ARX": {"na": 0, "nb": 1, "nk": 0},
           "ARMAX": {"na": 0, "nb": 1, "nc": 0, "nk": 0},
           "OE": {"nb": 1, "nf": 0, "nk": 0},
           "BJ": {"nb": 1, "nc": 0, "nd": 0, "nf": 0, "nk": 0},
           "AR": {"na": 1},
           "ARMA": {"na": 0, "nc": 0}}
_PER_INPUT = ("nb", "nf", "nk")

# learned attributes: every name a file may hold, and those it must hold
_ARX_FITTED = ("structure_", "n_params_", "n_inputs_", "n_outputs_", "theta_", "a_", "b_",
               "input_names_", "output_names_", "input_units_", "output_units_", "intercept_",
               "input_offset_", "output_offset_", "theta_cov_", "noise_variance_",
               "noise_covariance_", "n_samples_", "n_experiments_", "method_", "k0_", "lam_",
               "form_", "instruments_", "theta_history_", "recursive_residuals_",
               "residuals_", "trend_")
_ARX_REQUIRED = ("structure_", "n_params_", "n_inputs_", "n_outputs_", "theta_", "a_", "b_",
                 "input_names_", "output_names_", "input_offset_", "output_offset_",
                 "theta_cov_", "noise_variance_", "n_samples_", "n_experiments_", "method_")
_FAMILY_FITTED = ("method_", "fit_info_", "margins_", "theta_", "theta_cov_",
                  "noise_variance_", "n_samples_", "n_params_", "n_inputs_", "n_outputs_",
                  "structure_", "n_experiments_", "input_names_", "output_names_",
                  "input_units_", "output_units_", "a_", "c_", "d_", "b_", "f_",
                  "theta_history_", "recursive_residuals_", "residuals_", "trend_")
_FAMILY_REQUIRED = ("method_", "theta_", "theta_cov_", "noise_variance_", "n_samples_",
                    "n_params_", "n_inputs_", "n_outputs_", "structure_", "n_experiments_",
                    "input_names_", "output_names_", "a_", "c_", "d_", "b_", "f_")
# learned attributes only some fits set: name -> the methods that set them
_ARX_ONLY = {"lam_": ("rls",), "form_": ("rls",), "k0_": ("rls", "riv", "nlms", "lms"),
             "theta_history_": ("rls", "riv", "nlms", "lms"),
             "recursive_residuals_": ("rls", "riv", "nlms", "lms"),
             "instruments_": ("iv", "riv")}
_FAMILY_ONLY = {"fit_info_": ("pem",), "margins_": ("rplr",),
                "theta_history_": ("rpem", "rplr"), "recursive_residuals_": ("rpem", "rplr")}


def _file_name(klass):
    """The name a class of the closed set stores (its own ``_FILE_NAME``, never inherited:
    a subclass is not in the set), or None."""
    name = klass.__dict__.get("_FILE_NAME") if isinstance(klass, type) else None
    if name in MODEL_CLASSES and klass.__name__ == name and \
            klass.__module__.startswith("rlsfilt.models."):
        return name
    return None


def save_model(model, path, *, include_data=False, trend=None, classes=None):
    """Write `model` to `path` atomically (see :func:`rlsfilt.persistence.save_model`)."""
    doc = _document(model, include_data=include_data, trend=trend, classes=classes)
    text = _dumps(doc)
    try:
        _from_document(_parse(text, "the document"), cls=type(model), source=None)
    except ValueError as exc:
        raise ValueError(f"the {type(model).__name__} model cannot be saved: {exc}") from None
    with atomic_write(path) as fh:
        _write_text(fh, text + "\n")
    return doc


def load_model(path, cls=None, classes=None):
    """Read a model file (see :func:`rlsfilt.persistence.load_model`)."""
    source = os.fspath(path)
    with open(source, "rb") as fh:
        raw = fh.read()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"`path` is not a UTF-8 JSON file ({exc})") from None
    return _from_document(_parse(text, "`path`"), cls=cls, source=source, classes=classes)


# ----------------------------------------------------------------------
# writing
# ----------------------------------------------------------------------
def _write_text(fh, text):
    """One place the text is written (a test makes it fail midway)."""
    fh.write(text)


def _document(model, *, include_data=False, trend=None, classes=None):
    """The JSON-ready dict that :func:`save_model` writes."""
    name = _file_name(type(model))
    if name is None or classes is not None and classes.get(name) is not type(model):
        raise TypeError(f"`model` must be a model of one of the classes {list(MODEL_CLASSES)} "
                        f"(what a model file holds); got {type(model).__name__}")
    if "theta_" not in vars(model):
        raise ValueError(f"`model` has no learned attributes to save; call fit() on the "
                         f"{name} first")
    params = {}
    for key, value in model.get_params().items():
        try:
            params[key] = _encode(value)
        except TypeError as exc:
            raise TypeError(f"the parameter `{key}` of {name} cannot be saved as JSON: "
                            f"{exc}") from None
    declared = _ARX_FITTED if name == "ARX" else _FAMILY_FITTED
    fitted, omitted = {}, []
    for key, value in vars(model).items():
        if key.startswith("_") or not key.endswith("_"):
            continue
        if key not in declared or (key in _PER_SAMPLE and not include_data):
            omitted.append(key)
        elif key == "structure_":
            fitted[key] = {"__dict__": _encode(value.to_dict())["__dict__"]}
        elif key == "trend_":
            fitted[key] = _encode_trend(value)
        else:
            try:
                fitted[key] = _encode(value)
            except TypeError:
                omitted.append(key)
    if trend is not None:
        _check_trend(trend, model)
        fitted["trend_"] = _encode_trend(trend)
        if "trend_" in omitted:
            omitted.remove("trend_")
    from ._version import __version__

    return {"format": FORMAT, "format_version": FORMAT_VERSION, "rlsfilt_version": __version__,
            "class": name, "params": params, "fitted": fitted, "omitted": sorted(omitted)}


def _encode_trend(trend):
    return _encode(trend.to_dict())


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
    if isinstance(value, dict):
        if not all(isinstance(k, str) for k in value):
            raise TypeError("dict keys must be strings")
        return {"__dict__": {k: _encode(v) for k, v in value.items()}}
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
    else:
        raise TypeError(f"an array of dtype {arr.dtype} has no JSON form")
    return {"__ndarray__": {"dtype": arr.dtype.str, "shape": list(arr.shape), "data": data}}


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


# ----------------------------------------------------------------------
# reading: the JSON text
# ----------------------------------------------------------------------
class _Duplicate(ValueError):
    pass


def _unique_keys(pairs):
    out = {}
    for key, value in pairs:
        if key in out:
            raise _Duplicate(f"the key {key!r} appears twice in one JSON object")
        out[key] = value
    return out


def _no_constant(name):
    raise ValueError(f"non-standard JSON constant {name} (NaN and infinities are not numbers a "
                     "model file holds)")


def _parse(text, what):
    """The JSON document of `text`: strict JSON (no NaN/Infinity literals, no repeated keys)."""
    try:
        return json.loads(text, object_pairs_hook=_unique_keys, parse_constant=_no_constant)
    except RecursionError:
        raise ValueError(f"{what} is not an rlsfilt model file (JSON nested too deeply)") from None
    except ValueError as exc:       # JSONDecodeError, repeated keys, constants, huge integers
        raise ValueError(f"{what} is not a JSON file ({exc})") from None


# ----------------------------------------------------------------------
# reading: the schema
# ----------------------------------------------------------------------
def _got(value):
    """A short description of a JSON value for a message."""
    if isinstance(value, dict):
        keys = list(value)[:4]
        return f"an object with keys {keys}" if keys else "an empty object"
    if isinstance(value, list):
        return f"a list of {len(value)}"
    text = json.dumps(value) if not isinstance(value, float) or math.isfinite(value) \
        else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _fail(path, what, value):
    raise ValueError(f"`{path}` {what}; got {_got(value)}")


def _object(value, path, allowed, required=(), owner=None):
    """A JSON object whose keys are among `allowed` and include `required`."""
    if not isinstance(value, dict):
        _fail(path, "must be a JSON object", value)
    prefix = f"{path}." if path else ""
    for key in value:
        if key not in allowed:
            where = f" of {owner}" if owner else ""
            raise ValueError(f"`{prefix}{key}` is not a field{where} (a model file holds only "
                             f"declared fields: {sorted(allowed)})")
    for key in required:
        if key not in value:
            raise ValueError(f"`{prefix}{key}` is missing (a required field)")
    return value


def _tagged(value, path, tag, what):
    """The content of ``{tag: content}``, the only key allowed."""
    if not isinstance(value, dict) or list(value) != [tag]:
        _fail(path, f"must be {what} ({{\"{tag}\": ...}})", value)
    return value[tag]


def _int(value, path, minimum=None, maximum=None):
    if type(value) is not int:
        _fail(path, "must be an integer", value)
    if minimum is not None and value < minimum:
        _fail(path, f"must be >= {minimum}", value)
    # (a count or an order beyond 2^53 is no fit's: a double no longer holds it exactly)
    maximum = _MAX_INT if maximum is None else min(maximum, _MAX_INT)
    if value > maximum:
        _fail(path, f"must be <= {maximum}", value)
    return value


_MAX_INT = 2**53


def _number(value, path, minimum=None, positive=False):
    """A finite JSON number as a float."""
    if type(value) is int:
        if abs(value) > 2**1023:
            _fail(path, "must be a finite number", value)
        value = float(value)
    if type(value) is not float:
        _fail(path, "must be a finite number", value)
    if not math.isfinite(value):
        _fail(path, "must be a finite number", value)
    if minimum is not None and value < minimum:
        _fail(path, f"must be >= {minimum}", value)
    if positive and not value > 0:
        _fail(path, "must be > 0", value)
    return value


def _text(value, path, choices=None):
    if not isinstance(value, str):
        _fail(path, "must be a string", value)
    if choices is not None and value not in choices:
        _fail(path, f"must be one of {list(choices)}", value)
    return value


def _list(value, path, length=None):
    if not isinstance(value, list):
        _fail(path, "must be a list", value)
    if length is not None and len(value) != length:
        _fail(path, f"must have {length} entries", value)
    return value


def _texts(value, path, length):
    """A tuple of `length` strings (stored as ``{"__tuple__": [...]}`` or a list)."""
    items = value["__tuple__"] if isinstance(value, dict) and list(value) == ["__tuple__"] \
        else value
    if not isinstance(items, list):
        _fail(path, "must be a tuple of strings ({\"__tuple__\": [...]})", value)
    _list(items, path, length)
    return tuple(_text(v, f"{path}[{i}]") for i, v in enumerate(items))


def _dims(shape):
    return "(" + ", ".join("N" if d is None else str(d) for d in shape) + \
        ("," if len(shape) == 1 else "") + ")"


def _array(value, path, shapes, kind="f", allow_nan=False):
    """A stored float (or int) array whose shape is one of `shapes` (None: any length);
    with `allow_nan`, NaN entries (stored as ``"NaN"``) mark missing values."""
    spec = _tagged(value, path, "__ndarray__", "an array")
    _object(spec, f"{path}.__ndarray__", ("dtype", "shape", "data"),
            ("dtype", "shape", "data"))
    dtypes = ("<f8", ">f8") if kind == "f" else ("<i8", ">i8", "<i4", ">i4")
    _text(spec["dtype"], f"{path}.__ndarray__.dtype", dtypes)
    shape = _list(spec["shape"], f"{path}.__ndarray__.shape")
    shape = tuple(_int(d, f"{path}.__ndarray__.shape[{i}]", 0) for i, d in enumerate(shape))
    shapes = [shapes] if isinstance(shapes, tuple) else shapes
    if not any(len(s) == len(shape) and all(e is None or e == d for e, d in zip(s, shape))
               for s in shapes):
        raise ValueError(f"`{path}` must have shape {' or '.join(_dims(s) for s in shapes)}; "
                         f"got {_dims(shape)}")
    size = math.prod(shape)
    if size > _MAX_ELEMENTS:
        raise ValueError(f"`{path}` must have at most {_MAX_ELEMENTS} elements; got shape "
                         f"{_dims(shape)}")
    data = _list(spec["data"], f"{path}.__ndarray__.data")
    if len(data) != size:
        raise ValueError(f"`{path}.__ndarray__.data` must hold {size} numbers for shape "
                         f"{_dims(shape)}; got {len(data)}")
    if allow_nan:
        data = [math.nan if v == "NaN" else v for v in data]
    for i, v in enumerate(data):
        if type(v) is not float and (type(v) is not int or abs(v) > 2**53 and kind == "f"
                                     or abs(v) > 2**62):
            _fail(f"{path}[{i}]", "must be a finite number" if kind == "f" else
                  "must be an integer", v)
    if kind != "f":
        if any(type(v) is not int for v in data):
            i = next(i for i, v in enumerate(data) if type(v) is not int)
            _fail(f"{path}[{i}]", "must be an integer", data[i])
        return np.array(data, dtype=np.int64).reshape(shape)
    arr = np.array(data, dtype=float).reshape(shape)
    bad = np.isinf(arr) if allow_nan else ~np.isfinite(arr)
    if bad.any():
        i = int(np.flatnonzero(bad.ravel())[0])
        _fail(f"{path}[{i}]", "must be a finite number", data[i])
    return arr


def _matrix(value, path, rows, cols):
    """A nested list of `rows` lists of `cols` finite numbers (a `Trend`'s coefficients)."""
    _list(value, path, rows)
    return np.array([[_number(x, f"{path}[{i}][{j}]") for j, x in
                      enumerate(_list(row, f"{path}[{i}]", cols))]
                     for i, row in enumerate(value)], dtype=float).reshape(rows, cols)


def _stored_object(value, path, version, kind):
    """The field dict of a stored structure or trend: ``{"__dict__": {...}}``; in version 1
    ``{"__object__": "<fixed text>", "state": {"__dict__": {...}}}`` (the text compared,
    never imported)."""
    if version == 1:
        _object(value, path, ("__object__", "state"), ("__object__", "state"))
        if value["__object__"] != _V1_OBJECTS[kind]:
            _fail(f"{path}.__object__", f"must be {_V1_OBJECTS[kind]!r} (the only object a "
                  "version-1 file holds here; nothing is imported)", value["__object__"])
        value, path = value["state"], f"{path}.state"
    return _tagged(value, path, "__dict__", "an object")


def _orders(value, path, minimum, per_input):
    """A constructor order: an int, or for per-input orders a list/tuple/int array of them."""
    if type(value) is int:
        return _int(value, path, minimum)
    if not per_input:
        _fail(path, f"must be an integer >= {minimum}", value)
    if isinstance(value, list):
        return [_int(v, f"{path}[{i}]", minimum) for i, v in enumerate(value)]
    if isinstance(value, dict) and list(value) == ["__tuple__"]:
        items = _list(value["__tuple__"], f"{path}.__tuple__")
        return tuple(_int(v, f"{path}[{i}]", minimum) for i, v in enumerate(items))
    if isinstance(value, dict) and list(value) == ["__ndarray__"]:
        arr = _array(value, path, [(None,)], kind="i")
        if (arr < minimum).any():
            _fail(path, f"must hold integers >= {minimum}", value)
        return arr
    _fail(path, f"must be an integer >= {minimum} or a list of them (one per input)", value)


def _params(name, raw):
    """The constructor parameters of a `name` model, typed."""
    orders = _ORDERS[name]
    allowed = (*orders, "dt", "offset") if name == "ARX" else (*orders, "dt")
    _object(raw, "params", allowed, allowed, owner=f"{name}()")
    params = {k: _orders(raw[k], f"params.{k}", m, k in _PER_INPUT) for k, m in orders.items()}
    dt = raw["dt"]
    if dt is not True:
        if type(dt) not in (int, float):
            _fail("params.dt", "must be true (unspecified sampling period) or a positive "
                  "finite number", dt)
        _number(dt, "params.dt", positive=True)
    params["dt"] = dt
    if name == "ARX":
        if type(raw["offset"]) is not bool and raw["offset"] != "mean":
            _fail("params.offset", "must be false, true or \"mean\"", raw["offset"])
        params["offset"] = raw["offset"]
    return params


def _from_document(doc, cls=None, source="the document", classes=None):
    """The model described by a parsed model file (validated field by field)."""
    if not isinstance(doc, dict):
        raise ValueError(f"{source} is not an rlsfilt model file (the top level must be a JSON "
                         f"object; got {_got(doc)})")
    if doc.get("format") != FORMAT:
        raise ValueError(f"{source} is not an rlsfilt model file (no \"format\": "
                         f"\"{FORMAT}\" entry)")
    version = doc.get("format_version")
    if type(version) is not int or version not in _READABLE:
        raise ValueError(f"{source} has model format version {_got(version)}; this rlsfilt "
                         f"reads versions {_READABLE[0]} to {_READABLE[-1]}"
                         + (" (upgrade rlsfilt)" if type(version) is int and
                            version > FORMAT_VERSION else ""))
    try:
        return _build(doc, version, cls, classes)
    except ValueError as exc:
        if source is None:
            raise
        raise ValueError(f"{source}: {exc}") from None


def _build(doc, version, cls, classes):
    _object(doc, "", _TOP_V1 if version == 1 else _TOP, ("class", "params", "fitted"),
            owner="a model file")
    if "rlsfilt_version" in doc:
        _text(doc["rlsfilt_version"], "rlsfilt_version")
    if "module" in doc:
        _text(doc["module"], "module")                    # version 1: informative, unused
    if "omitted" in doc:
        for i, v in enumerate(_list(doc["omitted"], "omitted")):
            _text(v, f"omitted[{i}]")
    name = doc["class"]
    if not isinstance(name, str) or name not in MODEL_CLASSES:
        _fail("class", f"must be one of {list(MODEL_CLASSES)} (the classes a model file "
              "holds)", name)
    if cls is not None:
        if _file_name(cls) is None or classes is not None and cls not in classes.values():
            raise TypeError(f"`cls` must be one of the classes {list(MODEL_CLASSES)}; got "
                            f"{getattr(cls, '__name__', cls)!r}")
        if _file_name(cls) != name:
            raise ValueError(f"holds a {name} model; load it with {name}.load or "
                             f"load_model(path) (asked for {cls.__name__!r})")
        klass = cls
    else:
        klass = classes[name]
    params = _params(name, doc["params"])
    model = klass(**params)                               # __init__ only stores them
    if name == "ARX":
        fitted, derived = _arx_fitted(model, doc["fitted"], version)
    else:
        fitted, derived = _family_fitted(model, name, doc["fitted"], version)
    model._restore_fitted(fitted)
    for key, value in derived.items():                    # the polynomials theta_ holds
        mine = getattr(model, key)
        same = (len(mine) == len(value) and all(np.array_equal(a, b) for a, b in
                                                zip(mine, value))) \
            if isinstance(value, list) and isinstance(mine, list) else \
            (not isinstance(value, list) and not isinstance(mine, list)
             and np.array_equal(mine, value))
        if not same:
            raise ValueError(f"`fitted.{key}` must equal the coefficients `fitted.theta_` "
                             f"holds for the structure in `params`")
    if "trend_" in fitted:
        try:
            _check_trend(fitted["trend_"], model)
        except ValueError as exc:
            raise ValueError(f"`fitted.trend_` does not fit the model: {exc}") from None
    return model


def _check_method_fields(raw, only, method):
    for key, methods in only.items():
        if key in raw and method not in methods:
            raise ValueError(f"`fitted.{key}` is only set by fit(..., method="
                             f"{' or '.join(repr(m) for m in methods)}); the model was fitted "
                             f"with method {method!r}")


def _check_structure(stored, expected, names, path="fitted.structure_"):
    """The stored structure fields equal `expected` (the orders `params` give)."""
    _object(stored, path, tuple(expected), tuple(expected))
    for key, want in expected.items():
        got = stored[key]
        if isinstance(want, list):
            ok = isinstance(got, list) and len(got) == len(want) and \
                all(type(g) is int and g == w for g, w in zip(got, want))
        else:
            ok = type(got) is int and got == want
        if not ok:
            if key in names:
                raise ValueError(f"`params.{key}` and `{path}.{key}` disagree: the orders in "
                                 f"`params` give {want} for this number of signals; the fit "
                                 f"stored {_got(got)}")
            if key in ("n_inputs", "n_outputs"):
                raise ValueError(f"`{path}.{key}` and `fitted.{key}_` disagree: {_got(got)} "
                                 f"and {want}")
            _fail(f"{path}.{key}", f"must be {want} (from `params` and the number of "
                  "signals)", got)


def _structure_from_params(make, path):
    try:
        return make()
    except (TypeError, ValueError) as exc:
        raise ValueError(f"`{path}` do not describe a valid structure for the stored signals: "
                         f"{exc}") from None


def _signals_info(raw, nu, ny):
    names = {"input_names_": _texts(raw["input_names_"], "fitted.input_names_", nu),
             "output_names_": _texts(raw["output_names_"], "fitted.output_names_", ny)}
    for key, n in (("input_units_", nu), ("output_units_", ny)):
        if key in raw:
            names[key] = _texts(raw[key], f"fitted.{key}", n)
    return names


def _common(raw, out, n_params, per_output, ny, y_1d):
    """Covariance, noise variance, counts and per-sample arrays shared by every class."""
    # (a gradient fit has no covariance: NaN)
    out["theta_cov_"] = _array(raw["theta_cov_"], "fitted.theta_cov_",
                               (n_params, n_params) if y_1d else (ny, n_params, n_params),
                               allow_nan=out.get("method_") in ("nlms", "lms"))
    cov = out["theta_cov_"]
    diag = np.diagonal(cov, axis1=-2, axis2=-1)
    if (diag < 0).any():
        raise ValueError("`fitted.theta_cov_` must have a non-negative diagonal (variances); "
                         f"got {float(diag.min())}")
    # every fit stores a symmetric covariance (to the last bit; round-off allowed)
    with np.errstate(invalid="ignore"):
        skew = np.abs(cov - np.swapaxes(cov, -1, -2))
        if (skew > 4 * np.finfo(float).eps * np.abs(cov)).any():
            raise ValueError("`fitted.theta_cov_` must be symmetric (a covariance); got entries "
                             f"that differ from their transposes by up to {np.nanmax(skew):.3g}")
    if y_1d:
        out["noise_variance_"] = _number(raw["noise_variance_"], "fitted.noise_variance_", 0.0)
    else:
        out["noise_variance_"] = _array(raw["noise_variance_"], "fitted.noise_variance_", (ny,))
        if (out["noise_variance_"] < 0).any():
            raise ValueError("`fitted.noise_variance_` must be >= 0")
    out["n_samples_"] = _int(raw["n_samples_"], "fitted.n_samples_", 0)
    if "n_experiments_" in raw:
        out["n_experiments_"] = _int(raw["n_experiments_"], "fitted.n_experiments_", 0)
    n = out["n_samples_"]
    if "residuals_" in raw:
        out["residuals_"] = _array(raw["residuals_"], "fitted.residuals_",
                                   (n,) if y_1d else (n, ny))
    rows = None
    if "theta_history_" in raw:
        # NaN rows: samples before the batch start (no estimate yet)
        out["theta_history_"] = _array(raw["theta_history_"], "fitted.theta_history_",
                                       (None, per_output) if y_1d else (None, per_output, ny),
                                       allow_nan=True)
        rows = out["theta_history_"].shape[0]
    if "recursive_residuals_" in raw:
        out["recursive_residuals_"] = _array(raw["recursive_residuals_"],
                                             "fitted.recursive_residuals_",
                                             (rows,) if y_1d else (rows, ny), allow_nan=True)


def _arx_fitted(model, raw, version):
    """The learned attributes of an ARX file, typed and checked against ``params``."""
    _object(raw, "fitted", _ARX_FITTED, _ARX_REQUIRED, owner="a fitted ARX")
    method = _text(raw["method_"], "fitted.method_",
                   ("ls", "rls", "iv", "riv", "nlms", "lms", "true"))
    _check_method_fields(raw, _ARX_ONLY, method)
    nu = _int(raw["n_inputs_"], "fitted.n_inputs_", 1)
    ny = _int(raw["n_outputs_"], "fitted.n_outputs_", 1)
    s = _structure_from_params(lambda: model._structure(nu, ny), "params")
    _check_structure(_stored_object(raw["structure_"], "fitted.structure_", version,
                                    "ARXStructure"), s.to_dict(), ("na", "nb", "nk"))
    intercept = model.offset is True          # `params.offset` is False, True or "mean"
    n_params = _int(raw["n_params_"], "fitted.n_params_")
    if n_params != s.n_params + intercept:
        _fail("fitted.n_params_", f"must be {s.n_params + intercept} (the orders in `params` "
              f"and `params.offset` = {model.offset!r})", n_params)
    theta = _array(raw["theta_"], "fitted.theta_",
                   [(n_params,), (n_params, 1)] if ny == 1 else [(n_params, ny)])
    if ny == 1 and theta.ndim == 2:
        raise ValueError("`fitted.theta_` of one output must have shape "
                         f"({n_params},); got {_dims(theta.shape)}")
    y_1d = theta.ndim == 1
    out = {"structure_": s, "n_params_": n_params, "n_inputs_": nu, "n_outputs_": ny,
           "theta_": theta, "method_": method}
    out.update(_signals_info(raw, nu, ny))
    # the polynomials: compared with those theta_ holds once the model is built
    a_shape = (s.na,) if y_1d else (ny, ny, s.na)
    derived = {"a_": _array(raw["a_"], "fitted.a_", a_shape)}
    b_raw = raw["b_"]
    if isinstance(b_raw, list):
        _list(b_raw, "fitted.b_", nu)
        derived["b_"] = [_array(b, f"fitted.b_[{j}]", (nb,) if y_1d else (ny, nb))
                         for j, (b, nb) in enumerate(zip(b_raw, s.nb))]
    else:
        if nu != 1:
            _fail("fitted.b_", f"must be a list of {nu} arrays (one per input)", b_raw)
        derived["b_"] = _array(b_raw, "fitted.b_", (s.nb[0],) if y_1d else (ny, s.nb[0]))
    out["b_"] = derived["b_"]
    if intercept:
        if "intercept_" not in raw:
            raise ValueError("`fitted.intercept_` is missing (a model with offset=True has one)")
        value = _number(raw["intercept_"], "fitted.intercept_") if y_1d else \
            _array(raw["intercept_"], "fitted.intercept_", (ny,))
        if not np.array_equal(value, theta[-1]):
            raise ValueError("`fitted.intercept_` must equal the last row of `fitted.theta_` "
                             "(the intercept of offset=True)")
        out["intercept_"] = value
    elif "intercept_" in raw:
        raise ValueError(f"`fitted.intercept_` is only set with offset=True; `params.offset` is "
                         f"{model.offset!r}")
    out["input_offset_"] = _array(raw["input_offset_"], "fitted.input_offset_", (nu,))
    out["output_offset_"] = _array(raw["output_offset_"], "fitted.output_offset_", (ny,))
    if model.offset is False and (out["input_offset_"].any() or out["output_offset_"].any()):
        raise ValueError("`fitted.input_offset_` and `fitted.output_offset_` must be zero "
                         "with offset=False (`params.offset`)")
    _common(raw, out, n_params, n_params, ny, y_1d)
    if "noise_covariance_" in raw:
        if y_1d:
            raise ValueError("`fitted.noise_covariance_` is only set by a fit on 2-D `y` "
                             "(several outputs)")
        out["noise_covariance_"] = _array(raw["noise_covariance_"], "fitted.noise_covariance_",
                                          (ny, ny))
    if "k0_" in raw:
        out["k0_"] = _int(raw["k0_"], "fitted.k0_", 0)
    if "lam_" in raw:
        if isinstance(raw["lam_"], dict):        # one factor per parameter (diagonal)
            out["lam_"] = _array(raw["lam_"], "fitted.lam_", (n_params,))
            bad = ~((out["lam_"] > 0.0) & (out["lam_"] <= 1.0))
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                _fail(f"fitted.lam_[{i}]", "must be in (0, 1]", float(out["lam_"][i]))
        else:
            out["lam_"] = _number(raw["lam_"], "fitted.lam_", positive=True)
            if out["lam_"] > 1.0:
                _fail("fitted.lam_", "must be in (0, 1]", raw["lam_"])
    if "form_" in raw:
        out["form_"] = _text(raw["form_"], "fitted.form_",
                             ("covariance", "square_root", "window"))
    if "instruments_" in raw:
        out["instruments_"] = _array(raw["instruments_"], "fitted.instruments_",
                                     (out["n_samples_"], n_params))
    if "trend_" in raw:
        out["trend_"] = _trend(raw["trend_"], "fitted.trend_", version)
    return out, derived


def _family_fitted(model, name, raw, version):
    """The learned attributes of an ARMAX/OE/BJ/AR/ARMA file, typed and checked."""
    _object(raw, "fitted", _FAMILY_FITTED, _FAMILY_REQUIRED, owner=f"a fitted {name}")
    method = _text(raw["method_"], "fitted.method_", ("pem", "rpem", "rplr"))
    _check_method_fields(raw, _FAMILY_ONLY, method)
    series = name in ("AR", "ARMA")
    nu = _int(raw["n_inputs_"], "fitted.n_inputs_", 0, 0 if series else None)
    if not series and nu < 1:
        _fail("fitted.n_inputs_", f"must be >= 1 for {name}", nu)
    _int(raw["n_outputs_"], "fitted.n_outputs_", 1, 1)
    s = _structure_from_params(lambda: model._family(nu), "params")
    _check_structure(_stored_object(raw["structure_"], "fitted.structure_", version,
                                    "FamilyStructure"), s.to_dict(), tuple(_ORDERS[name]))
    n_params = _int(raw["n_params_"], "fitted.n_params_")
    if n_params != s.n_params:
        _fail("fitted.n_params_", f"must be {s.n_params} (the orders in `params`)", n_params)
    out = {"method_": method, "structure_": s, "n_params_": n_params, "n_inputs_": nu,
           "n_outputs_": 1, "theta_": _array(raw["theta_"], "fitted.theta_", (n_params,))}
    out.update(_signals_info(raw, nu, 1))
    derived = {key: _array(raw[key], f"fitted.{key}", (n,))
               for key, n in (("a_", s.na), ("c_", s.nc), ("d_", s.nd))}
    for key, sizes in (("b_", s.nb), ("f_", s.nf)):
        value = raw[key]
        if isinstance(value, list):
            _list(value, f"fitted.{key}", nu)
            derived[key] = [_array(v, f"fitted.{key}[{j}]", (n,))
                            for j, (v, n) in enumerate(zip(value, sizes))]
        elif nu == 1:
            derived[key] = _array(value, f"fitted.{key}", (sizes[0],))
        else:
            _fail(f"fitted.{key}", f"must be a list of {nu} arrays (one per input)", value)
    if isinstance(derived["b_"], list) != isinstance(derived["f_"], list):
        raise ValueError("`fitted.b_` and `fitted.f_` must both be lists (several inputs, or "
                         "2-D `u`) or both arrays (one input given as 1-D `u`)")
    out["b_"] = derived["b_"]
    _common(raw, out, n_params, n_params, 1, True)
    if "fit_info_" in raw:
        out["fit_info_"] = _fit_info(raw["fit_info_"], n_params)
    if "margins_" in raw:
        out["margins_"] = _margins(raw["margins_"])
    if "trend_" in raw:
        out["trend_"] = _trend(raw["trend_"], "fitted.trend_", version)
    return out, derived


#: What `fit_info_` of a prediction-error fit holds (the fields after ``theta0`` came with
#: #28; files without them load).
_FIT_INFO = ("cost", "n_fev", "n_jev", "status", "message", "theta0", "n_iter", "converged",
             "start", "start_costs", "n_starts", "max_root", "arx_cost", "warnings")


def _fit_info(value, n_params):
    path = "fitted.fit_info_"
    d = _object(_tagged(value, path, "__dict__", "an object"), path, _FIT_INFO,
                ("cost", "n_fev", "n_jev", "status", "message", "theta0"))
    theta0 = d["theta0"]
    out = {"cost": _number(d["cost"], f"{path}.cost", 0.0),
           "n_fev": _int(d["n_fev"], f"{path}.n_fev", 0),
           "n_jev": _int(d["n_jev"], f"{path}.n_jev", 0),
           "status": _int(d["status"], f"{path}.status", -10, 10),
           "message": _text(d["message"], f"{path}.message"),
           "theta0": None if theta0 is None else _array(theta0, f"{path}.theta0",
                                                        (n_params,))}
    for key in ("n_iter", "n_starts"):
        if key in d:
            out[key] = _int(d[key], f"{path}.{key}", 0)
    if "converged" in d:
        if type(d["converged"]) is not bool:
            _fail(f"{path}.converged", "must be true or false", d["converged"])
        out["converged"] = d["converged"]
    if "start" in d:
        out["start"] = _text(d["start"], f"{path}.start")
    if "max_root" in d:
        out["max_root"] = _number(d["max_root"], f"{path}.max_root", 0.0)
    if "arx_cost" in d:
        out["arx_cost"] = (None if d["arx_cost"] is None
                           else _number(d["arx_cost"], f"{path}.arx_cost", 0.0))
    if "start_costs" in d:
        costs = _tagged(d["start_costs"], f"{path}.start_costs", "__dict__", "an object")
        out["start_costs"] = {_text(k, f"{path}.start_costs"): _number(
            v, f"{path}.start_costs.{k}", 0.0) for k, v in costs.items()}
    if "warnings" in d:
        out["warnings"] = [_text(w, f"{path}.warnings[{i}]")
                           for i, w in enumerate(_list(d["warnings"], f"{path}.warnings"))]
    return out


def _margins(value):
    path = "fitted.margins_"
    d = _tagged(value, path, "__dict__", "an object")
    out = {}
    for key, pair in d.items():
        if len(key) > 40:
            _fail(path, "must name filters such as '1/C' (keys of at most 40 characters)", key)
        items = _list(_tagged(pair, f"{path}.{key}", "__tuple__", "a pair"), f"{path}.{key}", 2)
        out[key] = (_number(items[0], f"{path}.{key}[0]"),
                    _number(items[1], f"{path}.{key}[1]", 0.0))
    return out


def _trend(value, path, version):
    """A stored `Trend` (its fields typed, shapes consistent, numbers finite)."""
    from .data.trend import Trend

    keys = ("type", "breakpoints", "intercept", "slope", "n_inputs", "n_outputs", "one_d",
            "lengths")
    d = _object(_stored_object(value, path, version, "Trend"), path, keys, keys, owner="a Trend")
    kind = _text(d["type"], f"{path}.type", ("constant", "linear"))
    bps = _list(d["breakpoints"], f"{path}.breakpoints")
    if not bps:
        _fail(f"{path}.breakpoints", "must hold one list per experiment", bps)
    for e, bp in enumerate(bps):
        _list(bp, f"{path}.breakpoints[{e}]")
        for i, b in enumerate(bp):
            _int(b, f"{path}.breakpoints[{e}][{i}]", 0)
        if not bp or bp[0] != 0 or any(b <= a for a, b in zip(bp, bp[1:])):
            _fail(f"{path}.breakpoints[{e}]", "must start at 0 and increase", bp)
    n_in, n_out = d["n_inputs"], d["n_outputs"]
    if (n_in is None) != (n_out is None):
        raise ValueError(f"`{path}.n_inputs` and `{path}.n_outputs` must both be integers (the "
                         "trend of an IOData) or both null (of an array)")
    if n_in is not None:
        _int(n_in, f"{path}.n_inputs", 0)
        _int(n_out, f"{path}.n_outputs", 1)
    first = _list(d["intercept"], f"{path}.intercept", len(bps))[0]
    cols = len(_list(first, f"{path}.intercept[0]")[0]) if first and \
        isinstance(first[0], list) else 0
    if n_in is not None and cols != n_in + n_out:
        raise ValueError(f"`{path}.intercept` must have n_inputs + n_outputs = "
                         f"{n_in + n_out} columns; got {cols}")
    if cols < 1:
        _fail(f"{path}.intercept", "must hold at least one column", d["intercept"])
    intercept, slope = [], []
    _list(d["slope"], f"{path}.slope", len(bps))
    for e, bp in enumerate(bps):
        intercept.append(_matrix(d["intercept"][e], f"{path}.intercept[{e}]", len(bp), cols))
        slope.append(_matrix(d["slope"][e], f"{path}.slope[{e}]", len(bp), cols))
        if kind == "constant" and slope[-1].any():
            raise ValueError(f"`{path}.slope[{e}]` must be zero for a constant trend")
    one_d = d["one_d"]
    if type(one_d) is not bool:
        _fail(f"{path}.one_d", "must be true or false", one_d)
    lengths = d["lengths"]
    if lengths is not None:
        _list(lengths, f"{path}.lengths", len(bps))
        for e, (n, bp) in enumerate(zip(lengths, bps)):
            _int(n, f"{path}.lengths[{e}]", bp[-1] + 1)
    return Trend(kind, bps, intercept, slope, n_in, n_out, one_d, lengths)
