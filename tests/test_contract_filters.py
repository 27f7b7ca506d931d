"""The contract every filter keeps (see ``tests/contract.py``).

``FILTERS`` is the registry: one line per filter configuration, a factory
``make(dim_x, dim_z=1, **kw)`` (``kw``: ``x0``, ``P0``, ``R``,
``check_every``, ``cond_max``) and, where least squares is its oracle, the
weights of the samples (oldest first) that its estimate after ``initialize``
equals weighted least squares with. ``CHECKS`` is the list of checks; each
runs on every registered filter:

- least squares: without forgetting the estimate after ``initialize`` is
  ordinary least squares on all data so far (``numpy.linalg.lstsq``), with
  forgetting it is weighted least squares with the filter's weights
  (``lam**age``, or the sliding window), at every step, to 1e-9;
- a filterpy ``Saver`` records the same states as the filter produces;
- no caller array is ever written (read-only inputs everywhere, and arrays
  assigned to ``x`` and ``P`` stay as they were);
- assigning ``x``, ``P`` or ``R`` copies: the caller's array can change
  afterwards without changing the filter (#18 item 1);
- a rejected input (``ValueError``/``TypeError``) leaves the state
  bit-identical;
- the audit's bad arguments (complex ``R`` or ``P0``, ``P0 = 1e308``,
  ``R = 'a'``, ``batch_filter(None, Hs)``, ``saver=1``,
  ``update_first='no'``, ...) are a ``ValueError``/``TypeError`` naming the
  argument, and change nothing (#18 items 6 and 8);
- a warning turned into an error (``warnings.simplefilter("error")``: the
  health warning, ``ForgettingSkippedWarning``) leaves the state
  bit-identical, from every entry point (#18 item 4);
- ``copy.copy``, ``copy.deepcopy`` and a pickle round trip resume bit for
  bit like the original;
- streaming ``predict``/``update`` equals ``batch_filter`` bit for bit;
- the health warning points at the caller's line, from ``update``,
  ``predict_update`` and ``batch_filter`` (with and without a ``Saver``);
- ``as_iosystem`` (the python-control system every filter inherits) steps
  as the filter streamed (#26: the example filter's inherited system failed).

`RLSBank` and `GradientBank` are registered through `BankAdapter` and
`GradientBankAdapter`: a bank of ``len(SCALES)``
channels fed the contract's single-channel record, channel ``c`` with its
measurements scaled by ``SCALES[c]`` (powers of two, so every channel is
channel 0 times its scale, bit for bit, and differs from the others). The
checks read channel 0 in the filter's shapes; ``_same_state`` also compares
every channel of the two banks, and the least-squares check every channel
against its scaled oracle. Assigning ``x``, ``P``, ``R`` or ``Q`` sets every
channel; arguments the adapter cannot translate (None, text, complex) reach
the bank unchanged, so the bad-argument check reads the bank's own messages,
and the warning-turned-error check the bank's own atomicity. In a bank a NaN
in a regressor is missing data (that channel skips the step), not an error,
so the calls of the rejected-input check that pass one are not made on a bank.
"""

import copy
import inspect
import pickle
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pytest
from contract import parametrize_with_checks
from example_filter import NLMS
from filterpy.common import Saver
from numpy.testing import assert_allclose, assert_array_equal

from rlsfilt import (
    APA,
    LMS,
    ForgettingSkippedWarning,
    GradientBank,
    NumericalWarning,
    RecursiveLeastSquares,
    RLSBank,
    SignDataLMS,
    SignErrorLMS,
    SignSignLMS,
    SlidingWindowRLS,
    SquareRootRLS,
)
from rlsfilt import NLMS as GradientNLMS

N, DIM_X = 120, 3
K0 = 6                                   # samples of the batch start
STATE = ("x", "P", "x_prior", "P_prior", "x_post", "P_post", "y", "K", "S", "SI", "z", "H")


@dataclass(frozen=True)
class FilterCase:
    """One registered filter configuration."""

    name: str
    make: Callable
    weights: Callable = None     # weights(n) of least squares after initialize, or None
    nan_regressor_is_missing: bool = False   # a NaN in H skips the step (a bank), not an error


SCALES = np.array([1.0, -2.0, 0.5])      # measurement scale of each channel of BankAdapter
BANK_STATE = STATE[:-2] + ("z", "H", "lam_t")


def _real(value):
    """Whether the adapter can translate `value` (real numbers, array-like). Anything
    else (None, text, complex) goes to the bank as it is, so that the bank's own
    validation names its argument."""
    try:
        return np.asarray(value).dtype.kind in "biuf"
    except (TypeError, ValueError):      # ragged sequences
        return False


class _ChannelsAdapter:
    """A bank of ``len(SCALES)`` channels behind the single filter's interface
    (`BankAdapter` for `RLSBank`, `GradientBankAdapter` for `GradientBank`).

    Every call is forwarded to the bank (which validates it): a measurement
    ``z`` becomes ``z * SCALES`` (one per channel), a regressor row is
    given to every channel, a noise variance or random walk is shared, and
    an assigned ``x`` or ``P`` becomes every channel's. Arguments the
    adapter cannot translate (None, text, complex values) reach the bank
    unchanged, so the errors are the bank's and name the bank's arguments.
    The attributes the checks read are channel 0's, in the shapes of
    `RecursiveLeastSquares` (``x`` is ``(dim_x, 1)``, ``y`` is ``(1, 1)``,
    ``R`` is a float); ``bank`` is the bank.
    """

    # the forwarded calls: every channel gets the same regressor, scaled measurements
    @staticmethod
    def _z(z):
        """Measurements of a record, ``(N,)``, as ``(N, C)``."""
        if not _real(z):
            return z
        return np.multiply.outer(np.asarray(z, dtype=float).reshape(-1), SCALES)

    @staticmethod
    def _one_z(z):
        """One measurement as ``(C,)`` (several: passed on for the bank to refuse)."""
        if not _real(z):
            return z
        z = np.asarray(z, dtype=float)
        return z.reshape(()) * SCALES if z.size == 1 else np.multiply.outer(z, SCALES)

    @staticmethod
    def _H(H):
        if not _real(H):
            return H
        H = np.asarray(H)
        return np.broadcast_to(H.reshape(-1), (len(SCALES), H.size))

    @staticmethod
    def _shared(value):
        """A single variance (a float or a (1, 1) array) as the bank's shared scalar."""
        return np.asarray(value).reshape(()) if _real(value) and np.size(value) == 1 else value

    def update(self, z, H, R=None):
        self.bank.update(self._one_z(z), self._H(H), self._shared(R))

    def predict_update(self, z, H, R=None):
        self.bank.predict_update(self._one_z(z), self._H(H), self._shared(R))

    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True):
        C = len(SCALES)
        if _real(Hs) and np.ndim(Hs) == 2:
            Hs = np.asarray(Hs)
            Hs = np.broadcast_to(Hs[:, None, :], (Hs.shape[0], C, Hs.shape[-1]))
        if _real(Rs) and np.ndim(Rs) == 1:
            Rs = np.broadcast_to(np.asarray(Rs, dtype=float)[:, None], (len(Rs), C))
        h = self.bank.batch_filter(self._z(zs), Hs, Rs, update_first, saver=saver,
                                   store_covariances=store_covariances)
        self.history = h
        means, covs, means_p, covs_p = (None if a is None else a[:, 0] for a in h)
        return means[..., None], covs, means_p[..., None], covs_p

    def initialize(self, zs, Hs):
        if _real(Hs) and np.ndim(Hs) == 2:
            Hs = np.asarray(Hs)
            Hs = np.broadcast_to(Hs[:, None, :], (Hs.shape[0], len(SCALES), Hs.shape[-1]))
        self.bank.initialize(self._z(zs), Hs)

    def update_block(self, Z, H, R=None):
        C = len(SCALES)
        if _real(H) and np.ndim(H) == 2:
            H = np.asarray(H)
            H = np.broadcast_to(H[:, None, :], (H.shape[0], C, H.shape[-1]))
        if _real(R) and np.ndim(R) == 1:
            R = np.broadcast_to(np.asarray(R, dtype=float)[:, None], (len(R), C))
        assert self.bank.update_block(self._z(Z), H, R) is self.bank
        return self

    def copy(self):
        return copy.deepcopy(self)

    # the adaptation switch and the state, forwarded
    frozen = property(lambda self: self.bank.frozen)

    @property
    def adapt(self):
        return self.bank.adapt

    @adapt.setter
    def adapt(self, value):
        self.bank.adapt = value

    def freeze(self):
        assert self.bank.freeze() is self.bank
        return self

    def unfreeze(self):
        assert self.bank.unfreeze() is self.bank
        return self

    state_names = BANK_STATE            # what `_same_state` compares in every channel

    def get_state(self):
        """Every channel's ``x``, ``P``, counters and ``lam_t`` (copies)."""
        b = self.bank
        return {"x": b.x.copy(), "P": b.P.copy(), "n_updates": int(b.n_updates),
                "n_capped": b.n_capped.copy(), "lam_t": b.lam_t.copy()}

    # assignment: the same value for every channel (the bank stores its own copy)
    @property
    def x(self):
        return self.bank.x[0][:, None]

    @x.setter
    def x(self, value):
        if _real(value):
            value = np.asarray(value).reshape(-1)
            value = np.broadcast_to(value, (len(SCALES), value.size))
        self.bank.x = value

    @property
    def R(self):
        return float(self.bank.R[0])

    @R.setter
    def R(self, value):
        self.bank.R = self._shared(value)


def _channel0(name, view):
    """A property: the bank's attribute `name`, channel 0, in the filter's shape
    (a property, so that filterpy's Saver records it)."""
    return property(lambda self: view(getattr(self.bank, name)))


for _name, _view in [
        *[(n, lambda v: v[0][:, None]) for n in ("x_prior", "x_post", "K")],
        ("log_likelihood", lambda v: v[0]),
        *[(n, lambda v: np.full((1, 1), v[0])) for n in ("y", "z", "S", "SI")],
        ("H", lambda v: v[0][None, :]), ("n_updates", lambda v: v)]:
    setattr(_ChannelsAdapter, _name, _channel0(_name, _view))


class BankAdapter(_ChannelsAdapter):
    """An `RLSBank` of ``len(SCALES)`` channels (see `_ChannelsAdapter`), with ``P``
    and ``Q`` (assigned: every channel's)."""

    def __init__(self, dim_x, x0=None, **kw):
        self.bank = RLSBank(len(SCALES), dim_x, x0=x0, **kw)

    def predict(self, Q=None):
        self.bank.predict(Q)

    @property
    def P(self):
        return self.bank.P[0]

    @P.setter
    def P(self, value):
        if _real(value) and np.ndim(value) == 2:
            value = np.broadcast_to(value, (len(SCALES),) + np.shape(value))
        self.bank.P = value

    @property
    def Q(self):
        return self.bank.Q[0]

    @Q.setter
    def Q(self, value):
        self.bank.Q = value


for _name in ("P_prior", "P_post"):
    setattr(BankAdapter, _name, _channel0(_name, lambda v: v[0]))


class GradientBankAdapter(_ChannelsAdapter):
    """A `GradientBank` of ``len(SCALES)`` channels (see `_ChannelsAdapter`): no
    covariance (``has_covariance = False``: the checks skip ``P``), no ``Q``."""

    has_covariance = False
    least_squares = False
    state_names = ("x", "x_prior", "x_post", "y", "K", "S", "SI", "z", "H")

    def __init__(self, dim_x, x0=None, **kw):
        self.bank = GradientBank(len(SCALES), dim_x, x0=x0, **kw)

    def predict(self):
        self.bank.predict()

    def get_state(self):
        return self.bank.get_state()


def _ones(n):
    return np.ones(n)


def _exponential(lam):
    return lambda n: lam ** np.arange(n - 1, -1, -1.0)


def _window(w):
    return lambda n: (np.arange(n) >= n - w).astype(float)


def _constrained(**kw):
    f = RecursiveLeastSquares(DIM_X, lam=0.97, forgetting="directional", gate=50.0, Q=1e-6, **kw)
    return f.constrain([1.0, 0.0, 1.0], 0.5)


FILTERS = [
    FilterCase("RecursiveLeastSquares", lambda **kw: RecursiveLeastSquares(DIM_X, **kw), _ones),
    FilterCase("RecursiveLeastSquares-lam0.95",
               lambda **kw: RecursiveLeastSquares(DIM_X, lam=0.95, **kw), _exponential(0.95)),
    FilterCase("RecursiveLeastSquares-Q",
               lambda **kw: RecursiveLeastSquares(DIM_X, lam=0.98, Q=1e-4, **kw)),
    FilterCase("RecursiveLeastSquares-directional",
               lambda **kw: RecursiveLeastSquares(DIM_X, lam=0.95, forgetting="directional",
                                                  **kw)),
    FilterCase("RecursiveLeastSquares-constant_trace",
               lambda **kw: RecursiveLeastSquares(DIM_X, lam=0.95, forgetting="constant_trace",
                                                  **kw)),
    FilterCase("RecursiveLeastSquares-efra",
               lambda **kw: RecursiveLeastSquares(DIM_X, lam=0.95, forgetting="efra", **kw)),
    FilterCase("RecursiveLeastSquares-variable",
               lambda **kw: RecursiveLeastSquares(DIM_X, lam=0.95, forgetting="variable", **kw)),
    FilterCase("RecursiveLeastSquares-diagonal",
               lambda **kw: RecursiveLeastSquares(DIM_X, lam=[0.99, 0.9, 1.0], Q=1e-6,
                                                  forgetting="diagonal", **kw)),
    FilterCase("RecursiveLeastSquares-gate-constrained", _constrained),
    FilterCase("SquareRootRLS", lambda **kw: SquareRootRLS(DIM_X, **kw), _ones),
    FilterCase("SquareRootRLS-lam0.97", lambda **kw: SquareRootRLS(DIM_X, lam=0.97, **kw),
               _exponential(0.97)),
    FilterCase("SlidingWindowRLS-window1000", lambda **kw: SlidingWindowRLS(DIM_X, 1000, **kw),
               _ones),
    FilterCase("SlidingWindowRLS-window40", lambda **kw: SlidingWindowRLS(DIM_X, 40, **kw),
               _window(40)),
    FilterCase("NLMS-example", lambda **kw: NLMS(DIM_X, **kw)),
    FilterCase("LMS", lambda **kw: LMS(DIM_X, mu=0.02, **kw)),
    FilterCase("LMS-leaky", lambda **kw: LMS(DIM_X, mu=0.02, leak=0.1, **kw)),
    FilterCase("NLMS", lambda **kw: GradientNLMS(DIM_X, mu=0.5, eps=0.01, **kw)),
    FilterCase("SignErrorLMS", lambda **kw: SignErrorLMS(DIM_X, mu=0.01, **kw)),
    FilterCase("SignDataLMS", lambda **kw: SignDataLMS(DIM_X, mu=0.01, **kw)),
    FilterCase("SignSignLMS", lambda **kw: SignSignLMS(DIM_X, mu=0.01, **kw)),
    FilterCase("APA-order3", lambda **kw: APA(DIM_X, order=3, mu=0.5, eps=0.01, **kw)),
    FilterCase("RLSBank", lambda **kw: BankAdapter(DIM_X, **kw), _ones, True),
    FilterCase("RLSBank-lam0.95", lambda **kw: BankAdapter(DIM_X, lam=0.95, **kw),
               _exponential(0.95), True),
    FilterCase("RLSBank-directional-Q",
               lambda **kw: BankAdapter(DIM_X, lam=0.95, Q=1e-4, forgetting="directional",
                                        **kw), None, True),
    FilterCase("RLSBank-constant_trace",
               lambda **kw: BankAdapter(DIM_X, lam=0.95, forgetting="constant_trace", **kw),
               None, True),
    FilterCase("GradientBank-nlms",
               lambda **kw: GradientBankAdapter(DIM_X, mu=0.5, eps=0.01, **kw), None, True),
    FilterCase("GradientBank-lms-leaky",
               lambda **kw: GradientBankAdapter(DIM_X, mu=0.02, method="lms", leak=0.1, **kw),
               None, True),
    FilterCase("GradientBank-sign_sign",
               lambda **kw: GradientBankAdapter(DIM_X, mu=0.01, method="sign_sign", **kw),
               None, True),
]


def _record(seed=0, n=N, outliers=True):
    """Regressors of a well-excited plant and its noisy outputs (one gross outlier)."""
    rng = np.random.default_rng(seed)
    Hs = rng.standard_normal((n, DIM_X))
    zs = Hs @ np.array([0.7, -0.3, -0.2]) + 0.05 * rng.standard_normal(n)
    if outliers:
        zs[n // 2] += 100.0
    return zs, Hs


def _frozen(*arrays):
    out = []
    for a in arrays:
        a = np.array(a, dtype=float)
        a.setflags(write=False)
        out.append(a)
    return out


def _has_P(f):
    """The filter keeps a covariance ``P`` and checks its health (the contract's
    ``has_covariance``; the bank's adapter does)."""
    return getattr(f, "has_covariance", True)


def _state(f):
    """Everything the filter holds, as bytes (equal bytes: a bit-identical state)."""
    return pickle.dumps(f)


def _same_state(a, b):
    for name in STATE if _has_P(a) else [n for n in STATE if not n.startswith("P")]:
        assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    assert a.n_updates == b.n_updates
    if isinstance(a, _ChannelsAdapter):       # every channel, not only the one the checks read
        for name in a.state_names:
            assert_array_equal(getattr(a.bank, name), getattr(b.bank, name), err_msg=name)


# ----------------------------------------------------------------------
# the checks
# ----------------------------------------------------------------------
def check_least_squares(case):
    """After ``initialize`` the estimate is weighted least squares on all data so far."""
    if case.weights is None:
        pytest.skip("no least-squares oracle for this configuration")
    zs, Hs = _record(outliers=False)
    f = case.make()
    f.initialize(zs[:K0], Hs[:K0])
    means, *_ = f.batch_filter(zs[K0:], Hs[K0:])
    g = case.make()
    g.initialize(zs[:K0], Hs[:K0])
    for k in range(K0, N):
        g.predict_update(zs[k], Hs[k])
        assert_array_equal(g.x, means[k - K0])
    for k in range(K0, N, 7):
        w = np.sqrt(case.weights(k + 1))
        theta, *_ = np.linalg.lstsq(Hs[:k + 1] * w[:, None], zs[:k + 1] * w, rcond=None)
        assert_allclose(means[k - K0, :, 0], theta, rtol=1e-9, atol=1e-12, err_msg=str(k))
        if isinstance(f, _ChannelsAdapter):   # channel c: measurements and estimate times SCALES[c]
            assert_allclose(f.history.means[k - K0], SCALES[:, None] * theta, rtol=1e-9,
                            atol=1e-12, err_msg=str(k))


def check_saver_round_trip(case):
    """filterpy's Saver records the filter's states, step by step and in batch_filter."""
    zs, Hs = _record()
    f = case.make()
    saver = Saver(f)
    xs, Ps, ys = [], [], []
    for k in range(40):
        f.predict_update(zs[k], Hs[k])
        saver.save()
        xs.append(f.x.copy())
        if _has_P(f):
            Ps.append(f.P.copy())
        ys.append(f.y.copy())
    saver.to_array()
    assert len(saver) == 40
    assert_array_equal(saver.x, np.array(xs))
    if _has_P(f):
        assert_array_equal(saver.P, np.array(Ps))
    assert_array_equal(saver.y, np.array(ys))
    g = case.make()
    batch_saver = Saver(g)
    means, covs, _, _ = g.batch_filter(zs[:40], Hs[:40], saver=batch_saver)
    batch_saver.to_array()
    assert_array_equal(batch_saver.x, means)
    if _has_P(g):
        assert_array_equal(batch_saver.P, covs)
    assert_array_equal(means, np.array(xs))


def check_no_caller_array_is_written(case):
    """Read-only inputs everywhere; arrays assigned to ``x`` and ``P`` keep their values."""
    zs, Hs = _record()
    x0, P0 = _frozen(np.full(DIM_X, 0.1), 50.0 * np.eye(DIM_X))
    zf, Hf, Rs, R = _frozen(zs, Hs, np.full(N, 0.5), 0.5)
    keep = [a.copy() for a in (x0, P0, zf, Hf, Rs, R)]
    f = case.make(x0=x0, P0=P0) if _has_P(case.make()) else case.make(x0=x0)
    f.initialize(zf[:K0], Hf[:K0])
    for k in range(K0, 30):
        f.predict_update(zf[k:k + 1], Hf[k], R)
        f.predict()
        f.update(zf[k], Hf[k:k + 1], R)
    f.batch_filter(zf[30:60], Hf[30:60], Rs=Rs[30:60])
    f.batch_filter(zf[60:90], Hf[60:90], Rs=Rs[60:90], update_first=True,
                   store_covariances=False)
    X, P = np.full((DIM_X, 1), 0.2), 20.0 * np.eye(DIM_X)
    f.x = X.reshape(-1, 1)                   # a view of the caller's array (#18 item 1)
    if _has_P(f):
        f.P = P
    for k in range(90, N):
        f.predict()
        f.update(zs[k], Hs[k])
    f.x = X
    f.batch_filter(zs[90:], Hs[90:])
    for before, after in zip(keep, (x0, P0, zf, Hf, Rs, R), strict=True):
        assert_array_equal(after, before)
    assert_array_equal(X, 0.2)
    assert_array_equal(P, 20.0 * np.eye(DIM_X))


def check_rejected_input_leaves_the_state_unchanged(case):
    """A call that raises ValueError or TypeError changes nothing."""
    zs, Hs = _record()
    f = case.make()
    f.batch_filter(zs[:20], Hs[:20])
    f.predict_update(zs[20], Hs[20])
    bad_H = Hs[21].copy()
    bad_H[1] = np.nan
    nan_H = [
        lambda: f.update(1.0, bad_H),
        lambda: f.predict_update(1.0, bad_H),
        lambda: f.batch_filter(zs[:5], np.where(np.eye(5, DIM_X) > 0, np.nan, Hs[:5])),
    ]
    calls = [
        lambda: f.update(1.0, bad_H),
        lambda: f.update(np.inf, Hs[21]),
        lambda: f.update(1.0, Hs[21][:2]),
        lambda: f.update([1.0, 2.0], Hs[21]),
        lambda: f.update(1.0, Hs[21], R=-1.0),
        lambda: f.update(1.0, Hs[21], R=np.nan),
        lambda: f.update(1.0, "abc"),
        lambda: f.predict_update(1.0, bad_H),
        lambda: f.predict_update(np.inf, Hs[21]),
        lambda: f.predict_update(1.0, Hs[21], R=0.0),
        lambda: f.batch_filter(zs[:5], Hs[:4]),
        lambda: f.batch_filter(zs[:5], np.where(np.eye(5, DIM_X) > 0, np.nan, Hs[:5])),
        lambda: f.batch_filter(np.r_[zs[:4], np.inf], Hs[:5]),
        lambda: f.batch_filter(zs[:5], Hs[:5], Rs=[1.0, 1.0, -1.0, 1.0, 1.0]),
        lambda: f.initialize(zs[:5], np.ones((5, DIM_X))),          # rank-deficient
        lambda: f.initialize(zs[:5], Hs[:4]),
    ]
    if case.nan_regressor_is_missing:    # missing data in a bank (tested in test_bank.py)
        calls = [call for call in calls if call.__code__.co_code not in
                 {c.__code__.co_code for c in nan_H}]
    for i, call in enumerate(calls):
        before = _state(f)
        with pytest.raises((ValueError, TypeError)):
            call()
        assert _state(f) == before, f"call {i} changed the state"


def check_assignment_copies(case):
    """``f.x = X``, ``f.P = P``, ``f.R = R`` store copies: changing the caller's arrays
    afterwards changes nothing in the filter (as filterpy's users expect)."""
    zs, Hs = _record()
    f = case.make()
    f.batch_filter(zs[:20], Hs[:20])
    X, P, R = np.full((DIM_X, 1), 0.2), 20.0 * np.eye(DIM_X), np.array([[0.5]])
    f.x, f.R = X, R
    if _has_P(f):
        f.P = P
    X[:], P[:], R[:] = 7.0, 9.0, 3.0
    assert_array_equal(f.x, 0.2)
    if _has_P(f):
        assert_allclose(f.P, 20.0 * np.eye(DIM_X), rtol=1e-12)
    assert f.R == 0.5
    view = np.frombuffer(np.full(DIM_X, 0.1).tobytes())   # read-only memory of bytes
    f.x = view.reshape(-1, 1)
    f.predict_update(zs[20], Hs[20])
    f.batch_filter(zs[21:30], Hs[21:30])
    assert_array_equal(view, 0.1)


def check_bad_arguments_are_named(case):
    """The audit's bad arguments: a ValueError/TypeError naming the argument, and no
    change to a running filter."""
    zs, Hs = _record()
    constructions = [
        ("R", lambda: case.make(R=1.0 + 1.0j)),
        ("R", lambda: case.make(R="a")),
        ("P0", lambda: case.make(P0=np.eye(DIM_X) * (1.0 + 0.0j))),
        ("P0", lambda: case.make(P0=1e308)),
        ("x0", lambda: case.make(x0=np.full(DIM_X, 1.0j))),
    ]
    if not _has_P(case.make()):              # no covariance: no P0 to refuse
        constructions = [c for c in constructions if c[0] != "P0"]
    for name, call in constructions:
        with pytest.raises((ValueError, TypeError), match=f"`{name}`"):
            call()
    f = case.make()
    f.batch_filter(zs[:20], Hs[:20])
    calls = [
        ("zs", lambda: f.batch_filter(None, Hs[:5])),
        ("Hs", lambda: f.batch_filter(zs[:5], None)),
        ("saver", lambda: f.batch_filter(zs[:5], Hs[:5], saver=1)),
        ("update_first", lambda: f.batch_filter(zs[:5], Hs[:5], update_first="no")),
        ("store_covariances", lambda: f.batch_filter(zs[:5], Hs[:5], store_covariances=2)),
        ("R", lambda: f.update(zs[20], Hs[20], R="a")),
        ("R", lambda: f.update(zs[20], Hs[20], R=1.0 + 1.0j)),
        ("z", lambda: f.update(1.0j, Hs[20])),
        ("z", lambda: f.update("1.0", Hs[20])),
        ("H", lambda: f.update(zs[20], Hs[20] * 1.0j)),
        ("H", lambda: f.update(zs[20], "a")),           # (None: self.H, as filterpy)
        ("Rs", lambda: f.batch_filter(zs[:5], Hs[:5], Rs=np.full(5, 1.0j))),
    ]
    if "Q" in inspect.signature(f.predict).parameters:      # (every filter has a Q to read)
        calls += [("Q", lambda: f.predict(Q=1.0j)), ("Q", lambda: f.predict(Q=1e308))]
    for name, call in calls:
        before = _state(f)
        with pytest.raises((ValueError, TypeError), match=f"`{name}`"):
            call()
        assert _state(f) == before, name


def check_warning_turned_error_changes_nothing(case):
    """With ``warnings.simplefilter("error")`` a step whose warning becomes an exception
    leaves the filter bit-identical: the health warning from ``update``,
    ``predict_update`` and ``batch_filter`` (compiled and with a Saver), and
    ``ForgettingSkippedWarning`` from a second ``update`` without ``predict``."""
    zs, Hs = _record()
    has_P = _has_P(case.make())
    f = case.make(check_every=1, cond_max=1.0 + 1e-9) if has_P else None  # fails at once
    calls = [] if f is None else [lambda: f.update(zs[0], Hs[0]),
             lambda: f.predict_update(zs[0], Hs[0]),
             lambda: f.batch_filter(zs[:5], Hs[:5]),
             lambda: f.batch_filter(zs[:5], Hs[:5], store_covariances=False),
             lambda: f.batch_filter(zs[:5], Hs[:5], update_first=True),
             lambda: f.batch_filter(zs[:5], Hs[:5], saver=Saver(f))]
    if f is not None:
        f.predict()                                     # (predict itself checks nothing)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for i, call in enumerate(calls):
            before = _state(f)
            with pytest.raises(NumericalWarning):
                call()
            assert _state(f) == before, f"call {i} changed the state"
    g = case.make()
    g.predict()
    g.update(zs[0], Hs[0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        before = _state(g)
        try:
            g.update(zs[1], Hs[1])                  # no predict in between
        except ForgettingSkippedWarning:
            assert _state(g) == before
        else:                                       # nothing skipped: no warning is due
            assert not getattr(g, "forgets", False)


def _resume(case, copier):
    zs, Hs = _record()
    f = case.make()
    for k in range(50):
        f.predict_update(zs[k], Hs[k])
    g = copier(f)
    for other, first in ((f, True), (g, False)):
        for k in range(50, 80):
            other.predict()
            other.update(zs[k], Hs[k])
        if first:
            continue
    _same_state(f, g)
    f.batch_filter(zs[80:], Hs[80:])
    g.batch_filter(zs[80:], Hs[80:])
    _same_state(f, g)


def check_copy_resumes_bit_for_bit(case):
    """``copy.copy`` of a running filter continues exactly like the original."""
    zs, Hs = _record()
    f = case.make()
    for k in range(50):
        f.predict_update(zs[k], Hs[k])
    g = copy.copy(f)
    for k in range(50, 80):                  # interleaved: a shared array would show
        f.predict_update(zs[k], Hs[k])
        g.predict_update(zs[k], Hs[k])
        _same_state(f, g)
    f.batch_filter(zs[80:], Hs[80:])
    g.batch_filter(zs[80:], Hs[80:])
    _same_state(f, g)


def check_deepcopy_resumes_bit_for_bit(case):
    """``copy.deepcopy`` (and ``.copy()``) of a running filter continues exactly."""
    _resume(case, copy.deepcopy)
    _resume(case, lambda f: f.copy())


def check_pickle_resumes_bit_for_bit(case):
    """A pickle round trip of a running filter continues exactly."""
    _resume(case, lambda f: pickle.loads(pickle.dumps(f)))


def check_streaming_equals_batch(case):
    """``predict``/``update`` step by step equals ``batch_filter`` bit for bit."""
    zs, Hs = _record()
    zs[[3, 70]] = np.nan                     # missing samples
    Rs = np.random.default_rng(1).uniform(0.5, 2.0, N)
    for update_first in (False, True):
        a, b = case.make(), case.make()
        means, covs, means_p, covs_p = a.batch_filter(zs, Hs, Rs=Rs, update_first=update_first)
        for k in range(N):
            if not update_first:
                b.predict()
                assert_array_equal(b.x, means_p[k])
                if _has_P(b):
                    assert_array_equal(b.P, covs_p[k])
            b.update(zs[k], Hs[k], Rs[k])
            assert_array_equal(b.x, means[k])
            if _has_P(b):
                assert_array_equal(b.P, covs[k])
            if update_first:
                b.predict()
                if _has_P(b):
                    assert_array_equal(b.P, covs_p[k])
        _same_state(a, b)
        assert a.log_likelihood == b.log_likelihood


def check_health_warning_points_at_the_caller(case):
    """The warning names this file (the caller), from every entry point."""
    zs, Hs = _record()

    def run(how):
        # a condition number just above 1 fails the check at the first update
        f = case.make(check_every=1, cond_max=1.0 + 1e-9)
        with pytest.warns(NumericalWarning) as record:
            if how == "update":
                for k in range(5):
                    f.predict()
                    f.update(zs[k], Hs[k])
            elif how == "predict_update":
                for k in range(5):
                    f.predict_update(zs[k], Hs[k])
            else:
                f.batch_filter(zs[:5], Hs[:5], saver=Saver(f) if how == "saver" else None)
        assert len(record) == 1
        return record[0]

    if not _has_P(case.make()):
        pytest.skip("no covariance: no health check to warn")
    for how in ("update", "predict_update", "batch_filter", "saver"):
        warning = run(how)
        assert warning.filename == __file__, (how, warning.filename)


def check_freeze_keeps_the_state(case):
    """While frozen (``freeze()`` or ``adapt = False``) ``update`` gives the residual
    ``y = z - H x`` and ``S`` but ``x``, ``P`` and the state stay bit-unchanged, in
    ``predict``, ``update``, ``batch_filter`` and ``update_block``; after
    ``unfreeze()`` the filter continues bit for bit as one that never saw the frozen
    samples (MATLAB's ``EnableAdaptation``, #31)."""
    zs, Hs = _record()
    f = case.make()
    for k in range(30):
        f.predict_update(zs[k], Hs[k])
    g = copy.deepcopy(f)
    before = f.get_state()
    assert not f.frozen and f.adapt
    assert f.freeze() is f and f.frozen and not f.adapt
    for k in range(30, 50):
        f.predict()
        f.update(zs[k], Hs[k])
        assert_array_equal(f.y[:, 0], zs[k] - Hs[k] @ f.x)        # y = z - H x
        assert np.all(np.diag(f.S) > 0) and np.all(f.K == 0)
        assert pickle.dumps(f.get_state()) == pickle.dumps(before), k
    means, _, means_p, _ = f.batch_filter(zs[50:60], Hs[50:60])
    assert_array_equal(means, np.broadcast_to(f.x, means.shape))
    f.update_block(zs[60:70], Hs[60:70])
    f.update(None, Hs[70])                                          # missing: NaN residual
    assert np.isnan(f.y).all()
    assert pickle.dumps(f.get_state()) == pickle.dumps(before)
    f.adapt = True
    assert not f.frozen
    f.adapt = False
    assert f.frozen
    with pytest.raises(TypeError, match="`adapt`"):
        f.adapt = "no"
    f.unfreeze()
    for other in (f, g):
        for k in range(70, 90):
            other.predict_update(zs[k], Hs[k])
        other.batch_filter(zs[90:], Hs[90:])
    _same_state(f, g)
    assert pickle.dumps(f.get_state()) == pickle.dumps(g.get_state())


def check_update_block_equals_rows(case):
    """``update_block(Z, H, R)`` equals ``predict_update`` row by row bit for bit
    (frame-based input, #31), missing samples and per-row variances included, and
    leaves the diagnostics of the last row's update."""
    zs, Hs = _record()
    zs[[5, 44]] = np.nan
    Rs = np.random.default_rng(2).uniform(0.5, 2.0, N)
    a, b = case.make(), case.make()
    for lo, hi in ((0, 1), (1, 40), (40, 45), (45, N)):
        assert a.update_block(zs[lo:hi], Hs[lo:hi], Rs[lo:hi]) is a
        for k in range(lo, hi):
            b.predict_update(zs[k], Hs[k], Rs[k])
        _same_state(a, b)
        assert pickle.dumps(a.get_state()) == pickle.dumps(b.get_state())
        assert a.log_likelihood == b.log_likelihood
    a.update_block(zs[:10], Hs[:10], 0.7)                  # one variance for every row
    for k in range(10):
        b.predict_update(zs[k], Hs[k], 0.7)
    _same_state(a, b)
    before = _state(a)
    with pytest.raises(ValueError):
        a.update_block(zs[:5], Hs[:4])
    assert _state(a) == before


def check_as_iosystem_steps_like_the_filter(case):
    """A filter as a python-control system (``as_iosystem``, inherited from the base)
    steps as the filter does: its outputs ``theta`` and ``e`` over a record equal
    ``predict_update`` streamed on a twin (1e-12), and the filter itself is untouched.
    A bank is not a `contract.Filter` and has no system."""
    import control

    from rlsfilt.filters.contract import Filter

    f = case.make()
    if not isinstance(f, Filter):
        assert not hasattr(f, "as_iosystem"), case.name
        return
    zs, Hs = _record(outliers=False)
    zs, Hs = zs[:60], Hs[:60]
    before = pickle.dumps(f.get_state())
    sys = f.as_iosystem("direct")
    resp = control.input_output_response(sys, np.arange(len(zs)), np.vstack([zs, Hs.T]))
    twin, means, errors = case.make(), [], []
    for z, h in zip(zs, Hs, strict=True):
        errors.append(z - h @ twin.x[:, 0])
        twin.predict_update(z, h)
        means.append(twin.x[:, 0].copy())
    assert_allclose(resp.outputs[:DIM_X].T, means, rtol=0, atol=1e-12)
    assert_allclose(resp.outputs[DIM_X], errors, rtol=0, atol=1e-12)
    assert pickle.dumps(f.get_state()) == before


CHECKS = [
    check_least_squares,
    check_saver_round_trip,
    check_no_caller_array_is_written,
    check_assignment_copies,
    check_rejected_input_leaves_the_state_unchanged,
    check_bad_arguments_are_named,
    check_warning_turned_error_changes_nothing,
    check_copy_resumes_bit_for_bit,
    check_deepcopy_resumes_bit_for_bit,
    check_pickle_resumes_bit_for_bit,
    check_streaming_equals_batch,
    check_health_warning_points_at_the_caller,
    check_freeze_keeps_the_state,
    check_update_block_equals_rows,
    check_as_iosystem_steps_like_the_filter,
]

EXPECTED_FAILURES = {}


@parametrize_with_checks(FILTERS, CHECKS, EXPECTED_FAILURES)
def test_filter_contract(case, check):
    check(case)
