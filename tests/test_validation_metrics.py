"""fit_percent against its formula (MATLAB's NRMSE fit)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import rlsfilt
from rlsfilt.validation import fit_percent


def test_fit_percent_matches_formula(rng):
    y = rng.standard_normal(300).cumsum()
    yhat = y + 0.3 * rng.standard_normal(300)
    num = np.sqrt(np.sum((y - yhat) ** 2))
    den = np.sqrt(np.sum((y - y.mean()) ** 2))
    expected = 100.0 * (1.0 - num / den)
    assert fit_percent(y, yhat) == pytest.approx(expected, rel=1e-14)
    assert isinstance(fit_percent(y, yhat), float)


def test_fit_percent_limits(rng):
    y = rng.standard_normal(100)
    assert fit_percent(y, y) == 100.0
    assert fit_percent(y, np.full(100, y.mean())) == pytest.approx(0.0, abs=1e-12)
    assert fit_percent(y, -y + 2 * y.mean()) == pytest.approx(-100.0, abs=1e-10)


def test_fit_percent_per_output(rng):
    Y = rng.standard_normal((200, 3))
    Yh = Y + rng.standard_normal((200, 3)) * [0.1, 0.5, 1.0]
    fits = fit_percent(Y, Yh)
    assert fits.shape == (3,)
    for j in range(3):
        assert fits[j] == pytest.approx(fit_percent(Y[:, j], Yh[:, j]), rel=1e-14)
    assert fits[0] > fits[1] > fits[2]


def test_fit_percent_does_not_mutate_and_is_reexported(rng):
    y = rng.standard_normal(50)
    yh = y + 0.1
    y0, yh0 = y.copy(), yh.copy()
    assert rlsfilt.fit_percent(y, yh) == fit_percent(y0, yh0)
    np.testing.assert_array_equal(y, y0)
    np.testing.assert_array_equal(yh, yh0)


def test_fit_percent_errors():
    with pytest.raises(ValueError, match=r"`y` and `yhat` must have the same shape; got \(3,\) "
                                         r"and \(4,\)"):
        fit_percent([1, 2, 3], [1, 2, 3, 4])
    with pytest.raises(ValueError, match="output 0 is constant"):
        fit_percent([1.0, 1.0, 1.0], [1.0, 2.0, 3.0])
    with pytest.raises(ValueError, match=r"`yhat` must be finite; got nan at index 1"):
        fit_percent([1.0, 2.0, 3.0], [1.0, np.nan, 3.0])
    with pytest.raises(ValueError, match=r"`y` must have shape \(N,\) or \(N, ny\)"):
        fit_percent(np.zeros((2, 2, 2)), np.zeros((2, 2, 2)))
    with pytest.raises(TypeError, match="`y` must be numeric array-like"):
        fit_percent(["a", "b"], [1.0, 2.0])


@settings(max_examples=50, deadline=None)
@given(scale=st.floats(1e-3, 1e3), shift=st.floats(-1e3, 1e3), seed=st.integers(0, 2**31))
def test_fit_percent_is_affine_invariant(scale, shift, seed):
    """Scaling and shifting both signals together leaves the fit unchanged."""
    rng = np.random.default_rng(seed)
    y = rng.standard_normal(64)
    yhat = y + 0.5 * rng.standard_normal(64)
    assert fit_percent(scale * y + shift, scale * yhat + shift) == pytest.approx(
        fit_percent(y, yhat), rel=1e-9, abs=1e-9)


def test_fit_percent_rejects_complex():
    with pytest.raises(TypeError, match=r"`yhat` must be real; got complex values"):
        fit_percent([1.0, 2.0, 3.0], [1.0, 2.0 + 1j, 3.0])
