"""The default worker count is the cores a process may use, not the host's (renderer.cores):
a farm node's affinity mask and a container's CPU quota, and Blender's Threads setting."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import pytest

from addon.export.scene import worker_count
from renderer.cores import quota_cores, usable_cores

REPO = Path(__file__).resolve().parents[1]


def cgroup(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text + "\n")
    return tmp_path


@pytest.mark.parametrize("files, cores", [
    ({"cpu.max": "max 100000"}, None),  # cgroup v2, no quota
    ({"cpu.max": "200000 100000"}, 2.0),  # docker --cpus 2
    ({"cpu.max": "150000 100000"}, 1.5),
    ({"cpu/cpu.cfs_quota_us": "-1", "cpu/cpu.cfs_period_us": "100000"}, None),  # v1, no quota
    ({"cpu/cpu.cfs_quota_us": "50000", "cpu/cpu.cfs_period_us": "100000"}, 0.5),
    ({"cpu.max": "garbage"}, None),
    ({}, None),  # no cgroup files at all (another OS, or not mounted)
])
def test_cpu_quota_is_read_from_cgroup_v2_or_v1(tmp_path, files, cores):
    assert quota_cores(cgroup(tmp_path, files)) == cores


def test_a_quota_caps_the_cores_rounded_up(tmp_path):
    assert usable_cores(cgroup(tmp_path, {"cpu.max": "50000 100000"})) == 1
    many = cgroup(tmp_path / "many", {"cpu.max": "6400000 100000"})  # 64 cores: the mask decides
    assert usable_cores(many) == len(os.sched_getaffinity(0))


def in_affinity_mask(cores: set[int], code: str) -> str:
    """Run `code` in a fresh Python whose CPU affinity is `cores` (as taskset or a farm's
    cpuset gives it); its stdout."""
    run = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True,
                         timeout=120, preexec_fn=lambda: os.sched_setaffinity(0, cores))
    assert run.returncode == 0, run.stderr
    return run.stdout.strip()


@pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="no CPU affinity on this OS")
def test_a_farm_nodes_affinity_mask_sets_the_cli_and_renderer_default():
    available = sorted(os.sched_getaffinity(0))
    mask = set(available[:max(1, min(2, len(available) - 1))])  # fewer cores than the host has, if it can
    code = ("from renderer.cli import _parser; from renderer.render import default_workers; "
            "args = _parser().parse_args(['render', 'scene', '-o', 'x.exr']); "
            "print(args.workers, default_workers())")
    assert in_affinity_mask(mask, code) == f"{len(mask)} {len(mask)}"


def test_blender_threads_decide_the_automatic_worker_count():
    automatic, four = SimpleNamespace(workers=0), SimpleNamespace(workers=4)
    assert worker_count(four, SimpleNamespace(threads_mode="FIXED", threads=2)) == 4  # Haze's setting wins
    assert worker_count(automatic, SimpleNamespace(threads_mode="FIXED", threads=3)) == 3
    # AUTO (or `blender -t N`, which Blender reports as render.threads): capped by the usable cores.
    assert worker_count(automatic, SimpleNamespace(threads_mode="AUTO", threads=512)) == usable_cores()
    assert worker_count(automatic, SimpleNamespace(threads_mode="AUTO", threads=1)) == 1
    assert worker_count(automatic) == usable_cores()
