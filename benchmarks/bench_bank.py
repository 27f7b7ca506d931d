"""Time RLSBank and fit_many on fleets of channels (the targets of the fleet issue).

Every timing is the thread CPU time of the best of several interleaved
rounds (``time.thread_time``; one BLAS thread), so the ratios, printed in
one run, stay meaningful on a busy machine (absolute times are not). The
parallel kernel (``numba.prange`` over blocks of channels) is timed by the
wall clock, with 1 and 2 threads.

====================  =====================================================================
row                   what runs
====================  =====================================================================
batch (bank)          ``RLSBank.batch_filter``, C channels x N samples at 4 parameters,
                      no histories (``store_means=False, store_covariances=False,
                      store_residuals=False``), as the hand-written loop keeps none
batch (bank+resid.)   the same, keeping the residual histories (two (N, C) arrays)
batch (bank+means)    the same, also storing the estimate history (N, C, 4)
handwritten           ``benchmarks/handwritten_bank.py``: a compiled loop with the channel
                      index innermost, state only (the yardstick of the 1.5x target)
loop batch_filter     one ``RecursiveLeastSquares.batch_filter`` per channel (target:
                      the bank at least 15x faster)
prange 1 / 2 threads  the bank's parallel kernel, wall clock
update (bank)         one streaming ``update`` of 1000 channels at 5 parameters (target
                      < 0.3 ms); ``predict+update (bank)`` the full step
loop predict+update   one ``predict()`` + ``update()`` per filter for the same 1000 channels
                      (target: the bank at least 40x faster)
fit_many rls          ``fit_many(ARX(2, 2, 1), u, y, "rls", residual_tests=False)`` on the
                      record behind the batch rows (target: within 2x of ``batch_filter``
                      on its regressors, with the residual histories fit_many reports:
                      ``batch (bank+resid.)``); ``fit_many ls``, and ``fit_many rls +
                      tests`` with the residual tests
====================  =====================================================================

Usage::

    python benchmarks/bench_bank.py              # the table (a minute or two)
    python benchmarks/bench_bank.py --smoke      # tiny sizes, seconds
    python benchmarks/bench_bank.py --markdown   # the table for docs/performance.md
    python benchmarks/bench_bank.py --dask       # also channels x samples / s on 1 and
                                                 # 2 dask workers
"""

import os

# one BLAS thread (set before NumPy loads its BLAS): small matrices, no oversubscription
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from handwritten_bank import rls_bank_handwritten  # noqa: E402

import rlsfilt  # noqa: E402
from rlsfilt import ARX, RecursiveLeastSquares, RLSBank, fit_many  # noqa: E402
from rlsfilt.models import fleet  # noqa: E402

LAM = 0.99
P0 = 1e4


# ----------------------------------------------------------------------
# the workload: C second-order ARX plants (4 parameters), white equation error
# ----------------------------------------------------------------------
def fleet_record(C, N, rng):
    """Inputs and outputs ``(N, C)`` of C stable second-order plants."""
    r = rng.uniform(0.5, 0.85, C)
    w = rng.uniform(0.3, 1.2, C)
    a1, a2 = -2 * r * np.cos(w), r * r
    u = rng.standard_normal((N + 2, C))
    e = 0.1 * rng.standard_normal((N + 2, C))
    y = np.zeros((N + 2, C))
    for t in range(2, N + 2):
        y[t] = -a1 * y[t - 1] - a2 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2] + e[t]
    return u, y


def regressors(u, y):
    """The ARX(2, 2, 1) regressors ``(N, C, 4)`` and targets ``(N, C)`` of every channel."""
    s = rlsfilt.models.arx_structure(2, 2, 1)
    return fleet._regressors(u[:, :, None], y, s)


def _best(fn, rounds, clock=time.thread_time):
    best = np.inf
    for _ in range(rounds):
        t0 = clock()
        fn()
        best = min(best, clock() - t0)
    return best


# ----------------------------------------------------------------------
# contenders
# ----------------------------------------------------------------------
def run_bank(Hs, zs, store_means=False, store_residuals=False):
    bank = RLSBank(zs.shape[1], Hs.shape[2], lam=LAM, P0=P0)
    bank.batch_filter(zs, Hs, store_covariances=False, store_means=store_means,
                      store_residuals=store_residuals)
    return bank.x


def run_handwritten(Hs, zs):
    return rls_bank_handwritten(Hs, zs, np.full(zs.shape[1], LAM), P0)[0]


def run_loop(Hs, zs):
    out = np.empty((zs.shape[1], Hs.shape[2]))
    for c in range(zs.shape[1]):
        f = RecursiveLeastSquares(Hs.shape[2], lam=LAM, P0=P0)
        f.batch_filter(zs[:, c], Hs[:, c], store_covariances=False)
        out[c] = f.x[:, 0]
    return out


def run_parallel(Hs, zs, threads):
    import numba

    previous = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        bank = RLSBank(zs.shape[1], Hs.shape[2], lam=LAM, P0=P0, parallel=True)
        bank.batch_filter(zs, Hs, store_covariances=False, store_means=False,
                          store_residuals=False)
    finally:
        numba.set_num_threads(previous)
    return bank.x


def streaming(C, n, steps, rounds, rng):
    """Per-step times of the bank's update and predict+update, and of the filter loop."""
    H = rng.standard_normal((steps, C, n))
    z = rng.standard_normal((steps, C))
    bank = RLSBank(C, n, lam=LAM, P0=P0)
    bank.predict()
    bank.update(z[0], H[0])
    filters = [RecursiveLeastSquares(n, lam=LAM, P0=P0) for _ in range(C)]
    t_update = t_step = t_loop = np.inf
    for _ in range(rounds):
        for k in range(steps):
            bank.predict()
            t0 = time.thread_time()
            bank.update(z[k], H[k])
            t_update = min(t_update, time.thread_time() - t0)
            t0 = time.thread_time()
            bank.predict()
            bank.update(z[k], H[k])
            t_step = min(t_step, time.thread_time() - t0)
        t0 = time.thread_time()
        for k in range(min(steps, 5)):
            zk, Hk = z[k], H[k]
            for c, f in enumerate(filters):
                f.predict()
                f.update(zk[c], Hk[c])
        t_loop = min(t_loop, (time.thread_time() - t0) / min(steps, 5))
    return t_update, t_step, t_loop


# ----------------------------------------------------------------------
# the table
# ----------------------------------------------------------------------
def bench(C, N, C_stream, rounds, loop_channels, tests_channels):
    rng = np.random.default_rng(0)
    u, y = fleet_record(C, N, rng)
    Hs, zs = regressors(u, y)
    # warm up (compilation is cached on disk after the first run)
    run_bank(Hs[:5, :40], zs[:5, :40])
    run_handwritten(Hs[:5, :40], zs[:5, :40])
    run_parallel(Hs[:5, :40], zs[:5, :40], 1)
    run_loop(Hs[:5, :2], zs[:5, :2])
    fit_many(ARX(2, 2, 1), u[:, :20], y[:, :20], "rls", residual_tests=False)
    fit_many(ARX(2, 2, 1), u[:, :20], y[:, :20], residual_tests=False)
    check = np.abs(run_bank(Hs, zs) - run_handwritten(Hs, zs)).max()
    assert check < 1e-8, check
    sub = slice(0, loop_channels)
    t = {}
    for _ in range(rounds):       # interleaved rounds, the best of each
        for name, fn, clock in [
                ("batch (bank)", lambda: run_bank(Hs, zs), time.thread_time),
                ("batch (bank+resid.)", lambda: run_bank(Hs, zs, False, True),
                 time.thread_time),
                ("batch (bank+means)", lambda: run_bank(Hs, zs, True, True),
                 time.thread_time),
                ("handwritten", lambda: run_handwritten(Hs, zs), time.thread_time),
                ("prange 1 thread", lambda: run_parallel(Hs, zs, 1), time.perf_counter),
                ("prange 2 threads", lambda: run_parallel(Hs, zs, 2), time.perf_counter),
                ("fit_many rls", lambda: fit_many(ARX(2, 2, 1), u, y, "rls",
                                                  residual_tests=False), time.thread_time),
                ("fit_many ls", lambda: fit_many(ARX(2, 2, 1), u, y, residual_tests=False),
                 time.thread_time)]:
            t[name] = min(t.get(name, np.inf), _best(fn, 1, clock))
    t["loop batch_filter"] = _best(lambda: run_loop(Hs[:, sub], zs[:, sub]), 1) \
        * C / loop_channels
    tc = min(tests_channels, C)
    t["fit_many rls + tests"] = _best(
        lambda: fit_many(ARX(2, 2, 1), u[:, :tc], y[:, :tc], "rls"), 1) * C / tc
    t_update, t_step, t_loop = streaming(C_stream, 5, 20, rounds, rng)
    return t, (t_update, t_step, t_loop), (C, N, C_stream)


def report(t, stream, sizes, markdown=False):
    C, N, Cs = sizes
    t_update, t_step, t_loop = stream
    hand, bank, resid = t["handwritten"], t["batch (bank)"], t["batch (bank+resid.)"]
    rows = [
        ("batch (bank)", bank, f"{bank / hand:.2f}x handwritten (target <= 1.5)"),
        ("batch (bank+resid.)", t["batch (bank+resid.)"],
         f"{t['batch (bank+resid.)'] / hand:.2f}x handwritten"),
        ("batch (bank+means)", t["batch (bank+means)"],
         f"{t['batch (bank+means)'] / hand:.2f}x handwritten"),
        ("handwritten", hand, "1.00x"),
        ("loop batch_filter", t["loop batch_filter"],
         f"bank {t['loop batch_filter'] / bank:.0f}x faster (target >= 15), bank+resid. "
         f"{t['loop batch_filter'] / resid:.0f}x"),
        ("prange 1 thread (wall)", t["prange 1 thread"], ""),
        ("prange 2 threads (wall)", t["prange 2 threads"],
         f"{t['prange 1 thread'] / t['prange 2 threads']:.2f}x the 1-thread speed"),
        ("fit_many rls", t["fit_many rls"],
         f"{t['fit_many rls'] / resid:.2f}x batch (bank+resid.) (target <= 2)"),
        ("fit_many ls", t["fit_many ls"],
         f"{t['fit_many ls'] / resid:.2f}x batch (bank+resid.)"),
        ("fit_many rls + tests", t["fit_many rls + tests"],
         f"{t['fit_many rls + tests'] / resid:.0f}x batch (bank+resid.) (residual tests "
         "included)"),
    ]
    stream_rows = [
        ("update (bank)", t_update, f"target < 0.3 ms; loop is {t_loop / t_update:.0f}x slower"),
        ("predict+update (bank)", t_step, f"loop is {t_loop / t_step:.0f}x slower (target >= 40)"),
        ("loop predict+update", t_loop, ""),
    ]
    if markdown:
        print(f"| {C} channels x {N} samples, 4 parameters | time | ratio |")
        print("|---|---|---|")
        for name, sec, note in rows:
            print(f"| {name} | {sec:.3f} s | {note} |")
        print()
        print(f"| one step of {Cs} channels, 5 parameters | time | ratio |")
        print("|---|---|---|")
        for name, sec, note in stream_rows:
            print(f"| {name} | {1e3 * sec:.3f} ms | {note} |")
        return
    print(f"{C} channels x {N} samples at 4 parameters (thread CPU time, best of rounds)")
    for name, sec, note in rows:
        print(f"  {name:26s} {sec:9.4f} s   {note}")
    print(f"one streaming step of {Cs} channels at 5 parameters")
    for name, sec, note in stream_rows:
        print(f"  {name:26s} {1e3 * sec:9.4f} ms  {note}")


def _warm_up(method, residual_tests):
    rng = np.random.default_rng(0)
    u = rng.standard_normal((200, 4))
    fit_many(ARX(2, 2, 1), u, 0.5 * u + 0.1 * rng.standard_normal((200, 4)), method,
             residual_tests=residual_tests)


def dask_scaling(C, N, method, workers, residual_tests):
    """Channels x samples per second of rlsfilt.dask.fit_many on 1 and 2 local workers.

    The record is generated on the workers (``dask.array.random``) and kept
    there (``persist``) before the clock starts, so the time is that of the
    fits, and only the per-channel summaries cross process boundaries.
    """
    import dask.array as da
    from dask.distributed import Client, LocalCluster, wait

    import rlsfilt.dask

    out = {}
    for n in workers:
        with LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                          dashboard_address=":0") as cluster, Client(cluster) as client:
            rs = da.random.RandomState(0)
            u = rs.standard_normal((N, C), chunks=(-1, max(1, C // (4 * n))))
            y = 0.5 * u + 0.1 * rs.standard_normal((N, C), chunks=u.chunks)
            u, y = client.persist([u, y])
            wait([u, y])
            client.run(_warm_up, method, residual_tests)    # load the kernels on every worker
            t0 = time.perf_counter()
            rlsfilt.dask.fit_many(ARX(2, 2, 1), u, y, method, client=client,
                                  residual_tests=residual_tests)
            out[n] = C * N / (time.perf_counter() - t0)
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--smoke", action="store_true", help="tiny sizes (seconds)")
    parser.add_argument("--channels", type=int, default=10000)
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--markdown", action="store_true", help="print Markdown tables")
    parser.add_argument("--dask", action="store_true",
                        help="also time rlsfilt.dask.fit_many on 1 and 2 local workers")
    args = parser.parse_args(argv)
    if args.smoke:
        C, N, Cs, rounds, loop, tests = 64, 200, 50, 1, 8, 8
    else:
        C, N, Cs, rounds, loop, tests = (args.channels, args.samples, 1000, args.rounds,
                                         200, 500)
    t, stream, sizes = bench(C, N, Cs, rounds, loop, tests)
    report(t, stream, sizes, markdown=args.markdown)
    if args.dask:
        Cd, Nd = (64, 200) if args.smoke else (C, N)
        for method, tests_on in (("rls", False), ("ls", False), ("rls", True)):
            rate = dask_scaling(Cd, Nd, method, (1, 2), tests_on)
            label = f"dask fit_many {method}{' + tests' if tests_on else ''}"
            print(f"  {label:30s} " + "   ".join(
                f"{n} worker(s): {r / 1e6:.2f} M channel-samples/s" for n, r in rate.items()))


if __name__ == "__main__":
    main()
