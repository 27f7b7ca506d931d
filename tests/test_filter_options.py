"""Settings a filter does not take are refused by name; the ones it takes are honoured (#29).

filterpy's ``KalmanFilter`` accepts ``f.alpha``, ``f.M``, ... and rlsfilt's filters
have each their own settings (``lam``, ``window``, ``mu``, ``eps``, ``leak``,
``order``, ``gate``, ...). Assigning one of these names to a filter that does not take
it used to create a new attribute that the filter never read (``sw.lam = 0.9`` on a
sliding window, ``lms.P = ...``). Every registered filter of
``tests/test_contract_filters.py`` (``FILTERS``; for `RLSBank` and `GradientBank`,
registered through an adapter, the bank itself) meets every such name
(`rlsfilt.filters._base.option_names`): either the filter declares it in ``_options``
and then the next steps equal those of a filter constructed with the value, or the
assignment is an AttributeError naming the setting and the filter that leaves the
filter as it was. A user's own attribute stays free.
"""

import copy
import inspect
import pickle
import re
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from test_contract_filters import DIM_X, FILTERS

import rlsfilt.filters as filters_pkg
from rlsfilt import LMS, RecursiveLeastSquares, SlidingWindowRLS
from rlsfilt.filters._base import FILTERPY_OPTIONS, _FilterBase, option_names
from rlsfilt.filters.bank import BankBase

CASES = FILTERS
GUIDE = Path(__file__).resolve().parents[1] / "docs" / "guide" / "filters.md"

# a value of each setting, the constructor arguments that give a filter with that value,
# and settings both compared filters get (so that the value shows: a health check due
# at every update for cond_max, a condition bound it fails for check_every)
HONOURED = {
    # (x on the constrained filter's constraint x0 + x2 = 0.5: constrain projects x0)
    "x": ([[0.3], [-0.2], [0.2]], {"x0": [0.3, -0.2, 0.2]}, {}),
    "P": (7.0 * np.eye(DIM_X), {"P0": 7.0 * np.eye(DIM_X)}, {}),
    "R": (2.5, {"R": 2.5}, {}),
    "Q": (1e-3, {"Q": 1e-3}, {}),
    "lam": (0.9, {"lam": 0.9}, {}),
    "alpha": (1.1, {"lam": 1.0 / (1.1 * 1.1)}, {}),
    "gate": (1.5, {"gate": 1.5}, {}),
    "check_every": (1, {"check_every": 1}, {"cond_max": 1.01}),
    "cond_max": (1.01, {"cond_max": 1.01}, {"check_every": 1}),
    "refresh": (1, {"refresh": 1}, {}),
    "mu": (0.07, {"mu": 0.07}, {}),
    "eps": (0.3, {"eps": 0.3}, {}),
    "leak": (0.05, {"leak": 0.05}, {}),
    "parallel": (True, {"parallel": True}, {}),
}
STEPS = 30                                # (the window of 40 is not full yet)


def _target(case):
    """The registered filter, or the bank behind a bank's adapter."""
    f = case.make()
    return getattr(f, "bank", f)


def _value(f, name, value):
    """`value` in the shapes of a bank (every channel) where a filter's differ."""
    if isinstance(f, BankBase) and name in ("x", "P"):
        value = np.asarray(value, dtype=float)
        value = value.reshape(-1) if name == "x" else value
        return np.array(np.broadcast_to(value, (f.n_channels, *value.shape)))
    return copy.deepcopy(value)


def _record():
    rng = np.random.default_rng(3)
    Hs = rng.standard_normal((STEPS, DIM_X))
    zs = Hs @ np.array([0.7, -0.3, -0.2]) + 0.05 * rng.standard_normal(STEPS)
    zs[2] += 40.0                         # an outlier, so that a gate shows
    return zs, Hs


def _run(f):
    """The estimates, residuals, gains, innovation variances (and covariances) of `STEPS`
    predict/update steps, as bytes, and the messages of the warnings they issued."""
    zs, Hs = _record()
    out = []
    bank = isinstance(f, BankBase)
    scales = np.arange(1.0, f.n_channels + 1.0) if bank else None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for z, H in zip(zs, Hs):
            f.predict()
            if bank:                       # every channel: the row, a scaled measurement
                f.update(z * scales, np.broadcast_to(H, (f.n_channels, H.size)))
            else:
                f.update(z, H)
            arrays = [f.x, f.y, f.K, f.S] + ([f.P] if getattr(f, "has_covariance", True)
                                             else [])
            out.append(b"".join(np.ascontiguousarray(a, dtype=float).tobytes() for a in arrays))
    return out, [str(w.message) for w in caught]


def _rebuild(f, **kw):
    """A new filter of `f`'s class with `f`'s constructor settings (read back from
    it: the registry's filters set none that cannot be read), `kw` overriding them,
    and `f`'s equality constraints."""
    args = {}
    for name in inspect.signature(type(f)).parameters:
        if name in ("x0", "P0", "forgetting_params"):     # the registry's are the defaults
            continue
        if name not in kw:
            try:
                args[name] = getattr(f, name)
            except AttributeError:
                pass
    args.update(kw)
    g = type(f)(**args)
    if getattr(f, "constraints", None) is not None:
        g.constrain(f.constraints.A, f.constraints.b)
    return g


def _ids(case):
    return case.name


# ----------------------------------------------------------------------
# the names
# ----------------------------------------------------------------------
def _rlsfilt_filter_classes():
    found, todo = [], [_FilterBase, BankBase]
    while todo:
        for c in todo.pop().__subclasses__():
            todo.append(c)
            if c.__module__.startswith("rlsfilt."):
                found.append(c)
    return found


def test_the_names_are_the_filters_own_settings_and_filterpys():
    """`option_names` holds every constructor argument (but the sizes) and every public
    settable property (but ``adapt``) of rlsfilt's filters and banks, filterpy's
    KalmanFilter settings, and the settings #29 named; nothing else."""
    classes = _rlsfilt_filter_classes()
    assert {c.__name__ for c in classes} >= {
        "RecursiveLeastSquares", "SquareRootRLS", "SlidingWindowRLS", "LMS", "NLMS",
        "SignErrorLMS", "SignDataLMS", "SignSignLMS", "APA"}
    expected = set(FILTERPY_OPTIONS)
    for c in classes:
        expected |= set(inspect.signature(c).parameters)
        expected |= {n for n, v in vars(c).items() if isinstance(v, property)
                     and v.fset is not None and not n.startswith("_")}
    # the sizes and adapt (freeze/unfreeze), which every filter and bank takes
    assert set(option_names()) == expected - {"dim_x", "dim_z", "n_channels", "adapt"}
    assert set(option_names()) >= {"lam", "P", "P0", "Q", "window", "mu", "eps", "leak",
                                   "order", "forgetting", "gate", "x0", "refresh", "cond_max"}
    # filterpy's settings: its instance's public attributes but the diagnostics and sizes
    kf = KalmanFilter(dim_x=2, dim_z=1)
    # (H: the regressor every filter writes at each step and update(z) reads, as filterpy)
    diagnostics = {"H", "z", "y", "K", "S", "SI", "x_prior", "P_prior", "x_post", "P_post"}
    settings = {n for n in vars(kf) if not n.startswith("_")} - diagnostics - {"dim_x", "dim_z"}
    assert settings | {"alpha"} <= set(option_names())


def test_a_new_filter_s_options_join_the_others_refusals():
    """A filter defined in rlsfilt later (here a module named ``rlsfilt.<...>``) with a new
    constructor argument makes the filters defined before refuse it; a user's filter
    (another module) adds no name. In a new interpreter: the names are process-wide."""
    script = textwrap.dedent("""
        import types
        from rlsfilt import LMS, RecursiveLeastSquares
        from rlsfilt.filters._base import option_names
        ours = types.ModuleType("rlsfilt.filters._smoothed_lms")   # defined as rlsfilt's
        exec(
            "from rlsfilt import LMS\\n"
            "class Smoothed(LMS):\\n"
            "    _options = LMS._options | {'smoothing'}\\n"
            "    def __init__(self, dim_x, *, smoothing=0.5):\\n"
            "        self.smoothing = smoothing\\n"
            "        super().__init__(dim_x)\\n", ours.__dict__)
        assert "smoothing" in option_names()
        assert ours.Smoothed(2, smoothing=0.2).smoothing == 0.2
        try:
            RecursiveLeastSquares(2).smoothing = 0.3
            raise SystemExit("RecursiveLeastSquares accepted smoothing")
        except AttributeError as e:
            assert "smoothing is an option of Smoothed" in str(e), str(e)
        user = types.ModuleType("my_filters")                    # a user's filter
        exec(
            "from rlsfilt import LMS\\n"
            "class Mine(LMS):\\n"
            "    def __init__(self, dim_x, *, colour=None):\\n"
            "        self.colour = colour\\n"
            "        super().__init__(dim_x)\\n", user.__dict__)
        assert "colour" not in option_names()
        assert user.Mine(2, colour="red").colour == "red"
        g = LMS(2)
        g.colour = "blue"
        assert g.colour == "blue"
        print("ok")
        """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr
    assert run.stdout.strip() == "ok"


# ----------------------------------------------------------------------
# every registered filter x every name: refused or honoured
# ----------------------------------------------------------------------
def test_the_registry_holds_every_filter_class():
    """Every public rlsfilt filter and bank class is in the registry (so it meets every
    name)."""
    public = {c for c in _rlsfilt_filter_classes() if not c.__name__.startswith("_")}
    assert public | set(BankBase.__subclasses__()) <= {type(_target(case)) for case in CASES}


@pytest.mark.parametrize("name", option_names())
@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_a_setting_is_refused_by_name_or_honoured(case, name):
    f = _target(case)
    if name in type(f)._options:
        _check_honoured(f, name)
    else:
        _check_refused(f, name)


def _check_honoured(f, name):
    """The next steps equal those of a filter constructed with the value (and differ
    from those without it: the check can fail)."""
    assert name in HONOURED, f"give `{name}` a value in HONOURED"
    value, constructed, both = HONOURED[name]
    assert _run(_rebuild(f)) == _run(f), "the rebuilt filter steps as the registry's"
    g = _rebuild(f, **both)
    setattr(g, name, _value(f, name, value))
    with_value = _run(_rebuild(f, **both, **constructed))
    assert _run(g) == with_value
    if name == "parallel":               # threads, the same numbers by design: stored
        assert g.parallel is True and _rebuild(f, **constructed).parallel is True
        return
    assert with_value != _run(_rebuild(f, **both)), f"`{name}` = {value} changes nothing"


def _check_refused(f, name):
    """An AttributeError naming the setting and the filter, saying why and what else
    (``why; instead``), the filter unchanged; reading it is an AttributeError or a
    value (the documented ``F``, ``B``, ``Q``, ...), never anything else."""
    cls = type(f).__name__
    before = pickle.dumps(f)
    with pytest.raises(AttributeError) as info:
        setattr(f, name, 0.5)
    message = str(info.value)
    assert message.startswith(f"`{name}` cannot be assigned: "), message
    assert cls in message, message
    assert ";" in message, message        # the reason; what to use instead
    assert pickle.dumps(f) == before
    try:
        getattr(f, name)
    except AttributeError as e:
        assert name in str(e)
        assert not hasattr(f, name)
    else:
        assert hasattr(type(f), name)     # a documented read-only value of the class


# ----------------------------------------------------------------------
# the issue's cases, a user's own attributes, subclasses, copies
# ----------------------------------------------------------------------
@pytest.mark.parametrize("make, name, match", [
    (lambda: SlidingWindowRLS(2, 10), "lam", r"SlidingWindowRLS forgets by its window"),
    (lambda: SlidingWindowRLS(2, 10), "window", r"the window of SlidingWindowRLS is fixed"),
    (lambda: LMS(2), "lam", r"LMS adapts by its step size `mu`"),
    (lambda: LMS(2), "P", r"LMS keeps no covariance"),
    (lambda: LMS(2), "eps", r"LMS has no regularized normalization; eps is an option of "
                            r"APA, GradientBank, NLMS"),
    (lambda: RecursiveLeastSquares(2), "M", r"filterpy's M"),
    (lambda: RecursiveLeastSquares(2), "P0", r"the initial covariance of "
                                             r"RecursiveLeastSquares is fixed at "
                                             r"construction .*assign P"),
    (lambda: RecursiveLeastSquares(2), "window", r"window is an option of SlidingWindowRLS"),
    (lambda: RecursiveLeastSquares(2), "mu", r"mu is an option of APA, GradientBank, LMS, NLMS"),
    (lambda: RecursiveLeastSquares(2), "forgetting", r"construct a new filter"),
])
def test_the_issue_s_assignments_are_refused(make, name, match):
    f = make()
    with pytest.raises(AttributeError, match=rf"`{name}` cannot be assigned: .*{match}"):
        setattr(f, name, 3)


def test_a_user_s_own_attribute_is_kept_copied_and_pickled():
    f = RecursiveLeastSquares(2, lam=0.98)
    f.label = "ch1"
    g = LMS(2)
    g.label, g.owner = "ch2", {"site": 4}
    for h, label in ((f, "ch1"), (g, "ch2")):
        assert h.label == label
        for twin in (copy.copy(h), copy.deepcopy(h), pickle.loads(pickle.dumps(h)), h.copy()):
            assert twin.label == label
            assert type(twin) is type(h)
    assert pickle.loads(pickle.dumps(g)).owner == {"site": 4}
    del f.label
    assert not hasattr(f, "label")


def test_copies_refuse_and_honour_as_the_original():
    f = SlidingWindowRLS(DIM_X, 40)
    for twin in (copy.copy(f), copy.deepcopy(f), pickle.loads(pickle.dumps(f))):
        with pytest.raises(AttributeError, match="`lam` cannot be assigned"):
            twin.lam = 0.9
        twin.refresh = 3
        assert twin.refresh == 3 and f.refresh == 400


def test_a_subclass_declares_the_settings_it_takes():
    """A user's subclass inherits the refusals; declaring a name in ``_options`` takes it
    (an instance attribute again, pickled with the filter)."""
    class Plain(RecursiveLeastSquares):
        pass

    class Stepped(RecursiveLeastSquares):
        _options = RecursiveLeastSquares._options | {"mu"}

    with pytest.raises(AttributeError, match="`mu` cannot be assigned: Plain has no step size"):
        Plain(2).mu = 0.1
    s = Stepped(2)
    assert not hasattr(s, "mu")
    s.mu = 0.1
    assert s.mu == 0.1 and copy.deepcopy(s).mu == 0.1
    with pytest.raises(AttributeError, match="`window` cannot be assigned: Stepped"):
        s.window = 3


def test_reading_a_refused_name_is_absent_also_on_the_class():
    """``hasattr`` on the instance and on the class (which the HTML display asks) say
    absent; ``getattr`` with a default gives the default."""
    sw = SlidingWindowRLS(2, 10)
    assert not hasattr(sw, "lam") and not hasattr(SlidingWindowRLS, "lam")
    assert getattr(sw, "gate", None) is None
    assert getattr(LMS(2), "eps", 0.0) == 0.0
    assert LMS(2).check_every == 0
    assert "forgetting factor" not in sw._repr_html_()


def test_the_guide_lists_what_each_filter_takes():
    """The guide's table of settings per filter is the classes' ``_options``."""
    text = GUIDE.read_text()
    table = text.split("| filter | settings it takes by assignment |")[1].split("\n\n")[0]
    rows = [line for line in table.splitlines()[2:] if line.startswith("|")]
    seen = set()
    for row in rows:
        names, settings = (cell.strip() for cell in row.strip("|").split("|"))
        for cls_name in re.findall(r"`(\w+)`", names):
            cls = getattr(filters_pkg, cls_name)
            assert set(re.findall(r"`(\w+)`", settings)) == set(cls._options), cls_name
            seen.add(cls)
    assert seen == {type(_target(case)) for case in CASES
                    if type(_target(case)).__module__.startswith("rlsfilt.")}
