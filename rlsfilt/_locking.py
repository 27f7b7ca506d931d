"""A reentrant lock per object: the one home of the decorator and of the constructor's signature.

The filters, the bank and the streaming estimators make their lock in ``__new__``
(so that every instance has one, copies and unpickled ones included) and hold it
around every state-changing call (`locked`; `atomic` also undoes a call that
raises, for the banks). Python's ``inspect.signature`` and
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


def atomic(method):
    """`method` as one transaction holding ``self._lock``: if it raises (a rejected
    input, or a warning turned into an error after the step was computed), the
    object's attributes are put back as they were. For objects whose methods
    replace arrays and never write into the ones they leave behind (the banks),
    so that a shallow copy of ``__dict__`` is enough to undo them."""
    @functools.wraps(method)
    def run(self, *args, **kwargs):
        with self._lock:
            before = self.__dict__.copy()
            try:
                return method(self, *args, **kwargs)
            except BaseException:
                self.__dict__.clear()
                self.__dict__.update(before)
                raise
    return run


def init_signature(cls):
    """``inspect.Signature`` of ``cls.__init__`` without ``self``."""
    sig = inspect.signature(cls.__init__)
    return sig.replace(parameters=list(sig.parameters.values())[1:])
