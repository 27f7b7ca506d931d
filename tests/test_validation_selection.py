"""select_order: exact against brute-force least squares, finds the true
structure of simulated plants, and is fast (one factorization)."""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.signal import lfilter

from rlsfilt import ARX, datasets, select_order
from rlsfilt.validation import OrderSelection, criteria_from_loss


def _brute_force(u, y, cands, t_max):
    """Per-candidate lstsq on the rows aligned to the largest lag."""
    N = len(y)
    t = np.arange(t_max, N)
    out = []
    for na, nb, nk in cands:
        cols = [-y[t - k] for k in range(1, na + 1)] + [u[t - k] for k in range(nk, nk + nb)]
        Phi = np.column_stack(cols)
        theta = np.linalg.lstsq(Phi, y[t], rcond=None)[0]
        r = y[t] - Phi @ theta
        out.append((r @ r / len(t), theta))
    return out


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")  # small grids
def test_losses_match_brute_force_lstsq(rng):
    u = rng.standard_normal(1500)
    y = lfilter([0, 0, 1.0, -0.4], [1, -1.2, 0.5], u) + 0.2 * rng.standard_normal(1500)
    na, nb, nk = range(0, 4), range(1, 4), range(0, 3)
    sel = select_order(u, y, na=na, nb=nb, nk=nk)
    cands = list(itertools.product(na, nb, nk))
    assert [tuple(int(v) for v in r) for r in sel.table[["na", "nb", "nk"]]] == cands
    t_max = max(3, 2 + 3 - 1)
    assert sel.n_rows == 1500 - t_max
    for row, theta, (loss, theta_bf) in zip(sel.table, sel.thetas,
                                            _brute_force(u, y, cands, t_max)):
        assert row["loss"] == pytest.approx(loss, rel=1e-9)
        np.testing.assert_allclose(theta, theta_bf, rtol=1e-9, atol=1e-12)
        ic = criteria_from_loss(loss, sel.n_rows, int(row["n_params"]))
        assert row["bic"] == pytest.approx(ic.bic, rel=1e-12)
        assert row["aic"] == pytest.approx(ic.aic, rel=1e-12)


@pytest.mark.parametrize("make", [datasets.thermal_process, datasets.dc_motor,
                                  datasets.mass_spring_damper, datasets.nonminimum_phase])
def test_finds_true_structure_of_simulated_plants(make):
    d = make()
    sel = select_order(d.u, d.y, na=range(1, 5), nb=range(1, 5), nk=range(0, 6))
    assert sel.best == (d.na, d.nb, d.nk)


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")  # small grids
def test_validation_data_scores_on_fresh_record():
    d = datasets.dc_motor(n_samples=3000)
    u, y = d.u[:1500], d.y[:1500]
    uv, yv = d.u[1500:], d.y[1500:]
    sel = select_order(u, y, na=range(1, 4), nb=range(1, 4), nk=range(1, 3),
                       validation=(uv, yv), criterion="loss")
    assert not np.any(np.isnan(sel.table["val_loss"]))
    np.testing.assert_array_equal(sel.values, sel.table["val_loss"])
    # the true structure is as good as the best on fresh data; underfits are far worse
    vals = {tuple(int(v) for v in r[["na", "nb", "nk"]]): r["val_loss"] for r in sel.table}
    assert vals[(2, 2, 1)] <= 1.005 * sel.values.min()
    assert vals[(1, 1, 1)] > 2 * vals[(2, 2, 1)]
    # the validation loss of a candidate is the mean squared one-step error of
    # its estimation-data parameters on the aligned validation rows
    i = [k for k, r in enumerate(sel.table) if tuple(r[["na", "nb", "nk"]]) == (2, 2, 1)][0]
    theta = sel.thetas[i]
    t = np.arange(max(3, 2 + 3 - 1), 1500)
    Phi = np.column_stack([-yv[t - 1], -yv[t - 2], uv[t - 1], uv[t - 2]])
    assert sel.table["val_loss"][i] == pytest.approx(np.mean((yv[t] - Phi @ theta) ** 2),
                                                     rel=1e-12)
    sel_bic = select_order(u, y, na=range(1, 4), nb=range(1, 4), nk=range(1, 3),
                           validation=(uv, yv))
    assert sel_bic.best == (2, 2, 1)
    assert sel_bic.n_val_rows == 1500 - 4


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")  # small grids
def test_4000_samples_60_candidates():
    """The workload of benchmarks/bench_select_order.py (its time is measured there)."""
    rng = np.random.default_rng(3)
    u = rng.standard_normal(4000)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.1 * rng.standard_normal(4000)
    sel = select_order(u, y, na=range(1, 6), nb=range(1, 5), nk=range(0, 3))
    assert len(sel.table) == 60


def test_several_inputs(rng):
    U = rng.standard_normal((2000, 2))
    y = lfilter([0, 1.0], [1, -0.6], U[:, 0]) + lfilter([0, 0, 0.8], [1, -0.6], U[:, 1])
    y += lfilter([1.0], [1, -0.6], 0.05 * rng.standard_normal(2000))
    # common nb, nk for both inputs: the model needs nk=1, nb=2 (b = [0, 0.8] for input 2)
    sel = select_order(U, y, na=range(0, 3), nb=range(1, 4), nk=range(0, 3))
    assert sel.best == (1, 2, 1)
    theta = sel.thetas[sel.best_index]
    np.testing.assert_allclose(theta, [-0.6, 1.0, 0.0, 0.0, 0.8], atol=0.02)


def test_best_model_summary_dataframe_and_plot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = datasets.thermal_process()
    sel = select_order(d.u, d.y, na=range(1, 3), nb=range(1, 3), nk=range(3, 6), dt=d.dt)
    assert isinstance(sel, OrderSelection)
    model = sel.best_model()
    assert isinstance(model, ARX) and (model.na, model.nb, model.nk) == sel.best
    assert model.dt == d.dt
    np.testing.assert_allclose(model.theta_,
                               ARX(*sel.best).fit(d.u, d.y).theta_, rtol=1e-12)
    text = str(sel.summary(top=3))
    assert "<- best" in text and text.count("\n") == 4
    df = sel.to_dataframe()
    assert list(df.columns[:4]) == ["na", "nb", "nk", "n_params"] and len(df) == 12
    ax = sel.plot()
    assert ax.get_xlabel() == "number of parameters $d$"
    assert "(1, 1, 4)" in ax.get_legend().get_texts()[-1].get_text()
    assert "best (na, nb, nk) = (1, 1, 4)" in repr(sel)
    plt.close("all")


def test_select_order_errors(rng):
    u, y = rng.standard_normal(200), rng.standard_normal(200)
    with pytest.raises(ValueError, match="`criterion` must be one of aic, aicc, bic"):
        select_order(u, y, criterion="hqic")
    with pytest.raises(ValueError, match="`nb` must be >= 1; got 0"):
        select_order(u, y, nb=range(0, 3))
    with pytest.raises(ValueError, match="`na` must hold at least one order"):
        select_order(u, y, na=[])
    with pytest.raises(TypeError, match="`nk` must be an integer or an iterable"):
        select_order(u, y, nk=1.5)
    with pytest.raises(ValueError, match="`criterion`='loss' needs `validation` data"):
        select_order(u, y, criterion="loss")
    with pytest.raises(ValueError, match=r"`y` must have shape \(N,\) \(one output\)"):
        select_order(u, np.zeros((200, 2)))
    with pytest.raises(ValueError, match="`u` and `y` must have the same length; got 200 input "
                                         "samples and 150 output samples"):
        select_order(u, y[:150])
    with pytest.raises(ValueError, match="`y` is too short for these orders"):
        select_order(u[:12], y[:12])
    with pytest.raises(TypeError, match="`validation` must be a pair"):
        select_order(u, y, validation=u)
    with pytest.raises(ValueError, match=r"`validation\[0\]` and `validation\[1\]` must have the "
                                         r"same length; got 10 input samples and 5 output"):
        select_order(u, y, validation=(u[:10], y[:5]))
    with pytest.raises(ValueError, match=r"`validation\[1\]` must be finite; got nan at index 3"):
        select_order(u, y, validation=(u, np.r_[y[:3], np.nan, y[4:]]))
    with pytest.raises(ValueError, match=r"`validation` input must have 1 column\(s\) like `u`; "
                                         r"got 2"):
        select_order(u, y, validation=(np.column_stack([u, u]), y))
    with pytest.raises(ValueError, match=r"`dt` must be True \(unspecified sampling period\) or "
                                         r"a positive sampling period; got -1"):
        select_order(u, y, dt=-1)
    with pytest.raises(ValueError, match="exactly"):
        select_order(u, lfilter([0, 1.0], [1, -0.5], u), na=1, nb=1, nk=1)


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")  # small grids
@settings(max_examples=25, deadline=None)
@given(na_max=st.integers(0, 3), nb_max=st.integers(1, 3), nk_min=st.integers(0, 2),
       nk_span=st.integers(0, 2), n_inputs=st.integers(1, 2), seed=st.integers(0, 2**31))
def test_any_grid_matches_brute_force(na_max, nb_max, nk_min, nk_span, n_inputs, seed):
    """Every candidate of any grid, with one or two inputs, equals its own lstsq."""
    rng = np.random.default_rng(seed)
    N = 120
    U = rng.standard_normal((N, n_inputs))
    y = lfilter([1.0], [1.0, -0.5], U.sum(axis=1) + 0.3 * rng.standard_normal(N))
    na, nb, nk = range(0, na_max + 1), range(1, nb_max + 1), range(nk_min, nk_min + nk_span + 1)
    sel = select_order(U if n_inputs > 1 else U[:, 0], y, na=na, nb=nb, nk=nk)
    t_max = max(na_max, nk_min + nk_span + nb_max - 1)
    t = np.arange(t_max, N)
    for row, theta in zip(sel.table, sel.thetas):
        a, b, k = int(row["na"]), int(row["nb"]), int(row["nk"])
        cols = [-y[t - i] for i in range(1, a + 1)]
        cols += [U[t - i, j] for j in range(n_inputs) for i in range(k, k + b)]
        Phi = np.column_stack(cols)
        ref = np.linalg.lstsq(Phi, y[t], rcond=None)[0]
        np.testing.assert_allclose(theta, ref, rtol=1e-8, atol=1e-10)
        assert row["loss"] == pytest.approx(np.mean((y[t] - Phi @ ref) ** 2), rel=1e-9)


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")  # small grids
def test_summary_top_is_checked():
    d = datasets.thermal_process(n_samples=400)
    sel = select_order(d.u, d.y, na=[1], nb=[1], nk=[3, 4])
    assert str(sel.summary(top=1)).count("\n") == 2
    with pytest.raises(ValueError, match=r"`top` must be >= 1; got 0"):
        sel.summary(top=0)


@pytest.mark.parametrize("su, sy", [(1e-8, 1e6), (1e-12, 1e10)])
def test_selection_does_not_depend_on_units(su, sy):
    """Rescaling u and y (other units) scales losses and parameters, never the choice."""
    rng = np.random.default_rng(5)
    u = rng.standard_normal(2000)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u)
    y += lfilter([1.0], [1, -1.5, 0.7], 0.05 * rng.standard_normal(2000))
    grid = {"na": range(1, 4), "nb": range(1, 4), "nk": range(0, 3)}
    ref, scaled = select_order(u, y, **grid), select_order(su * u, sy * y, **grid)
    assert scaled.best == ref.best == (2, 2, 1)
    np.testing.assert_allclose(scaled.table["loss"], sy ** 2 * ref.table["loss"], rtol=1e-9)
    i = ref.best_index
    np.testing.assert_allclose(scaled.thetas[i], ref.thetas[i] * [1, 1, sy / su, sy / su],
                               rtol=1e-8)


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")  # small grids
def test_best_model_names_signals_like_a_direct_fit():
    """One 1-D input stays one signal `u` (not `u1`), pandas names are kept."""
    d = datasets.dc_motor(n_samples=600)
    sel = select_order(d.u, d.y, na=range(1, 4), nb=range(1, 3), nk=1, dt=d.dt)
    direct = ARX(*sel.best, dt=d.dt).fit(d.u, d.y)
    best = sel.best_model()
    assert best.param_names_ == direct.param_names_ == ["a1", "a2", "b1", "b2"]
    assert best.summary().as_text() == direct.summary().as_text()
    assert "u1" not in best.summary().as_text()
    np.testing.assert_array_equal(best.theta_, direct.theta_)
    # several inputs keep their 2-D names; pandas names carry through
    pd = pytest.importorskip("pandas")
    df = pd.DataFrame({"volt": d.u, "speed": d.y})
    sel_pd = select_order(df["volt"], df["speed"], na=2, nb=2, nk=1)
    text = sel_pd.best_model().summary().as_text()
    assert text == ARX(2, 2, 1).fit(df["volt"], df["speed"]).summary().as_text()
    assert "volt(t-1)" in text and "speed(t)" in text
    U2 = np.column_stack([d.u, np.roll(d.u, 3)])
    two = select_order(U2, d.y, na=2, nb=2, nk=1).best_model()
    assert two.param_names_ == ARX(2, 2, 1).fit(U2, d.y).param_names_


# ----------------------------------------------------------------------
# select_order over the prediction-error family (delegates to select_structure)
# ----------------------------------------------------------------------
def _armax_record(rng, n=3000):
    u, e = rng.standard_normal(n), 0.3 * rng.standard_normal(n)
    a = [1, -1.5, 0.7]
    return u, lfilter([0, 1, 0.5], a, u) + lfilter([1, -1, 0.2], a, e)


def test_select_order_armax_picks_the_truth_and_is_select_structure(rng):
    from rlsfilt import ARMAX, select_structure

    u, y = _armax_record(rng)
    grid = {"na": [1, 2, 3], "nb": [1, 2, 3], "nc": [1, 2, 3], "nk": [1]}
    sel = select_order(u, y, model=ARMAX, **grid)
    assert sel.best == {"na": 2, "nb": 2, "nc": 2, "nk": 1}
    ref = select_structure(ARMAX, u, y, grid)
    assert sel.best == ref.best and sel.best_index == ref.best_index
    np.testing.assert_array_equal(sel.values, ref.values)
    for c, r in zip(sel.candidates, ref.candidates):
        assert c["orders"] == r["orders"] and c["loss"] == r["loss"]
    np.testing.assert_array_equal(sel.best_model.theta_, ref.best_model.theta_)
    assert "<- best" in str(sel.summary())
    assert list(sel.to_dataframe()[["na", "nb", "nc", "nk"]].iloc[sel.best_index]) == [2, 2, 2, 1]
    # the ARMAX one-step loss is the noise variance (0.09); ARX of the true (na, nb, nk),
    # from the same entry point, leaves the coloured part C e in its residuals
    assert sel.candidates[sel.best_index]["loss"] == pytest.approx(0.09, rel=0.06)
    arx = select_order(u, y, na=[2], nb=[2], nk=[1])
    assert arx.best == (2, 2, 1) and arx.table["loss"][0] > 1.3 * 0.09


def test_select_order_family_validation_criterion_and_options(rng):
    import warnings

    from rlsfilt import OE, select_structure
    from rlsfilt.exceptions import OrderSelectionWarning

    u = rng.standard_normal(3000)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.3 * rng.standard_normal(3000)
    val = (u[2000:], y[2000:])
    sel = select_order(u[:2000], y[:2000], model=OE, nb=[2], nf=[1, 2, 3], nk=[1],
                       criterion="bic", validation=val)
    ref = select_structure(OE, u[:2000], y[:2000], {"nb": [2], "nf": [1, 2, 3], "nk": [1]},
                           criterion="bic", validation=val)
    assert sel.best == ref.best == {"nb": 2, "nf": 2, "nk": 1}
    np.testing.assert_array_equal(sel.values, ref.values)
    assert all(np.isfinite(c["val_loss"]) for c in sel.candidates)
    # orders not given take the documented default grid (1, 2; nk 1, 2, 3)
    with warnings.catch_warnings():  # the true (2, 2) is at the default grid's edge
        warnings.simplefilter("ignore", OrderSelectionWarning)
        short = select_order(u[:600], y[:600], model=OE, nk=[1])
    assert [c["orders"] for c in short.candidates] == [
        {"nb": b, "nf": f, "nk": 1} for b in (1, 2) for f in (1, 2)]


def test_select_order_family_warns_at_the_grid_edge(rng):
    from rlsfilt import ARMAX
    from rlsfilt.exceptions import OrderSelectionWarning

    u, y = _armax_record(rng, 2000)
    with pytest.warns(OrderSelectionWarning, match=r"\(na, nb, nc, nk\) = \(2, 2, 2, 1\).*"
                                                  r"upper edge of the `nc` range"):
        select_order(u, y, model=ARMAX, na=[2], nb=[2], nc=[1, 2], nk=[1])


def test_select_order_family_errors(rng):
    from rlsfilt import ARMA, ARMAX, BJ, OE

    u, y = _armax_record(rng, 300)
    with pytest.raises(ValueError, match="`nc` is not an order of ARX"):
        select_order(u, y, nc=[1, 2])
    with pytest.raises(ValueError, match="`fit_options` applies to the classes"):
        select_order(u, y, fit_options={"method": "rpem"})
    with pytest.raises(ValueError, match=r"`na` is not an order of OE \(its orders: nb, nf, nk\)"):
        select_order(u, y, na=[1, 2], model=OE)
    with pytest.raises(ValueError, match="`nf` is not an order of ARMAX"):
        select_order(u, y, model=ARMAX, nf=[1])
    with pytest.raises(ValueError, match="`na` is not an order of BJ"):
        select_order(u, y, model=BJ, na=2)
    with pytest.raises(TypeError, match="`model` must be a model class such as ARMAX"):
        select_order(u, y, model=ARMAX(2, 2, 2))
    with pytest.raises(ValueError, match="`offset` applies to ARX only"):
        select_order(u, y, model=ARMAX, offset=True)
    with pytest.raises(ValueError, match="`stable_only` applies to ARX only"):
        select_order(u, y, model=ARMAX, stable_only=True)
    with pytest.raises(ValueError, match="`u` must be None for the time-series class ARMA"):
        select_order(u, y, model=ARMA)
    with pytest.raises(ValueError, match="`nc` must be"):
        select_order(u, y, model=ARMAX, nc=[-1])
    with pytest.raises(ValueError, match="`criterion` must be one of"):
        select_order(u, y, model=ARMAX, criterion="r2")


def test_select_order_time_series_class(rng):
    from rlsfilt import ARMA, select_structure

    y = lfilter([1, 0.5], [1, -0.8], rng.standard_normal(3000))
    sel = select_order(None, y, model=ARMA, na=[1, 2, 3], nc=[0, 1, 2])
    assert sel.best == select_structure(ARMA, None, y, {"na": [1, 2, 3], "nc": [0, 1, 2]}).best \
        == {"na": 1, "nc": 1}
