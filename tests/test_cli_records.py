"""The command line on measured-like records: experiments, detrending, validation data,
delay range, saved models, unstable models."""

import json

import numpy as np
import pytest

from rlsfilt import ARX, IOData, detrend
from rlsfilt.cli import main
from rlsfilt.datasets import heat_exchanger


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _write(path, runs):
    """CSV with columns t, run, flow, T_out; `runs` is a list of (name, IOData of one run)."""
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("t,run,flow,T_out\n")
        for name, run in runs:
            for t, u, y in zip(run.t, run.u, run.y):
                fh.write(f"{t:.6g},{name},{u:.17g},{y:.17g}\n")
    return path


@pytest.fixture(scope="module")
def hx():
    return heat_exchanger()


@pytest.fixture
def hx_csv(tmp_path, hx):
    return _write(tmp_path / "hx.csv", [("run1", hx.getexp(0)), ("run2", hx.getexp(1))])


def _data(hx):
    """The exchanger record as the CLI reads it (names from the columns)."""
    runs = [hx.getexp(i) for i in range(2)]
    return IOData([r.u for r in runs], [r.y for r in runs], 1.0, input_names=["flow"],
                  output_names=["T_out"], experiment_names=["run1", "run2"])


BASE = ("identify", "{csv}", "-u", "flow", "-y", "T_out", "--time", "t",
        "--experiment-column", "run")


def _args(csv, *extra):
    return [a.format(csv=csv) for a in BASE] + list(extra)


def test_whole_workflow_split_select_save(capsys, hx, hx_csv, tmp_path):
    """Two runs, means removed, delay found by delayest, orders chosen on the held-out 30 %,
    model saved: every number equals the library's."""
    saved = tmp_path / "model.json"
    code, out, err = _run(capsys, *_args(hx_csv, "--split", "0.7", "--select-order",
                                         "--save-model", saved, "--json"))
    assert code == 0, err
    res = json.loads(out)
    meta = res["metadata"]
    assert meta["detrend"] == "constant" and meta["experiments"] == ["run1", "run2"]
    assert meta["delay_estimate"] == 8 and meta["experiment_lengths"] == [1200, 800]
    assert "last 30 % of each experiment" in meta["validated_on"]
    assert res["nk"] == [8] and res["n_experiments"] == 2 and res["offset"] == "mean"
    assert res["n_samples"] == 360 + 240 and res["stable"] is True
    # the library, step by step
    est, val = _data(hx).split(0.7)
    from rlsfilt import select_order

    sel = select_order(est, na=range(0, 5), nb=range(1, 5), nk=range(6, 11), validation=val,
                       dt=1.0, offset="mean")
    assert meta["order_selection"]["best"] == list(sel.best)
    model = ARX(*sel.best, dt=1.0, offset="mean").fit(est)
    np.testing.assert_allclose(res["theta"], model.theta_, rtol=1e-12)
    np.testing.assert_allclose(res["output_offset"], model.output_offset_, rtol=1e-14)
    # the saved model predicts and simulates in the units of the data, as the fitted one
    back = ARX.load(saved)
    run = val.getexp(1)
    np.testing.assert_array_equal(back.simulate(run.u), model.simulate(run.u))
    assert back.simulate(run.u).mean() == pytest.approx(97.0, abs=1.0)
    code, out, err = _run(capsys, *_args(hx_csv, "--split", "0.7", "--na", "2", "--nb", "2",
                                         "--nk", "8", "--save-model", saved))
    assert code == 0 and err == ""
    assert out.startswith(f"data: '{hx_csv}', 2000 samples in 2 experiments (run1: 1200, "
                          "run2: 800), sample time 1 s\ndetrend: constant (means removed: "
                          "flow = 40.")
    assert "samples of 2 experiments" in out and "operating point: flow = " in out
    assert out.rstrip().endswith(f"model saved to {saved}")


def test_validation_file_and_delay_range(capsys, hx, hx_csv, tmp_path):
    fresh = heat_exchanger(n_samples=600, rng=5)
    val_csv = _write(tmp_path / "val.csv", [("run3", fresh)])
    code, out, err = _run(capsys, *_args(hx_csv, "--validation", val_csv, "--select-order",
                                         "--delay-range", "6:10", "--max-order", "3",
                                         "--json"))
    assert code == 0, err
    res = json.loads(out)
    assert res["n_samples"] == 600 and "val.csv" in res["metadata"]["validated_on"]
    sel = res["metadata"]["order_selection"]
    assert sel["n_val_rows"] is not None and {c["nk"] for c in sel["candidates"]} == \
        set(range(6, 11))
    assert "delay_estimate" not in res["metadata"] and res["nk"] == [8]
    assert res["fit_percent"] > 70


def test_detrend_options(capsys, hx, hx_csv):
    # none: the raw record warns about its operating point, and the model is worthless
    code, out, err = _run(capsys, *_args(hx_csv, "--nk", "8", "--detrend", "none"))
    assert code == 0 and "detrend: none" in out
    assert err.startswith("rlsfilt: warning: input 'flow' has mean 40.") and \
        "offset=True" in err
    # linear: each record about its own line, the same numbers as the library
    code, out, err = _run(capsys, *_args(hx_csv, "--nk", "8", "--detrend", "linear",
                                         "--json"))
    assert code == 0, err
    model = ARX(2, 2, 8, dt=1.0).fit(detrend(_data(hx), "linear")[0])
    np.testing.assert_allclose(json.loads(out)["theta"], model.theta_, rtol=1e-12)


def test_unstable_model_is_said_plainly(capsys, hx, tmp_path):
    csv = _write(tmp_path / "run1.csv", [("run1", hx.getexp(0))])
    argv = ("identify", csv, "-u", "flow", "-y", "T_out", "--detrend", "none", "--na", "2",
            "--nb", "2", "--nk", "8")
    code, out, err = _run(capsys, *argv)
    assert code == 0
    assert "Simulation fit      : unstable model, largest pole magnitude 1.0" in out
    assert "simulation diverges" in out and "e+" not in out.split("Simulation fit")[1][:80]
    code, out, err = _run(capsys, *argv, "--json")
    res = json.loads(out)
    assert res["fit_percent"] is None and res["unstable"] is True
    assert res["stability"].startswith("unstable model, largest pole magnitude 1.0")


def test_errors(capsys, hx_csv, tmp_path):
    def one_line(r, text, code=1):
        assert r[0] == code and r[1] == "" and len(r[2].splitlines()) == 1, r
        assert text in r[2], r[2]

    one_line(_run(capsys, *_args(hx_csv, "--delay-range", "5:2", "--select-order")),
             "argument --delay-range: must have LO <= HI; got '5:2'", 2)
    one_line(_run(capsys, *_args(hx_csv, "--delay-range", "a:b", "--select-order")),
             "argument --delay-range: must be an integer; got 'a'", 2)
    one_line(_run(capsys, *_args(hx_csv, "--delay-range", "6:9")),
             "--delay-range needs --select-order")
    one_line(_run(capsys, *_args(hx_csv, "--split", "1.2")),
             "argument --split: must be in (0, 1); got 1.2", 2)
    one_line(_run(capsys, *_args(hx_csv, "--split", "0.5", "--validation", hx_csv)),
             "not allowed with argument", 2)
    one_line(_run(capsys, *_args(hx_csv, "--save-model", tmp_path / "no" / "m.json")),
             "cannot write")
    one_line(_run(capsys, "identify", hx_csv, "-u", "flow", "-y", "T_out",
                  "--experiment-column", "T_out"), "is given as --experiment-column and as")
    one_line(_run(capsys, "identify", hx_csv, "-u", "flow", "-y", "T_out",
                  "--experiment-column", "batch"), "column 'batch' not found")
    bad = tmp_path / "bad.csv"
    bad.write_text("t,run,flow,T_out\n0,a,1,2\n1,a,2,3\n2,a,1,2\n0,b,1,2\n2,b,2,3\n4,b,3,1\n")
    one_line(_run(capsys, "identify", bad, "-u", "flow", "-y", "T_out", "--time", "t",
                  "--experiment-column", "run"),
             "the experiments of '" + str(bad) + "' have different sample times (1 to 2)")
    other = tmp_path / "other.csv"
    other.write_text("t,run,flow,T_out\n" + "".join(f"{2 * k},c,{k % 3},{k % 5}\n"
                                                   for k in range(50)))
    one_line(_run(capsys, *_args(hx_csv, "--validation", other)),
             "has sample time 2; '" + str(hx_csv) + "' has 1")


def _two_delays_csv(path):
    """Two inputs at operating points 20 and 5 with delays 1 and 8 (issue #28, item 6)."""
    from scipy.signal import lfilter

    rng = np.random.default_rng(4)
    N = 1500
    u1 = np.repeat(rng.choice([-1.0, 1.0], N // 4 + 1), 4)[:N] + 20
    u2 = np.repeat(rng.choice([-1.0, 1.0], N // 3 + 1), 3)[:N] + 5
    y = (lfilter([0, 0.5, 0.25], [1, -0.7], u1)
         + lfilter(np.r_[np.zeros(8), 0.4, 0.2], [1, -0.7], u2)
         + 0.05 * rng.standard_normal(N))
    np.savetxt(path, np.column_stack([u1, u2, y]), delimiter=",", header="heater,fan,temp",
               comments="")
    return path, IOData(np.column_stack([u1, u2]), y, 1.0, input_names=["heater", "fan"],
                        output_names=["temp"])


def test_select_order_of_two_inputs_searches_each_inputs_delays(capsys, tmp_path):
    """delayest finds one delay per input; --select-order searched one nk for both (it
    picked nk = [1, 1], fit 39 %). Now each input's delays are d - 1 .. d + 1 around its own
    estimate and nb is per input, as in select_order: the command's choice is the library's
    on the same split records, their estimation means removed."""
    from rlsfilt import select_order

    csv, data = _two_delays_csv(tmp_path / "two.csv")
    code, out, err = _run(capsys, "identify", csv, "-u", "heater", "-u", "fan", "-y", "temp",
                          "--select-order", "--split", "0.7", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert res["metadata"]["delay_estimate"] == [1, 8] and res["nk"] == [1, 8]
    est, val = data.split(0.7)
    from rlsfilt.exceptions import OrderSelectionWarning

    with pytest.warns(OrderSelectionWarning, match="upper edge of the `nb\\[heater\\]` range"):
        sel = select_order(est, na=range(0, 6), nb=[range(1, 6)] * 2,
                           nk=[range(0, 3), range(7, 10)], validation=val, offset="mean")
    assert (res["na"], tuple(res["nb"]), tuple(res["nk"])) == sel.best
    assert res["fit_percent"] > 80
    # the edge warning of a per-input order names the command's option
    assert "upper edge of `nb[heater]` (--max-order 5): raise --max-order" in err
    assert "widen `nb[" not in err
    # the text output says which delays were searched for each input
    code, out, err = _run(capsys, "identify", csv, "-u", "heater", "-u", "fan", "-y", "temp",
                          "--select-order", "--max-order", "3")
    assert "delayest finds nk = 1,8; orders searched with nk in heater 0..2; fan 7..9" in out
    # given delays are kept per input
    code, out, err = _run(capsys, "identify", csv, "-u", "heater", "-u", "fan", "-y", "temp",
                          "--select-order", "--nk", "1,8", "--max-order", "3", "--json")
    assert code == 0, err
    assert json.loads(out)["nk"] == [1, 8]


def test_per_input_edge_warnings_name_the_command_options():
    import argparse

    from rlsfilt.cli import _option_names

    msg = ("the best structure (na, nb[heater], nb[fan], nk[heater], nk[fan]) = (4, 5, 5, 1, 9) "
           "is at the upper edge of the `nb[heater]` range (1..5): widen `nb[heater]` upwards; "
           "and at the upper edge of the `nk[fan]` range (7..9): widen `nk[fan]` upwards (the "
           "best may lie outside the grid)")
    out = _option_names(msg, argparse.Namespace(max_order=5, delay_range=None))
    assert "the upper edge of `nb[heater]` (--max-order 5): raise --max-order" in out
    assert ("the upper edge of the delays tried (`nk[fan]` (7..9)): widen them with "
            "--delay-range LO:HI") in out
    assert "widen `nb" not in out and "widen `nk" not in out
