"""Callers' arrays are never modified: every public entry point of ARX, the
datasets and the validation tools runs on read-only inputs (any in-place write
would raise) and leaves them bit-for-bit unchanged."""

import matplotlib
import numpy as np
import pytest

from rlsfilt import ARX, datasets, select_order, validate
from rlsfilt.validation import (
    PlantComparison,
    cusum,
    cusum_squares,
    fit_percent,
    frequency_response_band,
    information_criteria,
    parameter_intervals,
    recursive_residuals,
    residual_analysis,
)

matplotlib.use("Agg")


def frozen(*arrays):
    out = []
    for a in arrays:
        a = np.array(a, dtype=float)
        a.flags.writeable = False
        out.append(a)
    return out


@pytest.fixture
def record():
    d = datasets.dc_motor(n_samples=400)
    return d, *frozen(d.u, d.y, np.column_stack([d.u, np.roll(d.u, 7)]),
                      np.column_stack([d.y, np.roll(d.y, 3)]))


def test_arx_leaves_inputs_untouched(record):
    d, u, y, U2, Y2 = record
    keep = [a.copy() for a in (u, y, U2, Y2)]
    for uu, yy in ((u, y), (U2, y), (U2, Y2)):
        for method, kw in (("ls", {}), ("rls", {"lam": 0.99})):
            m = ARX(2, 2, 1, dt=d.dt).fit(uu, yy, method=method, **kw)
            m.regressors(uu, yy)
            m.predict(uu, yy, horizon=3)
            m.simulate(uu, y0=yy[:2])
            m.to_tf(), m.to_ss(), m.to_dlti(), str(m.summary())
    x0, P0 = frozen(np.zeros(4), 100.0 * np.eye(4))
    ARX(2, 2, 1).fit(u, y, method="rls", x0=x0, P0=P0)
    a, b = frozen([-1.5, 0.7], [1.0, 0.5])
    true = ARX.from_polynomials(a, b)
    true.a_[0] = 0.0  # fitted attributes are the model's own copies
    for before, after in zip(keep + [np.zeros(4), 100.0 * np.eye(4), [-1.5, 0.7], [1.0, 0.5]],
                             (u, y, U2, Y2, x0, P0, a, b)):
        np.testing.assert_array_equal(after, before)


def test_validation_leaves_inputs_untouched(record):
    d, u, y, U2, _ = record
    keep = [a.copy() for a in (u, y, U2)]
    model = ARX(2, 2, 1, dt=d.dt).fit(u, y)
    residual_analysis(model, u, y)
    information_criteria(model, u, y)
    parameter_intervals(model)
    omega, = frozen(np.linspace(0.1, 10.0, 20))
    frequency_response_band(model, omega=omega, n_draws=20, rng=0)
    PlantComparison(model, d.plant, omega=omega)
    rep = validate(model, u, y, plant=d.plant)
    rep.summary(), rep._repr_html_()
    select_order(u, y, na=range(1, 4), nb=range(1, 4), nk=[1], validation=(u, y)).best_model()
    fit_percent(y, y[::-1])
    Phi, target = (frozen(a)[0] for a in model.regressors(u, y))
    recursive_residuals(target, Phi), cusum(target, Phi), cusum_squares(target, Phi)
    two = ARX(1, 1, 1).fit(U2, y)
    validate(two, U2, y)
    for before, after in zip(keep + [np.linspace(0.1, 10.0, 20)], (u, y, U2, omega)):
        np.testing.assert_array_equal(after, before)
    import matplotlib.pyplot as plt

    plt.close("all")


def test_dataset_input_record_is_copied():
    u, = frozen(datasets.prbs(300, hold=3))
    d = datasets.thermal_process(n_samples=300, input=u)
    assert d.u is not u and not np.shares_memory(d.u, u)
    np.testing.assert_array_equal(d.u, u)
