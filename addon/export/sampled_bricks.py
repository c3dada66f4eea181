"""Grids of volumes that are not files (geometry nodes, modifiers, a mesh whose node tree
outputs a volume) read through the geometry-node sampler into 8^3 bricks, in bounded memory.

The sampler (grid_sampler) reads any box of a grid's index space. Here the volume's index
box is read one z-row of bricks at a time: the row's eight voxel layers plus the next row's
first (the bricks' apron, renderer.media.bricks), each layer read once (the apron layer is
kept for the next row), cleaned as clean_grid cleans dense grids (vdb_reader.clean_slab),
and only the bricks holding a non-zero voxel are kept (BrickBuilder). The memory is one
row's slab (9 layers of the box's x-y extent, per grid) plus the occupied bricks: the dense
bounding box is never allocated, so a large volume that occupies little of its box costs
what it occupies.
"""

from __future__ import annotations

import numpy as np

from renderer.media.bricks import BRICK, SPAN, BrickBuilder, SparseGrid

from .grid_sampler import GridInfo, GridSampler
from .messages import Messages
from .vdb_reader import clean_slab, warn_dropped


def sample_bricks(sampler: GridSampler, target, grids: dict[str, GridInfo], start, shape, clipping: float,
                  subject: str, messages: Messages) -> dict[str, SparseGrid]:
    """Scalar grids[attribute] of `target` over the index box start .. start + shape - 1
    (x, y, z) as SparseGrids sharing one brick index (keys: attributes), cleaned as
    clean_grid does (voxels below `clipping`, negative and non-finite ones read 0; the last
    two are counted and warned about once per grid)."""
    nx, ny, nz = (int(v) for v in shape)
    builder = BrickBuilder((nz, ny, nx), {attribute: 1 for attribute in grids})
    readers = {attribute: sampler.reader(target, grid) for attribute, grid in grids.items()}
    counts = {attribute: [0, 0] for attribute in grids}  # non-finite, negative voxels
    slab_shape = builder.slab_shape(next(iter(grids)))
    start = np.asarray(start, np.int64)
    carried: dict[str, np.ndarray] = {}  # each grid's first layer of the current row
    for bk in range(builder.index.shape[0]):
        z0 = bk * BRICK
        slabs = {}
        for attribute, grid in grids.items():
            slab = np.zeros(slab_shape, np.float32)
            first = z0 + (1 if attribute in carried else 0)
            last = min(z0 + SPAN, nz)  # past the grid the apron stays 0 (never read)
            if attribute in carried:
                slab[0, :ny, :nx] = carried.pop(attribute)
            if last > first:
                box = (start[0], start[1], start[2] + first)
                slab[first - z0:last - z0, :ny, :nx] = sampler.read_with(readers[attribute], grid, box,
                                                                         (nx, ny, last - first))
            if last == z0 + SPAN:
                carried[attribute] = slab[BRICK, :ny, :nx].copy()
            slabs[attribute] = clean_slab(slab, clipping, counts[attribute])
        builder.add_row(bk, slabs)
    warn_dropped(counts, {a: g.name for a, g in grids.items()}, subject, messages)
    return builder.finish()
