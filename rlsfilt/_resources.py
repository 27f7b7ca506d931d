"""Memory a call will need, checked before it allocates.

A call that would need more memory than the process can get should say so
at once, in one sentence naming what made it large, rather than run for
minutes, swap, and be killed by the operating system without a word. The
functions that allocate in proportion to their inputs (`ARX.fit`,
`select_order`, `validate`, the dataset generators) estimate their peak
working memory from the sizes involved and compare it with
:func:`available_memory`.

The available memory is the smallest of what the operating system reports
as available (Linux ``MemAvailable``), the room left under a cgroup memory
limit (containers, batch schedulers) and the room left under the address
space limit ``RLIMIT_AS`` (``ulimit -v``). Where none can be read the check
is skipped.
"""

import os

__all__ = []


def available_memory():
    """Bytes this process can still allocate (best estimate), or None when unknown."""
    room = [_meminfo_available(), _cgroup_room(), _address_space_room()]
    room = [r for r in room if r is not None]
    return max(min(room), 0) if room else None


def check_memory(nbytes, what):
    """Raise `MemoryError` if `what` would need more than the available memory.

    Parameters
    ----------
    nbytes : int or float
        The estimated peak working memory of the call.
    what : str
        The call and the sizes that make it large, for the message, for
        example ``"ARX.fit on `u`, `y` of 10000000 samples"``.
    """
    available = available_memory()
    if available is not None and nbytes > available:
        raise MemoryError(f"{what} needs about {format_bytes(nbytes)} of memory; "
                          f"{format_bytes(available)} are available")


def format_bytes(n):
    """``1.5 GB``, ``320 MB``, ``12 kB`` (powers of 1000)."""
    n = float(n)
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


# ----------------------------------------------------------------------
# private helpers: what the operating system says
# ----------------------------------------------------------------------
def _read(path):
    try:
        with open(path) as fh:
            return fh.read()
    except OSError:
        return None


def _meminfo_available():
    text = _read("/proc/meminfo")
    if text is None:
        return None
    for line in text.splitlines():
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) * 1024
    return None


def _cgroup_room():
    """Room under a cgroup v2 (``memory.max``) or v1 (``memory.limit_in_bytes``) limit."""
    for limit_file, usage_file in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                                   ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
                                    "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        limit, usage = _read(limit_file), _read(usage_file)
        if limit is None or usage is None:
            continue
        limit = limit.strip()
        if limit == "max" or not limit.isdigit() or int(limit) >= 2**62:   # no limit
            return None
        return int(limit) - int(usage.strip())
    return None


def _address_space_room():
    """Room under ``RLIMIT_AS``: the soft limit minus the current virtual size."""
    try:
        import resource
    except ImportError:  # not on Windows
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY:
        return None
    statm = _read("/proc/self/statm")
    if statm is None:
        return None
    return soft - int(statm.split()[0]) * os.sysconf("SC_PAGE_SIZE")
