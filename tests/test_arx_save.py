"""ARX.save / ARX.load: a loaded model predicts, simulates and reports exactly as the saved one."""

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX
from rlsfilt.datasets import heat_exchanger
from rlsfilt.persistence import load_model


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.tobytes() == b.tobytes()


def _check_round_trip(model, u, y, path):
    model.save(path)
    back = ARX.load(path)
    assert type(back) is ARX and back.get_params() == model.get_params()
    _same(back.theta_, model.theta_)
    _same(back.theta_cov_, model.theta_cov_)
    _same(back.std_errors_, model.std_errors_)
    _same(back.predict(u, y), model.predict(u, y))
    _same(back.predict(u, y, horizon=5), model.predict(u, y, horizon=5))
    _same(back.simulate(u), model.simulate(u))
    _same(back.noise_variance_, model.noise_variance_)
    assert str(back.summary()) == str(model.summary())
    assert back.param_names_ == model.param_names_
    G, H = model.to_tf(), back.to_tf()
    assert list(G.input_labels) == list(H.input_labels)
    assert list(G.output_labels) == list(H.output_labels)
    for i in range(G.noutputs):
        for j in range(G.ninputs):
            _same(G.num[i][j], H.num[i][j])
            _same(G.den[i][j], H.den[i][j])
    return back


def test_named_offset_model_round_trip(rng, tmp_path):
    pd = pytest.importorskip("pandas")
    u = 40 + rng.standard_normal(400)
    y = 97 + lfilter([0, 0.5, 0.2], [1, -1.2, 0.4], u - 40) + 0.05 * rng.standard_normal(400)
    frame = pd.DataFrame({"flow": u, "T_out": y})
    model = ARX(2, 2, 1, dt=0.5, offset=True).fit(frame[["flow"]], frame["T_out"])
    back = _check_round_trip(model, frame[["flow"]], frame["T_out"], tmp_path / "m.json")
    _same(back.input_offset_, model.input_offset_)
    assert back.intercept_ == model.intercept_
    assert list(back.to_tf().input_labels) == ["flow"]
    doc = json.loads((tmp_path / "m.json").read_text())
    assert doc["class"] == "ARX" and doc["params"] == {"na": 2, "nb": 2, "nk": 1, "dt": 0.5,
                                                      "offset": True}
    for key in ("theta_cov_", "noise_variance_", "input_offset_", "output_offset_",
                "input_names_", "output_names_", "intercept_", "structure_"):
        assert key in doc["fitted"], key
    assert doc["rlsfilt_version"] and doc["format_version"] == 2
    assert "residuals_" in doc["omitted"]


def test_recursive_and_multi_signal_models(rng, tmp_path):
    U = rng.standard_normal((500, 2))
    Y = np.column_stack([lfilter([0, 1.0], [1, -0.5], U[:, 0]),
                         lfilter([0, 0.4], [1, -0.8], U[:, 1])])
    Y += 0.01 * rng.standard_normal(Y.shape)
    mimo = ARX(1, [1, 2], [1, 0]).fit(U, Y)
    back = _check_round_trip(mimo, U, Y, tmp_path / "mimo.json")
    _same(back.noise_covariance_, mimo.noise_covariance_)
    rls = ARX(1, [1, 2], [1, 0]).fit(U, Y[:, 0], method="rls", lam=0.995)
    back = _check_round_trip(rls, U, Y[:, 0], tmp_path / "rls.json")
    assert "recursive least squares" in str(back.summary())
    with pytest.raises(AttributeError, match="`theta_history_` is only set by"):
        _ = back.theta_history_
    rls.save(tmp_path / "full.json", include_data=True)
    _same(ARX.load(tmp_path / "full.json").theta_history_, rls.theta_history_)


def test_two_experiment_mean_offset_model(tmp_path):
    ds = heat_exchanger()
    model = ARX(2, 2, 8, dt=1.0, offset="mean").fit(ds)
    run = ds.getexp(1)
    back = _check_round_trip(model, run.u, run.y, tmp_path / "hx.json")
    assert back.n_experiments_ == 2 and back.output_units_ == ("degC",)
    assert "T_out = 96.8" in repr(back)
    _same(back.to_tf(continuous=True).num[0][0], model.to_tf(continuous=True).num[0][0])
    assert load_model(tmp_path / "hx.json").input_names_ == ("flow",)


def test_load_errors(tmp_path):
    model = ARX.from_polynomials([-0.5], [1.0])
    with pytest.raises(Exception, match="not fitted"):
        ARX(1, 1).save(tmp_path / "x.json")
    model.save(tmp_path / "ok.json")
    doc = json.loads((tmp_path / "ok.json").read_text())
    doc["class"] = "ARMAX"
    (tmp_path / "other.json").write_text(json.dumps(doc))
    with pytest.raises(ValueError, match="holds a ARMAX model; load it with ARMAX.load"):
        ARX.load(tmp_path / "other.json")
