"""Contract tests every estimator inherits (scikit-learn's ``parametrize_with_checks``).

A contract suite is a registry of *cases* (one line per estimator
configuration: a name and a factory) and a list of *checks* (functions
``check(case)`` that raise on a broken contract). `parametrize_with_checks`
turns the cross product into one pytest parametrization, so a new estimator
gets every check by adding one line to its registry, and a new check runs on
every estimator by adding it to the list. Known failures are listed once,
with the issue that will fix them, and run as ``xfail(strict=True)``: they
must keep failing until the fix lands (then the entry must go).

``tests/test_contract_filters.py`` holds the filters' registry (``FILTERS``)
and checks; a models suite is a parallel module with its own registry
(``MODELS``) and checks built on the same helper.
"""

import pytest

__all__ = ["parametrize_with_checks"]


def parametrize_with_checks(cases, checks, expected_failures=None):
    """``pytest.mark.parametrize("case, check", ...)`` over every case and check.

    Parameters
    ----------
    cases : list
        Objects with a ``name`` attribute (the registry).
    checks : list of callable
        ``check(case)``; its ``__name__`` names the test.
    expected_failures : dict, optional
        ``{(case name, check name): reason}``; those pairs run as
        ``xfail(strict=True, reason=reason)``.
    """
    expected_failures = dict(expected_failures or {})
    params = []
    for case in cases:
        for check in checks:
            reason = expected_failures.pop((case.name, check.__name__), None)
            marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
            params.append(pytest.param(case, check, marks=marks,
                                       id=f"{case.name}-{check.__name__}"))
    if expected_failures:
        raise ValueError(f"expected failures name no case and check: {sorted(expected_failures)}")
    return pytest.mark.parametrize("case, check", params)
