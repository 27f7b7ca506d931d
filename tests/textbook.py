"""The NumPy textbook reference of the filters, imported from one place.

The readable recursions (``rls_predict``, ``rls_update``, ``update_<mode>``,
``square_root_update``, ``SlidingWindow``, ``lms_step``, ``apa_step``, ...) live
in ``tests/_reference.py``, not in the installed package (issue #26). Suites
import them as ``from textbook import ref``.
"""

import _reference as ref  # noqa: F401

__all__ = ["ref"]
