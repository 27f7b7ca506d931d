"""A model saved with the trend it was fitted under (``save(path, trend=...)``): the loaded
model carries it as ``trend_`` and puts predictions back in the units of the data exactly as
before saving; ``rlsfilt identify --detrend linear --save-model`` saves it."""

import json

import numpy as np
import pytest
import scipy.signal

from rlsfilt import ARMAX, ARX, OE, IOData, Trend, detrend, load_model, retrend, save_model
from rlsfilt.cli import main
from rlsfilt.datasets import heat_exchanger


def _same(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape and a.tobytes() == b.tobytes()


def _same_trend(a, b):
    assert isinstance(a, Trend) and a.type == b.type and a.breakpoints == b.breakpoints
    assert (a.n_inputs, a.n_outputs) == (b.n_inputs, b.n_outputs)
    assert len(a.intercept) == len(b.intercept)
    for x, y in zip(a.intercept + a.slope, b.intercept + b.slope):
        _same(x, y)
    _same(a.offset, b.offset)


def _drifting_record(rng, n=(400, 300)):
    """Two experiments of ARX(2, 2, 3) deviations on lines (a warming sensor, a ramp input)."""
    us, ys = [], []
    for i, N in enumerate(n):
        u = rng.standard_normal(N)
        e = 0.01 * rng.standard_normal(N)
        dev = scipy.signal.lfilter([0, 0, 0, 0.5, 0.25], [1, -1.2, 0.5], u) + e
        k = np.arange(N)
        us.append(u + 40.0 + 0.004 * k)
        ys.append(dev + 97.0 + 3.0 * i + 0.01 * k)
    return IOData(us, ys, 0.5, input_names=["flow"], output_names=["T_out"],
                  input_units=["%"], output_units=["degC"])


def _in_units(model, data_d, trend):
    """One-step predictions of `model` on detrended data, in the units of the data."""
    yh = model.predict(data_d)
    yh = yh if isinstance(yh, list) else [yh]
    back = retrend(IOData([U for U, _ in data_d.arrays()], yh, data_d.dt), trend)
    return [Y for _, Y in back.arrays()]


@pytest.mark.parametrize("method", ["ls", "rls"])
def test_linear_trend_round_trip(rng, tmp_path, method):
    data = _drifting_record(rng)
    data_d, trend = detrend(data, type="linear", bp=[[0, 150], [0]])
    model = ARX(2, 2, 3, dt=0.5).fit(data_d, method=method)
    path = tmp_path / "m.json"
    doc = model.save(path, trend=trend)
    assert "trend_" in doc["fitted"] and not hasattr(model, "trend_")   # save does not mutate
    back = ARX.load(path)
    _same_trend(back.trend_, trend)
    _same(back.theta_, model.theta_)
    _same(back.std_errors_, model.std_errors_)
    for a, b in zip(_in_units(back, data_d, back.trend_), _in_units(model, data_d, trend)):
        _same(a, b)
    # oracle: the trend is what scipy.signal.detrend removes (segment [0, 150) and [150, 400)
    # of the first run, one line on the second), and the predictions in data units are the
    # one-step predictions of the deviations plus that line
    in_units = _in_units(back, data_d, back.trend_)
    for i, (_, Y) in enumerate(data.arrays()):
        bp = [150] if i == 0 else 0
        line = Y[:, 0] - scipy.signal.detrend(Y[:, 0], type="linear", bp=bp)
        np.testing.assert_allclose(back.trend_.values(len(Y), i)[:, 1], line, rtol=0,
                                   atol=1e-12)
        np.testing.assert_allclose(in_units[i][:, 0], back.predict(data_d)[i] + line, rtol=0,
                                   atol=1e-12)
    # the saved trend removed from the record gives the detrended record back
    for (Ud, Yd), (Ud0, Yd0) in zip(back.trend_.remove(data).arrays(), data_d.arrays()):
        np.testing.assert_allclose(Ud, Ud0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(Yd, Yd0, rtol=0, atol=1e-12)
    # the file is plain JSON, with the trend's fields under the learned attributes (no
    # module path: the loader reads it against the schema of a Trend)
    stored = json.loads(path.read_text())["fitted"]["trend_"]
    assert list(stored) == ["__dict__"] and stored["__dict__"]["type"] == "linear"
    assert "__object__" not in path.read_text()


def test_resave_keeps_replace_and_refit_drops(rng, tmp_path):
    data_d, trend = detrend(_drifting_record(rng, (300,)), type="linear")
    model = ARX(2, 2, 3, dt=0.5, offset=True).fit(data_d)
    model.save(tmp_path / "a.json", trend=trend)
    back = ARX.load(tmp_path / "a.json")
    back.save(tmp_path / "b.json")                      # a loaded model keeps its trend
    _same_trend(ARX.load(tmp_path / "b.json").trend_, trend)
    const = detrend(_drifting_record(rng, (300,)))[1]
    save_model(back, tmp_path / "c.json", trend=const)   # an explicit trend replaces it
    _same_trend(load_model(tmp_path / "c.json").trend_, const)
    assert not hasattr(ARX.load(tmp_path / "c.json").fit(data_d), "trend_")   # stale after fit
    assert not hasattr(ARX.load(tmp_path / "c.json").fit(data_d, method="rls"), "trend_")
    model.save(tmp_path / "d.json")                      # no trend: none is written
    assert not hasattr(ARX.load(tmp_path / "d.json"), "trend_")


def test_family_model_carries_its_trend(rng, tmp_path):
    data = _drifting_record(rng, (500,))
    data_d, trend = detrend(data, type="linear")
    model = OE(2, 2, 3, dt=0.5).fit(data_d)
    model.save(tmp_path / "oe.json", trend=trend)
    back = OE.load(tmp_path / "oe.json")
    _same_trend(back.trend_, trend)
    for a, b in zip(_in_units(back, data_d, back.trend_), _in_units(model, data_d, trend)):
        _same(a, b)
    assert not hasattr(back.fit(data_d), "trend_")


def test_bad_trend_is_refused_and_writes_nothing(rng, tmp_path):
    data_d, trend = detrend(_drifting_record(rng, (300,)), type="linear")
    model = ARX(2, 2, 3, dt=0.5).fit(data_d)
    path = tmp_path / "m.json"
    with pytest.raises(TypeError, match=r"`trend` must be a Trend \(from rlsfilt.detrend\); "
                                        "got dict"):
        model.save(path, trend=trend.to_dict())
    two_in = detrend(IOData(np.ones((10, 2)) + np.arange(10)[:, None], np.arange(10.0), 1.0))[1]
    with pytest.raises(ValueError, match=r"`trend` must describe 1 input\(s\) and 1 output\(s\) "
                                         r"like the model; got 2 and 1"):
        model.save(path, trend=two_in)
    with pytest.raises(ValueError, match="the trend of an array with 2 column"):
        model.save(path, trend=detrend(np.ones((10, 2)))[1])
    assert not path.exists()


def _write(path, runs):
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("t,run,flow,T_out\n")
        for name, run in runs:
            for t, u, y in zip(run.t, run.u, run.y):
                fh.write(f"{t:.6g},{name},{u:.17g},{y:.17g}\n")
    return path


def _csv_record(tmp_path):
    """The exchanger's two runs on a slow drift of the outlet (as read back from the CSV)."""
    hx = heat_exchanger()
    runs = []
    for i in range(2):
        r = hx.getexp(i)
        y = r.y + 0.002 * np.arange(len(r.y))
        runs.append(IOData(r.u, y, 1.0))
    path = _write(tmp_path / "hx.csv", [(f"run{i + 1}", r) for i, r in enumerate(runs)])
    data = IOData([r.u for r in runs], [r.y for r in runs], 1.0, input_names=["flow"],
                  output_names=["T_out"], experiment_names=["run1", "run2"])
    return path, data


ARGS = ("identify", "{csv}", "-u", "flow", "-y", "T_out", "--time", "t",
        "--experiment-column", "run", "--na", "2", "--nb", "2", "--nk", "8")


def _run(capsys, csv, *extra):
    code = main([a.format(csv=csv) for a in ARGS] + [str(a) for a in extra])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out


def test_cli_linear_detrend_saves_the_trend(capsys, tmp_path):
    csv, data = _csv_record(tmp_path)
    saved = tmp_path / "model.json"
    out = _run(capsys, csv, "--detrend", "linear", "--split", "0.7", "--save-model", saved)
    assert out.rstrip().endswith(f"model saved to {saved} with the linear trend removed from "
                                 "the estimation data (load it back as its trend_)")
    est, _ = data.split(0.7)
    est_d, trend = detrend(est, "linear")
    model = ARX(2, 2, 8, dt=1.0).fit(est_d)
    back = ARX.load(saved)
    _same_trend(back.trend_, trend)
    np.testing.assert_allclose(back.theta_, model.theta_, rtol=1e-12)
    for a, b in zip(_in_units(back, est_d, back.trend_), _in_units(model, est_d, trend)):
        np.testing.assert_allclose(a, b, rtol=1e-12)
    # in the units of the data: the one-step predictions follow the drifting outlet
    for (_, Y), Yh in zip(est.arrays(), _in_units(back, est_d, back.trend_)):
        assert np.max(np.abs(Yh[8:] - Y[8:])) < 0.05
    res = json.loads(_run(capsys, csv, "--detrend", "linear", "--save-model", saved, "--json"))
    assert res["metadata"]["model_file_trend"] == "linear"
    _same_trend(ARX.load(saved).trend_, detrend(data, "linear")[1])


def test_cli_family_constant_detrend_saves_the_operating_point(capsys, tmp_path):
    csv, data = _csv_record(tmp_path)
    saved = tmp_path / "armax.json"
    _run(capsys, csv, "--model", "armax", "--nc", "1", "--save-model", saved)
    back = ARMAX.load(saved)
    u_op = np.vstack([U for U, _ in data.arrays()]).mean(axis=0)
    y_op = np.vstack([Y for _, Y in data.arrays()]).mean(axis=0)
    assert back.trend_.type == "constant" and back.trend_.n_experiments == 1
    _same(back.trend_.intercept[0], np.hstack([u_op, y_op])[None])   # the CLI's means
    _same(back.trend_.slope[0], np.zeros((1, 2)))
    np.testing.assert_allclose(back.trend_.input_offset, u_op, rtol=1e-13)
    np.testing.assert_allclose(back.trend_.output_offset, y_op, rtol=1e-13)
    # removing it from the record gives the deviations the CLI fitted on
    dev = back.trend_.remove(data)
    for (U, Y), (Ud, Yd) in zip(data.arrays(), dev.arrays()):
        np.testing.assert_allclose(Ud, U - u_op, rtol=0, atol=1e-13)
        np.testing.assert_allclose(Yd, Y - y_op, rtol=0, atol=1e-13)
    # ARX with constant detrend keeps the operating point itself: no trend is saved
    _run(capsys, csv, "--save-model", saved)
    assert not hasattr(ARX.load(saved), "trend_")
