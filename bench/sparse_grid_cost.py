"""Dense against sparse (bricked) grids: `.venv/bin/python -m bench sparse_grid_cost [n ...]`. Prints figures.

For each n (default 32 64 128) the smooth blob of bench/contrast.py on an n^3 grid, stored
dense and as 8^3 bricks (renderer/media/bricks.py), both with the majorant grid; reports
the memory of each and the CPU seconds per sample (pixel sample, all bounces) rendering
the same view on this thread (bench.contrast.seconds_per_sample), and the cost of one
trilinear lookup at random points.
Where sparse is no slower per sample, the add-on may read grids sparsely (its threshold is
addon/export/volume_read.py SPARSE_MIN_VOXELS).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
from numba import njit

from bench.contrast import grids, scene, seconds_per_sample
from renderer.media import compile_media
from renderer.media.bricks import to_sparse
from renderer.media.grid import grid_lookup


@njit(cache=True)
def _lookups(mt, m, pts):
    total = 0.0
    for i in range(len(pts)):
        total += grid_lookup(mt, m, 0, (pts[i, 0], pts[i, 1], pts[i, 2]))
    return total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench sparse_grid_cost", description=__doc__.splitlines()[0])
    parser.add_argument("sizes", type=int, nargs="*", default=[32, 64, 128],
                        help="voxels per axis (default 32 64 128)")
    sizes = parser.parse_args(argv).sizes
    pts = np.random.default_rng(0).random((2_000_000, 3))
    for n in sizes:
        dense = grids(n)["smooth"]
        sparse = to_sparse(dense)
        medium = scene(dense, 8, 1).media[0]
        mt = compile_media([medium, replace(medium, density=sparse)])
        _lookups(mt, 0, pts[:10])
        _lookups(mt, 1, pts[:10])
        per = []
        for m in (0, 1):
            t = time.process_time()
            _lookups(mt, m, pts)
            per.append((time.process_time() - t) / len(pts) * 1e9)
        cpu = [min(seconds_per_sample(scene(d, 32, 8)) for _ in range(2)) * 1e6 for d in (dense, sparse)]
        print(f"n={n}: dense {dense.nbytes / 2**20:.2f} MB, sparse {sparse.nbytes / 2**20:.2f} MB "
              f"({len(sparse.bricks)} of {sparse.index.size} bricks); lookup {per[0]:.1f} / {per[1]:.1f} ns; "
              f"CPU per sample {cpu[0]:.1f} / {cpu[1]:.1f} us (dense / sparse)", flush=True)
    return 0
