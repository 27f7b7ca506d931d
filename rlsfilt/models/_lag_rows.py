"""An ARX fit's regressor rows, read from the record's signals instead of a matrix.

`LagRows` stands where the regressor matrix :math:`\\Phi` of
``ARX.fit(method="rls")`` stood: the fused recursion reads the rows straight from
the signals (:mod:`rlsfilt.filters._kernels_lagged`), and so do the Gram matrix of
the form choice and the residuals of the final estimate. The matrix itself, ``8 n``
bytes per sample that would be written once and read once, is built only where a
path needs it (``matrix()``): several outputs, a forgetting mode the fused loop does
not run, the square-root form, an exact condition number.
"""

import numpy as np

from .._lazy import lazy_module

__all__ = ["LagRows", "MatrixRows"]

#: The compiled row readers, imported on first use.
_lagged = lazy_module("rlsfilt.filters._kernels_lagged")


class LagRows:
    """The rows ``phi(t)`` of an ARX structure on records (deviation signals).

    Parameters
    ----------
    records : list of (U, Y)
        The records the rows come from (``U`` (N_i, nu), ``Y`` (N_i, ny)), with
        any operating point already subtracted.
    s : ARXStructure
    intercept : bool
        A last column of ones.
    design : callable
        ``design() -> (Phi, target)``: the regressor matrix of the same records
        (`ARX._design`), built on the first call of `matrix`.

    Attributes
    ----------
    shape : tuple
        ``(rows, n)``, as the matrix's.
    """

    def __init__(self, records, s, intercept, design):
        self._design = design
        self._matrix = None
        lag = s.max_lag
        counts = np.array([max(len(U) - lag, 0) for U, _ in records], dtype=np.int64)
        lengths = np.array([len(U) for U, _ in records], dtype=np.int64)
        t_first = np.concatenate([[0], np.cumsum(lengths)[:-1]]) + lag
        keep = counts > 0
        if len(records) == 1:
            U, Y = records[0]
        else:
            U, Y = (np.concatenate([r[i] for r in records]) for i in (0, 1))
        # C-ordered, writable float64 (the layout the kernels are compiled for; they never
        # write into it): the caller's arrays as they are when they already are
        self.Y, self.U = (np.ascontiguousarray(X, dtype=np.float64) for X in (Y, U))
        self.Y, self.U = (X if X.flags.writeable else X.copy() for X in (self.Y, self.U))
        self.seg_rows = np.concatenate([[0], np.cumsum(counts[keep])]).astype(np.int64)
        self.seg_t0 = t_first[keep].astype(np.int64)
        cols = [(0, i, k) for i in range(s.n_outputs) for k in range(1, s.na + 1)]
        cols += [(1, j, k) for j in range(s.n_inputs)
                 for k in range(s.nk[j], s.nk[j] + s.nb[j])]
        cols += [(2, 0, 0)] * bool(intercept)
        self.cols = np.array(cols, dtype=np.int64).reshape(-1, 3)
        self.n_outputs = s.n_outputs
        self.shape = (int(self.seg_rows[-1]), len(self.cols))

    def __len__(self):
        return self.shape[0]

    def source(self, first=0):
        """``(Hm, lags)`` of the rows from row `first` on, as `_kernels.run_batch` takes
        them: no matrix, the lagged signals."""
        return None, self.lags(first)

    def lags(self, first=0):
        """The `_kernels_lagged` spec of the rows from row `first` on."""
        a, b = self.seg_rows[:-1], self.seg_rows[1:]
        keep = b > first
        t0 = self.seg_t0[keep] + np.maximum(first - a[keep], 0)
        starts = np.maximum(a[keep] - first, 0)
        seg_rows = np.concatenate([starts, [self.shape[0] - first]]).astype(np.int64)
        return self.Y, self.U, self.cols, seg_rows, t0.astype(np.int64)

    def rows(self, start, stop, scale=None):
        """``Phi[start:stop]`` (times `scale` column by column), a new array."""
        stop = min(stop, self.shape[0])
        out = np.empty((max(stop - start, 0), self.shape[1]))
        if len(out):
            _lagged().lag_rows_numpy(self.lags(start), 0, np.ones(self.shape[1])
                                     if scale is None
                                     else np.ascontiguousarray(scale, dtype=np.float64), out)
        return out

    def __getitem__(self, key):
        """Leading rows, ``rows[:k]`` (what `_full_rank_rows` and the batch start read)."""
        if not (isinstance(key, slice) and key.start is None and key.step is None
                and key.stop is not None and key.stop >= 0):
            raise TypeError(f"LagRows takes leading slices rows[:k]; got {key!r}")
        return self.rows(0, key.stop)

    def target(self, start, stop):
        """The targets ``y(t)`` of rows ``start:stop`` (rows, ny), a new array."""
        spec = self.lags(start)
        seg_rows, t0 = spec[3], spec[4]
        stop = min(stop, self.shape[0]) - start
        parts = [self.Y[t0[i]:t0[i] + min(seg_rows[i + 1], stop) - seg_rows[i]]
                 for i in range(len(t0)) if seg_rows[i] < stop]
        if len(parts) == 1:
            return parts[0]
        return np.concatenate(parts) if parts else np.empty((0, self.Y.shape[1]))

    def matrix(self):
        """``(Phi, target)``, built once."""
        if self._matrix is None:
            self._matrix = self._design()
        return self._matrix

    def gram(self, exponents=None):
        """The Gram matrix of the rows with column ``j`` times ``2^exponents[j]``."""
        n = self.shape[1]
        scale = np.ones(n) if exponents is None else np.ldexp(1.0, exponents)
        G = np.empty((n, n))
        _lagged().lag_gram(self.lags(), scale, G)
        return G

    def residuals(self, theta):
        """``(target - Phi theta, max_abs)``: the residuals (rows, ny) of `theta` (n, ny),
        and the largest magnitude in each column (`lag_residuals`)."""
        out = np.empty((self.shape[0], self.n_outputs))
        top = np.empty(self.n_outputs)
        theta = np.ascontiguousarray(theta, dtype=np.float64)
        _lagged().lag_residuals(self.lags(), theta, out, top)
        return out, top


class MatrixRows:
    """`LagRows`' interface over a regressor matrix and its targets (the recursion on
    scaled copies of the record)."""

    def __init__(self, Phi, target):
        self._matrix = (Phi, target)
        self.shape = Phi.shape
        self.n_outputs = target.shape[1]

    def __len__(self):
        return self.shape[0]

    def __getitem__(self, key):
        return self._matrix[0][key]

    def source(self, first=0):
        return self._matrix[0][first:], None

    def target(self, start, stop):
        return self._matrix[1][start:stop]

    def matrix(self):
        return self._matrix
