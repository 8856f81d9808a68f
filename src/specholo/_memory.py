"""How much memory this process may still take, and byte counts for people.

Used before large work starts (reading files, stippling, designing), so that a
request too large for the machine is refused in one line instead of swapping or
being killed.
"""

from __future__ import annotations

import contextlib
import os


def _read_int(path: str) -> int | None:
    try:
        with open(path, encoding="ascii") as fh:
            text = fh.read().strip()
    except (OSError, ValueError):
        return None
    return int(text) if text.isdigit() else None


def available_memory() -> int | None:
    """Bytes of memory this process can still allocate, or None when unknown.

    The least of: the kernel's estimate of available memory (``MemAvailable``),
    the room left under a cgroup memory limit (containers), and the address-space
    limit (``ulimit -v``).
    """
    room: list[int] = []
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    room.append(int(line.split()[1]) * 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    if not room:
        with contextlib.suppress(AttributeError, ValueError, OSError):
            room.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    for limit_file, usage_file in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        ("/sys/fs/cgroup/memory/memory.limit_in_bytes",
         "/sys/fs/cgroup/memory/memory.usage_in_bytes"),
    ):
        limit = _read_int(limit_file)
        usage = _read_int(usage_file)
        if limit is not None and usage is not None and limit < 1 << 60:
            room.append(max(0, limit - usage))
    with contextlib.suppress(ImportError, ValueError, OSError):
        import resource

        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft != resource.RLIM_INFINITY:
            with open("/proc/self/statm", encoding="ascii") as fh:
                used = int(fh.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
            room.append(max(0, soft - used))
    return min(room) if room else None


def format_bytes(n: float) -> str:
    """A byte count for people: '640 MB', '5.8 GB', '60 PB'."""
    for unit in ("B", "KB", "MB", "GB", "TB", "PB"):
        if abs(n) < 999.5:
            return f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} EB"
