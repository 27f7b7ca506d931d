r"""The smallest filter that keeps the filter contract: normalized LMS.

It is the proof of ``docs/develop.md`` ("Adding a filter"): one file that
subclasses the shared base, implements the abstract members of
`rlsfilt.filters.contract.Filter` and declares its capabilities, plus one
line in ``FILTERS`` of ``tests/test_contract_filters.py``, and the whole
contract runs on it. It has no covariance and is not least squares, so the
checks that need ``P`` or an ``lstsq`` oracle consult ``has_covariance`` and
``least_squares`` and leave those parts out.

.. math::

    y = z - H x, \qquad x \leftarrow x + \mu \frac{H^T y^T}{R + H H^T}

(Haykin 2002, ch. 6), with the noise variance ``R`` as the regularization.
"""

import numpy as np

from rlsfilt._validation import check_bool, check_real, check_variance
from rlsfilt.filters._base import _FilterBase
from rlsfilt.filters.contract import check_state

__all__ = ["NLMS"]


class NLMS(_FilterBase):
    """Normalized least-mean-squares filter with step size `mu` in (0, 2)."""

    has_covariance = False
    least_squares = False
    _options = _FilterBase._options | {"mu"}        # the settings it honours when assigned

    def __init__(self, dim_x, dim_z=1, mu=0.5, *, x0=None, R=1.0):
        self.dim_x, self.dim_z = dim_x, dim_z
        self.mu = check_real(mu, "mu", minimum=0, strict=True)
        self.R = R                                      # (no covariance: no health check)
        self._x0 = self._as_state(np.zeros((dim_x, dim_z)) if x0 is None else x0, "x0")
        self.reset()

    @property
    def x(self):
        """Estimate, ``(dim_x, dim_z)``; assigning copies the value."""
        return self._x

    @x.setter
    def x(self, value):
        self._x = self._as_state(value, "x")

    def predict(self):
        """No time update (a gradient filter has no state but ``x``)."""
        self.x_prior = self._x.copy()

    def update(self, z, H, R=None):
        """One normalized gradient step (a missing `z` changes nothing but ``z``)."""
        if self.frozen:                                 # adaptation off: only diagnostics
            return self._frozen_update(z, H, R)
        phi, r = self._as_regressor(H, "H"), self._R if R is None else check_variance(R, "R")
        zc = self._as_measurement(z, "z")
        self.H, self.n_updates = phi, self.n_updates + 1
        if zc is None:                                  # missing: posterior = prior
            self.x_post = self._x.copy()
            nan = np.full((self.dim_z, 1), np.nan)
            self.set_diagnostics(z=nan, y=nan.copy())
            return
        s = r + (phi @ phi.T).item()
        y = zc - (phi @ self._x).T                      # y = z - H x
        self.K = self.mu * phi.T / s                    # K = mu H^T / (R + H H^T)
        self._x = self._x + self.K @ y.T                # x <- x + K y^T
        self.x_post = self._x.copy()
        eye = np.eye(self.dim_z)
        self.set_diagnostics(z=zc, y=y, S=s * eye, SI=eye / s)   # S = (R + H H^T) I

    def initialize(self, zs, Hs):
        """Start from least squares on the given samples."""
        Z, Hm = self._as_batch(zs, Hs)
        keep = ~np.isnan(Z).any(axis=1)
        if np.linalg.matrix_rank(Hm[keep]) < self.dim_x:
            raise ValueError(f"`Hs` is rank-deficient: need {self.dim_x} independent rows")
        self._x = np.linalg.lstsq(Hm[keep], Z[keep], rcond=None)[0]
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()

    def batch_filter(self, zs, Hs, Rs=None, update_first=False, saver=None,
                     store_covariances=True):
        """`predict`/`update` over a record: ``(means, None, means_p, None)``."""
        check_bool(store_covariances, "store_covariances")     # no covariances to store
        return self._batch(zs, Hs, Rs, update_first, saver, False)

    def _batch_compiled(self, Z, Hm, Rv, update_first, store_covariances):
        before = self._shallow_state()
        try:
            return self._batch_stepwise(Z, Hm, Rv, update_first, None, False)
        except BaseException:
            self._restore(before)
            raise

    def _final_health_check(self):
        """No covariance, no health check."""

    def reset(self):
        """Back to ``x0``; diagnostics and counters cleared."""
        self._x = self._x0.copy()
        self.x_prior, self.x_post = self._x.copy(), self._x.copy()
        self._reset_diagnostics()
        self.n_updates = 0

    def get_state(self):
        """``x`` and the update count."""
        return {"x": self._x.copy(), "n_updates": int(self.n_updates)}

    def set_state(self, state):
        """Continue from a dict of :meth:`get_state`."""
        s = check_state(self, state)
        self._x, self.n_updates = s["x"], s["n_updates"]
