"""The whole family on records (#28 item 5): every selection and fit function takes an
`IOData` for estimation and for validation, and gives what the arrays give.

Oracle: the same function on the same samples given as arrays (one experiment), and,
for several experiments, the fit of each model on the list of arrays."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.signal import lfilter

from rlsfilt import (
    ARMAX,
    ARX,
    BJ,
    OE,
    IOData,
    compare,
    delayest,
    select_order,
    select_structure,
    validate,
)
from rlsfilt.exceptions import OrderSelectionWarning
from rlsfilt.validation import information_criteria


@pytest.fixture(scope="module")
def record():
    rng = np.random.default_rng(28)
    u = rng.standard_normal(900)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.2 * rng.standard_normal(900)
    return u, y


def _split(u, y, how):
    """Estimation and validation parts, as arrays or as IOData."""
    est, val = (u[:600], y[:600]), (u[600:], y[600:])
    if how == "iodata":
        return (IOData(*est),), IOData(*val)
    return est, val


_GRID = {"nb": [1, 2], "nf": [2], "nk": [1]}


def _call(fn, est, val, with_val):
    kw = {"validation": val} if with_val else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", OrderSelectionWarning)
        if fn == "select_order_arx":
            return select_order(*est, na=[1, 2], nb=[1, 2], nk=[1, 2], **kw)
        if fn == "select_order_oe":
            return select_order(*est, model=OE, nb=[1, 2], nf=[2], nk=[1], **kw)
        if fn == "select_order_armax":
            return select_order(*est, model=ARMAX, na=[2], nb=[2], nc=[0, 1], nk=[1], **kw)
        if fn == "select_structure_oe":
            return select_structure(OE, *est, grid=_GRID, **kw)
        if fn == "select_structure_bj":
            return select_structure(BJ, *est, grid={"nb": [2], "nc": [0], "nd": [0],
                                                    "nf": [1, 2], "nk": [1]}, **kw)
    raise AssertionError(fn)


def _numbers(result):
    if hasattr(result, "table"):
        return result.best, np.column_stack([result.table["loss"], result.table["val_loss"]])
    return result.best, np.array([[c["loss"], c["val_loss"]] for c in result.candidates])


@pytest.mark.parametrize("with_val", [False, True], ids=["estimation", "validation"])
@pytest.mark.parametrize("fn", ["select_order_arx", "select_order_oe", "select_order_armax",
                                "select_structure_oe", "select_structure_bj"])
def test_selection_takes_iodata_and_agrees_with_arrays(record, fn, with_val):
    arrays = _call(fn, *_split(*record, "arrays"), with_val)
    records = _call(fn, *_split(*record, "iodata"), with_val)
    best_a, num_a = _numbers(arrays)
    best_r, num_r = _numbers(records)
    assert best_a == best_r
    assert_allclose(num_r, num_a, rtol=1e-9, equal_nan=True)
    assert np.isnan(num_a[:, 1]).all() != with_val


def test_the_grid_may_follow_an_iodata_positionally(record):
    (data,), _ = _split(*record, "iodata")
    a = select_structure(OE, data, _GRID)
    b = select_structure(OE, data, grid=_GRID)
    assert a.best == b.best and a.values.tolist() == b.values.tolist()
    with pytest.raises(TypeError, match="`y` must be omitted when `u` is an IOData"):
        select_structure(OE, data, record[1][:600], _GRID)
    with pytest.raises(TypeError, match="`y` is required unless `u` is an IOData"):
        select_structure(OE, record[0], grid=_GRID)
    with pytest.raises(TypeError, match="`validation` must be a pair"):
        select_structure(OE, data, grid=_GRID, validation=record[0])


def test_several_experiments_estimation_and_validation(record):
    u, y = record
    data = IOData([u[:300], u[300:600]], [y[:300], y[300:600]])
    val = IOData([u[600:750], u[750:]], [y[600:750], y[750:]])
    sel = select_structure(OE, data, grid=_GRID, validation=val)
    for c, m in zip(sel.candidates, sel.models):
        ref = OE(**c["orders"]).fit([u[:300], u[300:600]], [y[:300], y[300:600]])
        assert_allclose(m.theta_, ref.theta_, rtol=1e-9)
        # the validation loss: each experiment's one-step errors, started afresh
        e = np.concatenate([yv[m.max_lag:] - m.predict(uv, yv)[m.max_lag:]
                            for uv, yv in ((u[600:750], y[600:750]), (u[750:], y[750:]))])
        assert c["val_loss"] == pytest.approx(np.mean(e ** 2), rel=1e-10)
        assert c["loss"] == pytest.approx(information_criteria(m, data).loss, rel=1e-12)


@pytest.mark.parametrize("cls, orders", [(OE, (2, 2, 1)), (ARMAX, (2, 2, 1, 1)),
                                         (BJ, (2, 0, 0, 2, 1)), (ARX, (2, 2, 1))])
def test_fits_and_validation_functions_take_iodata(record, cls, orders):
    (u, y), (uv, yv) = _split(*record, "arrays")
    (data,), val = _split(*record, "iodata")
    m_a, m_r = cls(*orders).fit(u, y), cls(*orders).fit(data)
    assert_allclose(m_r.theta_, m_a.theta_, rtol=1e-12)
    a, b = validate(m_a, uv, yv), validate(m_a, val)
    assert a.simulation_fit == pytest.approx(b.simulation_fit, rel=1e-12)
    assert a.prediction_fit == pytest.approx(b.prediction_fit, rel=1e-12)
    assert compare(m_a, uv, yv).fit == pytest.approx(compare(m_a, val).fit, rel=1e-12)
    assert delayest(u, y) == delayest(data)


# ----------------------------------------------------------------------
# several inputs (#28 item 6)
# ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def two_inputs():
    """Two inputs with delays 2 and 17 and nb 3 and 2: y = B1/A u1 + B2/A u2 + e/A."""
    rng = np.random.default_rng(6)
    N = 3000
    u = rng.standard_normal((N, 2))
    a = [1, -0.6]
    y = (lfilter([0, 0, 1.0, 0.5, 0.25], a, u[:, 0]) + lfilter([0] * 17 + [0.8, -0.4], a, u[:, 1])
         + lfilter([1], a, 0.1 * rng.standard_normal(N)))
    return u, y


def test_select_order_finds_both_delays_and_each_nb(two_inputs):
    u, y = two_inputs
    # nk not given: each input's delays are a window around delayest's estimate
    sel = select_order(u, y, na=range(0, 3), nb=[range(1, 5), range(1, 4)])
    assert sel.seeded_by_delayest == (2, 17)
    assert [list(r) for r in sel.nk_ranges] == [[1, 2, 3], [16, 17, 18]]
    assert sel.best == (1, (3, 2), (2, 17))
    model = sel.best_model()
    assert (tuple(model.nb), tuple(model.nk)) == ((3, 2), (2, 17))
    # oracle: the best candidate's loss is ordinary least squares on the aligned rows
    t0 = 17 + 3 - 1 + 1       # largest lag of the grid: nk 18 + nb 3 - 1
    rows = np.arange(t0, len(y))
    Phi = np.column_stack([-y[rows - 1]] + [u[rows - k, 0] for k in (2, 3, 4)]
                          + [u[rows - k, 1] for k in (17, 18)])
    theta, res, *_ = np.linalg.lstsq(Phi, y[rows], rcond=None)
    i = sel.best_index
    assert sel.table["loss"][i] == pytest.approx(res[0] / len(rows), rel=1e-9)
    assert_allclose(sel.thetas[i], theta, rtol=1e-8)


def test_per_input_ranges_as_lists_or_dicts_on_records(two_inputs):
    u, y = two_inputs
    data = IOData(u, y, input_names=["heater", "fan"])
    a = select_order(data, na=[1], nb=[range(1, 5), range(1, 4)],
                     nk=[range(0, 4), range(15, 20)])
    b = select_order(data, na=[1], nb={"heater": range(1, 5), "fan": range(1, 4)},
                     nk={0: range(0, 4), 1: range(15, 20)})
    assert a.best == b.best == (1, (3, 2), (2, 17))
    assert a.seeded_by_delayest is None
    assert "3,2" in str(a.summary()) and a.to_dataframe()["nk"][a.best_index] == [2, 17]
    with pytest.warns(OrderSelectionWarning, match=r"`nk\[fan\]` range \(15\.\.17\)"):
        select_order(data, na=[1], nb=[[3], [2]], nk=[range(0, 4), range(15, 18)])
    with pytest.raises(ValueError, match="`nk` must give every input a range; missing 'fan'"):
        select_order(data, na=[1], nk={"heater": range(0, 3)})
    with pytest.raises(ValueError, match=r"`nb` must hold one range per input \(2\); got 3"):
        select_order(data, na=[1], nb=[range(1, 2)] * 3)


def test_family_searches_per_input_delays(two_inputs):
    u, y = two_inputs
    data = IOData(u[:1500], y[:1500])
    sel = select_order(data, model=OE, nb=[[3], [2]], nf=[[1], [1]])
    assert sel.seeded_by_delayest == (2, 17)
    assert sel.best["nk"] == (2, 17)


def test_to_tf_of_several_inputs_points_to_to_ss(two_inputs):
    import importlib.util

    import control

    from rlsfilt.exceptions import ConversionWarning

    u, y = two_inputs
    model = ARX(1, [3, 2], [2, 17]).fit(u, y)
    if importlib.util.find_spec("slycot") is None:
        with pytest.warns(ConversionWarning, match=r"use model\.to_ss\(\)"):
            G = model.to_tf()
        with pytest.raises(control.ControlMIMONotImplemented):
            control.forced_response(G, np.arange(50), u[:50].T)
    # what the warning advises works without Slycot
    resp = control.forced_response(model.to_ss(), np.arange(200), u[:200].T)
    assert_allclose(np.ravel(resp.outputs), model.simulate(u[:200]), rtol=1e-9, atol=1e-10)
    # one input, one output: no warning (pytest turns warnings into errors)
    ARX(1, 3, 2).fit(u[:, 0], y).to_tf()
