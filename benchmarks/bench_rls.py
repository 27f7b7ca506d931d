"""Time rlsfilt's RLS against its peers on one ARX workload.

Every contender runs exponentially forgetting RLS (``lam = 0.99``,
``P0 = 1e4 I``) on the same regressors and measurements of an ARX plant
with ``dim_x`` parameters, and the script prints the time per sample and
its ratio to a careful hand-written compiled loop
(:mod:`handwritten`, the yardstick; ratio < 1 means faster than it):

========================  ===================================================
``batch_filter``          ``RecursiveLeastSquares.batch_filter(store_covariances=False)``
``batch_filter+P``        the same, storing both covariance histories
``write 2 N n^2``         allocating and filling two ``(N, n, n)`` arrays: the floor
                          of ``batch_filter+P`` on this machine
``kernel``                rlsfilt's compiled kernel without the Python wrapper
``ARX.fit``               ``ARX(na, nb).fit(u, y, method="rls")``: regressors, the
                          filter run and the fit's statistics
``predict+update``        the streaming pair, one Python call each per sample
``handwritten``           the yardstick (``benchmarks/handwritten.py``)
``numpy loop``            a lean pure-NumPy loop
``filterpy``              ``filterpy.kalman.KalmanFilter`` as RLS (predict+update)
``padasip``               ``padasip.filters.FilterRLS.run``
``statsmodels``           ``statsmodels.api.RecursiveLS(...).fit()`` (no forgetting)
========================  ===================================================

The slow contenders (pure Python per sample) run on the first
``--peer-samples`` samples only; all times are per sample. Every contender
runs once per round, rounds are interleaved and the best round counts, which
keeps the ratios meaningful on a busy machine (absolute times are not). On a
machine that other jobs load heavily, ``--clock cpu`` times each contender
by the process's CPU time instead of wall time (run with
``OPENBLAS_NUM_THREADS=1``, so that every contender computes in one thread).

Usage::

    python benchmarks/bench_rls.py --smoke          # a few seconds (CI)
    python benchmarks/bench_rls.py                  # the full table, minutes
    python benchmarks/bench_rls.py --plot bench.png --markdown
    # the figure of the docs, redrawn from its saved times without measuring again:
    python benchmarks/bench_rls.py --replot docs/images/bench_rls.json \
        --plot docs/images/bench_rls.png

Install the peers with ``pip install rlsfilt[bench]``; a peer that is not
installed is skipped.

Two narrower measurements of the streaming pair (``docs/performance.md``,
"Streaming" and "Threads"; thread CPU time, ``OPENBLAS_NUM_THREADS=1``, the
shared 2-core machine at a load average of 8 to 12)::

    python benchmarks/bench_rls.py --streaming-ablation --dims 2 5 20 --rounds 7
    #   dim_x         2        5        20
    #   before #27    4.87 us  4.96 us  5.44 us   (predict()+update() as shipped)
    #   after #27     5.17 us  5.20 us  5.71 us   (with the lock; the fast paths
    #                                              for a float64 row and a float z
    #                                              save 0.1-0.2 us of it)
    #   kernels + the 13 fresh arrays of a step:  3.37, 3.42, 3.85 us (the floor
    #                 of a step handing out new filterpy attributes)
    #   kernels alone 1.38 us  1.40 us  1.59 us
    python benchmarks/bench_rls.py --lock-cost --dims 2 5 20 --rounds 9
    #   the two lock acquisitions of a pair: 0.24-0.25 us, 4.5-4.9 % of the step
"""

import argparse
import json
import os
import sys
import time
import warnings

import numpy as np
from scipy.signal import lfilter

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from handwritten import rls_handwritten  # noqa: E402

import rlsfilt  # noqa: E402
from rlsfilt.filters import _kernels  # noqa: E402
from rlsfilt.filters.forgetting import EXPONENTIAL, kernel_config, mode_params  # noqa: E402

LAM = 0.99
P0 = 1e4
FULL_DIMS = (2, 5, 10, 20, 50)
COLUMNS = ("batch_filter", "batch_filter+P", "write 2 N n^2", "kernel", "ARX.fit",
           "predict+update", "handwritten", "numpy loop", "filterpy", "padasip", "statsmodels")
# one distinct colour, marker and line style per contender in the plot: rlsfilt's own paths solid
# (Okabe-Ito colours), the reference loops dashed, the peer libraries dotted (the colours are
# colour-blind-safe; marker and line style tell the families apart without colour)
STYLES = {
    "batch_filter": ("#0072B2", "o", "-"),
    "batch_filter+P": ("#56B4E9", "s", "-"),
    "kernel": ("#009E73", "^", "-"),
    "ARX.fit": ("#CC79A7", "D", "-"),
    "predict+update": ("#E69F00", "v", "-"),
    "write 2 N n^2": ("#7F7F7F", "", "--"),
    "handwritten": ("#000000", "x", "--"),
    "numpy loop": ("#882255", "P", "--"),
    "filterpy": ("#D55E00", "o", ":"),
    "padasip": ("#332288", "s", ":"),
    "statsmodels": ("#999933", "*", ":"),
}


# ----------------------------------------------------------------------
# the workload
# ----------------------------------------------------------------------
def arx_data(dim_x, n_samples, rng):
    """Regressors ``(N, dim_x)`` and outputs ``(N,)`` of a stable ARX plant.

    ``na = dim_x // 2`` output lags and ``nb = dim_x - na`` input lags, a
    white-noise input, poles of radius 0.6 and noise of standard deviation
    0.1.
    """
    na, nb = dim_x // 2, dim_x - dim_x // 2
    lag = max(na, nb)
    total = n_samples + lag
    u = rng.standard_normal(total)
    poles = 0.6 * np.exp(1j * np.pi * rng.uniform(0.1, 0.9, na))
    a = np.real(np.poly(np.concatenate([poles[: na // 2], np.conj(poles[: na // 2]),
                                        np.real(poles[na // 2 * 2:])])))
    b = np.concatenate([[0.0], rng.uniform(-1.0, 1.0, nb)])
    y = lfilter(b, a, u) + lfilter([1.0], a, 0.1 * rng.standard_normal(total))
    cols = [-y[lag - i: total - i] for i in range(1, na + 1)]
    cols += [u[lag - i: total - i] for i in range(1, nb + 1)]
    Hs = np.ascontiguousarray(np.column_stack(cols))
    zs = np.ascontiguousarray(y[lag:])
    _IO[id(Hs)] = (u, y, na, nb)     # the raw record, for ARX.fit
    return Hs, zs


_IO = {}


def run_arx_fit(Hs, zs):
    """``ARX(na, nb).fit(u, y, method="rls")`` on the record behind ``Hs``, regressors included."""
    base = Hs.base if Hs.base is not None and id(Hs.base) in _IO else Hs
    u, y, na, nb = _IO[id(base)]
    lag = max(na, nb)
    N = len(zs)
    model = rlsfilt.ARX(na, nb, nk=1).fit(u[:N + lag], y[:N + lag], method="rls", lam=LAM,
                                          P0=P0)
    return model.theta_


# ----------------------------------------------------------------------
# the contenders: each takes (Hs, zs) and runs the whole record
# ----------------------------------------------------------------------
def run_batch(Hs, zs):
    rls = rlsfilt.RecursiveLeastSquares(Hs.shape[1], lam=LAM, P0=P0)
    rls.batch_filter(zs, Hs, store_covariances=False)
    return rls.x.ravel()


def run_batch_cov(Hs, zs):
    rls = rlsfilt.RecursiveLeastSquares(Hs.shape[1], lam=LAM, P0=P0)
    rls.batch_filter(zs, Hs, store_covariances=True)
    return rls.x.ravel()


def run_write_floor(Hs, zs):
    """Allocate and fill the two covariance histories: the floor of ``batch_filter+P``."""
    N, n = Hs.shape
    a, b = np.empty((N, n, n)), np.empty((N, n, n))
    a.fill(1.0)
    b.fill(1.0)
    return a[-1, 0] + b[-1, :, 0]


def run_kernel(Hs, zs):
    n = Hs.shape[1]
    params = mode_params(EXPONENTIAL, None, n, LAM, 1.0, n * P0)      # the windup cap
    out = _kernels.run_batch(np.zeros((n, 1)), P0 * np.eye(n), zs.reshape(-1, 1), Hs,
                             np.ones(1), kernel_config(EXPONENTIAL, LAM, params), None, None,
                             False, False, 0, 0, np.inf, (1.0, 0.0, 0.0, 0.0, 1.0))
    return out.x.ravel()


def run_stream(Hs, zs):
    rls = rlsfilt.RecursiveLeastSquares(Hs.shape[1], lam=LAM, P0=P0)
    predict, update = rls.predict, rls.update
    for k in range(len(zs)):
        predict()
        update(zs[k], Hs[k])
    return rls.x.ravel()


def run_handwritten(Hs, zs):
    n = Hs.shape[1]
    thetas, _ = rls_handwritten(Hs, zs, LAM, P0 * np.eye(n), np.zeros(n))
    return thetas[-1]


def run_numpy(Hs, zs):
    n = Hs.shape[1]
    P = P0 * np.eye(n)
    th = np.zeros(n)
    for h, z in zip(Hs, zs):
        g = P @ h
        s = LAM + h @ g
        th = th + g * ((z - h @ th) / s)
        P = (P - np.outer(g, g / s)) / LAM
        P = 0.5 * (P + P.T)
    return th


def run_filterpy(Hs, zs):
    from filterpy.kalman import KalmanFilter

    n = Hs.shape[1]
    kf = KalmanFilter(dim_x=n, dim_z=1)
    kf.F = np.eye(n)
    kf.P = P0 * np.eye(n)
    kf.Q = np.zeros((n, n))
    kf.R = np.eye(1)
    kf.alpha = np.sqrt(1.0 / LAM)
    for k in range(len(zs)):
        kf.predict()
        kf.update(zs[k], H=Hs[k:k + 1])
    return kf.x.ravel()


def run_padasip(Hs, zs):
    from padasip.filters import FilterRLS

    f = FilterRLS(Hs.shape[1], mu=LAM, eps=1.0 / P0, w="zeros")
    f.run(zs, Hs)
    return f.w


def run_statsmodels(Hs, zs):
    import statsmodels.api as sm

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = sm.RecursiveLS(zs, Hs).fit()
    return np.asarray(res.params)


CONTENDERS = {
    "batch_filter": (run_batch, "full", None),
    "batch_filter+P": (run_batch_cov, "cov", None),
    "write 2 N n^2": (run_write_floor, "cov", None),
    "kernel": (run_kernel, "full", None),
    "ARX.fit": (run_arx_fit, "full", None),
    "predict+update": (run_stream, "peer", None),
    "handwritten": (run_handwritten, "full", None),
    "numpy loop": (run_numpy, "peer", None),
    "filterpy": (run_filterpy, "peer", "filterpy"),
    "padasip": (run_padasip, "peer", "padasip"),
    "statsmodels": (run_statsmodels, "peer", "statsmodels"),
}


def _available(module):
    if module is None:
        return True
    try:
        __import__(module)
    except ImportError:
        return False
    return True


# ----------------------------------------------------------------------
# timing
# ----------------------------------------------------------------------
def bench(dims, n_samples, peer_samples, rounds, max_cov_numbers=2e7, max_numbers=2e7,
          rng=0, log=print, clock=time.perf_counter):
    """Time every contender; returns ``{dim_x: {name: seconds per sample}}``.

    The compiled contenders run on ``min(n_samples, max_numbers / dim_x)``
    samples (the estimate history is ``N x dim_x``), ``batch_filter+P`` on
    at most ``max_cov_numbers / dim_x**2`` and the per-sample Python ones on
    ``peer_samples``.
    """
    rng = np.random.default_rng(rng)
    results = {}
    for n in dims:
        N = int(min(n_samples, max_numbers / n))
        Hs, zs = arx_data(n, N, rng)
        sizes = {"full": N, "cov": int(min(N, max_cov_numbers / n**2)),
                 "peer": min(N, peer_samples)}
        todo = {name: (fn, sizes[kind]) for name, (fn, kind, mod) in CONTENDERS.items()
                if _available(mod)}
        for fn, _ in todo.values():                 # compile / load caches, warm up
            fn(Hs[:50], zs[:50])
        best = {name: np.inf for name in todo}
        for _ in range(rounds):
            for name, (fn, size) in todo.items():
                t0 = clock()
                fn(Hs[:size], zs[:size])
                best[name] = min(best[name], (clock() - t0) / size)
        results[n] = best
        log(f"dim_x = {n:3d}: N = {N}, " + ", ".join(
            f"{k} {v * 1e9:.0f} ns" for k, v in best.items()))
    return results


def ratio_table(results, markdown=False):
    """Text table of time per sample relative to the hand-written loop."""
    names = [c for c in COLUMNS if any(c in r for r in results.values())]
    head = ["dim_x", "handwritten [ns]"] + [c for c in names if c != "handwritten"]
    rows = []
    for n, r in results.items():
        ref = r["handwritten"]
        row = [str(n), f"{ref * 1e9:.0f}"]
        for c in names:
            if c == "handwritten":
                continue
            row.append(f"{r[c] / ref:.3g}" if c in r else "-")
        rows.append(row)
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(row) + " |" for row in rows]
        return "\n".join(lines)
    widths = [max(len(h), *(len(row[i]) for row in rows)) for i, h in enumerate(head)]
    fmt = "  ".join(f"{{:>{w}}}" for w in widths)
    return "\n".join([fmt.format(*head)] + [fmt.format(*row) for row in rows])


def streaming_vs_filterpy(results):
    """Speed-up of rlsfilt's predict+update pair over filterpy's, per dim_x."""
    return {n: r["filterpy"] / r["predict+update"] for n, r in results.items()
            if "filterpy" in r and "predict+update" in r}


def streaming_ablation(dims, n_samples=5000, rounds=7, rng=0, log=print):
    """Time the streaming pair against the floors a trick could bring it to.

    ``as shipped``: ``predict()`` then ``update()``; ``kernels + arrays``: the
    two compiled calls plus the 13 new arrays a step hands out as filterpy's
    attributes (``P`` and ``P_prior`` of the predict, ``x_prior``, the copied
    row ``H`` and column ``z``, ``x``, ``P``, ``y``, ``K``, ``S``, ``SI``,
    ``x_post``, ``P_post``), with no validation, lock or bookkeeping: the
    floor of any step that, like filterpy's, hands out fresh arrays and never
    reuses them; ``kernels alone``: the
    two compiled calls they make (``predict_kernel``, ``update_kernel``)
    through numba's dispatcher on arrays allocated once, so no validation,
    no new arrays and no commit: the floor of any Python-side trick (the
    recycled arrays and the deferred predict of versions before 0.9);
    ``entry points``: the same two calls through the compiled entry points
    (what the direct calls of before 0.9 saved at most). Thread CPU time per
    sample (``time.thread_time``: steadier than wall time on a busy
    machine); returns ``{dim_x: {variant: seconds}}``.
    """
    from numba import typeof

    from rlsfilt.filters import _streaming

    kern = _streaming.kernels()
    rng = np.random.default_rng(rng)
    results = {}
    for n in dims:
        Hs, zs = arx_data(n, n_samples, rng)
        rls = rlsfilt.RecursiveLeastSquares(n, lam=LAM, P0=P0)
        x, P, cfg, Q = rls.x, rls.P, rls._cfg, np.zeros((0, 0))
        rows, cols = Hs.reshape(-1, 1, n).copy(), zs.reshape(-1, 1, 1).copy()
        outs = (np.empty((n, 1)), np.empty((n, n)), np.empty((1, 1)), np.empty((n, 1)),
                np.empty((1, 1)), np.empty((1, 1)))
        Pm = np.empty((n, n))
        args_p = (P, 1.0 / LAM, Q, cfg, Pm)
        args_u = (x, Pm, rows[0], cols[0], 1.0, cfg, 1.0) + outs
        kern.predict_kernel(*args_p)
        kern.update_kernel(*args_u)
        entry_p = kern.predict_kernel.overloads[tuple(map(typeof, args_p))].entry_point
        entry_u = kern.update_kernel.overloads[tuple(map(typeof, args_u))].entry_point

        def kernels_alone(predict_kernel, update_kernel, P=P, Q=Q, cfg=cfg, Pm=Pm, x=x,
                          rows=rows, cols=cols, outs=outs):
            for k in range(n_samples):
                predict_kernel(P, 1.0 / LAM, Q, cfg, Pm)
                update_kernel(x, Pm, rows[k], cols[k], 1.0, cfg, 1.0, *outs)

        def kernels_and_arrays(n=n, P=P, Q=Q, cfg=cfg, x=x, Hs=Hs, zs=zs):
            for k in range(n_samples):
                P_prior = np.empty((n, n))
                kern.predict_kernel(P, 1.0 / LAM, Q, cfg, P_prior)
                x.copy(), P_prior.copy()                                  # x_prior, P_prior
                H, z = np.array(Hs[k], ndmin=2), np.array(zs[k], ndmin=2)
                xn, Pn, y, K, S, SI = (np.empty((n, 1)), np.empty((n, n)), np.empty((1, 1)),
                                       np.empty((n, 1)), np.empty((1, 1)), np.empty((1, 1)))
                kern.update_kernel(x, P_prior, H, z, 1.0, cfg, 1.0, xn, Pn, y, K, S, SI)
                xn.copy(), Pn.copy()                                      # x_post, P_post

        variants = {"as shipped": lambda Hs=Hs, zs=zs: run_stream(Hs, zs),
                    "kernels + arrays": kernels_and_arrays,
                    "kernels alone": lambda: kernels_alone(kern.predict_kernel,
                                                           kern.update_kernel),
                    "entry points": lambda p=entry_p, u=entry_u: kernels_alone(p, u)}
        best = dict.fromkeys(variants, np.inf)
        for _ in range(rounds):
            for name, run in variants.items():
                t0 = time.thread_time()
                run()
                best[name] = min(best[name], (time.thread_time() - t0) / n_samples)
        results[n] = best
        log(f"dim_x = {n:3d}, predict+update: " + ", ".join(
            f"{k} {v * 1e6:.2f} us" for k, v in best.items()))
    return results


def lock_cost(dims, n_samples=5000, rounds=7, rng=0, log=print):
    """Time the filter's lock against the streaming pair it guards.

    ``predict+update``: the pair as shipped (each call holds the filter's
    reentrant lock, so a filter shared by threads loses no update);
    ``lock``: what the two acquisitions cost alone, ``with rls._lock:`` twice
    per sample in the same kind of loop, minus the empty loop. Thread CPU
    time per sample, interleaved rounds, best round; returns ``{dim_x:
    {variant: seconds}}`` and logs the lock's share of the step.
    """
    rng = np.random.default_rng(rng)
    results = {}
    for n in dims:
        Hs, zs = arx_data(n, n_samples, rng)
        lock = rlsfilt.RecursiveLeastSquares(n)._lock

        def locks(lock=lock):
            for _ in range(n_samples):
                with lock:
                    pass
                with lock:
                    pass

        def empty():
            for _ in range(n_samples):
                pass

        variants = {"predict+update": lambda Hs=Hs, zs=zs: run_stream(Hs, zs), "locks": locks,
                    "empty": empty}
        for run in variants.values():
            run()
        best = dict.fromkeys(variants, np.inf)
        for _ in range(rounds):
            for name, run in variants.items():
                t0 = time.thread_time()
                run()
                best[name] = min(best[name], (time.thread_time() - t0) / n_samples)
        result = {"predict+update": best["predict+update"],
                  "lock": max(best["locks"] - best["empty"], 0.0)}
        results[n] = result
        log(f"dim_x = {n:3d}: predict+update {result['predict+update'] * 1e6:.2f} us, of "
            f"which the two lock acquisitions {result['lock'] * 1e6:.3f} us "
            f"({100 * result['lock'] / result['predict+update']:.1f} %)")
    return results


def plot(results, path=None, ax=None):
    """Time per sample against dim_x, one line per contender; returns the axes."""
    import matplotlib.pyplot as plt
    from matplotlib.ticker import NullFormatter

    if ax is None:
        _, ax = plt.subplots(figsize=(8, 4.5))
    dims = sorted(results)
    for c in COLUMNS:
        ys = [results[n].get(c, np.nan) * 1e9 for n in dims]
        if not np.all(np.isnan(ys)):
            color, marker, style = STYLES[c]
            ax.loglog(dims, ys, color=color, marker=marker, linestyle=style, lw=1.4, ms=5,
                      label=c)
    ax.set_xticks(dims)
    ax.set_xticklabels([str(n) for n in dims])
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.set_xlabel(r"number of parameters $n$ (dim_x)")
    ax.set_ylabel("time per sample [ns]")
    ax.set_title(r"RLS, $\lambda = 0.99$, ARX workload")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8, loc="center left", bbox_to_anchor=(1.01, 0.5))
    if path:
        ax.figure.savefig(path, dpi=150, bbox_inches="tight")
    return ax


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--smoke", action="store_true",
                        help="tiny sizes, one round: checks that everything runs (seconds)")
    parser.add_argument("--dims", type=int, nargs="+", help="values of dim_x (default: "
                        "2 5 10 20 50, smoke: 2 5)")
    parser.add_argument("-N", "--samples", type=float, default=1e6,
                        help="samples for the compiled contenders (default 1e6)")
    parser.add_argument("--peer-samples", type=int, default=3000,
                        help="samples for the per-sample Python contenders (default 3000)")
    parser.add_argument("--rounds", type=int, default=5, help="interleaved rounds (default 5)")
    parser.add_argument("--plot", metavar="PATH", help="save a plot of the times")
    parser.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    parser.add_argument("--clock", choices=("wall", "cpu"), default="wall",
                        help="wall: time.perf_counter (default); cpu: time.process_time, the "
                             "process's CPU time, steadier on a machine other jobs load")
    parser.add_argument("--streaming-ablation", action="store_true",
                        help="only time predict+update against its compiled calls alone")
    parser.add_argument("--lock-cost", action="store_true",
                        help="only time predict+update with and without the filter's lock")
    parser.add_argument("--json", metavar="PATH",
                        help="also save the times (seconds per sample) as JSON")
    parser.add_argument("--replot", metavar="JSON",
                        help="do not measure: plot the times saved by --json (with --plot)")
    args = parser.parse_args(argv)
    if args.replot:
        with open(args.replot) as f:
            results = {int(n): r for n, r in json.load(f).items()}
        if args.plot:
            plot(results, args.plot)
            print(f"plot saved to {args.plot}")
        return results
    if args.streaming_ablation:
        return streaming_ablation(args.dims or [5, 20], rounds=1 if args.smoke else args.rounds)
    if args.lock_cost:
        return lock_cost(args.dims or [2, 5, 20], rounds=1 if args.smoke else args.rounds)
    if args.smoke:
        dims = args.dims or [2, 5]
        n_samples, peer_samples, rounds = 2000, 100, 1
    else:
        dims = args.dims or list(FULL_DIMS)
        n_samples, peer_samples, rounds = int(args.samples), args.peer_samples, args.rounds
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    results = bench(dims, n_samples, peer_samples, rounds, clock=clock)
    print()
    print("time per sample as a ratio to the hand-written compiled loop (< 1: faster);")
    print("the second column is the loop's own time per sample")
    print(ratio_table(results, markdown=args.markdown))
    speedup = streaming_vs_filterpy(results)
    if speedup:
        print()
        print("streaming predict+update, speed-up over filterpy's KalmanFilter: " + ", ".join(
            f"dim_x={n}: {v:.1f}x" for n, v in speedup.items()))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({str(n): r for n, r in results.items()}, f, indent=1)
    if args.plot:
        plot(results, args.plot)
        print(f"plot saved to {args.plot}")
    return results


if __name__ == "__main__":
    main()
