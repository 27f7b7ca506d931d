"""save_model / load_model: strict JSON, bit-for-bit numbers, generic over estimators."""

import json

import numpy as np
import pytest

from rlsfilt.data import IOData, Trend, detrend
from rlsfilt.persistence import FORMAT_VERSION, load_model, save_model


class Toy:
    """A minimal estimator: constructor parameters and learned attributes ending in _."""

    def __init__(self, order=2, dt=True, lags=(1, 2)):
        self.order = order
        self.dt = dt
        self.lags = lags

    def get_params(self, deep=True):
        return {"order": self.order, "dt": self.dt, "lags": self.lags}

    def fit(self, rng):
        self.theta_ = rng.standard_normal(self.order) * 1e-3
        self.cov_ = np.cov(rng.standard_normal((self.order, 50)))
        self.noise_variance_ = float(np.pi) / 7
        self.odd_ = np.array([np.nan, np.inf, -np.inf, -0.0, 5e-324, 1.7976931348623157e308])
        self.poles_ = np.array([0.5 + 0.25j, np.nan + 1j])
        self.counts_ = np.array([[1, 2], [3, 4]], dtype=np.int64)
        self.flags_ = np.array([True, False])
        self.names_ = ("u", "y")
        self.nested_ = {"a": [1, 2.5, None], "b": range(0, 6, 2), "c": np.float64(0.1)}
        self.residuals_ = rng.standard_normal(500)
        self.theta_history_ = rng.standard_normal((500, self.order))
        self.filter_ = object()            # a live object: not written
        self.note = "not learned"           # no trailing underscore: not written
        return self


class Restoring(Toy):
    def _restore_fitted(self, fitted):
        self.restored_from_ = sorted(fitted)
        for key, value in fitted.items():
            setattr(self, key, value)


def _equal_bits(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.dtype == b.dtype and a.shape == b.shape
    if a.dtype.kind in "fc":
        assert a.tobytes() == b.tobytes()
    else:
        np.testing.assert_array_equal(a, b)


def test_round_trip_is_bit_for_bit(rng, tmp_path):
    model = Toy(order=3, dt=0.25, lags=(1, 4)).fit(rng)
    path = tmp_path / "toy.json"
    doc = save_model(model, path)
    assert doc["omitted"] == ["filter_", "residuals_", "theta_history_"]
    back = load_model(path, cls=Toy)
    assert isinstance(back, Toy) and back.get_params() == {"order": 3, "dt": 0.25,
                                                           "lags": (1, 4)}
    for name in ("theta_", "cov_", "odd_", "poles_", "counts_", "flags_"):
        _equal_bits(getattr(back, name), getattr(model, name))
    assert back.noise_variance_ == model.noise_variance_
    assert back.names_ == ("u", "y") and isinstance(back.names_, tuple)
    assert back.nested_ == {"a": [1, 2.5, None], "b": range(0, 6, 2), "c": 0.1}
    assert not hasattr(back, "residuals_") and not hasattr(back, "filter_")
    assert not hasattr(back, "note")
    # strict JSON: no NaN/Infinity literals, readable one entry per line
    text = path.read_text()
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-standard constant {c}"))
    assert '\n    "theta_": {"__ndarray__"' in text
    assert json.loads(text)["format_version"] == FORMAT_VERSION


def test_include_data_and_dt_true(rng, tmp_path):
    model = Toy().fit(rng)
    save_model(model, tmp_path / "m.json", include_data=True)
    back = load_model(str(tmp_path / "m.json"), cls=Toy)
    _equal_bits(back.residuals_, model.residuals_)
    _equal_bits(back.theta_history_, model.theta_history_)
    assert back.dt is True


def test_restore_hook_and_rlsfilt_objects(rng, tmp_path):
    model = Restoring().fit(rng)
    _, model.trend_ = detrend(IOData(40 + rng.standard_normal(30), 97 + rng.standard_normal(30)))
    save_model(model, tmp_path / "r.json")
    back = load_model(tmp_path / "r.json", cls=Restoring)
    assert "trend_" in back.restored_from_
    assert isinstance(back.trend_, Trend)
    np.testing.assert_array_equal(back.trend_.output_offset, model.trend_.output_offset)


def test_class_lookup(tmp_path):
    """Without `cls`, only rlsfilt classes are built (found in their module or in rlsfilt)."""
    from rlsfilt import ARX

    ARX.from_polynomials([-0.5, 0.1], [1.0, 0.5], dt=0.5).save(tmp_path / "arx.json")
    doc = json.loads((tmp_path / "arx.json").read_text())
    doc["module"] = "rlsfilt.somewhere.moved"   # a class that moved is still found
    (tmp_path / "arx.json").write_text(json.dumps(doc))
    model = load_model(tmp_path / "arx.json")
    assert isinstance(model, ARX) and model.get_params() == {"na": 2, "nb": 2, "nk": 1,
                                                             "dt": 0.5, "offset": False}
    doc["fitted"] = {}
    (tmp_path / "empty.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="lacks its learned attributes"):
        load_model(tmp_path / "empty.json")
    doc.update({"class": "Toy", "module": "tests.test_persistence"})
    (tmp_path / "toy.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="which is not an rlsfilt class; pass `cls=`"):
        load_model(tmp_path / "toy.json")
    with pytest.raises(ValueError, match="holds a Toy model; load it with Toy.load"):
        load_model(tmp_path / "toy.json", cls=ARX)


def test_errors(rng, tmp_path):
    with pytest.raises(ValueError, match="has no learned attributes to save; call fit"):
        save_model(Toy(), tmp_path / "x.json")
    with pytest.raises(TypeError, match="the parameter `lags` of Toy cannot be saved as JSON"):
        save_model(Toy(lags=object()).fit(rng), tmp_path / "x.json")
    with pytest.raises(TypeError, match="`model` must be an estimator with get_params"):
        save_model(np.zeros(3), tmp_path / "x.json")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(ValueError, match="is not a JSON file"):
        load_model(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text(json.dumps({"hello": 1}))
    with pytest.raises(ValueError, match="is not an rlsfilt model file"):
        load_model(tmp_path / "other.json")
    (tmp_path / "new.json").write_text(json.dumps({"format": "rlsfilt.model",
                                                   "format_version": FORMAT_VERSION + 1}))
    with pytest.raises(ValueError, match="has model format version 2; this rlsfilt reads "
                                         "versions up to 1"):
        load_model(tmp_path / "new.json")
