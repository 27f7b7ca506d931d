"""The Examples sections of the models, datasets and validation modules run as doctests.

Equivalent to ``python -m pytest --doctest-modules rlsfilt/models rlsfilt/validation
rlsfilt/datasets``, but part of the normal suite so that a docstring example that
drifts from the code fails CI.
"""

import doctest
import importlib
import pkgutil

import matplotlib
import pytest

matplotlib.use("Agg")

PACKAGES = ["rlsfilt.models", "rlsfilt.validation", "rlsfilt.datasets", "rlsfilt.adaptive",
            "rlsfilt.data"]
# single-module parts of the package with Examples sections
TOP_MODULES = ["rlsfilt.continuous", "rlsfilt.persistence", "rlsfilt._display", "rlsfilt.river",
               "rlsfilt.sklearn"]


def _modules():
    names = []
    for pkg_name in PACKAGES:
        pkg = importlib.import_module(pkg_name)
        names.append(pkg_name)
        names += [f"{pkg_name}.{m.name}" for m in pkgutil.iter_modules(pkg.__path__)]
    return names + TOP_MODULES


MODULES = _modules()


def test_every_subpackage_module_is_collected():
    assert {"rlsfilt.models.arx", "rlsfilt.validation.selection",
            "rlsfilt.datasets.plants"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    report = []
    for test in finder.find(module, name, globs={}):
        runner.run(test, out=report.append)
    result = runner.summarize(verbose=False)  # prints only on failure
    assert result.failed == 0, "".join(report)
