"""ARX instrumental variables with an intercept, on several experiments, and the
streaming form with delayed-input instruments.

Oracles: ``numpy.linalg.solve`` of the IV normal equations summed over the
experiments, ``(sum_i Z_i^T Phi_i) theta = sum_i Z_i^T y_i``, with every row built
here from shifted columns of its own experiment (and a column of ones for the
intercept), at every step of the recursion; the refined-IV fixed point.
"""

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX, IOData, RecursiveIV

A, B, C = [1, -1.5, 0.7], [0, 1.0, 0.5], [1, -1.0, 0.2]
THETA = np.array([-1.5, 0.7, 1.0, 0.5])
OFFSET = 2.0          # A y = B u + c + C e with c = OFFSET * A(1)


def _record(rng, N, offset=0.0):
    u = rng.standard_normal(N)
    y = lfilter(B, A, u) + lfilter(C, A, rng.standard_normal(N)) + offset
    return u, y


def _shift(x, k):
    out = np.zeros_like(x)
    out[k:] = x[:len(x) - k]
    return out


def _rows(u, y, intercept=False):
    """ARX(2, 2, 1) rows, delayed-input instruments and targets of one experiment."""
    Phi = np.column_stack([-_shift(y, 1), -_shift(y, 2), _shift(u, 1), _shift(u, 2)])[2:]
    Z = np.column_stack([_shift(u, 3), _shift(u, 4), _shift(u, 1), _shift(u, 2)])[2:]
    if intercept:
        Phi = np.column_stack([Phi, np.ones(len(Phi))])
        Z = np.column_stack([Z, np.ones(len(Z))])
    return Phi, Z, y[2:]


def _stacked(recs, intercept=False):
    parts = [_rows(u, y, intercept) for u, y in recs]
    return (np.vstack([p[0] for p in parts]), np.vstack([p[1] for p in parts]),
            np.concatenate([p[2] for p in parts]))


@pytest.mark.parametrize("offset", [False, True], ids=["no-offset", "intercept"])
def test_batch_iv_on_two_experiments_solves_the_summed_normal_equations(offset, rng):
    recs = [_record(rng, 700, OFFSET if offset else 0.0),
            _record(rng, 500, OFFSET if offset else 0.0)]
    data = IOData(u=[r[0] for r in recs], y=[r[1] for r in recs])
    model = ARX(2, 2, 1, offset=offset).fit(data, method="iv", instruments="delayed")
    Phi, Z, target = _stacked(recs, offset)
    theta = np.linalg.solve(Z.T @ Phi, Z.T @ target)
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-10)   # the intercept is last
    if offset:
        # (the fit runs on the record scaled by powers of two: the oracle to round-off)
        assert model.intercept_ == model.theta_[4] and model.param_names_[-1] == "c"
    np.testing.assert_allclose(model.instruments_, Z, rtol=0, atol=0)
    assert model.n_experiments_ == 2 and model.n_samples_ == len(target)
    # the concatenation pairs samples across the seam: a different estimate
    joined = ARX(2, 2, 1, offset=offset).fit(np.concatenate([r[0] for r in recs]),
                                             np.concatenate([r[1] for r in recs]),
                                             method="iv", instruments="delayed")
    assert np.max(np.abs(joined.theta_ - model.theta_)) > 1e-6


@pytest.mark.parametrize("offset", [False, True], ids=["no-offset", "intercept"])
def test_recursive_iv_on_two_experiments_is_batch_iv_at_every_step(offset, rng):
    recs = [_record(rng, 300, OFFSET if offset else 0.0),
            _record(rng, 250, OFFSET if offset else 0.0)]
    model = ARX(2, 2, 1, offset=offset).fit([r[0] for r in recs], [r[1] for r in recs],
                                            method="riv", instruments="delayed")
    Phi, Z, target = _stacked(recs, offset)
    n = Phi.shape[1]
    assert model.k0_ == n and len(model.theta_history_) == len(target)
    for t in range(n, len(target) + 1, 7):
        batch = np.linalg.solve(Z[:t].T @ Phi[:t], Z[:t].T @ target[:t])
        np.testing.assert_allclose(model.theta_history_[t - 1], batch, rtol=1e-9,
                                   atol=1e-10 * np.max(np.abs(batch)), err_msg=f"row {t}")


def test_refined_iv_with_intercept_on_two_experiments_is_a_fixed_point(rng):
    """"model" instruments: the estimate reproduces itself when its auxiliary model
    x = (B u + c)/A, simulated from rest in each experiment, and the prefilter 1/A
    (applied to every column, the ones too) make the instruments."""
    recs = [_record(rng, 3000, OFFSET), _record(rng, 2000, OFFSET)]
    model = ARX(2, 2, 1, offset=True).fit([r[0] for r in recs], [r[1] for r in recs],
                                          method="iv", n_iter=60)
    a = np.r_[1.0, model.a_]
    rows = []
    for u, y in recs:
        x = lfilter(np.r_[0.0, model.b_], a, u) + lfilter([model.intercept_], a, np.ones(len(u)))
        uf, yf, xf, one = (lfilter([1.0], a, v) for v in (u, y, x, np.ones(len(u))))
        Phi = np.column_stack([-_shift(yf, 1), -_shift(yf, 2), _shift(uf, 1), _shift(uf, 2),
                               one])[2:]
        Zr = np.column_stack([-_shift(xf, 1), -_shift(xf, 2), _shift(uf, 1), _shift(uf, 2),
                              one])[2:]
        rows.append((Phi, Zr, yf[2:]))
    Phi, Z, target = (np.vstack([r[k] for r in rows]) if k < 2
                      else np.concatenate([r[k] for r in rows]) for k in range(3))
    theta = np.linalg.solve(Z.T @ Phi, Z.T @ target)
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-8)
    # and it is unbiased where least squares is not (coloured equation error)
    assert np.all(np.abs(model.theta_[:4] - THETA) < 3 * model.std_errors_[:4])
    ls = ARX(2, 2, 1, offset=True).fit([r[0] for r in recs], [r[1] for r in recs])
    assert np.any(np.abs(ls.theta_[:4] - THETA) > 5 * ls.std_errors_[:4])


def test_user_instruments_on_two_experiments_with_intercept(rng):
    recs = [_record(rng, 400, OFFSET), _record(rng, 300, OFFSET)]
    Zfull = [np.column_stack([_shift(u, k) for k in (1, 2, 3, 5)]) for u, _ in recs]
    model = ARX(2, 2, 1, offset=True).fit([r[0] for r in recs], [r[1] for r in recs],
                                          method="iv", instruments=np.vstack(Zfull))
    Phi, _, target = _stacked(recs, True)
    Z = np.vstack([np.column_stack([z[2:], np.ones(len(z) - 2)]) for z in Zfull])
    theta = np.linalg.solve(Z.T @ Phi, Z.T @ target)
    np.testing.assert_allclose(model.theta_, theta, rtol=1e-10)
    with pytest.raises(ValueError, match=r"N = 700 rows \(one per sample of every experiment, "
                                         r"one after the other\) and n_z >= n_params = 4 \(a "
                                         r"column of ones is appended for the intercept\); got "
                                         r"\(400, 4\)"):
        ARX(2, 2, 1, offset=True).fit([r[0] for r in recs], [r[1] for r in recs],
                                      method="iv", instruments=Zfull[0])


def test_streaming_riv_with_delayed_instruments_is_batch_iv(rng):
    u, y = _record(rng, 500)
    est = RecursiveIV(2, 2, 1, instruments="delayed", k0=4)
    Phi, Z, target = _rows(u, y)
    preds = []
    for t in range(len(y)):
        yhat, theta = est.step(y[t], u[t])
        preds.append(yhat)
        row = t - 2
        np.testing.assert_array_equal(est.z, Z[row]) if row >= 0 else None
        if row >= 3:                 # after the exact start on rows 0..3
            batch = np.linalg.solve(Z[:row + 1].T @ Phi[:row + 1],
                                    Z[:row + 1].T @ target[:row + 1])
            np.testing.assert_allclose(theta, batch, rtol=1e-9, err_msg=f"sample {t}")
    # and it equals the batch fit's recursion on the same instruments
    fit = ARX(2, 2, 1).fit(u, y, method="riv", instruments="delayed", k0=4)
    np.testing.assert_allclose(est.theta, fit.theta_, rtol=1e-10)
    with pytest.raises(ValueError, match="`z` only applies to instruments='given'"):
        est.step(y[0], u[0], z=np.ones(4))


def test_recursive_refined_iv_on_two_experiments_is_batch_iv_on_its_rows(rng):
    """"model" instruments, refreshed every 50 rows: every estimate after the exact start is
    the IV solution of the rows used so far, and the rows of each experiment are its own
    (the input block of the instruments is the per-experiment regressor's)."""
    recs = [_record(rng, 400), _record(rng, 300)]
    model = ARX(2, 2, 1).fit([r[0] for r in recs], [r[1] for r in recs], method="riv",
                             refresh=50)
    Phi, _, target = _stacked(recs)
    Z = model.instruments_
    np.testing.assert_array_equal(Z[:, 2:], Phi[:, 2:])
    for t in range(4, len(target) + 1, 9):
        batch = np.linalg.solve(Z[:t].T @ Phi[:t], Z[:t].T @ target[:t])
        np.testing.assert_allclose(model.theta_history_[t - 1], batch, rtol=1e-9,
                                   atol=1e-10 * np.max(np.abs(batch)), err_msg=f"row {t}")


def test_a_short_first_experiment_says_how_to_start_the_recursion(rng):
    # the exact start is on the first experiment: a 2-sample one has no row for it; the
    # message named only `k0`, an argument the caller had not passed
    u, u2 = rng.standard_normal(200), rng.standard_normal(2)
    y, y2 = lfilter([0, 1.0, 0.5], [1, -0.5], u), lfilter([0, 1.0], [1], u2)
    data = IOData([u2, u], [y2, y])
    with pytest.raises(ValueError, match=r"got 4 \(the default, n_params\) \(the exact start "
                                         r"is on the first experiment: put a longer one first, "
                                         r"or pass k0=0"):
        ARX(2, 2, 1).fit(data, method="riv")
    model = ARX(2, 2, 1).fit(data, method="riv", k0=0)         # the prior start works
    assert np.all(np.isfinite(model.theta_))
