"""select_structure: any model class, a grid of orders, criteria of the prediction errors.

Oracles: the criteria of each candidate equal information_criteria of the same fitted
model (MATLAB's definitions); the true structure wins on long simulated records."""

import json

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARMA, ARMAX, OE, select_structure
from rlsfilt.validation import information_criteria


def test_the_true_armax_structure_wins_and_criteria_are_the_models(rng):
    u, e = rng.standard_normal(4000), rng.standard_normal(4000)
    a = [1, -1.5, 0.7]
    y = lfilter([0, 1, 0.5], a, u) + lfilter([1, -1, 0.2], a, e)
    sel = select_structure(ARMAX, u, y, {"na": [1, 2, 3], "nb": [2], "nc": [0, 1, 2],
                                         "nk": [1]})
    assert sel.best == {"na": 2, "nb": 2, "nc": 2, "nk": 1}
    for c, m in zip(sel.candidates, sel.models):
        ic = information_criteria(m, u, y)
        assert c["bic"] == pytest.approx(ic.bic, rel=1e-12)
        assert c["n_params"] == ic.n_params
    assert sel.best_model is sel.models[sel.best_index]
    assert "<- best" in str(sel.summary())
    json.dumps(sel.to_dict(), allow_nan=False)


def test_validation_data_and_the_loss_criterion(rng):
    u = rng.standard_normal(3000)
    y = lfilter([0, 1.0, 0.5], [1, -1.5, 0.7], u) + 0.3 * rng.standard_normal(3000)
    sel = select_structure(OE, u[:2000], y[:2000], [{"nb": 1, "nf": 1}, {"nb": 2, "nf": 2}],
                           criterion="loss", validation=(u[2000:], y[2000:]))
    assert sel.best == {"nb": 2, "nf": 2}
    m = sel.best_model
    e = y[2000:][m.max_lag:] - m.predict(u[2000:], y[2000:])[m.max_lag:]
    assert sel.values[sel.best_index] == pytest.approx(np.mean(e ** 2), rel=1e-12)


def test_time_series_and_refused_candidates(rng):
    y = lfilter([1, 0.5], [1, -0.8], rng.standard_normal(3000))
    sel = select_structure(ARMA, None, y, {"na": [1, 2], "nc": [0, 1]})
    assert sel.best == {"na": 1, "nc": 1}
    short = select_structure(ARMA, None, y[:12], {"na": [1, 12], "nc": [1]})
    assert short.candidates[1]["error"].startswith("`y` must have more than")
    assert np.isnan(short.values[1]) and short.models[1] is None
    assert "refused" in str(short.summary())


def test_errors(rng):
    y = rng.standard_normal(200)
    with pytest.raises(ValueError, match="`criterion` must be one of"):
        select_structure(ARMA, None, y, {"na": [1]}, criterion="r2")
    with pytest.raises(TypeError, match="`model_class` must be a model class"):
        select_structure(ARMA(1, 1), None, y, {"na": [1]})
    with pytest.raises(TypeError, match="`grid` names a parameter ARMA does not take"):
        select_structure(ARMA, None, y, {"nb": [1]})
    with pytest.raises(ValueError, match="no candidate structure could be fitted"):
        select_structure(ARMA, None, y[:5], {"na": [4], "nc": [4]})


def test_structure_search_shows_progress_when_asked(capsys):
    """#28: a search that fits many candidates can show a tqdm bar (``progress=True`` at once,
    ``"auto"`` after a few seconds, False never); the result does not depend on it."""
    pytest.importorskip("tqdm")
    from scipy.signal import lfilter

    from rlsfilt import OE, select_structure

    rng = np.random.default_rng(5)
    u = rng.standard_normal(300)
    y = lfilter([0, 0.5], [1, -0.7], u) + 0.05 * rng.standard_normal(300)
    grid = {"nb": [1, 2], "nf": [1], "nk": [1]}
    quiet = select_structure(OE, u, y, grid, progress=False)
    shown = select_structure(OE, u, y, grid, progress=True)
    assert "select_structure(OE)" in capsys.readouterr().err
    assert [c["orders"] for c in quiet.candidates] == [c["orders"] for c in shown.candidates]
    with pytest.raises(ValueError, match="`progress`"):
        select_structure(OE, u, y, grid, progress="yes")


def _two_output_records(rng, lengths):
    out = []
    for N in lengths:
        u, e = rng.standard_normal(N), rng.standard_normal((N, 2))
        Y = np.column_stack([lfilter([0, 1, 0.5], [1, -0.5], u) + e[:, 0],
                             lfilter([0, 1], [1, -0.3], u) + 0.5 * e[:, 0] + 0.3 * e[:, 1]])
        out.append((u, Y))
    return out


@pytest.mark.parametrize("ny", [1, 2])
@pytest.mark.parametrize("with_validation", [False, True])
def test_criteria_with_or_without_validation_are_information_criteria(ny, with_validation, rng):
    # with validation data the criteria of a two-output model used the mean of every squared
    # error (and the constant of one output) instead of the determinant of their covariance
    from rlsfilt import ARX, IOData

    est = _two_output_records(rng, (300, 150))
    val = _two_output_records(rng, (200, 120))

    def data(recs):
        return IOData([u for u, _ in recs], [Y if ny == 2 else Y[:, 0] for _, Y in recs])

    sel = select_structure(ARX, data(est), {"na": [1, 2], "nb": [1, 2], "nk": [1]},
                           validation=data(val) if with_validation else None)
    for c, m in zip(sel.candidates, sel.models):
        ic = information_criteria(m, data(val if with_validation else est))
        assert ic.n_outputs == ny
        for key in ("aic", "aicc", "bic", "naic", "fpe", "mdl"):
            assert c[key] == pytest.approx(getattr(ic, key), rel=1e-12), key
        assert c["val_loss" if with_validation else "loss"] == pytest.approx(ic.loss, rel=1e-12)
        if ny == 2:       # the oracle of the loss: det of the residual covariance, numpy only
            E = np.vstack([Y[m.max_lag:] - m.predict(u, Y)[m.max_lag:]
                           for u, Y in (val if with_validation else est)])
            assert ic.loss == pytest.approx(np.linalg.det(E.T @ E / len(E)), rel=1e-12)
