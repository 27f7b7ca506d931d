"""select_order on real records: delay range, edge warnings, stability, experiments, offsets."""

import itertools

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import ARX
from rlsfilt.data import IOData
from rlsfilt.datasets import heat_exchanger, thermal_process
from rlsfilt.exceptions import OperatingPointWarning, OrderSelectionWarning
from rlsfilt.validation import select_order


def _brute_losses(runs, grid, t_max, const=False, op=None):
    """Oracle: np.linalg.lstsq on regressors built by hand, rows t_max.. of every run."""
    out = []
    for a, b, k in itertools.product(*grid):
        Phis, targets = [], []
        for u, y in runs:
            if op is not None:
                u, y = u - op[0], y - op[1]
            t = np.arange(t_max, len(y))
            cols = [-y[t - i] for i in range(1, a + 1)] + [u[t - k - m] for m in range(b)]
            cols += [np.ones(len(t))] if const else []
            Phis.append(np.column_stack(cols))
            targets.append(y[t])
        Phi, target = np.vstack(Phis), np.concatenate(targets)
        res = target - Phi @ np.linalg.lstsq(Phi, target, rcond=None)[0]
        out.append(res @ res / len(target))
    return np.array(out)


def _plant(rng, n, nk=2, level=0.0, u_level=0.0):
    u = u_level + rng.standard_normal(n)
    y = level + lfilter(np.r_[np.zeros(nk), 1.0, 0.5], [1, -1.5, 0.7], u - u_level)
    return u, y + lfilter([1.0], [1, -1.5, 0.7], 0.1 * rng.standard_normal(n))


def test_delay_range_is_independent_of_the_orders():
    """16 samples of dead time: the default delay range (1..3) cannot hold them (the grid
    compensates with other orders), delayest finds the delay, and a delay range around it
    with small orders gives the true structure."""
    from rlsfilt.validation.delay import delayest

    d = thermal_process(delay=15)
    assert d.nk == 16
    assert select_order(d.u, d.y).best[2] != 16
    nk = delayest(d.u, d.y)
    assert nk == 16
    sel = select_order(d.u, d.y, na=range(1, 4), nb=range(1, 4), nk=range(nk - 2, nk + 3))
    assert sel.best == (1, 1, 16)


def test_edge_warnings_name_the_bound(rng):
    u, y = _plant(rng, 1500, nk=2)
    with pytest.warns(OrderSelectionWarning, match=r"is at the upper edge of the `na` range "
                                                   r"\(1..2\): widen `na` upwards"):
        select_order(u, y, na=range(1, 3), nb=range(1, 4), nk=range(1, 4))
    with pytest.warns(OrderSelectionWarning, match=r"upper edge of the `na` range \(1..2\): "
                                                   r"widen `na` upwards; and at the upper edge "
                                                   r"of the `nb` range \(1..2\)"):
        select_order(u, y, na=range(1, 3), nb=range(1, 3), nk=range(1, 4))
    with pytest.warns(OrderSelectionWarning, match=r"lower edge of the `nk` range \(3..6\).*"
                                                   r"widen `nk` downwards"):
        select_order(u, y, na=range(1, 4), nb=range(1, 4), nk=range(3, 7))
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert select_order(u, y, na=range(1, 5), nb=range(1, 5), nk=range(1, 5)).best == \
            (2, 2, 2)


def test_stable_only_on_a_raw_record():
    """On the raw exchanger record (97 degC, no offset handling) BIC picks a model with a
    pole outside the unit circle; stable_only picks a stable one; with an intercept the
    best is stable anyway."""
    est = heat_exchanger().getexp(0)
    grid = {"na": range(1, 6), "nb": range(1, 6), "nk": range(6, 11)}
    raw = select_order(est, **grid)
    i = raw.best_index
    assert not raw.table["stable"][i] and raw.table["max_pole"][i] > 1.0
    assert "unstable" in str(raw.summary())
    with pytest.warns(OrderSelectionWarning, match="widen `nk` upwards"):
        safe = select_order(est, **grid, stable_only=True)
    assert safe.table["stable"][safe.best_index]
    with pytest.warns(OperatingPointWarning, match="ARX.fit: input 'flow'"):
        assert safe.best_model().is_stable      # refitted on the raw record: warned
    offset = select_order(est, **grid, offset=True)
    assert offset.table["stable"][offset.best_index] and offset.best == (3, 3, 8)
    model = offset.best_model()
    assert model.get_params()["offset"] is True and model.output_names_ == ("T_out",)
    # the table's pole magnitude is that of the candidate's own fit
    np.testing.assert_allclose(
        offset.table["max_pole"][offset.best_index],
        np.max(np.abs(np.roots(np.r_[1.0, offset.thetas[offset.best_index][:3]]))),
        rtol=1e-12)


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")
def test_several_experiments_equal_stacked_lstsq(rng):
    runs = [_plant(rng, 400), _plant(rng, 300, level=5.0)]
    grid = (range(1, 4), range(1, 3), range(1, 4))
    data = IOData([r[0] for r in runs], [r[1] for r in runs])
    sel = select_order(data, na=grid[0], nb=grid[1], nk=grid[2])
    t_max = max(3, 3 + 2 - 1)
    np.testing.assert_allclose(sel.table["loss"], _brute_losses(runs, grid, t_max),
                               rtol=1e-9)
    assert sel.n_rows == 400 + 300 - 2 * t_max
    val = IOData(*_plant(rng, 500))
    picked = select_order(data, na=grid[0], nb=grid[1], nk=grid[2], validation=val,
                          criterion="loss")
    assert picked.n_val_rows == 500 - t_max
    assert isinstance(picked.best_model(), ARX) and picked.best_model().n_experiments_ == 2


@pytest.mark.filterwarnings("ignore::rlsfilt.exceptions.OrderSelectionWarning")
def test_offsets_equal_lstsq(rng):
    u, y = _plant(rng, 600, level=97.0, u_level=40.0)
    grid = (range(1, 3), range(1, 3), range(1, 3))
    t_max = 3
    sel = select_order(u, y, na=grid[0], nb=grid[1], nk=grid[2], offset=True)
    np.testing.assert_allclose(sel.table["loss"], _brute_losses([(u, y)], grid, t_max,
                                                                 const=True), rtol=1e-9)
    assert np.all(sel.table["n_params"] == [a + b + 1 for a, b, _ in
                                            itertools.product(*grid)])
    mean = select_order(u, y, na=grid[0], nb=grid[1], nk=grid[2], offset="mean")
    np.testing.assert_allclose(mean.table["loss"],
                               _brute_losses([(u, y)], grid, t_max,
                                             op=(u.mean(), y.mean())), rtol=1e-9)
    with pytest.raises(ValueError, match="`offset` must be False, True"):
        select_order(u, y, offset="yes")


def test_stable_only_without_a_stable_candidate(rng):
    u = rng.standard_normal(300)
    y = np.cumsum(np.cumsum(u))  # a double integrator: every fitted A is on or past the edge
    with pytest.raises(ValueError, match="`stable_only`: none of the 1 candidates is stable"):
        select_order(u, y + 1e-3 * rng.standard_normal(300), na=2, nb=1, nk=1,
                     stable_only=True)
