"""A reentrant lock per object: the one home of the decorator and of the constructor's signature.

The filters, the bank and the streaming estimators make their lock in ``__new__``
(so that every instance has one, copies and unpickled ones included) and hold it
around every state-changing call (`locked`). Python's ``inspect.signature`` and
Sphinx look at ``__new__`` before ``__init__``, so they would show ``(*args,
**kwargs)``; a ``__signature__`` taken from ``__init__`` (`init_signature`) puts
the real parameters back (``help()``, IDEs, the API pages).
"""

import functools
import inspect

__all__ = []


def locked(method):
    """`method` holding ``self._lock``: an object shared by threads applies each call whole."""
    @functools.wraps(method)
    def run(self, *args, **kwargs):
        with self._lock:
            return method(self, *args, **kwargs)
    return run


def init_signature(cls):
    """``inspect.Signature`` of ``cls.__init__`` without ``self``."""
    sig = inspect.signature(cls.__init__)
    return sig.replace(parameters=list(sig.parameters.values())[1:])
