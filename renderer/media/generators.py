"""Density grids of the paper's media figures (seed/volumetric-path-tracing.txt); numpy only.

One home for the generators that both the renderer's example scenes (examples/media_scenes.py)
and the Blender add-on's Add > Volume operators (addon/volume_grids.py) use. Grids are
(nz, ny, nx) float32 arrays indexed [z, y, x], x fastest: the pseudo-code's flat list
density[(z * ny + y) * nx + x] reshaped, as in Haze's scene format.
"""

from __future__ import annotations

import numpy as np


def smoke_ball_density(n: int = 11, radius: float | None = None, falloff: float = 2.0) -> np.ndarray:
    """The Fig. 3 generator: density falloff^-(dist + 2) at `dist` voxels from the grid centre
    (1 / 2^(dist + 2) by default), within `radius` voxels (default (n - 2) / 2, the paper's
    9/2 for 11^3) and 0 on the grid's faces (the caption's two changes to the pseudo-code,
    which keep the ball's edge soft)."""
    radius = (n - 2) / 2.0 if radius is None else radius
    centre = (n - 1) / 2.0
    z, y, x = np.meshgrid(np.arange(n), np.arange(n), np.arange(n), indexing="ij")
    dist = np.sqrt((x - centre) ** 2 + (y - centre) ** 2 + (z - centre) ** 2)
    density = 1.0 / falloff ** (dist + 2.0)
    interior = np.zeros((n, n, n), bool)
    interior[1:-1, 1:-1, 1:-1] = True  # the pseudo-code's loops skip the faces
    return np.where(interior & (dist <= radius), density, 0.0).astype(np.float32)


def gaussian_smoke_density(n: int = 32, seed: int = 6, blobs: int = 24) -> np.ndarray:
    """Fig. 6's gaussian-randomised smoke: `blobs` gaussian puffs with normally distributed
    centres (around the grid centre) and radii from a seeded generator, scaled to peak
    density 1 and faded to 0 at the grid's outermost voxels (no hard edge)."""
    rng = np.random.default_rng(seed)
    axis = (np.arange(n) + 0.5) / n
    z, y, x = np.meshgrid(axis, axis, axis, indexing="ij")
    density = np.zeros((n, n, n))
    for _ in range(blobs):
        cx, cy, cz = np.clip(rng.normal(0.5, 0.14, 3), 0.2, 0.8)
        r = abs(rng.normal(0.12, 0.04)) + 0.04
        w = rng.uniform(0.5, 1.0)
        density += w * np.exp(-((x - cx) ** 2 + (y - cy) ** 2 + (z - cz) ** 2) / (2 * r * r))
    # distance to the outermost voxel centres: those are 0
    fade = np.minimum.reduce([x, 1 - x, y, 1 - y, z, 1 - z]) - 0.5 / n
    density *= np.clip(fade / 0.1, 0.0, 1.0)
    return (density / density.max()).astype(np.float32)
