"""Shared fixtures: seeded randomness and a non-interactive plot backend."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")
# Small matrices are slower with threaded BLAS on a shared 2-core machine.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from numpy.testing import assert_array_equal  # noqa: E402


@pytest.fixture
def rng():
    """A fresh, seeded generator for each test."""
    return np.random.default_rng(20261121)


def arx_record(rng, n_samples=400, noise_std=0.1, a=(-1.5, 0.7), b=(1.0, 0.5)):
    """Regressors and targets of a second-order ARX plant driven by white noise.

    Returns ``(Hs, zs)`` with rows ``[-y(t-1), -y(t-2), u(t-1), u(t-2)]``.
    """
    u = rng.standard_normal(n_samples)
    y = np.zeros(n_samples)
    e = noise_std * rng.standard_normal(n_samples)
    for t in range(2, n_samples):
        y[t] = -a[0] * y[t - 1] - a[1] * y[t - 2] + b[0] * u[t - 1] + b[1] * u[t - 2] + e[t]
    Hs = np.column_stack([-y[1:-1], -y[:-2], u[1:-1], u[:-2]])
    return Hs, y[2:]


def assert_close_steps(a, b, name, rtol=1e-12):
    """Equal to `rtol` relative to the largest entry of each step's array.

    For histories of shape (N, rows, cols) each step is scaled by its own
    largest entry; NaN (missing samples) must sit at the same places.
    """
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    assert a.shape == b.shape, name
    assert_array_equal(np.isnan(a), np.isnan(b), err_msg=name)
    mag = np.abs(np.nan_to_num(b))
    scale = mag.max(axis=(1, 2), keepdims=True) if a.ndim == 3 else (mag.max() if b.size else 1.0)
    err = np.abs(np.nan_to_num(a - b))
    assert np.all(err <= rtol * np.maximum(scale, 1e-300)), (name, float(err.max()))


TINY = np.finfo(float).tiny                       # smallest normal double, 2^-1022
SUBNORMAL = np.finfo(float).smallest_subnormal    # 2^-1074


def assert_in_units(actual, expected, rtol, scale):
    """`actual` equals `expected` (a unit-scale result times the factors of the user's units,
    in floating point): ``|actual - expected| <= rtol * scale``, plus a few units in the last
    place of the subnormal range where the product underflows (each of its roundings there
    is absolute, 2^-1074); ``inf`` (with its sign) where the product overflows."""
    actual, expected = np.broadcast_arrays(np.asarray(actual, float), np.asarray(expected, float))
    scale = np.broadcast_to(scale, expected.shape)
    big = ~np.isfinite(expected)
    assert_array_equal(actual[big], expected[big])
    fin = ~big
    err = np.abs(actual[fin] - expected[fin])
    bound = rtol * scale[fin] + np.where(np.abs(expected[fin]) < TINY, 3 * SUBNORMAL, 0.0)
    assert np.all(err <= bound), (err - bound).max()


def scaled_by(x, factor):
    """``x * factor`` without over/underflow warnings (``inf`` or subnormal where it must)."""
    with np.errstate(over="ignore", under="ignore"):
        return x * factor
