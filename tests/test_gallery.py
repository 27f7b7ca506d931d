"""Every gallery example (``examples/plot_*.py``) runs and draws labelled figures, and its
page shows no stray output (#32).

The documentation build executes them too (sphinx-gallery); this test keeps a
broken example from reaching the build. Each script runs in this process with
the Agg backend, ``plt.show`` as a no-op, and its working directory in a
temporary folder, block by block as sphinx-gallery runs it: the value of the
last expression of a block is what its page prints as ``Out:`` (a bare
``fig.suptitle(...)`` shows ``Out: Text(...)``), so it must be None; nothing
printed may hold a temporary path, and nothing may warn.
"""

import ast
import io
import re
import tempfile
import warnings
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = sorted((ROOT / "examples").glob("plot_*.py"))
PLOTTING_FUNCTIONS = ["plot_parameters", "plot_trace", "plot_tracking", "plot_comparison",
                      "plot_autocorrelation", "plot_cross_correlation", "plot_residuals",
                      "plot_bode", "plot_step", "plot_plant_comparison", "plot_frequency_band",
                      "plot_order_selection", "plot_cusum", "plot_report", "plot_str_history",
                      "plot_smoothed", "plot_compare", "plot_impulse", "plot_segmentation",
                      "plot_profile_likelihood"]


def test_the_gallery_shows_every_plotting_function():
    import rlsfilt.plotting

    functions = [n for n in rlsfilt.plotting.__all__ if n.startswith("plot_")]
    assert sorted(functions) == sorted(PLOTTING_FUNCTIONS)
    text = "\n".join(p.read_text() for p in EXAMPLES)
    missing = [f for f in functions if f not in text]
    assert not missing, f"no gallery example shows {missing}"
    assert (ROOT / "examples" / "README.rst").is_file()


def gallery_blocks(source):
    """The code blocks of a gallery script as sphinx-gallery splits them (at ``# %%``):
    ``(first line number, text)``."""
    blocks, start, lines = [], 1, []
    for number, line in enumerate(source.splitlines(keepends=True), 1):
        if re.match(r"# ?%%", line):
            blocks.append((start, "".join(lines)))
            start, lines = number, [line]
        else:
            lines.append(line)
    blocks.append((start, "".join(lines)))
    return blocks


def run_blocks(source, filename, namespace):
    """Run `source` block by block in `namespace`; returns ``[(line, value)]``: the value of
    each block's last expression statement (what sphinx-gallery prints after the block)."""
    values = []
    for start, text in gallery_blocks(source):
        tree = ast.parse(text, filename)
        ast.increment_lineno(tree, start - 1)
        last = tree.body[-1] if tree.body and isinstance(tree.body[-1], ast.Expr) else None
        if last is not None and isinstance(last.value, ast.Constant):
            last = None                                   # a docstring: text, not output
        body = tree.body[:-1] if last is not None else tree.body
        exec(compile(ast.Module(body=body, type_ignores=[]), filename, "exec"), namespace)
        if last is not None:
            value = eval(compile(ast.Expression(last.value), filename, "eval"), namespace)
            values.append((last.lineno, value))
    return values


def test_run_blocks_returns_what_sphinx_gallery_prints():
    source = ('"""Title\n=====\n"""\nx = 1\nx + 1\n# %%\n# text\nprint(x)\n'
              '# %%\ny = [x]\n')
    namespace = {}
    assert run_blocks(source, "s.py", namespace) == [(5, 2), (8, None)]
    assert namespace["y"] == [1]
    assert [start for start, _ in gallery_blocks(source)] == [1, 6, 9]


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_example_runs(script, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(plt, "show", lambda *args, **kwargs: None)
    plt.close("all")
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            values = run_blocks(script.read_text(), str(script),
                                {"__name__": "__main__", "__file__": str(script)})
        assert not caught, [f"{w.category.__name__}: {w.message}" for w in caught]
        shown = [(line, repr(v)) for line, v in values if v is not None]
        assert not shown, f"{script.name}: blocks that end in a value (line, Out:): {shown}"
        figures = [plt.figure(n) for n in plt.get_fignums()]
        assert figures, f"{script.name} draws no figure"
        for fig in figures:
            fig.savefig(io.BytesIO(), format="png", dpi=72)
            for ax in fig.axes:                      # every panel says what it shows
                assert ax.get_ylabel() or ax.get_title(), (script.name, ax)
        # a docstring title for the gallery page
        first = script.read_text().split('"""')[1].strip().splitlines()
        assert len(first) >= 2 and set(first[1]) == {"="}, script.name
    finally:
        plt.close("all")
    printed = capsys.readouterr()
    for temp in {tempfile.gettempdir(), "/tmp/", str(tmp_path)}:
        assert temp not in printed.out + printed.err, f"{script.name} prints a temporary path"
    assert "Warning" not in printed.err, printed.err
