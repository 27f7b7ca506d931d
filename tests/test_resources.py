"""Resource limits checked up front, and O(N) memory with small constants (issue #18, item 5).

No wall-clock assertions: "fails at once" is measured as the peak memory the
call allocated before it failed (tracemalloc), which is what used to grow
without bound (``select_order(u, y, na=10**9)`` built a 1e9-column matrix).
The available memory is pinned with monkeypatch where a test needs a limit,
so the outcome does not depend on the machine.
"""

import contextlib
import io
import os
import resource
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest
from scipy.signal import lfilter

import rlsfilt._resources as resources
from rlsfilt import ARX, InsufficientDataError, datasets, select_order, validate
from rlsfilt.cli import main
from rlsfilt.models import arx_regressors
from rlsfilt.validation import residual_analysis

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# bytes per sample, measured with tracemalloc on 2e5 samples (ARX(2, 2, 1), one input and
# output): validate 145, `rlsfilt identify` (CSV reading, fit, validation) 170. The bounds
# documented in `validate` and in the CLI's module docstring, with a margin.
VALIDATE_BYTES_PER_SAMPLE = 250
IDENTIFY_BYTES_PER_SAMPLE = 300


def _record(n, seed=5):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    e = 0.1 * rng.standard_normal(n)   # equation error: ARX(2, 2, 1) is the true structure
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1.0], [1, -1.5, 0.7], e)
    return u, y


def _peak(f):
    """``(result or exception, peak bytes allocated by f)``."""
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        try:
            out = f()
        except Exception as exc:      # noqa: BLE001 - returned to the caller to check
            out = exc
        return out, tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


@pytest.fixture
def little_memory(monkeypatch):
    """The process can allocate 50 MB more."""
    monkeypatch.setattr(resources, "available_memory", lambda: 50_000_000)


# ----------------------------------------------------------------------
# orders and grids: refused before anything of their size is allocated
# ----------------------------------------------------------------------
@pytest.mark.parametrize("grid", [{"na": 10**9}, {"na": range(10**12)},
                                  {"nb": range(1, 10**20)}, {"nk": [10**9]},
                                  {"na": range(0, 600), "nb": range(1, 600), "nk": range(600)}])
def test_select_order_refuses_orders_beyond_the_record_at_once(grid):
    u, y = _record(2000)
    err, peak = _peak(lambda: select_order(u, y, **grid))
    assert isinstance(err, InsufficientDataError), err
    assert "`y` is too short for these orders" in str(err)
    assert peak < 1_000_000, peak


def test_select_order_refuses_a_grid_that_would_take_hours():
    """600 x 599 x 3 candidates with up to 1200 parameters fit the record (1399 rows for
    1200 regressors) but would take about 4e14 operations."""
    u, y = _record(2000)
    err, peak = _peak(lambda: select_order(u, y, na=range(0, 600), nb=range(1, 600)))
    assert isinstance(err, ValueError), err
    assert "`na`, `nb`, `nk` span 1078200 candidate structures" in str(err)
    assert peak < 1_000_000, peak


def test_select_order_checks_its_memory_before_building(little_memory):
    u, y = _record(20_000)
    err, peak = _peak(lambda: select_order(u, y, na=[3000], nb=[1], nk=[1]))
    assert isinstance(err, MemoryError), err
    assert "select_order with 1 candidates (`na`, `nb`, `nk`) and up to 3001 regressors" \
        in str(err)
    assert "50 MB are available" in str(err)
    assert peak < 1_000_000, peak


def test_arx_fit_checks_its_memory_and_stays_unfitted(little_memory):
    u, y = _record(20_000)
    model = ARX(2000, 2)
    err, peak = _peak(lambda: model.fit(u, y))
    assert isinstance(err, MemoryError), err
    assert "2002 parameters on `u`, `y` of 20000 samples" in str(err)
    assert peak < 2_000_000, peak
    assert "theta_" not in model.__dict__


def test_orders_beyond_the_record_fail_without_allocating():
    u, y = _record(2000)
    err, peak = _peak(lambda: ARX(10**9, 2).fit(u, y))
    assert isinstance(err, InsufficientDataError), err
    assert peak < 1_000_000
    err, peak = _peak(lambda: arx_regressors(u, y, na=10**9, nb=1))
    assert isinstance(err, ValueError) and "`start` must be <= N = 2000" in str(err), err
    assert peak < 1_000_000
    (Phi, target), peak = _peak(lambda: arx_regressors(u, y, na=2000, nb=1))
    assert Phi.shape == (0, 2001) and target.shape == (0,)
    assert peak < 1_000_000


def test_validate_and_residual_tests_check_their_memory(little_memory):
    u, y = _record(2000)
    model = ARX(2, 2).fit(u, y)
    err = _peak(lambda: residual_analysis(model, u, y, max_lag=900))[0]
    assert isinstance(err, MemoryError) and "`max_lag` = 900" in str(err), err
    big_u, big_y = _record(600_000)
    err = _peak(lambda: validate(model, big_u, big_y))[0]
    assert isinstance(err, MemoryError), err
    assert "validate on `u`, `y` of 600000 samples" in str(err)


def test_dataset_larger_than_memory_is_refused_up_front():
    import control  # noqa: F401 - imported before measuring (the plant is a python-control tf)

    err, peak = _peak(lambda: datasets.dc_motor(n_samples=10**13))
    assert isinstance(err, MemoryError), err
    assert "`n_samples` = 10000000000000" in str(err)
    assert peak < 1_000_000


def test_available_memory_reads_the_address_space_limit():
    """``ulimit -v`` (RLIMIT_AS) caps what a process can allocate: the estimate sees it."""
    code = ("import resource; resource.setrlimit(resource.RLIMIT_AS, (2 * 10**9, "
            "resource.RLIM_INFINITY)); import rlsfilt._resources as r; print(r.available_memory())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         env={**os.environ, "PYTHONPATH": ROOT}).stdout
    assert 0 < int(out) < 2 * 10**9
    assert resources.available_memory() is None or resources.available_memory() > 0


# ----------------------------------------------------------------------
# the command line: one line, never a traceback or a silent kill
# ----------------------------------------------------------------------
def test_cli_demo_too_large_for_memory_is_one_line():
    """``rlsfilt demo --samples 10000000`` under a 3 GB address-space limit (``ulimit -v``)."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (3 * 10**9, resource.RLIM_INFINITY))

    proc = subprocess.run([sys.executable, "-m", "rlsfilt", "demo", "--samples", "10000000"],
                          capture_output=True, text=True, preexec_fn=limit, timeout=300,
                          env={**os.environ, "PYTHONPATH": ROOT, "MPLBACKEND": "Agg"})
    assert proc.returncode == 1
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("rlsfilt: error: out of memory: the demo with --samples "
                               "10000000 needs about"), lines[0]
    assert proc.stdout == ""


def test_cli_reports_a_failed_allocation_in_one_line(monkeypatch, tmp_path, capsys):
    u, y = _record(300)
    path = tmp_path / "data.csv"
    np.savetxt(path, np.column_stack([u, y]), delimiter=",", header="u,y", comments="")

    def fail(*args, **kwargs):
        raise MemoryError("Unable to allocate 7.45 GiB for an array with shape (1000000000,)")

    monkeypatch.setattr(ARX, "fit", fail)
    assert main(["identify", str(path), "-u", "u", "-y", "y"]) == 1
    err = capsys.readouterr().err
    assert err == ("rlsfilt: error: out of memory: Unable to allocate 7.45 GiB for an array "
                   "with shape (1000000000,)\n")


# ----------------------------------------------------------------------
# O(N) memory with small constants
# ----------------------------------------------------------------------
def test_validate_memory_per_sample_is_bounded():
    """validate on 2e5 samples: below 250 bytes per sample (was 2.2 kB: dense lagged-input
    matrices and their orthogonal factors in the independence test)."""
    u, y = _record(200_000)
    model = ARX(2, 2).fit(u, y)
    report, peak = _peak(lambda: validate(model, u, y))
    assert report.passed
    assert peak / len(u) < VALIDATE_BYTES_PER_SAMPLE, peak / len(u)


def test_identify_memory_per_sample_is_bounded(tmp_path):
    """`rlsfilt identify` on a 2e5-row CSV: below 300 bytes per sample (the file is read line
    by line into arrays of doubles, then fitted and validated)."""
    n = 200_000
    u, y = _record(n)
    path = tmp_path / "big.csv"
    np.savetxt(path, np.column_stack([np.arange(n) * 0.01, u, y]), delimiter=",",
               header="t,u,y", comments="", fmt="%.17g")
    with contextlib.redirect_stdout(io.StringIO()) as out:
        rc, peak = _peak(lambda: main(["identify", str(path), "-u", "u", "-y", "y", "-q",
                                       "--json"]))
    assert rc == 0, out.getvalue()
    assert '"white": true' in out.getvalue()
    assert peak / n < IDENTIFY_BYTES_PER_SAMPLE, peak / n
