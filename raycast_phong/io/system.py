"""What the machine can give now: available memory (Linux's /proc/meminfo, capped by cgroup v1/v2 limits and
`ulimit -v`), and how byte and triangle counts are written in messages.
"""

from __future__ import annotations

import math
import os
import re
import sys
from contextlib import suppress
from pathlib import Path


def default_threads() -> int:
    """Threads a render (its tiles, and its mesh preparation) uses when not told: the machine's cores, at most 8."""
    return max(1, min(os.cpu_count() or 1, 8))


def usable_cores() -> int:
    """The cores this process may run on (its affinity, on Linux), else the machine's."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def available_memory() -> int | None:
    """Bytes the machine can give this process now: MemAvailable (Linux), capped by its cgroup's limit (v2 or
    v1, its own cgroup and every parent) and by the address space `ulimit -v` (RLIMIT_AS) leaves; else free
    pages. A command's --max-memory is its caller's to apply (io.meshes.size.check_mesh_read's max_memory)."""
    found = None
    with suppress(OSError, ValueError, IndexError), open("/proc/meminfo", "rb") as meminfo:
        found = next((int(line.split()[1]) * 1024 for line in meminfo if line.startswith(b"MemAvailable:")), None)
    if found is None:
        try:
            found = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            return None
    limits = [limit for limit in (_cgroup_room(), _address_space_room()) if limit is not None]
    return min([found, *limits])


UNITS = {"": 1, "k": 1 << 10, "m": 1 << 20, "g": 1 << 30, "t": 1 << 40}


def parse_size(text: str) -> int:
    """'8G', '500M', '1.5GiB', '2048' (bytes) → bytes; K, M, G, T are powers of 1024. ValueError otherwise."""
    match = re.fullmatch(r"\s*(\d+(?:\.\d*)?|\.\d+)\s*([kmgt]?)(?:i?b)?\s*", str(text), re.I)
    size = float(match[1]) * UNITS[match[2].lower()] if match else math.nan  # 400 digits: inf
    if not 0 < size < math.inf:
        shown = repr(text)
        shown = shown if len(shown) <= 60 else f"{shown[:60]}… ({len(shown) - 60:,} more characters)"
        raise ValueError(f"expected a size such as 8G, 500M or 1.5GiB (K, M, G, T: powers of 1024), got {shown}")
    return int(size)


BUDGET_SHARE = 0.75  # of the memory available now: the rest is for the OS and other programs


def default_budget() -> int | None:
    """BUDGET_SHARE of the available memory; None (no limit) where the platform tells nothing."""
    available = available_memory()
    return None if available is None else int(available * BUDGET_SHARE)


def budget_of(max_memory: int | str | None) -> int | None:
    """The bytes a command may use: `max_memory` (bytes, or '8G'), else default_budget(); None: no limit known.

    The one home of that rule (render, compare, batch, the references). A budget of 0 bytes or less is a
    ValueError, never the default in disguise (`max_memory or default_budget()` would make 0 that default)."""
    budget = parse_size(max_memory) if isinstance(max_memory, str) else max_memory
    if budget is None:
        return default_budget()
    if isinstance(budget, bool) or not isinstance(budget, int | float) or not budget > 0:
        raise ValueError(f"max_memory must be a positive number of bytes or a size such as '8G', got {budget!r}")
    return int(budget)


def memory_allowed(max_memory: int | str | None) -> int | None:
    """What a read may use: the memory available now (available_memory), capped by `max_memory` (a command's
    --max-memory: bytes, or '8G' as parse_size reads it); None: no limit known."""
    if isinstance(max_memory, str):
        max_memory = parse_size(max_memory)
    available = available_memory()
    if max_memory is not None:
        available = max_memory if available is None else min(available, max_memory)
    return available


_CGROUP_ROOT = "/sys/fs/cgroup"  # tests/contracts/test_watchdog.py points it at a fake tree, from outside


def _cgroup_room(root: str | Path | None = None, lines: list[str] | None = None) -> int | None:
    """What the tightest memory limit of this process's cgroup and its parents leaves (v2, else v1): the
    cgroup tree under `root` (default /sys/fs/cgroup), the process's cgroups from `lines` (default
    /proc/self/cgroup's)."""
    root = Path(root or _CGROUP_ROOT)
    room = None
    if lines is None:
        lines = []
        with suppress(OSError):
            lines = Path("/proc/self/cgroup").read_text().splitlines()
    places = []
    for line in lines:
        number, controllers, where = [*line.split(":", 2), "", ""][:3]
        if number == "0" and controllers == "":
            places.append((root / where.lstrip("/"), "memory.max", "memory.current"))
        elif "memory" in controllers.split(","):
            places.append((root / "memory" / where.lstrip("/"), "memory.limit_in_bytes", "memory.usage_in_bytes"))
    places.append((root, "memory.max", "memory.current"))
    for folder, limit_name, used_name in places:
        while True:
            with suppress(OSError, ValueError):
                limit = (folder / limit_name).read_text().strip()
                used = int((folder / used_name).read_text())
                if limit != "max" and int(limit) < 1 << 62:  # v1 writes "no limit" as a huge number
                    left = max(int(limit) - used, 0)
                    room = left if room is None else min(room, left)
            if folder.parent == folder or folder in (root, root / "memory"):
                break
            folder = folder.parent
    return room


def _address_space_room() -> int | None:
    """What `ulimit -v` (RLIMIT_AS) leaves above this process's mapped size now; None without a limit."""
    try:
        import resource
        soft = resource.getrlimit(resource.RLIMIT_AS)[0]
        if soft == resource.RLIM_INFINITY:
            return None
        with open("/proc/self/status", "rb") as status:
            size = next((int(line.split()[1]) * 1024 for line in status if line.startswith(b"VmSize:")), 0)
        return max(soft - size, 0)
    except (ImportError, OSError, ValueError):
        return None


# NUMBA_* settings whose values need no numba to check: validated below, or a string numba takes as it is.
PARSED_HERE = {"NUMBA_NUM_THREADS", "NUMBA_DISABLE_JIT", "NUMBA_CACHE_DIR"}


def check_environment() -> list[str]:
    """Refuse (OptionError) NUMBA_* settings the renderer cannot run under, before numba is imported:
    NUMBA_NUM_THREADS that is not a whole number from 1 (numba's import fails on it) and NUMBA_DISABLE_JIT
    (the kernels would run as Python without Embree's calls: a wrong image). Returns numba's own complaints
    about other NUMBA_* values it cannot parse, one line each, instead of its raw multi-line warnings."""
    from ..errors import OptionError
    threads = os.environ.get("NUMBA_NUM_THREADS", "").strip()
    if threads and not (threads.isascii() and threads.isdigit() and 1 <= int(threads) <= 1024):  # not '¹
        raise OptionError(f"NUMBA_NUM_THREADS={threads[:20]!r}: numba's thread count; allowed: a whole number from 1 "
                          f"to 1024 (this machine has {os.cpu_count()} cores), or unset it")
    if os.environ.get("NUMBA_DISABLE_JIT", "").strip() not in ("", "0"):
        raise OptionError("NUMBA_DISABLE_JIT is set: the renderer's kernels call Embree only when compiled, so "
                          "without numba's compiler the image would be wrong; allowed: 0 or unset")
    if all(name in PARSED_HERE for name in os.environ if name.startswith("NUMBA_")) or "numba" in sys.modules:
        return []  # numba (and numpy under it) not imported ahead of the command: `view` sets BLAS's threads first
    import warnings
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        import numba  # noqa: F401  (numba reads its environment once, at import)
    found = []
    for warning in caught:
        text = str(warning.message).splitlines()[0]
        match = re.search(r"variable '(NUMBA_\w+)' is defined but its associated value '(.*)' could not be parsed",
                          text)
        found.append(f"{match[1]}={match[2][:40]!r} is not a value numba understands; it is ignored" if match
                     else text)
    return found


def format_bytes(count: float) -> str:
    """3.4 GB, 512 MB, 20 kB: binary units, written the way people say them."""
    for unit, size in (("TB", 1 << 40), ("GB", 1 << 30), ("MB", 1 << 20), ("kB", 1 << 10)):
        if count >= size:  # 3 figures, but never "1e+03": from 999.5 of a unit up, whole units
            return f"{count / size:.3g} {unit}" if count / size < 999.5 else f"{count / size:,.0f} {unit}"
    return f"{int(count)} bytes"


def count_text(n: int) -> str:
    """335M, 1.3M, 40,000: a triangle count at a glance."""
    if n >= 10_000_000:
        return f"{n / 1e6:.0f}M"
    if n >= 1_000_000:
        return f"{n / 1e6:.1f}M"
    return f"{n:,}"
