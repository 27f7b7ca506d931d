"""Compiled kernels of SlidingWindowRLS and SquareRootRLS against the textbook reference.

``predict``, ``update``, ``initialize`` and ``batch_filter`` run the numba
kernels of ``rlsfilt.filters._kernels_window``; the readable recursions are
in ``tests/_reference.py`` (the sliding window's update, downdate and
refit; the square root's Givens rotations, the same algorithm as its
kernel). The two must agree to 1e-12 step by step on well-conditioned data
for every option, and the streaming ``update`` must reproduce
``batch_filter`` bit for bit (both run the same compiled step).
"""

import _reference
import numpy as np
import pytest
from conftest import arx_record
from conftest import assert_close_steps as _close
from numpy.testing import assert_array_equal
from reference_runs import sliding_window_run, square_root_run

from rlsfilt import RecursiveLeastSquares, SlidingWindowRLS, SquareRootRLS

STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H",
         "n_updates")


def _record(rng, n_samples, dim_z=1, missing=(), white=False):
    """ARX regressors, or (`white`) independent standard normal ones, which keep
    even short windows well conditioned."""
    Hs, zs = arx_record(rng, n_samples=n_samples + 2)
    if white:
        Hs = rng.standard_normal(Hs.shape)
        zs = Hs @ [0.5, -1.0, 2.0, 0.3] + 0.1 * rng.standard_normal(len(zs))
    if dim_z > 1:
        extra = [Hs @ rng.standard_normal(4) + 0.1 * rng.standard_normal(len(zs))
                 for _ in range(dim_z - 1)]
        zs = np.column_stack([zs] + extra)
    zs = zs.astype(float)
    for k in missing:
        zs[k] = np.nan
    return Hs, zs




def _run_both(make, zs, Hs, run, **kwargs):
    """`batch_filter` on a fresh filter and the reference run from the same start."""
    f = make()
    ref = run(f, zs, Hs, kwargs.get("Rs"), kwargs.get("update_first", False))
    return f, ref, f.batch_filter(zs, Hs, **kwargs)


def _compare(f, ref, out):
    for label, c, r in zip(("means", "covariances", "means_p", "covariances_p"), out,
                           (ref.means, ref.covs, ref.means_p, ref.covs_p)):
        if c is not None and len(c):
            _close(c, r, label)
    if len(ref.means):
        _close(f.x, ref.means[-1], "x")
        _close(f.x_post, ref.means[-1], "x_post")
        _close(f.P_post, ref.covs[-1], "P_post")
        _close(f.y, ref.ys[-1].reshape(-1, 1), "y")
        _close(f.K, ref.K, "K")
        assert f.S[0, 0] == pytest.approx(ref.ss[-1], rel=1e-12)


# ----------------------------------------------------------------------
# SlidingWindowRLS
# ----------------------------------------------------------------------
SW_OPTIONS = [
    # window, refresh, dim_z, use_Rs, update_first, store, missing
    (8, None, 1, False, False, True, ()),
    (8, 0, 1, False, True, True, ()),
    (30, None, 1, True, False, False, (0, 7, 150, 299)),
    (30, 7, 2, True, True, True, (3, 4, 5, 299)),
    (100, 0, 2, False, False, True, (10, 11, 200)),
    (100, 25, 3, True, True, False, (150,)),
    (4, 1, 1, False, False, True, (50, 51, 52, 53)),
]


@pytest.mark.parametrize("window, refresh, dim_z, use_Rs, update_first, store, missing",
                         SW_OPTIONS)
def test_sliding_window_compiled_equals_reference(rng, window, refresh, dim_z,
                                                  use_Rs, update_first, store, missing):
    # downdating amplifies round-off by about cond(window)^2: short windows
    # of the resonant ARX record are not well conditioned, white rows are
    Hs, zs = _record(rng, 300, dim_z, missing, white=window < 30)
    kwargs = {"update_first": update_first, "store_covariances": store}
    if use_Rs:
        kwargs["Rs"] = rng.uniform(0.5, 2.0, len(zs))

    def make():
        return SlidingWindowRLS(4, window, dim_z, refresh=refresh, P0=100.0, R=0.7)

    f, ref, out = _run_both(make, zs, Hs, sliding_window_run, **kwargs)
    _compare(f, ref, out)
    w = ref.window
    assert (f.exact, f.n_samples, f._head, f._count) == (w.exact, w.nw, w.head, w.count)
    assert_array_equal(f._wH, w.wH)
    assert_array_equal(f._wZ, w.wZ)
    assert_array_equal(f._wR, w.wR)


def test_sliding_window_unexciting_stretch_and_initialize(rng):
    """Failed downdates, the prior fallback and the exact restart take the same turns."""
    N, window = 400, 20
    u = rng.standard_normal(N)
    u[100:200] = 1.0                                  # regressors [u(t), u(t-1)] = [1, 1]
    Hs = np.column_stack([u[1:], u[:-1]])
    zs = Hs @ [2.0, -1.0] + 0.01 * rng.standard_normal(N - 1)
    f, ref, out = _run_both(lambda: SlidingWindowRLS(2, window), zs, Hs, sliding_window_run)
    # inside the stretch the prior carries the unidentifiable direction (P ~ P0)
    _compare(f, ref, out)
    assert f.exact == ref.window.exact

    def make():
        f = SlidingWindowRLS(2, window, x0=[0.5, 0.5], P0=[[4.0, 1.0], [1.0, 2.0]])
        f.initialize(zs[:30], Hs[:30])
        return f

    f, ref, out = _run_both(make, zs[30:], Hs[30:], sliding_window_run, update_first=True)
    _compare(f, ref, out)
    # initialize is the compiled refit: exact least squares on the last `window` rows
    g = make()
    x, P = _reference.window_lstsq(Hs[10:30], zs[10:30].reshape(-1, 1), np.ones(20))
    _close(g.x, x, "x of initialize")
    _close(g.P, P, "P of initialize")


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("n_samples", [0, 1, 2])
def test_sliding_window_tiny_records(rng, update_first, n_samples):
    Hs, zs = _record(rng, 5)
    f, ref, out = _run_both(lambda: SlidingWindowRLS(4, 5), zs[:n_samples], Hs[:n_samples],
                            sliding_window_run, update_first=update_first)
    assert [c.shape for c in out] == [(n_samples, 4, 1), (n_samples, 4, 4)] * 2
    _compare(f, ref, out)


@pytest.mark.parametrize("dim_z", [1, 2])
def test_sliding_window_streaming_equals_batch_bit_for_bit(rng, dim_z):
    Hs, zs = _record(rng, 150, dim_z=dim_z, missing=(20, 149))
    Rs = rng.uniform(0.5, 2.0, len(zs))
    a = SlidingWindowRLS(4, 12, dim_z, refresh=30)
    b = a.copy()
    m, c, mp, cp = a.batch_filter(zs, Hs, Rs=Rs)
    for k in range(len(zs)):
        b.predict()
        assert_array_equal(mp[k], b.x)
        assert_array_equal(cp[k], b.P)
        b.update(zs[k] if dim_z > 1 else float(zs[k]), Hs[k], Rs[k])
        assert_array_equal(m[k], b.x)
        assert_array_equal(c[k], b.P)
    for name in STATE:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_sliding_window_streaming_compiled_equals_reference(rng):
    Hs, zs = _record(rng, 200, dim_z=2, missing=(5, 60), white=True)
    a = SlidingWindowRLS(4, 15, 2, refresh=40)
    ref = sliding_window_run(a, zs, Hs)
    w = _reference.SlidingWindow(a.x, a.P, a.window, a.refresh, a._x0, a._P0)
    for k in range(len(zs)):
        a.predict_update(zs[k], Hs[k])
        z = None if np.isnan(zs[k]).any() else zs[k].reshape(-1, 1)
        y, K, s = w.update(Hs[k:k + 1], z, 1.0)
        _close(a.x, w.x, "x")
        _close(a.P, w.P, "P")
        _close(a.K, K, "K")
        assert a.exact == w.exact
        _close(a.x, ref.means[k], "x of the run")


# ----------------------------------------------------------------------
# SquareRootRLS
# ----------------------------------------------------------------------
SR_OPTIONS = [
    # lam, dim_z, use_Rs, update_first, store, missing
    (1.0, 1, False, False, True, ()),
    (0.99, 1, False, True, True, ()),
    (0.95, 1, True, False, False, (0, 7, 150, 299)),
    (0.97, 2, True, True, True, (3, 4, 5, 299)),
    (1.0, 3, False, True, False, (10, 298)),
    (0.9, 2, False, False, True, (0, 1, 200)),
]


@pytest.mark.parametrize("lam, dim_z, use_Rs, update_first, store, missing", SR_OPTIONS)
def test_square_root_compiled_equals_reference(rng, lam, dim_z, use_Rs, update_first, store,
                                               missing):
    Hs, zs = _record(rng, 300, dim_z, missing)
    kwargs = {"update_first": update_first, "store_covariances": store}
    if use_Rs:
        kwargs["Rs"] = rng.uniform(0.5, 2.0, len(zs))

    def make():
        return SquareRootRLS(4, dim_z, lam=lam, P0=[[50.0, 1.0, 0, 0], [1.0, 40.0, 0, 0],
                                                    [0, 0, 30.0, 2.0], [0, 0, 2.0, 20.0]],
                             R=0.7)

    f, ref, out = _run_both(make, zs, Hs, square_root_run, **kwargs)
    _compare(f, ref, out)
    _close(f.U, ref.U, "U")


@pytest.mark.parametrize("update_first", [False, True])
@pytest.mark.parametrize("n_samples", [0, 1, 2])
def test_square_root_tiny_records_and_initialize(rng, update_first, n_samples):
    Hs, zs = _record(rng, 20)

    def make():
        f = SquareRootRLS(4, lam=0.9)
        f.initialize(zs[:8], Hs[:8])
        return f

    f, ref, out = _run_both(make, zs[8:8 + n_samples], Hs[8:8 + n_samples], square_root_run,
                            update_first=update_first)
    assert [c.shape for c in out] == [(n_samples, 4, 1), (n_samples, 4, 4)] * 2
    _compare(f, ref, out)


@pytest.mark.parametrize("dim_z", [1, 2])
def test_square_root_streaming_equals_batch_bit_for_bit(rng, dim_z):
    Hs, zs = _record(rng, 150, dim_z=dim_z, missing=(20, 149))
    a = SquareRootRLS(4, dim_z, lam=0.96)
    b = a.copy()
    m, c, mp, cp = a.batch_filter(zs, Hs)
    for k in range(len(zs)):
        b.predict()
        assert_array_equal(mp[k], b.x)
        assert_array_equal(cp[k], b.P)
        b.update(zs[k] if dim_z > 1 else float(zs[k]), Hs[k])
        assert_array_equal(m[k], b.x)
        assert_array_equal(c[k], b.P)
    for name in STATE:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert_array_equal(a.U, b.U)


def test_square_root_streaming_compiled_equals_reference(rng):
    """Each predict and update against the Givens reference, step by step."""
    Hs, zs = _record(rng, 200, dim_z=2, missing=(5, 60))
    a = SquareRootRLS(4, 2, lam=0.98, R=0.4)
    U = a.U
    d = U @ a.x
    for k in range(len(zs)):
        a.predict()
        U, d = _reference.square_root_predict(U, d, a.lam)
        _close(a.U, U, "U after predict")
        _close(a.P, _reference.square_root_covariance(U), "P_prior")
        a.update(zs[k], Hs[k])
        z = None if np.isnan(zs[k]).any() else zs[k].reshape(-1, 1)
        U, d, x, y, K, s = _reference.square_root_update(U, d, Hs[k:k + 1], z, 0.4)
        _close(a.U, U, "U")
        _close(a.x, x, "x")
        _close(a.K, K, "K")
        assert a.S[0, 0] == pytest.approx(s, rel=1e-12)
        if y is not None:
            _close(a.y, y, "y")


@pytest.mark.parametrize("n", [2, 3, 5, 7, 8, 9, 13])
@pytest.mark.parametrize("dim_z", [1, 3])
def test_square_root_blocks_of_rows_equal_reference(rng, n, dim_z):
    """The kernel rotates four rows of ``[W | v]`` per pass and solves for ``x``
    four columns at a time: every remainder (n mod 4), several outputs, and
    regressors with exact zeros (rows with nothing to eliminate) against the
    Givens reference, step by step."""
    N = 120
    Hs = rng.standard_normal((N, n))
    Hs[rng.random((N, n)) < 0.3] = 0.0                    # sparse rows: a_i = 0 exactly
    zs = Hs @ rng.standard_normal((n, dim_z)) + 0.05 * rng.standard_normal((N, dim_z))
    zs[[7, 50]] = np.nan
    if dim_z == 1:
        zs = zs[:, 0]
    P0 = np.diag(rng.uniform(10.0, 100.0, n))
    f, ref, out = _run_both(lambda: SquareRootRLS(n, dim_z, lam=0.97, P0=P0, R=0.3), zs, Hs,
                            square_root_run)
    _compare(f, ref, out)
    _close(f.U, ref.U, "U")
    # the oracle of it all: the same estimate as the covariance form
    rls = RecursiveLeastSquares(n, dim_z, lam=0.97, P0=P0, R=0.3)
    _close(rls.batch_filter(zs, Hs)[0], out[0], "means against RecursiveLeastSquares")


def test_square_root_compiled_keeps_the_factor_triangular(rng):
    Hs, zs = _record(rng, 500)
    sq = SquareRootRLS(4, lam=0.97)
    _, covs, _, _ = sq.batch_filter(zs, Hs)
    U = sq.U
    assert_array_equal(U, np.triu(U))
    assert np.all(np.diag(U) > 0)
    assert_array_equal(covs, covs.transpose(0, 2, 1))
    # an independent oracle: P = (U^T U)^-1
    _close(sq.P, np.linalg.inv(U.T @ U), "P", rtol=1e-10)


@pytest.mark.parametrize("update_first", [False, True])
def test_one_parameter_filters(rng, update_first):
    """dim_x = 1: the kernels' loops reduce to scalars (a gain tracked over time)."""
    u = rng.standard_normal(300)
    zs = np.where(np.arange(300) < 150, 2.0, -1.0) * u + 0.05 * rng.standard_normal(300)
    zs[[40, 41]] = np.nan
    Hs = u.reshape(-1, 1)
    kwargs = {"update_first": update_first, "Rs": rng.uniform(0.5, 2.0, 300)}
    for run, make in ((sliding_window_run, lambda: SlidingWindowRLS(1, 5, refresh=13)),
                      (square_root_run, lambda: SquareRootRLS(1, lam=0.9))):
        f, ref, out = _run_both(make, zs, Hs, run, **kwargs)
        _compare(f, ref, out)
        assert f.x[0, 0] == pytest.approx(-1.0, abs=0.15)     # the second gain


@pytest.mark.parametrize("make", [lambda: SlidingWindowRLS(4, 10),
                                  lambda: SquareRootRLS(4, lam=0.95)])
def test_streaming_measurement_spellings(rng, make):
    """float, numpy scalar, 0-d and (1, 1) arrays, lists and None give the same step."""
    Hs, zs = _record(rng, 30)
    filters = [make() for _ in range(5)]
    for k in range(len(zs)):
        z = zs[k]
        spellings = [float(z), np.float64(z), np.array(z), np.array([[z]]), [z]]
        if k % 7 == 3:
            spellings = [np.nan, np.float64(np.nan), None, np.array(np.nan), [np.nan]]
        for f, zk in zip(filters, spellings):
            f.predict()
            f.update(zk, Hs[k])
    for f in filters[1:]:
        for name in STATE:
            assert_array_equal(getattr(f, name), getattr(filters[0], name), err_msg=name)
    with pytest.raises(ValueError, match=r"`z` must be finite or NaN \(missing\)"):
        filters[0].update(np.inf, Hs[0])


def test_variants_benchmark_runs_in_smoke_mode(tmp_path):
    import os
    import pathlib
    import subprocess
    import sys

    ROOT = pathlib.Path(__file__).resolve().parents[1]
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    proc = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "bench_variants.py"),
                           "--smoke"], env=env, cwd=str(tmp_path), capture_output=True,
                          text=True, timeout=300, check=True)
    out = proc.stdout
    assert "speed-up" in out
    assert "SlidingWindowRLS" in out and "SquareRootRLS" in out
