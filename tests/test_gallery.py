"""Every gallery example (``examples/plot_*.py``) runs and draws labelled figures.

The documentation build executes them too (sphinx-gallery); this test keeps a
broken example from reaching the build. Each script runs in this process with
the Agg backend, ``plt.show`` as a no-op, and its working directory in a
temporary folder.
"""

import io
import runpy
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


@pytest.mark.parametrize("script", EXAMPLES, ids=lambda p: p.name)
def test_example_runs(script, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(plt, "show", lambda *args, **kwargs: None)
    plt.close("all")
    try:
        runpy.run_path(str(script), run_name="__main__")
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
    capsys.readouterr()
