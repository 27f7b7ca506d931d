"""Rich HTML display of the filters (``_repr_html_``): numbers against numpy, health in words."""

import re
import warnings

import numpy as np
import pytest

from rlsfilt import RecursiveLeastSquares, SlidingWindowRLS, SquareRootRLS
from rlsfilt._display import health


def _cells(html_text, row):
    """The <td> texts of the table row headed `row`."""
    m = re.search(rf"<tr><th>{re.escape(row)}</th>(.*?)</tr>", html_text)
    assert m, row
    return re.findall(r"<td>(.*?)</td>", m.group(1))


@pytest.fixture
def record(rng):
    H = rng.standard_normal((300, 3))
    z = H @ [1.0, -2.0, 0.5] + 0.1 * rng.standard_normal(300)
    return z, H


@pytest.mark.parametrize("make", [
    lambda: RecursiveLeastSquares(3, R=0.01),
    lambda: SquareRootRLS(3, R=0.01),
    lambda: SlidingWindowRLS(3, window=400, R=0.01),
], ids=["rls", "square_root", "sliding_window"])
def test_estimate_and_standard_deviations_match_least_squares(make, record):
    """After an exact batch start every filter equals least squares with covariance
    R (H^T H)^-1, so the table shows the lstsq estimate and sqrt(diag) of that matrix."""
    z, H = record
    f = make()
    f.initialize(z[:10], H[:10])
    f.batch_filter(z[10:], H[10:])
    theta = np.linalg.lstsq(H, z, rcond=None)[0]
    sd = np.sqrt(np.diag(0.01 * np.linalg.inv(H.T @ H)))
    out = f._repr_html_()
    assert f"<strong>{type(f).__name__}</strong>: 3 parameters, 1 output" in out
    assert "P is <strong>healthy</strong>" in out
    for i in range(3):
        est, std = (float(c) for c in _cells(out, f"x[{i}]"))
        assert est == pytest.approx(theta[i], rel=1e-5)   # 6 significant digits shown
        assert std == pytest.approx(sd[i], rel=1e-5)
    assert "R (noise variance)</th><td style='text-align:left'>0.01" in out


def test_settings_shown_and_long_states_cut(rng):
    f = RecursiveLeastSquares(30, dim_z=2, lam=0.98, gate=4.0, Q=1e-6)
    out = f._repr_html_()
    assert "30 parameters, 2 outputs" in out
    assert "<th>x[:, 0]</th><th>x[:, 1]</th><th>std dev</th>" in out
    assert "... 10 more parameters" in out and "<th>x[19]</th>" in out and "x[20]" not in out
    for label, value in (("forgetting factor lam", "0.98"), ("forgetting mode", "exponential"),
                         ("outlier gate (std devs)", "4"), ("updates so far", "0")):
        assert f"{label}</th><td style='text-align:left'>{value}</td>" in out
    assert "Q (random walk)" in out
    assert "outlier gate" not in RecursiveLeastSquares(2)._repr_html_()


def test_windup_is_reported_in_words():
    f = RecursiveLeastSquares(2, lam=0.9)
    H = np.tile([1.0, 0.0], (400, 1))                     # the second direction is never excited
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                    # the filter's own health warning
        f.batch_filter(np.ones(400), H)
    out = f._repr_html_()
    assert "P is <strong>ill-conditioned</strong>" in out
    eig = np.linalg.eigvalsh(f.P)
    assert f"condition number {eig[-1] / eig[0]:.6g}" in out


def test_health_verdicts():
    assert health(np.eye(2))[0] == "healthy"
    assert health(np.diag([1.0, np.nan]))[0] == "not finite"
    assert health(np.array([[1.0, 0.5], [0.0, 1.0]]))[0] == "not symmetric"
    assert health(np.diag([1.0, -1e-3]))[0] == "not positive definite"
    verdict, details = health(np.diag([1.0, 1e-9]), cond_max=1e6)
    assert verdict == "ill-conditioned" and "condition number 1e+09" in details


def test_report_shows_percent_and_the_verdict_in_words():
    from rlsfilt import ARX, validate
    from rlsfilt.datasets import dc_motor, mass_spring_damper

    d = dc_motor()
    rep = validate(ARX(*d.orders, dt=d.dt).fit(d.u, d.y), d.u, d.y, plant=d.plant)
    pc = rep.plant_comparison
    for text in (str(rep.summary()), rep._repr_html_()):
        assert f"{100 * pc.frequency_error:.4g}%" in text
        assert f"{100 * pc.dc_gain_error:.4g}%" in text
        assert f"{100 * pc.step_error:.4g}%" in text
    html_text = rep._repr_html_()
    assert "PASS: residual tests passed" in html_text and "&#10004;" in html_text
    d2 = mass_spring_damper()
    bad = validate(ARX(1, 1, 1, dt=d2.dt).fit(d2.u, d2.y), d2.u, d2.y)._repr_html_()
    assert "FAIL: residual tests FAILED" in bad and "&#10008;" in bad and "NOT white" in bad


# ----------------------------------------------------------------------
# banks, selections and trends (issue #32)
# ----------------------------------------------------------------------
def _looks_like_html(text, name):
    assert text.startswith("<div class='rlsfilt-display'>") and text.endswith("</div>")
    assert f"<strong>{name}" in text
    assert text.count("<table") == text.count("</table>")


def test_bank_html_and_repr_stay_short_for_many_channels():
    from rlsfilt import RLSBank
    from rlsfilt._display import bank_html

    bank = RLSBank(1000, 3, P0=4.0)
    bank.x = np.arange(3000.0).reshape(1000, 3)
    out = bank._repr_html_()
    _looks_like_html(out, "RLSBank")
    assert "1000 channels, 3 parameters each" in out
    assert out.count("<tr>") < 40 and "... 990 more channels ..." in out
    assert "<th>999</th><td>2997 ± 2</td>" in out and "<th>5</th>" not in out
    text = repr(bank)
    assert len(text.splitlines()) < 30 and "... 990 more channels ..." in text
    assert "RLSBank object" in text and "n_channels = 1000" in text
    assert "P = " in repr(RLSBank(3, 2))                 # few channels: every matrix, as before
    labelled = bank_html(RLSBank(2, 1), labels=["<b>", "ok"])
    assert "<th>&lt;b&gt;</th>" in labelled and "<b>" not in labelled


def test_selection_html_best_first_top_ten():
    from rlsfilt import select_order
    from rlsfilt.datasets import dc_motor
    from rlsfilt.validation.structure import StructureSelection

    d = dc_motor()
    sel = select_order(d.u, d.y, na=range(1, 5), nb=range(1, 5), nk=range(1, 3))
    out = sel._repr_html_()
    _looks_like_html(out, "OrderSelection")
    na, nb, nk = sel.best
    assert f"<tr><th>na={na} nb={nb} nk={nk} (best)</th>" in out
    assert out.count("<tr>") == 1 + 10 + 1 and f"... {len(sel.table) - 10} more candidates" in out

    class Model:
        pass

    cands = [{"orders": {"na": k}, "n_params": k, "loss": 1.0 / k, "error": None}
             for k in range(1, 4)]
    cands.append({"orders": {"na": 9}, "n_params": 9, "loss": np.nan, "error": "<b>bad</b>"})
    st = StructureSelection(cands, "aic", [3.0, 1.0, 2.0, np.nan], [Model()] * 4)
    out = st._repr_html_()
    _looks_like_html(out, "StructureSelection")
    rows = re.findall(r"<tr><th>(.*?)</th>", out)
    assert rows == ["candidate", "na=2 (best)", "na=3", "na=1"]
    assert "refused: &lt;b&gt;bad&lt;/b&gt;" in out and "<b>" not in out


def test_trend_html_shows_the_coefficients():
    from rlsfilt.data import detrend

    x = np.column_stack([np.arange(10.0), 5.0 + 3.0 * np.arange(10.0)])
    _, trend = detrend(x, type="linear")
    out = trend._repr_html_()
    _looks_like_html(out, "Trend")
    assert "<th>intercept</th><th>slope</th>" in out
    assert _cells(out, "column 1") == ["from sample 0", "5", "3"]
    _, many = detrend(np.ones((400, 1)), type="linear", bp=list(range(10, 400, 5)))
    assert many._repr_html_().count("<tr>") < 45 and "more coefficients" in many._repr_html_()
