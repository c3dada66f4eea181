"""A volume's material over sparse grids (SparseGrid bricks) to a GridMedium, in bounded memory.

The dense path (grid_fields) stores the material's coefficients per voxel, then factors
them. On sparse grids the material is evaluated brick chunk by brick chunk as well, but
nothing per voxel is kept: the common material (Principled Volume, Volume Scatter and
Absorption, ... scaling one grid by constants) gives sigma_s = s x grid and sigma_a = a x
grid in every chunk, with the same s and a, and then Haze renders that grid unchanged as
its density (no copy). A chunk that does not fit (emission or blackbody per voxel, a
colour grid, a non-linear Math node) makes build_sparse return None and the caller runs the
general factorisation on the bricks' voxels instead (memory per active voxel).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from renderer.media.bricks import BRICK, SparseGrid

from .grid_fields import CHUNK, EXACT, FieldAccumulator, GridMedium, VoxelFields, shape_text
from .volume_shader import VoxelCoefficients

Evaluate = Callable[[dict[str, np.ndarray]], VoxelCoefficients | None]


def build_sparse(grids: dict[str, SparseGrid], evaluate: Evaluate, start: np.ndarray,
                 index_to_object: np.ndarray) -> tuple[GridMedium, VoxelFields] | None:
    """(GridMedium, fields for the anisotropy warning) whose density is one of `grids`
    (SparseGrids sharing a brick index) times constant coefficients, if the material is that
    everywhere; else None."""
    # Every non-zero voxel is in the core (8^3, apron left out) of the brick it belongs to,
    # which is stored; apron voxels repeat a core voxel or are 0, where the material gives 0.
    bricks = len(next(iter(grids.values())).bricks)
    if bricks == 0:
        return None
    count = bricks * BRICK**3
    candidates = list(grids)
    constants: dict[str, dict[str, np.ndarray]] = {}
    # Only the anisotropy goes through the accumulator: its columns get constant zero rows.
    accumulator = FieldAccumulator(count)
    step = max(1, CHUNK // BRICK**3)
    for first in range(0, bricks, step):
        last = min(first + step, bricks)
        chunk = {name: g.bricks[first:last, :BRICK, :BRICK, :BRICK].reshape(-1) for name, g in grids.items()}
        c = evaluate(chunk)
        if c is None:
            return None
        blackbody = any(np.any((t.intensity > 0.0) & (t.weight != 0.0)) for t in c.blackbody)
        if blackbody or np.any(c.emission > 0.0):
            return None
        candidates = [n for n in candidates if _fits(c, chunk[n], constants.setdefault(n, {}))]
        if not candidates:
            return None
        zero = np.zeros((1, 3))
        accumulator.add(first * BRICK**3, last * BRICK**3, VoxelCoefficients(zero, zero, zero, c.anisotropy))
    name = candidates[0]
    fields = accumulator.result()
    sigma_s, sigma_a = (np.maximum(constants[name].get(k, np.zeros(3)), 0.0) for k in ("sigma_s", "sigma_a"))
    medium = GridMedium(grids[name], None, None, sigma_a, sigma_s, np.zeros(3), fields.anisotropy, 0.0, 1.0,
                        np.asarray(start), index_to_object)
    grid = grids[name]
    medium.stats = [f"density grid {shape_text(grid.shape)} voxels, sparse: {len(grid.bricks)} of "
                    f"{grid.index.size} bricks of 8^3, {grid.nbytes / 2**20:.3f} MB"]
    return medium, fields


def _fits(c: VoxelCoefficients, grid: np.ndarray, found: dict[str, np.ndarray]) -> bool:
    """Whether this chunk's sigma_s and sigma_a are grid x the constants found so far (or
    the first chunk that sets them), to float32 precision."""
    g = np.asarray(grid, np.float64)
    norm = float(g @ g)
    for key in ("sigma_s", "sigma_a"):
        values = np.broadcast_to(np.asarray(getattr(c, key), np.float64), (len(g), 3))
        scale = float(np.max(np.abs(values))) if values.size else 0.0
        if norm == 0.0:
            if scale > 0.0:
                return False
            continue
        fit = (g @ values) / norm
        constants = found.setdefault(key, fit)
        if np.any(np.abs(constants - fit) > EXACT * np.maximum(np.abs(constants), 1e-30)):
            return False
        if float(np.max(np.abs(values - np.outer(g, constants)))) > EXACT * max(scale, 1e-30):
            return False
    return True
