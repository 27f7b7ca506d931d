"""Every ``summary()`` of every public class returns one kind of object, `rlsfilt.Summary`:
``str``/``repr``/``as_text()`` are its text, ``_repr_html_``/``as_html()`` valid, escaped
HTML holding the same numbers (#32)."""

import html
import inspect
from html.parser import HTMLParser

import numpy as np
import pytest
from scipy.signal import lfilter

import rlsfilt
import rlsfilt.adaptive
import rlsfilt.filters
import rlsfilt.models
import rlsfilt.validation
from rlsfilt import AR, ARMA, ARMAX, ARX, BJ, OE, RecursiveLeastSquares, Summary
from rlsfilt.adaptive import rst_design
from rlsfilt.models import fit_many
from rlsfilt.validation import (
    compare,
    impulseest,
    parameter_intervals,
    residual_analysis,
    segment,
    select_order,
    validate,
)
from rlsfilt.validation.structure import StructureSelection

# the tags a summary's HTML may use: anything else is text that was not escaped
ALLOWED_TAGS = {"div", "p", "table", "tr", "th", "td", "pre", "strong", "details", "summary",
                "caption", "h4", "span", "br", "em", "code", "sub", "sup", "i", "b"}
VOID_TAGS = {"br"}


class _Checker(HTMLParser):
    """Records the tags, checks they nest, and collects the text (entities decoded)."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.stack, self.tags, self.errors, self.text = [], set(), [], []

    def handle_starttag(self, tag, attrs):
        self.tags.add(tag)
        if tag not in VOID_TAGS:
            self.stack.append(tag)

    def handle_endtag(self, tag):
        if not self.stack or self.stack.pop() != tag:
            self.errors.append(f"</{tag}> closes nothing open")

    def handle_data(self, data):
        self.text.append(data)


def html_text(page, allowed=ALLOWED_TAGS):
    """The text of `page` after checking it is well-formed HTML of `allowed` tags."""
    checker = _Checker()
    checker.feed(page)
    checker.close()
    assert not checker.errors, checker.errors
    assert not checker.stack, f"unclosed tags {checker.stack}"
    assert checker.tags <= allowed, f"unexpected tags {checker.tags - allowed}"
    return "".join(checker.text)


def test_checker_finds_bad_html():
    with pytest.raises(AssertionError):
        html_text("<table><tr><td>1</td></table>")
    with pytest.raises(AssertionError):
        html_text("<p>a <script>x</script></p>")          # unescaped text
    assert html_text("<p>1 &lt; 2</p>") == "1 < 2"


# ----------------------------------------------------------------------
# one case per public class with a summary(): (summary, numbers its HTML must show)
# ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def record():
    gen = np.random.default_rng(3)
    u = gen.standard_normal(600)
    e = 0.1 * gen.standard_normal(600)
    y = lfilter([0.0, 1.0, 0.5], [1.0, -1.5, 0.7], u) + lfilter([1.0], [1.0, -1.5, 0.7], e)
    return u, y


@pytest.fixture(scope="module")
def arx(record):
    return ARX(2, 2, 1).fit(*record)


def _model_case(make):
    def case(record, arx):
        u, y = record
        model = make(u, y)
        return model.summary(), [f"{v:.6g}" for v in np.ravel(model.theta_)]
    return case


def _bank(record, arx):
    gen = np.random.default_rng(5)
    u = gen.standard_normal((300, 12))
    y = np.column_stack([lfilter([0.0, 1.0], [1.0, -0.5 - 0.02 * c], u[:, c])
                         + 0.05 * gen.standard_normal(300) for c in range(12)])
    labels = ["<b>"] + [f"ch{c}" for c in range(1, 12)]
    bank = fit_many(ARX(1, 1, 1), u, y, channels=labels)
    s = bank.summary()
    assert "&lt;b&gt;" in s.as_html() and "... 2 more channels ..." in s.as_text()
    assert "ch5" not in s.as_text() and "ch11" in s.as_text()
    return s, [f"{bank.theta_[-1, 0]:.5g}", f"{bank.simulation_fit_[0]:.2f}"]


def _report(record, arx):
    import control

    rep = validate(arx, *record, plant=control.tf([1.0, 0.5], [1.0, -1.5, 0.7], True))
    pc = rep.plant_comparison
    s = rep.summary()
    assert s.as_html() == rep._repr_html_()
    return s, [f"{rep.simulation_fit:.2f}", f"{100 * pc.dc_gain_error:.4g}%"]


def _plant(record, arx):
    import control

    pc = validate(arx, *record, plant=control.tf([1.0, 0.5], [1.0, -1.5, 0.7], True)
                  ).plant_comparison
    return pc.summary(), [f"{100 * pc.step_error:.4g}%", f"{pc.max_pole_distance:.4g}"]


def _comparison(record, arx):
    c = compare(arx, *record)
    return c.summary(), [f"{float(np.ravel(c.fit)[0]):.2f}%"]


def _impulse(record, arx):
    g = impulseest(*record, 15)
    return g.summary(), [str(g.delay())]


def _order_selection(record, arx):
    sel = select_order(*record, na=range(1, 4), nb=range(1, 4), nk=range(1, 2))
    s = sel.summary(top=3)
    best = sel.best_index
    return s, [f"{sel.values[best]:.6g}"]


def _structure_selection(record, arx):
    cands = [{"orders": {"na": k}, "n_params": k, "loss": 1.0 / k, "error": None}
             for k in range(1, 4)]
    cands.append({"orders": {"na": 9}, "n_params": 9, "loss": np.nan, "error": "<b>bad</b>"})
    sel = StructureSelection(cands, "aic", [3.0, 1.5, 2.0, np.nan], [arx] * 4)
    s = sel.summary()
    assert "&lt;b&gt;bad&lt;/b&gt;" in s.as_html()
    assert s.as_html() == sel._repr_html_()
    return s, ["1.5", "0.5"]


def _intervals(record, arx):
    ci = parameter_intervals(arx)
    return ci.summary(), [f"{ci.upper[0]:.6g}", f"{ci.std_error[1]:.4g}"]


def _residuals(record, arx):
    r = residual_analysis(arx, *record)
    return r.summary(), [f"{r.pvalue_white:.4g}", f"{r.f_statistic:.4g}"]


def _tune(record, arx):
    gen = np.random.default_rng(7)
    H = gen.standard_normal((300, 2))
    z = H @ [1.0, -0.5] + 0.1 * gen.standard_normal(300)
    fit = RecursiveLeastSquares(2, P0=100.0).tune(z, H, "lam")
    return fit.summary(), [f"{float(np.ravel(fit.estimate)[0]):.6g}", f"{fit.loglik:.6f}"]


def _closed_loop(record, arx):
    A, B = [1.0, -1.5, 0.7], [0.0, 1.0, 0.5]
    loop = rst_design(A, B, Am=np.poly([0.5, 0.4])).closed_loop(A, B)
    assert repr(loop) == loop.summary().as_text()
    return loop.summary(), [f"{loop.dcgain:.6g}"]


def _segmentation(record, arx):
    gen = np.random.default_rng(3)
    u = gen.standard_normal(400)
    y = np.zeros(400)
    for t in range(1, 400):
        a = -0.5 if t < 200 else -0.8
        y[t] = -a * y[t - 1] + u[t - 1] + 0.1 * gen.standard_normal()
    seg = segment(y, u, na=1, nb=1, R2=0.01)
    assert seg._repr_html_() == seg.summary().as_html()
    return seg.summary(), [f"{seg.theta[0, 0]:.4g}", f"{seg.theta[-1, 1]:.4g}"]


CASES = {
    "ARX": _model_case(lambda u, y: ARX(2, 2, 1).fit(u, y)),
    "ARMAX": _model_case(lambda u, y: ARMAX(2, 2, 1, 1).fit(u, y)),
    "OE": _model_case(lambda u, y: OE(2, 2, 1).fit(u, y)),
    "BJ": _model_case(lambda u, y: BJ(2, 1, 1, 2, 1).fit(u, y)),
    "AR": _model_case(lambda u, y: AR(2).fit(y)),
    "ARMA": _model_case(lambda u, y: ARMA(2, 1).fit(y)),
    "ARXBank": _bank,
    "ValidationReport": _report,
    "PlantComparison": _plant,
    "Comparison": _comparison,
    "ImpulseResponse": _impulse,
    "OrderSelection": _order_selection,
    "StructureSelection": _structure_selection,
    "ParameterIntervals": _intervals,
    "ResidualAnalysis": _residuals,
    "TuneResult": _tune,
    "ClosedLoop": _closed_loop,
    "Segmentation": _segmentation,
}


def _public_classes_with_summary():
    found = set()
    for mod in (rlsfilt, rlsfilt.models, rlsfilt.validation, rlsfilt.filters, rlsfilt.adaptive,
                rlsfilt.data, rlsfilt.datasets):
        for name in mod.__all__:
            obj = getattr(mod, name)
            if inspect.isclass(obj) and callable(getattr(obj, "summary", None)) \
                    and not inspect.isabstract(obj) and obj.__name__ != "IdentifiedModel":
                found.add(obj.__name__)
    return found


def test_every_public_summary_has_a_case():
    """A new public class with a summary() must join CASES (and so return a Summary)."""
    assert _public_classes_with_summary() == set(CASES)


@pytest.mark.parametrize("name", list(CASES))
def test_summary_is_one_printable_kind(name, record, arx):
    summary, numbers = CASES[name](record, arx)
    assert isinstance(summary, Summary), type(summary)
    text = summary.as_text()
    assert isinstance(text, str) and text
    assert str(summary) == text and repr(summary) == text
    page = summary._repr_html_()
    assert page == summary.as_html()
    shown = html_text(page)
    assert "&amp;" not in page.replace("&amp; ", "")        # escaped once, not twice
    for number in numbers:
        assert number in text, (number, text)
        assert number in shown, (number, shown)


def test_summary_escapes_its_text():
    s = Summary("a <b> & c")
    assert str(s) == "a <b> & c"
    assert s.as_html() == "<pre class='rlsfilt-summary'>a &lt;b&gt; &amp; c</pre>"
    assert html_text(s.as_html()) == "a <b> & c"
    page = Summary("x", html="<p>y</p>")
    assert page._repr_html_() == "<p>y</p>" and repr(page) == "x"
    with pytest.raises(TypeError, match="`text` must be a str; got int"):
        Summary(3)
    with pytest.raises(TypeError, match="`html` must be a str or None; got bytes"):
        Summary("x", html=b"<p>")


def test_report_text_is_unchanged_by_the_type(record, arx):
    """``str(report.summary())`` is the text ``rlsfilt identify`` prints, with the model's
    coefficient table and the residual tests' lines."""
    rep = validate(arx, *record)
    text = str(rep.summary())
    assert text.startswith("Validation of ARX") and text.endswith("Verdict: " + rep.verdict)
    assert arx.summary().as_text() in text
    assert rep.residuals[0].summary().as_text() in text
    assert html.escape(rep.verdict) in rep._repr_html_()


def test_bank_dataframe_has_every_channel(record, arx):
    pd = pytest.importorskip("pandas")
    gen = np.random.default_rng(2)
    u = gen.standard_normal((200, 15))
    y = np.column_stack([lfilter([0.0, 1.0], [1.0, -0.6], u[:, c]) for c in range(15)])
    bank = fit_many(ARX(1, 1, 1), u, y + 0.01 * gen.standard_normal(y.shape))
    frame = bank.to_dataframe()
    assert isinstance(frame, pd.DataFrame) and len(frame) == 15
    np.testing.assert_array_equal(frame["a1"], bank.theta_[:, 0])
    assert bank._repr_html_() == bank.summary().as_html()
