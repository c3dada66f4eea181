"""How many cores this process may use: the default number of render workers.

os.cpu_count() counts the host's cores. A farm node or a container usually gives a process
fewer: a CPU affinity mask (taskset, a scheduler's cpuset) and a CFS quota (docker --cpus,
Kubernetes limits, written to the cgroup as quota / period). Each worker holds a copy of the
scene, so starting one per host core on a 4-core slot of a 64-core machine wastes memory and
time-slices the slot. Python 3.13 has os.process_cpu_count() for the affinity part; Haze runs
on 3.11.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

CGROUP_ROOT = Path("/sys/fs/cgroup")


def affinity_cores() -> int:
    """Cores in this process's affinity mask (all cores where the OS has no masks)."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def quota_cores(root: Path = CGROUP_ROOT) -> float | None:
    """The cgroup's CPU quota in cores (cgroup v2 cpu.max, else v1 cpu.cfs_quota_us over
    cpu.cfs_period_us), or None when there is none or it cannot be read."""
    v2 = _read(root / "cpu.max")  # "max 100000" or "200000 100000"
    if v2 is not None:
        quota, _, period = v2.partition(" ")
        return _ratio(quota, period)
    return _ratio(_read(root / "cpu" / "cpu.cfs_quota_us"), _read(root / "cpu" / "cpu.cfs_period_us"))


def _ratio(quota: str | None, period: str | None) -> float | None:
    try:
        q, p = int(quota), int(period)  # "max" or -1 (v1) mean no quota
    except (TypeError, ValueError):
        return None
    return q / p if q > 0 and p > 0 else None


def usable_cores(root: Path = CGROUP_ROOT) -> int:
    """The cores this process may use: its affinity mask, capped by a CPU quota (rounded up:
    a 1.5-core quota still runs two workers at three quarters each)."""
    cores = affinity_cores()
    quota = quota_cores(root)
    if quota is not None:
        cores = min(cores, math.ceil(quota))
    return max(1, cores)
