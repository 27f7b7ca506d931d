"""Atomic saves (issue #27 item 4): a save that fails midway leaves the existing file intact
and no temporary file behind, for every file rlsfilt and its command line write."""

import argparse
import os

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX, _atomic, _model_file, load_model, persistence
from rlsfilt import _cli_fleet as cli_fleet
from rlsfilt.cli import main


def _folder(path):
    return sorted(os.listdir(path))


def test_atomic_write_replaces_or_keeps(tmp_path):
    target = tmp_path / "f.txt"
    target.write_text("old\n")
    os.chmod(target, 0o640)
    with _atomic.atomic_write(target) as fh:
        fh.write("new\n")
    assert target.read_text() == "new\n" and _folder(tmp_path) == ["f.txt"]
    assert os.stat(target).st_mode & 0o777 == 0o640            # the old file's permissions
    with pytest.raises(RuntimeError, match="midway"):
        with _atomic.atomic_write(target) as fh:
            fh.write("half")
            raise RuntimeError("midway")
    assert target.read_text() == "new\n" and _folder(tmp_path) == ["f.txt"]
    with pytest.raises(FileNotFoundError):
        with _atomic.atomic_write(tmp_path / "missing" / "f.txt") as fh:
            fh.write("x")
    with pytest.raises(ValueError, match="`mode` must be 'w' or 'wb'"):
        with _atomic.atomic_write(target, "a"):
            pass


def test_a_model_save_failing_midway_keeps_the_old_model(tmp_path, monkeypatch):
    path = tmp_path / "model.json"
    old = ARX.from_polynomials([-0.5], [1.0])
    old.save(path)
    before = path.read_bytes()

    def half(fh, text):                         # the serializer dies after writing part
        fh.write(text[: len(text) // 2])
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(_model_file, "_write_text", half)
    new = ARX.from_polynomials([-0.9], [2.0])
    with pytest.raises(OSError, match="No space left"):
        new.save(path)
    assert path.read_bytes() == before and _folder(tmp_path) == ["model.json"]
    with pytest.raises(OSError):
        persistence.save_model(new, path)
    assert load_model(path).theta_.tolist() == [-0.5, 1.0]
    assert _folder(tmp_path) == ["model.json"]


def _fail_sync(monkeypatch):
    def fsync(fd):
        raise OSError(5, "Input/output error")
    monkeypatch.setattr(_atomic.os, "fsync", fsync)


def test_cli_save_model_and_json_are_atomic(tmp_path, monkeypatch, capsys):
    rng = np.random.default_rng(4)
    u = rng.standard_normal(300)
    y = lfilter([0, 1.0, 0.5], [1, -0.6], u) + 0.01 * rng.standard_normal(300)
    pd.DataFrame({"u": u, "y": y}).to_csv(tmp_path / "rec.csv", index=False)
    saved, params = tmp_path / "model.json", tmp_path / "params.json"
    saved.write_text("previous model\n")
    params.write_text("previous params\n")
    argv = ["identify", str(tmp_path / "rec.csv"), "-u", "u", "-y", "y", "--na", "1",
            "--save-model", str(saved)]
    _fail_sync(monkeypatch)
    assert main(argv) != 0
    assert "cannot write" in capsys.readouterr().err
    assert saved.read_text() == "previous model\n"
    assert sorted(os.listdir(tmp_path)) == ["model.json", "params.json", "rec.csv"]
    monkeypatch.undo()
    assert main(argv) == 0
    capsys.readouterr()
    assert isinstance(load_model(saved), ARX)
    from rlsfilt import cli

    _fail_sync(monkeypatch)
    with pytest.raises(cli.CLIError, match="cannot write"):
        cli._write_json(str(params), {"a": 1})
    assert params.read_text() == "previous params\n"
    assert sorted(os.listdir(tmp_path)) == ["model.json", "params.json", "rec.csv"]


def test_identify_many_out_is_atomic(tmp_path, monkeypatch):
    rng = np.random.default_rng(5)
    rows = []
    for c in range(2):
        u = rng.standard_normal(200)
        rows.append(pd.DataFrame({"cell": f"c{c}", "current": u,
                                  "voltage": lfilter([0, 1.0], [1, -0.5], u)
                                  + 0.01 * rng.standard_normal(200)}))
    pd.concat(rows).to_csv(tmp_path / "pack.csv", index=False)
    out = tmp_path / "summary.csv"
    out.write_text("previous summary\n")
    parser = argparse.ArgumentParser(prog="rlsfilt")
    cli_fleet.add_parser(parser.add_subparsers(dest="command"))
    args = parser.parse_args(["identify-many", str(tmp_path / "pack.csv"), "-c", "cell",
                              "-u", "current", "-y", "voltage", "-o", str(out), "-q",
                              "--no-residual-tests"])
    _fail_sync(monkeypatch)
    with pytest.raises(OSError, match="Input/output error"):
        args.run(args)
    assert out.read_text() == "previous summary\n"
    assert sorted(os.listdir(tmp_path)) == ["pack.csv", "summary.csv"]
    monkeypatch.undo()
    assert args.run(args) == 0
    assert pd.read_csv(out, index_col="channel").index.tolist() == ["c0", "c1"]


@pytest.mark.parametrize("ext", ["png", "svg"])
def test_cli_plot_is_atomic(tmp_path, monkeypatch, capsys, ext):
    """``--plot``: a figure whose writing fails midway keeps the old file (it was written
    in place); a successful one replaces it with the figure in the extension's format."""
    rng = np.random.default_rng(6)
    u = rng.standard_normal(300)
    y = lfilter([0, 1.0, 0.5], [1, -0.6], u) + 0.01 * rng.standard_normal(300)
    pd.DataFrame({"u": u, "y": y}).to_csv(tmp_path / "rec.csv", index=False)
    plot = tmp_path / f"fig.{ext}"
    plot.write_bytes(b"previous figure")
    argv = ["identify", str(tmp_path / "rec.csv"), "-u", "u", "-y", "y", "--na", "1",
            "--plot", str(plot)]
    _fail_sync(monkeypatch)
    assert main(argv) != 0
    assert "cannot write" in capsys.readouterr().err
    assert plot.read_bytes() == b"previous figure"
    assert _folder(tmp_path) == [f"fig.{ext}", "rec.csv"]
    monkeypatch.undo()
    assert main(argv) == 0
    capsys.readouterr()
    head = plot.read_bytes()[:64]
    assert head.startswith(b"\x89PNG") if ext == "png" else b"<svg" in plot.read_bytes()[:2000]
    assert _folder(tmp_path) == [f"fig.{ext}", "rec.csv"]
