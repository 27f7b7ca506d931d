"""Time the streaming estimators (one ``step(y, u)`` call per sample) against the batch run.

A streaming object (``RecursiveARMAX``, ``RecursiveOE``, ``RecursiveBJ``,
``RecursiveARMA``, ``RecursiveIV``) runs the same compiled step as the batch
fit, one Python call per sample. This script times, per sample:

==============  ============================================================
``step``        ``est.step(y[t], u[t])`` in a Python loop (float samples:
                the fast path)
``step(list)``  the same with ``u`` given as a one-element list (the fully
                validated path)
``batch``       ``est.batch(y, u)``: the whole record in one compiled call
==============  ============================================================

and checks that the three end at the same estimate (bit for bit for the
prediction-error family). Every contender runs once per round, rounds are
interleaved and the best round counts.

Measured on the development machine (2 shared cores), ARMAX(2, 2, 1, 1):
before the packed compiled step about 16 us per ``step`` (ARMAX, OE, BJ,
ARMA: 16-18 us; ``RecursiveIV``: 29 us), of which 8 us in the numba call
with some thirty arguments and 8 us of Python validation and argument
building; after, about 3 us (the compiled arithmetic itself is about 1.5
us).

Usage::

    python benchmarks/bench_streaming.py --smoke    # a few seconds
    python benchmarks/bench_streaming.py            # N = 20000 samples, 3 rounds
"""

import argparse
import os
import sys
import time

import numpy as np
from scipy.signal import lfilter

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from rlsfilt import (  # noqa: E402
    RecursiveARMA,
    RecursiveARMAX,
    RecursiveBJ,
    RecursiveIV,
    RecursiveOE,
)

#: name, factory, has an input
ESTIMATORS = [
    ("RecursiveARMAX(2, 2, 1, 1)", lambda: RecursiveARMAX(2, 2, 1, 1), True),
    ("RecursiveOE(2, 2, 1)", lambda: RecursiveOE(2, 2, 1), True),
    ("RecursiveBJ(2, 1, 1, 2, 1)", lambda: RecursiveBJ(2, 1, 1, 2, 1), True),
    ("RecursiveARMA(2, 1)", lambda: RecursiveARMA(2, 1), False),
    ("RecursiveIV(2, 2, 1)", lambda: RecursiveIV(2, 2, 1), True),
]


def record(N, seed=0):
    """An ARMAX(2, 2, 2, 1) record with white input: ``(y, u)``."""
    rng = np.random.default_rng(seed)
    u, e = rng.standard_normal(N), 0.5 * rng.standard_normal(N)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + lfilter([1, 0.4], [1, -1.5, 0.7], e)
    return y, u


def run_step(make, y, u, with_input, as_list=False):
    est = make()
    step = est.step
    if not with_input:
        for t in range(len(y)):
            step(y[t])
    elif as_list:
        for t in range(len(y)):
            step(y[t], [u[t]])
    else:
        for t in range(len(y)):
            step(y[t], u[t])
    return est.theta


def run_batch(make, y, u, with_input):
    return make().batch(y, u if with_input else None)[1][-1]


def time_all(N, rounds):
    """``{name: {contender: seconds per sample}}`` and the final estimates."""
    y, u = record(N)
    warm_y, warm_u = record(50, seed=1)
    results, estimates = {}, {}
    for name, make, with_input in ESTIMATORS:
        contenders = {"step": lambda m=make, w=with_input: run_step(m, y, u, w),
                      "step(list)": lambda m=make, w=with_input: run_step(m, y, u, w, True)}
        if hasattr(make(), "batch"):         # RecursiveIV streams only
            contenders["batch"] = lambda m=make, w=with_input: run_batch(m, y, u, w)
        run_step(make, warm_y, warm_u, with_input)          # compile outside the clock
        run_step(make, warm_y, warm_u, with_input, as_list=True)
        if "batch" in contenders:
            run_batch(make, warm_y, warm_u, with_input)
        best = {key: np.inf for key in ("step", "step(list)", "batch")}
        for _ in range(rounds):
            for key, fn in contenders.items():
                t = time.perf_counter()
                theta = fn()
                best[key] = min(best[key], (time.perf_counter() - t) / N)
                estimates[(name, key)] = theta
        results[name] = best
    return results, estimates


def check_agreement(estimates):
    """The step, step(list) and batch runs end at the same estimate."""
    for (name, key), theta in estimates.items():
        ref = estimates[(name, "step")]
        if not np.array_equal(theta, ref):
            raise AssertionError(f"{name}: {key} ends at {theta}, step at {ref}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="tiny sizes (seconds)")
    parser.add_argument("-N", type=int, default=20000, help="samples (default 20000)")
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args(argv)
    N, rounds = (500, 1) if args.smoke else (args.N, args.rounds)
    results, estimates = time_all(N, rounds)
    check_agreement(estimates)
    print(f"streaming estimators, {N} samples, best of {rounds} round(s): us per sample")
    print(f"{'estimator':<28}{'step':>10}{'step(list)':>12}{'batch':>10}")
    for name, best in results.items():
        cells = "".join(f"{1e6 * best[k]:>{w}.2f}" if np.isfinite(best[k]) else f"{'-':>{w}}"
                        for k, w in (("step", 10), ("step(list)", 12), ("batch", 10)))
        print(f"{name:<28}{cells}")
    print("every contender ends at the same estimate")


if __name__ == "__main__":
    main()
