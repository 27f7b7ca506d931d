"""Stream `RecursiveLeastSquares` over a long record with intermittent excitation.

The audit of #27: blocks of 100,000 samples whose first 2,000 are excited
(white input; then the input is held), 4e6 samples in all, regressor ``[1,
u(t), u(t-1)]``, ``lam = 0.95`` (the windup cap holds ``P`` at a spread of
about ``spread_max = 1e15``). ``predict_update`` sample by sample must give
the numbers of one ``batch_filter`` call, bit for bit.

What went wrong before the fix: where excitation returns after a hold, the
update of a ``P`` that spread far loses a little of its definiteness to
round-off, and for a step or two ``S = H P H^T + R`` comes out negative
(both paths compute the same ``S``). The streaming update's gate test
``y^T y > gate^2 S`` with the default ``gate = inf`` was then ``y^T y >
-inf``, true: the sample was rejected, ``P`` kept its negative direction,
every later ``S`` stayed negative and every later sample was rejected too,
while the estimate ran away (1e4 to 1e9) and never came back; the fused loop
of ``batch_filter`` has no gate and recovered at the next samples. Without a
gate (``inf``) nothing is gated now (``_kernels._innovation``), as in the
NumPy reference. ``tests/test_windup_cap.py`` runs the same mechanism on a
shortened record (blocks of 3,000 samples, the first 60 excited).

Usage::

    python benchmarks/bench_intermittent.py --smoke      # 90,000 samples, seconds
    python benchmarks/bench_intermittent.py              # 4e6 samples, a few minutes

Prints the time of each path, the first sample where they differ (none) and
the count of negative ``S`` (the transient loss of definiteness, which the
two paths share).
"""

import argparse
import os
import sys
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rlsfilt import NumericalWarning, RecursiveLeastSquares  # noqa: E402

THETA = np.array([0.5, 2.0, -1.0])


def intermittent_record(n_blocks, block, excited, seed=0):
    """``(zs, Hs)``: regressor ``[1, u(t), u(t-1)]``, the input white for the first
    `excited` samples of each block of `block` samples, then held at its last value."""
    rng = np.random.default_rng(seed)
    N = n_blocks * block + 1
    u = rng.standard_normal(N)
    for b in range(n_blocks):
        start = b * block + excited
        u[start:(b + 1) * block] = u[start - 1]
    Hs = np.column_stack([np.ones(N - 1), u[1:], u[:-1]])
    zs = Hs @ THETA + 0.1 * rng.standard_normal(N - 1)
    return zs, Hs


def run(n_blocks, block, excited, lam=0.95, seed=0):
    """Batch and streamed estimates after every sample, and the streamed ``S``."""
    zs, Hs = intermittent_record(n_blocks, block, excited, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", NumericalWarning)
        t0 = time.perf_counter()
        batch = RecursiveLeastSquares(3, lam=lam)
        means = batch.batch_filter(zs, Hs, store_covariances=False)[0][:, :, 0]
        t1 = time.perf_counter()
        stream = RecursiveLeastSquares(3, lam=lam)
        xs = np.empty((len(zs), 3))
        S = np.empty(len(zs))
        for k in range(len(zs)):
            stream.predict_update(zs[k], Hs[k])
            xs[k] = stream.x[:, 0]
            S[k] = stream.S[0, 0]
        t2 = time.perf_counter()
    return means, xs, S, stream, batch, (t1 - t0, t2 - t1)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="the shortened record")
    parser.add_argument("--blocks", type=int, default=40)
    parser.add_argument("--block", type=int, default=100_000)
    parser.add_argument("--excited", type=int, default=2_000)
    parser.add_argument("--lam", type=float, default=0.95)
    args = parser.parse_args(argv)
    if args.smoke:
        args.blocks, args.block, args.excited = 30, 3_000, 60
    means, xs, S, stream, batch, (tb, ts) = run(args.blocks, args.block, args.excited,
                                                args.lam)
    diff = np.flatnonzero((xs != means).any(axis=1))
    print(f"{len(xs)} samples, blocks of {args.block} ({args.excited} excited), "
          f"lam = {args.lam}")
    print(f"batch_filter {tb:.1f} s, predict_update {ts:.1f} s")
    print(f"first sample where they differ: {int(diff[0]) if diff.size else 'none'}")
    print(f"negative S (transient, both paths): {int((S < 0).sum())}; gated: "
          f"{stream.n_gated}; capped updates: stream {stream.n_capped}, batch "
          f"{batch.n_capped}")
    print(f"final estimate: stream {xs[-1]}, batch {means[-1]} (true {THETA})")
    return 0 if not diff.size else 1


if __name__ == "__main__":
    sys.exit(main())
