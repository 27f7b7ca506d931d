"""Streaming change detection on every channel of an `RLSBank`, in one compiled call per step.

`BankChangeDetector` is `ChangeDetector` run on each channel of a bank: the
same statistics (CUSUM, Page-Hinkley, GLR) on the normalized innovations
``bank.y / sqrt(bank.S)``, the same thresholds, the same alarms, bit for bit,
and the action applied to the alarmed channels only. Its step is one numba
call over the channels (``_kernels_detection.py``); the actions run in
Python, only on a step that alarmed.
"""

import numpy as np

from .._lazy import lazy_module
from .._validation import as_float_array, check_int
from .detection import _settings

__all__ = ["BankChangeDetector"]

_kernels = lazy_module("rlsfilt.validation._kernels_detection")
_METHOD_CODES = {"cusum": 0, "page_hinkley": 1, "glr": 2}
_FLOAT = np.dtype(np.float64)


class BankChangeDetector:
    r"""One `ChangeDetector` per channel of an `RLSBank`, run together.

    Parameters
    ----------
    n_channels : int
        Number of channels ``C`` (that of the bank).
    method : {"cusum", "page_hinkley", "glr"}, default "cusum"
        The test, as in :class:`ChangeDetector`.
    arl, shift, window, threshold
        As in :class:`ChangeDetector` (one threshold for every channel).
    action : {"none", "reset", "boost", "lambda"}, default "none"
        What :meth:`step` does to each alarmed channel of the bank, as
        `ChangeDetector` does to its filter: ``"reset"``:
        ``bank.reset(channels)`` (those channels back to their ``x0``,
        ``P0``); ``"boost"``: their ``P <- boost * P``; ``"lambda"``: their
        ``lam <- alarm_lam`` for the next `hold` samples, then their own
        ``lam`` back. The other channels are not touched.
    boost, alarm_lam, hold
        As in :class:`ChangeDetector`.

    Attributes
    ----------
    threshold, drift, window : float, float, int
        As in :class:`ChangeDetector`.
    g_plus, g_minus : ndarray, shape (C,)
        The statistics of every channel now (zero after its alarm).
    n_samples : ndarray of int, shape (C,)
        Innovations each channel has seen since :meth:`reset` (its missing
        ones, NaN ``y``, not counted).
    alarms : list of list of int
        ``alarms[c]``: the indices (counted in channel ``c``'s innovations
        seen) of its samples that raised an alarm, as `ChangeDetector.alarms`.
    n_steps : int
        Calls of :meth:`update` (or :meth:`step`) since :meth:`reset`.

    Notes
    -----
    Every channel runs the recursion of :class:`ChangeDetector` (see there
    for the statistics and their thresholds) with the same arithmetic in the
    same order, so channel ``c`` alarms exactly when a `ChangeDetector` fed
    ``bank.y[c]``, ``bank.S[c]`` would, and the actions leave channel ``c``
    of the bank exactly where that detector's action leaves a
    `RecursiveLeastSquares` that runs as the channel (tested against
    per-channel runs). The state of the GLR is ``C * window`` numbers; a
    step costs :math:`O(C)` for CUSUM and Page-Hinkley, :math:`O(C M)` for
    the GLR (``benchmarks/bench_detect.py``).

    Examples
    --------
    Two of three channels whose bias jumps at sample 200:

    >>> import numpy as np
    >>> from rlsfilt import RLSBank
    >>> from rlsfilt.validation import BankChangeDetector
    >>> rng = np.random.default_rng(1)
    >>> H = np.stack([np.ones((400, 3)), rng.standard_normal((400, 3))], axis=-1)
    >>> z = H[..., 0] + 0.5 * H[..., 1] + 0.1 * rng.standard_normal((400, 3))
    >>> z[200:, :2] += 0.5
    >>> bank = RLSBank(3, 2, R=0.01)
    >>> det = BankChangeDetector(3, "glr", arl=10_000, action="boost")
    >>> for k in range(400):
    ...     bank.predict_update(z[k], H[k])
    ...     _ = det.step(bank)
    >>> [det.alarms[c][0] for c in (0, 1)]    # the first alarm of the two that jumped
    [200, 200]
    """

    def __init__(self, n_channels, method="cusum", *, arl=1000.0, shift=1.0, window=100,
                 threshold=None, action="none", boost=1e3, alarm_lam=0.9, hold=20):
        self.n_channels = check_int(n_channels, "n_channels", minimum=1)
        (self.method, self.threshold, self.drift, self.window, self.action, self.boost,
         self.alarm_lam, self.hold) = _settings(method, arl, shift, window, threshold, action,
                                                boost, alarm_lam, hold)
        kernels = _kernels()
        self._consts = kernels.constants(_METHOD_CODES[self.method], self.drift,
                                         self.threshold, self.window)
        self._detect, self._glr_statistics = kernels.bank_detect, kernels.glr_statistics
        self._shape = (self.n_channels,)
        self._held = None
        self.reset()

    def reset(self):
        """Forget everything seen, in every channel. Temporary forgetting factors
        (``action="lambda"``) still in force end: their channels get their own
        ``lam`` back."""
        if self._held is not None:
            bank, own, left = self._held
            bank.lam = np.where(left > 0, own, bank.lam)
        self._held = None
        C, glr = self.n_channels, self.method == "glr"
        self._fstate = np.zeros((4, C))
        self._istate = np.zeros((3, C), dtype=np.int64)
        self._istate[1] = -1
        self._recent = np.zeros((self.window, C) if glr else (1, 1))
        self._bounds = np.zeros((2, int(self._consts[3]), C if glr else 1))
        self._state = (self._consts, self._fstate, self._istate, self._recent, self._bounds)
        self.alarms = [[] for _ in range(C)]
        self.n_steps = 0

    def _statistics(self):
        if self.method != "glr":
            return self._fstate[:2].copy()
        out = np.empty((2, self.n_channels))
        self._glr_statistics(self._istate, self._recent, self._consts, out)
        return out

    @property
    def g_plus(self):
        """:math:`g^+` of every channel, shape (C,) (for the GLR computed from its
        window when read)."""
        return self._statistics()[0]

    @property
    def g_minus(self):
        """:math:`g^-` of every channel, shape (C,)."""
        return self._statistics()[1]

    @property
    def statistic(self):
        """``max(g_plus, g_minus)`` of every channel, shape (C,)."""
        return self._statistics().max(axis=0)

    @property
    def n_samples(self):
        """Innovations seen by each channel since :meth:`reset`, shape (C,)."""
        return self._istate[0].copy()

    def update(self, y, S):
        """Feed one innovation per channel with its variance; return the alarms.

        Parameters
        ----------
        y, S : array_like, shape (C,)
            The bank's ``y`` and ``S`` after its update; a NaN in `y` skips
            that channel.

        Returns
        -------
        ndarray of bool, shape (C,)
            Which channels alarmed.
        """
        shape = self._shape
        if not (type(y) is np.ndarray and type(S) is np.ndarray and y.shape == shape
                and S.shape == shape and y.dtype == _FLOAT and S.dtype == _FLOAT
                and y.flags.c_contiguous and S.flags.c_contiguous):
            y, S = self._vectors(y, S)                   # (the bank's own y, S pass as they are)
        alarm = np.empty(shape, dtype=np.bool_)
        n = self._detect(y, S, *self._state, alarm)
        if n < 0:
            c = -n - 1
            raise ValueError(f"`S` must be a positive finite variance; got {S[c]} for "
                             f"channel {c}")
        self.n_steps += 1
        self._n_new = n
        if n:
            seen = self._istate[0]
            for c in np.flatnonzero(alarm):
                self.alarms[c].append(int(seen[c]) - 1)
        return alarm

    def _vectors(self, y, S):
        """`y` and `S` as contiguous float64 arrays of shape ``(C,)``, or an error."""
        C = self.n_channels
        y = np.ascontiguousarray(as_float_array(y, "y"), dtype=np.float64)
        S = np.ascontiguousarray(as_float_array(S, "S"), dtype=np.float64)
        if y.shape != (C,) or S.shape != (C,):
            raise ValueError(f"`y` and `S` must have shape ({C},) (one per channel); got "
                             f"{y.shape} and {S.shape}")
        return y, S

    def step(self, bank):
        """:meth:`update` with ``bank.y`` and ``bank.S`` (call it after each
        ``bank.update``), and apply the action to the alarmed channels; returns
        the alarms, shape (C,)."""
        alarm = self.update(bank.y, bank.S)              # (first: a bad S changes nothing)
        if self._held is not None:                       # the holds count every sample
            held_bank, own, left = self._held
            left = left - 1
            ending = left == 0
            if ending.any():
                held_bank.lam = np.where(ending, own, held_bank.lam)
            self._held = (held_bank, own, left) if (left > 0).any() else None
        if not self._n_new or self.action == "none":
            return alarm
        if self.action == "reset":
            bank.reset(alarm)
        elif self.action == "boost":
            P = bank.P.copy(order="F")
            P[alarm] = self.boost * P[alarm]
            bank.P = P
        else:                                            # "lambda"
            lam = bank.lam
            if self._held is None:
                own, left = lam, np.zeros(self.n_channels, dtype=np.int64)
            else:
                _, own, left = self._held
                own = np.where(left > 0, own, lam)       # (a channel still held keeps its own)
            self._held = (bank, own, np.where(alarm, self.hold, left))
            bank.lam = np.where(alarm, self.alarm_lam, lam)
        return alarm

    def run(self, ys, Ss):
        """Feed a record, ``(N, C)`` innovations and variances; returns the alarms,
        a boolean array ``(N, C)`` (no action: the record is past). Same numbers as
        :meth:`update` row by row."""
        ys = as_float_array(ys, "ys")
        Ss = as_float_array(Ss, "Ss")
        if ys.ndim != 2 or ys.shape != Ss.shape or ys.shape[1] != self.n_channels:
            raise ValueError(f"`ys` and `Ss` must both have shape (N, {self.n_channels}); "
                             f"got {ys.shape} and {Ss.shape}")
        return np.array([self.update(y, s) for y, s in zip(ys, Ss, strict=True)],
                        dtype=bool).reshape(ys.shape)

    def __repr__(self):
        k = f", M={self.window}" if self.method == "glr" else f", k={self.drift:.4g}"
        return (f"<BankChangeDetector {self.method}: {self.n_channels} channels, "
                f"h={self.threshold:.4g}{k}, {sum(map(len, self.alarms))} alarm(s) "
                f"in {self.n_steps} steps>")

