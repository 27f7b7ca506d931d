"""The constructor's signature of a class that defines ``__new__(cls, *args, **kwargs)``.

The filters, the bank and the streaming estimators make their lock in ``__new__``
(so that every instance has one, copies and unpickled ones included). Python's
``inspect.signature`` and Sphinx look at ``__new__`` before ``__init__``, so they
would show ``(*args, **kwargs)``; a ``__signature__`` taken from ``__init__``
puts the real parameters back (``help()``, IDEs, the API pages).
"""

import inspect

__all__ = []


def init_signature(cls):
    """``inspect.Signature`` of ``cls.__init__`` without ``self``."""
    sig = inspect.signature(cls.__init__)
    return sig.replace(parameters=list(sig.parameters.values())[1:])
