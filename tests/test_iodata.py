"""IOData: one or several experiments, names and units, slicing, split, merge, DataFrames."""

import numpy as np
import pytest

from rlsfilt.data import IOData


def _record(rng, n=200, nu=1, ny=1):
    u = rng.standard_normal((n, nu)) if nu > 1 else rng.standard_normal(n)
    y = rng.standard_normal((n, ny)) if ny > 1 else rng.standard_normal(n)
    return u, y


def test_single_experiment_from_arrays(rng):
    u, y = _record(rng)
    data = IOData(u, y, dt=0.5)
    assert data.n_experiments == 1 and data.lengths == (200,) and data.n_samples == 200
    assert (data.n_inputs, data.n_outputs) == (1, 1)
    assert data.input_names == ("u",) and data.output_names == ("y",)
    assert data.input_units == ("",) and data.experiment_names == ("exp1",)
    np.testing.assert_array_equal(data.u, u)
    np.testing.assert_array_equal(data.y, y)
    assert data.u.shape == (200,) and data.dt == 0.5
    np.testing.assert_allclose(data.t, 0.5 * np.arange(200), rtol=0, atol=0)
    # a copy: the caller's arrays can change without changing the record, and the
    # record's arrays are read-only
    u[0] = 1e6
    assert data.u[0] != 1e6
    with pytest.raises(ValueError, match="read-only"):
        data.u[0] = 1.0
    U, Y = data.arrays()[0]
    assert U.shape == (200, 1) and Y.shape == (200, 1)


def test_several_signals_and_pandas_names(rng):
    pd = pytest.importorskip("pandas")
    u, y = _record(rng, nu=2, ny=2)
    data = IOData(u, y)
    assert data.input_names == ("u1", "u2") and data.output_names == ("y1", "y2")
    assert data.u.shape == (200, 2) and data.dt is True
    np.testing.assert_array_equal(data.t, np.arange(200))
    frame = pd.DataFrame(u, columns=["valve", "fan"])
    data = IOData(frame, pd.Series(y[:, 0], name="T"), dt=1.0, output_units=["degC"])
    assert data.input_names == ("valve", "fan") and data.output_names == ("T",)
    assert data.output_units == ("degC",)
    data = IOData(frame, y[:, 0], input_names=["a", "b"])
    assert data.input_names == ("a", "b")


def test_several_experiments_from_lists(rng):
    """The call that gave a 3,098-character error in ARX.fit now builds two experiments."""
    u1, y1 = _record(rng, 300)
    u2, y2 = _record(rng, 300)
    data = IOData([u1, u2], [y1, y2], dt=0.1, tstart=[0.0, 100.0])
    assert data.n_experiments == 2 and data.lengths == (300, 300)
    assert data.experiment_names == ("exp1", "exp2") and data.tstart == (0.0, 100.0)
    with pytest.raises(ValueError, match=r"`u` is defined for a record of one experiment; "
                                         r"this one holds 2 \(exp1, exp2\): use `getexp\(i\)"):
        _ = data.u
    with pytest.raises(ValueError, match="`t` is defined"):
        _ = data.t
    e2 = data.getexp(1)
    np.testing.assert_array_equal(e2.y, y2)
    np.testing.assert_allclose(e2.t, 100.0 + 0.1 * np.arange(300))
    assert data.getexp("exp2").experiment_names == ("exp2",)
    np.testing.assert_array_equal(data.getexp(-2).u, u1)
    both = data.getexp(["exp2", 0])
    assert both.experiment_names == ("exp2", "exp1")
    assert [len(e.u) for e in data.experiments] == [300, 300]
    assert IOData((u1, u2), (y1, y2)).n_experiments == 2


@pytest.mark.parametrize("args, match", [
    (lambda u, y: ([u, u], y), "same number of experiments; got 2 input record"),
    (lambda u, y: ([u, u[:-1]], [y, y]), r"`u\[1\]` and `y\[1\]` must have the same length; "
                                         "got 299 input samples and 300 output samples"),
    (lambda u, y: ([u, np.column_stack([u, u])], [y, y]),
     "every experiment must have the same number of inputs; experiment 0 has 1 and "
     "experiment 1 has 2"),
    (lambda u, y: (u[:10], y), "same length; got 10 input samples and 300"),
    (lambda u, y: (u[:0], y[:0]), "at least one sample"),
    (lambda u, y: (np.ones((3, 2, 2)), np.ones(3)), r"shape \(N,\) or \(N, n_signals\)"),
    (lambda u, y: (np.ones((3, 0)), np.ones(3)), "at least one column"),
])
def test_shape_errors_are_short_and_name_the_argument(rng, args, match):
    u, y = _record(rng, 300)
    with pytest.raises(ValueError, match=match) as info:
        IOData(*args(u, y))
    assert len(str(info.value)) < 200


def test_value_and_metadata_errors(rng):
    u, y = _record(rng, 50)
    bad = y.copy()
    bad[7] = np.nan
    with pytest.raises(ValueError, match=r"`y\[1\]` must be finite; got nan at index 7"):
        IOData([u, u], [y, bad])
    with pytest.raises(TypeError, match="`u` must be real"):
        IOData(u + 1j, y)
    with pytest.raises(ValueError, match="`dt` must be True"):
        IOData(u, y, dt=-1.0)
    with pytest.raises(ValueError, match="`input_names` must have 1 entry; got 2"):
        IOData(u, y, input_names=["a", "b"])
    with pytest.raises(TypeError, match="`output_units` must hold strings"):
        IOData(u, y, output_units=[3])
    with pytest.raises(ValueError, match="`experiment_names` must be distinct"):
        IOData([u, u], [y, y], experiment_names=["a", "a"])
    with pytest.raises(ValueError, match="`tstart` must be a number or have one entry per"):
        IOData([u, u], [y, y], tstart=[0.0, 1.0, 2.0])
    with pytest.raises(TypeError, match="got an IOData"):
        IOData(IOData(u, y), y)


def test_immutable(rng):
    data = IOData(*_record(rng, 20))
    with pytest.raises(AttributeError, match="IOData is immutable"):
        data.dt = 2.0
    with pytest.raises(AttributeError, match="immutable"):
        data.u = np.zeros(20)
    with pytest.raises(AttributeError, match="immutable"):
        del data._U


def test_slicing_per_experiment(rng):
    u1, y1 = _record(rng, 100)
    u2, y2 = _record(rng, 60)
    data = IOData([u1, u2], [y1, y2], dt=0.5, tstart=[0.0, 10.0])
    part = data[10:50]
    assert part.lengths == (40, 40) and part.tstart == (5.0, 15.0) and part.dt == 0.5
    np.testing.assert_array_equal(part.getexp(1).u, u2[10:50])
    tail = data[-20:]
    np.testing.assert_array_equal(tail.getexp(0).y, y1[-20:])
    assert tail.tstart == (40.0, 30.0)
    half = data[1::2]
    assert half.dt == 1.0 and half.lengths == (50, 30) and half.tstart == (0.5, 10.5)
    np.testing.assert_array_equal(half.getexp(0).u, u1[1::2])
    with pytest.raises(ValueError, match=r"the slice \[70:\] leaves no samples of experiment "
                                         r"'exp2' \(60 samples\)"):
        data[70:]
    with pytest.raises(ValueError, match="slice step must be >= 1"):
        data[::-1]
    with pytest.raises(TypeError, match="indexed by a slice of samples"):
        data[3]
    with pytest.raises(TypeError, match="`slice start` must be an integer"):
        data[1.5:]


def test_split_per_experiment(rng):
    u1, y1 = _record(rng, 100)
    u2, y2 = _record(rng, 51)
    data = IOData([u1, u2], [y1, y2], dt=2.0)
    est, val = data.split(0.7)
    assert est.lengths == (70, 36) and val.lengths == (30, 15)
    assert val.tstart == (140.0, 72.0) and est.tstart == (0.0, 0.0)
    np.testing.assert_array_equal(est.getexp(1).u, u2[:36])
    np.testing.assert_array_equal(val.getexp(1).y, y2[36:])
    np.testing.assert_allclose(val.getexp(0).t, 2.0 * np.arange(70, 100))
    for bad in (0, 1, 1.5, True, "0.5"):
        with pytest.raises(ValueError, match=r"`fraction` must be a number in \(0, 1\)"):
            data.split(bad)
    with pytest.raises(ValueError, match="leaves an empty part of experiment 'exp1'"):
        IOData(u1[:3], y1[:3]).split(0.1)


def test_merge(rng):
    a = IOData(*_record(rng, 40), dt=0.1)
    b = IOData(*_record(rng, 30), dt=0.1, experiment_names=["run b"])
    m = a.merge(b)
    assert m.lengths == (40, 30) and m.experiment_names == ("exp1", "run b")
    np.testing.assert_array_equal(m.getexp(1).y, b.y)
    mm = a.merge(a, a)  # duplicate names: renumbered
    assert mm.experiment_names == ("exp1", "exp2", "exp3")
    with pytest.raises(ValueError, match="same sampling period"):
        a.merge(IOData(*_record(rng, 30), dt=0.2))
    with pytest.raises(ValueError, match="same input_names"):
        a.merge(IOData(*_record(rng, 30), dt=0.1, input_names=["v"]))
    with pytest.raises(TypeError, match=r"`others\[0\]` must be an IOData; got ndarray"):
        a.merge(np.zeros(3))


def test_from_dataframe_infers_dt_and_groups_experiments(rng):
    pd = pytest.importorskip("pandas")
    n1, n2 = 50, 40
    t = np.concatenate([0.1 * np.arange(n1), 3.0 + 0.1 * np.arange(n2)])
    df = pd.DataFrame({"time": t, "run": ["first"] * n1 + ["second"] * n2,
                       "Q": rng.standard_normal(n1 + n2), "P": rng.standard_normal(n1 + n2),
                       "T": 97 + rng.standard_normal(n1 + n2)})
    data = IOData.from_dataframe(df, inputs=["Q", "P"], outputs="T", time="time",
                                 experiment="run", units={"T": "degC", "Q": "%"})
    assert data.dt == 0.1 and data.lengths == (n1, n2)
    assert data.experiment_names == ("first", "second") and data.tstart == (0.0, 3.0)
    assert data.input_names == ("Q", "P") and data.input_units == ("%", "")
    assert data.output_units == ("degC",)
    np.testing.assert_array_equal(data.getexp("second").u, df[["Q", "P"]].to_numpy()[n1:])
    # round trip through to_dataframe
    back = data.to_dataframe(time="time", experiment="run")
    pd.testing.assert_frame_equal(back[["run", "Q", "P", "T"]], df[["run", "Q", "P", "T"]])
    np.testing.assert_allclose(back["time"], df["time"], rtol=0, atol=1e-12)
    # the time as the index, datetimes, no time column
    idx = df.iloc[:n1].set_index("time")
    assert IOData.from_dataframe(idx, "Q", "T", time="time").dt == 0.1
    stamps = df.iloc[:n1].assign(time=pd.Timestamp("2024-01-01")
                                 + pd.to_timedelta(df["time"].iloc[:n1], unit="s"))
    assert IOData.from_dataframe(stamps, "Q", "T", time="time").dt == 0.1
    assert IOData.from_dataframe(df, "Q", "T").dt is True
    assert IOData.from_dataframe(df, "Q", "T", dt=0.1).n_experiments == 1
    assert IOData.from_dataframe(df.iloc[:n1], "Q", "T", time="time", dt=0.1).dt == 0.1


def test_from_dataframe_errors(rng):
    pd = pytest.importorskip("pandas")
    t = 0.5 * np.arange(20)
    t[12:] += 0.2  # a jitter of 40 % of dt at row 12
    df = pd.DataFrame({"t": t, "u": rng.standard_normal(20), "y": rng.standard_normal(20),
                       "s": ["x"] * 20})
    with pytest.raises(ValueError, match=r"`time` column 't' is not uniformly sampled: steps "
                                         r"range from 0.5 to 0.7 .* ends at row 12"):
        IOData.from_dataframe(df, "u", "y", time="t")
    back = df.assign(t=np.r_[0.0, 2.0, 1.0, np.arange(3.0, 20.0)])
    with pytest.raises(ValueError, match="must be increasing; got 2 then 1 at row 2"):
        IOData.from_dataframe(back, "u", "y", time="t")
    with pytest.raises(ValueError, match=r"`inputs` names columns that are not in `df`: "
                                         r"\['v'\]"):
        IOData.from_dataframe(df, "v", "y")
    with pytest.raises(ValueError, match="`time` must be a column of `df` or the name of"):
        IOData.from_dataframe(df, "u", "y", time="clock")
    with pytest.raises(ValueError, match="`experiment` must be a column"):
        IOData.from_dataframe(df, "u", "y", experiment="run")
    with pytest.raises(TypeError, match="column 's' must be numeric"):
        IOData.from_dataframe(df, "s", "y")
    nan = df.assign(y=np.r_[np.ones(5), np.nan, np.ones(14)])
    with pytest.raises(ValueError, match="column 'y' must be finite; got nan at row 5"):
        IOData.from_dataframe(nan, "u", "y")
    ok = df.assign(t=0.5 * np.arange(20))
    with pytest.raises(ValueError, match="`dt`=0.1 disagrees with the sampling period 0.5"):
        IOData.from_dataframe(ok, "u", "y", time="t", dt=0.1)
    with pytest.raises(ValueError, match="`units` names"):
        IOData.from_dataframe(ok, "u", "y", units={"z": "m"})
    with pytest.raises(TypeError, match="`df` must be a pandas DataFrame"):
        IOData.from_dataframe(ok.to_numpy(), "u", "y")
    two = ok.assign(run=["a"] * 10 + ["b"] * 10,
                    t=np.r_[0.5 * np.arange(10), 0.25 * np.arange(10)])
    with pytest.raises(ValueError, match="different sampling periods"):
        IOData.from_dataframe(two, "u", "y", time="t", experiment="run")


def test_repr_and_html(rng):
    u1, y1 = _record(rng, 30)
    data = IOData([u1, u1], [y1, y1], dt=0.5, input_names=["Q"], output_names=["T<out>"],
                  output_units=["degC"], experiment_names=["day 1", "day 2"])
    text = repr(data)
    assert text.startswith("IOData: 2 experiments, 60 samples, dt = 0.5 s")
    assert "outputs: T<out> [degC]" in text and "day 2: 30 samples, t = 0 .. 14.5 s" in text
    page = data._repr_html_()
    assert "T&lt;out&gt; [degC]" in page and "<td>day 1</td><td>30</td>" in page
    assert "dt = unspecified" in repr(IOData(u1, y1))


def test_plot(rng):
    u1, y1 = _record(rng, 30)
    fig = IOData([u1, u1], [y1, y1], dt=0.5, output_units=["m"]).plot()
    axes = fig.get_axes()
    assert len(axes) == 2 and axes[0].get_ylabel() == "y [m]"
    assert axes[-1].get_xlabel() == "time [s]" and len(axes[0].lines) == 2
