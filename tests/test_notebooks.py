"""Every notebook in ``notebooks/`` executes, and is committed without outputs."""

import os
import re
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
