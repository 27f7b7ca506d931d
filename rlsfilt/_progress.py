"""A progress bar that appears only when a loop runs long (tqdm, when installed).

Searches that fit many candidates (`select_structure`, and through it
`select_order` for the model family) and the prediction-error fits (their
criterion evaluations) say nothing while they are quick; once one has run
`after` seconds, a tqdm bar shows how far it is. Without tqdm the loop runs
silently, unless the caller asked for the bar (``progress=True``: an
ImportError says how to get it).
"""

import time

__all__ = []

#: ``progress="auto"`` shows a bar once a loop has run this many seconds.
AFTER = 3.0


class LazyProgress:
    """``tick()`` once per item of a loop of `total` items; a bar from `after` seconds on.

    Parameters
    ----------
    total : int
        Items in the loop.
    progress : {"auto", True, False}
        ``"auto"``: a bar after `after` seconds; True: at once; False: never.
    desc : str
        The bar's label.
    unit : str
        What one item is (tqdm's ``unit``).
    """

    def __init__(self, total, progress="auto", desc="", after=AFTER, unit="it"):
        if progress not in ("auto", True, False):
            raise ValueError(f"`progress` must be 'auto', True or False; got {progress!r}")
        self.total, self.progress, self.desc, self.after = total, progress, desc, after
        self.unit = unit
        self.start, self.count, self.bar = time.monotonic(), 0, None
        if progress is True:
            self._open()

    def _open(self):
        try:
            from tqdm.auto import tqdm
        except ImportError:
            if self.progress is True:
                raise ImportError("`progress=True` needs tqdm: pip install tqdm") from None
            self.progress = False
            return
        self.bar = tqdm(total=self.total, desc=self.desc, unit=self.unit, leave=False)
        self.bar.update(self.count)

    def tick(self, **postfix):
        """One item done (`postfix`: values shown beside the bar); returns the seconds
        since the start."""
        self.count += 1
        elapsed = time.monotonic() - self.start
        if self.bar is None and self.progress == "auto" and elapsed > self.after:
            self._open()
        if self.bar is not None:
            self.bar.update(1)
            if postfix:
                self.bar.set_postfix(postfix, refresh=False)
        return elapsed

    def close(self):
        if self.bar is not None:
            self.bar.close()
