"""Time `RecursiveLeastSquares.tune` against statsmodels' maximum likelihood of the same model.

The model: ``z_t = H_t x_t + v_t`` with three random-walk coefficients
``x_t = x_{t-1} + w_t``, ``Q = q R I`` (one hyperparameter) or ``Q = R diag(q)``
(three), the noise variance concentrated out, known initialization; N = 2,000
samples per series. statsmodels runs its ``MLEModel.fit()`` (L-BFGS, its
defaults) on the same model. Times are thread CPU time (``time.thread_time``)
per series, the median over the series; the estimates are compared too. Each
is timed twice: the two libraries alternating series by series (each call in
the caches the other left: the number to quote), and each over all the series
in a row (a loop of series, as when tuning many). ``lam`` (statsmodels has no
forgetting factor) is timed against statsmodels' scalar-``q`` fit of the same
record: the same one-variable search. Last,
``RLSBank.tune`` of 10,000 channels x 1,000 samples (``--channels``; the issue's
target: about a minute on one core).

Run from the repository root: ``PYTHONPATH=. python benchmarks/bench_tune.py``
(``--series 5`` for a shorter run). Not a test: numbers depend on the machine
and its load.
"""

import argparse
import time

import numpy as np

from rlsfilt import RecursiveLeastSquares


def record(seed, N=2000, n=3):
    rng = np.random.default_rng(seed)
    H = rng.standard_normal((N, n))
    x = np.array([1.0, -0.5, 0.3]) + np.cumsum(0.02 * rng.standard_normal((N, n)), 0)
    z = np.sum(H * x, axis=1) + 0.1 * rng.standard_normal(N)
    return z, H


def statsmodels_model(z, H, x0, P0, diagonal):
    from statsmodels.tsa.statespace.mlemodel import MLEModel

    n = H.shape[1]

    class RandomWalkCoefficients(MLEModel):
        def __init__(self):
            super().__init__(z, k_states=n, k_posdef=n, initialization="known",
                             initial_state=x0, initial_state_cov=P0)
            self.ssm.filter_concentrated = True
            self["design"] = H.T[None]
            self["transition"] = np.eye(n)
            self["selection"] = np.eye(n)
            self["obs_cov"] = np.array([[1.0]])

        @property
        def param_names(self):
            return [f"q{i}" for i in range(n)] if diagonal else ["q"]

        @property
        def start_params(self):
            return np.full(n if diagonal else 1, 0.01)

        def transform_params(self, unconstrained):
            return unconstrained ** 2

        def untransform_params(self, constrained):
            return constrained ** 0.5

        def update(self, params, **kwargs):
            params = super().update(params, **kwargs)
            Q = np.diag(params) if diagonal else params[0] * np.eye(n)
            self["state_cov"] = Q
            self.ssm.initialize_known(x0, P0 + Q)

    return RandomWalkCoefficients()


def main(series=10, channels=10000):
    n = 3
    x0, P0 = np.zeros(n), 100.0 * np.eye(n)
    rls = RecursiveLeastSquares(n, P0=P0, x0=x0)
    for param in ("q", "q_diag", "lam"):
        rls.tune(*record(0, N=50), param)                 # compile / load the kernel
    # (param, statsmodels' model: lam against its scalar-q fit, statsmodels having no
    # forgetting factor: the same one-variable search on the same record)
    for param, diagonal in (("q", False), ("lam", False), ("q_diag", True)):
        ours, theirs, rel, passes = [], [], [], []
        for seed in range(series):                        # alternating, series by series
            z, H = record(seed)
            t0 = time.thread_time()
            fit = rls.tune(z, H, param)
            ours.append(time.thread_time() - t0)
            passes.append(fit.n_evals)
            mod = statsmodels_model(z, H, x0, P0, diagonal)
            t0 = time.thread_time()
            res = mod.fit(disp=0)
            theirs.append(time.thread_time() - t0)
            if param != "lam":
                rel.append(np.max(np.abs(np.atleast_1d(fit.estimate) - res.params)
                                  / res.params))
        a, b = np.median(ours), np.median(theirs)
        versus = "its scalar-q fit" if param == "lam" else "fit"
        same = f"; largest relative difference of the estimates {max(rel):.1e}" if rel else ""
        print(f"{param:7s} N = 2000, 3 coefficients, {series} series, alternating: rlsfilt tune "
              f"{1e3 * a:.2f} ms, statsmodels {versus} {1e3 * b:.1f} ms per series "
              f"(x{b / a:.0f}){same}; {np.median(passes):.0f} passes")
        # the same, each library over all the series in a row (a loop of series, as when
        # tuning many): above, each call runs right after the other library's, in the
        # caches that one left
        ours, theirs = [], []
        for seed in range(series):
            z, H = record(seed)
            t0 = time.thread_time()
            rls.tune(z, H, param)
            ours.append(time.thread_time() - t0)
        for seed in range(series):
            mod = statsmodels_model(*record(seed), x0, P0, diagonal)
            t0 = time.thread_time()
            mod.fit(disp=0)
            theirs.append(time.thread_time() - t0)
        a, b = np.median(ours), np.median(theirs)
        print(f"{param:7s} each in a loop of the {series} series: rlsfilt tune {1e3 * a:.2f} ms, "
              f"statsmodels {versus} {1e3 * b:.1f} ms per series (x{b / a:.0f})")
    # a bank: every channel tuned (scalar q), 1,000 samples per channel
    from rlsfilt import RLSBank

    rng = np.random.default_rng(1)
    C, N = channels, 1000
    Hs = rng.standard_normal((N, C, n))
    x = np.cumsum(0.02 * rng.standard_normal((N, C, n)), 0) + 1.0
    zs = np.einsum("tcn,tcn->tc", Hs, x) + 0.1 * rng.standard_normal((N, C))
    bank = RLSBank(C, n, P0=100.0)
    t0 = time.thread_time()
    fits = bank.tune(zs, Hs, "q")
    t = time.thread_time() - t0
    print(f"RLSBank.tune, {C} channels x {N} samples, 3 coefficients: {t:.2f} s "
          f"({1e3 * t / C:.2f} ms per channel; 10,000 channels: about {1e4 * t / C:.0f} s), "
          f"{int(fits.converged.sum())} converged")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--series", type=int, default=10)
    parser.add_argument("--channels", type=int, default=10000)
    args = parser.parse_args()
    main(args.series, args.channels)
