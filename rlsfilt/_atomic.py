"""Atomic file writes: a file rlsfilt writes is either the old one or the complete new one.

Every file the package or the command line writes (model files, the JSON
results and the summaries of ``rlsfilt identify`` and ``identify-many``)
goes through :func:`atomic_write`: the text is written to a temporary file
in the target's folder, flushed and synced to disk, then renamed over the
target with :func:`os.replace` (atomic on POSIX and Windows within one
file system). A write that fails or is interrupted midway leaves the
existing file as it was and removes the temporary file.
"""

import contextlib
import os
import tempfile

__all__ = []


@contextlib.contextmanager
def atomic_write(path, mode="w", *, encoding="utf-8", newline=None):
    """Open a temporary file beside `path`; on success it replaces `path`.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write (created or replaced).
    mode : {"w", "wb"}, default "w"
        Text or binary.
    encoding : str, default "utf-8"
        Text mode only.
    newline : str, optional
        Text mode only, as for :func:`open` (``""`` writes line endings
        untranslated, what the `csv` module expects).

    Yields
    ------
    file object
        Write to it; when the ``with`` block ends without an exception the
        data is flushed, synced (:func:`os.fsync`) and the file renamed to
        `path`. On an exception the temporary file is removed, `path` is
        untouched and the exception propagates.

    Raises
    ------
    OSError
        If the folder of `path` cannot be written (nothing is created).
    ValueError
        For a `mode` other than ``"w"`` or ``"wb"``.
    """
    if mode not in ("w", "wb"):
        raise ValueError(f"`mode` must be 'w' or 'wb'; got {mode!r}")
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=f".{os.path.basename(path)}.", suffix=".tmp",
                               dir=folder)
    try:
        if mode == "wb":
            fh = os.fdopen(fd, "wb")
        else:
            fh = os.fdopen(fd, "w", encoding=encoding, newline=newline)
        with fh:
            yield fh
            fh.flush()
            os.fsync(fh.fileno())
        _keep_mode(path, tmp)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def _keep_mode(path, tmp):
    """Give the new file the permissions the old one had (mkstemp makes it 0600), or the
    usual ones of a new file (0666 minus the umask)."""
    try:
        mode = os.stat(path).st_mode & 0o7777
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        mode = 0o666 & ~umask
    with contextlib.suppress(OSError):
        os.chmod(tmp, mode)
