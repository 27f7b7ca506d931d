"""The bad-input catalogue, tried against every public entry point (issue #18).

The audit behind #18 fed rlsfilt what a hurried user or an attacker would:
wrong shapes, NaN, inf, None, lists, pandas, 0-d arrays, complex, object,
bool and int arrays, read-only and non-contiguous arrays, and records around
1e160 and 1e-160. This module keeps that audit. It is a table: one
`Entry` per (entry point, argument), with a `run(value)` that calls the
entry point with the argument replaced, a valid value, and the outcome
expected for each kind of bad value where it differs from the default:

``ERROR``
    ``ValueError`` or ``TypeError`` (``MemoryError`` for sizes) whose
    message names the argument in backticks; for a filter, the state is
    bit-identical afterwards.
``SAME``
    the result equals the result for the valid value bit for bit (lists,
    pandas, read-only and strided arrays are the same numbers).
``AS_FLOAT``
    the result equals the result for the same values as float64 (an int
    array is its numbers).
``EITHER``
    a clear error as above, or a result (an unusual value that some entry
    points can use).
``OK``
    any result (e.g. NaN marks a missing measurement).
``WARNS``
    a clear error, or the filter's documented health warning
    (`NumericalWarning`, raised as an exception under ``-W error``) with the
    state unchanged: regressors around 1e160 are out of a filter's range (its
    prior covariance has units), which its health check reports.
``scaled(f)``
    the result equals ``f(valid result, s)`` for the value multiplied by
    ``s`` (1e160 or 1e-160), to ``rtol`` 1e-9: what a scale-invariant or
    linear entry point must give over the whole double range.

pytest runs with ``-W error``, so a stray warning is a failure of its own.
To cover a new entry point, add its `Entry` lines to `ENTRIES`.
"""

import itertools
import json
import os
import pickle
import re
import subprocess
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.signal import lfilter

from rlsfilt import (
    ARMAX,
    ARX,
    BJ,
    OE,
    IOData,
    NumericalWarning,
    OrderSelectionWarning,
    RecursiveLeastSquares,
    RLSBank,
    SlidingWindowRLS,
    SquareRootRLS,
    datasets,
    fit_percent,
    select_order,
    validate,
)
from rlsfilt.validation import cusum, information_criteria, residual_analysis

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

ERROR, SAME, AS_FLOAT, EITHER, OK, WARNS = "error", "same", "as_float", "either", "ok", "warns"
HUGE, TINY = 1e160, 1e-160

ARRAY_KINDS = ("shape", "nan", "inf", "none", "list", "pandas", "0d", "complex", "object",
               "bool", "int", "readonly", "strided", "huge", "tiny", "datetime64", "timedelta",
               "pandas_dates", "nullable", "categorical", "decimal")
SCALAR_KINDS = ("shape", "nan", "inf", "none", "list", "0d", "complex", "object", "bool",
                "int", "text", "huge", "tiny")
INT_KINDS = ("float", "bool", "none", "negative", "huge", "numpy", "0d", "complex", "text")

DEFAULT = {"shape": ERROR, "nan": ERROR, "inf": ERROR, "none": ERROR, "list": SAME,
           "pandas": SAME, "0d": ERROR, "complex": ERROR, "object": ERROR, "bool": EITHER,
           "int": AS_FLOAT, "readonly": SAME, "strided": SAME, "huge": EITHER, "tiny": EITHER,
           "text": ERROR, "float": ERROR, "negative": ERROR, "numpy": SAME,
           # dates and durations are not samples (numpy would read seconds since 1970);
           # pandas' nullable floats, a categorical of numbers and Decimal objects are
           # the same numbers
           "datetime64": ERROR, "timedelta": ERROR, "pandas_dates": ERROR,
           "nullable": SAME, "categorical": SAME,
           "decimal": SAME}
SCALAR_DEFAULT = {**DEFAULT, "list": SAME, "0d": SAME, "bool": ERROR}
INT_DEFAULT = {**DEFAULT, "0d": SAME}


def scaled(f):
    """Expected result for the value times ``s``: ``f(result, s)``."""
    return ("scaled", f)


@dataclass(frozen=True)
class Entry:
    """One argument of one public entry point."""

    name: str                  # "ARX.fit"
    arg: str                   # the argument's name, as error messages spell it
    run: Callable              # run(value) -> result (an array or a tuple of arrays)
    good: object               # a valid value
    kind: str = "array"        # "array", "scalar" or "int"
    expect: dict = field(default_factory=dict)   # outcome per kind, where not the default
    state: Callable = None     # state() -> bytes of the object whose state must not change
    known: dict = field(default_factory=dict)    # kind -> reason: xfail(strict=True) until fixed


# ----------------------------------------------------------------------
# the bad values
# ----------------------------------------------------------------------
def _variants(entry):
    g = entry.good
    if entry.kind == "int":
        return {"float": float(g), "bool": True, "none": None, "negative": -1, "huge": 10**13,
                "numpy": np.int64(g), "0d": np.array(g), "complex": complex(g),
                "text": str(g)}
    if entry.kind == "scalar":
        return {"shape": np.full((2, 2), g), "nan": np.nan, "inf": np.inf, "none": None,
                "list": [g], "0d": np.array(g), "complex": complex(g, 1.0),
                "object": np.array(["a"], dtype=object), "bool": True, "int": 1,
                "text": "a", "huge": g * HUGE, "tiny": g * TINY}
    a = np.array(g, dtype=float)
    flat = a.reshape(-1)
    mid = flat.size // 2
    nan, inf = a.copy(), a.copy()
    nan.reshape(-1)[mid] = np.nan
    inf.reshape(-1)[mid] = np.inf
    obj = a.astype(object)
    obj.reshape(-1)[mid] = "a"
    readonly = a.copy()
    readonly.flags.writeable = False
    strided = np.repeat(a, 2, axis=0)[::2]
    return {"shape": a[None, None], "nan": nan, "inf": inf, "none": None,
            "list": a.tolist(),
            "pandas": pd.Series(a) if a.ndim == 1 else pd.DataFrame(a) if a.ndim == 2 else a,
            "0d": np.array(flat[0]), "complex": a + 0.0j, "object": obj,
            "bool": a > np.median(a), "int": np.round(4.0 * a).astype(np.int64),
            "readonly": readonly, "strided": strided, "huge": a * HUGE, "tiny": a * TINY,
            "datetime64": (np.round(1e3 * a).astype(np.int64)
                           + np.int64(1_700_000_000_000)).astype("datetime64[ms]"),
            "timedelta": np.round(1e3 * a).astype(np.int64).astype("timedelta64[ms]"),
            # pandas' to_numpy(dtype=float) reads dates as nanoseconds since 1970 (#27
            # review): time-zone aware dates in a Series, durations in a DataFrame
            "pandas_dates": _pandas_dates(a),
            "nullable": (pd.array(a, dtype="Float64") if a.ndim == 1
                         else pd.DataFrame(a).astype("Float64") if a.ndim == 2 else a),
            "categorical": pd.Series(pd.Categorical(a)) if a.ndim == 1 else a,
            "decimal": _decimals(a)}


def _pandas_dates(a):
    """`a` as pandas dates or durations (a Series of time-zone aware dates, a DataFrame
    of durations; numpy dates beyond two dimensions)."""
    ms = np.round(1e3 * a).astype(np.int64)
    if a.ndim == 1:
        return pd.Series(pd.to_datetime(ms + 1_700_000_000_000, unit="ms", utc=True))
    if a.ndim == 2:
        return pd.DataFrame(ms.astype("timedelta64[ms]"))
    return (ms + np.int64(1_700_000_000_000)).astype("datetime64[ms]")


def _decimals(a):
    """`a` as an object array of `decimal.Decimal` (each the exact value of its double)."""
    from decimal import Decimal
    out = np.empty(a.shape, dtype=object)
    out.reshape(-1)[:] = [Decimal(v) for v in a.reshape(-1)]
    return out


def _as_float(value):
    if isinstance(value, np.ndarray):
        return value.astype(float)
    return float(value)


# ----------------------------------------------------------------------
# records and helpers for the table
# ----------------------------------------------------------------------
_RNG = np.random.default_rng(18)
N = 300
U = _RNG.standard_normal(N)
Y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], U) + lfilter([1.0], [1, -1.5, 0.7],
                                                         0.1 * _RNG.standard_normal(N))
HS = _RNG.standard_normal((40, 3))
ZS = HS @ np.array([0.7, -0.3, -0.2]) + 0.05 * _RNG.standard_normal(40)
ROW = np.array([0.3, -1.2, 0.8])
MODEL = ARX(2, 2).fit(U, Y)
PHI, TARGET = MODEL.regressors(U, Y)


def _filters():
    return {"RecursiveLeastSquares": lambda **kw: RecursiveLeastSquares(3, **kw),
            "RecursiveLeastSquares-lam0.95": lambda **kw: RecursiveLeastSquares(3, lam=0.95,
                                                                                **kw),
            "SquareRootRLS": lambda **kw: SquareRootRLS(3, **kw),
            "SlidingWindowRLS": lambda **kw: SlidingWindowRLS(3, 20, **kw)}


def _xp(f):
    return f.x.copy(), f.P.copy()


class _Running:
    """A filter run on the first samples, whose method is then called; its state is
    compared before and after a rejected call, and put back after an accepted one."""

    def __init__(self, make):
        self.f = make()
        self.f.batch_filter(ZS[:10], HS[:10])

    def state(self):
        return pickle.dumps(self.f)

    def call(self, method):
        def run(v):
            before = self.state()
            try:
                return method(self.f, v)
            finally:
                if self.state() != before:          # an accepted call: back to the start
                    self.f = pickle.loads(before)
        return run


def _filter_entries(label, make):
    """The table lines of one filter configuration."""
    linear_in_z = scaled(lambda r, s: (r[0] * s, r[1]))     # x0 = 0: x is linear in z
    entries = [
        Entry(f"{label}()", "x0", lambda v: _xp(_batch(make(x0=v))), [0.1, 0.2, 0.3],
              expect={"none": OK}),
        Entry(f"{label}()", "P0", lambda v: _xp(_batch(make(P0=v))), 10.0 * np.eye(3),
              expect={"none": ERROR, "huge": ERROR, "0d": SAME}),
        Entry(f"{label}()", "R", lambda v: _xp(_batch(make(R=v))), 0.5, kind="scalar",
              expect={"huge": ERROR, "tiny": ERROR}),
    ]
    running = _Running(make)

    def update(z=ZS[10], H=HS[10], R=None):
        g = pickle.loads(running.state())
        g.predict()
        g.update(z, H, R)
        return _xp(g)

    on_running = running.call

    entries += [
        Entry(f"{label}.update", "z", lambda v: update(z=v), ZS[10], kind="scalar",
              expect={"nan": OK, "none": OK, "bool": EITHER, "huge": EITHER, "tiny": EITHER}),
        # H=None is H omitted: self.H, as filterpy's update(z, R=None, H=None)
        Entry(f"{label}.update", "H", lambda v: update(H=v), ROW,
              expect={"huge": WARNS, "none": OK}),
        Entry(f"{label}.update", "R", lambda v: update(R=v), 0.5, kind="scalar",
              expect={"none": OK, "huge": ERROR, "tiny": ERROR}),
        Entry(f"{label}.batch_filter", "zs",
              on_running(lambda g, v: g.batch_filter(v, HS[10:])[0]), ZS[10:],
              expect={"nan": OK, "pandas": SAME}, state=running.state),
        Entry(f"{label}.batch_filter", "Hs",
              on_running(lambda g, v: g.batch_filter(ZS[10:], v)[0]), HS[10:],
              expect={"huge": WARNS}, state=running.state),
        Entry(f"{label}.batch_filter", "Rs",
              on_running(lambda g, v: g.batch_filter(ZS[10:], HS[10:], Rs=v)[0]),
              np.linspace(0.5, 2.0, 30), expect={"none": OK, "0d": OK, "int": EITHER,
                                                 "huge": ERROR, "tiny": ERROR},
              state=running.state),
        Entry(f"{label}.initialize", "zs", lambda v: _xp(_init(make(), v, HS[:12])), ZS[:12],
              expect={"nan": OK, "huge": linear_in_z, "tiny": linear_in_z}),
        Entry(f"{label}.initialize", "Hs", lambda v: _xp(_init(make(), ZS[:12], v)), HS[:12],
              expect={"bool": EITHER, "int": EITHER, "huge": WARNS, "tiny": WARNS}),
    ]
    if label in ("RecursiveLeastSquares", "SquareRootRLS"):
        entries.append(Entry(f"{label}()", "lam", lambda v: _xp(_batch(make(lam=v))), 0.95,
                             kind="scalar", expect={"huge": ERROR, "tiny": WARNS}))
    if label == "RecursiveLeastSquares":      # one factor per parameter (#30)
        entries.append(Entry(f"{label}(forgetting='diagonal')", "lam",
                             lambda v: _xp(_batch(make(lam=v, forgetting="diagonal"))),
                             np.array([0.95, 0.99, 1.0]),
                             # a number is every parameter's; 4, 4, 4 are not in (0, 1]
                             expect={"0d": OK, "int": ERROR, "tiny": WARNS}))
    if label.startswith("RecursiveLeastSquares"):
        entries += [
            Entry(f"{label}()", "Q", lambda v: _xp(_batch(make(Q=v))), 1e-4 * np.eye(3),
                  expect={"none": ERROR, "huge": ERROR, "0d": EITHER, "bool": EITHER,
                          "int": EITHER}),
            Entry(f"{label}.constrain", "A",
                  on_running(lambda g, v: _xp(g.constrain(v, [0.5]))), [[1.0, 1.0, 0.0]],
                  expect={"shape": ERROR, "0d": ERROR, "int": EITHER, "bool": EITHER},
                  state=running.state),
            Entry(f"{label}.constrain", "b",
                  on_running(lambda g, v: _xp(g.constrain([[1.0, 1.0, 0.0]], v))), [0.5],
                  expect={"0d": SAME}, state=running.state),
        ]
    if label == "SlidingWindowRLS":
        entries.append(Entry("SlidingWindowRLS()", "window",
                             lambda v: _xp(_batch(SlidingWindowRLS(3, v))), 20, kind="int"))
    entries.append(Entry(f"{label}()", "dim_x", lambda v: _dims(label, v), 3, kind="int"))
    return entries


def _dims(label, n):
    make = {"RecursiveLeastSquares": RecursiveLeastSquares, "SquareRootRLS": SquareRootRLS}
    if label == "SlidingWindowRLS":
        f = SlidingWindowRLS(n, 20)
    else:
        f = make[label.split("-")[0]](n)
    return f.x.shape


def _batch(f):
    f.batch_filter(ZS, HS)
    return f


def _init(f, zs, Hs):
    f.initialize(zs, Hs)
    return f


def _theta(model):
    return model.theta_.copy()


def _arx_entries():
    b_scaled = scaled(lambda r, s: r * np.array([1.0, 1.0, s, s]))     # y * s: b * s
    b_inverse = scaled(lambda r, s: r * np.array([1.0, 1.0, 1 / s, 1 / s]))  # u * s: b / s
    linear = scaled(lambda r, s: r * s)
    same_scale = scaled(lambda r, s: r)
    return [
        Entry("ARX.fit", "u", lambda v: _theta(ARX(2, 2).fit(v, Y)), U,
              expect={"huge": b_inverse, "tiny": b_inverse}),
        Entry("ARX.fit", "y", lambda v: _theta(ARX(2, 2).fit(U, v)), Y,
              expect={"huge": b_scaled, "tiny": b_scaled, "shape": ERROR}),
        # the IV and recursive fits run in power-of-two scaled units too (#18 item 7)
        *[Entry(f"ARX.fit(method={m!r})", "u",
                lambda v, m=m: _theta(ARX(2, 2).fit(v, Y, method=m)), U,
                expect={"huge": b_inverse, "tiny": b_inverse}) for m in ("iv", "riv", "rls")],
        *[Entry(f"ARX.fit(method={m!r})", "y",
                lambda v, m=m: _theta(ARX(2, 2).fit(U, v, method=m)), Y,
                expect={"huge": b_scaled, "tiny": b_scaled, "shape": ERROR})
          for m in ("iv", "riv", "rls")],
        # lam="tune" and Q="tune" tune in those units too (#30): a record around 1e+-160
        # tunes (the power-of-two images: test_scale.py); Q="tune" far below unit size is
        # refused naming `u` or `y`, `Q` and `R` (its random walk beyond a filter's range
        # in the signals' units)
        *[Entry(f"ARX.fit(method='rls', {p}='tune')", arg,
                lambda v, p=p, arg=arg: _theta(ARX(2, 2).fit(
                    *((v, Y) if arg == "u" else (U, v)), method="rls", **{p: "tune"})),
                U if arg == "u" else Y,
                expect={"huge": OK, "tiny": OK if p == "lam" else ERROR,
                        **({} if arg == "u" else {"shape": ERROR})})
          for p in ("lam", "Q") for arg in ("u", "y")],
        Entry("ARX()", "na", lambda v: _theta(ARX(v, 2).fit(U, Y)), 2, kind="int",
              expect={"negative": ERROR, "huge": ERROR}),
        Entry("ARX()", "nb", lambda v: _theta(ARX(2, v).fit(U, Y)), 2, kind="int"),
        Entry("ARX()", "nk", lambda v: _theta(ARX(2, 2, v).fit(U, Y)), 1, kind="int"),
        Entry("ARX()", "dt", lambda v: float(ARX(2, 2, dt=v).fit(U, Y).to_tf().dt), 0.1,
              kind="scalar", expect={"list": ERROR, "0d": ERROR, "int": AS_FLOAT,
                                     "huge": OK, "tiny": OK, "none": ERROR, "bool": OK}),
        Entry("ARX.predict", "u", lambda v: MODEL.predict(v, Y, horizon=2), U,
              expect={"huge": EITHER, "tiny": EITHER}),
        Entry("ARX.predict", "y", lambda v: MODEL.predict(U, v, horizon=2), Y),
        Entry("ARX.predict", "horizon", lambda v: MODEL.predict(U, Y, horizon=v), 3,
              kind="int", expect={"huge": OK, "negative": ERROR}),
        Entry("ARX.simulate", "u", lambda v: MODEL.simulate(v), U,
              expect={"huge": linear, "tiny": linear}),
        Entry("ARX.simulate", "y0", lambda v: MODEL.simulate(U, y0=v), Y[:2],
              expect={"none": OK, "0d": ERROR, "huge": EITHER}),
        Entry("ARX.from_polynomials", "a", lambda v: _theta(ARX.from_polynomials(v, [1.0])),
              [-1.5, 0.7], expect={"0d": OK, "huge": OK, "tiny": OK}),
        Entry("ARX.from_polynomials", "b",
              lambda v: _theta(ARX.from_polynomials([-0.5], v)), [1.0, 0.5],
              expect={"0d": OK, "huge": OK, "tiny": OK}),
        Entry("validate", "u", lambda v: validate(MODEL, v, Y).simulation_fit, U,
              expect={"huge": EITHER, "tiny": EITHER}),
        Entry("validate", "y", lambda v: validate(MODEL, U, v).simulation_fit, Y,
              expect={"huge": EITHER, "tiny": EITHER}),
        Entry("validate", "max_lag", lambda v: validate(MODEL, U, Y, max_lag=v).residuals[0]
              .q_statistic, 10, kind="int"),
        Entry("validate", "alpha", lambda v: validate(MODEL, U, Y, alpha=v).passed, 0.01,
              kind="scalar", expect={"huge": ERROR, "tiny": OK, "int": ERROR}),
        Entry("residual_analysis", "y", lambda v: residual_analysis(MODEL, U, v).q_statistic,
              Y),
        Entry("information_criteria", "u", lambda v: information_criteria(MODEL, v, Y).aic,
              U),
        Entry("select_order", "u", lambda v: _best(v, Y), U,
              expect={"huge": same_scale, "tiny": same_scale}),
        Entry("select_order", "y", lambda v: _best(U, v), Y,
              expect={"huge": same_scale, "tiny": same_scale}),
        Entry("select_order", "na", lambda v: _best(U, Y, na=v), 2, kind="int",
              expect={"negative": ERROR}),
        Entry("cusum", "zs", lambda v: cusum(v, PHI).statistic, TARGET,
              expect={"huge": scaled(lambda r, s: r), "tiny": scaled(lambda r, s: r)}),
        Entry("cusum", "Hs", lambda v: cusum(TARGET, v).statistic, PHI,
              expect={"huge": scaled(lambda r, s: r), "tiny": scaled(lambda r, s: r),
                      "bool": EITHER, "int": EITHER}),
        Entry("cusum", "alpha", lambda v: cusum(TARGET, PHI, alpha=v).critical_value, 0.05,
              kind="scalar", expect={"huge": ERROR, "tiny": OK, "int": ERROR}),
        Entry("fit_percent", "yhat", lambda v: fit_percent(Y, v), 0.9 * Y,
              expect={"huge": EITHER, "tiny": EITHER}),
        Entry("datasets.dc_motor", "n_samples", lambda v: datasets.dc_motor(n_samples=v).y,
              400, kind="int", expect={"huge": ERROR}),
        Entry("datasets.dc_motor", "noise_std",
              lambda v: datasets.dc_motor(n_samples=300, noise_std=v).y, 0.01, kind="scalar",
              expect={"int": OK, "huge": OK, "tiny": OK}),
        Entry("datasets.prbs", "n_samples", lambda v: datasets.prbs(v), 100, kind="int",
              expect={"huge": ERROR}),
    ]


def _bank_entries():
    """`RLSBank`: four channels of three parameters."""
    C = 4
    zs = np.column_stack([ZS + 0.01 * c for c in range(C)])            # (N, C)
    Hs = np.repeat(HS[:, None, :], C, axis=1)                        # (N, C, 3)

    def run(**kw):
        bank = RLSBank(C, 3, **kw)
        bank.batch_filter(zs, Hs)
        return bank.x.copy(), bank.P.copy()

    def update(z=zs[10], H=Hs[10], R=None):
        bank = RLSBank(C, 3)
        bank.batch_filter(zs[:10], Hs[:10])
        bank.predict()
        bank.update(z, H, R)
        return bank.x.copy(), bank.P.copy()

    return [
        Entry("RLSBank()", "R", lambda v: run(R=v), 0.5, kind="scalar",
              expect={"huge": ERROR, "tiny": ERROR, "list": ERROR}),
        Entry("RLSBank()", "lam", lambda v: run(lam=v), 0.95, kind="scalar",
              expect={"huge": ERROR, "tiny": WARNS, "list": ERROR}),
        Entry("RLSBank()", "P0", lambda v: run(P0=v), 10.0 * np.eye(3),
              expect={"huge": ERROR, "0d": SAME, "none": ERROR}),
        # None: no measurement for any channel (documented since the bank's freeze, #31)
        Entry("RLSBank.update", "z", lambda v: update(z=v), zs[10],
              expect={"nan": OK, "none": OK}),
        Entry("RLSBank.update", "H", lambda v: update(H=v), Hs[10],
              expect={"nan": OK, "huge": WARNS}),
        Entry("RLSBank.batch_filter", "zs",
              lambda v: RLSBank(C, 3).batch_filter(v, Hs).means, zs, expect={"nan": OK}),
        Entry("RLSBank.batch_filter", "Hs",
              lambda v: RLSBank(C, 3).batch_filter(zs, v).means, Hs,
              expect={"nan": OK, "huge": WARNS}),
        Entry("RLSBank()", "n_channels", lambda v: RLSBank(v, 3).x.shape, 4, kind="int"),
    ]


def _family_entries():
    """`ARMAX`, `OE` and `BJ` (prediction-error method) and `IOData`, the containers of
    real records.

    The prediction-error fits run in scaled units (`rlsfilt.models._units.RecordUnits`), so
    around 1e160 and 1e-160 they are the fit of the unscaled record with the ``b``
    coefficients scaled by ``s`` (``y * s``) or ``1 / s`` (``u * s``), the others unchanged;
    the recursive ones run there as well, from a prior in the signals' units.
    """
    def b_times(mask):          # mask: 1 where theta_ holds a b coefficient
        mask = np.array(mask, dtype=float)
        return (scaled(lambda r, s: r * np.where(mask == 1, s, 1.0)),
                scaled(lambda r, s: r * np.where(mask == 1, 1 / s, 1.0)))

    models = {"ARMAX": (lambda: ARMAX(2, 2, 1), [0, 0, 1, 1, 0]),       # a1 a2 b1 b2 c1
              "OE": (lambda: OE(2, 2), [1, 1, 0, 0]),                   # b1 b2 f1 f2
              "BJ": (lambda: BJ(2, 1, 1, 2), [1, 1, 0, 0, 0, 0])}       # b1 b2 c1 d1 f1 f2
    entries = []
    for name, (make, mask) in models.items():
        y_scaled, u_scaled = b_times(mask)
        entries += [
            Entry(f"{name}.fit", "u", lambda v, make=make: _theta(make().fit(v, Y)), U,
                  expect={"huge": u_scaled, "tiny": u_scaled}),
            Entry(f"{name}.fit", "y", lambda v, make=make: _theta(make().fit(U, v)), Y,
                  expect={"huge": y_scaled, "tiny": y_scaled}),
        ]
    # the recursive prediction-error fits: their prior P0 = 1e4 I is in the signals' units
    # (MATLAB's, and the streaming estimators'), so a record around 1e-160 hears that the
    # prior outweighs the data (NumericalWarning naming P0), one around 1e160 that it is too
    # diffuse for double precision (ValueError naming P0 and the scale of `u` and `y`)
    for arg in ("u", "y"):
        entries.append(Entry(
            "ARMAX.fit(method='rpem')", arg,
            (lambda v: _theta(ARMAX(2, 2, 1).fit(v, Y, method="rpem"))) if arg == "u" else
            (lambda v: _theta(ARMAX(2, 2, 1).fit(U, v, method="rpem"))), U if arg == "u" else Y,
            expect={"huge": ERROR, "tiny": WARNS}))
    return entries + [
        Entry("IOData", "u", lambda v: np.asarray(IOData(v, Y, dt=0.1).u), U,
              expect={"huge": OK, "tiny": OK}),
        Entry("IOData", "y", lambda v: np.asarray(IOData(U, v, dt=0.1).y), Y,
              expect={"huge": OK, "tiny": OK}),
        Entry("IOData", "dt", lambda v: IOData(U, Y, dt=v).dt, 0.1, kind="scalar",
              expect={"list": EITHER, "0d": EITHER, "int": AS_FLOAT, "huge": OK, "tiny": OK,
                      "none": EITHER, "bool": EITHER}),
    ]


def _persistence_entries():
    """`load_model` (#27): fields of a model file replaced by the catalogue's bad values.

    A value is written as a model file would store it (an array as ``{"__ndarray__": ...}``
    with its dtype, a NumPy scalar as its number, a non-finite float by name); the loader
    reads the file against its schema, so a bad value is a ValueError naming the field by
    its JSON path (more tampered files: test_persistence_tampered.py).
    """
    import copy
    import json
    import math
    import tempfile

    from rlsfilt import load_model
    from rlsfilt._model_file import _document, _dumps

    folder = tempfile.mkdtemp(prefix="rlsfilt-audit-")
    base = json.loads(_dumps(_document(MODEL)))

    def stored(v):
        if isinstance(v, (pd.Series, pd.DataFrame, pd.api.extensions.ExtensionArray)):
            v = v.to_numpy(dtype=float)     # pandas' own dtypes hold the same numbers
        if isinstance(v, np.ndarray):
            if v.ndim == 0:
                return stored(v.item())
            data = [x if isinstance(x, (bool, int)) or isinstance(x, float) and math.isfinite(x)
                    else str(x) for x in v.ravel().tolist()]
            return {"__ndarray__": {"dtype": v.dtype.str, "shape": list(v.shape), "data": data}}
        if isinstance(v, np.generic):
            v = v.item()
        if isinstance(v, complex):
            return [v.real, v.imag]
        if isinstance(v, float) and not math.isfinite(v):
            return {"__float__": "NaN" if math.isnan(v) else "Infinity"}
        if isinstance(v, list):
            return [stored(x) for x in v]
        return v

    def run(section, field, result):
        def load(v):
            doc = copy.deepcopy(base)
            doc[section][field] = stored(v)
            path = os.path.join(folder, "model.json")
            with open(path, "w", encoding="utf-8") as fh:
                json.dump(doc, fh)
            return result(load_model(path))
        return load

    # a plain list is not a stored array, an int or bool array not a float one
    # (an array of Decimal objects is stored with dtype object: not a float array either)
    # (a file holds no pandas objects: `stored` writes pandas dates as the nanosecond counts
    # pandas gives, numbers like any other, or fails on time-zone aware ones)
    array = {"list": ERROR, "int": ERROR, "bool": ERROR, "huge": OK, "tiny": OK,
             "decimal": ERROR, "pandas_dates": EITHER}
    return [
        # scaled coefficients no longer match the stored polynomials a_, b_: refused
        Entry("load_model", "fitted.theta_",
              run("fitted", "theta_", lambda m: m.theta_.copy()), MODEL.theta_,
              expect={**array, "huge": ERROR, "tiny": ERROR}),
        Entry("load_model", "fitted.theta_cov_",
              run("fitted", "theta_cov_", lambda m: m.std_errors_.copy()), MODEL.theta_cov_,
              expect=array),
        Entry("load_model", "fitted.input_offset_",
              run("fitted", "input_offset_", lambda m: m.input_offset_.copy()),
              MODEL.input_offset_, expect=array),
        Entry("load_model", "fitted.noise_variance_",
              run("fitted", "noise_variance_", lambda m: m.noise_variance_),
              MODEL.noise_variance_, kind="scalar",
              expect={"list": ERROR, "int": AS_FLOAT, "huge": OK, "tiny": OK}),
        Entry("load_model", "fitted.n_samples_",
              run("fitted", "n_samples_", lambda m: m.n_samples_), MODEL.n_samples_,
              kind="int", expect={"huge": OK}),
        Entry("load_model", "params.na", run("params", "na", lambda m: m.theta_.copy()), 2,
              kind="int"),
        Entry("load_model", "params.dt", run("params", "dt", lambda m: m.dt), 0.5,
              kind="scalar",
              expect={"list": ERROR, "bool": OK, "int": AS_FLOAT, "huge": OK, "tiny": OK}),
    ]


def _running_on(obj):
    """A `_Running` around `obj` as it is (a bank or a streaming model)."""
    running = object.__new__(_Running)
    running.f = obj
    return running


def _online_entries():
    """The online estimation of #31: `GradientBank`, the gradient and window options of
    `ARX.fit`, the `Recursive*` models' methods, window and steps (a rejected step or
    batch leaves the estimator as it was)."""
    from rlsfilt import GradientBank, RecursiveAR, RecursiveARX, RecursiveOE

    C = 4
    zs = np.column_stack([ZS + 0.01 * c for c in range(C)])            # (N, C)
    Hs = np.repeat(HS[:, None, :], C, axis=1)                        # (N, C, 3)

    def bank(**kw):
        b = GradientBank(C, 3, **{"mu": 0.5, **kw})
        b.batch_filter(zs, Hs)
        return b.x.copy()

    running = _running_on(GradientBank(C, 3, mu=0.5))
    running.f.batch_filter(zs[:10], Hs[:10])
    on_bank = running.call
    entries = [
        Entry("GradientBank()", "mu", lambda v: bank(mu=v), 0.5, kind="scalar",
              expect={"huge": EITHER, "tiny": OK, "list": EITHER, "int": AS_FLOAT}),
        Entry("GradientBank()", "eps", lambda v: bank(eps=v), 1e-3, kind="scalar",
              expect={"huge": OK, "tiny": OK, "list": EITHER, "int": AS_FLOAT}),
        Entry("GradientBank()", "leak", lambda v: bank(leak=v), 1e-3, kind="scalar",
              expect={"huge": EITHER, "tiny": OK, "list": EITHER, "int": EITHER}),
        Entry("GradientBank()", "x0", lambda v: bank(x0=v), [0.1, 0.2, 0.3],
              expect={"none": OK, "huge": EITHER, "tiny": OK}),
        Entry("GradientBank()", "n_channels", lambda v: GradientBank(v, 3).x.shape, 4,
              kind="int"),
        Entry("GradientBank()", "dim_x", lambda v: GradientBank(4, v).x.shape, 3, kind="int"),
        Entry("GradientBank.update", "z",
              on_bank(lambda g, v: (g.predict(), g.update(v, Hs[10]), g.x.copy())[-1]),
              zs[10], expect={"nan": OK, "none": OK, "huge": EITHER, "tiny": OK},
              state=running.state),          # None: no measurement (every channel skips)
        Entry("GradientBank.update", "H",
              on_bank(lambda g, v: (g.predict(), g.update(zs[10], v), g.x.copy())[-1]),
              Hs[10], expect={"nan": OK, "huge": EITHER, "tiny": OK, "bool": EITHER},
              state=running.state),
        # update_block's messages use batch_filter's names (documented, as RLSBank's)
        Entry("GradientBank.update_block", "zs",
              on_bank(lambda g, v: (g.update_block(v, Hs[10:20]), g.x.copy())[-1]),
              zs[10:20], expect={"nan": OK, "huge": EITHER, "tiny": OK}, state=running.state),
        Entry("GradientBank.update_block", "Hs",
              on_bank(lambda g, v: (g.update_block(zs[10:20], v), g.x.copy())[-1]),
              Hs[10:20], expect={"nan": OK, "huge": EITHER, "tiny": OK, "bool": EITHER},
              state=running.state),
        Entry("GradientBank.batch_filter", "zs",
              on_bank(lambda g, v: g.batch_filter(v, Hs[10:]).means), zs[10:],
              expect={"nan": OK, "huge": EITHER, "tiny": OK}, state=running.state),
        Entry("GradientBank.batch_filter", "Hs",
              on_bank(lambda g, v: g.batch_filter(zs[10:], v).means), Hs[10:],
              expect={"nan": OK, "huge": EITHER, "tiny": OK, "bool": EITHER},
              state=running.state),
    ]
    # ARX.fit's gradient methods and window
    b_inv = scaled(lambda r, s: r * np.array([1.0, 1.0, 1 / s, 1 / s]))     # u * s: b / s
    b_scaled_y = scaled(lambda r, s: r * np.array([1.0, 1.0, s, s]))        # y * s: b * s
    for m in ("nlms", "lms"):
        mu = 0.5 if m == "nlms" else 0.01
        entries += [
            Entry(f"ARX.fit(method={m!r})", "u",
                  lambda v, m=m, mu=mu: _theta(ARX(2, 2).fit(v, Y, method=m, mu=mu)), U,
                  expect={"huge": EITHER, "tiny": EITHER}),
            Entry(f"ARX.fit(method={m!r})", "y",
                  lambda v, m=m, mu=mu: _theta(ARX(2, 2).fit(U, v, method=m, mu=mu)), Y,
                  expect={"huge": EITHER, "tiny": EITHER, "shape": ERROR}),
            Entry(f"ARX.fit(method={m!r})", "mu",
                  lambda v, m=m: _theta(ARX(2, 2).fit(U, Y, method=m, mu=v)), mu,
                  kind="scalar", expect={"huge": EITHER, "tiny": OK, "int": EITHER}),
            Entry(f"ARX.fit(method={m!r})", "leak",
                  lambda v, m=m, mu=mu: _theta(ARX(2, 2).fit(U, Y, method=m, mu=mu, leak=v)),
                  1e-3, kind="scalar", expect={"huge": EITHER, "tiny": OK, "int": EITHER}),
        ]
    entries += [
        Entry("ARX.fit(method='nlms')", "eps",
              lambda v: _theta(ARX(2, 2).fit(U, Y, method="nlms", mu=0.5, eps=v)), 1e-3,
              kind="scalar", expect={"huge": OK, "tiny": OK, "int": AS_FLOAT}),
        Entry("ARX.fit(method='rls')", "window",
              lambda v: _theta(ARX(2, 2).fit(U, Y, method="rls", window=v)), 50, kind="int",
              expect={"none": OK}),                  # None: no window (the default)
        # the window runs in power-of-two scaled units as the other ARX fits (#18 item 7)
        Entry("ARX.fit(method='rls', window=50)", "u",
              lambda v: _theta(ARX(2, 2).fit(v, Y, method="rls", window=50)), U,
              expect={"huge": b_inv, "tiny": b_inv}),
        Entry("ARX.fit(method='rls', window=50)", "y",
              lambda v: _theta(ARX(2, 2).fit(U, v, method="rls", window=50)), Y,
              expect={"huge": b_scaled_y, "tiny": b_scaled_y, "shape": ERROR}),
    ]
    # the streaming models: options, steps and records
    makers = {"RecursiveARX(method='nlms')": lambda: RecursiveARX(2, 2, 1, method="nlms",
                                                                  mu=0.5),
              "RecursiveARX(window=40)": lambda: RecursiveARX(2, 2, 1, window=40),
              "RecursiveOE(window=60)": lambda: RecursiveOE(2, 2, 1, window=60),
              "RecursiveARX": lambda: RecursiveARX(2, 2, 1)}
    for label, make in makers.items():
        est = _running_on(make())
        est.f.batch(Y[:30], U[:30])

        # a window's prior is in the signals' units (the module notes of
        # rlsfilt.models.recursive): around 1e160 its health warning, the state unchanged
        big = WARNS if "window" in label else EITHER

        def step(g, v, which):
            out = g.step(v, U[30]) if which == "y" else g.step(Y[30], v)
            return out[0], out[1]

        entries += [
            Entry(f"{label}.step", "y", est.call(lambda g, v: step(g, v, "y")), Y[30],
                  kind="scalar", expect={"huge": EITHER, "tiny": EITHER, "bool": EITHER},
                  state=est.state),
            Entry(f"{label}.step", "u", est.call(lambda g, v: step(g, v, "u")), U[30],
                  kind="scalar", expect={"huge": EITHER, "tiny": EITHER, "bool": EITHER,
                                         "none": ERROR}, state=est.state),
            Entry(f"{label}.batch", "y", est.call(lambda g, v: g.batch(v, U[30:60])[1]),
                  Y[30:60], expect={"huge": big, "tiny": EITHER}, state=est.state),
            Entry(f"{label}.batch", "u", est.call(lambda g, v: g.batch(Y[30:60], v)[1]),
                  U[30:60], expect={"huge": big, "tiny": EITHER}, state=est.state),
        ]
    frozen = _running_on(RecursiveARX(2, 2, 1))
    frozen.f.batch(Y[:30], U[:30])
    frozen.f.freeze()
    entries += [
        Entry("RecursiveARX(frozen).step", "y",
              frozen.call(lambda g, v: g.step(v, U[30])[0]), Y[30], kind="scalar",
              expect={"huge": EITHER, "tiny": EITHER, "bool": EITHER}, state=frozen.state),
        Entry("RecursiveARX(frozen).batch", "u",
              frozen.call(lambda g, v: g.batch(Y[30:60], v)[0]), U[30:60],
              expect={"huge": EITHER, "tiny": EITHER}, state=frozen.state),
        Entry("RecursiveARX()", "mu",
              lambda v: RecursiveARX(2, 2, 1, method="nlms", mu=v).batch(Y, U)[1], 0.5,
              kind="scalar", expect={"huge": EITHER, "tiny": OK, "int": EITHER}),
        Entry("RecursiveARX()", "window",
              lambda v: RecursiveARX(2, 2, 1, window=v).batch(Y, U)[1], 40, kind="int",
              expect={"none": OK}),
        Entry("RecursiveAR()", "window",
              lambda v: RecursiveAR(2, window=v).batch(Y)[1], 40, kind="int", expect={"none": OK}),
        Entry("RecursiveOE()", "window",
              lambda v: RecursiveOE(2, 2, 1, window=v).batch(Y, U)[1], 60, kind="int",
              expect={"none": OK}),
        Entry("RecursiveAR()", "mu",
              lambda v: RecursiveAR(2, method="lms", mu=v).batch(Y)[1], 0.01,
              kind="scalar", expect={"huge": EITHER, "tiny": OK, "int": EITHER}),
    ]
    return entries


def _adapter_entries():
    """The streaming adapters (#31): river's and scikit-learn's `RLSRegressor`
    (constructors, ``learn_one``/``predict_one``, ``fit``/``partial_fit``/``predict``)."""
    from rlsfilt.river import RLSRegressor as RiverRLS
    from rlsfilt.sklearn import RLSRegressor as SkRLS

    def river_run(**kw):
        m = RiverRLS(**kw)
        for h, z in zip(HS, ZS):
            m.learn_one({"a": h[0], "b": h[1], "c": h[2]}, z)
        return np.array(list(m.weights.values()))

    learner = _running_on(RiverRLS())
    for h, z in zip(HS[:10], ZS[:10]):
        learner.f.learn_one({"a": h[0], "b": h[1], "c": h[2]}, z)
    row = {"a": HS[10, 0], "b": HS[10, 1]}

    def learn(g, v, which):
        x = {**row, "c": v} if which == "x" else {**row, "c": HS[10, 2]}
        g.learn_one(x, v if which == "y" else ZS[10])
        return np.array(list(g.weights.values()))

    sk = _running_on(SkRLS().partial_fit(HS[:10], ZS[:10]))

    def coef(m):
        return np.append(m.coef_, m.intercept_)

    return [
        # lam around 1e-160: the filter's health warning (P^- = P / lam overflows)
        Entry("river.RLSRegressor()", "lam", lambda v: river_run(lam=v), 0.98, kind="scalar",
              expect={"huge": ERROR, "tiny": WARNS, "list": EITHER}),
        Entry("river.RLSRegressor()", "delta", lambda v: river_run(delta=v), 100.0,
              kind="scalar", expect={"huge": EITHER, "tiny": EITHER, "list": EITHER}),
        Entry("river.RLSRegressor()", "R", lambda v: river_run(R=v), 0.5, kind="scalar",
              expect={"huge": ERROR, "tiny": ERROR, "list": EITHER}),
        Entry("river.RLSRegressor.learn_one", "y",
              learner.call(lambda g, v: learn(g, v, "y")), ZS[10], kind="scalar",
              expect={"huge": EITHER, "tiny": EITHER, "list": EITHER, "0d": EITHER},
              state=learner.state),
        Entry("river.RLSRegressor.learn_one", "x",
              learner.call(lambda g, v: learn(g, v, "x")), HS[10, 2], kind="scalar",
              expect={"huge": WARNS, "tiny": EITHER, "list": EITHER, "0d": EITHER},
              state=learner.state),
        Entry("river.RLSRegressor.predict_one", "x",
              lambda v: learner.f.predict_one({**row, "c": v}), HS[10, 2], kind="scalar",
              expect={"huge": EITHER, "tiny": EITHER, "list": EITHER, "0d": EITHER},
              state=learner.state),
        Entry("sklearn.RLSRegressor.fit", "lam", lambda v: coef(SkRLS(lam=v).fit(HS, ZS)),
              0.98, kind="scalar", expect={"huge": ERROR, "tiny": WARNS, "list": EITHER}),
        Entry("sklearn.RLSRegressor.fit", "delta",
              lambda v: coef(SkRLS(delta=v).fit(HS, ZS)), 100.0, kind="scalar",
              expect={"huge": EITHER, "tiny": EITHER, "list": EITHER}),
        Entry("sklearn.RLSRegressor.fit", "X", lambda v: coef(SkRLS().fit(v, ZS)), HS,
              expect={"huge": WARNS, "tiny": EITHER, "bool": EITHER}),
        Entry("sklearn.RLSRegressor.fit", "y", lambda v: coef(SkRLS().fit(HS, v)), ZS,
              expect={"huge": EITHER, "tiny": EITHER, "bool": EITHER}),
        Entry("sklearn.RLSRegressor.partial_fit", "X",
              sk.call(lambda g, v: coef(g.partial_fit(v, ZS[10:]))), HS[10:],
              expect={"huge": WARNS, "tiny": EITHER, "bool": EITHER}, state=sk.state),
        Entry("sklearn.RLSRegressor.partial_fit", "y",
              sk.call(lambda g, v: coef(g.partial_fit(HS[10:], v))), ZS[10:],
              expect={"huge": EITHER, "tiny": EITHER, "bool": EITHER}, state=sk.state),
        Entry("sklearn.RLSRegressor.predict", "X", lambda v: sk.f.predict(v), HS[10:],
              expect={"huge": EITHER, "tiny": EITHER, "bool": EITHER}, state=sk.state),
    ]


ONLINE_ENTRIES = _online_entries() + _adapter_entries()
ONLINE_PARAMS = [pytest.param(e, kind, id=f"{e.name}-{e.arg}-{kind}",
                              marks=[pytest.mark.xfail(strict=True, reason=e.known[kind])]
                              if kind in e.known else [])
                 for e in ONLINE_ENTRIES
                 for kind in {"array": ARRAY_KINDS, "scalar": SCALAR_KINDS,
                              "int": INT_KINDS}[e.kind]]


@pytest.mark.parametrize("entry, kind", ONLINE_PARAMS)
def test_bad_input_catalogue_online(entry, kind):
    """#31's entry points: each bad value a clear error naming the argument (the
    estimator unchanged), or the documented outcome."""
    test_bad_input_catalogue(entry, kind)


def _best(u, y, na=range(1, 4)):
    with warnings.catch_warnings():      # advice that the best lies at an edge of the grid
        warnings.simplefilter("ignore", OrderSelectionWarning)
        return np.array(select_order(u, y, na=na, nb=range(1, 4), nk=[1]).best)


ENTRIES = [e for label, make in _filters().items() for e in _filter_entries(label, make)]
ENTRIES += _arx_entries() + _bank_entries() + _family_entries() + _persistence_entries()
CASES = [(e, kind) for e in ENTRIES
         for kind in {"array": ARRAY_KINDS, "scalar": SCALAR_KINDS, "int": INT_KINDS}[e.kind]]
PARAMS = [pytest.param(e, kind, id=f"{e.name}-{e.arg}-{kind}",
                       marks=[pytest.mark.xfail(strict=True, reason=e.known[kind])]
                       if kind in e.known else [])
          for e, kind in CASES]


# ----------------------------------------------------------------------
# the test
# ----------------------------------------------------------------------
def _expected(entry, kind):
    if kind in entry.expect:
        return entry.expect[kind]
    return {"scalar": SCALAR_DEFAULT, "int": INT_DEFAULT}.get(entry.kind, DEFAULT)[kind]


def _equal(a, b, rtol=0.0):
    a = a if isinstance(a, tuple) else (a,)
    b = b if isinstance(b, tuple) else (b,)
    assert len(a) == len(b)
    for x, y in zip(a, b):
        if rtol:
            assert_allclose(np.asarray(x, float), np.asarray(y, float), rtol=rtol,
                            atol=rtol * np.abs(np.asarray(y, float)).max())
        else:
            assert_array_equal(x, y)


@pytest.mark.parametrize("entry, kind", PARAMS)
def test_bad_input_catalogue(entry, kind):
    value = _variants(entry)[kind]
    expected = _expected(entry, kind)
    before = entry.state() if entry.state else None
    try:
        result = entry.run(value)
    except NumericalWarning as exc:
        assert expected == WARNS, f"warned ({exc!r}); expected {expected}"
        if before is not None:
            assert entry.state() == before, "a call that warned changed the state"
        return
    except (ValueError, TypeError, MemoryError) as exc:
        assert expected in (ERROR, EITHER, WARNS), f"refused ({exc!r}); expected {expected}"
        assert f"`{entry.arg}" in str(exc), f"the message does not name `{entry.arg}`: {exc}"
        if before is not None:
            assert entry.state() == before, "a rejected call changed the state"
        return
    assert expected != ERROR, f"accepted {kind} {entry.arg}; expected a clear error"
    if expected == SAME:
        _equal(result, entry.run(entry.good))
    elif expected == AS_FLOAT:
        _equal(result, entry.run(_as_float(value)))
    elif isinstance(expected, tuple):                       # scaled(f)
        s = HUGE if kind == "huge" else TINY
        _equal(result, expected[1](entry.run(entry.good), s), rtol=1e-9)


def test_every_kind_has_an_outcome():
    """The table is complete: every case resolves to one of the outcome classes."""
    for entry, kind in CASES:
        assert _expected(entry, kind) in (ERROR, SAME, AS_FLOAT, EITHER, OK, WARNS) or \
            _expected(entry, kind)[0] == "scaled"


def test_arx_accepts_numpy_scalar_sampling_periods():
    """``ARX(dt=np.float32(0.1))`` failed later inside python-control."""
    model = ARX(2, 2, dt=np.float32(0.1)).fit(U, Y)
    assert model.to_tf().dt == float(np.float32(0.1))
    assert model.to_ss().dt == float(np.float32(0.1))
    assert model.to_dict()["dt"] == float(np.float32(0.1))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_from_tf_refuses_non_finite_coefficients(bad):
    import control

    for G in (control.tf([1.0, bad], [1.0, -0.5], 0.1), control.tf([1.0], [1.0, bad], 0.1)):
        with pytest.raises(ValueError, match="`G` must have finite coefficients"):
            ARX.from_tf(G)


def test_sliding_window_missing_sample_downdates_the_oldest():
    """What ``SlidingWindowRLS.update`` documents: once the window is full a missing
    sample adds nothing but the oldest sample still leaves, so the estimate becomes
    least squares on the samples left in the window."""
    w = 12
    sw = SlidingWindowRLS(3, w)
    sw.initialize(ZS[:w], HS[:w])
    x_full = sw.x.copy()
    sw.predict()
    sw.update(None, HS[w])
    assert not np.array_equal(sw.x, x_full)
    theta = np.linalg.lstsq(HS[1:w], ZS[1:w], rcond=None)[0]
    assert_allclose(sw.x[:, 0], theta, rtol=1e-9)
    assert sw.n_samples == w


@pytest.mark.slow
def test_no_input_array_is_written_in_a_fresh_process():
    """In a fresh process (every kernel called with read-only arrays: numba's variants
    for them, compiled there or loaded from the disk cache an earlier process wrote,
    the same machine code), read-only arrays and memory from ``np.frombuffer(bytes)``
    go through every entry point of every filter unchanged, and assigning ``x`` then
    stepping leaves the caller's array as it was. The process shares the kernel cache
    of the run (an empty one cost 1,192 s of compiling and checked nothing more)."""
    job = r"""
import numpy as np
from rlsfilt import RecursiveLeastSquares as RLS, SlidingWindowRLS as SW, SquareRootRLS as SR
rng = np.random.default_rng(0)
Hs_w = rng.standard_normal((12, 3)); zs_w = Hs_w @ [1.0, 2.0, 3.0]
Hs = np.frombuffer(Hs_w.tobytes()).reshape(12, 3); zs = np.frombuffer(zs_w.tobytes())
H = np.frombuffer(np.array([1.0, 2.0, 3.0]).tobytes())
x0 = np.zeros(3); x0.flags.writeable = False
X = np.full((3, 1), 0.5)
for make in (lambda: RLS(3, x0=x0), lambda: RLS(3, lam=0.9, forgetting="directional"),
             lambda: RLS(3, lam=0.95, Q=1e-4), lambda: SR(3, lam=0.9, x0=x0),
             lambda: SW(3, 6, x0=x0)):
    f = make()
    f.x = X
    for k in range(4):
        f.predict(); f.update(zs[k], H)
        f.predict_update(np.frombuffer(np.array([2.0]).tobytes()), Hs[k])
    f.batch_filter(zs, Hs); f.batch_filter(zs, Hs, store_covariances=False)
    f.batch_filter(zs, Hs, Rs=np.frombuffer(np.ones(12).tobytes()), update_first=True)
    f.initialize(zs, Hs)
    f.x = X.reshape(-1, 1)
    f.predict(); f.update(1.0, H)
assert np.array_equal(X, np.full((3, 1), 0.5)) and np.array_equal(x0, np.zeros(3))
assert np.array_equal(Hs, Hs_w) and np.array_equal(zs, zs_w)
print("ok")
"""
    env = {**os.environ, "PYTHONPATH": ROOT}
    env.pop("NUMBA_DISABLE_JIT", None)
    proc = subprocess.run([sys.executable, "-c", job], env=env, capture_output=True, text=True,
                          timeout=1200)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().endswith("ok")


# ----------------------------------------------------------------------
# the second audit (#27): records
# ----------------------------------------------------------------------
def _frame(columns, n=12):
    rng = np.random.default_rng(27)
    return pd.DataFrame(rng.standard_normal((n, len(columns))), columns=columns)


RECORD_CASES = {
    "duplicated column names": (
        lambda: IOData.from_dataframe(_frame(["u", "y", "y"]), inputs="u", outputs="y"),
        ValueError, "`outputs`"),
    "missing experiment label": (
        lambda: IOData.from_dataframe(
            _frame(["u", "y"], 6).assign(e=["a", "a", None, "b", "b", "b"]),
            inputs="u", outputs="y", experiment="e"),
        ValueError, "`experiment`"),
    "NaN experiment label": (
        lambda: IOData.from_dataframe(
            _frame(["u", "y"], 6).assign(e=[1.0, 1.0, np.nan, 2.0, 2.0, 2.0]),
            inputs="u", outputs="y", experiment="e"),
        ValueError, "row 2"),
    "an experiment picked twice": (
        lambda: IOData([U[:50], U[50:100]], [Y[:50], Y[50:100]]).getexp([0, 0]),
        ValueError, "`which`"),
    "one name for an input and an output": (
        lambda: IOData(U, Y, input_names=["flow"], output_names=["flow"]),
        ValueError, "`input_names` and `output_names`"),
}


@pytest.mark.parametrize("case", list(RECORD_CASES))
def test_record_cases_give_clear_errors(case):
    run, error, words = RECORD_CASES[case]
    with pytest.raises(error, match=re.escape(words)):
        run()


def test_integer_column_labels_are_read():
    df = pd.DataFrame({0: U, 1: Y})
    data = IOData.from_dataframe(df, inputs=0, outputs=[1])
    assert data.input_names == ("0",) and data.output_names == ("1",)
    assert_array_equal(data.u, U)
    assert_array_equal(data.y, Y)


@pytest.mark.parametrize("index", [
    pd.date_range("2026-01-01", periods=N, freq="80ms"),
    pd.timedelta_range(0, periods=N, freq="80ms"),
])
def test_a_time_index_gives_the_sampling_period(index):
    data = IOData.from_dataframe(pd.DataFrame({"u": U, "y": Y}, index=index), "u", "y")
    assert data.dt == pytest.approx(0.08, rel=1e-12)


# ----------------------------------------------------------------------
# the second audit (#27): the fleets in the table
# ----------------------------------------------------------------------
def _fleet_entries():
    """`fit_many` (least squares and recursive): three channels of the table's record
    (each channel its own input), the estimates one row per channel."""
    from rlsfilt import fit_many

    C = 3
    us = np.column_stack([np.roll(U, 7 * c) for c in range(C)])
    ys = np.column_stack([lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], us[:, c])
                          + 0.1 * np.roll(Y - lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], U), c)
                          for c in range(C)])
    b_scaled = scaled(lambda r, s: r * np.array([1.0, 1.0, s, s]))         # y * s: b * s
    b_inverse = scaled(lambda r, s: r * np.array([1.0, 1.0, 1 / s, 1 / s]))
    # scale-invariant over the double range as ARX.fit is (#18 item 7, #27): each channel
    # runs in its power-of-two units
    entries = []
    for method in ("ls", "rls"):
        def run(u, y, method=method):
            return fit_many(ARX(2, 2), u, y, method=method, residual_tests=False).theta_.copy()
        entries += [
            Entry(f"fit_many(method={method!r})", "u", lambda v, run=run: run(v, ys), us,
                  expect={"huge": b_inverse, "tiny": b_inverse}),
            Entry(f"fit_many(method={method!r})", "y", lambda v, run=run: run(us, v), ys,
                  expect={"huge": b_scaled, "tiny": b_scaled}),
        ]
    for p in ("lam", "Q"):                   # (as ARX.fit's entries of the tune, #30)
        def tuned(u, y, p=p):
            return fit_many(ARX(2, 2), u, y, method="rls", residual_tests=False,
                            **{p: "tune"}).theta_.copy()
        tiny = OK if p == "lam" else ERROR
        entries += [
            Entry(f"fit_many(method='rls', {p}='tune')", "u",
                  lambda v, tuned=tuned: tuned(v, ys), us, expect={"huge": OK, "tiny": tiny}),
            Entry(f"fit_many(method='rls', {p}='tune')", "y",
                  lambda v, tuned=tuned: tuned(us, v), ys, expect={"huge": OK, "tiny": tiny}),
        ]
    return entries


FLEET_ENTRIES = _fleet_entries()
FLEET_PARAMS = [pytest.param(e, kind, id=f"{e.name}-{e.arg}-{kind}",
                             marks=[pytest.mark.xfail(strict=True, reason=e.known[kind])]
                             if kind in e.known else [])
                for e in FLEET_ENTRIES for kind in ARRAY_KINDS]


@pytest.mark.parametrize("entry, kind", FLEET_PARAMS)
def test_bad_input_catalogue_fleets(entry, kind):
    test_bad_input_catalogue(entry, kind)


# ----------------------------------------------------------------------
# the second audit (#27): the command line reads its CSV files
# ----------------------------------------------------------------------
def _long_csv(labels=("a", "b"), n=80, extra=None):
    """A long-format record, one row per sample: channel, input, output (and a notes
    column, whose row 5 holds `extra`)."""
    rng = np.random.default_rng(27)
    lines = ["ch,u,y,notes"]
    for c, label in enumerate(labels):
        u = rng.standard_normal(n)
        y = lfilter([0, 1.0 + c], [1, -0.5], u) + 0.01 * rng.standard_normal(n)
        lines += [f"{label},{float(a)!r},{float(b)!r}," for a, b in zip(u, y)]
    if extra is not None:
        lines[5] += extra
    return "\n".join(lines) + "\n"


_MANY = ["identify-many", "{path}", "-c", "ch", "-u", "u", "-y", "y", "--na", "1", "--nb", "1",
         "--no-residual-tests", "-q", "--format", "json"]
_ONE = ["identify", "{path}", "-u", "u", "-y", "y", "--na", "1", "--nb", "1", "--json"]
_LONG = "1" * 140_000                   # a number of 140,000 digits: over csv's 131,072


def _long_cell(text, line, column):
    """`text` with the cell of `line` (0: the header) and `column` replaced by `_LONG`."""
    lines = text.split("\n")
    fields = lines[line].split(",")
    fields[column] = _LONG
    lines[line] = ",".join(fields)
    return "\n".join(lines)


#: name -> (file bytes, command line, fragments of the one-line error); exit status 1
CLI_CASES = {
    "a field over 131,072 characters (identify)": (
        _long_cell(_long_csv(("a",)), 1, 1).encode(), _ONE,
        ["line 2 (data row 1), column 'u'", "140,000 characters"]),
    "a field over 131,072 characters (identify-many)": (
        _long_cell(_long_csv(), 81, 1).encode(), _MANY,
        ["column 'u', data row 81", "140,000 characters"]),
    "a file that is not UTF-8 (identify-many)": (
        _long_csv().encode().replace(b"\na,", b"\n\xff\xfe,", 1), _MANY,
        ["is not a UTF-8 text file"]),
    "an unclosed quote (identify-many)": (
        _long_csv().encode() + b'b,"1,2,\n', _MANY, ["cannot be read as CSV"]),
}


def _cli(argv, path, capsys):
    from rlsfilt.cli import main

    status = main([a.format(path=path) for a in argv])
    out, err = capsys.readouterr()
    return status, out, err


@pytest.mark.parametrize("case", list(CLI_CASES))
def test_cli_cases_give_one_line_errors(case, tmp_path, capsys):
    import csv

    content, argv, fragments = CLI_CASES[case]
    path = tmp_path / "record.csv"
    path.write_bytes(content)
    status, _, err = _cli(argv, path, capsys)
    assert status == 1, err
    assert err.startswith("rlsfilt: error: ") and err.count("\n") == 1, err
    for words in fragments:
        assert words in err, err
    assert len(err) < 400                      # the long cell is not printed
    assert csv.field_size_limit() == 131_072   # the csv module's limit is put back


@pytest.mark.parametrize("argv", [_ONE, _MANY], ids=["identify", "identify-many"])
@pytest.mark.parametrize("variant", ["byte order mark", "a long cell in an unread column"])
def test_cli_reads_what_it_should(variant, argv, tmp_path, capsys):
    """A UTF-8 byte order mark (spreadsheets write one) and a cell over csv's limit in a
    column the command does not read give the numbers of the plain file."""
    labels = ("a",) if argv is _ONE else ("a", "b")
    plain, other = tmp_path / "plain.csv", tmp_path / "other.csv"
    plain.write_text(_long_csv(labels), encoding="utf-8")
    if variant == "byte order mark":
        other.write_text(_long_csv(labels), encoding="utf-8-sig")
        assert other.read_bytes().startswith(b"\xef\xbb\xbf")
    else:
        other.write_text(_long_csv(labels, extra="x" * 140_000), encoding="utf-8")
    results = []
    for path in (plain, other):
        status, out, err = _cli(argv, path, capsys)
        assert status == 0, err
        results.append(json.loads(out))
    if argv is _ONE:
        assert results[1]["theta"] == results[0]["theta"]
    else:
        assert results[1] == results[0]


def test_cli_channels_named_like_missing_values(tmp_path, capsys):
    """Channels "NA", "None", "null" (pandas' missing-value markers) are three channels."""
    labels = ("NA", "None", "null")
    path = tmp_path / "record.csv"
    path.write_text(_long_csv(labels))
    status, out, err = _cli(_MANY, path, capsys)
    assert status == 0, err
    rows = json.loads(out)
    assert [r["channel"] for r in rows] == list(labels)
    assert_allclose([r["b1"] for r in rows], [1.0, 2.0, 3.0], atol=0.01)


# ----------------------------------------------------------------------
# the second audit (#27): the model family, the regulators, structure selection
# ----------------------------------------------------------------------
def _collinear(make, second):
    """`make()` fitted to two inputs, the second `second(u)`."""
    u = U.copy()
    return make().fit(np.column_stack([u, second(u)]), Y)


def _to_kalman(noise_variance, model=None):
    from rlsfilt.adaptive import to_kalman
    return to_kalman(MODEL if model is None else model, noise_variance=noise_variance)


def _two_outputs():
    rng = np.random.default_rng(27)
    y2 = np.column_stack([Y, lfilter([0, 0.5], [1, -0.3], U) + 0.1 * rng.standard_normal(N)])
    return ARX(1, 1).fit(U, y2)


def _gmv(**kw):
    from rlsfilt.adaptive import generalized_minimum_variance
    return generalized_minimum_variance([1, -0.9], [0, 1, 1.5], **kw)


def _recursive_ar_batch_with_u():
    from rlsfilt.models import RecursiveAR
    return RecursiveAR(2).batch(Y, U)


def _select_structure(grid, **kw):
    from rlsfilt import select_structure
    return select_structure(OE, U, Y, grid, **kw)


#: name -> (call, error class, words the message holds)
FAMILY_CASES = {
    **{f"{name} on two exactly collinear inputs": (
        lambda make=make: _collinear(make, lambda u: 2.0 * u), ValueError,
        "`u` is not persistently exciting for these orders, or two of its inputs are collinear")
       for name, make in (("OE", lambda: OE([2, 2], [2, 2], [1, 1])),
                          ("BJ", lambda: BJ([2, 2], 1, 1, [2, 2], [1, 1])),
                          ("ARMAX", lambda: ARMAX(2, [2, 2], 1, [1, 1])))},
    "OE on an input and its delayed copy": (
        lambda: _collinear(lambda: OE([2, 2], [2, 2], [1, 1]), lambda u: np.r_[0.0, u[:-1]]),
        ValueError, "rank 3 < sum(nb) = 4"),
    "OE(method='rpem') on two collinear inputs": (
        lambda: OE([1, 1], [1, 1], [1, 1]).fit(np.column_stack([U, -U]), Y, method="rpem"),
        ValueError, "two of its inputs are collinear"),
    "to_kalman(noise_variance=-1)": (lambda: _to_kalman(-1), ValueError,
                                     "`noise_variance` must be a positive variance; got -1"),
    "to_kalman(noise_variance=0)": (lambda: _to_kalman(0.0), ValueError, "`noise_variance`"),
    "to_kalman(noise_variance='1')": (lambda: _to_kalman("1"), TypeError, "`noise_variance`"),
    "to_kalman with an indefinite covariance": (
        lambda: _to_kalman([[1.0, 2.0], [2.0, 1.0]], _two_outputs()), ValueError,
        "`noise_variance` must be positive definite; got smallest eigenvalue -1"),
    "to_kalman with an asymmetric covariance": (
        lambda: _to_kalman([[1.0, 0.5], [0.0, 1.0]], _two_outputs()), ValueError,
        "`noise_variance` must be a symmetric (2, 2) covariance"),
    "generalized_minimum_variance(Q=-1)": (lambda: _gmv(Q=-1.0), ValueError,
                                           "`Q` must have Q(0) >= 0"),
    "RecursiveAR.batch(y, u)": (_recursive_ar_batch_with_u, ValueError,
                                "`u` must be omitted: RecursiveAR has no input"),
    "select_structure with 10^6 candidates": (
        lambda: _select_structure({"nb": range(1, 101), "nf": range(1, 101),
                                   "nk": range(100)}),
        ValueError, "`grid` gives 1,000,000 candidate structures (100 nb x 100 nf x 100 nk "
                    "values)"),
    "select_structure with a long list of structures": (
        lambda: _select_structure([{"nb": 1, "nf": 1}] * 20_000), ValueError,
        "`grid` gives 20,000 candidate structures"),
    "select_structure with an endless generator": (
        lambda: _select_structure({"nb": 1, "nf": 1} for _ in itertools.count()),
        ValueError, "`grid` gives more than 10,000 candidate structures"),
    "select_structure(max_candidates=1.5)": (
        lambda: _select_structure({"nb": [1], "nf": [1]}, max_candidates=1.5), TypeError,
        "`max_candidates` must be an integer"),
}


@pytest.mark.parametrize("case", list(FAMILY_CASES))
def test_family_cases_give_clear_errors(case):
    run, error, words = FAMILY_CASES[case]
    with pytest.raises(error, match=re.escape(words)):
        run()


def test_refused_collinear_fit_and_input_leave_the_state():
    """A refused fit keeps the model's previous fit; a refused batch the recursion's state."""
    from rlsfilt.models import RecursiveAR

    model = OE([2, 2], [2, 2], [1, 1]).fit(np.column_stack([U, np.roll(U, 17)]), Y)
    theta = model.theta_.copy()
    with pytest.raises(ValueError, match="collinear"):
        model.fit(np.column_stack([U, 3.0 * U]), Y)
    assert_array_equal(model.theta_, theta)
    ar = RecursiveAR(2)
    ar.batch(Y[:50])
    before = pickle.dumps(ar)
    with pytest.raises(ValueError, match="`u`"):
        ar.batch(Y[50:], U[50:])
    assert pickle.dumps(ar) == before
    assert ar.n_steps == 50


def test_select_structure_fits_a_large_grid_when_told():
    """The count comes first; `max_candidates` lifts the bound (and the result is the same)."""
    grid = {"nb": [1, 2], "nf": [1, 2], "nk": [1]}
    with pytest.raises(ValueError, match="`grid` gives 4 candidate structures"):
        _select_structure(grid, max_candidates=3)
    assert _select_structure(grid, max_candidates=4).best == _select_structure(grid).best


def test_to_kalman_takes_positive_variances():
    model = _two_outputs()
    for value, Sigma in ((2.0, 2.0 * np.eye(2)), ([1.0, 3.0], np.diag([1.0, 3.0])),
                         ([[2.0, 0.5], [0.5, 1.0]], np.array([[2.0, 0.5], [0.5, 1.0]]))):
        assert_array_equal(_to_kalman(value, model).Q[-2:, -2:], Sigma)
