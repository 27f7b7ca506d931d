"""The fits of the model family warn, at fit time, about a record around an operating point.

A record far from zero fitted by a model without offset handling mostly describes the
operating point (an OE fit on such a record ends with a criterion 100 times that of the
detrended one). `ARX` (without ``offset``), `ARMAX`, `OE`, `BJ`, `AR` and `ARMA` warn once
per fit (`OperatingPointWarning`) naming the remedy, by the rule `validate` uses
(`rlsfilt.models._offset.offset_messages`); zero-mean data, detrended records, a model
with ``offset`` and a step test from rest never warn.
"""

import warnings

import numpy as np
import pytest
from scipy.signal import lfilter

from rlsfilt import AR, ARMA, ARMAX, ARX, BJ, OE, IOData, OperatingPointWarning, detrend
from rlsfilt.models._offset import offset_messages
from rlsfilt.validation import validate


def _record(N=400, seed=0, u0=20.0, y0=60.0):
    rng = np.random.default_rng(seed)
    u = np.repeat(rng.choice([-1.0, 1.0], N // 4 + 1), 4)[:N]
    y = lfilter([0, 0.5, 0.25], [1, -1.2, 0.5], u) + 0.05 * rng.standard_normal(N)
    return u0 + u, y0 + y


#: (model, whether it has an offset parameter)
CASES = [
    (lambda: ARX(2, 2, 1), True),
    (lambda: ARMAX(2, 2, 1, 1), False),
    (lambda: OE(2, 2, 1), False),
    (lambda: BJ(2, 1, 1, 2, 1), False),
    (lambda: AR(2), False),
    (lambda: ARMA(2, 1), False),
]
IDS = ["ARX", "ARMAX", "OE", "BJ", "AR", "ARMA"]


def _fit(model, u, y, **kw):
    if isinstance(model, (AR, ARMA)):
        return model.fit(y, **kw)
    return model.fit(u, y, **kw)


def _caught(fn):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = fn()
    return out, [w for w in caught if issubclass(w.category, OperatingPointWarning)]


@pytest.mark.parametrize(("make", "has_offset"), CASES, ids=IDS)
def test_every_class_warns_once_on_an_offset_record_naming_the_remedy(make, has_offset):
    u, y = _record()
    model = make()
    _, ops = _caught(lambda: _fit(model, u, y))
    assert len(ops) == 1, [str(w.message) for w in ops]
    text = str(ops[0].message)
    name = type(model).__name__
    assert text.startswith(f"{name}.fit: ")
    assert "output 'y' has mean 6" in text
    assert ("input 'u' has mean 2" in text) != isinstance(model, (AR, ARMA))
    assert "rlsfilt.detrend(u)" in text and "detrend(data) of an IOData" in text
    assert ("offset=True" in text) == has_offset
    assert ops[0].filename == __file__            # points at the user's call
    assert hasattr(model, "theta_")               # a warning, not an error: the fit is done


@pytest.mark.parametrize(("make", "has_offset"), CASES, ids=IDS)
def test_the_detrended_record_fits_without_a_warning(make, has_offset):
    u, y = _record()
    ud, _ = detrend(u)
    yd, _ = detrend(y)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")     # a convergence warning is not the question here
        warnings.simplefilter("error", OperatingPointWarning)
        _fit(make(), ud, yd)
        if not isinstance(make(), (AR, ARMA)):   # an IOData detrended as a whole
            data, _ = detrend(IOData(u, y))
            make().fit(data)


@pytest.mark.parametrize("offset", [True, "mean"])
def test_arx_with_offset_handling_does_not_warn(offset):
    u, y = _record()
    with warnings.catch_warnings():
        warnings.simplefilter("error", OperatingPointWarning)
        ARX(2, 2, 1, offset=offset).fit(u, y)


def test_the_warning_is_raised_once_with_multistart_and_recursive_methods():
    u, y = _record(seed=3)
    for kw in ({"n_starts": 3, "rng": 0}, {"method": "rpem"}):
        _, ops = _caught(lambda kw=kw: OE(2, 2, 1).fit(u, y, **kw))
        assert len(ops) == 1
    _, ops = _caught(lambda: ARX(2, 2, 1).fit(u, y, method="rls"))
    assert len(ops) == 1


def test_the_warning_speaks_of_the_record_and_names_its_signals():
    u, y = _record(u0=-30.0)
    data = IOData(u, y, input_names=["valve"], output_names=["T_out"])
    _, ops = _caught(lambda: OE(2, 2, 1).fit(data))
    text = str(ops[0].message)
    assert "input 'valve' has mean -29.8" in text and "output 'T_out' has mean 6" in text
    # only the signal that sits far from zero is named
    _, ops = _caught(lambda: OE(2, 2, 1).fit(u - u.mean(), y))
    assert "'u'" not in str(ops[0].message) and "output 'y'" in str(ops[0].message)


def test_the_operating_point_is_what_the_fit_gets_wrong():
    """The reason for the warning: on the raw record the OE criterion is many times that
    of the detrended one (the operating point absorbs the fit)."""
    u, y = _record(N=800, seed=5)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        raw = OE(2, 2, 1).fit(u, y)
        centred = OE(2, 2, 1).fit(detrend(u)[0], detrend(y)[0])
    assert raw.fit_info_["cost"] > 10 * centred.fit_info_["cost"]


# ----------------------------------------------------------------------
# the rule itself (one home, shared with validate)
# ----------------------------------------------------------------------
@pytest.mark.parametrize("N", [20, 50, 300, 3000])
def test_zero_mean_data_is_never_flagged(N):
    """White, coloured (a pole up to 0.99, started from rest), uniform and PRBS zero-mean
    records, many seeds: none is flagged (``|mean| / std`` of zero-mean data is of order
    ``1 / sqrt(N_eff)``; a short window of a slow process can drift away from zero, which
    the ratio 5 and the zero crossing tell from an operating point)."""
    for seed in range(300 if N < 3000 else 30):
        rng = np.random.default_rng(seed)
        u = rng.standard_normal((N, 2))
        for a in (0.0, 0.8, 0.95, 0.99):
            y = lfilter([1.0], [1, -a], rng.standard_normal(N))
            assert offset_messages([(u, y)], (None, None)) == [], (seed, a)
        w = rng.uniform(-1, 1, N)
        p = rng.choice([-1.0, 1.0], N)
        assert offset_messages([(np.column_stack([w, p]), w)], (None, None)) == []


def test_fewer_than_20_samples_are_not_judged():
    e = np.random.default_rng(0).standard_normal(40)
    assert offset_messages([(50 + e[:19], 50 + e[20:39])], (None, None)) == []
    assert len(offset_messages([(50 + e[:20], 50 + e[20:40])], (None, None))) == 2


def test_the_rule_flags_only_records_that_sit_far_from_zero():
    rng = np.random.default_rng(1)
    e = rng.standard_normal(500)
    flagged = offset_messages([(40 + e, -97 + e)], (["flow"], ["T"]))
    m, sd = e.mean(), e.std()
    assert flagged == [f"input 'flow' has mean {40 + m:.4g} against a standard deviation of "
                       f"{sd:.3g}",
                       f"output 'T' has mean {-97 + m:.4g} against a standard deviation of "
                       f"{sd:.3g}"]
    # a step test from rest at zero is a record of deviations already
    step = np.r_[np.zeros(10), np.ones(490)]
    response = lfilter([0, 0.5], [1, -0.9], step)
    assert offset_messages([(step, response)], (None, None)) == []
    # mean above 3 standard deviations but reaching zero: not flagged
    assert offset_messages([(np.r_[0.0, 10 + e], e)], (None, None)) == []
    # below 5 standard deviations: not flagged even when one-sided
    assert offset_messages([(1.0 + 0.5 * rng.uniform(-1, 1, 500), e)], (None, None)) == []
    assert len(offset_messages([(1.6 + 0.5 * rng.uniform(-1, 1, 500), e)], (None, None))) == 1
    # several experiments: over all their samples; an empty input set (a time series)
    assert len(offset_messages([(np.zeros((50, 0)), 5 + e[:50]),
                                (np.zeros((60, 0)), 5 + e[50:110])], (None, None))) == 1


def test_validate_and_the_fit_apply_the_same_rule():
    u, y = _record()
    model, fit_ops = _caught(lambda: OE(2, 2, 1).fit(u, y))
    _, val_ops = _caught(lambda: validate(model, u, y, max_lag=10))
    assert len(val_ops) == 1
    for part in offset_messages([(u, y)], (None, None)):
        assert part in str(fit_ops[0].message) and part in str(val_ops[0].message)
    # validate names the remedy of the model's class: OE has no offset to set
    assert "Detrend the record first" in str(val_ops[0].message)
    assert "offset=True" not in str(val_ops[0].message)
    # the step test from rest warns in neither
    step = np.r_[np.zeros(10), np.repeat(np.random.default_rng(0).choice([1.0, 2.0], 98), 5)]
    noise = 0.01 * np.random.default_rng(1).standard_normal(500)
    response = lfilter([0, 0.5], [1, -0.9], step) + noise
    with warnings.catch_warnings():
        warnings.simplefilter("error", OperatingPointWarning)
        m = ARX(1, 1, 1).fit(step, response)
        validate(m, step, response, max_lag=10)


def _fleet(C=6, N=400):
    records = [_record(N, seed=c) for c in range(C)]
    u = np.column_stack([r[0] for r in records])
    y = np.column_stack([r[1] for r in records])
    return u, y


@pytest.mark.parametrize("method", ["ls", "rls"])
def test_fit_many_warns_once_naming_the_channels_far_from_zero(method):
    from rlsfilt.models import fit_many

    u, y = _fleet()
    u[:, :3] -= 20.0                        # channels 0-2: their inputs centred ...
    y[:, :3] -= 60.0                        # ... and outputs: deviations, no warning
    fleet, ops = _caught(lambda: fit_many(ARX(2, 2, 1), u, y, method=method))
    assert len(ops) == 1
    text = str(ops[0].message)
    assert "3 of 6 channels (3, 4, 5)" in text and "offset=True" in text
    assert ops[0].filename == __file__       # points at the caller's line
    # the channel by channel rule is ARX.fit's: the channels it flags are those ARX.fit warns of
    for c in range(6):
        _, single = _caught(lambda c=c: ARX(2, 2, 1).fit(u[:, c], y[:, c]))
        assert bool(single) == (c >= 3)


@pytest.mark.parametrize("offset", [True, "mean"])
def test_fit_many_with_an_offset_does_not_warn(offset):
    from rlsfilt.models import fit_many

    u, y = _fleet()
    _, ops = _caught(lambda: fit_many(ARX(2, 2, 1, offset=offset), u, y))
    assert ops == []


def test_fit_many_on_centred_channels_does_not_warn():
    from rlsfilt.models import fit_many

    u, y = _fleet()
    _, ops = _caught(lambda: fit_many(ARX(2, 2, 1), u - u.mean(axis=0), y - y.mean(axis=0)))
    assert ops == []
