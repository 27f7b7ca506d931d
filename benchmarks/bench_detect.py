"""The overhead of `BankChangeDetector` on a streaming `RLSBank` step (issue 30's target: at
most 20 % of a bank step at 1,000 channels).

Per sample, a bank of ``C`` channels with ``dim_x`` parameters (a bias and inputs, no
change) runs ``bank.predict_update(z[k], H[k])``; with a detector it also runs
``det.step(bank)``. Both loops run in the same process, rounds interleaved, the best
round counts; times are thread CPU time (``time.thread_time``) with one BLAS thread. The
overhead is ``(with detector - without) / without``, printed for CUSUM, Page-Hinkley
and the GLR at several windows (its step is O(C M)).

Measured on the development machine (2 shared cores, C = 1000, dim_x = 3; best of 7 rounds,
about +-3 % from run to run): a bank step 33.2 us; with CUSUM 10.6 %, Page-Hinkley 10.4 %,
GLR 11.9 % (M = 10), 12.5 % (M = 30) and 13.9 % (M = 100) more. In the same run, the
detector before its trimming (a ring ``(C, 2 M)`` written twice per sample, one cache line
per channel; ten kernel arguments; the kernel module looked up per step) cost 12.0 %,
13.2 %, 18.1 %, 18.3 % and 19.8 % (earlier runs on a busier machine: up to 25 % at
M = 100). About 1 us of each is the Python call, the CUSUM's kernel about 3 us (a sqrt and
a division per channel); the GLR's exact pruning (one CUSUM bound per piece of window
lengths, see ``_kernels_detection.py``) keeps it from the O(C M) of a full scan (before
it: 230 % at M = 10, 1000 % at M = 100).

Usage::

    PYTHONPATH=. python benchmarks/bench_detect.py            # C = 1000, 2000 samples, 5 rounds
    PYTHONPATH=. python benchmarks/bench_detect.py --smoke    # a few seconds

Not a test: the numbers depend on the machine and its load.
"""

import os

# one BLAS thread (set before NumPy loads its BLAS)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rlsfilt import RLSBank  # noqa: E402
from rlsfilt.validation import BankChangeDetector  # noqa: E402


def record(C, n, N, seed=0):
    rng = np.random.default_rng(seed)
    H = np.concatenate([np.ones((N, C, 1)), rng.standard_normal((N, C, n - 1))], axis=-1)
    theta = rng.standard_normal((C, n))
    z = np.einsum("kci,ci->kc", H, theta) + 0.1 * rng.standard_normal((N, C))
    return z, H


def run(z, H, detector):
    """Thread CPU time per sample of the streaming loop (after a short warm start)."""
    C, n = H.shape[1], H.shape[2]
    bank = RLSBank(C, n, lam=0.999, R=0.01)
    det = detector() if detector is not None else None
    for k in range(20):                                    # warm start (and compile)
        bank.predict_update(z[k], H[k])
        if det is not None:
            det.step(bank)
    t0 = time.thread_time()
    if det is None:
        for k in range(20, len(z)):
            bank.predict_update(z[k], H[k])
    else:
        for k in range(20, len(z)):
            bank.predict_update(z[k], H[k])
            det.step(bank)
    return (time.thread_time() - t0) / (len(z) - 20)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--channels", type=int, default=1000)
    parser.add_argument("--dim-x", type=int, default=3)
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--smoke", action="store_true", help="a few seconds")
    args = parser.parse_args(argv)
    if args.smoke:
        args.samples, args.rounds = 300, 2
    C, n = args.channels, args.dim_x
    z, H = record(C, n, args.samples)
    contenders = {
        "cusum": lambda: BankChangeDetector(C, "cusum", arl=10_000),
        "page_hinkley": lambda: BankChangeDetector(C, "page_hinkley", arl=10_000),
        "glr M=10": lambda: BankChangeDetector(C, "glr", arl=10_000, window=10),
        "glr M=30": lambda: BankChangeDetector(C, "glr", arl=10_000, window=30),
        "glr M=100": lambda: BankChangeDetector(C, "glr", arl=10_000, window=100),
    }
    best = {"bank step": np.inf, **dict.fromkeys(contenders, np.inf)}
    for _ in range(args.rounds):
        best["bank step"] = min(best["bank step"], run(z, H, None))
        for name, make in contenders.items():
            best[name] = min(best[name], run(z, H, make))
    base = best["bank step"]
    print(f"RLSBank streaming step, C = {C}, dim_x = {n}: {1e6 * base:.1f} us per sample "
          f"(best of {args.rounds} rounds, thread CPU time)")
    print(f"{'detector':14s} {'step + det (us)':>16s} {'overhead':>9s}")
    for name in contenders:
        print(f"{name:14s} {1e6 * best[name]:16.1f} {100 * (best[name] - base) / base:8.1f}%")


if __name__ == "__main__":
    main()
