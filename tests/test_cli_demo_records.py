"""`rlsfilt demo --plant heat_exchanger`: operating point, dead time, two runs."""

import json

import numpy as np
import pytest

from rlsfilt.cli import main
from rlsfilt.datasets import heat_exchanger


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_demo_heat_exchanger_estimates_on_one_run_and_validates_on_the_other(capsys):
    code, out, err = _run(capsys, "demo", "--plant", "heat_exchanger", "--json", "-q")
    assert code == 0, err
    res = json.loads(out)
    ds = heat_exchanger(rng=0)
    run1 = ds.getexp("run1")
    # oracle: least squares on the deviations of run1 from its means, rows t >= max_lag
    u = np.asarray(run1.u) - np.mean(run1.u)
    y = np.asarray(run1.y) - np.mean(run1.y)
    t = np.arange(9, len(y))
    Phi = np.column_stack([-y[t - 1], -y[t - 2], u[t - 8], u[t - 9]])
    theta = np.linalg.lstsq(Phi, y[t], rcond=None)[0]
    np.testing.assert_allclose(res["theta"], theta, rtol=1e-9)
    np.testing.assert_allclose(res["metadata"]["theta_batch"], theta, rtol=1e-9)
    np.testing.assert_array_equal(res["metadata"]["theta_true"], ds.theta)
    assert (res["na"], res["nb"], res["nk"]) == (2, [2], [8])
    # validated on the fresh run, in the units of the data (the model keeps the means)
    assert res["n_samples"] == 800 and res["metadata"]["validated_on"] == "experiment run2"
    assert res["metadata"]["inputs"] == ["flow"] and res["metadata"]["output"] == "T_out"
    assert res["plant_comparison"]["dc_gain_error"] < 0.02
    assert res["fit_percent"] > 70


def test_demo_heat_exchanger_text_and_figure(capsys, tmp_path):
    png = tmp_path / "he.png"
    code, out, err = _run(capsys, "demo", "--plant", "heat_exchanger", "--samples", "400",
                          "--plot", str(png))
    assert code == 0, err
    assert "estimated on run1 (400 samples), validated on run2 (400 samples, fresh data)" in out
    assert "operating point: constant (means removed: flow = " in out
    assert "Verdict:" in out and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("option", ["--lam", "--noise"])
def test_demo_heat_exchanger_options(capsys, option):
    value = "0.995" if option == "--lam" else "0.001"
    code, out, err = _run(capsys, "demo", "--plant", "heat_exchanger", option, value, "-q")
    assert code == 0, err
    assert "Validation of ARX(na=2, nb=2, nk=8, offset='mean')" in out
