"""`compare` (MATLAB ``compare``) and the fits `validate` reports with it.

The oracle for the estimated initial state is built here by hand: the free
responses of the model's difference equation are the solutions of the
homogeneous recursion ``A_t(q) y = 0`` (a loop over samples), the forced
response is scipy's ``lfilter`` of the model's own polynomials, and the
initial state that minimizes the simulation error is ``numpy.linalg.lstsq``
over them: nothing of `compare` is used.
"""

import inspect
import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

import rlsfilt
from rlsfilt import ARMAX, ARX, BJ, OE, compare, fit_percent, validate
from rlsfilt.validation import Comparison


def _prbs(gen, n, hold):
    return np.repeat(gen.choice([-1.0, 1.0], n // hold + 1), hold)[:n]


_B1, _F1 = [0.1, 0.08], [1.0, -1.6, 0.65]          # input 1: delay 0, slow
_B2, _F2 = [0.0, 0.2, 0.1], [1.0, -1.2, 0.4]       # input 2: delay 1


def _two_input_record(seed, n, warm=300):
    """Two inputs with different delays around an operating point far from zero (the
    output near 60, varying by a few units), colored output noise, started in steady
    operation (the first `warm` samples dropped), as a measured record is."""
    gen = np.random.default_rng(seed)
    m = n + warm
    u = np.column_stack([20.0 + _prbs(gen, m, 5), -8.0 + _prbs(gen, m, 3)])
    y = (lfilter(_B1, _F1, u[:, 0]) + lfilter(_B2, _F2, u[:, 1])
         + lfilter([1.0], [1.0, -0.9], 0.05 * gen.standard_normal(m)))
    return u[warm:], y[warm:]


@pytest.fixture(scope="module")
def true_oe():
    """OE([2, 2], [2, 2], [0, 1]) with the true polynomials (fitted on noise-free data)."""
    gen = np.random.default_rng(7)
    u = np.column_stack([_prbs(gen, 600, 5), _prbs(gen, 600, 3)])
    y = lfilter(_B1, _F1, u[:, 0]) + lfilter(_B2, _F2, u[:, 1])
    model = OE([2, 2], [2, 2], [0, 1]).fit(u, y)
    np.testing.assert_allclose(np.concatenate(model.f_), [-1.6, 0.65, -1.2, 0.4], atol=1e-8)
    return model


def _homogeneous_basis(a, N):
    """Solutions of ``a(q) y(t) = 0`` for t >= n, y(0..n-1) the unit vectors (a loop)."""
    n = len(a) - 1
    E = np.zeros((N, n))
    for j in range(n):
        E[j, j] = 1.0
        for t in range(n, N):
            E[t, j] = -sum(a[k] * E[t - k, j] for k in range(1, n + 1))
    return E


def _oracle_fit(model, u, y):
    """The least-squares initial condition of an OE model's simulation, by hand."""
    b = [np.r_[np.zeros(k), bi] for k, bi in zip(model.nk, model.b_)]
    f = [np.r_[1.0, fi] for fi in model.f_]
    forced = sum(lfilter(bi, fi, u[:, i]) for i, (bi, fi) in enumerate(zip(b, f)))
    a = np.convolve(f[0], f[1])
    # the realization has deg(A_t) states when no numerator is longer: here 4 = 2 + 2
    assert max(len(np.convolve(b[0], f[1])), len(np.convolve(b[1], f[0]))) <= len(a)
    E = _homogeneous_basis(a, len(y))
    c = np.linalg.lstsq(E, y - forced, rcond=None)[0]
    yhat = forced + E @ c
    return yhat, fit_percent(y, yhat)


def test_compare_estimates_the_least_squares_initial_state(true_oe):
    u, y = _two_input_record(2, 101)
    c = compare(true_oe, u, y)
    yhat, fit = _oracle_fit(true_oe, u, y)
    assert isinstance(c, Comparison) and c.initial == "estimate" and c.start == 0
    np.testing.assert_allclose(c.y_hat, yhat, rtol=1e-9, atol=1e-8)
    assert c.fit == pytest.approx(fit, abs=1e-8)
    # from rest the operating point (y near 60) costs the short record everything
    rest = compare(true_oe, u, y, initial="zero")
    np.testing.assert_allclose(rest.y_hat, true_oe.simulate(u), rtol=1e-12, atol=1e-12)
    assert rest.fit < 0 < 90 < c.fit


@pytest.mark.parametrize("horizon", [1, 2, 3, 7])
def test_k_step_prediction_of_oe_is_its_simulation_fit_included(true_oe, horizon):
    # an OE predictor is its simulation at every horizon (H = 1); the k-step predictor's
    # polynomials carried k - 1 trailing zeros (h = [1, 0, ..]), each a state whose free
    # response raised the k-step fit above the simulation fit of the same predictions
    u, y = _two_input_record(2, 101)
    yhat, fit = _oracle_fit(true_oe, u, y)
    c = compare(true_oe, u, y, horizon=horizon)
    np.testing.assert_allclose(c.y_hat, yhat, rtol=1e-9, atol=1e-8)
    assert c.fit == pytest.approx(fit, abs=1e-8)
    assert len(c.x0[0]) == len(compare(true_oe, u, y).x0[0]) == 4
    np.testing.assert_allclose(true_oe.predict(u, y, horizon=horizon), true_oe.simulate(u),
                               rtol=1e-12, atol=1e-12)


def test_short_two_input_oe_record_gets_a_sane_validate_fit(true_oe):
    """Issue #28, 1 and 3: two inputs with different delays, an operating point far from
    zero, 101 validation samples, default arguments."""
    u, y = _two_input_record(2, 101)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # the operating-point warning
        rep = validate(true_oe, u, y)               # max_lag="auto": no InsufficientDataError
    _, fit = _oracle_fit(true_oe, u, y)
    assert rep.simulation_fit == pytest.approx(fit, abs=1e-8)      # was -5959 %
    assert rep.prediction_fit == rep.simulation_fit                 # OE: the same predictor
    assert rep.simulation_fit > 90
    assert rep.initial == "estimate" and "estimated" in str(rep.summary())
    # the simulation the report holds is the model's, from the state it reports
    control = pytest.importorskip("control")
    sim = control.forced_response(true_oe.to_ss(), np.arange(101.0), u.T, X0=rep.x0[0])
    sim = np.ravel(sim.outputs)
    np.testing.assert_allclose(rep.y_simulated, sim, rtol=1e-9, atol=1e-8)


def test_predictions_and_measured_start(rng):
    u = rng.standard_normal(300)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.1 * rng.standard_normal(300)
    arx = ARX(2, 2, 1).fit(u, y)
    for k in (1, 3):
        np.testing.assert_allclose(compare(arx, u, y, initial="zero", horizon=k).y_hat,
                                   arx.predict(u, y, horizon=k), rtol=1e-12, atol=1e-12)
    m = compare(arx, u, y, initial="measured")
    assert m.start == 2
    np.testing.assert_allclose(m.y_hat, arx.simulate(u, y0=y[:2]), rtol=1e-12, atol=1e-12)
    assert m.fit == pytest.approx(fit_percent(y[2:], m.y_hat[2:]), rel=1e-12)
    p = compare(arx, u, y, initial="measured", horizon=1)
    Phi, target = arx.regressors(u, y)
    np.testing.assert_allclose(p.y_hat[2:], Phi @ arx.theta_, rtol=1e-12, atol=1e-12)
    # a horizon as long as the record is the simulation
    np.testing.assert_allclose(compare(arx, u, y, horizon=300).y_hat, compare(arx, u, y).y_hat)


def test_measured_is_refused_where_the_past_does_not_define_the_state(rng):
    u = rng.standard_normal(300)
    y = lfilter([0, 0.5], [1, -0.8], u) + 0.1 * rng.standard_normal(300)
    with pytest.raises(ValueError, match=r"initial='measured' does not apply to the "
                                         r"simulation of OE: its output B/F u is not the "
                                         r"measured output.*use initial='estimate'"):
        compare(OE(1, 1).fit(u, y), u, y, initial="measured")
    armax = ARMAX(1, 1, 1).fit(u, y)
    compare(armax, u, y, initial="measured")          # A y = B u from the measured past
    with pytest.raises(ValueError, match=r"1-step prediction of ARMAX: its predictor filters "
                                         r"by C F"):
        compare(armax, u, y, initial="measured", horizon=1)
    with pytest.raises(ValueError, match=r"`initial` must be 'estimate', 'zero' or "
                                         r"'measured'; got 'e'"):
        compare(armax, u, y, initial="e")
    with pytest.raises(ValueError, match="`initial` must be"):
        validate(armax, u, y, initial="rest")


def test_every_experiment_has_its_own_initial_state(true_oe):
    (u1, y1), (u2, y2) = _two_input_record(3, 150), _two_input_record(4, 120)
    c = compare(true_oe, [u1, u2], [y1, y2])
    assert len(c.x0) == 2 and c.experiment_lengths == (150, 120)
    np.testing.assert_allclose(c.y_hat[:150], compare(true_oe, u1, y1).y_hat, atol=1e-9)
    np.testing.assert_allclose(c.y_hat[150:], compare(true_oe, u2, y2).y_hat, atol=1e-9)
    assert c.fit == pytest.approx(fit_percent(np.r_[y1, y2], c.y_hat), rel=1e-12)


def test_defaults_match_matlab_and_the_command_line(monkeypatch):
    """`validate` defaults: max_lag="auto" (the CLI's) and initial="estimate" (MATLAB's);
    the CLI passes neither, so it uses the library's."""
    params = inspect.signature(validate).parameters
    assert params["max_lag"].default == "auto" and params["initial"].default == "estimate"
    assert inspect.signature(compare).parameters["initial"].default == "estimate"
    import rlsfilt.cli as cli

    seen = {}

    def spy(*args, **kwargs):
        seen.update(kwargs)
        return "report"

    monkeypatch.setattr(cli, "validate", spy)

    class Progress:
        def task(self, _):
            import contextlib
            return contextlib.nullcontext()

    u = np.zeros(50)
    assert cli._validate(ARX(1, 1), u, u, 1.0, {}, Progress()) == "report"
    assert "max_lag" not in seen and "initial" not in seen
    assert rlsfilt.compare is compare


def _colored(rng, n=1500):
    u = _prbs(rng, n, 3)
    v = lfilter([1.0], [1.0, -0.95], 0.1 * rng.standard_normal(n))
    return u, lfilter([0, 0.5, 0.3], [1, -1.2, 0.5], u) + v


def test_verdicts_per_model_class(rng):
    """Issue #28, 4: OE and IV fits are judged by the input test; non-white residuals point
    to a noise model, not to other orders."""
    u, y = _colored(rng)
    oe = OE(2, 2, 1).fit(u, y)
    rep = validate(oe, u, y)
    assert not all(r.is_white for r in rep.residuals) and rep.residuals[0].is_independent
    assert rep.judged_by_input and rep.passed
    text = str(rep.summary())
    assert "fit BJ or ARMAX" in text and "consider other orders" not in text
    assert "fit BJ or ARMAX" in rep._repr_html_()
    out = rep.to_dict()
    assert out["judged_by_input"] is True and out["passed"] is True
    assert out["initial_condition"] == "estimate" and "estimated" in out["initial_condition_text"]
    iv = ARX(2, 2, 1).fit(u, y, method="iv")
    rep_iv = validate(iv, u, y)
    assert rep_iv.judged_by_input and "an instrumental-variable fit" in rep_iv.verdict
    # ARX by least squares has a noise model (1/A): judged by both tests, as before
    rep_ls = validate(ARX(2, 2, 1).fit(u, y), u, y)
    assert not rep_ls.judged_by_input and not rep_ls.passed
    assert "FAILED" in rep_ls.verdict
    # BJ models the colour: both tests apply
    bj = BJ(2, 1, 1, 2, 1).fit(u, y)
    rep_bj = validate(bj, u, y)
    assert not rep_bj.judged_by_input


def test_report_and_figure_state_the_initial_condition(rng):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    u, y = _colored(rng, 400)
    model = OE(2, 2, 1).fit(u, y)
    for initial, words in (("estimate", "initial state estimated"),
                           ("zero", "zero initial state (from rest)")):
        rep = validate(model, u, y, initial=initial)
        assert f"Initial condition   : {words}" in str(rep.summary())
        assert words in rep._repr_html_()
        assert rep.to_dict()["initial_condition"] == initial
    fig = validate(model, u, y).plot()
    labels = [line.get_label() for line in fig.axes[0].get_lines()]
    assert any("x0 estimated" in s for s in labels)
    c = compare(model, u, y, horizon=2)
    ax = c.plot()
    assert ax.get_title().endswith("initial state estimated (least squares over the record)")
    assert "2-step prediction" in str(c.summary()) and c.to_dict()["horizon"] == 2
    plt.close("all")


def test_closed_loop_record_oe_fit_is_the_simulation_from_the_estimated_state():
    """Issue #28, 1: a closed-loop record (a proportional controller around the plant, the
    reference stepping, coloured noise at the output) and an OE model fitted to it:
    validate's simulation fit is compare's, equals python-control's forced response from
    the reported initial state, and is a sane number (the start from measured outputs
    through A prod(F_i) gave hundreds of millions of negative percent)."""
    control = pytest.importorskip("control")
    rng = np.random.default_rng(28)
    N = 1200
    r = np.repeat(rng.choice([-1.0, 1.0], N // 60), 60) + 5.0       # far from zero
    v = lfilter([1.0], [1, -0.9], 0.05 * rng.standard_normal(N))    # coloured
    x1 = x2 = 0.0
    u, y = np.zeros(N), np.zeros(N)
    for t in range(N):
        y[t] = x1 + v[t]                       # y = 0.5 q^-1 / (1 - 1.5 q^-1 + 0.7 q^-2) u
        u[t] = 0.3 * (r[t] - y[t]) + 0.05 * rng.standard_normal()
        x1, x2 = 1.5 * x1 - 0.7 * x2 + 0.5 * u[t], x1
    est, val = slice(0, 900), slice(900, N)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # operating point, convergence notes
        model = OE(1, 2, 1).fit(u[est], y[est])
        rep = validate(model, u[val], y[val])
    comp = compare(model, u[val], y[val])
    assert rep.simulation_fit == pytest.approx(comp.fit, abs=1e-9)
    sim = control.forced_response(model.to_ss(), np.arange(float(N - 900)), u[val],
                                  X0=rep.x0[0])
    np.testing.assert_allclose(rep.y_simulated, np.ravel(sim.outputs), rtol=1e-9, atol=1e-8)
    assert rep.simulation_fit == pytest.approx(fit_percent(y[val], rep.y_simulated), abs=1e-9)
    assert 30 < rep.simulation_fit <= 100


@pytest.fixture(scope="module")
def two_input_bj():
    """BJ([2, 2], 1, 1, [2, 2], [0, 1]) fitted on a zero-mean record of the same plant with
    coloured noise (1 + 0.3 q^-1) / (1 - 0.9 q^-1) e."""
    gen = np.random.default_rng(11)
    n = 1500
    u = np.column_stack([_prbs(gen, n, 5), _prbs(gen, n, 3)])
    y = (lfilter(_B1, _F1, u[:, 0]) + lfilter(_B2, _F2, u[:, 1])
         + lfilter([1.0, 0.3], [1.0, -0.9], 0.05 * gen.standard_normal(n)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return BJ([2, 2], 1, 1, [2, 2], [0, 1]).fit(u, y)


def test_bj_two_inputs_simulation_and_prediction_against_least_squares(two_input_bj):
    """Issue #28, 1: a two-input BJ on a short record at an operating point. The simulation
    ignores the noise model (the OE oracle applies to B_i/F_i); the one-step prediction
    (D/C) sum B_i/F_i u_i + (1 - D/C) y is built here with lfilter, its initial condition the
    least-squares combination of the solutions of C F_1 F_2 yhat = 0. validate reports both
    fits, equal to fit_percent of what it holds and to python-control's forced response."""
    model = two_input_bj
    u, y = _two_input_record(2, 101)
    N = len(y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")              # the operating-point warning
        rep = validate(model, u, y)
    yhat, fit = _oracle_fit(model, u, y)
    np.testing.assert_allclose(rep.y_simulated, yhat, rtol=1e-9, atol=1e-8)
    assert rep.simulation_fit == pytest.approx(fit, abs=1e-8)
    assert rep.simulation_fit == pytest.approx(fit_percent(y, rep.y_simulated), abs=1e-12)
    assert rep.simulation_fit > 90
    # the one-step predictor, by hand
    c, d = np.r_[1.0, model.c_], np.r_[1.0, model.d_]
    b = [np.r_[np.zeros(k), bi] for k, bi in zip(model.nk, model.b_)]
    f = [np.r_[1.0, fi] for fi in model.f_]
    forced = (sum(lfilter(np.convolve(d, bi), np.convolve(c, fi), u[:, i])
                  for i, (bi, fi) in enumerate(zip(b, f)))
              + lfilter(np.r_[0.0, (c - d)[1:]], c, y))
    a = np.convolve(c, np.convolve(f[0], f[1]))
    E = _homogeneous_basis(a, N)
    pred = forced + E @ np.linalg.lstsq(E, y - forced, rcond=None)[0]
    np.testing.assert_allclose(rep.y_predicted, pred, rtol=1e-9, atol=1e-8)
    assert rep.prediction_fit == pytest.approx(fit_percent(y, pred), abs=1e-8)
    assert rep.prediction_fit > rep.simulation_fit     # the noise model predicts the colour
    # from rest: the model's own simulate and predict
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rest = validate(model, u, y, initial="zero")
    np.testing.assert_allclose(rest.y_simulated, model.simulate(u), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(rest.y_predicted, model.predict(u, y), rtol=1e-10, atol=1e-10)
    control = pytest.importorskip("control")
    sim = control.forced_response(model.to_ss(), np.arange(float(N)), u.T, X0=rep.x0[0])
    np.testing.assert_allclose(rep.y_simulated, np.ravel(sim.outputs), rtol=1e-9, atol=1e-8)
    with pytest.raises(ValueError, match="initial='measured' does not apply to the simulation "
                                         "of BJ"):
        compare(model, u, y, initial="measured")
