"""Time the compiled SlidingWindowRLS and SquareRootRLS against their NumPy reference.

Both filters run their recursion in compiled code (``_kernels_window``);
the same recursion in textbook NumPy is ``tests/_reference.py``
(``SlidingWindow``, ``square_root_update``). This script times, per sample
and on the same ARX data as ``bench_rls.py``:

==================  =========================================================
``batch``           ``batch_filter(store_covariances=False)``
``batch+P``         the same, storing both covariance histories
``stream``          ``predict()`` + ``update()`` per sample
``reference``       the NumPy reference recursion, one step per sample
``RLS batch``       ``RecursiveLeastSquares.batch_filter`` (exponential
                    forgetting), for scale
==================  =========================================================

and prints the speed-up of ``batch`` over ``reference``. The reference and
``stream`` run on the first ``--slow-samples`` samples only. Every
contender runs once per round, rounds are interleaved and the best round
counts.

Usage::

    python benchmarks/bench_variants.py --smoke     # a few seconds
    python benchmarks/bench_variants.py             # dim_x 2..20, N = 20000
"""

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# the textbook recursions live with the tests (not installed with the package)
sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                                "tests"))

import _reference  # noqa: E402
from bench_rls import arx_data  # noqa: E402

import rlsfilt  # noqa: E402

LAM = 0.99
P0 = 1e4
COLUMNS = ("batch", "batch+P", "stream", "reference", "RLS batch")


def _sliding_window_reference(window):
    def run(Hs, zs):
        n = Hs.shape[1]
        w = _reference.SlidingWindow(np.zeros((n, 1)), P0 * np.eye(n), max(window, n),
                                     10 * max(window, n), np.zeros((n, 1)), P0 * np.eye(n))
        for k in range(len(zs)):
            w.update(Hs[k:k + 1], zs[k:k + 1].reshape(1, 1), 1.0)
        return w.x.ravel()
    return run


def _square_root_reference(Hs, zs):
    n = Hs.shape[1]
    U, d = np.eye(n) / np.sqrt(P0), np.zeros((n, 1))
    for k in range(len(zs)):
        U, d = _reference.square_root_predict(U, d, LAM)
        U, d, x, *_ = _reference.square_root_update(U, d, Hs[k:k + 1],
                                                    zs[k:k + 1].reshape(1, 1), 1.0)
    return x.ravel()


def _variants(window):
    return {
        f"SlidingWindowRLS(window={window})":
            (_sliding_window_reference(window),
             lambda n: rlsfilt.SlidingWindowRLS(n, max(window, n), P0=P0)),
        f"SquareRootRLS(lam={LAM})":
            (_square_root_reference, lambda n: rlsfilt.SquareRootRLS(n, lam=LAM, P0=P0)),
    }


def _batch(make, store):
    def run(Hs, zs):
        f = make(Hs.shape[1])
        f.batch_filter(zs, Hs, store_covariances=store)
        return f.x.ravel()
    return run


def _stream(make):
    def run(Hs, zs):
        f = make(Hs.shape[1])
        predict, update = f.predict, f.update
        for k in range(len(zs)):
            predict()
            update(zs[k], Hs[k])
        return f.x.ravel()
    return run


def _rls_batch(Hs, zs):
    f = rlsfilt.RecursiveLeastSquares(Hs.shape[1], lam=LAM, P0=P0)
    f.batch_filter(zs, Hs, store_covariances=False)
    return f.x.ravel()


def time_row(reference, make, Hs, zs, n_slow, rounds):
    """Best time per sample (seconds) of every column, and the final estimates."""
    jobs = {
        "batch": (_batch(make, False), len(zs)),
        "batch+P": (_batch(make, True), len(zs)),
        "stream": (_stream(make), n_slow),
        "reference": (reference, n_slow),
        "RLS batch": (_rls_batch, len(zs)),
    }
    best = dict.fromkeys(jobs, np.inf)
    estimates = {}
    for run, n in jobs.values():          # warm-up: compile or load the kernels
        run(Hs[:min(n, 50)], zs[:min(n, 50)])
    for _ in range(rounds):
        for name, (run, n) in jobs.items():
            t0 = time.perf_counter()
            estimates[name] = run(Hs[:n], zs[:n])
            best[name] = min(best[name], (time.perf_counter() - t0) / n)
    return best, estimates


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny sizes (CI)")
    parser.add_argument("--samples", type=int, default=20000)
    parser.add_argument("--slow-samples", type=int, default=2000)
    parser.add_argument("--window", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    dims = (2, 5) if args.smoke else (2, 5, 10, 20)
    N = 300 if args.smoke else args.samples
    n_slow = min(N, 100 if args.smoke else args.slow_samples)
    window = 40 if args.smoke else args.window
    rounds = 1 if args.smoke else args.rounds
    rng = np.random.default_rng(0)
    print(f"time per sample in us (N = {N}; reference and stream on {n_slow} samples)")
    print(f"{'filter':<32}{'dim_x':>6}" + "".join(f"{c:>14}" for c in COLUMNS)
          + f"{'speed-up':>10}")
    rows = []
    for n in dims:
        Hs, zs = arx_data(n, N, rng)
        for label, (reference, make) in _variants(window).items():
            best, est = time_row(reference, make, Hs, zs, n_slow, rounds)
            # the compiled filter and the reference agree on the same samples
            np.testing.assert_allclose(est["stream"], est["reference"], rtol=1e-8, atol=1e-10)
            speedup = best["reference"] / best["batch"]
            print(f"{label:<32}{n:>6}" + "".join(f"{1e6 * best[c]:>14.3f}" for c in COLUMNS)
                  + f"{speedup:>9.0f}x")
            rows.append((label, n, best, speedup))
    return rows


if __name__ == "__main__":
    main()
