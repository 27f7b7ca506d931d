"""The ``rlsfilt`` command line, driven through ``main([...])`` as a user's shell would."""

import json
import subprocess
import sys

import control
import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt.cli import main

A_TRUE = [-1.5, 0.7]
B1_TRUE = [1.0, 0.5]
B2_TRUE = [0.3]


def _write_csv(path, header, rows, fmt="{:.12g}", sep=","):
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(sep.join(header) + "\n")
        for r in rows:
            fh.write(sep.join(fmt.format(v) if not isinstance(v, str) else v for v in r) + "\n")
    return str(path)


@pytest.fixture
def record(rng):
    """Two-input ARX record: nk = 1 for u1 (nb = 2), nk = 2 for u2 (nb = 1), dt = 0.1 s."""
    n = 500
    u1 = rng.standard_normal(n)
    u2 = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    e = 0.05 * rng.standard_normal(n)
    a = [1.0] + A_TRUE
    y = (lfilter([0.0] + B1_TRUE, a, u1) + lfilter([0.0, 0.0] + B2_TRUE, a, u2)
         + lfilter([1.0], a, e))
    t = 0.1 * np.arange(n)
    return dict(t=t, u1=u1, u2=u2, y=y)


@pytest.fixture
def csv_file(tmp_path, record):
    rows = zip(record["t"], record["u1"], record["u2"], record["y"])
    return _write_csv(tmp_path / "data.csv", ["t", "u1", "u2", "y"], rows)


def _regression(record, na=2, nb=(2, 1), nk=(1, 2)):
    """Oracle regressors written out independently of the CLI."""
    y, us = record["y"], [record["u1"], record["u2"]]
    start = max([na] + [k + b - 1 for b, k in zip(nb, nk)])
    rows = []
    for t in range(start, len(y)):
        row = [-y[t - i] for i in range(1, na + 1)]
        for u, b, k in zip(us, nb, nk):
            row += [u[t - k - i] for i in range(b)]
        rows.append(row)
    return np.array(rows), y[start:]


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


IDENT = ("identify", "{csv}", "--input", "u1", "--input", "u2", "--output", "y",
         "--na", "2", "--nb", "2,1", "--nk", "1,2")


def _ident_args(csv, *extra):
    return [a.format(csv=csv) for a in IDENT] + list(extra)


# ----------------------------------------------------------------------
# identify: numbers against independent oracles
# ----------------------------------------------------------------------
def test_identify_json_matches_least_squares(capsys, csv_file, record):
    import statsmodels.api as sm

    code, out, err = _run(capsys, *_ident_args(csv_file, "--json", "--detrend", "none"))
    assert code == 0, err
    res = json.loads(out)
    Phi, z = _regression(record)
    ols = sm.OLS(z, Phi).fit()
    np.testing.assert_allclose(res["theta"], ols.params, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(res["theta_std"], ols.bse, rtol=1e-8)
    np.testing.assert_allclose(res["noise_variance"], ols.scale, rtol=1e-10)
    assert res["na"] == 2 and res["nb"] == [2, 1] and res["nk"] == [1, 2]
    np.testing.assert_allclose(res["a"], ols.params[:2], rtol=1e-10)
    np.testing.assert_allclose(res["b"][0], ols.params[2:4], rtol=1e-10)
    np.testing.assert_allclose(res["b"][1], ols.params[4:], rtol=1e-10)
    assert res["theta_names"] == ["a1", "a2", "b1[u1]", "b2[u1]", "b1[u2]"]
    # the estimate is close to the truth (standard errors ~ 2e-3)
    np.testing.assert_allclose(res["theta"], A_TRUE + B1_TRUE + B2_TRUE, atol=0.01)
    assert res["n_samples"] == 500 and res["n_used"] == 498


def test_identify_json_is_the_report_dict(capsys, csv_file, record, tmp_path):
    """The CLI is a thin layer: --json prints exactly json.dumps(report.to_dict()) of the same
    fit made with the library (the default --detrend constant is ARX(offset='mean')); the
    text is two context lines and report.summary(), the figure report.plot()."""
    from rlsfilt import ARX, IOData, validate

    code, out, err = _run(capsys, *_ident_args(csv_file, "--json", "--dt", "0.1"))
    assert code == 0, err
    # the same numbers as the CLI read them (the CSV holds 12 significant digits)
    table = np.genfromtxt(csv_file, delimiter=",", names=True)
    data = IOData(np.column_stack([table["u1"], table["u2"]]), table["y"], 0.1,
                  input_names=["u1", "u2"], output_names=["y"])
    model = ARX(2, [2, 1], [1, 2], dt=0.1, offset="mean").fit(data)
    report = validate(model, data, max_lag="auto", skip_undefined=True,
                      metadata={"source": csv_file, "inputs": ["u1", "u2"], "output": "y",
                                "detrend": "constant", "experiments": ["exp1"],
                                "experiment_lengths": [500],
                                "validated_on": "the estimation data",
                                "validation_start": 0})
    assert out == json.dumps(report.to_dict()) + "\n"
    code, text, _ = _run(capsys, *_ident_args(csv_file, "--dt", "0.1"))
    means = ", ".join(f"{n} = {table[n].mean():.6g}" for n in ("u1", "u2", "y"))
    assert text == (f"data: '{csv_file}', 500 samples, sample time 0.1 s\n"
                    f"detrend: constant (means removed: {means}; the model keeps them and "
                    "predicts in the units of the data)\n\n" + str(report.summary()) + "\n")
    png = tmp_path / "fig.png"
    _run(capsys, *_ident_args(csv_file, "--dt", "0.1", "--plot", str(png)))
    assert len(report.plot().axes) >= 3 and png.stat().st_size > 0


def test_identify_fit_percent_against_a_plain_simulation(capsys, csv_file, record):
    code, out, _ = _run(capsys, *_ident_args(csv_file, "--json", "--detrend", "none"))
    res = json.loads(out)
    # the library's default (MATLAB compare's 'e'): the simulation of the identified
    # difference equation from the initial condition that fits the record best, by hand:
    # the forced response plus the free responses of a(q) y = 0 (two of them, the model's
    # largest lag L = 2), weighted by least squares
    a, (b1, b2) = res["a"], res["b"]
    y, u1, u2 = record["y"], record["u1"], record["u2"]
    L, N = 2, len(y)
    forced = np.zeros(N)
    for t in range(N):
        forced[t] = (-a[0] * forced[t - 1] * (t >= 1) - a[1] * forced[t - 2] * (t >= 2)
                     + b1[0] * u1[t - 1] * (t >= 1) + b1[1] * u1[t - 2] * (t >= 2)
                     + b2[0] * u2[t - 2] * (t >= 2))
    free = np.zeros((N, L))
    free[:L] = np.eye(L)
    for t in range(L, N):
        free[t] = -a[0] * free[t - 1] - a[1] * free[t - 2]
    y_sim = forced + free @ np.linalg.lstsq(free, y - forced, rcond=None)[0]
    expected = 100 * (1 - np.linalg.norm(y - y_sim) / np.linalg.norm(y - y.mean()))
    np.testing.assert_allclose(res["fit_percent"], expected, rtol=1e-9)
    assert res["fit_percent"] > 90 and res["initial_condition"] == "estimate"
    # the one-step predictor of ARX uses the measured past (a finite filter): from the
    # estimated state its first L predictions are exact, the others are Phi @ theta
    Phi, z = _regression(record)
    pred = Phi @ np.asarray(res["theta"])
    expected = 100 * (1 - np.linalg.norm(z - pred) / np.linalg.norm(y - y.mean()))
    np.testing.assert_allclose(res["fit_percent_prediction"], expected, rtol=1e-9)


def test_identify_transfer_functions_for_python_control(capsys, csv_file, record):
    code, out, _ = _run(capsys, *_ident_args(csv_file, "--json", "--dt", "0.1"))
    res = json.loads(out)
    T = np.arange(500) * 0.1
    y_ctrl = np.zeros(500)
    for col, tf in zip(("u1", "u2"), res["transfer_functions"]):
        assert tf["variable"] == "z" and tf["dt"] == 0.1
        y_ctrl += control.forced_response(control.tf(tf["num"], tf["den"], tf["dt"]), T,
                                          record[col]).outputs
    a = np.r_[1.0, res["a"]]
    y_lfilter = (lfilter(np.r_[0.0, res["b"][0]], a, record["u1"])
                 + lfilter(np.r_[0.0, 0.0, res["b"][1]], a, record["u2"]))
    np.testing.assert_allclose(y_ctrl, y_lfilter, rtol=1e-9, atol=1e-9)


def test_identify_ljung_box_matches_statsmodels(capsys, csv_file, record):
    from statsmodels.stats.diagnostic import acorr_ljungbox

    code, out, _ = _run(capsys, *_ident_args(csv_file, "--json"))
    res = json.loads(out)
    Phi, z = _regression(record)
    e = z - Phi @ np.asarray(res["theta"])
    lb = acorr_ljungbox(e, lags=[25])
    tests = res["residual_tests"]
    assert tests["max_lag"] == 25 and tests["ljung_box_df"] == 25 and tests["alpha"] == 0.01
    np.testing.assert_allclose(tests["ljung_box"], lb["lb_stat"].iloc[0], rtol=1e-9)
    np.testing.assert_allclose(tests["ljung_box_pvalue"], lb["lb_pvalue"].iloc[0], rtol=1e-7)
    np.testing.assert_allclose(tests["autocorr_band"], 2.5758293 / np.sqrt(len(e)), rtol=1e-6)
    assert tests["white"] == (tests["ljung_box_pvalue"] > 0.01)
    assert tests["independent"] == (tests["independence_pvalue"] > 0.01)


def test_identify_flags_an_underfitted_model(capsys, csv_file):
    # a FIR model (na = 0) of an AR plant leaves coloured residuals
    code, out, _ = _run(capsys, "identify", csv_file, "-u", "u1", "-u", "u2", "-y", "y",
                        "--na", "0", "--json")
    tests = json.loads(out)["residual_tests"]
    assert tests["white"] is False and tests["ljung_box_pvalue"] < 1e-6


def test_identify_rls_equals_ls_and_forgetting_changes_it(capsys, csv_file):
    _, out_ls, _ = _run(capsys, *_ident_args(csv_file, "--json"))
    _, out_rls, _ = _run(capsys, *_ident_args(csv_file, "--json", "--method", "rls"))
    ls, rls = json.loads(out_ls), json.loads(out_rls)
    np.testing.assert_allclose(rls["theta"], ls["theta"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(rls["theta_std"], ls["theta_std"], rtol=1e-7)
    _, out_f, _ = _run(capsys, *_ident_args(csv_file, "--json", "--method", "rls",
                                            "--lam", "0.95"))
    forget = json.loads(out_f)
    assert forget["lam"] == 0.95 and forget["method"] == "rls"
    assert np.max(np.abs(np.subtract(forget["theta"], ls["theta"]))) > 1e-4


@pytest.mark.parametrize("mode", ["directional", "constant_trace", "efra", "variable"])
def test_identify_forgetting_modes_match_the_filter(capsys, tmp_path, mode):
    from rlsfilt import ARX, RecursiveLeastSquares
    from rlsfilt.datasets import time_varying

    ds = time_varying(n_samples=800, rng=1)
    path = _write_csv(tmp_path / "tv.csv", ["u", "y"], zip(ds.u, ds.y))
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--method", "rls",
                          "--lam", "0.97", "--forgetting", mode, "--json", "--detrend", "none")
    assert code == 0, err
    res = json.loads(out)
    assert res["forgetting"] == mode
    # oracle: the filter run directly on ARX's regressors with the same batch start
    ref = ARX(2, 2, 1).fit(ds.u, ds.y, method="rls", lam=0.97)
    Phi, z = ref.regressors(ds.u, ds.y)
    rls = RecursiveLeastSquares(4, lam=0.97, forgetting=mode)
    rls.initialize(z[:ref.k0_], Phi[:ref.k0_])
    rls.batch_filter(z[ref.k0_:], Phi[ref.k0_:])
    np.testing.assert_allclose(res["theta"], rls.x.ravel(), rtol=1e-12, atol=1e-14)
    # the CLI is a thin layer: the same numbers as ARX.fit with the forgetting mode
    model = ARX(2, 2, 1).fit(ds.u, ds.y, method="rls", lam=0.97, forgetting=mode)
    np.testing.assert_allclose(res["theta"], model.theta_, rtol=1e-12, atol=1e-14)
    assert res["k0"] == model.k0_
    # every mode tracks the jump: close to the parameters in force at the end
    np.testing.assert_allclose(res["theta"], ds.theta_true[-1], atol=0.12)


@pytest.mark.parametrize("method, mu", [("nlms", 0.5), ("lms", 0.01), ("nlms", None)])
def test_identify_gradient_methods_are_the_filter_on_the_rows(capsys, tmp_path, method, mu):
    """--method nlms|lms (--mu): the filter run by hand on ARX's regressor rows (1e-12)."""
    from rlsfilt import ARX, LMS, NLMS
    from rlsfilt.datasets import time_varying

    ds = time_varying(n_samples=800, rng=1)
    path = _write_csv(tmp_path / "tv.csv", ["u", "y"], zip(ds.u, ds.y))
    extra = () if mu is None else ("--mu", str(mu))
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--method", method,
                          *extra, "--json", "--detrend", "none")
    assert code == 0, err
    res = json.loads(out)
    assert res["method"] == method and res["theta_std"] == [None] * 4
    Phi, z = ARX(2, 2, 1).regressors(ds.u, ds.y)
    filt = {"nlms": NLMS, "lms": LMS}[method](4, **({} if mu is None else {"mu": mu}))
    filt.batch_filter(z, Phi)
    np.testing.assert_allclose(res["theta"], filt.x[:, 0], rtol=1e-12, atol=1e-14)


def test_identify_window_is_least_squares_over_the_last_rows(capsys, tmp_path):
    from rlsfilt import ARX
    from rlsfilt.datasets import time_varying

    ds = time_varying(n_samples=800, rng=2)
    path = _write_csv(tmp_path / "tv.csv", ["u", "y"], zip(ds.u, ds.y))
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--method", "rls",
                          "--window", "120", "--json", "--detrend", "none")
    assert code == 0, err
    res = json.loads(out)
    assert res["form"] == "window"
    # validated on the samples of the last window (the estimate describes them only)
    assert res["metadata"]["validation_start"] == 800 - (120 + 2)
    assert "the last window of 120 rows" in res["metadata"]["validation_note"]
    Phi, z = ARX(2, 2, 1).regressors(ds.u, ds.y)
    ref = np.linalg.lstsq(Phi[-120:], z[-120:], rcond=None)[0]
    np.testing.assert_allclose(res["theta"], ref.ravel(), rtol=1e-9, atol=1e-12)
    # the whole record's least squares differs (the plant changes): the window mattered
    full = np.linalg.lstsq(Phi, z, rcond=None)[0]
    assert np.max(np.abs(full.ravel() - res["theta"])) > 1e-3


def test_error_gradient_and_window_options(capsys, csv_file):
    base = ("identify", csv_file, "-u", "u1", "-y", "y")
    r = _run(capsys, *base, "--mu", "0.1")
    _assert_one_line_error(*r, "--mu needs --method nlms or lms")
    r = _run(capsys, *base, "--method", "nlms", "--lam", "0.9")
    _assert_one_line_error(*r, "--lam 0.9 needs --method rls or riv")
    r = _run(capsys, *base, "--window", "50")
    _assert_one_line_error(*r, "--window needs --method rls (--model arx); got --method ls")
    r = _run(capsys, *base, "--method", "rls", "--window", "50", "--lam", "0.9")
    _assert_one_line_error(*r, "--window replaces forgetting: give --window or --lam, not both")
    r = _run(capsys, *base, "--method", "rls", "--window", "2")
    _assert_one_line_error(*r, "ARX: `window` must be >= 4; got 2")
    r = _run(capsys, *base, "--model", "oe", "--method", "nlms")
    _assert_one_line_error(*r, "--method nlms does not apply to --model oe")
    r = _run(capsys, *base, "--method", "lms", "--mu", "5")
    _assert_one_line_error(*r, "--method lms diverged (the estimate is not finite): lower --mu "
                               "(got 5)")
    for option, value in (("--mu", "0"), ("--mu", "inf"), ("--window", "0")):
        r = _run(capsys, *base, option, value)
        assert r[0] == 2 and f"argument {option}: must be" in r[2]


def test_identify_text_report(capsys, csv_file):
    code, out, err = _run(capsys, *_ident_args(csv_file, "--time", "t"))
    assert code == 0 and err == ""
    # the text is the library's ValidationReport.summary(), after the data and its detrending
    assert out.startswith(f"data: '{csv_file}', 500 samples, sample time 0.1 s\n"
                          "detrend: constant (means removed: u1 = ")
    assert "Validation of ARX(na=2, nb=[2, 1], nk=[1, 2], offset='mean') on 500 samples" in out
    assert "operating point: u1 = " in out
    assert "sample time 0.1" in out
    for name in ("a1", "a2", "b1[u1]", "b2[u1]", "b1[u2]"):
        assert f"\n  {name} " in out
    assert "std err" in out and "Simulation fit" in out and "P>|t|" in out
    assert "whiteness (Ljung-Box" in out and "independence of inputs (F" in out
    assert "AIC" in out and "BIC" in out


def test_identify_noise_free_data_keeps_the_table_columns(capsys, tmp_path):
    """An exact fit has standard errors at or near round-off and t values near 1e15 or
    infinite (the QR of [Phi, y] can give zero residuals): every row of the coefficient
    table still splits into name, coef, std err, t, P>|t| and the interval."""
    rng = np.random.default_rng(3)
    u = rng.standard_normal(400)
    y = lfilter([0.0, 1.0], [1.0, -0.5], u)
    csv = tmp_path / "exact.csv"
    _write_csv(csv, ["u", "y"], np.column_stack([u, y]), fmt="{:.17g}")
    code, out, err = _run(capsys, "identify", str(csv), "--input", "u", "--output", "y",
                          "--na", "1", "--nb", "1", "--detrend", "none")
    assert code == 0 and err == ""
    rows = {line.split()[0]: line.split() for line in out.splitlines()
            if line.startswith(("  a1 ", "  b1 "))}
    assert set(rows) == {"a1", "b1"}
    for name, truth in (("a1", -0.5), ("b1", 1.0)):
        assert len(rows[name]) == 7, rows[name]
        est, sd, t = map(float, rows[name][1:4])
        assert est == pytest.approx(truth, abs=1e-12)
        # round-off residuals, or none at all when the QR solution is the exact one
        assert abs(t) > 1e9 and (t == pytest.approx(est / sd, rel=0.06) if sd else np.isinf(t))


def test_identify_single_input_defaults_and_save_params(capsys, tmp_path, record):
    path = _write_csv(tmp_path / "siso.csv", ["u", "y"],
                      zip(record["u1"], lfilter([0, 1.0, 0.5], [1] + A_TRUE, record["u1"])))
    params = tmp_path / "params.json"
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--json",
                          "--save-params", str(params), "--detrend", "none")
    assert code == 0, err
    res = json.loads(out)
    assert json.loads(params.read_text()) == res
    # noise-free data: the default na=2, nb=2, nk=1 recovers the plant to round-off
    np.testing.assert_allclose(res["a"], A_TRUE, atol=1e-9)
    np.testing.assert_allclose(res["b"], [B1_TRUE], atol=1e-9)
    assert res["theta_names"] == ["a1", "a2", "b1", "b2"]
    assert res["dt"] == 1.0


def test_identify_select_order_finds_the_true_orders(capsys, tmp_path, record):
    path = _write_csv(tmp_path / "siso.csv", ["u", "y"],
                      zip(record["u1"], record["y"] - lfilter([0, 0, 0.3], [1] + A_TRUE,
                                                              record["u2"])))
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--select-order",
                          "--json")
    assert code == 0, err
    res = json.loads(out)
    assert (res["na"], res["nb"], res["nk"]) == (2, [2], [1])
    sel = res["metadata"]["order_selection"]
    # na in 0..5, nb in 1..5 (the library's default largest order), nk in 1..4
    assert sel["criterion"] == "bic" and len(sel["candidates"]) == 6 * 5 * 4
    assert sel["best"] == [2, 2, 1]
    best = min(sel["candidates"], key=lambda c: c["bic"])
    assert (best["na"], best["nb"], best["nk"]) == (2, 2, 1)
    # with --nk given only na and nb are searched
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--select-order",
                          "--nk", "1", "--max-order", "3", "--json")
    assert code == 0, err
    assert len(json.loads(out)["metadata"]["order_selection"]["candidates"]) == 4 * 3


def test_identify_plot(capsys, csv_file, tmp_path):
    png = tmp_path / "fig.png"
    code, out, err = _run(capsys, *_ident_args(csv_file, "--method", "rls", "--plot", str(png)))
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"figure saved to {png}" in out


def test_identify_semicolon_and_comments(capsys, tmp_path, record):
    path = tmp_path / "semi.csv"
    lines = ["# exported by a logger", "u; y"]
    y = lfilter([0, 1.0, 0.5], [1] + A_TRUE, record["u1"])
    lines += [f"{a:.12g}; {b:.12g}" for a, b in zip(record["u1"], y)]
    path.write_text("\n".join(lines) + "\n")
    code, out, err = _run(capsys, "identify", str(path), "-u", "u", "-y", "y", "--json",
                          "--detrend", "none")
    assert code == 0, err
    np.testing.assert_allclose(json.loads(out)["a"], A_TRUE, atol=1e-9)


def test_identify_tab_separated_with_time_column(capsys, tmp_path, record):
    y = lfilter([0, 1.0, 0.5], [1] + A_TRUE, record["u1"])
    path = _write_csv(tmp_path / "tab.tsv", ["time", "volts", "speed"],
                      zip(record["t"], record["u1"], y), sep="\t")
    code, out, err = _run(capsys, "identify", path, "-u", "volts", "-y", "speed", "--time",
                          "time", "--json", "--detrend", "none")
    assert code == 0, err
    res = json.loads(out)
    assert res["dt"] == pytest.approx(0.1, rel=1e-12) and res["metadata"]["inputs"] == ["volts"]
    np.testing.assert_allclose(res["a"], A_TRUE, atol=1e-9)
    assert res["transfer_functions"][0]["dt"] == res["dt"]
    # an explicit delimiter that does not match: the header is one unknown column
    r = _run(capsys, "identify", path, "-u", "volts", "-y", "speed", "--delimiter", ";")
    _assert_one_line_error(*r, "column 'volts' not found")


# ----------------------------------------------------------------------
# demo
# ----------------------------------------------------------------------
def test_demo_report(capsys):
    code, out, err = _run(capsys, "demo")
    assert code == 0 and err == ""
    for text in ("estimate", "std err", "true", "batch LS", "Simulation fit",
                 "whiteness", "Comparison with the true plant", "vs plant", "DC-gain"):
        assert text in out


def test_demo_json_against_truth_and_batch(capsys):
    from rlsfilt.datasets import dc_motor

    code, out, _ = _run(capsys, "demo", "--json", "--samples", "800", "--seed", "3")
    assert code == 0
    res = json.loads(out)
    ds = dc_motor(n_samples=800, rng=3)
    assert (res["na"], res["nb"], res["nk"]) == (ds.na, [ds.nb], [ds.nk])
    np.testing.assert_array_equal(res["metadata"]["theta_true"], ds.theta)
    # RLS with the batch start equals batch least squares on all data
    np.testing.assert_allclose(res["theta"], res["metadata"]["theta_batch"], rtol=1e-9,
                               atol=1e-15)
    Phi = np.column_stack([-ds.y[1:-1], -ds.y[:-2], ds.u[1:-1], ds.u[:-2]])
    np.testing.assert_allclose(res["theta"], np.linalg.lstsq(Phi, ds.y[2:], rcond=None)[0],
                               rtol=1e-8, atol=1e-14)
    # and the truth lies within 4 standard errors
    err = (np.abs(np.subtract(res["theta"], res["metadata"]["theta_true"]))
           / np.asarray(res["theta_std"]))
    assert np.all(err < 4)
    pc = res["plant_comparison"]
    np.testing.assert_allclose(pc["dc_gain_true"], float(np.real(ds.plant.dcgain())),
                               rtol=1e-10)
    np.testing.assert_allclose(pc["dc_gain_model"], sum(res["b"][0]) / (1 + sum(res["a"])),
                               rtol=1e-9)
    poles = np.sort_complex(np.roots([1.0] + res["a"]))
    np.testing.assert_allclose([complex(*p) for p in pc["poles_model"]], poles, atol=1e-10)
    np.testing.assert_allclose([complex(*p) for p in pc["poles_true"]],
                               np.sort_complex(np.roots(np.r_[1.0, ds.a])), atol=1e-10)
    assert pc["frequency_error"] < 0.1 and pc["step_error"] < 0.02


def test_demo_every_plant(capsys):
    from rlsfilt.datasets import PLANTS

    for name in PLANTS:
        code, out, err = _run(capsys, "demo", "--plant", name, "--json", "--samples", "600")
        assert code == 0, (name, err)
        res = json.loads(out)
        # every plant is recovered to within 5 standard errors (for the time-varying plant:
        # the parameters in force at the end, tracked with forgetting)
        err = (np.abs(np.subtract(res["theta"], res["metadata"]["theta_true"]))
               / np.asarray(res["theta_std"]))
        assert np.all(err < 5), (name, err)


def test_demo_time_varying_tracks_with_forgetting(capsys):
    from rlsfilt.datasets import time_varying

    code, out, _ = _run(capsys, "demo", "--plant", "time_varying")
    assert code == 0
    assert "true at the end" in out and "lam = 0.98" in out
    assert "validation (on the last 150 samples, three memory lengths of lam = 0.98)" in out
    assert "whiteness (Ljung-Box" in out
    code, out, _ = _run(capsys, "demo", "--plant", "time_varying", "--json")
    res = json.loads(out)
    ds = time_varying(rng=0)
    np.testing.assert_array_equal(res["metadata"]["theta_true"], ds.theta_true[-1])
    np.testing.assert_allclose(res["theta"], ds.theta_true[-1], atol=0.02)
    # batch least squares averages both halves and misses the end by far more
    assert np.max(np.abs(np.subtract(res["metadata"]["theta_batch"], ds.theta_true[-1]))) > 0.1


def test_demo_plot(capsys, tmp_path):
    png = tmp_path / "demo.png"
    code, _, err = _run(capsys, "demo", "--samples", "300", "--plot", str(png))
    assert code == 0, err
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_no_command_prints_help(capsys):
    code, out, _ = _run(capsys)
    assert code == 0 and "demo" in out and "identify" in out


def test_progress_line_on_a_terminal(monkeypatch, capsys):
    import time

    from rlsfilt import cli

    monkeypatch.setattr(cli, "_PROGRESS_AFTER", 0.0)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    progress = cli._Progress(enabled=True)
    with progress.task("fitting"):
        time.sleep(0.6)
    err = capsys.readouterr().err
    assert "rlsfilt: fitting ... 0 s" in err and err.endswith("\r\x1b[K")
    # --quiet, or no terminal: nothing
    with cli._Progress(enabled=False).task("fitting"):
        time.sleep(0.3)
    assert capsys.readouterr().err == ""


def test_python_dash_m_entry_point():
    proc = subprocess.run([sys.executable, "-m", "rlsfilt", "--version"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0 and proc.stdout.startswith("rlsfilt ")


# ----------------------------------------------------------------------
# errors: one line on stderr, non-zero exit, never a traceback
# ----------------------------------------------------------------------
def _assert_one_line_error(code, out, err, match, expected_code=1):
    assert code == expected_code
    assert out == ""
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert match in lines[0], lines[0]


def test_error_missing_file(capsys, tmp_path):
    missing = tmp_path / "nope.csv"
    r = _run(capsys, "identify", str(missing), "-u", "u", "-y", "y")
    _assert_one_line_error(*r, f"file '{missing}' not found")


def test_error_directory(capsys, tmp_path):
    r = _run(capsys, "identify", str(tmp_path), "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "is a directory; expected a CSV file")


def test_error_unknown_column_lists_available(capsys, csv_file):
    r = _run(capsys, "identify", csv_file, "-u", "volts", "-y", "y")
    _assert_one_line_error(*r, "column 'volts' not found in")
    assert "available columns: t, u1, u2, y" in r[2]
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", "--time", "clock")
    _assert_one_line_error(*r, "column 'clock' not found")


def test_error_non_numeric_cell_names_row_and_column(capsys, tmp_path):
    rows = [["1", "2"], ["3", "abc"], ["5", "6"]]
    path = _write_csv(tmp_path / "bad.csv", ["u", "y"], rows)
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "line 3 (data row 2), column 'y': expected a number; got 'abc'")


def test_error_empty_and_nonfinite_cells(capsys, tmp_path):
    path = _write_csv(tmp_path / "gap.csv", ["u", "y"], [["1", "2"], ["", "4"]])
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "data row 2), column 'u': expected a number; got an empty cell")
    path = _write_csv(tmp_path / "nan.csv", ["u", "y"], [["1", "nan"]])
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "column 'y': expected a finite number; got 'nan'")


def test_error_ragged_row(capsys, tmp_path):
    path = _write_csv(tmp_path / "ragged.csv", ["u", "y"], [["1", "2"], ["3"]])
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "line 3 (data row 2) has 1 fields; the header has 2")


def test_error_empty_file_and_header_only(capsys, tmp_path):
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    r = _run(capsys, "identify", str(empty), "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "is empty; expected a header row and data rows")
    header = tmp_path / "header.csv"
    header.write_text("u,y\n")
    r = _run(capsys, "identify", str(header), "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "has a header but no data rows")


def test_error_too_few_rows(capsys, tmp_path, rng):
    path = _write_csv(tmp_path / "short.csv", ["u", "y"], rng.standard_normal((6, 2)))
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--na", "2", "--nb", "2")
    _assert_one_line_error(*r, "too few rows for the orders na=2, nb=2, nk=1 (4 parameters, "
                               "largest lag 2): need at least 7 data rows;")
    # 6 rows are enough for na=1, nb=2 (3 parameters)
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--na", "1", "--json")
    assert code == 0, err
    res = json.loads(out)
    assert len(res["theta"]) == 3 and "residual_tests" not in res
    assert res["validation_skipped"] == "only 4 residuals, too few for the residual tests"
    code, out, err = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--na", "1")
    assert code == 0 and "Residual tests skipped: only 4 residuals" in out


def test_error_rank_deficient_input(capsys, tmp_path):
    path = _write_csv(tmp_path / "const.csv", ["u", "y"], [[1.0, float(k % 3)] for k in range(50)])
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y")
    _assert_one_line_error(*r, "not persistently exciting")


def test_error_time_column(capsys, tmp_path):
    path = _write_csv(tmp_path / "t.csv", ["t", "u", "y"],
                      [[0.0, 1, 2], [0.1, 2, 3], [0.3, 3, 4], [0.4, 1, 1]])
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--time", "t")
    _assert_one_line_error(*r, "time column 't' is not uniformly sampled: steps range from "
                               "0.1 to 0.2")
    path = _write_csv(tmp_path / "t2.csv", ["t", "u", "y"],
                      [[0.0, 1, 2], [0.1, 2, 3], [0.1, 3, 4]])
    r = _run(capsys, "identify", path, "-u", "u", "-y", "y", "--time", "t")
    _assert_one_line_error(*r, "time column 't' must be strictly increasing; row 3")


def test_error_same_column_twice(capsys, csv_file):
    r = _run(capsys, "identify", csv_file, "-u", "y", "-y", "y")
    _assert_one_line_error(*r, "column 'y' is given as both --input and --output")
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-u", "u1", "-y", "y")
    _assert_one_line_error(*r, "column 'u1' is given twice as --input")


def test_error_forgetting_options(capsys, csv_file):
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", "--forgetting", "efra")
    _assert_one_line_error(*r, "--forgetting efra needs --method rls")
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", "--method", "rls",
             "--forgetting", "constant_trace")
    _assert_one_line_error(*r, "--forgetting constant_trace needs --lam < 1")
    # a forgetting factor without the recursive method was ignored (JSON: method ls, lam 0.9)
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", "--lam", "0.9")
    _assert_one_line_error(*r, "--lam 0.9 needs --method rls")
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", "--method", "ls", "--lam", "1")
    assert r[0] == 0 and r[2] == ""
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", "--forgetting", "fast")
    _assert_one_line_error(*r, "argument --forgetting: invalid choice: 'fast'", 2)


def test_error_orders_per_input_count(capsys, csv_file):
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-u", "u2", "-y", "y", "--nb", "1,2,3")
    _assert_one_line_error(*r, "--nb must give one value or one per input (2); got 3 values")


@pytest.mark.parametrize("option, value, message", [
    ("--na", "-1", "argument --na: must be >= 0; got -1"),
    ("--na", "two", "argument --na: must be an integer; got 'two'"),
    ("--nb", "0", "argument --nb: must be >= 1; got 0"),
    ("--nk", "1,-2", "argument --nk: must be >= 0; got -2"),
    ("--lam", "1.5", "argument --lam: must be in (0, 1]; got 1.5"),
    ("--lam", "0", "argument --lam: must be in (0, 1]; got 0"),
    ("--lam", "abc", "argument --lam: must be a number; got 'abc'"),
    ("--dt", "-0.1", "argument --dt: must be a positive number; got -0.1"),
    ("--method", "svd", "argument --method: invalid choice: 'svd'"),
    ("--plot", "fig.txt", "argument --plot: must be a .png, .pdf or .svg file name"),
    ("--max-order", "0", "argument --max-order: must be >= 1; got 0"),
])
def test_error_invalid_option_values(capsys, csv_file, option, value, message):
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", option, value)
    _assert_one_line_error(*r, message, expected_code=2)
    assert r[2].startswith("rlsfilt identify: error:")


def test_error_usage(capsys, csv_file):
    r = _run(capsys, "identify", csv_file, "-y", "y")
    _assert_one_line_error(*r, "the following arguments are required: --input", 2)
    r = _run(capsys, "identify", csv_file, "-u", "u1", "-y", "y", "--dt", "1", "--time", "t")
    _assert_one_line_error(*r, "not allowed with argument", 2)
    r = _run(capsys, "fit")
    _assert_one_line_error(*r, "invalid choice: 'fit'", 2)
    r = _run(capsys, "demo", "--plant", "nope")
    _assert_one_line_error(*r, "argument --plant: invalid choice: 'nope'", 2)


def test_error_unwritable_outputs(capsys, csv_file, tmp_path):
    target = tmp_path / "no" / "such" / "dir"
    r = _run(capsys, *_ident_args(csv_file, "--save-params", str(target / "p.json")))
    _assert_one_line_error(*r, "cannot write")


def test_identify_rls_on_noise_free_data_skips_the_residual_tests(capsys, tmp_path):
    """y(t) = u(t-1) exactly: recursive least squares fits it with zero residuals, so the
    residual tests are undefined; the report says so instead of failing the command."""
    u = np.sign(np.random.default_rng(4).standard_normal(300))
    csv = _write_csv(tmp_path / "exact.csv", ["u", "y"], np.column_stack([u, np.r_[0.0, u[:-1]]]))
    argv = ("identify", csv, "--input", "u", "--output", "y", "--na", "0", "--nb", "1",
            "--method", "rls", "--detrend", "none")
    code, out, err = _run(capsys, *argv)
    assert code == 0 and err == ""
    assert "Residual tests skipped: the residuals are zero or constant (an exact fit)" in out
    assert "Simulation fit      : 100.00%" in out
    code, out, err = _run(capsys, *argv, "--json")
    res = json.loads(out)
    assert code == 0 and err == ""
    assert res["theta"] == [1.0] and "exact fit" in res["validation_skipped"]


def test_warnings_are_one_line_on_stderr(capsys, tmp_path):
    """Covariance windup (input held constant, lam = 0.9) triggers the NumericalWarning of the
    filter: the command prints it as one `rlsfilt: warning:` line and goes on."""
    rng = np.random.default_rng(5)
    u = np.r_[rng.standard_normal(200), np.ones(600), rng.standard_normal(400)]
    y = lfilter([0.0, 1.0, 0.5], [1.0], u) + 0.01 * rng.standard_normal(len(u))  # FIR: while
    # u is held, every regressor row is [1, 1] and P grows as 0.9**-k across it
    csv = _write_csv(tmp_path / "windup.csv", ["u", "y"], np.column_stack([u, y]))
    code, out, err = _run(capsys, "identify", csv, "--input", "u", "--output", "y",
                          "--na", "0", "--nb", "2", "--method", "rls", "--lam", "0.9")
    assert code == 0 and "Simulation fit" in out
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("rlsfilt: warning: `P` is ill-conditioned")
    assert "at step" in lines[0]


def test_select_order_edge_warning_names_the_cli_options():
    import argparse

    from rlsfilt.cli import _option_names

    msg = ("the best structure (na, nb, nk) = (5, 2, 3) is at the upper edge of the `na` range "
           "(0..5): widen `na` upwards; and at the upper edge of the `nk` range (1..3): widen "
           "`nk` upwards (the best may lie outside the grid)")
    out = _option_names(msg, argparse.Namespace(max_order=5, delay_range=None))
    assert "`na` (--max-order 5): raise --max-order" in out
    assert "widen them with --delay-range LO:HI" in out
    assert "widen `na`" not in out and "widen `nk`" not in out
