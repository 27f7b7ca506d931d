"""`rlsfilt identify --model armax|oe|bj` and the IV methods of ARX on the command line.

Oracle: the library itself on the same record (the command line is a thin layer):
the printed parameters equal ``ARMAX(...).fit(...)`` on the record with the
estimation means removed, bit for bit.
"""

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARMAX, ARX, BJ, OE, IOData, compare
from rlsfilt.cli import main

U_OP, Y_OP = 40.0, 95.0


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(21)
    N = 1500
    u = rng.standard_normal(N)
    y = (lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u)
         + lfilter([1, 0.6], [1, -1.5, 0.7], 0.3 * rng.standard_normal(N)))
    return U_OP + u, Y_OP + y


@pytest.fixture
def csv_file(tmp_path, record):
    u, y = record
    path = tmp_path / "plant.csv"
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("flow,T\n")
        for a, b in zip(u, y):
            fh.write(f"{a:.17g},{b:.17g}\n")
    return path


def _deviations(u, y):
    return IOData(u - u.mean(), y - y.mean(), input_names=["flow"], output_names=["T"])


BASE = ("identify", "{csv}", "-u", "flow", "-y", "T", "--json")


def _args(csv, *extra):
    return [a.format(csv=csv) for a in BASE] + list(extra)


@pytest.mark.parametrize("model, extra, make", [
    ("armax", ("--na", "2", "--nb", "2", "--nc", "1"), lambda: ARMAX(2, 2, 1, 1, dt=1.0)),
    ("oe", ("--nb", "2", "--nf", "2"), lambda: OE(2, 2, 1, dt=1.0)),
    ("bj", ("--nb", "2", "--nc", "1", "--nd", "2", "--nf", "2"),
     lambda: BJ(2, 1, 2, 2, 1, dt=1.0)),
])
def test_family_model_equals_the_library_fit(capsys, csv_file, record, model, extra, make):
    code, out, err = _run(capsys, *_args(csv_file, "--model", model, "--dt", "1", *extra))
    assert code == 0, err
    res = json.loads(out)
    ref = make().fit(_deviations(*record))
    assert res["model"] == type(ref).__name__
    np.testing.assert_array_equal(res["theta"], ref.theta_)
    assert res["metadata"]["detrend"] == "constant"
    assert res["n_samples"] == len(record[0]) and res["unstable"] is False


def test_text_report_and_recursive_method(capsys, csv_file, record):
    code, out, err = _run(capsys, "identify", csv_file, "-u", "flow", "-y", "T", "--model",
                          "armax", "--nc", "1", "--method", "rpem", "--lam", "0.999")
    assert code == 0, err
    assert "recursive prediction-error method (RPEM)" in out
    assert "the model describes the deviations" in out
    ref = ARMAX(2, 2, 1, 1).fit(_deviations(*record), method="rpem", lam=0.999)
    assert f"{ref.theta_[0]:.6g}" in out


def test_split_validates_with_the_estimation_means(capsys, csv_file, record):
    code, out, err = _run(capsys, *_args(csv_file, "--model", "oe", "--nb", "2", "--nf", "2",
                                         "--split", "0.7", "--dt", "1"))
    assert code == 0, err
    u, y = record
    n = int(round(0.7 * len(u)))
    ue, ye = u[:n], y[:n]
    model = OE(2, 2, 1, dt=1.0).fit(ue - ue.mean(), ye - ye.mean())
    res = json.loads(out)
    np.testing.assert_array_equal(res["theta"], model.theta_)
    # the library's validate: the simulation from the initial state that fits best (compare)
    yv = y[n:] - ye.mean()
    c = compare(model, u[n:] - ue.mean(), yv)
    fit = 100 * (1 - np.linalg.norm(yv - c.y_hat) / np.linalg.norm(yv - yv.mean()))
    assert res["fit_percent"] == pytest.approx(fit, rel=1e-10)
    assert res["initial_condition"] == "estimate" and res["fit_start"] == 0


@pytest.mark.parametrize("method", ["iv", "riv"])
def test_arx_instrumental_variables(capsys, csv_file, record, method):
    code, out, err = _run(capsys, *_args(csv_file, "--method", method, "--dt", "1"))
    assert code == 0, err
    u, y = record
    ref = ARX(2, 2, 1, dt=1.0, offset="mean").fit(
        IOData(u, y, input_names=["flow"], output_names=["T"]), method=method)
    np.testing.assert_array_equal(json.loads(out)["theta"], ref.theta_)


@pytest.mark.parametrize("extra, message", [
    (("--nc", "1"), "--nc does not apply to --model arx (it is an order of --model armax "
                    "and bj)"),
    (("--model", "oe", "--na", "2"), "--na does not apply to --model oe"),
    (("--method", "pem"), "--method pem does not apply to --model arx; its methods are ls, "
                          "rls, iv, riv"),
    (("--model", "bj", "--method", "rls"), "--method rls does not apply to --model bj"),
    (("--model", "armax", "--lam", "0.9"), "--lam 0.9 needs --method rpem or rplr"),
    (("--method", "riv", "--forgetting", "efra"), "--forgetting efra needs --method rls"),
    (("--model", "armax", "--select-order"), "--select-order searches ARX orders"),
    (("--model", "armax", "--na", "800", "--nb", "800"), "too few rows for the orders "
                                                         "na=800, nb=800, nc=1, nk=1"),
])
def test_option_errors_are_one_line(capsys, csv_file, extra, message):
    code, out, err = _run(capsys, "identify", csv_file, "-u", "flow", "-y", "T", *extra)
    assert code == 1 and out == "" and "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], err
