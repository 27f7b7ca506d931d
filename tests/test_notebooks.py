"""Every notebook in ``notebooks/`` executes, is committed without outputs, and prints no stray
output (a temporary path, a bare matplotlib repr, a warning: #32)."""

import os
import re
import tempfile
from pathlib import Path

import pytest

nbformat = pytest.importorskip("nbformat")

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
TIMEOUT = 300  # seconds per cell; each notebook takes a few seconds in total


def test_there_are_notebooks():
    names = [p.name for p in NOTEBOOKS]
    assert names[:5] == ["01_quickstart.ipynb", "02_tracking.ipynb", "03_validation.ipynb",
                         "04_control.ipynb", "05_beside_filterpy.ipynb"]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_committed_clean(path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    assert nb.metadata.get("kernelspec", {}).get("name") == "python3"
    for i, cell in enumerate(nb.cells):
        if cell.cell_type != "code":
            continue
        assert cell.outputs == [], f"{path.name} cell {i} has outputs; clear them before committing"
        assert cell.execution_count is None, f"{path.name} cell {i} has an execution count"
        # randomness goes through a seeded Generator, never the global NumPy state
        assert not re.search(r"np\.random\.(seed|rand|randn|normal|uniform)\(", cell.source), (
            f"{path.name} cell {i} uses the global NumPy random state; use "
            "np.random.default_rng(seed)")


@pytest.mark.notebooks
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_executes(path, tmp_path, monkeypatch):
    nbclient = pytest.importorskip("nbclient")
    # the kernel is a subprocess: it inherits this environment
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.setenv("PYTHONHASHSEED", "0")
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(
        [str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    nb = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        nb, timeout=TIMEOUT, kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}})  # files a notebook writes land here
    client.execute()
    errors = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs
              if o.output_type == "error"]
    assert not errors
    # what the documentation page shows of each cell (the same execution: no second run)
    stray = [(i, problem) for i, cell in enumerate(nb.cells) if cell.cell_type == "code"
             for problem in stray_outputs(cell.outputs, [str(tmp_path)])]
    assert not stray, f"{path.name}: stray outputs (cell, problem): {stray}"


# a bare repr of a matplotlib object: the value of a cell ending in ``ax.set_title(...)``,
# ``ax.plot(...)``, ``ax.legend()``, ...
_MATPLOTLIB_REPR = re.compile(r"^(\[)?<?(matplotlib\.|Text\(|Line2D\(|<matplotlib|Legend|"
                              r"<Figure size|Figure\(|<Axes|Axes\(|\[<matplotlib)")


def stray_outputs(outputs, temp_dirs=()):
    """What should not be in the outputs of a documentation cell: a temporary directory (the
    system's, or one of `temp_dirs`), a bare matplotlib repr as the cell's value, a warning on
    stderr. Returns a list of descriptions (empty when the outputs are clean)."""
    temps = {tempfile.gettempdir(), "/tmp/", *temp_dirs}
    found = []
    for out in outputs:
        if out.get("output_type") == "stream":
            text = out.get("text", "")
            if out.get("name") == "stderr" and "Warning" in text:
                found.append(f"a warning on stderr: {text[:120]!r}")
        elif out.get("output_type") in ("execute_result", "display_data"):
            text = out.get("data", {}).get("text/plain", "")
            if out.get("output_type") == "execute_result" and _MATPLOTLIB_REPR.match(text.strip()):
                found.append(f"a bare matplotlib repr: {text[:80]!r}")
        else:
            continue
        text = text if isinstance(text, str) else "".join(text)
        hits = [temp for temp in temps if temp and temp in text]
        if hits:                                   # one finding per output
            found.append(f"a temporary path {hits[0]!r}: {text[:120]!r}")
    return found


def test_stray_outputs_are_found():
    """The check of the outputs finds each kind of stray output, and passes clean ones."""
    stream = nbformat.v4.new_output
    clean = [stream("stream", name="stdout", text="fit 96.8 %\n"),
             stream("execute_result", data={"text/plain": "IOData(2 experiments)"},
                    execution_count=1),
             stream("display_data", data={"text/plain": "<Figure size 640x480 with 1 Axes>",
                                          "image/png": ""})]
    assert stray_outputs(clean) == []
    bad = [stream("stream", name="stderr", text=f"{tempfile.gettempdir()}/ipykernel_1/2.py:5: "
                  "OperatingPointWarning: the record has an offset\n"),
           stream("execute_result", data={"text/plain": "Text(0.5, 1.0, 'title')"},
                  execution_count=2),
           stream("execute_result", data={"text/plain": "[<matplotlib.lines.Line2D at 0x7f>]"},
                  execution_count=3),
           stream("stream", name="stdout", text="saved to /tmp/tmpab12/model.json\n")]
    found = stray_outputs(bad)
    assert len(found) == 5, found          # the warning is also a temporary path
    assert sum("warning" in f for f in found) == 1
    assert sum("matplotlib repr" in f for f in found) == 2
