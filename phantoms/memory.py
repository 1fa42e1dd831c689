"""Memory checks before a grid is allocated: refuse what cannot fit with the largest size that would."""

from __future__ import annotations

import numpy as np

from geometry.errors import InputError

__all__ = ["available_memory", "check_memory"]


def available_memory() -> int | None:
    """Bytes of memory available for new allocations (``MemAvailable`` of /proc/meminfo), None if unknown."""
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def check_memory(shape, channels: int, itemsize: int = 8, what: str = "the volume") -> None:
    """Refuse, before allocating, a grid of ``shape`` that needs ``channels`` arrays of ``itemsize`` bytes per
    point (N³ × channels × itemsize) when that exceeds the available memory: an :class:`InputError` that
    gives the need and the largest N (N³ grid) that fits, instead of a MemoryError after seconds of work."""
    avail = available_memory()
    points = float(np.prod([float(s) for s in shape]))
    need = points * channels * itemsize
    if avail is None or need <= avail:
        return
    n_max = int((avail / (channels * itemsize)) ** (1 / 3))
    while (n_max + 1) ** 3 * channels * itemsize <= avail:
        n_max += 1
    while n_max > 1 and n_max ** 3 * channels * itemsize > avail:
        n_max -= 1
    dims = "×".join(str(int(s)) for s in shape)
    raise InputError(f"{what} on a {dims} grid needs about {need / 2**30:.1f} GiB ({channels} arrays of "
                     f"{itemsize}-byte values per grid point) but {avail / 2**30:.1f} GiB of memory are "
                     f"available; the largest N³ grid that fits is N = {n_max}")
