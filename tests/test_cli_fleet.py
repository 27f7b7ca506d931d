"""``rlsfilt identify-many``: one ARX model per channel of a long-format CSV file.

Oracle: ``fit_many(...).to_dataframe()`` of the same channels (the CSV round trip
of a float is exact, so the written table equals it exactly).
"""

import argparse
import json

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX, fit_many
from rlsfilt import _cli_fleet as cli_fleet


def _write_csv(path, rng, C=5, N=300, bad=None):
    rows = []
    for c in range(C):
        u = rng.standard_normal(N)
        a = [1.0, -1.2 + 0.05 * c, 0.5]
        y = lfilter([0, 1.0, 0.4], a, u) + lfilter([1.0], a, 0.1 * rng.standard_normal(N))
        rows.append(pd.DataFrame({"t": np.arange(N), "cell": f"cell{c}", "current": u,
                                  "voltage": y}))
    frame = pd.concat(rows, ignore_index=True).sort_values(["t", "cell"], kind="stable")
    if bad is not None:
        frame = bad(frame)
    frame.to_csv(path, index=False)
    return frame


def _run(argv):
    """Parse with a parser holding only identify-many (independent of rlsfilt.cli)."""
    parser = argparse.ArgumentParser(prog="rlsfilt")
    cli_fleet.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(argv)
    return args.run(args)


def _expected(frame, method="ls", **options):
    labels = list(dict.fromkeys(frame["cell"]))
    u = np.column_stack([frame.loc[frame["cell"] == c, "current"].to_numpy() for c in labels])
    y = np.column_stack([frame.loc[frame["cell"] == c, "voltage"].to_numpy() for c in labels])
    return fit_many(ARX(2, 2, 1), u, y, method, channels=labels, **options).to_dataframe()


def test_csv_summary_equals_fit_many(rng, tmp_path):
    frame = _write_csv(tmp_path / "pack.csv", rng)
    out = tmp_path / "summary.csv"
    assert _run(["identify-many", str(tmp_path / "pack.csv"), "--channel-column", "cell",
                 "--input", "current", "--output", "voltage", "-o", str(out), "-q"]) == 0
    got = pd.read_csv(out, index_col="channel")
    expected = _expected(frame)
    pd.testing.assert_frame_equal(got, expected, check_exact=True, check_index_type=False)


def test_json_to_stdout_with_rls(rng, tmp_path, capsys):
    frame = _write_csv(tmp_path / "pack.csv", rng)
    _run(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
          "-y", "voltage", "--method", "rls", "--lam", "0.99", "--forgetting", "directional",
          "--format", "json", "-q"])
    records = json.loads(capsys.readouterr().out)
    expected = _expected(frame, "rls", lam=0.99, forgetting="directional")
    assert [r["channel"] for r in records] == list(expected.index)
    for rec, (_, row) in zip(records, expected.iterrows()):
        for key, value in row.items():
            assert rec[key] == (value.item() if hasattr(value, "item") else value), key


@pytest.mark.parametrize("method, mu", [("nlms", "0.3"), ("lms", "0.02")])
def test_gradient_methods_equal_fit_many_and_the_filter_by_hand(rng, tmp_path, method, mu):
    """--method nlms|lms --mu: fit_many's GradientBank (exactly), which is the filter run
    by hand on each channel's regressor rows (1e-12)."""
    from rlsfilt import LMS, NLMS

    frame = _write_csv(tmp_path / "pack.csv", rng, C=3)
    out = tmp_path / "summary.csv"
    _run(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
          "-y", "voltage", "--method", method, "--mu", mu, "-o", str(out), "-q"])
    got = pd.read_csv(out, index_col="channel")
    expected = _expected(frame, method, mu=float(mu))
    pd.testing.assert_frame_equal(got, expected, check_exact=True, check_index_type=False)
    for label in got.index:
        rows = frame[frame["cell"] == label]
        Phi, z = ARX(2, 2, 1).regressors(rows["current"].to_numpy(), rows["voltage"].to_numpy())
        filt = {"nlms": NLMS, "lms": LMS}[method](4, mu=float(mu))
        filt.batch_filter(z, Phi)
        np.testing.assert_allclose(got.loc[label, ["a1", "a2", "b1", "b2"]].to_numpy(float),
                                   filt.x[:, 0], rtol=1e-12, atol=1e-14)
    with pytest.raises(ValueError, match="--mu needs --method nlms or lms"):
        _run(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
              "-y", "voltage", "--method", "rls", "--mu", mu, "-q"])


def test_bad_channel_is_named_or_reported(rng, tmp_path, capsys):
    def blank(frame):
        frame.loc[(frame["cell"] == "cell3") & (frame["t"] == 40), "voltage"] = np.nan
        return frame

    _write_csv(tmp_path / "pack.csv", rng, bad=blank)
    argv = ["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
            "-y", "voltage", "-q", "--no-residual-tests"]
    with pytest.raises(ValueError, match=r"`y` must be finite; got nan .*\(channel 'cell3'\)"):
        _run(argv)
    _run(argv + ["--on-error", "nan"])
    captured = capsys.readouterr()
    assert "1 of 5 channel(s) could not be fitted" in captured.err
    table = pd.read_csv(pd.io.common.StringIO(captured.out), index_col="channel")
    assert table.loc["cell3", "error"].startswith("`y` must be finite")
    assert table["error"].isna().sum() == 4 and np.isnan(table.loc["cell3", "a1"])


def test_user_errors_are_one_line(rng, tmp_path):
    def garble(frame):                      # the 8th data row: a cell that is not a number
        frame = frame.astype({"current": object})
        frame.iloc[7, frame.columns.get_loc("current")] = "4,2V"
        return frame

    _write_csv(tmp_path / "pack.csv", rng, bad=garble)
    base = ["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-y", "voltage", "-q"]
    with pytest.raises(ValueError, match="column 'current', data row 8 of .* is not a number: "
                                         "'4,2V'"):
        _run(base + ["-u", "current"])
    with pytest.raises(ValueError, match="column 'power' is not in"):
        _run(base + ["-u", "power"])
    with pytest.raises(ValueError, match="--lam needs --method rls"):
        _run(base + ["-u", "voltage2", "--lam", "0.9"])
    with pytest.raises(ValueError, match="given as both --input and --output"):
        _run(base + ["-u", "voltage"])
    with pytest.raises(SystemExit):
        _run(base + ["-u", "current", "--lam", "1.5"])
    with pytest.raises(ValueError, match=r"^--nb must give one value or one per input \(1\); "
                                         r"got 2 values$"):
        _run(base + ["-u", "current", "--nb", "2,3"])


@pytest.mark.parametrize("option, value, message", [
    ("--lam", "1.5", "argument --lam: must be in (0, 1]; got 1.5"),
    ("--alpha", "x", "argument --alpha: must be a number; got 'x'"),
    ("--na", "-1", "argument --na: must be >= 0; got -1"),
    ("--nk", "1,-2", "argument --nk: must be >= 0; got -2"),
    ("--forgetting", "efra", "argument --forgetting: invalid choice: 'efra'"),
    ("--mu", "-0.1", "argument --mu: must be a positive number; got -0.1"),
    ("--mu", "nan", "argument --mu: must be a positive number; got nan"),
    ("--method", "rpem", "argument --method: invalid choice: 'rpem'"),
])
def test_option_errors_read_as_rlsfilt_identify(option, value, message, tmp_path, capsys):
    """identify-many parses its options with the types of ``rlsfilt identify`` (the same
    messages), and offers the forgetting modes RLSBank runs."""
    with pytest.raises(SystemExit):
        _run(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
              "-y", "voltage", option, value])
    assert message in capsys.readouterr().err


def test_main_runs_identify_many(rng, tmp_path, capsys):
    from rlsfilt.cli import main

    frame = _write_csv(tmp_path / "pack.csv", rng, C=3)
    code = main(["identify-many", str(tmp_path / "pack.csv"), "--channel-column", "cell",
                 "--input", "current", "--output", "voltage", "--no-residual-tests", "-q"])
    assert code == 0
    got = pd.read_csv(pd.io.common.StringIO(capsys.readouterr().out), index_col="channel")
    pd.testing.assert_frame_equal(got, _expected(frame, residual_tests=False), check_exact=True,
                                  check_index_type=False)
    assert main(["identify-many", str(tmp_path / "nope.csv"), "-c", "cell", "-u", "current",
                 "-y", "voltage"]) == 1
    assert "nope.csv" in capsys.readouterr().err


# ----------------------------------------------------------------------
# safe CSV output (#27 item 5): formula-leading text escaped, CR/LF quoted, a round trip
# ----------------------------------------------------------------------
LABELS = ["=HYPERLINK(\"http://x\",\"y\")", "+cmd", "-z", "@SUM(A1)", "\tTab", "\rCR",
          "a\rb", "a\nb", "a\r\nb", 'q"uote', "com,ma", "'quoted", "''two", "-1.5", "plain",
          "été", " lead"]


def _table(labels):
    a1 = -1.5 + 0.25 * np.arange(len(labels))
    return pd.DataFrame({"a1": a1, "b1": 1e-300 * np.arange(len(labels)),
                         "error": [None] * (len(labels) - 1) + ["=bad"]},
                        index=pd.Index(labels, name="channel"))


def test_csv_cells_are_escaped_and_read_back():
    import csv
    import io

    table = _table(LABELS)
    text = cli_fleet._render(table, "csv")
    rows = list(csv.reader(io.StringIO(text, newline="")))
    assert len(rows) == len(LABELS) + 1
    assert rows[0] == ["channel", "a1", "b1", "error"]
    for row, label, a1 in zip(rows[1:], LABELS, table["a1"]):
        # no text cell starts a formula; numbers are written as numbers, unescaped
        assert not row[0].startswith(("=", "+", "-", "@", "\t", "\r"))
        assert cli_fleet.unescape_cell(row[0]) == label
        assert row[1] == repr(float(a1)) and float(row[1]) == a1
    assert rows[1][1] == "-1.5" and rows[-1][3] == "'=bad" and rows[1][3] == ""
    # a bare CR inside a label is quoted (it does not end the record)
    assert '"\rCR"' not in text and "\"'\rCR\"" in text and '"a\rb"' in text
    # pandas reads the same labels back (as text), and the numbers exactly
    got = pd.read_csv(io.StringIO(text, newline=""), index_col="channel",
                      dtype={"channel": str, "error": str}, keep_default_na=False)
    assert [cli_fleet.unescape_cell(v) for v in got.index] == LABELS
    np.testing.assert_array_equal(got["a1"].to_numpy(), table["a1"].to_numpy())
    np.testing.assert_array_equal(got["b1"].to_numpy(), table["b1"].to_numpy())


def test_identify_many_escapes_formula_labels_end_to_end(rng, tmp_path):
    labels = {"cell0": "=1+2", "cell1": "@cmd", "cell2": "+x", "cell3": "-y z", "cell4": "ok"}

    def rename(frame):
        frame["cell"] = frame["cell"].map(labels)
        return frame

    _write_csv(tmp_path / "pack.csv", rng, bad=rename)
    out = tmp_path / "summary.csv"
    assert _run(["identify-many", str(tmp_path / "pack.csv"), "--channel-column", "cell",
                 "--input", "current", "--output", "voltage", "-o", str(out), "-q",
                 "--no-residual-tests"]) == 0
    with open(out, newline="", encoding="utf-8") as fh:
        import csv
        rows = list(csv.reader(fh))
    assert [r[0] for r in rows[1:]] == ["'=1+2", "'@cmd", "'+x", "'-y z", "ok"]
    a1 = rows[0].index("a1")
    assert all(r[a1].startswith("-") and float(r[a1]) < 0 for r in rows[1:])  # not escaped


@pytest.mark.parametrize("labels", [("01", "1"), ("1e3", "1000"), ("NA", "null")])
def test_channel_labels_are_read_as_text(rng, tmp_path, capsys, labels):
    """Labels that type inference merged ("01" and "1" are both 1) or read as
    missing ("NA") stay two channels, each with its own fit."""
    N = 300
    parts = []
    for c, label in enumerate(labels):
        u = rng.standard_normal(N)
        a = [1.0, -0.5 - 0.3 * c]                     # different plants
        y = lfilter([0, 1.0 + c], a, u) + 0.01 * rng.standard_normal(N)
        parts.append(pd.DataFrame({"t": np.arange(N), "cell": label, "current": u,
                                   "voltage": y}))
    frame = pd.concat(parts, ignore_index=True).sort_values(["t", "cell"], kind="stable")
    frame.to_csv(tmp_path / "pack.csv", index=False)
    assert _run(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
                 "-y", "voltage", "--na", "1", "--nb", "1", "--format", "json", "-q"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["channel"] for r in rows] == list(dict.fromkeys(frame["cell"]))  # as they come
    assert [r["n_samples"] for r in rows] == [N - 1, N - 1]
    for row in rows:
        c = labels.index(row["channel"])
        sel = frame["cell"] == labels[c]
        u, y = frame.loc[sel, "current"].to_numpy(), frame.loc[sel, "voltage"].to_numpy()
        model = ARX(1, 1).fit(u, y)
        np.testing.assert_allclose([row["a1"], row["b1"]], model.theta_, rtol=1e-10)
        np.testing.assert_allclose([row["a1"], row["b1"]], [-0.5 - 0.3 * c, 1.0 + c],
                                   atol=0.01)


def test_empty_channel_label_is_named(rng, tmp_path):
    (tmp_path / "pack.csv").write_text("cell,current,voltage\na,1,2\n,2,3\na,3,4\n")
    with pytest.raises(ValueError, match="column 'cell', data row 2 of .* has no channel "
                                         "label"):
        _run(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
              "-y", "voltage", "-q"])


def test_a_huge_label_in_a_message_is_shown_shortened(rng, tmp_path, capsys):
    """A channel label of 200,000 characters (a channel of one sample, too short to fit)
    is quoted in the error, which the terminal gets as its start and end (#27 item 7)."""
    from rlsfilt.cli import main

    frame = _write_csv(tmp_path / "pack.csv", rng, C=2)
    frame = frame.astype({"cell": object})
    frame.iloc[0, frame.columns.get_loc("cell")] = "x" * 200_000
    frame.to_csv(tmp_path / "pack.csv", index=False)
    assert main(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell", "-u", "current",
                 "-y", "voltage", "-q"]) == 1
    err = capsys.readouterr().err
    assert err.startswith("rlsfilt: error: ") and err.count("\n") == 1
    assert 2000 < len(err) < 2200 and "characters) ... " in err
    assert err.rstrip().endswith("got 1")            # the reason: one sample
