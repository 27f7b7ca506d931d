"""detrend / retrend / Trend against scipy.signal.detrend and numpy means."""

import json

import numpy as np
import pytest
from scipy import signal

from rlsfilt.data import IOData, Trend, detrend, retrend


def _signals(rng, n=300, cols=3):
    k = np.arange(n)[:, None]
    return 97.0 + 0.02 * k * np.arange(1, cols + 1) + rng.standard_normal((n, cols))


@pytest.mark.parametrize("kind", ["constant", "linear", "c", "l"])
def test_arrays_equal_scipy(rng, kind):
    X = _signals(rng)
    Xd, trend = detrend(X, type=kind)
    np.testing.assert_allclose(Xd, signal.detrend(X, axis=0, type=kind), rtol=0, atol=1e-12)
    x1d, t1 = detrend(X[:, 0], kind)
    assert x1d.shape == (300,)
    np.testing.assert_allclose(x1d, signal.detrend(X[:, 0], type=kind), rtol=0, atol=1e-12)
    # retrend is the inverse to round-off (relative to the 97-unit offset)
    np.testing.assert_allclose(retrend(Xd, trend), X, rtol=1e-14, atol=0)
    np.testing.assert_allclose(retrend(x1d, t1), X[:, 0], rtol=1e-14, atol=0)
    np.testing.assert_allclose(trend.offset, X.mean(axis=0), rtol=1e-14)
    assert isinstance(t1.offset, float)


def test_linear_breakpoints_equal_scipy(rng):
    X = _signals(rng)
    X[100:] += 5.0  # a level change at the breakpoint
    bp = [100, 220]
    Xd, trend = detrend(X, "linear", bp=bp)
    np.testing.assert_allclose(Xd, signal.detrend(X, axis=0, type="linear", bp=bp),
                               rtol=0, atol=1e-12)
    assert trend.breakpoints == ((0, 100, 220),)
    np.testing.assert_allclose(retrend(Xd, trend), X, rtol=1e-14)
    # a one-sample segment is removed exactly, as by scipy's minimum-norm fit
    Xd1, _ = detrend(X, "linear", bp=[299])
    np.testing.assert_allclose(Xd1, signal.detrend(X, axis=0, type="linear", bp=[299]),
                               rtol=0, atol=1e-12)


def test_piecewise_constant_is_the_segment_means(rng):
    X = _signals(rng)
    Xd, trend = detrend(X, "constant", bp=[120])
    expected = np.vstack([X[:120] - X[:120].mean(axis=0), X[120:] - X[120:].mean(axis=0)])
    np.testing.assert_allclose(Xd, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(trend.intercept[0], [X[:120].mean(0), X[120:].mean(0)])
    np.testing.assert_array_equal(trend.slope[0], 0.0)


def test_iodata_per_experiment(rng):
    X1, X2 = _signals(rng, 200, 2), _signals(rng, 150, 2) + 10.0
    data = IOData([X1[:, 0], X2[:, 0]], [X1[:, 1], X2[:, 1]], dt=0.5,
                  output_names=["T"], output_units=["degC"])
    dd, trend = detrend(data, "linear")
    assert isinstance(dd, IOData) and dd.output_names == ("T",) and dd.dt == 0.5
    for i, X in enumerate((X1, X2)):
        ref = signal.detrend(X, axis=0, type="linear")
        np.testing.assert_allclose(dd.getexp(i).u, ref[:, 0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(dd.getexp(i).y, ref[:, 1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(trend.input_offset, [[X1[:, 0].mean()], [X2[:, 0].mean()]],
                               rtol=1e-14)
    np.testing.assert_allclose(trend.output_offset, [[X1[:, 1].mean()], [X2[:, 1].mean()]],
                               rtol=1e-14)
    back = retrend(dd, trend)
    for i, X in enumerate((X1, X2)):
        np.testing.assert_allclose(back.getexp(i).y, X[:, 1], rtol=1e-14)
    # one breakpoint list per experiment
    dd2, trend2 = detrend(data, "constant", bp=[[50], [100]])
    assert trend2.breakpoints == ((0, 50), (0, 100))
    np.testing.assert_allclose(dd2.getexp(1).y[:100], X2[:100, 1] - X2[:100, 1].mean(),
                               atol=1e-12)
    # the operating point of a one-experiment record is a vector per signal group
    _, t1 = detrend(data.getexp(0))
    np.testing.assert_allclose(t1.output_offset, [X1[:, 1].mean()], rtol=1e-14)


def test_trend_applies_to_new_data(rng):
    est = IOData(40 + rng.standard_normal(100), 97 + rng.standard_normal(100))
    new = IOData(40 + rng.standard_normal(60), 97 + rng.standard_normal(60))
    _, trend = detrend(est)
    moved = trend.remove(new)
    np.testing.assert_allclose(moved.y, new.y - est.y.mean(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(trend.add(moved).u, new.u, rtol=1e-14)
    # a linear trend extends its last segment beyond the fitted record
    x = 2.0 + 0.5 * np.arange(10.0)
    _, lin = detrend(x, "linear")
    np.testing.assert_allclose(lin.values(15)[:, 0], 2.0 + 0.5 * np.arange(15.0), atol=1e-12)


def test_does_not_write_into_the_caller(rng):
    X = _signals(rng)
    keep = X.copy()
    detrend(X, "linear", bp=[10])
    np.testing.assert_array_equal(X, keep)


def test_to_dict_round_trip_is_exact(rng):
    data = IOData(_signals(rng, 80, 1)[:, 0], _signals(rng, 80, 2))
    _, trend = detrend(data, "linear", bp=[30])
    again = Trend.from_dict(json.loads(json.dumps(trend.to_dict())))
    for a, b in zip(again.intercept + again.slope, trend.intercept + trend.slope):
        np.testing.assert_array_equal(a, b)
    assert again.breakpoints == trend.breakpoints and again.n_outputs == 2
    np.testing.assert_array_equal(again.output_offset, trend.output_offset)
    assert "Trend(type='linear', 1 experiment(s), 1 input(s), 2 output(s)" in repr(again)


def test_errors(rng):
    X = _signals(rng, 50, 2)
    with pytest.raises(ValueError, match="`type` must be 'constant' or 'linear'; got 'quad'"):
        detrend(X, "quad")
    with pytest.raises(ValueError, match=r"`bp` must hold sample indices in \[0, N = 50\]; "
                                         "got 60"):
        detrend(X, "linear", bp=[60])
    with pytest.raises(ValueError, match="`bp` must be >= 0; got -1"):
        detrend(X, "linear", bp=[-1])
    with pytest.raises(TypeError, match="`bp` must be a sequence of sample indices"):
        detrend(X, "linear", bp=2.5)
    with pytest.raises(ValueError, match="one per experiment"):
        detrend(IOData([X[:, 0]] * 2, [X[:, 1]] * 2), bp=[[1], [2], [3]])
    with pytest.raises(ValueError, match=r"shape \(N,\) or \(N, n\)"):
        detrend(np.ones((2, 2, 2)))
    _, trend = detrend(X)
    with pytest.raises(ValueError, match=r"`data` must have 2 column\(s\) like the trend; "
                                         "got 3"):
        retrend(np.ones((4, 3)), trend)
    with pytest.raises(TypeError, match="got an IOData"):
        retrend(IOData(X[:, 0], X[:, 1]), trend)
    with pytest.raises(TypeError, match="`trend` must be a Trend"):
        retrend(X, "mean")
    _, io_trend = detrend(IOData([X[:, 0]] * 2, [X[:, 1]] * 2))
    with pytest.raises(ValueError, match="must have 2 experiments like the trend"):
        io_trend.add(IOData([X[:, 0]] * 3, [X[:, 1]] * 3))
    with pytest.raises(ValueError, match="`input_offset` is defined for the trend of an "
                                         "IOData"):
        _ = trend.input_offset
