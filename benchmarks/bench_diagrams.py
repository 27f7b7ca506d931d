"""Cost of the estimator and the self-tuning regulator inside python-control diagrams (#29).

Everything is timed in one process, as CPU time of the measuring thread
(``time.thread_time``) with one BLAS thread; each figure is the minimum over
`repeats` runs, and the ratios are taken within the run. Per simulated step:

=====  ==========================================================================
(a)    the bare filter step: ``RecursiveLeastSquares(4)`` ``predict()`` +
       ``update(z, H)`` on precomputed ARX(2, 2, 1) regressors (the compiled step)
(b)    the estimator system's update and output functions called directly, one
       of each per step (what ``input_output_response`` calls)
(b2)   the same functions in python-control's call pattern for a sample, without
       python-control: the outputs on the inputs of its first pass over the loop
       (the loop's signals at zero: ``y = 0``), then on the settled inputs, all of it
       twice (once for the outputs, once for the update), then the update: ours
       alone, as the diagram calls it
(c)    a whole ``input_output_response`` of ``interconnect([plant, estimator])``
(d)    the same diagram with a trivial ``NonlinearIOSystem`` of the same state
       size (update ``x``, outputs zeros): python-control's own overhead
(e)    the regulator: ``SelfTuningRegulator.step`` in a loop with the plant,
       its system's update and output functions called directly (once each, and
       in python-control's pattern, three output passes: ``y = 0``, then the
       settled ``y`` twice), the whole
       interconnect simulation (and its trivial twin, whose output ``u = (r - y) / 2``
       passes ``y`` through as the regulator's does: python-control then
       iterates its algebraic loop as often, three output passes per
       evaluation instead of two), against a plain-numpy
       loop doing the same work (RLS, the coprimeness SVD, the Sylvester solve,
       the check ``A R + B S`` and the closed-loop roots, the control law)
=====  ==========================================================================

Usage::

    python benchmarks/bench_diagrams.py             # N = 1000, 5 repeats
    python benchmarks/bench_diagrams.py --quick
"""

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"      # one BLAS thread, set before NumPy loads its BLAS

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

import control  # noqa: E402

from rlsfilt import RecursiveLeastSquares  # noqa: E402
from rlsfilt.adaptive import SelfTuningRegulator, estimator_iosystem  # noqa: E402

A = np.array([1.0, -1.5, 0.7])
B = np.array([0.0, 1.0, 0.5])
DESIGN = dict(Am=np.poly([0.5, 0.6]), Ao=np.poly([0.2, 0.3]))


def best(fn, repeats):
    """Minimum thread CPU time of `fn()` over `repeats` calls (after one warm-up)."""
    fn()
    times = []
    for _ in range(repeats):
        t0 = time.thread_time()
        fn()
        times.append(time.thread_time() - t0)
    return min(times)


def plant_sys():
    return control.ss(control.tf(B, A, True), inputs="u", outputs="y", name="plant")


def trivial(nstates, inputs, outputs, name, feedthrough=False):
    """A NonlinearIOSystem doing nothing, of the given size: python-control's overhead.

    With `feedthrough`, the outputs are ``(u[1] - u[0]) / 2`` (a proportional law on
    the first two inputs, ``r - y`` for the regulator's), so that python-control
    iterates an algebraic loop through it as often as through a system whose outputs
    depend on its inputs.
    """
    zeros = np.zeros(len(outputs))
    if feedthrough:
        def out(t, x, u, p):
            return zeros + 0.5 * (u[1] - u[0])
    else:
        def out(t, x, u, p):
            return zeros
    return control.nlsys(lambda t, x, u, p: x, out, inputs=inputs,
                         outputs=outputs, states=nstates, dt=True, name=name)


def replay(sysm, W, W0, passes):
    """A loop calling `sysm`'s output function as python-control does in a sample
    (`passes`: 0 the inputs of the first pass, `W0`, 1 the settled ones, `W`; for the
    outputs, then again for the update) and then its update function."""
    def run():
        x = np.zeros(sysm.nstates)
        upd, out, p = sysm.updfcn, sysm.outfcn, {}
        for t in range(len(W)):
            for _ in range(2):
                for j in passes:
                    out(t, x, W0[t] if j == 0 else W[t], p)
            x = upd(t, x, W[t], p)
    return run


def arx_data(N, seed=0):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(N)
    y = control.input_output_response(plant_sys(), np.arange(N), u).outputs
    H = np.zeros((N, 4))
    for t in range(N):
        H[t] = [-y[t - 1] if t >= 1 else 0.0, -y[t - 2] if t >= 2 else 0.0,
                u[t - 1] if t >= 1 else 0.0, u[t - 2] if t >= 2 else 0.0]
    return u, y, H


def bench_estimator(N, repeats):
    u, y, H = arx_data(N)

    def bare():
        f = RecursiveLeastSquares(4, lam=0.98, P0=100.0)
        for t in range(N):
            f.predict()
            f.update(y[t], H[t])

    est = estimator_iosystem(RecursiveLeastSquares(4, lam=0.98, P0=100.0), regressor=(2, 2, 1))
    W = np.column_stack([u, y])

    def direct():
        x = np.zeros(est.nstates)
        upd, out, p = est.updfcn, est.outfcn, {}
        for t in range(N):
            out(t, x, W[t], p)
            x = upd(t, x, W[t], p)

    W0 = W.copy()
    W0[:, 1] = 0.0                  # python-control's first pass: y, from the plant, is 0
    T = np.arange(N)
    outs = ["y", "theta[0]", "theta[1]", "theta[2]", "theta[3]", "e"]
    loop = control.interconnect([plant_sys(), est], inputs="u", outputs=outs)
    twin = control.interconnect(
        [plant_sys(), trivial(est.nstates, ["u", "y"], outs[1:], "estimator")],
        inputs="u", outputs=outs)
    t = {"(a) bare filter step": best(bare, repeats),
         "(b) estimator update+output functions": best(direct, repeats),
         "(b2) the same in python-control's call pattern": best(
             replay(est, W, W0, (0, 1)), repeats),
         "(c) interconnect simulation": best(
             lambda: control.input_output_response(loop, T, u), repeats),
         "(d) same diagram, trivial system": best(
             lambda: control.input_output_response(twin, T, u), repeats)}
    return {k: v / N * 1e6 for k, v in t.items()}


def numpy_regulator(N, r, d):
    """The regulator's work in plain NumPy: RLS, design, checks, control law."""
    lam, P, th = 1.0, 100.0 * np.eye(4), np.zeros(4)
    Acl = np.convolve(DESIGN["Am"], DESIGN["Ao"])
    Ao = DESIGN["Ao"]
    xs = np.zeros(2)
    Ad, Bd, Cd, Dd = (np.asarray(m) for m in control.ssdata(plant_sys()))
    yp, up, rp = np.zeros(3), np.zeros(3), np.zeros(3)
    R = S = T = None
    for k in range(N):
        yk = float((Cd @ xs)[0])
        phi = np.array([-yp[0], -yp[1], up[0], up[1]])
        g = P @ phi                                       # RLS
        s = 1.0 + phi @ g
        th = th + g * ((yk - phi @ th) / s)
        P = (P - np.outer(g, g) / s) / lam
        a = np.r_[1.0, th[:2]]
        b = np.r_[0.0, th[2:]]
        a1 = np.convolve(a, [1.0, -1.0])
        ok = bool(np.any(b != 0.0)) and abs(b.sum()) > 1e-12
        if ok:
            M = np.zeros((5, 5))
            for j in range(2):
                M[j:j + 4, j] = a1 / np.linalg.norm(a1)
            for j in range(3):
                M[j:j + 3, 2 + j] = b / np.linalg.norm(b)
            ok = np.linalg.svd(M, compute_uv=False)[-1] >= 1e-4
        if ok:
            M = np.zeros((5, 5))
            for j in range(2):
                M[j:j + 4, j] = a1
            for j in range(3):
                M[j:j + 3, 2 + j] = b
            x = np.linalg.solve(M, np.r_[Acl, np.zeros(5 - len(Acl))])
            Rn = np.convolve(x[:2], [1.0, -1.0])
            Sn = x[2:]
            Tn = DESIGN["Am"].sum() / b.sum() * Ao
            char = np.convolve(a, Rn) + np.convolve(b, Sn)
            ok = np.abs(char - np.r_[Acl, np.zeros(5 - len(Acl))]).max() <= 1e-8 * (
                np.abs(a).sum() * np.abs(Rn).sum() + np.abs(b).sum() * np.abs(Sn).sum())
            ok = ok and np.abs(np.roots(char)).max() < 1.0
            if ok:
                R, S, T = Rn, Sn, Tn
        u = d[k]
        if R is not None:
            u += (T[0] * r[k] + T[1:] @ rp[:2] - S[0] * yk - S[1:] @ yp[:2]
                  - R[1:] @ up[:2]) / R[0]
        yp[1:], up[1:], rp[1:] = yp[:-1].copy(), up[:-1].copy(), rp[:-1].copy()
        yp[0], up[0], rp[0] = yk, u, r[k]
        xs = Ad @ xs + Bd[:, 0] * u


def bench_regulator(N, repeats):
    rng = np.random.default_rng(0)
    r = np.where(np.arange(N) % 80 < 40, 1.0, -1.0)
    d = 0.1 * rng.choice([-1.0, 1.0], N)
    Ad, Bd, Cd, Dd = (np.asarray(m) for m in control.ssdata(plant_sys()))

    def make():
        return SelfTuningRegulator(RecursiveLeastSquares(4, P0=100.0), DESIGN, na=2, nb=2)

    def step_loop():
        stre = make()
        xs = np.zeros(2)
        for k in range(N):
            yk = float((Cd @ xs)[0])
            u = stre.step(yk, r[k], d[k])
            xs = Ad @ xs + Bd[:, 0] * u

    sysm = make().as_iosystem()
    # the inputs the regulator sees: record them from one step loop
    W = np.zeros((N, 3))
    stre, xs = make(), np.zeros(2)
    for k in range(N):
        W[k] = [float((Cd @ xs)[0]), r[k], d[k]]
        xs = Ad @ xs + Bd[:, 0] * stre.step(*W[k])

    def direct():
        x = np.zeros(sysm.nstates)
        upd, out, p = sysm.updfcn, sysm.outfcn, {}
        for k in range(N):
            out(k, x, W[k], p)
            x = upd(k, x, W[k], p)

    W0 = W.copy()
    W0[:, 0] = 0.0                  # python-control's first pass: y, from the plant, is 0
    T = np.arange(N)
    loop = control.interconnect([plant_sys(), sysm], inputs=["r", "dither"], outputs=["y", "u"])
    twin = control.interconnect(
        [plant_sys(), trivial(sysm.nstates, ["y", "r", "dither"], ["u"], "str", True)],
        inputs=["r", "dither"], outputs=["y", "u"])
    t = {"(e) plain-numpy loop (same work)": best(lambda: numpy_regulator(N, r, d), repeats),
         "(e) SelfTuningRegulator.step loop": best(step_loop, repeats),
         "(e) regulator update+output functions": best(direct, repeats),
         "(e) the same in python-control's call pattern": best(
             replay(sysm, W, W0, (0, 1, 1)), repeats),
         "(e) interconnect simulation": best(
             lambda: control.input_output_response(loop, T, [r, d]), repeats),
         "(e) same diagram, trivial system": best(
             lambda: control.input_output_response(twin, T, [r, d]), repeats)}
    return {k: v / N * 1e6 for k, v in t.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="N = 300, 3 repeats")
    parser.add_argument("-N", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    N, repeats = (300, 3) if args.quick else (args.N, args.repeats)
    warnings.simplefilter("ignore")
    est = bench_estimator(N, repeats)
    reg = bench_regulator(N, repeats)
    print(f"per simulated step, us (thread CPU time, minimum of {repeats}, N = {N})")
    for k, v in {**est, **reg}.items():
        print(f"  {k:48s} {v:9.1f}")
    bare = est["(a) bare filter step"]
    own = est["(c) interconnect simulation"] - est["(d) same diagram, trivial system"]
    direct = est["(b) estimator update+output functions"]
    line("estimator: update+output functions / bare step", f"{direct / bare:.2f}x")
    line("  in the diagram, python-control's overhead aside",
         f"{own:.1f} us = {own / bare:.2f}x the bare step")
    alone = est["(b2) the same in python-control's call pattern"]
    line("  ours alone in python-control's call pattern", f"{alone / bare:.2f}x the bare step")
    ref = reg["(e) plain-numpy loop (same work)"]
    own_r = reg["(e) interconnect simulation"] - reg["(e) same diagram, trivial system"]
    stepped = reg["(e) SelfTuningRegulator.step loop"]
    direct_r = reg["(e) regulator update+output functions"]
    line("regulator: step loop / plain-numpy loop", f"{stepped / ref:.2f}x")
    line("  update+output functions / plain-numpy loop", f"{direct_r / ref:.2f}x")
    line("  update+output functions / bare filter step", f"{direct_r / bare:.2f}x")
    line("  in the diagram, python-control's overhead aside",
         f"{own_r:.1f} us = {own_r / ref:.2f}x the numpy loop, {own_r / bare:.1f}x the bare step")
    alone_r = reg["(e) the same in python-control's call pattern"]
    line("  ours alone in python-control's call pattern", f"{alone_r / bare:.2f}x the bare step")


def line(label, value):
    print(f"  {label:52s} {value}")

if __name__ == "__main__":
    main()
