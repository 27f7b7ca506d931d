"""Bad input to ARX gets a clear error naming what is wrong and where."""

import control
import numpy as np
import pytest

from rlsfilt import ARX, NotFittedError
from rlsfilt.models import arx_regressors


@pytest.fixture
def data(rng):
    return rng.standard_normal(100), rng.standard_normal(100)


@pytest.mark.parametrize("which, index, value", [
    ("u", 3, np.nan), ("u", 0, np.inf), ("y", 7, -np.inf), ("y", 99, np.nan),
])
def test_nonfinite_data_names_first_bad_index(data, which, index, value):
    u, y = (d.copy() for d in data)
    target = u if which == "u" else y
    target[index] = value
    target[index + 1 if index < 99 else 0] = np.nan  # a later/other bad value is not the one named
    first = min(index, index + 1 if index < 99 else 0)
    with pytest.raises(ValueError, match=rf"`{which}` must be finite; got .* at index {first}$"):
        ARX(2, 2).fit(u, y)


def test_finite_data_whose_sum_overflows_is_accepted_and_bad_entries_still_named(data):
    """The summation that screens a record for NaN and inf overflows on finite entries near
    the largest double: the exact test then decides (no false alarm, no warning), and an
    inf beside them is still named with its index."""
    from rlsfilt._validation import check_finite
    big = np.full(10, 1e308)
    assert check_finite(big, "y") is big
    big[6] = np.inf
    with pytest.raises(ValueError, match=r"`y` must be finite; got inf at index 6$"):
        check_finite(big, "y")
    with pytest.raises(ValueError, match=r"`u` must be finite; got -inf at index 2$"):
        check_finite(np.array([1.0, 2.0, -np.inf, np.inf]), "u")  # the sum is NaN


def test_nonfinite_multichannel_index(data):
    u = np.column_stack([data[0], data[0]])
    u[5, 1] = np.nan
    with pytest.raises(ValueError, match=r"`u` must be finite; got nan at index \(5, 1\)"):
        ARX(2, 2).fit(u, data[1])


def test_nonfinite_pandas_and_predict(data):
    pd = pytest.importorskip("pandas")
    u, y = data
    bad = pd.Series(y).copy()
    bad.iloc[12] = np.nan
    with pytest.raises(ValueError, match=r"`y` must be finite; got nan at index 12"):
        ARX(1, 1).fit(u, bad)
    model = ARX(1, 1).fit(u, y)
    with pytest.raises(ValueError, match=r"`y` must be finite; got nan at index 12"):
        model.predict(u, bad)
    with pytest.raises(ValueError, match=r"`u` must be finite; got inf at index 4"):
        model.simulate(np.r_[u[:4], np.inf, u[5:]])


def test_length_mismatch(data):
    u, y = data
    with pytest.raises(ValueError, match=r"`u` and `y` must have the same length; got 100 "
                                         r"input samples and 99 output samples"):
        ARX(2, 2).fit(u, y[:-1])
    with pytest.raises(ValueError, match=r"same length"):
        ARX(2, 2).regressors(u[:50], y)
    model = ARX(2, 2).fit(u, y)
    with pytest.raises(ValueError, match=r"same length; got 10 input samples and 100"):
        model.predict(u[:10], y)


def test_too_few_samples(data):
    u, y = data
    # na=2, nb=2, nk=1: max_lag 2, 4 parameters -> need 6 samples
    with pytest.raises(ValueError, match=r"`y` must have at least max_lag \+ n_params = 2 \+ 4 = "
                                         r"6 samples for ARX\(na=2, nb=2, nk=1\); got 5"):
        ARX(2, 2, 1).fit(u[:5], y[:5])
    ARX(2, 2, 1).fit(u[:6], y[:6])  # exactly enough: an exact fit
    with pytest.raises(ValueError, match=r"at least max_lag \+ n_params = 5 \+ 7 = 12 samples"):
        ARX(3, [1, 3], [0, 3]).fit(np.column_stack([u, u ** 2])[:11], y[:11])


def test_exact_fit_has_no_noise_estimate(data):
    u, y = data
    model = ARX(2, 2, 1).fit(u[:6], y[:6])
    assert np.isnan(model.noise_variance_) and np.isnan(model.theta_cov_).all()


@pytest.mark.parametrize("kwargs, exc, match", [
    ({"na": -1, "nb": 2}, ValueError, r"`na` must be >= 0; got -1"),
    ({"na": 2, "nb": 0}, ValueError, r"`nb` must be >= 1; got 0"),
    ({"na": 2, "nb": -2}, ValueError, r"`nb` must be >= 1; got -2"),
    ({"na": 2, "nb": 2, "nk": -1}, ValueError, r"`nk` must be >= 0; got -1"),
    ({"na": 2.0, "nb": 2}, TypeError, r"`na` must be an integer; got 2.0"),
    ({"na": 2, "nb": 1.5}, TypeError, r"`nb` must be an integer; got 1.5"),
    ({"na": 2, "nb": "2"}, TypeError, r"`nb` must be an integer; got '2'"),
    ({"na": True, "nb": 2}, TypeError, r"`na` must be an integer"),
    ({"na": 2, "nb": 2, "dt": 0.0}, ValueError, r"`dt` must be True \(unspecified sampling "
                                               r"period\) or a positive sampling period; got 0.0"),
    ({"na": 2, "nb": 2, "dt": -1}, ValueError, r"`dt` must be True .*; got -1"),
    ({"na": 2, "nb": 2, "dt": None}, ValueError, r"`dt` must be True .*; got None"),
])
def test_bad_orders(data, kwargs, exc, match):
    model = ARX(**kwargs)  # __init__ only stores
    with pytest.raises(exc, match=match):
        model.fit(*data)
    with pytest.raises(exc, match=match):
        model.regressors(*data)


@pytest.mark.parametrize("nb, nk, match", [
    ([2, 2, 2], 1, r"`nb` must be an integer or have one entry per input \(2\); got 3 entries"),
    ([2], 1, r"`nb` must be .* one entry per input \(2\); got 1 entries"),
    (2, [1, 1, 1], r"`nk` must be an integer or have one entry per input \(2\); got 3 entries"),
    ([2, 0], 1, r"`nb\[1\]` must be >= 1; got 0"),
    (2, [1, -1], r"`nk\[1\]` must be >= 0; got -1"),
    ([2, 1.0], 1, r"`nb\[1\]` must be an integer; got 1.0"),
    ({2, 3}, 1, r"`nb` must be an integer or a sequence of integers \(one per input, in input "
                r"order\); got set"),
    (2, {0: 1, 1: 1}, r"`nk` must be an integer or a sequence of integers .*; got dict"),
])
def test_bad_per_input_orders(rng, nb, nk, match):
    u, y = rng.standard_normal((100, 2)), rng.standard_normal(100)
    with pytest.raises((ValueError, TypeError), match=match):
        ARX(2, nb, nk).fit(u, y)
    with pytest.raises((ValueError, TypeError), match=match):
        arx_regressors(u, y, 2, nb, nk)


def test_zero_dimensional_array_orders_are_scalars(rng):
    u, y = rng.standard_normal(100), rng.standard_normal(100)
    model = ARX(np.array(2), np.array(2), np.array(1)).fit(u, y)
    np.testing.assert_array_equal(model.theta_, ARX(2, 2, 1).fit(u, y).theta_)
    with pytest.raises(TypeError, match=r"`nb` must be an integer; got 2.0"):
        ARX(2, np.array(2.0)).fit(u, y)


def test_bad_shapes_and_types(data):
    u, y = data
    with pytest.raises(ValueError, match=r"`u` must have shape \(N,\) or \(N, n_signals\); "
                                         r"got \(100, 1, 1\)"):
        ARX(1, 1).fit(u.reshape(100, 1, 1), y)
    with pytest.raises(ValueError, match=r"`y` must have at least one column; got shape"):
        ARX(1, 1).fit(u, np.zeros((100, 0)))
    with pytest.raises(TypeError, match=r"`u` must be numeric array-like"):
        ARX(1, 1).fit(["a"] * 100, y)


def test_bad_method_and_options(data):
    with pytest.raises(ValueError, match=r"`method` must be 'ls', 'rls', 'iv', 'riv', 'nlms' or "
                                        r"'lms'; got 'qr'"):
        ARX(2, 2).fit(*data, method="qr")
    with pytest.raises(TypeError, match=r"`lam` only applies to method='rls'; got method='ls'"):
        ARX(2, 2).fit(*data, lam=0.99)
    with pytest.raises(ValueError, match=r"`lam` must be in \(0, 1\]; got 1.5"):
        ARX(2, 2).fit(*data, method="rls", lam=1.5)
    with pytest.raises(ValueError, match=r"`k0` must be <= the number of regressor rows \(98\); "
                                         r"got 99"):
        ARX(2, 2).fit(*data, method="rls", k0=99)
    with pytest.raises(ValueError, match=r"`k0` must be >= 0; got -1"):
        ARX(2, 2).fit(*data, method="rls", k0=-1)
    with pytest.raises(ValueError, match=r"`Hs` is rank-deficient"):
        ARX(2, 2).fit(*data, method="rls", k0=3)
    with pytest.raises(ValueError, match=r"`P0` only applies to a prior start \(k0=0\); the "
                                         r"batch start on k0=4 rows sets both x0 and P0"):
        ARX(2, 2).fit(*data, method="rls", k0=4, P0=100.0)
    with pytest.raises(ValueError, match=r"`x0` only applies to a prior start"):
        ARX(2, 2).fit(*data, method="rls", k0=10, x0=np.zeros(4))
    with pytest.raises(TypeError, match=r"`gate` only applies to method='rls'; got method='ls'"):
        ARX(2, 2).fit(*data, gate=3.0)
    with pytest.raises(TypeError, match=r"`lamda` is not an option of ARX.fit or "
                                        r"RecursiveLeastSquares; the filter's other options"):
        ARX(2, 2).fit(*data, method="rls", lamda=0.9)
    with pytest.raises(TypeError, match=r"`foo` is not a parameter of ARX"):
        ARX(2, 2).set_params(foo=1)


def test_not_persistently_exciting(data):
    _, y = data
    with pytest.raises(ValueError, match=r"rank 3 < n_params = 4: the input is not "
                                         r"persistently exciting"):
        ARX(2, 2).fit(np.ones(100), y)


@pytest.mark.parametrize("call", [
    lambda m, u, y: m.predict(u, y),
    lambda m, u, y: m.simulate(u),
    lambda m, u, y: m.to_tf(),
    lambda m, u, y: m.to_ss(),
    lambda m, u, y: m.to_dlti(),
    lambda m, u, y: m.summary(),
    lambda m, u, y: m.polynomials(),
    lambda m, u, y: m.std_errors_,
    lambda m, u, y: m.n_params,
    lambda m, u, y: m.max_lag,
])
def test_not_fitted(data, call):
    model = ARX(2, 2)
    with pytest.raises(NotFittedError, match=r"not fitted yet; call `fit\(u, y\)` before"):
        call(model, *data)
    with pytest.raises(ValueError):
        call(model, *data)
    with pytest.raises(AttributeError):
        call(model, *data)
    assert not hasattr(model, "theta_")


def test_unfitted_attributes_absent_after_init():
    model = ARX(2, 2)
    assert not hasattr(model, "n_params") and not hasattr(model, "std_errors_")
    assert "ARX(na=2, nb=2, nk=1, dt=True)" in model._repr_html_()


def test_data_mismatch_after_fit(rng):
    u, y = rng.standard_normal((100, 2)), rng.standard_normal(100)
    model = ARX(1, 1).fit(u, y)
    with pytest.raises(ValueError, match=r"`u` must have 2 input column\(s\) as in `fit`; got 1"):
        model.simulate(u[:, 0])
    with pytest.raises(ValueError, match=r"`y` must have 1 output column\(s\) as in `fit`; got 2"):
        model.predict(u, np.column_stack([y, y]))
    with pytest.raises(ValueError, match=r"`horizon` must be >= 1; got 0"):
        model.predict(u, y, horizon=0)
    with pytest.raises(TypeError, match=r"`horizon` must be an integer; got 1.5"):
        model.predict(u, y, horizon=1.5)
    with pytest.raises(ValueError, match=r"`y0` must have 1 output column\(s\); got 2"):
        model.simulate(u, y0=np.ones((2, 2)))
    with pytest.raises(ValueError, match=r"`y0` must have at most N = 100 samples; got 101"):
        model.simulate(u, y0=np.ones(101))
    with pytest.raises(ValueError, match=r"`y0` must be finite; got nan at index 0"):
        model.simulate(u, y0=[np.nan])


def test_bad_plants_for_from_tf_and_from_polynomials():
    with pytest.raises(ValueError, match=r"`G` must be a discrete-time transfer function; "
                                         r"got dt=0"):
        ARX.from_tf(control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(ValueError, match=r"`G` must be proper \(causal\); entry \(0, 0\) has a "
                                         r"numerator of degree 2 over a denominator of degree 1"):
        ARX.from_tf(control.tf([1.0, 0.0, 0.0], [1.0, -0.5], 1.0))
    with pytest.raises(ValueError, match=r"`G` has a zero transfer function from input 0"):
        ARX.from_tf(control.tf([0.0], [1.0, -0.5], 1.0))
    with pytest.raises(ValueError, match=r"`b` must hold 1-D coefficient arrays with nb >= 1; "
                                         r"got shape \(0,\)"):
        ARX.from_polynomials([-0.5], [])
    with pytest.raises(ValueError, match=r"`a` must be 1-D"):
        ARX.from_polynomials([[-0.5]], [1.0])
    with pytest.raises(ValueError, match=r"`dt` must be True"):
        ARX.from_polynomials([-0.5], [1.0], dt=-0.1)


def test_complex_data_is_rejected_not_truncated(data):
    """Complex signals would lose their imaginary part silently; they are a TypeError."""
    pd = pytest.importorskip("pandas")
    u, y = data
    with pytest.raises(TypeError, match=r"`u` must be real; got complex values"):
        ARX(1, 1).fit(u + 1j, y)
    with pytest.raises(TypeError, match=r"`y` must be real; got complex values"):
        ARX(1, 1).fit(u, pd.Series(y + 0j))
    with pytest.raises(TypeError, match=r"`u` must be real; got complex values"):
        ARX(1, 1).fit(pd.DataFrame({"a": u, "b": u * 1j}), y)
    model = ARX(1, 1).fit(u, y)
    with pytest.raises(TypeError, match=r"`u` must be real"):
        model.simulate(u.astype(complex))


@pytest.mark.parametrize("call, exc, match", [
    (lambda: ARX.from_polynomials([-0.5, np.nan], [1.0]), ValueError,
     r"`a` must be finite; got nan at index 1"),
    (lambda: ARX.from_polynomials([-0.5], [1.0, np.inf]), ValueError,
     r"`b` must be finite; got inf at index 1"),
    (lambda: ARX.from_polynomials([-0.5], [[1.0], [2.0, np.nan]], nk=[1, 1]), ValueError,
     r"`b\[1\]` must be finite; got nan at index 1"),
    (lambda: ARX.from_polynomials([-0.5], "ab"), TypeError, r"`b` must be numeric array-like"),
    (lambda: ARX.from_polynomials(["x"], [1.0]), TypeError, r"`a` must be numeric array-like"),
    (lambda: ARX.from_polynomials([-0.5], [1.0], noise_variance=-1.0), ValueError,
     r"`noise_variance` must be a finite value >= 0; got -1.0"),
    (lambda: ARX.from_polynomials([-0.5], [1.0], noise_variance=np.nan), ValueError,
     r"`noise_variance` must be a finite value >= 0; got nan"),
    (lambda: ARX.from_polynomials([-0.5], [1.0], noise_variance="x"), TypeError,
     r"`noise_variance` must be a real number"),
    (lambda: ARX.from_tf("z/(z - 0.5)"), TypeError,
     r"`G` must be a discrete python-control LTI system \(control.tf, control.ss\); got str"),
    (lambda: ARX.from_tf([1.0, 0.5]), TypeError, r"`G` must be a discrete python-control LTI"),
])
def test_bad_coefficients_for_true_models(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


@pytest.mark.parametrize("name", ["theta_", "a_", "b_", "theta_cov_", "noise_variance_",
                                  "residuals_", "n_samples_", "param_names_"])
def test_learned_attributes_before_fit_say_to_call_fit(name):
    model = ARX(2, 2)
    with pytest.raises(NotFittedError, match=rf"not fitted yet; call `fit\(u, y\)` before using "
                                             rf"`{name}`"):
        getattr(model, name)
    assert not hasattr(model, name)  # NotFittedError is an AttributeError
    with pytest.raises(AttributeError, match=r"'ARX' object has no attribute 'foo'"):
        model.foo  # noqa: B018


def test_attributes_of_other_fits_say_which_fit_sets_them(data):
    model = ARX(1, 1).fit(*data)
    with pytest.raises(AttributeError, match=r"`theta_history_` is only set by "
                                             r"fit\(\.\.\., method='rls', 'riv', 'nlms' or "
                                             r"'lms'\)"):
        model.theta_history_  # noqa: B018
    with pytest.raises(AttributeError, match=r"`noise_covariance_` is only set by a fit on 2-D"):
        model.noise_covariance_  # noqa: B018
    with pytest.raises(AttributeError, match=r"'ARX' object has no attribute 'foo_'"):
        model.foo_  # noqa: B018
