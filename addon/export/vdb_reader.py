"""OpenVDB files read sparsely into bricks (renderer.media.bricks), with Blender's openvdb module.

A Volume object that loads a file (and has no modifiers) is read here rather than through
the geometry-node sampler: grid names, types and transforms come from the file's metadata,
and each grid the material reads is copied one row of 8^3 bricks at a time (copyToArray
over a 9-voxel-deep slab of the index box, the row's apron included), keeping only the
bricks that hold a non-zero voxel. The dense index box is never allocated: memory is one
slab plus the occupied bricks, so it grows with the active voxels.

The index box and the cleaning are the sampler path's: the grids' active voxel bounding box
plus one voxel of background on every side (so the density falls to 0 inside the grid box,
as Cycles reads the background beyond the voxels), voxels below the volume's clipping value,
negative and NaN voxels read as 0. Only float grids with background 0 are read this way;
anything else goes through the sampler.
"""

from __future__ import annotations

import numpy as np

from renderer.media.bricks import BRICK, SPAN, BrickBuilder, SparseGrid

from .grid_sampler import GridInfo, VolumeInfo
from .messages import Messages

# OpenVDB value type names -> Blender's VolumeGrid.data_type (what GridInfo expects).
BLENDER_TYPES = {"float": "FLOAT", "double": "DOUBLE", "int32": "INT", "int64": "INT64", "bool": "BOOLEAN",
                 "mask": "MASK", "vec3s": "VECTOR_FLOAT", "vec3d": "VECTOR_DOUBLE", "vec3i": "VECTOR_INT"}
SPARSE_TYPES = ("float", "double")  # grid types read into bricks here


def openvdb_module():
    from ..volume_grids import import_openvdb

    return import_openvdb()


def index_to_object(transform) -> np.ndarray:
    """The (4, 4) matrix of an OpenVDB linear transform (index space -> object space)."""
    origin = np.array(transform.indexToWorld((0.0, 0.0, 0.0)), np.float64)
    matrix = np.eye(4)
    for axis in range(3):
        unit = [0.0, 0.0, 0.0]
        unit[axis] = 1.0
        matrix[:3, axis] = np.array(transform.indexToWorld(tuple(unit)), np.float64) - origin
    matrix[:3, 3] = origin
    return matrix


class VdbFile:
    """One .vdb file: its grids' metadata (without their voxels) and sparse reads of them."""

    def __init__(self, path: str) -> None:
        self.vdb = openvdb_module()
        if self.vdb is None:
            raise RuntimeError("this Blender has no OpenVDB Python module")
        self.path = path
        self.meta = {grid.name: grid for grid in self.vdb.readAllGridMetadata(path)}

    def info(self) -> VolumeInfo:
        """Grids (as the sampler would describe them) and the object-space box of the active voxels."""
        grids, corners = {}, []
        for name, grid in self.meta.items():
            matrix = index_to_object(grid.transform)
            kind = BLENDER_TYPES.get(grid.valueTypeName, grid.valueTypeName.upper())
            grids[name] = GridInfo(name, kind, matrix)
            box = self.active_box(name)
            if box is not None:
                lo, hi = box
                index = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                  for z in (lo[2], hi[2])])
                corners.append((index @ matrix.T)[:, :3])
        if not corners:
            return VolumeInfo(grids, (np.zeros(3), np.zeros(3)))
        every = np.concatenate(corners)
        return VolumeInfo(grids, (every.min(axis=0), every.max(axis=0)))

    def active_box(self, name: str) -> tuple[np.ndarray, np.ndarray] | None:
        """Inclusive (x, y, z) index bounds of grid `name`'s active voxels (file metadata), or None."""
        meta = self.meta[name].metadata
        if "file_bbox_min" not in meta or int(meta.get("file_voxel_count", 1)) == 0:
            return None
        lo, hi = np.array(meta["file_bbox_min"], np.int64), np.array(meta["file_bbox_max"], np.int64)
        return (lo, hi) if np.all(hi >= lo) else None

    def sparse_readable(self, name: str) -> bool:
        return self.meta[name].valueTypeName in SPARSE_TYPES

    def read_bricks(self, names: dict[str, str], start, shape, clipping: float, subject: str,
                    messages: Messages, convert=None) -> dict[str, SparseGrid] | None:
        """Grids names[attribute] over the index box start .. start + shape - 1 (x, y, z) as
        SparseGrids sharing one brick index (keys: attributes), cleaned as clean_grid does,
        then convert({attribute: slab}) (a per-voxel function keeping 0 at 0: a smoke cache's
        attributes) if given; None if a grid's background is not 0 (then the sampler path
        reads it)."""
        grids = {attribute: self.vdb.read(self.path, name) for attribute, name in names.items()}
        if any(float(grid.background) != 0.0 for grid in grids.values()):
            return None
        nx, ny, nz = (int(v) for v in shape)
        builder = BrickBuilder((nz, ny, nx), {attribute: 1 for attribute in grids})
        counts = {attribute: [0, 0] for attribute in grids}  # non-finite, negative voxels
        slab_shape = builder.slab_shape(next(iter(grids)))
        start = np.asarray(start, np.int64)
        extent = (slab_shape[2], slab_shape[1], builder.index.shape[0] * BRICK + 1)  # x, y, z
        blocks = [_occupied_blocks(grid, start, extent) for grid in grids.values()]
        for bk in range(builder.index.shape[0]):
            z0 = int(start[2]) + bk * BRICK
            rect = _row_rectangle(blocks, start, z0, slab_shape[2], slab_shape[1])
            if rect is None:
                continue  # no voxel of any grid in this row of bricks: its bricks stay empty
            (x0, x1), (y0, y1) = rect
            slabs = {}
            for attribute, grid in grids.items():
                buffer = np.zeros((x1 - x0, y1 - y0, SPAN), np.float32)  # copyToArray fills [x, y, z]
                grid.copyToArray(buffer, ijk=(int(start[0]) + x0, int(start[1]) + y0, z0))
                slab = np.zeros(slab_shape, np.float32)
                slab[:, y0:y1, x0:x1] = buffer.transpose(2, 1, 0)
                slabs[attribute] = clean_slab(slab, clipping, counts[attribute])
            builder.add_row(bk, convert(slabs) if convert is not None else slabs)
        grids.clear()  # the file's trees (as large as the bricks) go before finish() gathers them
        grid = slabs = None  # the loop variable holds a tree too
        warn_dropped(counts, names, subject, messages)
        return builder.finish()


BLOCK = 128  # voxels per axis of an OpenVDB lower internal node (a block of 16^3 leaves)


def _occupied_blocks(grid, start: np.ndarray, extent: tuple[int, int, int]) -> np.ndarray:
    """(k, 3) index-space origins of the 128^3 blocks (aligned as the tree's internal nodes)
    over the box start .. start + extent (x, y, z) that may hold a non-zero value: a
    block whose value at its origin lies above the lower internal nodes (depth < 2) is one
    constant tile, empty when that value is 0."""
    accessor = grid.getConstAccessor()
    lo = (start // BLOCK) * BLOCK
    hi = start + np.array(extent)
    found = []
    for z in range(int(lo[2]), int(hi[2]), BLOCK):
        for y in range(int(lo[1]), int(hi[1]), BLOCK):
            for x in range(int(lo[0]), int(hi[0]), BLOCK):
                if accessor.getValueDepth((x, y, z)) >= 2 or accessor.getValue((x, y, z)) != 0.0:
                    found.append((x, y, z))
    return np.array(found, np.int64).reshape(-1, 3)


def _row_rectangle(blocks: list[np.ndarray], start: np.ndarray, z0: int, width: int, height: int):
    """((x0, x1), (y0, y1)) slab coordinates covering the occupied blocks that meet slab
    depths z0 .. z0 + 8 (of any grid), or None when there are none."""
    origins = np.concatenate(blocks)
    meets = (origins[:, 2] <= z0 + BRICK) & (origins[:, 2] + BLOCK > z0)
    if not meets.any():
        return None
    near = origins[meets]
    low = np.maximum(near[:, :2].min(axis=0) - start[:2], 0)
    high = np.minimum(near[:, :2].max(axis=0) + BLOCK - start[:2], (width, height))
    return (int(low[0]), int(high[0])), (int(low[1]), int(high[1]))


def warn_dropped(counts: dict[str, list[int]], names: dict[str, str], subject: str,
                 messages: Messages) -> None:
    """Warn, per grid names[attribute], about the voxels clean_slab dropped (counts[attribute])."""
    for attribute, (bad, negative) in counts.items():
        name = names[attribute]
        if bad:
            messages.warn(subject, f"grid '{name}' has {bad} NaN or infinite voxel values; they are "
                                   "treated as 0")
        if negative:
            messages.warn(subject, f"grid '{name}' has {negative} negative voxel values; they are "
                                   "treated as 0 (empty, as Cycles' clipping makes them)")


def clean_slab(slab: np.ndarray, clipping: float, counts: list[int]) -> np.ndarray:
    """clean_grid's rules on one slab, in place (the caller's own buffer), counting what it
    drops into `counts`: non-finite voxels and negative ones read 0, and so do voxels below
    the clipping value (at or below 0 without one)."""
    core = slice(0, BRICK)  # layer 8 is the next row's layer 0: counted there
    finite = np.isfinite(slab)
    if not finite.all():  # rare: the general path
        counts[0] += int(finite[core].size - np.count_nonzero(finite[core]))
        slab[~finite] = 0.0
    counts[1] += int(np.count_nonzero(slab[core] < 0.0))
    drop = slab < max(float(clipping), 0.0) if clipping > 0.0 else slab <= 0.0
    slab[drop] = 0.0
    return slab
