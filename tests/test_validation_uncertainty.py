"""Parameter confidence intervals (statsmodels OLS oracle, coverage) and
sampled frequency-response bands (nominal response, coverage of the truth)."""

import control
import numpy as np
import pytest
import statsmodels.api as sm
from scipy.signal import freqz, lfilter
from scipy.stats import binom

from rlsfilt import ARX, datasets
from rlsfilt.validation import (
    FrequencyBand,
    ParameterIntervals,
    frequency_response_band,
    parameter_intervals,
)

B_TRUE, A_TRUE = [0, 1.0, 0.5], [1, -1.5, 0.7]
THETA_TRUE = [-1.5, 0.7, 1.0, 0.5]


def _record(seed, n=300, noise=0.5):
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(n)
    y = lfilter(B_TRUE, A_TRUE, u) + lfilter([1.0], A_TRUE, noise * rng.standard_normal(n))
    return u, y


def test_intervals_match_statsmodels_ols():
    d = datasets.nonminimum_phase()
    model = ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y)
    Phi, target = model.regressors(d.u, d.y)
    ols = sm.OLS(target, Phi).fit()
    for level in (0.9, 0.95, 0.99):
        ci = parameter_intervals(model, level=level)
        assert isinstance(ci, ParameterIntervals)
        ref = ols.conf_int(alpha=1 - level)
        np.testing.assert_allclose(ci.lower, ref[:, 0], rtol=1e-9)
        np.testing.assert_allclose(ci.upper, ref[:, 1], rtol=1e-9)
        np.testing.assert_allclose(ci.std_error, ols.bse, rtol=1e-9)
    assert ci.names == ["a1", "a2", "b1", "b2"]
    assert ci.dof == model.n_samples_ - 4


def test_intervals_cover_truth_at_their_level():
    n_exp = 200
    inside = np.zeros(4)
    for seed in range(n_exp):
        u, y = _record(seed)
        inside += parameter_intervals(ARX(2, 2).fit(u, y), level=0.95).contains(THETA_TRUE)
    lo, hi = binom.ppf(0.0005, n_exp, 0.95), binom.ppf(0.9995, n_exp, 0.95)
    assert np.all((lo <= inside) & (inside <= hi)), inside


def test_intervals_of_true_and_multi_output_models(rng):
    true = ARX.from_polynomials([-0.5], [1.0], nk=1)
    ci = parameter_intervals(true)
    np.testing.assert_array_equal(ci.lower, ci.upper)
    u = rng.standard_normal(500)
    Y = np.column_stack([lfilter([0, 1.0], [1, -0.5], u), lfilter([0, 0.3], [1, -0.2], u)])
    Y += 0.1 * rng.standard_normal((500, 2))
    model = ARX(1, 1).fit(u, Y)
    ci2 = parameter_intervals(model)
    assert ci2.lower.shape == model.theta_.shape == (3, 2)
    np.testing.assert_allclose(ci2.std_error, model.std_errors_, rtol=1e-12)
    assert "(y2)" in str(ci2.summary())


def test_zero_standard_error_with_no_spare_equations_is_a_point_interval():
    """dof = 0 makes the quantile infinite; a zero standard error still gives a
    zero-width interval, a positive one an infinite interval, and no inf * 0."""
    with np.errstate(all="raise"):
        ci = ParameterIntervals(["a1", "b1"], np.array([0.5, 1.0]), np.array([0.0, 0.1]),
                                0.95, dof=0)
    assert ci.quantile == np.inf
    np.testing.assert_array_equal(ci.lower, [0.5, -np.inf])
    np.testing.assert_array_equal(ci.upper, [0.5, np.inf])


def test_band_nominal_response_and_shape():
    d = datasets.mass_spring_damper()
    model = ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y)
    band = frequency_response_band(model, n_draws=500, rng=1)
    assert isinstance(band, FrequencyBand)
    z = np.exp(1j * band.omega * d.dt)
    assert band.response.shape == band.magnitude_upper.shape == (1, 1, 300)
    np.testing.assert_allclose(band.response[0, 0], model.to_tf()(z), rtol=1e-10)
    assert band.omega[-1] == pytest.approx(np.pi / d.dt)
    assert np.all(band.magnitude_lower <= band.magnitude_upper)
    assert np.all(band.phase_lower <= band.phase_upper)
    mid = band.omega < 0.9 * band.omega[-1]
    assert band.contains(band.response)[0, 0, mid].mean() > 0.95
    # the same seed gives the same band
    again = frequency_response_band(model, n_draws=500, rng=1)
    np.testing.assert_array_equal(again.magnitude_upper, band.magnitude_upper)


def test_band_covers_the_true_response():
    omega = np.array([0.05, 0.3, 1.0, 2.5])
    _, G_true = freqz(B_TRUE, A_TRUE, worN=omega)
    n_exp = 200
    inside = np.zeros(4)
    for seed in range(n_exp):
        u, y = _record(seed)
        band = frequency_response_band(ARX(2, 2).fit(u, y), omega=omega, n_draws=400, rng=seed)
        inside += band.contains(G_true)[0, 0]
    lo, hi = binom.ppf(0.0005, n_exp, 0.95), binom.ppf(0.9995, n_exp, 0.95)
    assert np.all((lo - 4 <= inside) & (inside <= hi)), inside   # 4: sampling error of quantiles


def test_band_narrows_with_more_data():
    u, y = _record(0, n=4000)
    om = np.array([0.2, 1.0])
    wide = frequency_response_band(ARX(2, 2).fit(u[:500], y[:500]), omega=om, rng=0)
    narrow = frequency_response_band(ARX(2, 2).fit(u, y), omega=om, rng=0)
    ratio = (wide.magnitude_upper - wide.magnitude_lower) / \
        (narrow.magnitude_upper - narrow.magnitude_lower)
    assert np.all((ratio > 2.0) & (ratio < 4.5))          # about sqrt(8) = 2.8


def test_band_several_inputs(rng):
    U = rng.standard_normal((1000, 2))
    y = lfilter([0, 1.0], [1, -0.6], U[:, 0]) + lfilter([0, 0, 0.8], [1, -0.6], U[:, 1])
    y += 0.05 * rng.standard_normal(1000)
    model = ARX(1, [1, 1], nk=[1, 2]).fit(U, y)
    band = frequency_response_band(model, n_draws=200, rng=0)
    G = model.to_tf()
    z = np.exp(1j * band.omega)
    np.testing.assert_allclose(band.response, np.asarray(G(z, squeeze=False)), rtol=1e-10)


def test_band_several_outputs(rng):
    """Joint draws of both outputs' parameters; nominal response is A(z)^-1 B(z)."""
    n = 3000
    u = rng.standard_normal(n)
    E = rng.multivariate_normal([0, 0], [[0.01, 0.008], [0.008, 0.01]], size=n)
    Y = np.zeros((n, 2))
    for t in range(1, n):
        Y[t, 0] = 0.5 * Y[t - 1, 0] + 0.2 * Y[t - 1, 1] + u[t - 1] + E[t, 0]
        Y[t, 1] = -0.3 * Y[t - 1, 0] + 0.6 * Y[t - 1, 1] + 0.5 * u[t - 1] + E[t, 1]
    model = ARX(1, 1).fit(u, Y)
    om = np.linspace(0.01, np.pi, 50)
    band = frequency_response_band(model, omega=om, n_draws=2000, rng=2)
    z = np.exp(1j * om)
    np.testing.assert_allclose(band.response, np.asarray(model.to_tf()(z, squeeze=False)),
                               rtol=1e-10)
    assert band.response.shape == (2, 1, 50)
    true = control.ss([[0.5, 0.2], [-0.3, 0.6]], [[1.0], [0.5]], np.eye(2), 0, True)
    G_true = np.asarray(true(z, squeeze=False))
    # one experiment: the truth is within a few standard deviations everywhere
    assert np.all(np.abs(np.abs(G_true) - np.abs(band.response)) < 4 * band.magnitude_std)
    # the spread of |G| follows the linearized covariance of vec(theta_),
    # kron(noise_covariance_, (Phi^T Phi)^-1), by the delta method
    M = model.theta_cov_[0] / model.noise_variance_[0]
    cov = np.kron(model.noise_covariance_, M)

    def gain(vec, zk, out):
        Th = vec.reshape(3, 2, order="F")            # columns = equations
        A1, b = Th[:2].T, Th[2]
        return abs(np.linalg.solve(np.eye(2) + A1 / zk, b / zk)[out])

    vec0 = model.theta_.ravel(order="F")
    for k in (5, 25):
        for out in (0, 1):
            J = np.array([(gain(vec0 + h, z[k], out) - gain(vec0 - h, z[k], out)) / 2e-7
                          for h in 1e-7 * np.eye(6)])
            assert band.magnitude_std[out, 0, k] == pytest.approx(np.sqrt(J @ cov @ J),
                                                                  rel=0.1)


def test_band_plot_and_errors(rng):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = datasets.dc_motor()
    model = ARX(2, 2, 1, dt=d.dt).fit(d.u, d.y)
    band = frequency_response_band(model, n_draws=100, rng=0)
    fig = band.plot(plant=d.plant)
    assert len(fig.axes) == 2
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert texts == ["95% band", "model", "plant"]
    assert fig.axes[1].get_xlabel() == "$\\omega$ (rad/s)"
    plt.close("all")
    with pytest.raises(ValueError, match=r"`level` must be in \(0, 1\); got 95.0"):
        frequency_response_band(model, level=95)
    with pytest.raises(ValueError, match="`n_draws` must be >= 2; got 1"):
        frequency_response_band(model, n_draws=1)
    nyq = np.pi / d.dt
    for bad in ([-1.0], [np.nan], [], [1.01 * nyq]):  # the same grid rules as PlantComparison
        with pytest.raises(ValueError, match=rf"`omega` must hold finite frequencies in \[0, "
                                             rf"{nyq:.6g}\] \(up to Nyquist\)"):
            frequency_response_band(model, omega=bad)
    with pytest.raises(TypeError, match="`omega` must be numeric array-like"):
        frequency_response_band(model, omega="low")
    with pytest.raises(ValueError, match=r"`level` must be in \(0, 1\); got 1.0"):
        parameter_intervals(model, level=1.0)
    assert isinstance(control.tf(model.to_tf()), control.TransferFunction)


def test_band_names_a_bad_rng():
    d = datasets.thermal_process(n_samples=200)
    model = ARX(*d.orders, dt=d.dt).fit(d.u, d.y)
    with pytest.raises(TypeError, match=r"`rng` must be None, a non-negative integer seed"):
        frequency_response_band(model, rng="seed")


def test_contains_checks_shapes_and_plot_bode_makes_its_axes():
    import matplotlib.pyplot as plt

    d = datasets.thermal_process(n_samples=300)
    model = ARX(*d.orders, dt=d.dt).fit(d.u, d.y)
    ci = parameter_intervals(model)
    with pytest.raises(ValueError, match=r"`theta` must have the shape of the estimate \(2,\); "
                                         r"got \(3,\)"):
        ci.contains([0.1, 0.2, 0.3])
    with pytest.raises(ValueError, match=r"`theta` must have the shape .*; got \(2, 1\)"):
        ci.contains([[-0.95], [0.1]])  # the same size but not the same layout
    band = frequency_response_band(model, n_draws=50, rng=0)
    with pytest.raises(ValueError, match=r"`response` must have shape \(1, 1, 300\); got \(299,\)"):
        band.contains(band.response[0, 0, 1:])
    assert band.contains(band.response[0, 0]).shape == (1, 1, 300)
    ax_mag, ax_phase = band.plot_bode()
    assert ax_mag.figure is ax_phase.figure and ax_phase.get_ylabel() == "phase (deg)"
    plt.close("all")


def test_band_uses_the_fitted_structure_after_set_params():
    """Changing the constructor orders without refitting must not reslice theta_."""
    d = datasets.dc_motor(n_samples=400)
    model = ARX(2, 2, 1, dt=d.dt).fit(d.u, d.y)
    before = frequency_response_band(model, n_draws=20, rng=0).response
    model.set_params(na=3, nk=2)
    after = frequency_response_band(model, n_draws=20, rng=0).response
    np.testing.assert_array_equal(after, before)
