"""Compile the common kernels ahead (``rlsfilt warmup``) and say when a first compile starts.

The kernels are ``njit(cache=True)``: the first process on a machine compiles
them and writes numba's disk cache, later processes load it. `JOBS` lists
small jobs, one per public class, that together reach the kernels a usual
session calls; `warmup` runs them (for images and CI, so that users and test
processes start warm). The same list is the registry of
``tests/test_kernel_cache.py``: a second process running any job compiles
nothing.

`announce_cold` is called by the lazy kernel loader (:mod:`rlsfilt._lazy`)
when a kernel module is first imported: if none of its kernels has a cache
index yet, it logs one message on the ``rlsfilt`` logger, once per process
("rlsfilt: compiling kernels, about N s of CPU, once per machine"). It goes
through :mod:`logging` (shown on stderr when logging is not configured,
silenced with ``logging.getLogger("rlsfilt").setLevel(logging.ERROR)``), not
:mod:`warnings`, so a ``-W error`` run does not fail on it.
"""

import logging
import os
import time

__all__ = []

logger = logging.getLogger("rlsfilt")

#: Rough CPU seconds a cold module costs on first use (a 2-core laptop-class machine).
_COLD_SECONDS = {
    "rlsfilt.filters._kernels": 6,
    "rlsfilt.filters._kernels_window": 10,
    "rlsfilt.filters._kernels_bank": 15,
    "rlsfilt.models._recursive_kernels": 10,
    "rlsfilt.validation._kernels_detection": 5,
    "rlsfilt.adaptive._kernels_design": 10,
    "rlsfilt.filters._kernels_vector": 3,
}

_announced = []

_PRELUDE = """
import numpy as np
import rlsfilt
rng = np.random.default_rng(0)
u = rng.standard_normal(300)
e = 0.05 * rng.standard_normal(300)
y = np.zeros(300)
for t in range(2, 300):
    y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2] + e[t] - 0.3 * e[t - 1]
H = np.arange(60.0).reshape(20, 3) % 7 + np.eye(20, 3)
z = H @ np.array([1.0, -2.0, 0.5])
"""

#: (name, code) run after `_PRELUDE`: each reaches the kernels of one public class.
JOBS = (
    ("RecursiveLeastSquares", """
rls = rlsfilt.RecursiveLeastSquares(3, lam=0.99, check_every=7)
rls.batch_filter(z, H, store_covariances=False)
rls.batch_filter(z, H)
for k in range(14):
    rls.predict()
    rls.update(1.0, H[k])
robust = rlsfilt.RecursiveLeastSquares(3, lam=0.99, forgetting="directional", gate=4.0)
robust.constrain([1.0, 1.0, 0.0], -1.0)
robust.batch_filter(z, H, store_covariances=False)
robust.predict()
robust.update(1.0, H[0])
diagonal = rlsfilt.RecursiveLeastSquares(3, lam=[0.99, 0.98, 1.0], forgetting="diagonal")
diagonal.batch_filter(z, H, store_covariances=False)
"""),
    ("SlidingWindowRLS", """
sw = rlsfilt.SlidingWindowRLS(3, 8, check_every=7)
sw.initialize(z[:8], H[:8])
sw.batch_filter(z, H)
sw.update(1.0, H[0])
"""),
    ("SquareRootRLS", """
sq = rlsfilt.SquareRootRLS(3, lam=0.99, check_every=7)
sq.batch_filter(z, H)
sq.predict()
sq.update(1.0, H[0])
sq.U
"""),
    ("RLSBank", """
bank = rlsfilt.RLSBank(4, 3, lam=0.99)
Hb = np.broadcast_to(H[:, None, :], (20, 4, 3))
bank.batch_filter(np.tile(z[:, None], (1, 4)), Hb)
bank.update(z[0] * np.ones(4), Hb[0])
"""),
    ("GradientBank", """
gb = rlsfilt.GradientBank(4, 3, mu=0.5)
Hb = np.broadcast_to(H[:, None, :], (20, 4, 3))
gb.batch_filter(np.tile(z[:, None], (1, 4)), Hb)
gb.update(z[0] * np.ones(4), Hb[0])
"""),
    ("gradient filters", """
for f in (rlsfilt.NLMS(3), rlsfilt.LMS(3), rlsfilt.APA(3, order=2)):
    f.batch_filter(z, H)
    f.update(1.0, H[0])
"""),
    ("ARX", """
rlsfilt.ARX(2, 2, 1).fit(u, y)
rlsfilt.ARX(2, 2, 1).fit(u, y, method="rls")
rlsfilt.ARX(2, 2, 1).fit(u, y, method="ls")
"""),
    ("ARMAX", "rlsfilt.ARMAX(2, 2, 1, 1).fit(u, y)\n"
              "rlsfilt.ARMAX(2, 2, 1, 1).fit(u, y, method='rpem')"),
    ("OE", "rlsfilt.OE(2, 2, 1).fit(u, y); rlsfilt.OE(2, 2, 1).fit(u, y, method='rpem')"),
    ("BJ", "rlsfilt.BJ(2, 1, 1, 2, 1).fit(u, y)\n"
           "rlsfilt.BJ(2, 1, 1, 2, 1).fit(u, y, method='rpem')"),
    ("AR", "rlsfilt.AR(2).fit(y); rlsfilt.AR(2).fit(y, method='rpem')"),
    ("ARMA", "rlsfilt.ARMA(2, 1).fit(y); rlsfilt.ARMA(2, 1).fit(y, method='rpem')"),
    ("RecursiveARMAX", """
r = rlsfilt.RecursiveARMAX(2, 2, 1, 1)
r.batch(y, u)
r.step(float(y[0]), float(u[0]))
"""),
    ("RecursiveOE", "rlsfilt.RecursiveOE(2, 2, 1).batch(y, u)"),
    ("RecursiveBJ", "rlsfilt.RecursiveBJ(2, 1, 1, 2, 1).batch(y, u)"),
    ("RecursiveARX", "r = rlsfilt.RecursiveARX(2, 2, 1)\n"
                     "r.batch(y, u)\nr.step(float(y[0]), float(u[0]))"),
    ("RecursiveAR", "rlsfilt.RecursiveAR(2).batch(y)"),
    ("RecursiveARMA", "rlsfilt.RecursiveARMA(2, 1).batch(y)"),
    ("BankChangeDetector", """
from rlsfilt.validation import BankChangeDetector
for method in ("cusum", "glr"):
    det = BankChangeDetector(4, method, window=8)
    det.update(np.ones(4), np.ones(4))
    det.g_plus
"""),
    ("SelfTuningRegulator", """
import control
from rlsfilt.adaptive import SelfTuningRegulator, estimator_iosystem
stre = SelfTuningRegulator(rlsfilt.RecursiveLeastSquares(4, P0=100.0),
                           dict(Am=np.poly([0.5, 0.6]), Ao=np.poly([0.2])), na=2, nb=2)
for t in range(20):
    stre.step(y[t], 1.0)
plant = control.tf([0, 1, 0.5], [1, -1.5, 0.7], True, inputs="u", outputs="y")
est = estimator_iosystem(rlsfilt.RecursiveLeastSquares(4, P0=100.0), regressor=(2, 2, 1))
loop = control.interconnect([plant, stre.as_iosystem(), est], inputs=["r", "dither"],
                            outputs=["y", "u"])
control.input_output_response(loop, np.arange(10), [np.ones(10), 0.01 * u[:10]])
"""),
)


def job_code(name):
    """The code of the job `name` of `JOBS`, with its prelude."""
    return _PRELUDE + dict(JOBS)[name]


def warmup(names=None, log=None):
    """Run the jobs `names` (all of `JOBS` by default), compiling what they reach.

    Returns ``{name: cpu_seconds}``. `log` (a function of one string) hears
    each job as it finishes.
    """
    import warnings

    done = {}
    for name, _ in JOBS:
        if names is not None and name not in names:
            continue
        t0 = time.process_time()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")     # tiny records: warnings are not the point
            exec(compile(job_code(name), f"<rlsfilt warmup: {name}>", "exec"), {})
        done[name] = time.process_time() - t0
        if log is not None:
            log(f"{name:24s} {done[name]:6.1f} s")
    return done


def _cache_index_exists(dispatcher):
    """Whether numba has a cache index file for `dispatcher` (None when it cannot tell)."""
    try:
        return os.path.exists(dispatcher._cache._cache_file._index_path)
    except AttributeError:          # no disk cache (NullCache) or another numba layout
        return None


def announce_cold(module):
    """Log one message (once per process) when no kernel of `module` is in the disk cache."""
    if _announced:
        return
    known = [_cache_index_exists(d) for d in vars(module).values()
             if getattr(d, "__module__", None) == module.__name__ and hasattr(d, "_cache")]
    known = [k for k in known if k is not None]
    if not known or any(known):
        return
    _announced.append(module.__name__)
    seconds = _COLD_SECONDS.get(module.__name__, 10)
    logger.warning("rlsfilt: compiling kernels, about %d s, once per machine "
                   "(`rlsfilt warmup` compiles them ahead)", seconds)
