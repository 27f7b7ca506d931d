"""A progress bar that appears only when a loop runs long (tqdm, when installed).

Searches that fit many candidates (`select_structure`, and through it
`select_order` for the model family) say nothing while they are quick; once a
search has run `after` seconds, a tqdm bar shows how many candidates are done
and how many remain. Without tqdm the search runs silently, unless the caller
asked for the bar (``progress=True``: an ImportError says how to get it).
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
    """

    def __init__(self, total, progress="auto", desc="", after=AFTER):
        if progress not in ("auto", True, False):
            raise ValueError(f"`progress` must be 'auto', True or False; got {progress!r}")
        self.total, self.progress, self.desc, self.after = total, progress, desc, after
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
        self.bar = tqdm(total=self.total, desc=self.desc, leave=False)
        self.bar.update(self.count)

    def tick(self):
        """One item done."""
        self.count += 1
        if (self.bar is None and self.progress == "auto"
                and time.monotonic() - self.start > self.after):
            self._open()
        if self.bar is not None:
            self.bar.update(1)

    def close(self):
        if self.bar is not None:
            self.bar.close()
