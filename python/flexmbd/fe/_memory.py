"""The memory a file needs once read, against the memory this machine has free: files that
would not fit are refused before they are read, with the estimate."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import InvalidModelError


def available_memory() -> int:
    """Bytes of memory available to a new allocation (Linux: MemAvailable; else the physical
    memory)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as lines:
            for line in lines:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return 1 << 62


def check_fits(path: Path, size: int, bytes_per_byte: float, what: str) -> None:
    """Raises `InvalidModelError` if `size` bytes of `what` (the file `path`, with its
    includes), read at about `bytes_per_byte` bytes of memory per byte of text, would need
    more memory than is available."""
    needed = size * bytes_per_byte
    free = available_memory()
    if needed > free:
        raise InvalidModelError(
            f"{path}: reading this {what} of {size / 2**20:.0f} MB would take about "
            f"{needed / 2**30:.1f} GB of memory; {free / 2**30:.1f} GB are available. Reduce "
            "the model in the code that wrote it (fewer nodes, or modes instead of matrices) "
            "or read it on a larger machine",
            item=f"file '{path}'",
        )
