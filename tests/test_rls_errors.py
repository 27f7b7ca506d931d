"""Bad input to RecursiveLeastSquares gets a clear error naming the argument."""

import numpy as np
import pytest

from rlsfilt import RecursiveLeastSquares


@pytest.mark.parametrize("dim_x, exc, match", [
    (0, ValueError, r"`dim_x` must be >= 1; got 0"),
    (-3, ValueError, r"`dim_x` must be >= 1; got -3"),
    (2.0, TypeError, r"`dim_x` must be an integer"),
    (True, TypeError, r"`dim_x` must be an integer"),
])
def test_bad_dim_x(dim_x, exc, match):
    with pytest.raises(exc, match=match):
        RecursiveLeastSquares(dim_x)


def test_bad_dim_z():
    with pytest.raises(ValueError, match=r"`dim_z` must be >= 1; got 0"):
        RecursiveLeastSquares(2, dim_z=0)


@pytest.mark.parametrize("lam", [0.0, -0.5, 1.5, np.nan, np.inf])
def test_bad_lam(lam):
    with pytest.raises(ValueError, match=r"`lam` must be in \(0, 1\]; got"):
        RecursiveLeastSquares(2, lam=lam)
    rls = RecursiveLeastSquares(2)
    with pytest.raises(ValueError, match=r"`lam` must be in \(0, 1\]"):
        rls.lam = lam


@pytest.mark.parametrize("H, match", [
    ([1.0, 2.0, 3.0], r"`H` must have shape \(2,\) or \(1, 2\).*got shape \(3,\)"),
    (np.ones((2, 1)), r"`H` must have shape \(2,\) or \(1, 2\).*got shape \(2, 1\)"),
    (np.ones((2, 2)), r"got shape \(2, 2\)"),
    (1.0, r"got shape \(\)"),
    ([1.0, np.nan], r"`H` must be finite; got nan at index 1"),
    ([np.inf, 1.0], r"`H` must be finite; got inf at index 0"),
])
def test_bad_regressor(H, match):
    rls = RecursiveLeastSquares(2)
    with pytest.raises(ValueError, match=match):
        rls.update(1.0, H)
    assert np.all(rls.x == 0)


def test_non_numeric_regressor():
    with pytest.raises(TypeError, match=r"`H` must be numeric"):
        RecursiveLeastSquares(2).update(1.0, ["a", "b"])


@pytest.mark.parametrize("z, match", [
    ([1.0, 2.0], r"`z` must be a scalar or have shape \(1,\).*got shape \(2,\)"),
    (np.inf, r"`z` must be finite or NaN"),
])
def test_bad_measurement(z, match):
    with pytest.raises(ValueError, match=match):
        RecursiveLeastSquares(2).update(z, [1.0, 1.0])


def test_bad_measurement_multi_output():
    rls = RecursiveLeastSquares(2, dim_z=3)
    with pytest.raises(ValueError, match=r"`z` must be a scalar or have shape \(3,\).*\(2,\)"):
        rls.update([1.0, 2.0], [1.0, 1.0])


@pytest.mark.parametrize("R, match", [
    (0.0, r"`R` must be a positive finite variance; got 0.0"),
    (-1.0, r"`R` must be a positive finite variance; got -1.0"),
    (np.nan, r"`R` must be a positive finite variance"),
    (np.eye(2), r"`R` must be a positive scalar variance or a \(1, 1\) array; got an array of "
                r"shape \(2, 2\)"),
])
def test_bad_R(R, match):
    with pytest.raises(ValueError, match=match):
        RecursiveLeastSquares(2, R=R)
    with pytest.raises(ValueError, match=match):
        RecursiveLeastSquares(2).update(1.0, [1.0, 1.0], R=R)


@pytest.mark.parametrize("Q, match", [
    (-1.0, r"`Q` must be positive semidefinite; got smallest eigenvalue -1"),
    (np.array([[1.0, 2.0], [0.0, 1.0]]), r"`Q` must be symmetric"),
    (np.diag([1.0, -1.0]), r"`Q` must be positive semidefinite"),
    (np.eye(3), r"`Q` must be a scalar or have shape \(2, 2\); got \(3, 3\)"),
    (np.array([[np.nan, 0], [0, 1]]), r"`Q` must be finite"),
])
def test_bad_Q(Q, match):
    with pytest.raises(ValueError, match=match):
        RecursiveLeastSquares(2, Q=Q)
    with pytest.raises(ValueError, match=match):
        RecursiveLeastSquares(2).predict(Q=Q)


def test_bad_P0():
    with pytest.raises(ValueError, match=r"`P0` must be positive definite"):
        RecursiveLeastSquares(2, P0=0.0)
    with pytest.raises(ValueError, match=r"`P0` must be symmetric"):
        RecursiveLeastSquares(2, P0=np.array([[1.0, 1.0], [0.0, 1.0]]))


def test_bad_x0():
    with pytest.raises(ValueError, match=r"`x0` must have shape \(2, 1\); got \(3,\)"):
        RecursiveLeastSquares(2, x0=[1.0, 2.0, 3.0])


def test_wrongly_assigned_state_is_reported_not_broadcast():
    rls = RecursiveLeastSquares(2)
    rls.x = np.zeros(2)
    with pytest.raises(ValueError, match=r"`x` must be an array of shape \(2, 1\); got \(2,\)"):
        rls.update(1.0, [1.0, 1.0])
    rls = RecursiveLeastSquares(2)
    rls.P = np.eye(3)
    with pytest.raises(ValueError, match=r"`P` must be an array of shape \(2, 2\); got \(3, 3\)"):
        rls.predict()


def test_batch_length_mismatch():
    rls = RecursiveLeastSquares(2)
    with pytest.raises(ValueError, match=r"`zs` and `Hs` must have the same length; got 5 "
                                         r"measurements and 4 regressor rows"):
        rls.batch_filter(np.ones(5), np.ones((4, 2)))
    with pytest.raises(ValueError, match=r"`Rs` must be a scalar or have shape \(5,\)"):
        rls.batch_filter(np.ones(5), np.ones((5, 2)), Rs=np.ones(4))
    with pytest.raises(ValueError, match=r"`zs` and `Hs` must have the same length"):
        rls.initialize(np.ones(5), np.ones((6, 2)))


def test_batch_bad_values():
    rls = RecursiveLeastSquares(2)
    H = np.ones((5, 2))
    H[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"`Hs` must be finite; got nan at index \(3, 1\)"):
        rls.batch_filter(np.ones(5), H)
    with pytest.raises(ValueError, match=r"`Hs` must have shape \(N, 2\).*got \(5, 3\)"):
        rls.batch_filter(np.ones(5), np.ones((5, 3)))
    with pytest.raises(ValueError, match=r"`Rs` must hold positive finite variances; got -1.0 at "
                                         r"index 2"):
        rls.batch_filter(np.ones(5), np.ones((5, 2)), Rs=[1, 1, -1, 1, 1])
    with pytest.raises(ValueError, match=r"`zs` must be finite; got inf at index \(1, 0\)"):
        rls.batch_filter([1, np.inf, 1, 1, 1], np.ones((5, 2)))
    with pytest.raises(ValueError, match=r"`zs` must have shape \(N,\) or \(N, 1\).*\(5, 2\)"):
        rls.batch_filter(np.ones((5, 2)), np.ones((5, 2)))
    assert np.all(rls.x == 0)


@pytest.mark.parametrize("Hs, rank", [
    (np.ones((3, 3)), 1),                                            # collinear
    (np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), 2),               # too few rows
    (np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 0.0]]), 2),
])
def test_initialize_rank_deficient(Hs, rank):
    rls = RecursiveLeastSquares(3)
    with pytest.raises(ValueError, match=rf"rank-deficient: found {rank} linearly independent rows"
                                         rf" in {len(Hs)} usable samples; need 3"):
        rls.initialize(np.ones(len(Hs)), Hs)
    assert np.all(rls.x == 0) and np.all(rls.P == 1e4 * np.eye(3))


def test_initialize_drops_missing_rows():
    rls = RecursiveLeastSquares(2)
    with pytest.raises(ValueError, match=r"found 1 linearly independent rows in 1 usable"):
        rls.initialize([1.0, np.nan], np.eye(2))


def test_residual_of_missing():
    with pytest.raises(ValueError, match=r"`z` must be a measurement"):
        RecursiveLeastSquares(2).residual_of(None, [1.0, 1.0])
