r"""Recursive least squares as a river regressor: :class:`RLSRegressor`.

Install with ``pip install "rlsfilt[river]"``; ``import rlsfilt`` never
imports river, only ``import rlsfilt.river`` does.

:class:`RLSRegressor` is a :class:`~rlsfilt.RecursiveLeastSquares` filter
behind river's online-learning interface: features come as a dict per
sample, are discovered as they appear (a new feature enters with the
prior), and ``predict_one(x, with_dist=True)`` returns the predictive
distribution, a Gaussian whose variance is the filter's innovation variance
``S = H P H^T + R``. One step costs O(n^2) for n features, with or without
forgetting (river's ``BayesianLinearRegression`` inverts the whole matrix
at every step when it forgets).

Examples
--------
>>> from rlsfilt.river import RLSRegressor
>>> model = RLSRegressor(lam=0.99)
>>> for t in range(200):
...     x = {"u": t % 7 - 3.0, "v": (t * 3) % 5 - 2.0}
...     model.learn_one(x, 0.5 * x["u"] - 2.0 * x["v"] + 1.0)
>>> round(model.predict_one({"u": 1.0, "v": 1.0}), 6)
-0.5
>>> dist = model.predict_one({"u": 1.0, "v": 1.0}, with_dist=True)
>>> round(dist.mu, 6), round(dist.sigma, 2)     # the noise variance R = 1 dominates
(-0.5, 1.01)
"""

import numbers

import numpy as np

try:
    from river import base, proba
except ImportError as exc:  # pragma: no cover - exercised without river only
    raise ImportError('rlsfilt.river needs river: pip install "rlsfilt[river]"') from exc

from ._validation import COVARIANCE_MAX, check_bool, check_lam, check_real, check_variance
from .filters.rls import RecursiveLeastSquares

__all__ = ["RLSRegressor"]


class RLSRegressor(base.Regressor):
    r"""Recursive least squares with river's ``learn_one``/``predict_one``.

    Parameters
    ----------
    lam : float, default 1.0
        Forgetting factor in (0, 1]: the weight of a sample decays like
        ``lam ** age`` (memory about ``1 / (1 - lam)`` samples), for drifting
        targets.
    delta : float, default 1e4
        Prior variance of every weight (``P0 = delta I``, MATLAB's ``rarx``
        default); a feature seen for the first time enters with weight 0 and
        this variance, uncorrelated with the others.
    R : float, default 1.0
        Variance of the noise on the target: the predictive variance is
        ``H P H^T + R``. With ``lam = 1`` the model is river's
        ``BayesianLinearRegression(alpha=1 / delta, beta=1 / R)`` (its `alpha`
        is the prior precision).
    intercept : bool, default True
        Learn an intercept (the weight of a constant feature, with the same
        prior).

    Features that appear together in one sample take their places in sorted
    order (of their names as text), so the model does not depend on the order
    of the keys of `x`: shuffled dicts give the same numbers, bit for bit.

    Attributes
    ----------
    weights : dict
        The current weight of every feature seen (a new dict).
    filter : RecursiveLeastSquares or None
        The filter behind the model (None before the first ``learn_one``):
        its ``x`` holds the intercept first (if any), then the features in
        the order they appeared (sorted within a sample).

    See Also
    --------
    rlsfilt.RecursiveLeastSquares : the filter behind it.
    rlsfilt.sklearn.RLSRegressor : the same recursion with scikit-learn's API.

    Notes
    -----
    One ``learn_one(x, y)`` is the filter's ``predict()`` then
    ``update(y, H)`` with the row :math:`H` of the features' values (0 for
    a known feature absent from `x`):

    .. math::

        P^- = P / \lambda, \quad S = H P^- H^T + R, \quad K = P^- H^T / S,
        \quad \theta \leftarrow \theta + K (y - H \theta),
        \quad P \leftarrow P^- - K S K^T.

    ``predict_one(x, with_dist=True)`` gives :math:`\mathcal{N}(H\theta, S)`
    with the :math:`S` the next ``learn_one`` of the same `x` will use; a
    feature never learned adds ``0`` to the mean and ``delta * value**2`` to
    the variance (its prior). With ``lam = 1`` a feature that appears late
    gives the same numbers as a filter that had it from the start with value
    0 (the update leaves an uncorrelated, unexcited weight untouched); with
    ``lam < 1`` the late feature starts at ``delta`` rather than
    ``delta / lam**t``.

    References
    ----------
    Ljung, L. (1999). *System Identification: Theory for the User*, 2nd ed.,
    section 11.2. Prentice Hall.

    Examples
    --------
    >>> from rlsfilt.river import RLSRegressor
    >>> model = RLSRegressor(delta=1e8, intercept=False)
    >>> model.learn_one({"a": 1.0}, 2.0)
    >>> model.learn_one({"a": 2.0, "b": 1.0}, 5.0)    # "b" appears
    >>> {k: round(w, 6) for k, w in model.weights.items()}
    {'a': 2.0, 'b': 1.0}
    """

    def __init__(self, lam: float = 1.0, delta: float = 1e4, R: float = 1.0,
                 intercept: bool = True):
        self.lam = lam
        self.delta = delta
        self.R = R
        self.intercept = intercept
        self._lam = check_lam(lam, "lam")
        self._delta = _check_delta(delta)
        self._R = check_variance(R, "R")
        self._offset = int(check_bool(intercept, "intercept"))
        self._index = {}        # feature name -> its column of H (after the intercept)
        self.filter = None

    @classmethod
    def _unit_test_params(cls):
        yield {}
        yield {"lam": 0.98, "intercept": False}

    @property
    def weights(self):
        """The current weight of every feature seen, ``{name: weight}`` (a new dict)."""
        if self.filter is None:
            return {}
        x = self.filter.x[:, 0]
        return {f: float(x[i]) for f, i in self._index.items()}

    def learn_one(self, x, y):
        """Update the weights with one sample (the filter's ``predict`` and ``update``).

        Parameters
        ----------
        x : dict
            ``{feature name: number}``; a known feature absent from `x` counts as 0,
            a new one enters with the prior.
        y : float
            The target.
        """
        y = check_real(y, "y")
        values = self._values(x)
        # features new in one sample enter in a fixed order, not the dict's: the state
        # (and every number after it) does not depend on the order of the keys
        new = sorted((f for f in values if f not in self._index), key=_feature_order)
        filt, index = self.filter, dict(self._index)    # a call that raises changes nothing
        try:
            if new or self.filter is None:
                if not self._grow(new):
                    return              # no intercept and no feature: nothing to learn
            H = np.zeros(self.filter.dim_x)
            H[:self._offset] = 1.0
            for f, v in values.items():
                H[self._index[f]] = v
            # P^- = P / lam; theta += K (y - H theta), P = P^- - K S K^T (undone if it raises)
            self.filter.predict_update(y, H)
        except BaseException:
            self.filter, self._index = filt, index
            raise

    def predict_one(self, x, with_dist=False):
        """The prediction ``H theta`` for the features `x`, or its distribution.

        Parameters
        ----------
        x : dict
            ``{feature name: number}``; a feature never learned contributes 0.
        with_dist : bool, default False
            Return the predictive distribution: a ``river.proba.Gaussian`` with
            mean ``H theta`` and variance ``S = H P^- H^T + R`` (the innovation
            variance the next ``learn_one`` of `x` will have), plus ``delta`` times
            the squares of the values of features never learned.

        Returns
        -------
        float or river.proba.Gaussian
        """
        values = self._values(x)
        unseen = sum(v * v for f, v in values.items() if f not in self._index)
        if self.filter is None:
            mean, var = 0.0, self._delta * (unseen + self._offset) + self._R
        else:
            H = np.zeros(self.filter.dim_x)
            H[:self._offset] = 1.0
            for f, v in values.items():
                i = self._index.get(f)
                if i is not None:
                    H[i] = v
            mean = float(H @ self.filter.x[:, 0])
            if not with_dist:
                return mean
            _, P_prior = self.filter.get_prediction()          # P^- = P / lam
            var = float(H @ P_prior @ H) + self._R + self._delta * unseen
        if not with_dist:
            return mean
        # river's BayesianLinearRegression builds its predictive Gaussian the same way
        return proba.Gaussian._from_state(n=1, m=mean, var=var, ddof=0)

    # ------------------------------------------------------------------
    def _values(self, x):
        """`x`'s values as floats (a new dict), with a message naming a bad one."""
        out = {}
        for f, v in x.items():
            if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real):
                raise TypeError(f"`x[{f!r}]` must be a real number; got {v!r}")
            out[f] = float(v)
            if not np.isfinite(out[f]):
                raise ValueError(f"`x[{f!r}]` must be finite; got {out[f]}")
        return out

    def _grow(self, new):
        """Give the features `new` their columns: weight 0, variance `delta`, no
        correlation (a new filter carrying the old one's state). False if the
        model would have no parameter at all."""
        n = self._offset + len(self._index) + len(new)
        if n == 0:
            return False
        filt = RecursiveLeastSquares(n, lam=self._lam, P0=self._delta, R=self._R)
        if self.filter is not None:
            state = self.filter.get_state()
            m = self.filter.dim_x
            x = np.zeros((n, 1))
            x[:m] = state["x"]
            P = self._delta * np.eye(n)
            P[:m, :m] = state["P"]
            state.update(x=x, P=P)
            filt.set_state(state)
        for f in new:
            self._index[f] = self._offset + len(self._index)
        self.filter = filt
        return True


def _check_delta(delta):
    """The prior variance `delta` of a weight: positive, finite, at most
    ``COVARIANCE_MAX`` (the filter's covariance update multiplies two of them)."""
    delta = check_real(delta, "delta", minimum=0, strict=True)
    if delta > COVARIANCE_MAX:
        raise ValueError(f"`delta` must be at most {COVARIANCE_MAX:.0e} (the covariance update "
                         f"multiplies two prior variances); got {delta}")
    return delta


def _feature_order(name):
    """Sort key of feature names of any (mixed) types."""
    return type(name).__name__, str(name)
