"""Memory of the worker processes with a large grid: `.venv/bin/python -m bench worker_memory [n]`.

Renders the Cornell box with an n^3 float32 smoke grid (default 256: 64 MB) on two worker
processes and prints, per worker, the peak RSS, PSS (shared pages divided among the
processes mapping them) and USS (pages of its own), read from /proc/PID/smaps_rollup
(Linux) while the render runs, and the same at the last progress report, when both
workers hold the scene (a page mapped by one process only counts as its own). With the
scene's arrays mapped from the shipment file (renderer/workers.py), the grid counts once
per machine: each worker's USS stays far below the grid's size.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from examples.media_scenes import grid_medium, with_grid_medium
from examples.scenes import cornell_box
from renderer.render import render_progressive, worker_pids


def smaps(pid: int) -> dict[str, int]:
    """Rss, Pss and Uss (private clean + dirty) of a process, in bytes."""
    fields = {}
    for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines()[1:]:
        name, value = line.split(":", 1)
        fields[name] = int(value.split()[0]) * 1024
    return {"rss": fields["Rss"], "pss": fields["Pss"],
            "uss": fields["Private_Clean"] + fields["Private_Dirty"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench worker_memory", description=__doc__.splitlines()[0])
    parser.add_argument("n", type=int, nargs="?", default=256,
                        help="voxels per axis of the grid (default 256)")
    n = parser.parse_args(argv).n
    c = (np.arange(n) + 0.5) / n - 0.5
    z, y, x = np.meshgrid(c, c, c, indexing="ij", sparse=True)
    density = np.exp(-(x * x + y * y + z * z) / 0.05).astype(np.float32)
    smoke = grid_medium("smoke", density, (0.0, -0.5, 0.0), (0.4, 0.4, 0.4), (2.0, 2.0, 2.0), (8.0, 8.0, 8.0))
    scene = with_grid_medium(cornell_box(size=64, spp=64, boxes=False), smoke)
    peak: dict[int, dict[str, int]] = {}
    last: dict[int, dict[str, int]] = {}
    for _ in render_progressive(scene, workers=2, in_process=False):
        for pid in worker_pids():
            try:
                last[pid] = now = smaps(pid)
            except OSError:
                continue
            old = peak.setdefault(pid, now)
            peak[pid] = {k: max(old[k], now[k]) for k in now}
    mb = 1024 * 1024
    print(f"grid {n}^3: {density.nbytes / mb:.0f} MB")
    for what, table in (("peak", peak), ("last", last)):
        for pid, m in sorted(table.items()):
            rss, pss, uss = (m[k] / mb for k in ("rss", "pss", "uss"))
            print(f"worker {pid} {what}: RSS {rss:.0f} MB, PSS {pss:.0f} MB, USS {uss:.0f} MB")
    return 0
