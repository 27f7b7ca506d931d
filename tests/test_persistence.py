"""save_model / load_model: strict JSON, bit-for-bit numbers, a closed set of model classes.

The tampered files (every field, wrong types, extra keys, NaN, a foreign class, stored
objects) and the test that loading imports nothing are in test_persistence_tampered.py.
"""

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX, IOData, Trend, detrend
from rlsfilt.persistence import FORMAT_VERSION, MODEL_CLASSES, load_model, save_model


def _equal_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes()


def _record(rng, n=400):
    U = rng.standard_normal((n, 2))
    Y = np.column_stack([lfilter([0, 1.0], [1, -0.5], U[:, 0]),
                         lfilter([0, 0.4], [1, -0.8], U[:, 1])])
    return U, Y + 0.01 * rng.standard_normal(Y.shape)


def test_round_trip_is_bit_for_bit(rng, tmp_path):
    U, Y = _record(rng)
    model = ARX(1, [1, 2], [1, 0], dt=0.25, offset=True).fit(U + 3.0, Y - 1.0)
    path = tmp_path / "mimo.json"
    doc = save_model(model, path)
    assert doc["omitted"] == ["residuals_"] and doc["class"] == "ARX"
    back = load_model(path)
    assert type(back) is ARX and back.get_params() == model.get_params()
    for name in ("theta_", "theta_cov_", "noise_variance_", "noise_covariance_", "a_",
                 "intercept_", "input_offset_", "output_offset_"):
        _equal_bits(getattr(back, name), getattr(model, name))
    for b1, b2 in zip(back.b_, model.b_):
        _equal_bits(b1, b2)
    assert back.input_names_ == ("u1", "u2") and isinstance(back.input_names_, tuple)
    assert not hasattr(back, "residuals_")
    _equal_bits(back.predict(U + 3.0, Y - 1.0, horizon=3),
                model.predict(U + 3.0, Y - 1.0, horizon=3))
    # strict JSON: no NaN/Infinity literals, readable one entry per line, no module paths
    text = path.read_text()
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard constant {c}"))
    assert '\n    "theta_": {"__ndarray__"' in text
    assert "__object__" not in text and '"module"' not in text
    assert json.loads(text)["format_version"] == FORMAT_VERSION == 2


def test_include_data_keeps_the_histories(rng, tmp_path):
    U, Y = _record(rng)
    model = ARX(1, 1, 1, dt=True).fit(U[:, 0], Y[:, 0], method="rls", lam=0.99)
    save_model(model, tmp_path / "m.json", include_data=True)
    back = load_model(str(tmp_path / "m.json"))
    _equal_bits(back.residuals_, model.residuals_)
    _equal_bits(back.theta_history_, model.theta_history_)     # NaN rows before the start
    _equal_bits(back.recursive_residuals_, model.recursive_residuals_)
    assert back.dt is True and back.lam_ == 0.99 and back.form_ == "covariance"
    assert not hasattr(back, "filter_")


def test_trend_travels_with_the_model(rng, tmp_path):
    u, y = 40 + rng.standard_normal(300), 97 + rng.standard_normal(300)
    data_d, trend = detrend(IOData(u, y, dt=1.0))
    model = ARX(1, 1).fit(data_d)
    save_model(model, tmp_path / "r.json", trend=trend)
    back = load_model(tmp_path / "r.json")
    assert isinstance(back.trend_, Trend)
    np.testing.assert_array_equal(back.trend_.output_offset, trend.output_offset)


def test_class_lookup(tmp_path):
    """Only the closed set of classes is built; the class comes from a dict, never a module."""
    assert MODEL_CLASSES == ("ARX", "ARMAX", "OE", "BJ", "AR", "ARMA")
    ARX.from_polynomials([-0.5, 0.1], [1.0, 0.5], dt=0.5).save(tmp_path / "arx.json")
    doc = json.loads((tmp_path / "arx.json").read_text())
    model = load_model(tmp_path / "arx.json")
    assert isinstance(model, ARX) and model.get_params() == {"na": 2, "nb": 2, "nk": 1,
                                                             "dt": 0.5, "offset": False}
    doc["fitted"] = {}
    (tmp_path / "empty.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"`fitted.structure_` is missing \(a required field\)"):
        load_model(tmp_path / "empty.json")
    doc["class"] = "Toy"
    (tmp_path / "toy.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=r"`class` must be one of \['ARX', 'ARMAX', 'OE', "
                                         r"'BJ', 'AR', 'ARMA'\].*; got \"Toy\""):
        load_model(tmp_path / "toy.json")
    doc["class"] = "ARMAX"
    (tmp_path / "armax.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="holds a ARMAX model; load it with ARMAX.load"):
        load_model(tmp_path / "armax.json", cls=ARX)
    with pytest.raises(TypeError, match=r"`cls` must be one of the classes"):
        load_model(tmp_path / "arx.json", cls=dict)


def test_errors(rng, tmp_path):
    class Mine(ARX):
        pass

    with pytest.raises(ValueError, match="has no learned attributes to save; call fit"):
        save_model(ARX(1, 1), tmp_path / "x.json")
    with pytest.raises(TypeError, match=r"`model` must be a model of one of the classes "
                                        r"\['ARX'.*got Mine"):
        save_model(Mine.from_polynomials([-0.5], [1.0]), tmp_path / "x.json")
    with pytest.raises(TypeError, match="`model` must be a model of one of the classes"):
        save_model(np.zeros(3), tmp_path / "x.json")
    assert not (tmp_path / "x.json").exists()
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(ValueError, match="is not a JSON file"):
        load_model(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text(json.dumps({"hello": 1}))
    with pytest.raises(ValueError, match="is not an rlsfilt model file"):
        load_model(tmp_path / "other.json")
    (tmp_path / "new.json").write_text(json.dumps({"format": "rlsfilt.model",
                                                   "format_version": FORMAT_VERSION + 1}))
    with pytest.raises(ValueError, match="has model format version 3; this rlsfilt reads "
                                         r"versions 1 to 2 \(upgrade rlsfilt\)"):
        load_model(tmp_path / "new.json")


def test_a_model_that_cannot_be_loaded_is_not_saved(rng, tmp_path):
    """save checks the document against the loader's schema before replacing the file."""
    model = ARX.from_polynomials([-0.5], [1.0])
    model.save(tmp_path / "m.json")
    before = (tmp_path / "m.json").read_bytes()
    model.theta_cov_ = np.full((2, 2), np.nan)
    with pytest.raises(ValueError, match=r"the ARX model cannot be saved: `fitted.theta_cov_\[0\]` "
                                         "must be a finite number; got \"NaN\""):
        model.save(tmp_path / "m.json")
    assert (tmp_path / "m.json").read_bytes() == before
