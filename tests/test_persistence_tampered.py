"""Tampered model files (issue #27 item 1): loading never runs anything.

A model file is read against a declared schema. Every field removed, of a wrong type,
unknown, too large, not finite, of the wrong shape, naming a foreign class or holding a
stored object gives a ValueError that names the field by its JSON path; loading a crafted
file imports no module and opens no socket (checked in a fresh process with an audit
hook); every class of the closed set round-trips to equal predictions; the files of
format version 1 kept in tests/data/model_files_v1 still load.
"""

import copy
import glob
import json
import os
import re
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import AR, ARMA, ARMAX, ARX, BJ, OE, IOData, detrend, load_model
from rlsfilt._model_file import _document, _dumps
from rlsfilt.persistence import MODEL_CLASSES

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
V1_FILES = sorted(glob.glob(os.path.join(ROOT, "tests", "data", "model_files_v1", "*.json")))


def _data(n=300, seed=27):
    rng = np.random.default_rng(seed)
    U = rng.standard_normal((n, 2))
    y = (lfilter([0, 1.0, 0.5], [1, -0.5], U[:, 0]) + lfilter([0, 0.3], [1, -0.2], U[:, 1])
         + 0.1 * rng.standard_normal(n))
    Y2 = np.column_stack([y, lfilter([0, 1], [1, -0.3], U[:, 1]) + 0.1 * rng.standard_normal(n)])
    return U, y, Y2


U, Y, Y2 = _data()


def _fit(make, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return make().fit(*args, **kw)


# every class of the closed set, SISO and MISO where the class has inputs, and each method
MODELS = {
    "ARX-siso": (lambda: _fit(lambda: ARX(2, 2, 1, dt=0.5), U[:, 0], Y), (U[:, 0], Y)),
    "ARX-miso-offset": (lambda: _fit(lambda: ARX(2, [2, 1], [1, 0], offset=True), U, Y + 3),
                        (U, Y + 3)),
    "ARX-mimo": (lambda: _fit(lambda: ARX(1, [1, 2], [1, 0]), U, Y2), (U, Y2)),
    "ARX-mean": (lambda: _fit(lambda: ARX(1, 2, 1, offset="mean"), U[:, 0], Y + 3),
                 (U[:, 0], Y + 3)),
    "ARX-rls": (lambda: _fit(lambda: ARX(2, 2, 1), U[:, 0], Y, method="rls", lam=0.99),
                (U[:, 0], Y)),
    "ARX-iv": (lambda: _fit(lambda: ARX(2, 2, 1), U[:, 0], Y, method="iv"), (U[:, 0], Y)),
    "ARX-riv-miso": (lambda: _fit(lambda: ARX(1, [1, 1]), U, Y, method="riv"), (U, Y)),
    "ARX-true": (lambda: ARX.from_polynomials([-0.5], [1.0, 0.5], dt=0.1), (U[:, 0], Y)),
    "ARMAX-siso": (lambda: _fit(lambda: ARMAX(2, 2, 1), U[:, 0], Y), (U[:, 0], Y)),
    "ARMAX-miso-rplr": (lambda: _fit(lambda: ARMAX(1, [1, 1], 1, [1, 0]), U, Y,
                                     method="rplr"), (U, Y)),
    "OE-siso": (lambda: _fit(lambda: OE(1, 2, 1), U[:, 0], Y), (U[:, 0], Y)),
    "OE-miso-rpem": (lambda: _fit(lambda: OE([1, 1], [1, 1], [1, 1]), U, Y, method="rpem"),
                     (U, Y)),
    "BJ-siso": (lambda: _fit(lambda: BJ(1, 1, 1, 1, 1), U[:, 0], Y), (U[:, 0], Y)),
    "BJ-miso": (lambda: _fit(lambda: BJ([1, 1], 1, 1, [1, 1], [1, 1]), U, Y), (U, Y)),
    "AR": (lambda: _fit(lambda: AR(2), Y), (None, Y)),
    "ARMA-rpem": (lambda: _fit(lambda: ARMA(1, 1), Y, method="rpem"), (None, Y)),
}
_CACHE = {}


def _model(key):
    if key not in _CACHE:
        _CACHE[key] = MODELS[key][0]()
    return _CACHE[key]


def _doc(key, include_data=False, trend=None):
    """The parsed document save() writes for a model (a fresh copy to tamper with)."""
    return json.loads(_dumps(_document(_model(key), include_data=include_data, trend=trend)))


def _trend_doc():
    data_d, trend = detrend(IOData(U[:, 0] + 40, Y + 97, dt=0.5), type="linear")
    _CACHE.setdefault("ARX-trend", ARX(2, 2, 1, dt=0.5).fit(data_d))
    return json.loads(_dumps(_document(_CACHE["ARX-trend"], trend=trend)))


def _read(path):
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def _load(tmp_path, doc, raw=None):
    path = tmp_path / "m.json"
    path.write_text(raw if raw is not None else json.dumps(doc))
    return load_model(path)


def _names(message, field):
    """Whether `message` names `field` in backticks (the field itself or a path inside it)."""
    return re.search("`" + re.escape(field) + r"(`|\.|\[)", message) is not None


def _refused(tmp_path, doc, field, raw=None):
    with pytest.raises(ValueError) as info:
        _load(tmp_path, doc, raw)
    assert _names(str(info.value), field), f"the message does not name `{field}`: {info.value}"
    return str(info.value)


# ----------------------------------------------------------------------
# every class round-trips to equal predictions
# ----------------------------------------------------------------------
@pytest.mark.parametrize("key", list(MODELS))
def test_every_class_round_trips(key, tmp_path):
    model = _model(key)
    u, y = MODELS[key][1]
    for include_data in (False, True):
        model.save(tmp_path / "m.json", include_data=include_data)
        back = load_model(tmp_path / "m.json")
        assert type(back) is type(model) and type(back).__name__ in MODEL_CLASSES
        assert type(model).load(tmp_path / "m.json").get_params() == model.get_params()
        assert back.theta_.tobytes() == model.theta_.tobytes()
        assert back.param_names_ == model.param_names_
        np.testing.assert_array_equal(back.predict(u, y, horizon=2), model.predict(u, y, horizon=2))
        if u is not None:
            np.testing.assert_array_equal(back.simulate(u), model.simulate(u))
        assert str(back.summary()) == str(model.summary())


@pytest.mark.parametrize("path", V1_FILES, ids=[os.path.basename(p) for p in V1_FILES])
def test_version_1_files_still_load(path, tmp_path):
    """Files of the previous format (stored objects by module path, matched as text)."""
    doc = _read(path)
    assert doc["format_version"] == 1
    model = load_model(path)
    assert type(model).__name__ == doc["class"]
    np.testing.assert_array_equal(model.theta_.ravel(),
                                  doc["fitted"]["theta_"]["__ndarray__"]["data"])
    model.save(tmp_path / "v2.json", include_data=True)
    again = load_model(tmp_path / "v2.json")
    assert json.loads((tmp_path / "v2.json").read_text())["format_version"] == 2
    nu = model.n_inputs_
    u = None if nu == 0 else np.ones((50, nu)) if isinstance(model.b_, list) else np.ones(50)
    y = np.sin(np.arange(50.0)) if model.n_outputs_ == 1 else np.ones((50, model.n_outputs_))
    np.testing.assert_array_equal(again.predict(u, y), model.predict(u, y))
    if "trend_" in doc["fitted"]:
        np.testing.assert_array_equal(again.trend_.slope[0], model.trend_.slope[0])


def test_version_1_objects_are_matched_not_imported(tmp_path):
    doc = _read(V1_FILES[0])
    doc["fitted"]["structure_"]["__object__"] = "rlsfilt.dask:Client"
    msg = _refused(tmp_path, doc, "fitted.structure_.__object__")
    assert "nothing is imported" in msg
    doc = _read(V1_FILES[0])
    doc["module"] = "ftplib"                       # informative in version 1, never used
    assert type(_load(tmp_path, doc)).__name__ == doc["class"]


# ----------------------------------------------------------------------
# tampered files: each refused with a message naming the field
# ----------------------------------------------------------------------
BASES = ["ARX-siso", "ARX-miso-offset", "ARX-mimo", "ARX-rls", "ARX-riv-miso",
         "ARMAX-miso-rplr", "OE-siso", "BJ-miso", "AR", "ARMA-rpem"]
OPTIONAL = {"input_units_", "output_units_", "noise_covariance_", "k0_", "lam_", "form_",
            "instruments_", "theta_history_", "recursive_residuals_", "residuals_", "trend_",
            "fit_info_", "margins_"}
WRONG = [None, "text", {"__object__": "os:system", "state": {"__dict__": {}}}, [[]],
         {"__dict__": {"x": 1}}, {"__ndarray__": {"dtype": "|O", "shape": [1], "data": ["x"]}},
         -1, 1e300, True]


def _valid_replacement(section, key, value):
    """Replacements that are valid for a field (so not tampering)."""
    return (section == "params" and key in ("dt", "offset") and value is True
            or section == "params" and key == "dt" and value == 1e300
            or section == "fitted" and key in ("noise_variance_", "intercept_")
            and value == 1e300)


@pytest.mark.parametrize("key", BASES)
def test_every_field_removed_or_mistyped(key, tmp_path):
    base = _doc(key, include_data=True)
    for section in ("params", "fitted"):
        for field in list(base[section]):
            doc = copy.deepcopy(base)
            del doc[section][field]
            if section == "fitted" and field in OPTIONAL:
                _load(tmp_path, doc)                 # an optional field may be left out
            elif section == "fitted" and field == "intercept_":
                _refused(tmp_path, doc, "fitted.intercept_")
            else:
                msg = _refused(tmp_path, doc, f"{section}.{field}")
                assert "missing" in msg
            for value in WRONG:
                if _valid_replacement(section, field, value):
                    continue
                doc = copy.deepcopy(base)
                doc[section][field] = value
                _refused(tmp_path, doc, f"{section}.{field}")


def test_extra_keys_and_shadowing_names(tmp_path):
    base = _doc("ARX-miso-offset")
    for section, name in [(None, "extra"), ("params", "extra"), ("params", "lam"),
                          ("fitted", "extra_"), ("fitted", "predict"), ("fitted", "summary"),
                          ("fitted", "__class__"), ("fitted", "__dict__"), ("fitted", "_info"),
                          ("fitted", "param_names_"), ("fitted", "std_errors_"),
                          ("fitted", "filter_"), ("fitted", "state_")]:
        doc = copy.deepcopy(base)
        (doc if section is None else doc[section])[name] = 1
        field = name if section is None else f"{section}.{name}"
        msg = _refused(tmp_path, doc, field)
        assert "is not a field" in msg
    doc = copy.deepcopy(base)
    doc["fitted"]["theta_"]["__ndarray__"]["extra"] = 1
    _refused(tmp_path, doc, "fitted.theta_.__ndarray__.extra")
    doc = copy.deepcopy(base)
    doc["fitted"]["structure_"]["__dict__"]["extra"] = 1
    _refused(tmp_path, doc, "fitted.structure_.extra")
    doc = _trend_doc()
    doc["fitted"]["trend_"]["__dict__"]["extra"] = 1
    _refused(tmp_path, doc, "fitted.trend_.extra")


def test_huge_arrays(tmp_path):
    base = _doc("ARX-siso")
    doc = copy.deepcopy(base)
    doc["fitted"]["theta_"]["__ndarray__"]["shape"] = [10**9]
    _refused(tmp_path, doc, "fitted.theta_")
    doc = copy.deepcopy(base)
    doc["fitted"]["theta_"]["__ndarray__"].update(shape=[10**5], data=[0.5] * 10**5)
    assert "must have shape (4,)" in _refused(tmp_path, doc, "fitted.theta_")
    doc = _doc("ARX-rls", include_data=True)
    doc["fitted"]["theta_history_"]["__ndarray__"]["shape"] = [10**12, 4]
    assert "at most" in _refused(tmp_path, doc, "fitted.theta_history_")
    doc = copy.deepcopy(base)
    doc["params"]["na"] = 10**6
    _refused(tmp_path, doc, "params.na")
    doc = copy.deepcopy(base)
    doc["params"]["na"] = 10**400                              # beyond a float
    _refused(tmp_path, doc, "params.na")
    with pytest.raises(ValueError, match="not an rlsfilt model file|not a JSON file"):
        _load(tmp_path, None, raw="[" * 100000 + "]" * 100000)


@pytest.mark.parametrize("bad", ["NaN", "Infinity", "-Infinity", 1e999, -1e999])
def test_non_finite_numbers(bad, tmp_path):
    cases = [("ARX-siso", ["fitted", "theta_", "__ndarray__", "data", 1], "fitted.theta_"),
             ("ARX-siso", ["fitted", "theta_cov_", "__ndarray__", "data", 0],
              "fitted.theta_cov_"),
             ("ARX-siso", ["fitted", "noise_variance_"], "fitted.noise_variance_"),
             ("ARX-siso", ["fitted", "input_offset_", "__ndarray__", "data", 0],
              "fitted.input_offset_"),
             ("ARX-siso", ["params", "dt"], "params.dt"),
             ("ARX-mimo", ["fitted", "noise_covariance_", "__ndarray__", "data", 3],
              "fitted.noise_covariance_"),
             ("ARMAX-miso-rplr", ["fitted", "margins_", "__dict__", "1/C", "__tuple__", 0],
              "fitted.margins_"),
             ("OE-siso", ["fitted", "fit_info_", "__dict__", "cost"], "fitted.fit_info_"),
             ("trend", ["fitted", "trend_", "__dict__", "intercept", 0, 0, 1],
              "fitted.trend_")]
    for key, where, field in cases:
        doc = _trend_doc() if key == "trend" else _doc(key)
        node = doc
        for step in where[:-1]:
            node = node[step]
        node[where[-1]] = bad if isinstance(bad, str) else "@BIG@"
        raw = json.dumps(doc).replace('"@BIG@"', "-1e999" if bad == -1e999 else "1e999")
        _refused(tmp_path, doc, field, raw=raw)            # 1e999 parses to inf
    # NaN and Infinity literals are not JSON: the file is refused before any field is read
    raw = json.dumps(_doc("ARX-siso")).replace('"noise_variance_": ',
                                               '"noise_variance_": NaN, "x": ')
    with pytest.raises(ValueError, match="is not a JSON file"):
        _load(tmp_path, None, raw=raw)


def test_wrong_shapes_and_inconsistent_fits(tmp_path):
    base = _doc("ARX-miso-offset")

    def tamper(path, value, field, doc=None, match=None):
        doc = copy.deepcopy(base if doc is None else doc)
        node = doc
        for step in path[:-1]:
            node = node[step]
        node[path[-1]] = value
        msg = _refused(tmp_path, doc, field)
        if match:
            assert re.search(match, msg), msg

    theta = base["fitted"]["theta_"]["__ndarray__"]
    tamper(["fitted", "theta_", "__ndarray__"], {**theta, "shape": [6], "data": theta["data"]
                                                 + [0.1]}, "fitted.theta_", match="shape")
    tamper(["fitted", "theta_", "__ndarray__", "shape"], [2, 3], "fitted.theta_")
    tamper(["fitted", "theta_", "__ndarray__", "data"], theta["data"][:-1], "fitted.theta_")
    tamper(["fitted", "theta_", "__ndarray__", "dtype"], "<c16", "fitted.theta_")
    tamper(["fitted", "theta_", "__ndarray__", "data", 0], {"__dict__": {}}, "fitted.theta_")
    tamper(["fitted", "theta_", "__ndarray__", "data", 0], [0.5], "fitted.theta_")
    tamper(["fitted", "theta_cov_", "__ndarray__", "shape"], [25], "fitted.theta_cov_")
    tamper(["fitted", "a_", "__ndarray__", "data", 0], 0.123, "fitted.a_", match="must equal")
    tamper(["fitted", "b_", 1, "__ndarray__", "data", 0], 0.123, "fitted.b_")
    tamper(["fitted", "b_"], base["fitted"]["b_"][:1], "fitted.b_")
    tamper(["fitted", "intercept_"], 0.123, "fitted.intercept_", match="last row")
    tamper(["fitted", "input_names_", "__tuple__"], ["u1"], "fitted.input_names_")
    tamper(["fitted", "input_names_", "__tuple__", 0], {"__tuple__": []}, "fitted.input_names_")
    tamper(["fitted", "n_params_"], 4, "fitted.n_params_")
    tamper(["fitted", "n_inputs_"], 3, "params")
    tamper(["fitted", "n_outputs_"], 2, "fitted.n_outputs_", match="disagree")
    tamper(["fitted", "structure_", "__dict__", "nb"], [2, 2], "params.nb", match="disagree")
    tamper(["fitted", "structure_", "__dict__", "n_outputs"], 2, "fitted.structure_.n_outputs")
    tamper(["params", "na"], 3, "params.na", match="disagree")
    tamper(["params", "nb"], [2, 1, 1], "params")
    tamper(["params", "nk"], [-1, 0], "params.nk")
    tamper(["params", "offset"], False, "params.offset", match="fitted.n_params_")
    tamper(["params", "offset"], 1, "params.offset")
    tamper(["params", "dt"], 0, "params.dt")
    tamper(["params", "dt"], False, "params.dt")
    tamper(["fitted", "method_"], "pem", "fitted.method_")
    tamper(["fitted", "n_samples_"], 1.5, "fitted.n_samples_")
    tamper(["fitted", "theta_cov_", "__ndarray__", "data", 0], -1.0, "fitted.theta_cov_",
           match="non-negative diagonal")
    # a field a fit of another method sets
    tamper(["fitted", "lam_"], 0.99, "fitted.lam_", match="only set by")
    tamper(["fitted", "k0_"], 3, "fitted.k0_", match="only set by")
    rls = _doc("ARX-rls")
    tamper(["fitted", "lam_"], 1.5, "fitted.lam_", doc=rls)
    tamper(["fitted", "form_"], "magic", "fitted.form_", doc=rls)
    zero = _doc("ARX-siso")
    tamper(["fitted", "output_offset_", "__ndarray__", "data", 0], 1.0, "fitted.input_offset_",
           doc=zero, match="must be zero with offset=False")
    # the family: structure and polynomials
    fam = _doc("ARMAX-miso-rplr")
    tamper(["fitted", "c_", "__ndarray__", "data", 0], 0.5, "fitted.c_", doc=fam)
    tamper(["fitted", "f_"], {"__ndarray__": {"dtype": "<f8", "shape": [0], "data": []}},
           "fitted.f_", doc=fam)
    tamper(["fitted", "n_outputs_"], 2, "fitted.n_outputs_", doc=fam)
    tamper(["fitted", "structure_", "__dict__", "nd"], 1, "fitted.structure_.nd", doc=fam)
    tamper(["params", "nc"], [1, 1], "params.nc", doc=fam)
    tamper(["fitted", "margins_", "__dict__", "1/C"], {"__tuple__": [0.1]}, "fitted.margins_",
           doc=fam)
    tamper(["fitted", "fit_info_"], {"__dict__": {"cost": 1.0}}, "fitted.fit_info_", doc=fam)
    ar = _doc("AR")
    tamper(["fitted", "n_inputs_"], 1, "fitted.n_inputs_", doc=ar)
    tamper(["params", "na"], 0, "params.na", doc=ar)
    # the trend: typed, consistent with the model
    trend = _trend_doc()
    tamper(["fitted", "trend_", "__dict__", "type"], "cubic", "fitted.trend_.type", doc=trend)
    tamper(["fitted", "trend_", "__dict__", "breakpoints"], [[5]], "fitted.trend_.breakpoints",
           doc=trend)
    tamper(["fitted", "trend_", "__dict__", "n_inputs"], 2, "fitted.trend_", doc=trend)
    tamper(["fitted", "trend_", "__dict__", "one_d"], 1, "fitted.trend_.one_d", doc=trend)
    tamper(["fitted", "trend_", "__dict__", "lengths"], [0], "fitted.trend_.lengths", doc=trend)
    tamper(["fitted", "trend_", "__dict__", "slope", 0], [[0.0]], "fitted.trend_.slope",
           doc=trend)


@pytest.mark.parametrize("name", ["Toy", "RecursiveLeastSquares", "RLSBank", "ARXBank",
                                  "Trend", "IOData", "ARXStructure", "object", "Exception",
                                  "ndarray", "os.system", "ftplib:FTP", "arx", "", 7, None,
                                  ["ARX"]])
def test_foreign_class_names(name, tmp_path):
    doc = _doc("ARX-siso")
    doc["class"] = name
    msg = _refused(tmp_path, doc, "class")
    assert "must be one of ['ARX', 'ARMAX', 'OE', 'BJ', 'AR', 'ARMA']" in msg


def test_stored_objects_anywhere_are_refused(tmp_path):
    evil = {"__object__": "rlsfilt.dask:Client", "state": {"__dict__": {"address": "h:21"}}}
    for key in ("ARX-siso", "OE-siso"):
        base = _doc(key)
        for section in ("params", "fitted"):
            for field in base[section]:
                doc = copy.deepcopy(base)
                doc[section][field] = evil
                _refused(tmp_path, doc, f"{section}.{field}")
        doc = copy.deepcopy(base)
        doc["fitted"]["theta_"]["__ndarray__"]["data"][0] = evil
        _refused(tmp_path, doc, "fitted.theta_")
        doc = copy.deepcopy(base)
        doc["fitted"]["input_names_"]["__tuple__"][0] = evil
        _refused(tmp_path, doc, "fitted.input_names_")
    doc = _doc("ARX-siso")
    doc["fitted"]["trend_"] = evil
    _refused(tmp_path, doc, "fitted.trend_")
    doc["fitted"]["trend_"] = {"__dict__": evil}
    _refused(tmp_path, doc, "fitted.trend_")
    for v in ("params", "fitted"):
        doc = _doc("ARX-siso")
        doc[v] = evil
        _refused(tmp_path, doc, v)


@pytest.mark.parametrize("top", [[], "text", 1, None, True, [{"format": "rlsfilt.model"}]])
def test_non_object_top_level(top, tmp_path):
    with pytest.raises(ValueError, match="is not an rlsfilt model file"):
        _load(tmp_path, top)


@pytest.mark.parametrize("version", [0, 3, 99, "2", 2.0, True, None, -1, 10**30])
def test_wrong_versions(version, tmp_path):
    doc = _doc("ARX-siso")
    doc["format_version"] = version
    with pytest.raises(ValueError, match="has model format version .*; this rlsfilt reads "
                                         "versions 1 to 2"):
        _load(tmp_path, doc)
    del doc["format_version"]
    with pytest.raises(ValueError, match="has model format version"):
        _load(tmp_path, doc)


def test_a_version_1_layout_in_a_version_2_file_is_refused(tmp_path):
    doc = _read(V1_FILES[0])
    doc["format_version"] = 2
    _refused(tmp_path, doc, "module")                # not a field of version 2
    del doc["module"]
    _refused(tmp_path, doc, "fitted.structure_")


def test_repeated_keys_and_bad_text(tmp_path):
    raw = json.dumps(_doc("ARX-siso"))
    with pytest.raises(ValueError, match="appears twice"):
        _load(tmp_path, None, raw=raw.replace('"class": "ARX"', '"class": "ARX", "class": "OE"'))
    (tmp_path / "bin.json").write_bytes(b"\xff\xfe{}")
    with pytest.raises(ValueError, match="`path` is not a UTF-8 JSON file"):
        load_model(tmp_path / "bin.json")


# ----------------------------------------------------------------------
# loading imports nothing and opens no socket (a fresh process, audit hooks)
# ----------------------------------------------------------------------
_CRAFTED = r"""
import json, socket, sys
import rlsfilt
from rlsfilt import load_model

good, crafted = sys.argv[1], sys.argv[2:]
load_model(good)                         # the lazy imports of a legitimate load happen here
before = set(sys.modules)
events = []

def hook(event, args):
    if event == "import" or event.startswith("socket.") or event in (
            "subprocess.Popen", "os.system", "exec", "compile", "ctypes.dlopen", "open"):
        events.append((event, repr(args)[:120]))

def refuse(*args, **kwargs):
    raise AssertionError("a socket was opened")

socket.socket.connect = refuse
socket.create_connection = refuse
sys.addaudithook(hook)
refused = 0
for path in crafted:
    events.clear()
    try:
        load_model(path)
    except ValueError:
        refused += 1
    bad = [e for e in events if not (e[0] == "open" and path in e[1])]
    assert not bad, (path, bad)
new = set(sys.modules) - before
assert not new, sorted(new)
print("refused", refused)
"""


def test_loading_a_crafted_file_imports_nothing_and_opens_no_socket(tmp_path):
    good = tmp_path / "good.json"
    _model("ARX-siso").save(good)
    base = _doc("ARX-siso")
    v1 = _read(V1_FILES[0])
    crafted = []

    def add(doc):
        path = tmp_path / f"crafted{len(crafted)}.json"
        path.write_text(json.dumps(doc))
        crafted.append(str(path))

    ftp = {"__object__": "ftplib:FTP", "state": {"__dict__": {"host": "127.0.0.1"}}}
    dask = {"__object__": "rlsfilt.dask:Client", "state": {"__dict__": {"address": "tcp://10.0.0.1:8786"}}}
    for obj in (ftp, dask, {"__object__": "rlsfilt.models.regressors:ARXStructure",
                            "state": {"__dict__": {"na": "__import__('os')"}}}):
        for doc, key in ((base, "structure_"), (base, "trend_"), (v1, "structure_"),
                         (v1, "trend_"), (base, "theta_")):
            doc = copy.deepcopy(doc)
            doc["fitted"][key] = obj
            add(doc)
        doc = copy.deepcopy(base)
        doc["params"]["na"] = obj
        add(doc)
    for cls, module in (("FTP", "ftplib"), ("Client", "rlsfilt.dask"), ("TestCase", "unittest"),
                        ("Popen", "subprocess"), ("ARX", "antigravity")):
        doc = copy.deepcopy(v1)
        doc.update({"class": cls, "module": module})
        add(doc)
    doc = copy.deepcopy(v1)
    doc["module"] = "antigravity"            # a legitimate version-1 file with a strange module
    add(doc)
    env = {**os.environ, "PYTHONPATH": ROOT}
    proc = subprocess.run([sys.executable, "-c", _CRAFTED, str(good), *crafted], env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip() == f"refused {len(crafted) - 1}"


# ----------------------------------------------------------------------
# counts beyond what a fit can hold, covariances that are no covariances (#27 review)
# ----------------------------------------------------------------------
@pytest.mark.parametrize("key", ["ARX-miso-offset", "ARMAX-siso", "ARX-rls"])
@pytest.mark.parametrize("field", ["n_samples_", "n_experiments_", "n_params_"])
def test_integers_beyond_2_53_are_refused(key, field, tmp_path):
    """A count of 10^400 loaded, and summary() then failed in scipy with a TypeError."""
    doc = _doc(key)
    doc["fitted"][field] = 10**400
    assert "must be <= 9007199254740992" in _refused(tmp_path, doc, f"fitted.{field}")
    doc["fitted"][field] = 2**53 + 1
    _refused(tmp_path, doc, f"fitted.{field}")


@pytest.mark.parametrize("key", ["ARX-miso-offset", "ARMAX-siso", "ARX-rls"])
def test_a_covariance_that_is_not_symmetric_is_refused(key, tmp_path):
    """Every fit stores a symmetric ``theta_cov_``: an off-diagonal entry changed on one
    side only (wrong standard errors for one parameter) is refused; the file as written
    loads."""
    doc = _doc(key)
    _load(tmp_path, doc)
    cov = doc["fitted"]["theta_cov_"]["__ndarray__"]
    cov["data"][1] = cov["data"][1] * 2 + 1.0
    assert "symmetric" in _refused(tmp_path, doc, "fitted.theta_cov_")
