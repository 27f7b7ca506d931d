"""Simulated plants with known truth and the excitation signals of rlsfilt.datasets."""

import control
import numpy as np
import pytest
from scipy import signal

from rlsfilt import ARX, datasets
from rlsfilt.datasets import (
    PLANTS,
    Dataset,
    dc_motor,
    mass_spring_damper,
    multisine,
    nonminimum_phase,
    prbs,
    steps,
    thermal_process,
    time_varying,
    white_noise,
)

NAMES = ["thermal_process", "dc_motor", "mass_spring_damper", "nonminimum_phase", "time_varying"]


def test_registry_and_public_names():
    assert list(PLANTS) == NAMES
    for name in NAMES:
        assert PLANTS[name] is getattr(datasets, name)
    assert set(datasets.__all__) >= {"Dataset", "PLANTS", "prbs", "white_noise", "multisine",
                                     "steps", *NAMES}


@pytest.mark.parametrize("name", NAMES)
def test_default_call_returns_complete_dataset(name):
    ds = PLANTS[name]()
    assert isinstance(ds, Dataset) and ds.name == name
    N = ds.n_samples
    assert ds.u.shape == ds.y.shape == ds.y_clean.shape == (N,) and N >= 1000
    assert np.isfinite(ds.u).all() and np.isfinite(ds.y).all()
    assert isinstance(ds.plant, control.TransferFunction)
    assert ds.plant.isdtime(strict=True) and ds.plant.dt == ds.dt
    assert (ds.plant.ninputs, ds.plant.noutputs) == (1, 1)
    assert ds.a.shape == (ds.na,) and ds.b.shape == (ds.nb,) and ds.orders == (ds.na, ds.nb, ds.nk)
    assert ds.noise == "white" and ds.noise_std > 0
    assert ds.description and "\n" not in ds.description
    np.testing.assert_allclose(ds.t, np.arange(N) * ds.dt)
    np.testing.assert_array_equal(ds.theta, np.r_[ds.a, ds.b])
    assert name in repr(ds) and ds.description in repr(ds)
    assert np.std(ds.u) > 0 and np.std(ds.y_clean) > 5 * ds.noise_std


@pytest.mark.parametrize("name", NAMES)
def test_reproducible_by_seed(name):
    gen = PLANTS[name]
    a, b, c = gen(), gen(), gen(rng=1)
    np.testing.assert_array_equal(a.u, b.u)
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.array_equal(a.y, c.y)
    d, e = gen(rng=np.random.default_rng(7)), gen(rng=7)
    np.testing.assert_array_equal(d.y, e.y)


@pytest.mark.parametrize("name", NAMES)
def test_truth_matches_plant(name):
    """The clean output is the plant's forced response, and (a, b, nk) is the plant."""
    ds = PLANTS[name](n_samples=400)
    t = ds.t
    resp = control.forced_response(ds.plant, t, ds.u).outputs
    if name != "time_varying":
        scale = np.max(np.abs(resp))
        np.testing.assert_allclose(ds.y_clean, resp, rtol=0, atol=1e-9 * scale)
    else:  # before the change the plant is the initial one
        k = ds.change_time
        np.testing.assert_allclose(ds.y_clean[:k], resp[:k], rtol=0, atol=1e-9)
    true = ds.true_model()
    assert true.noise_variance_ == pytest.approx(ds.noise_std ** 2)
    for z in (1.0, 0.5 + 0.5j, -0.7, 2.0j):
        assert complex(true.to_tf()(z)) == pytest.approx(complex(ds.plant(z)), rel=1e-10)


def _z_scores(ds, n=None):
    n = ds.n_samples if n is None else n
    model = ARX(*ds.orders, dt=ds.dt).fit(ds.u[:n], ds.y[:n])
    return (model.theta_ - ds.theta) / model.std_errors_


@pytest.mark.parametrize("name", NAMES)
def test_plant_recovered_by_right_structure_within_noise(name):
    """Five seeds; each parameter within 4.5 standard errors (white equation error)."""
    for seed in range(5):
        ds = PLANTS[name](rng=seed)
        z = _z_scores(ds, ds.change_time)
        assert np.all(np.abs(z) < 4.5), (seed, z)


def test_thermal_process_closed_form():
    ds = thermal_process(gain=3.0, time_constant=10.0, delay=2, dt=0.5)
    p = np.exp(-0.5 / 10.0)
    np.testing.assert_allclose(ds.a, [-p], rtol=1e-12)
    np.testing.assert_allclose(ds.b, [3.0 * (1 - p)], rtol=1e-12)
    assert ds.orders == (1, 1, 3)
    assert complex(ds.plant.dcgain()).real == pytest.approx(3.0, rel=1e-12)
    no_delay = thermal_process(delay=0)
    assert no_delay.nk == 1


def test_zero_order_hold_is_exact_for_steps():
    """The discrete plants agree with their continuous models at the samples for a step."""
    cases = [
        (dc_motor(n_samples=200, input=np.ones(200)),
         signal.lti([0.01], [0.01 * 0.5, 0.01 * 1 + 0.1 * 0.5, 0.1 * 1 + 0.01 ** 2])),
        (mass_spring_damper(n_samples=200, input=np.ones(200)),
         signal.lti([1.0], [1.0, 0.1, 4.0])),
        (nonminimum_phase(n_samples=200, input=np.ones(200)),
         signal.lti([-2.0, 1.0], [0.5, 1.5, 1.0])),
    ]
    for ds, cont in cases:
        _, yc = signal.step(cont, T=ds.t)
        np.testing.assert_allclose(ds.y_clean, yc, rtol=0, atol=1e-8 * np.max(np.abs(yc)))


def test_mass_spring_damper_is_lightly_damped():
    ds = mass_spring_damper()
    s = np.roots([1.0, 0.1, 4.0])
    np.testing.assert_allclose(np.sort_complex(ds.plant.poles()), np.sort_complex(np.exp(s * 0.1)),
                               rtol=1e-10)
    zeta = -np.cos(np.angle(np.log(ds.plant.poles()[0]) / ds.dt))
    assert zeta == pytest.approx(0.025, rel=1e-9)


def test_nonminimum_phase_zero_and_inverse_response():
    ds = nonminimum_phase(n_samples=100, input=np.ones(100), noise_std=0.0)
    zeros = ds.plant.zeros()
    assert len(zeros) == 1 and abs(zeros[0]) > 1
    assert abs(zeros[0]) == pytest.approx(np.exp(0.5 * 0.2), rel=0.05)
    first = ds.y[np.flatnonzero(ds.y)[0]]
    assert first < 0 and ds.y[-1] == pytest.approx(1.0, rel=1e-3)  # wrong way first, gain 1


@pytest.mark.parametrize("name", ["thermal_process", "dc_motor", "mass_spring_damper",
                                  "nonminimum_phase"])
def test_noise_models(name):
    gen = PLANTS[name]
    std = 0.1
    A = np.r_[1.0, gen().a]
    for kind in ("white", "colored", "output"):
        ds = gen(noise=kind, noise_std=std, rng=3)
        B = np.r_[np.zeros(ds.nk), ds.b]
        eq_err = signal.lfilter(A, [1.0], ds.y) - signal.lfilter(B, [1.0], ds.u)
        out_err = ds.y - ds.y_clean
        if kind == "white":
            e = eq_err
        elif kind == "colored":  # AR(1) equation error with pole 0.9
            e = signal.lfilter([1.0, -0.9], [1.0], eq_err)
            assert np.corrcoef(eq_err[1:], eq_err[:-1])[0, 1] > 0.8
        else:
            e = out_err
        assert e.std() == pytest.approx(std, rel=0.1)
        assert abs(np.corrcoef(e[1:], e[:-1])[0, 1]) < 4 / np.sqrt(len(e))


def test_colored_noise_biases_arx():
    """The datasets show ARX bias: colored equation error pushes estimates far off."""
    for gen in (thermal_process, nonminimum_phase):
        assert np.abs(_z_scores(gen(noise="colored"))).max() > 8
    assert np.abs(_z_scores(dc_motor(noise="output", noise_std=0.2))).max() > 8


def test_time_varying_truth():
    ds = time_varying(n_samples=600, noise_std=0.0)
    assert ds.change_time == 300 and ds.theta_true.shape == (600, 4)
    np.testing.assert_array_equal(ds.theta_true[:300], np.tile([-1.5, 0.7, 1.0, 0.5], (300, 1)))
    np.testing.assert_array_equal(ds.theta_true[300:], np.tile([-1.2, 0.5, 0.6, 0.9], (300, 1)))
    np.testing.assert_array_equal(ds.theta, ds.theta_true[0])
    Phi, target = ARX(2, 2, 1).regressors(ds.u, ds.y)
    np.testing.assert_allclose(np.sum(Phi * ds.theta_true[2:], axis=1), target, atol=1e-12)
    np.testing.assert_allclose(ds.y, ds.y_clean)
    after = ARX.from_tf(ds.plant_after)
    np.testing.assert_allclose(after.theta_, ds.theta_true[-1], atol=1e-14)
    drift = time_varying(n_samples=500, kind="drift")
    assert drift.change_time is None
    np.testing.assert_allclose(drift.theta_true[0], [-1.5, 0.7, 1.0, 0.5])
    np.testing.assert_allclose(drift.theta_true[-1], [-1.2, 0.5, 0.6, 0.9])
    np.testing.assert_allclose(np.diff(drift.theta_true, 2, axis=0), 0, atol=1e-14)


def test_time_varying_is_tracked_by_forgetting():
    ds = time_varying()
    model = ARX(*ds.orders).fit(ds.u, ds.y, method="rls", lam=0.97)
    hist = model.theta_history_
    k = ds.change_time - model.max_lag  # row of the sample just before the change
    np.testing.assert_allclose(hist[k - 1], ds.theta_true[ds.change_time - 1], atol=0.05)
    np.testing.assert_allclose(hist[-1], ds.theta_true[-1], atol=0.05)
    fixed = ARX(*ds.orders).fit(ds.u, ds.y)  # no forgetting: stuck between the two
    assert np.abs(fixed.theta_ - ds.theta_true[-1]).max() > 0.1


def test_dataset_helpers():
    pd = pytest.importorskip("pandas")
    ds = dc_motor(n_samples=300)
    frame = ds.to_frame()
    assert list(frame.columns) == ["u", "y"] and frame.index.name == "t"
    np.testing.assert_array_equal(frame["y"].to_numpy(), ds.y)
    assert isinstance(frame, pd.DataFrame)
    np.testing.assert_allclose(ds.true_model().simulate(ds.u), ds.y_clean, atol=1e-10)
    assert ds.noise_variance == ds.noise_std ** 2
    with pytest.raises(AttributeError):
        ds.u = np.zeros(3)  # frozen


@pytest.mark.parametrize("kind", ["prbs", "white", "multisine", "steps"])
def test_plants_accept_every_input_kind(kind):
    ds = thermal_process(n_samples=500, input=kind)
    assert ds.u.shape == (500,) and np.std(ds.u) > 0
    z = _z_scores(ds)
    assert np.all(np.abs(z) < 4.5)


# ----------------------------------------------------------------------
# input signals
# ----------------------------------------------------------------------
def test_prbs_is_a_maximum_length_sequence():
    M = 2 ** 7 - 1
    u = prbs(M, nbits=7)
    assert set(np.unique(u)) == {-1.0, 1.0}
    assert u.sum() == 1.0  # one more +1 than -1
    for lag in range(1, M):
        assert np.dot(u, np.roll(u, lag)) == -1.0  # two-level periodic autocorrelation
    held = prbs(100, hold=4, amplitude=2.0, offset=1.0)
    assert set(np.unique(held)) == {-1.0, 3.0}
    assert np.all(held.reshape(25, 4) == held.reshape(25, 4)[:, :1])
    np.testing.assert_array_equal(prbs(50), prbs(50))
    assert not np.array_equal(prbs(50), prbs(50, rng=1))
    assert prbs().shape == (1000,)


def test_white_noise_and_steps():
    w = white_noise(20000, std=2.0, mean=1.0)
    assert w.std() == pytest.approx(2.0, rel=0.03) and w.mean() == pytest.approx(1.0, abs=0.06)
    s = steps(250, hold=50, amplitude=3.0)
    blocks = s.reshape(5, 50)
    assert np.all(blocks == blocks[:, :1]) and np.all(np.abs(s) <= 3.0)
    assert len(np.unique(s)) == 5
    np.testing.assert_array_equal(steps(7, hold=2, levels=[0, 1]), [0, 0, 1, 1, 0, 0, 1])
    assert white_noise().shape == steps().shape == (1000,)


def test_multisine_spectrum():
    N = 1000
    u = multisine(N, n_components=10, band=(0.1, 0.5), rms=2.0)
    assert np.sqrt(np.mean(u ** 2)) == pytest.approx(2.0, rel=1e-12)
    spec = np.abs(np.fft.rfft(u))
    lines = np.flatnonzero(spec > 1e-8 * spec.max())
    assert len(lines) == 10
    assert lines.min() >= 0.1 * N / 2 and lines.max() <= 0.5 * N / 2
    crest = np.max(np.abs(u)) / 2.0
    assert crest < 2.5  # Schroeder phases keep the crest factor low
    r = multisine(N, n_components=10, phases="random", rng=1)
    assert not np.allclose(r, multisine(N, n_components=10))
    assert multisine().shape == (1000,)


@pytest.mark.parametrize("call, exc, match", [
    (lambda: prbs(0), ValueError, r"`n_samples` must be >= 1; got 0"),
    (lambda: prbs(10, hold=0), ValueError, r"`hold` must be >= 1; got 0"),
    (lambda: prbs(10, nbits=40), ValueError, r"`nbits` must be <= 32; got 40"),
    (lambda: prbs(10.0), TypeError, r"`n_samples` must be an integer"),
    (lambda: white_noise(10, std=-1), ValueError, r"`std` must be a finite value >= 0; got -1.0"),
    (lambda: white_noise(10, std=np.nan), ValueError,
     r"`std` must be a finite value >= 0; got nan"),
    (lambda: white_noise(10, mean=np.inf), ValueError, r"`mean` must be a finite number; got inf"),
    (lambda: prbs(10, amplitude=np.nan), ValueError,
     r"`amplitude` must be a finite number; got nan"),
    (lambda: prbs(10, offset=np.inf), ValueError, r"`offset` must be a finite number; got inf"),
    (lambda: prbs(10, rng="seed"), TypeError,
     r"`rng` must be None, a non-negative integer seed or a numpy.random.Generator; got 'seed'"),
    (lambda: white_noise(10, rng=-3), ValueError, r"`rng` must be None, a non-negative integer"),
    (lambda: multisine(100, rms=np.nan), ValueError, r"`rms` must be a finite value >= 0; got nan"),
    (lambda: multisine(100, rms=-1.0), ValueError, r"`rms` must be a finite value >= 0; got -1.0"),
    (lambda: steps(10, amplitude=np.inf), ValueError,
     r"`amplitude` must be a finite value >= 0; got inf"),
    (lambda: steps(10, levels=[0.0, np.nan]), ValueError, r"`levels` must be finite; got nan at "
                                                          r"index 1"),
    (lambda: steps(10, levels="ab"), TypeError, r"`levels` must be numeric array-like"),
    (lambda: multisine(100, band=(0.5, 0.2)), ValueError,
     r"`band` must satisfy 0 <= low < high <= 1; got \(0.5, 0.2\)"),
    (lambda: multisine(100, band=0.5), ValueError, r"`band` must be a pair"),
    (lambda: multisine(100, n_components=80), ValueError,
     r"`n_components` must be <= 49 \(frequencies in the band\); got 80"),
    (lambda: multisine(100, phases="zero"), ValueError,
     r"`phases` must be 'schroeder' or 'random'; got 'zero'"),
    (lambda: steps(10, levels=[]), ValueError, r"`levels` must hold at least one value"),
])
def test_input_errors(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


@pytest.mark.parametrize("call, exc, match", [
    (lambda: thermal_process(input="chirp"), ValueError,
     r"`input` must be one of \['multisine', 'prbs', 'steps', 'white'\] or an array; "
     r"got 'chirp'"),
    (lambda: thermal_process(n_samples=10, input=np.ones(9)), ValueError,
     r"`input` must have n_samples = 10 samples; got 9"),
    (lambda: thermal_process(n_samples=3, input=[1, np.nan, 1]), ValueError,
     r"`input` must be finite; got nan at index 1"),
    (lambda: dc_motor(noise="pink"), ValueError,
     r"`noise` must be one of \['white', 'colored', 'output'\]; got 'pink'"),
    (lambda: dc_motor(noise_std=-0.1), ValueError, r"`noise_std` must be a finite value >= 0"),
    (lambda: thermal_process(gain=np.inf), ValueError, r"`gain` must be a finite number; got inf"),
    (lambda: thermal_process(gain=0.0), ValueError, r"`gain` must be a finite nonzero number"),
    (lambda: dc_motor(amplitude=np.nan), ValueError,
     r"`amplitude` must be a positive finite number; got nan"),
    (lambda: dc_motor(rng="x"), TypeError, r"`rng` must be None, a non-negative integer seed"),
    (lambda: thermal_process(time_constant=0), ValueError,
     r"`time_constant` must be a positive finite number; got 0.0"),
    (lambda: thermal_process(delay=-1), ValueError, r"`delay` must be >= 0; got -1"),
    (lambda: mass_spring_damper(damping=-1), ValueError, r"`damping` must be a finite value >= 0"),
    (lambda: nonminimum_phase(zero=-0.5), ValueError, r"`zero` must be a positive finite number"),
    (lambda: time_varying(kind="ramp"), ValueError, r"`kind` must be 'jump' or 'drift'; got"),
    (lambda: time_varying(a_after=(-2.0, 1.2)), ValueError,
     r"`a_after` must give a stable plant \(poles inside the unit circle\)"),
    (lambda: time_varying(b_before=(1.0,)), ValueError, r"`b_before` must have 2 entries; got 1"),
    (lambda: time_varying(kind="drift", change_time=5), ValueError,
     r"`change_time` only applies to kind='jump'"),
    (lambda: time_varying(n_samples=100, change_time=101), ValueError,
     r"`change_time` must be <= n_samples = 100; got 101"),
])
def test_plant_errors(call, exc, match):
    with pytest.raises(exc, match=match):
        call()


# ----------------------------------------------------------------------
# Dataset is an IOData; the measured-like heat exchanger record
# ----------------------------------------------------------------------
def test_every_dataset_is_an_iodata():
    from rlsfilt.data import IOData

    ds = dc_motor(n_samples=300)
    assert isinstance(ds, IOData) and ds.n_experiments == 1
    assert ds.input_names == ("u",) and ds.output_names == ("y",) and (ds.u0, ds.y0) == (0, 0)
    est, val = ds.split(0.5)
    np.testing.assert_array_equal(val.y, ds.y[150:])
    assert type(est) is IOData  # derived records are plain IOData (no truth)
    assert ds.getexp(0).plant is ds.plant


def test_heat_exchanger_truth_per_experiment():
    from rlsfilt.datasets import heat_exchanger

    ds = heat_exchanger()
    assert (ds.n_experiments, ds.lengths, ds.orders) == (2, (1200, 800), (2, 2, 8))
    assert ds.input_names == ("flow",) and ds.output_names == ("T_out",)
    assert ds.input_units == ("%",) and ds.output_units == ("degC",)
    assert ds.experiment_names == ("run1", "run2") and ds.noise == "colored"
    with pytest.raises(ValueError, match="`y_clean` is defined for a record of one experiment"):
        _ = ds.y_clean
    # the clean output is y0 + the plant's forced response to u - u0, run by run
    for i in range(2):
        run = ds.getexp(i)
        assert isinstance(run, Dataset) and run.n_experiments == 1
        resp = control.forced_response(ds.plant, run.t, run.u - ds.u0).outputs
        np.testing.assert_allclose(run.y_clean, ds.y0 + resp, rtol=0, atol=1e-9)
        np.testing.assert_allclose(run.u.mean(), 40.0, atol=0.5)
        assert 0.05 < np.std(run.y - run.y_clean) < 0.5       # a colored drift of ~0.2 degC
        assert np.all(np.abs(np.diff(run.u)[np.diff(run.u) != 0]) == 8.0)  # PRBS +-4 %
    # the static gain of the true plant is the physical one (more flow, cooler outlet)
    assert complex(ds.plant(1.0)).real == pytest.approx(-0.6, rel=1e-10)
    assert ds.plant.dt == 1.0 and "operating point: u0 = 40, y0 = 97" in repr(ds)


def test_heat_exchanger_options_and_errors():
    from rlsfilt.datasets import heat_exchanger

    a, b = heat_exchanger(), heat_exchanger()
    np.testing.assert_array_equal(a.getexp(1).y, b.getexp(1).y)
    c = heat_exchanger(n_samples=300, delay=0, rng=3, u0=0.0, y0=20.0)
    assert c.n_experiments == 1 and c.nk == 1 and c.y_clean[0] == 20.0
    with pytest.raises(ValueError, match=r"`n_samples\[1\]` must be >= 50; got 10"):
        heat_exchanger(n_samples=(100, 10))
    with pytest.raises(ValueError, match="`gain` must be a finite nonzero number"):
        heat_exchanger(gain=0.0)
    with pytest.raises(ValueError, match=r"`time_constants` must be a pair"):
        heat_exchanger(time_constants=3.0)
