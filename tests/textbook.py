"""The NumPy textbook reference of the filters, imported from one place.

The readable recursions (``rls_predict``, ``rls_update``, ``update_<mode>``,
``square_root_update``, ``SlidingWindow``, ...) live in
``rlsfilt/filters/_reference.py`` today and are moving into ``tests/`` (issue
#26: test-only code out of the installed package). Suites import them as
``from textbook import ref`` so that the move changes this file only.
"""

try:                                           # in the package (before the move)
    from rlsfilt.filters import _reference as ref
except ImportError:                            # in tests/ (after the move)
    import _reference as ref  # noqa: F401

__all__ = ["ref"]
