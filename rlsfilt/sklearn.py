r"""Recursive least squares as a scikit-learn estimator: :class:`RLSRegressor`.

Install with ``pip install "rlsfilt[sklearn]"``; ``import rlsfilt`` never
imports scikit-learn, only ``import rlsfilt.sklearn`` does.

:class:`RLSRegressor` is a :class:`~rlsfilt.RecursiveLeastSquares` filter
behind scikit-learn's estimator interface: ``fit`` runs the filter over the
rows from its prior, ``partial_fit`` continues from where the last call left
off (out-of-core learning, one chunk at a time), and it passes
``sklearn.utils.estimator_checks.check_estimator``, so it fits in pipelines,
grid searches and cross-validation.

Examples
--------
A static gain and an offset, learned in two chunks:

>>> import numpy as np
>>> from rlsfilt.sklearn import RLSRegressor
>>> rng = np.random.default_rng(0)
>>> X = rng.standard_normal((200, 2))
>>> y = X @ [0.5, -1.0] + 2.0 + 0.01 * rng.standard_normal(200)
>>> reg = RLSRegressor().partial_fit(X[:100], y[:100]).partial_fit(X[100:], y[100:])
>>> np.round(reg.coef_, 2), round(float(reg.intercept_), 2)
(array([ 0.5, -1. ]), 2.0)
"""

import numpy as np

try:
    from sklearn.base import BaseEstimator, RegressorMixin
    from sklearn.utils.validation import check_is_fitted, validate_data
except ImportError as exc:  # pragma: no cover - exercised without scikit-learn only
    raise ImportError('rlsfilt.sklearn needs scikit-learn >= 1.6: pip install "rlsfilt[sklearn]"'
                      ) from exc

from ._validation import COVARIANCE_MAX, check_bool, check_lam, check_real
from .filters.rls import RecursiveLeastSquares

__all__ = ["RLSRegressor"]


class RLSRegressor(RegressorMixin, BaseEstimator):
    r"""Recursive least squares with scikit-learn's ``fit``/``partial_fit``/``predict``.

    The coefficients are the estimate of a
    :class:`~rlsfilt.RecursiveLeastSquares` filter run over the rows of `X`
    in order (with an intercept: the column of ones appended last), so with
    ``lam = 1`` they are the ridge-regularized least-squares solution and,
    with ``lam < 1``, the exponentially weighted one (recent rows count more:
    tracking of slowly varying coefficients).

    Parameters
    ----------
    lam : float, default 1.0
        Forgetting factor in (0, 1]; ``1`` remembers every row equally.
    delta : float, default 1e4
        Prior variance of every coefficient (the filter's ``P0 = delta I``,
        MATLAB's ``rarx`` default); the estimate is shrunk towards zero by
        ``1 / delta``, so a large value is an almost flat prior.
    fit_intercept : bool, default True
        Estimate an intercept (a coefficient of a constant regressor, with
        the same prior).

    Attributes
    ----------
    coef_ : ndarray, shape (n_features,) or (n_targets, n_features)
        Coefficients (one row per target for a 2-D `y`).
    intercept_ : float or ndarray of shape (n_targets,)
        The intercept; ``0.0`` when ``fit_intercept=False``.
    filter_ : RecursiveLeastSquares
        The fitted filter (``x``, ``P``, ``S``, ... after the last row): the
        covariance of the coefficients is ``filter_.P`` scaled by the noise
        variance.
    n_features_in_ : int
        Number of features seen by ``fit``.
    feature_names_in_ : ndarray of str
        Names of the features, when `X` had string column names.
    n_samples_seen_ : int
        Number of rows learned since the last ``fit``.

    See Also
    --------
    rlsfilt.RecursiveLeastSquares : the filter behind it.
    rlsfilt.river.RLSRegressor : the same recursion with river's dict features.

    Notes
    -----
    With ``lam = 1`` and ``P_0 = \delta I`` the estimate after rows
    :math:`\Phi, Y` is

    .. math:: \hat\theta = (\Phi^T \Phi + I / \delta)^{-1} \Phi^T Y,

    and with ``lam < 1`` row :math:`k` of :math:`N` is weighted by
    :math:`\lambda^{N-k}` and the prior by :math:`\lambda^N` (Ljung 1999,
    section 11.2). ``fit`` is ``partial_fit`` from the prior; ``partial_fit``
    on consecutive chunks gives the same coefficients, bit for bit, as one
    ``fit`` on their concatenation.

    References
    ----------
    Ljung, L. (1999). *System Identification: Theory for the User*, 2nd ed.
    Prentice Hall.

    Examples
    --------
    >>> import numpy as np
    >>> from rlsfilt.sklearn import RLSRegressor
    >>> X = np.array([[0.0], [1.0], [2.0], [3.0]])
    >>> reg = RLSRegressor(delta=1e8).fit(X, [1.0, 3.0, 5.0, 7.0])
    >>> np.round(reg.predict([[4.0]]), 6)
    array([9.])
    """

    def __init__(self, lam=1.0, delta=1e4, fit_intercept=True):
        self.lam = lam
        self.delta = delta
        self.fit_intercept = fit_intercept

    def __sklearn_tags__(self):
        tags = super().__sklearn_tags__()
        tags.target_tags.multi_output = True      # one shared regressor, several outputs
        return tags

    def fit(self, X, y):
        """Run the filter over the rows of `X` from the prior.

        Parameters
        ----------
        X : array_like, shape (n_samples, n_features)
            Regressors, one row per sample, in time order.
        y : array_like, shape (n_samples,) or (n_samples, n_targets)
            Targets.

        Returns
        -------
        self : RLSRegressor
        """
        before = self.__dict__.copy()       # a fit that raises leaves the estimator as it was
        try:
            X, y = self._validated(X, y, reset=True)
            self._start(y)
            return self._learn(X, y)
        except BaseException:
            self.__dict__.clear()
            self.__dict__.update(before)
            raise

    def partial_fit(self, X, y):
        """Learn the rows of `X`, continuing from the previous call (or the prior).

        Parameters
        ----------
        X : array_like, shape (n_samples, n_features)
            Regressors; the same features as the first call.
        y : array_like, shape (n_samples,) or (n_samples, n_targets)
            Targets; the same number of targets as the first call.

        Returns
        -------
        self : RLSRegressor
        """
        first = not hasattr(self, "filter_")
        before = self.__dict__.copy()       # a call that raises leaves the estimator as it was
        try:
            X, y = self._validated(X, y, reset=first)
            if first:
                self._start(y)
            else:
                self._same_targets(y)
            return self._learn(X, y)
        except BaseException:
            self.__dict__.clear()
            self.__dict__.update(before)
            raise

    def _same_targets(self, y):
        """A later `partial_fit` takes the first call's number of targets."""
        if (y.ndim == 2) != self._multi or (y.ndim == 2 and y.shape[1] != self.filter_.dim_z):
            raise ValueError(f"`y` has shape {y.shape}; expected "
                             + (f"(n_samples, {self.filter_.dim_z})" if self._multi
                                else "(n_samples,)") + " as in the first partial_fit")

    def predict(self, X):
        """The predictions ``X coef_^T + intercept_``.

        Parameters
        ----------
        X : array_like, shape (n_samples, n_features)

        Returns
        -------
        ndarray, shape (n_samples,) or (n_samples, n_targets)
        """
        check_is_fitted(self)
        _no_dates(X, "X")
        try:
            X = validate_data(self, X, dtype=np.float64, reset=False)
        except (ValueError, TypeError) as exc:
            raise type(exc)(f"`X`: {exc}") from exc
        # C order: a DataFrame's (Fortran-ordered) rows give the bits of the same array's
        return np.ascontiguousarray(X) @ self.coef_.T + self.intercept_

    # ------------------------------------------------------------------
    def _validated(self, X, y, reset):
        """scikit-learn's checks of ``(X, y)``, with a message naming the argument."""
        _no_dates(X, "X")
        _no_dates(y, "y")
        try:
            return validate_data(self, X, y, dtype=np.float64, y_numeric=True,
                                 multi_output=True, reset=reset)
        except (ValueError, TypeError) as exc:
            raise type(exc)(f"{_culprit(X, y)}: {exc}") from exc

    def _start(self, y):
        """A new filter at the prior, for `y`'s number of targets."""
        lam = check_lam(self.lam, "lam")
        delta = check_real(self.delta, "delta", minimum=0, strict=True)
        if delta > COVARIANCE_MAX:
            raise ValueError(f"`delta` must be at most {COVARIANCE_MAX:.0e} (the covariance "
                             f"update multiplies two prior variances); got {delta}")
        check_bool(self.fit_intercept, "fit_intercept")
        self._multi = y.ndim == 2
        dim_z = y.shape[1] if self._multi else 1
        self.filter_ = RecursiveLeastSquares(self.n_features_in_ + bool(self.fit_intercept),
                                             dim_z, lam=lam, P0=delta)
        self.n_samples_seen_ = 0

    def _learn(self, X, y):
        """Run the filter over ``(X, y)`` (one compiled call) and read the coefficients."""
        H = np.hstack([X, np.ones((len(X), 1))]) if self.fit_intercept else X
        self.filter_.batch_filter(y, H, store_covariances=False)
        self.n_samples_seen_ += len(X)
        theta = self.filter_.x                                  # (dim_x, dim_z)
        coef = theta[:self.n_features_in_].T                    # (dim_z, n_features)
        intercept = theta[-1] if self.fit_intercept else np.zeros(theta.shape[1])
        self.coef_ = coef.copy() if self._multi else coef[0].copy()
        self.intercept_ = intercept.copy() if self._multi else float(intercept[0])
        return self


def _no_dates(a, name):
    """Dates and durations are not numbers (numpy would read them as counts of units)."""
    kind = getattr(getattr(a, "dtype", None), "kind", None)
    dtypes = getattr(a, "dtypes", [])             # a DataFrame's, one per column
    kinds = [getattr(t, "kind", None)
             for t in ([dtypes] if hasattr(dtypes, "kind") else dtypes)]
    if kind in ("M", "m") or any(k in ("M", "m") for k in kinds):
        raise TypeError(f"`{name}` must be numeric; got dates or durations")


def _culprit(X, y):
    """Which of `X`, `y` scikit-learn's combined check refused (both if each alone passes)."""
    from sklearn.utils import check_array

    for a, name, opts in ((X, "X", {}), (y, "y", {"ensure_2d": False})):
        try:
            check_array(a, dtype=np.float64, **opts)
        except (ValueError, TypeError):
            return f"`{name}`"
    return "`X`, `y`"
