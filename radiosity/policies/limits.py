"""Policies every stage applies the same way: the seed's range, an exposure's, and the
memory this process may still use. One implementation each, so the commands agree.
"""

from __future__ import annotations

import math
import os

from radiosity.files.errors import InputError

DEFAULT_NODES = 8  # quadrature nodes of the emitters' highlights (``--highlight-nodes``, ``radiosity.physics.emitters``)
MAX_NODES = 32
SEED_LIMIT = 2**63  # seeds are hashed as unsigned 64-bit numbers; the CLI keeps them in int64


def check_seed(seed, flag="--seed"):
    """``seed`` as an int in [0, 2^63); otherwise InputError naming ``flag``."""
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < SEED_LIMIT:
        raise InputError(f"{flag} must be a whole number from 0 to 2^63 - 1, got {seed}")
    return seed


def check_exposure(exposure, flag="--exposure"):
    """``exposure`` as a float that is positive and finite; otherwise InputError naming ``flag``."""
    value = float(exposure)
    if not (value > 0.0 and math.isfinite(value)):
        raise InputError(f"{flag} must be a positive finite number, got {exposure:g}")
    return value


def available_memory():
    """Bytes of memory this process may still use: the kernel's MemAvailable, lowered
    to what is left under a cgroup (container) limit; None where unknown."""
    candidates = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    candidates.append(int(line.split()[1]) * 1024)
                    break
    except (OSError, ValueError, IndexError):
        pass
    if not candidates:
        try:
            candidates.append(os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
        except (OSError, ValueError, AttributeError):
            pass
    for limit_file, used_file in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),  # cgroup v2
        ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"),  # v1
    ):
        try:
            with open(limit_file) as f:
                limit = f.read().strip()
            with open(used_file) as f:
                used = int(f.read().strip())
        except (OSError, ValueError):
            continue
        if limit != "max" and int(limit) < 2**62:  # v1 says "no limit" with a huge number
            candidates.append(max(int(limit) - used, 0))
        break
    return min(candidates) if candidates else None
