"""PlantComparison: python-control and scipy as oracles, small for the right
model, large for a wrong one."""

import control
import numpy as np
import pytest
from scipy.signal import freqz, lfilter

from rlsfilt import ARX, datasets
from rlsfilt.exceptions import NotFittedError
from rlsfilt.validation import PlantComparison


@pytest.mark.parametrize("make", [datasets.thermal_process, datasets.dc_motor,
                                  datasets.nonminimum_phase])
def test_small_for_right_model_large_for_wrong(make):
    d = make()
    right = PlantComparison(ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y), d.plant)
    wrong = PlantComparison(ARX(1, 1, 1, dt=d.dt).fit(d.u, d.y), d.plant)
    assert right.frequency_error < 0.1
    assert right.dc_gain_error < 0.05
    assert right.step_error < 0.05
    assert right.max_pole_distance < 0.01
    assert wrong.frequency_error > 1.0
    assert wrong.dc_gain_error > 0.5
    assert wrong.step_error > 0.2
    assert wrong.max_pole_distance > 5 * right.max_pole_distance
    assert wrong.unmatched_plant_poles.size >= 1


def test_mass_spring_damper_sampling_zero_and_custom_grid():
    d = datasets.mass_spring_damper()
    model = ARX(d.na, d.nb, d.nk, dt=d.dt).fit(d.u, d.y)
    full = PlantComparison(model, d.plant)
    # the sampled plant has a zero at z = -0.9966: the relative error is large at Nyquist only
    assert full.frequency_error > 1.0
    assert full.relative_error[0, 0, full.omega < 0.9 * full.omega[-1]].max() < 0.1
    grid = np.linspace(0.01, 0.9 * np.pi / d.dt, 200)
    part = PlantComparison(model, d.plant, omega=grid)
    np.testing.assert_array_equal(part.omega, grid)
    assert part.frequency_error < 0.1


def test_numbers_against_scipy_oracles():
    b, a = [0.0, 0.4, 0.2], [1.0, -1.1, 0.3]
    bm, am = [0.0, 0.41, 0.19], [1.0, -1.08, 0.29]
    dt = 0.05
    plant = control.tf(b, a, dt)
    model = ARX.from_polynomials(am[1:], bm[1:], nk=1, dt=dt)
    cmp = PlantComparison(model, plant, n_points=64, n_steps=120)
    _, hp = freqz(b, a, worN=cmp.omega * dt)
    _, hm = freqz(bm, am, worN=cmp.omega * dt)
    np.testing.assert_allclose(cmp.response_plant[0, 0], hp, rtol=1e-12)
    np.testing.assert_allclose(cmp.response_model[0, 0], hm, rtol=1e-12)
    assert cmp.frequency_error == pytest.approx(np.max(np.abs(hm - hp) / np.abs(hp)), rel=1e-12)
    assert cmp.omega[-1] == pytest.approx(np.pi / dt, rel=1e-14)
    assert cmp.omega[0] == pytest.approx(1e-3 * np.pi / dt, rel=1e-12)
    np.testing.assert_allclose(cmp.time, np.arange(120) * dt)
    np.testing.assert_allclose(cmp.step_plant[0, 0], lfilter(b, a, np.ones(120)), atol=1e-12)
    np.testing.assert_allclose(cmp.step_model[0, 0], lfilter(bm, am, np.ones(120)), atol=1e-12)
    kp, km = sum(b) / sum(a), sum(bm) / sum(am)
    assert cmp.dc_gain_error == pytest.approx(abs(km - kp) / abs(kp), rel=1e-12)
    # poles matched by distance, whatever order python-control returns them in
    pp, pm = np.sort(np.roots(a)), np.sort(np.roots(am))
    np.testing.assert_allclose(np.sort(cmp.poles_plant.real), pp.real, rtol=1e-12)
    np.testing.assert_allclose(np.sort(cmp.pole_distances), np.sort(np.abs(pm - pp)), rtol=1e-9)


def test_continuous_plant_is_sampled_with_zoh():
    plant_c = control.tf([2.0], [1.0, 3.0, 2.0])
    dt = 0.1
    exact = plant_c.sample(dt, method="zoh")
    cmp = PlantComparison(exact, plant_c)
    assert cmp.frequency_error < 1e-9
    assert cmp.step_error < 1e-9
    assert cmp.max_pole_distance < 1e-12
    assert cmp.dc_gain_error < 1e-12
    # a state-space plant works the same way
    assert PlantComparison(exact, control.ss(plant_c)).frequency_error < 1e-9


def test_integrator_plant_dc_gain():
    plant = control.tf([1.0], [1.0, -1.0], 1.0)
    assert PlantComparison(plant, plant).dc_gain_error == 0.0
    leaky = control.tf([1.0], [1.0, -0.99], 1.0)
    assert PlantComparison(leaky, plant).dc_gain_error == np.inf


def test_summary_and_plot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = datasets.dc_motor()
    cmp = PlantComparison(ARX(2, 2, 1, dt=d.dt).fit(d.u, d.y), d.plant)
    text = str(cmp.summary())
    assert "max relative frequency-response error" in text
    assert text.count("vs plant") == 2
    fig = cmp.plot()
    assert len(fig.axes) == 3
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["plant", "model"]
    assert fig.axes[2].get_xlabel() == "time (s)"
    fig2 = plt.figure()
    assert cmp.plot(fig=fig2) is fig2
    assert "frequency_error=" in repr(cmp)
    plt.close("all")


def test_plot_methods_pass_their_options_to_the_plotting_functions():
    """The methods are the plotting functions applied to the comparison: their keyword
    options (the band, the units) reach the figure."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from rlsfilt.validation import frequency_response_band

    d = datasets.dc_motor(n_samples=400)
    model = ARX(2, 2, 1, dt=d.dt).fit(d.u, d.y)
    cmp = PlantComparison(model, d.plant)
    band = frequency_response_band(model, n_draws=50, rng=0)
    fig = cmp.plot(band=band)
    labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert labels == ["95% band", "plant", "model"]
    ax_mag, _ = cmp.plot_bode(band=band)
    assert "95% band (parameters)" in ax_mag.get_title()
    ax = cmp.plot_step(input_unit="V", output_unit="rad/s")
    assert ax.get_ylabel() == "y (rad/s) per 1 V of u"
    with pytest.raises(TypeError, match="unexpected keyword argument 'units'"):
        cmp.plot_step(units="V")
    plt.close("all")


def test_plant_comparison_errors():
    plant = control.tf([1.0], [1.0, -0.5], 0.1)
    with pytest.raises(TypeError, match="`plant` must be a python-control LTI system"):
        PlantComparison(plant, ([1.0], [1.0, -0.5]))
    with pytest.raises(TypeError, match="`model` must be a fitted ARX model or a python-control"):
        PlantComparison("model", plant)
    with pytest.raises(NotFittedError, match="not fitted yet"):
        PlantComparison(ARX(1, 1, dt=0.1), plant)
    with pytest.raises(ValueError, match="`plant` must have the model's sample time 0.2; "
                                         "got dt=0.1"):
        PlantComparison(control.tf([1.0], [1.0, -0.5], 0.2), plant)
    with pytest.raises(ValueError, match="`model` must be a discrete-time system"):
        PlantComparison(control.tf([1.0], [1.0, 1.0]), plant)
    with pytest.raises(ValueError, match="unspecified sample time"):
        PlantComparison(control.tf([1.0], [1.0, -0.5], True), control.tf([1.0], [1.0, 1.0]))
    with pytest.raises(ValueError, match="same numbers of inputs and outputs"):
        PlantComparison(plant, control.tf([[[1.0], [1.0]]], [[[1.0, -0.5], [1.0, -0.2]]], 0.1))
    with pytest.raises(ValueError, match=r"`omega` must hold finite frequencies in \[0, 31.4159"):
        PlantComparison(plant, plant, omega=[1.0, 100.0])
    with pytest.raises(ValueError, match="`n_points` must be >= 2; got 1"):
        PlantComparison(plant, plant, n_points=1)
