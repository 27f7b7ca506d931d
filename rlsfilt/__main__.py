"""Command line: ``rlsfilt demo`` (also ``python -m rlsfilt``).

For now the only command is ``demo``: simulate a second-order ARX plant,
identify it with `RecursiveLeastSquares` started by batch least squares (the
lecture notes' algorithm) and print the estimate beside the truth and
beside batch least squares on all data.
"""

import argparse
import sys

import numpy as np

from . import RecursiveLeastSquares, __version__

__all__ = ["main"]

_TRUE_A = np.array([-1.5, 0.7])   # y(t) - 1.5 y(t-1) + 0.7 y(t-2)
_TRUE_B = np.array([1.0, 0.5])    #   = 1.0 u(t-1) + 0.5 u(t-2) + e(t)


def _simulate(n_samples, noise_std, rng):
    u = np.where(rng.random(n_samples) < 0.5, -1.0, 1.0)
    e = noise_std * rng.standard_normal(n_samples)
    y = np.zeros(n_samples)
    for t in range(2, n_samples):
        y[t] = -_TRUE_A @ y[t - 2:t][::-1] + _TRUE_B @ u[t - 2:t][::-1] + e[t]
    return u, y


def _demo(args):
    rng = np.random.default_rng(args.seed)
    u, y = _simulate(args.samples, args.noise, rng)
    # regressor rows phi(t) = [-y(t-1), -y(t-2), u(t-1), u(t-2)] for t = 2 .. N-1
    Hs = np.column_stack([-y[1:-1], -y[:-2], u[1:-1], u[:-2]])
    zs = y[2:]
    k0 = 2 * Hs.shape[1]
    rls = RecursiveLeastSquares(dim_x=Hs.shape[1])
    rls.initialize(zs[:k0], Hs[:k0])
    rls.batch_filter(zs[k0:], Hs[k0:], store_covariances=False)
    theta_ls = np.linalg.lstsq(Hs, zs, rcond=None)[0]
    sigma2 = np.mean((zs - Hs @ rls.x[:, 0]) ** 2)
    std = np.sqrt(sigma2 * np.diag(rls.P) / rls.R)
    names = ["a1", "a2", "b1", "b2"]
    truth = np.concatenate([_TRUE_A, _TRUE_B])
    print(f"rlsfilt {__version__} demo: ARX(na=2, nb=2, nk=1) plant, {args.samples} samples, "
          f"noise std {args.noise}")
    print("  y(t) + a1 y(t-1) + a2 y(t-2) = b1 u(t-1) + b2 u(t-2) + e(t)")
    print(f"  recursive least squares started by batch least squares on {k0} samples\n")
    print(f"  {'param':>5} {'true':>9} {'RLS':>11} {'+-1 std':>9} {'batch LS':>11}")
    for name, t, est, sd, ls in zip(names, truth, rls.x[:, 0], std, theta_ls):
        print(f"  {name:>5} {t:9.4f} {est:11.6f} {sd:9.2e} {ls:11.6f}")
    gap = np.max(np.abs(rls.x[:, 0] - theta_ls))
    print(f"\n  max |RLS - batch LS| = {gap:.2e}   noise variance estimate = {sigma2:.3g}")
    return 0


def main(argv=None):
    """Run the ``rlsfilt`` command line; return the exit status."""
    parser = argparse.ArgumentParser(prog="rlsfilt", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"rlsfilt {__version__}")
    sub = parser.add_subparsers(dest="command")
    demo = sub.add_parser("demo", help="identify a simulated plant and print the estimate")
    demo.add_argument("--samples", type=int, default=2000, help="record length (default 2000)")
    demo.add_argument("--noise", type=float, default=0.1, help="noise std (default 0.1)")
    demo.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    args = parser.parse_args(argv)
    if args.command in (None, "demo"):
        if args.command is None:
            args = parser.parse_args(["demo"])
        return _demo(args)
    return 2  # pragma: no cover - argparse exits on unknown commands


if __name__ == "__main__":
    sys.exit(main())
