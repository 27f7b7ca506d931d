"""rlsfilt.dask: fit_many over Dask collections on a two-worker LocalCluster.

Oracle: the in-memory ``fit_many(...).to_dataframe()``; the distributed result
must equal it exactly (a channel's numbers do not depend on which other
channels share its block). Also: ``import rlsfilt`` never imports Dask.
"""

import json
import pathlib
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX, fit_many

ROOT = pathlib.Path(__file__).resolve().parents[1]

da = pytest.importorskip("dask.array")
dd = pytest.importorskip("dask.dataframe")
distributed = pytest.importorskip("dask.distributed")
rdask = pytest.importorskip("rlsfilt.dask")


def test_import_rlsfilt_does_not_import_dask():
    code = ("import json, sys, rlsfilt, rlsfilt.models, rlsfilt.filters; "
            "print(json.dumps([m for m in ('dask', 'distributed') if m in sys.modules]))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                         text=True, check=True)
    assert json.loads(out.stdout) == []


@pytest.fixture(scope="module")
def client():
    """Two worker processes with one thread each. The scheduler always serves HTTP (its
    dashboard, or at least health and metrics routes) and takes port 8787 unless told
    otherwise: ":0" lets the OS pick a free port, so concurrent runs do not collide."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        yield c


def _fleet(rng, C=23, N=300, nu=1):
    u = rng.standard_normal((N, C, nu))
    y = np.zeros((N, C))
    for c in range(C):
        r = rng.uniform(0.5, 0.85)
        a = [1.0, -2 * r * np.cos(rng.uniform(0.3, 1.2)), r * r]
        for j in range(nu):
            y[:, c] += lfilter([0.0, 1.0, 0.5], a, u[:, c, j])
        y[:, c] += lfilter([1.0], a, 0.2 * rng.standard_normal(N))
    return (u[:, :, 0] if nu == 1 else u), y


@pytest.mark.parametrize("method, options", [("ls", {}), ("rls", {"lam": 0.99}),
                                             ("rls", {"lam": "per channel"})])
def test_dask_arrays_on_two_workers_equal_fit_many(rng, client, method, options):
    u, y = _fleet(rng)
    if options.get("lam") == "per channel":
        options = {"lam": rng.uniform(0.97, 1.0, 23)}
    labels = [f"cell{c:02d}" for c in range(23)]
    expected = fit_many(ARX(2, 2, 1), u, y, method, channels=labels, **options).to_dataframe()
    chunks = (-1, (5, 9, 1, 8))                         # uneven blocks of channels
    got = rdask.fit_many(ARX(2, 2, 1), da.from_array(u, chunks=chunks),
                         da.from_array(y, chunks=chunks), method, channels=labels,
                         client=client, **options)
    # the estimates and fits bit for bit; the residual tests' statistics (vectorized over
    # the channels of a block, whose size the chunks set) to round-off
    tests = [c for c in expected.columns if c.startswith(("f_statistic", "q_statistic", "pvalue"))]
    pd.testing.assert_frame_equal(got.drop(columns=tests), expected.drop(columns=tests),
                                  check_exact=True)
    pd.testing.assert_frame_equal(got[tests], expected[tests], check_exact=False, rtol=1e-12)


def test_several_inputs_and_lazy_result(rng, client):
    u, y = _fleet(rng, C=10, nu=2)
    model = ARX(2, 2, 1)
    lazy = rdask.fit_many(model, da.from_array(u, chunks=(-1, 4, -1)),
                          da.from_array(y, chunks=(-1, 3)), residual_tests=False, compute=False)
    assert isinstance(lazy, dd.DataFrame) and lazy.npartitions == 4   # y's channel blocks
    future = client.compute(lazy)
    distributed.wait(future)
    got = future.result().drop(columns="error")
    expected = fit_many(model, u, y, residual_tests=False).to_dataframe()
    pd.testing.assert_frame_equal(got, expected, check_exact=True)


def test_long_dask_dataframe_partitioned_by_channel(rng, client):
    u, y = _fleet(rng, C=9)
    frames = []
    for c in range(9):
        n = 300 if c % 3 else 250                      # channels of two lengths
        frames.append(pd.DataFrame({"sensor": f"s{c}", "u": u[:n, c], "y": y[:n, c]}))
    long = pd.concat(frames, ignore_index=True)
    ddf = dd.from_pandas(long, npartitions=3, sort=False)   # 3 channels per partition
    got = rdask.fit_many_frame(ARX(2, 2, 1), ddf, channel="sensor", input="u", output="y",
                               method="rls", client=client)
    full = [c for c in range(9) if c % 3]
    short = [c for c in range(9) if not c % 3]
    expected = pd.concat([
        fit_many(ARX(2, 2, 1), u[:, full], y[:, full], "rls",
                 channels=[f"s{c}" for c in full]).to_dataframe(),
        fit_many(ARX(2, 2, 1), u[:250, short], y[:250, short], "rls",
                 channels=[f"s{c}" for c in short]).to_dataframe(),
    ]).loc[[f"s{c}" for c in range(9)]]
    assert list(got.index) == [f"s{c}" for c in range(9)]
    pd.testing.assert_frame_equal(got, expected, check_exact=True, check_index_type=False)


@pytest.mark.parametrize("compute", [True, False])
def test_channel_split_over_partitions_is_an_error(rng, client, compute):
    """Lazy or not: the lazy frame once computed gave two rows for the split channel,
    each a fit of part of its record."""
    u, y = _fleet(rng, C=2)
    long = pd.concat([pd.DataFrame({"ch": c, "u": u[:, c], "y": y[:, c]}) for c in range(2)],
                     ignore_index=True)
    ddf = dd.from_pandas(long, npartitions=3, sort=False)   # splits a channel
    with pytest.raises(ValueError, match=r"channel [01] has rows in partitions [01] and [12] of "
                                         r"`frame`: each channel must lie in one partition"):
        table = rdask.fit_many_frame(ARX(2, 2, 1), ddf, channel="ch", input="u", output="y",
                                     residual_tests=False, client=client, compute=compute)
        if not compute:
            client.compute(table).result()


def test_argument_errors():
    y = da.zeros((100, 4), chunks=(-1, 2))
    with pytest.raises(ValueError, match=r"`u` must have one column per channel of `y` \(4\)"):
        rdask.fit_many(ARX(1, 1), da.zeros((100, 3)), y)
    with pytest.raises(ValueError, match="`u` and `y` must have the same length"):
        rdask.fit_many(ARX(1, 1), da.zeros((90, 4)), y)
    with pytest.raises(ValueError, match=r"`y` must have shape \(N, C\)"):
        rdask.fit_many(ARX(1, 1), da.zeros(100), da.zeros(100))
    with pytest.raises(TypeError, match="`frame` must be a dask or pandas DataFrame"):
        rdask.fit_many_frame(ARX(1, 1), np.zeros((3, 3)), channel="c", input="u", output="y")


@pytest.mark.parametrize("chunk", [1, 3])
def test_rls_estimates_of_small_blocks_equal_the_whole_fleet_bit_for_bit(chunk):
    """A block of one channel ran the batch start of a 1-channel RLSBank, 1 ulp off the
    same channel in the in-memory fleet (matmul's path depended on the channel count)."""
    rng = np.random.default_rng(11)
    C, N = 7, 150
    u = rng.standard_normal((N, C, 2))
    y = np.column_stack([lfilter([0, .5, .2], [1, -.6], u[:, c, 0])
                         + lfilter([0, 0, .3], [1, -.6], u[:, c, 1])
                         + .1 * rng.standard_normal(N) for c in range(C)])
    model = ARX(2, [2, 2], [0, 1])
    ref = fit_many(model, u, y, "rls", lam=0.99, residual_tests=False).to_dataframe()
    import dask

    with dask.config.set(scheduler="synchronous"):
        table = rdask.fit_many(model, da.from_array(u, chunks=(-1, chunk, -1)),
                               da.from_array(y, chunks=(-1, chunk)), "rls", lam=0.99,
                               residual_tests=False)
    names = [c for c in ref.columns if c[:1] in "ab" or c.startswith("se_")]
    np.testing.assert_array_equal(table[names].to_numpy(), ref[names].to_numpy())
