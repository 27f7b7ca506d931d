"""Time the gradient filters' ``batch_filter`` against padasip, per sample (thread CPU time).

For LMS, NLMS, sign-sign LMS and affine projection (order 4), on the same
Gaussian regressors and step sizes: rlsfilt's ``batch_filter`` (one compiled
loop) against padasip's ``run`` (a Python loop over NumPy steps). Each
contender runs once per round (rlsfilt three times back to back: its output
array is then allocated from a warm heap rather than from pages that
padasip's many small arrays left to the kernel), rounds are interleaved and
the best round counts (thread CPU time, so the other users of a shared
machine count less).
Prints ns per sample and the speed-up; the issue's target is >= 100x.

The second table times `GradientBank` (C NLMS channels in one compiled call)
against a Python loop of one `NLMS.batch_filter` per channel, in ns per
channel-sample: what the bank saves is the per-call cost of C filters.

Usage::

    python benchmarks/bench_gradient.py --smoke     # a few seconds
    python benchmarks/bench_gradient.py             # dim_x 4 and 16, N = 20000
"""

import argparse
import time

import numpy as np
import padasip as pa

import rlsfilt

CASES = {
    "LMS": (lambda n: rlsfilt.LMS(n, mu=0.01), lambda n: pa.filters.FilterLMS(n, mu=0.01,
                                                                              w="zeros")),
    "NLMS": (lambda n: rlsfilt.NLMS(n, mu=0.5, eps=0.01),
             lambda n: pa.filters.FilterNLMS(n, mu=0.5, eps=0.01, w="zeros")),
    "SignSignLMS": (lambda n: rlsfilt.SignSignLMS(n, mu=0.001),
                    lambda n: pa.filters.FilterSSLMS(n, mu=0.001, w="zeros")),
    "APA(order=4)": (lambda n: rlsfilt.APA(n, order=4, mu=0.5, eps=0.01),
                     lambda n: pa.filters.FilterAP(n, order=4, mu=0.5, ifc=0.01, w="zeros")),
}


def _cpu(fn):
    t = time.thread_time()
    fn()
    return time.thread_time() - t


def run(dims, n_samples, slow_samples, rounds):
    rng = np.random.default_rng(0)
    print(f"{'filter':14s} {'dim_x':>5s} {'rlsfilt ns':>11s} {'padasip ns':>11s} {'speed-up':>9s}")
    for n in dims:
        Hs = rng.standard_normal((n_samples, n))
        zs = Hs @ rng.standard_normal(n) + 0.1 * rng.standard_normal(n_samples)
        for name, (ours, theirs) in CASES.items():
            ours(n).batch_filter(zs[:10], Hs[:10])              # compile / load the cache
            best_o = best_p = np.inf
            def run_ours(ours=ours, n=n, zs=zs, Hs=Hs):
                ours(n).batch_filter(zs, Hs, store_covariances=False)

            def run_theirs(theirs=theirs, n=n, zs=zs[:slow_samples], Hs=Hs[:slow_samples]):
                theirs(n).run(zs, Hs)

            for _ in range(rounds):
                for _ in range(3):      # back to back: the allocator warm after padasip's
                    best_o = min(best_o, _cpu(run_ours) / n_samples)
                best_p = min(best_p, _cpu(run_theirs) / slow_samples)
            print(f"{name:14s} {n:5d} {1e9 * best_o:11.0f} {1e9 * best_p:11.0f} "
                  f"{best_p / best_o:8.0f}x")


def run_bank(n, channels, n_samples, rounds):
    """`GradientBank.batch_filter` against one `NLMS.batch_filter` per channel."""
    rng = np.random.default_rng(1)
    print(f"\n{'bank of NLMS':14s} {'C':>5s} {'bank ns':>11s} {'loop ns':>11s} {'speed-up':>9s}")
    for C in channels:
        Hs = rng.standard_normal((n_samples, C, n))
        zs = np.einsum("kci,ci->kc", Hs, rng.standard_normal((C, n)))
        mu = np.full(C, 0.5)
        rlsfilt.GradientBank(C, n, mu).batch_filter(zs[:10], Hs[:10])   # compile / load
        Hc = [np.ascontiguousarray(Hs[:, c]) for c in range(C)]

        def bank(C=C, mu=mu, zs=zs, Hs=Hs):
            rlsfilt.GradientBank(C, n, mu).batch_filter(zs, Hs, store_means=False)

        def loop(C=C, zs=zs, Hc=Hc):
            for c in range(C):
                rlsfilt.NLMS(n, mu=0.5).batch_filter(zs[:, c], Hc[c])

        best_b = best_l = np.inf
        for _ in range(rounds):
            best_b = min(best_b, _cpu(bank) / (n_samples * C))
            best_l = min(best_l, _cpu(loop) / (n_samples * C))
        print(f"{'dim_x=' + str(n):14s} {C:5d} {1e9 * best_b:11.1f} {1e9 * best_l:11.1f} "
              f"{best_l / best_b:8.1f}x")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="a few seconds")
    args = parser.parse_args(argv)
    if args.smoke:
        run([4], 2000, 500, 2)
        run_bank(4, [100], 200, 2)
    else:
        run([4, 16], 20000, 2000, 5)
        run_bank(4, [100, 10000], 1000, 5)


if __name__ == "__main__":
    main()
