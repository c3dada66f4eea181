"""The environment map's tables: what renderer.lights.environment's kernels read.

`build_environment` turns an Environment's equirectangular radiance map into the kernel
tuple below (the importance-sampling distribution included); `mean_radiance` gives the
light table the environment's power. The density over the map's (u, v) is constant per
cell, proportional to f[i, j] = (the mean of the interpolated luminance over the cell) x
sin(theta at the row's centre), as pbrt's 2-D piecewise-constant distribution and Cycles'
background map; a cell is a pixel, or for an image under MAP_COLUMNS / 2 columns a k x k
part of one.

Kernel tuple: laid out in renderer.lights.environment_lookup (None for a constant world,
so that no kernel compiles the map's code).
The distribution is over the equirectangular (u, v) of the map's frame whatever the image's
projection: for an equirectangular image its own pixels (H, W above), for a mirror ball a
grid evaluated from the image (_grid_radiance).
"""

from __future__ import annotations

import math

import numpy as np

from ..scene import ENV_INTERPOLATIONS, ENV_PROJECTIONS, LUMINANCE, Environment
from .environment_lookup import (
    CLOSEST,
    INFO_INTERP,
    INFO_NORM,
    INFO_PROJ,
    INFO_TINT,
    MIRROR_BALL,
    evaluate_grid,
)

# A mirror-ball image is sampled through an equirectangular grid of at most this many rows
# (twice as many columns), evaluated at 2 x 2 points per cell.
MAX_GRID_ROWS = 512

# Cycles evaluates its background map at 1024 columns by default (world.cycles.
# sample_map_resolution); an image narrower than that gets its pixels split into k x k cells
# (k even), so that the density follows Linear's ramps around a small bright spot (a sun of
# 2 x 2 pixels spreads over 3 x 3 with a tent profile, which a constant per pixel
# matches badly).
MAP_COLUMNS = 1024


def build_environment(env: Environment) -> tuple | None:
    """The kernel tuple of `env`'s radiance map; None for a constant environment."""
    if env.radiance_map is None:
        return None
    image, _, _, _, rot, info = reader = _reader(env)
    if info[INFO_PROJ] == MIRROR_BALL:
        func = _grid_density(_grid_radiance(reader))
    else:
        func = _pixel_density(image, ENV_INTERPOLATIONS[env.interpolation])
    h, w = func.shape
    rows = func.sum(axis=1)
    total = rows.sum()
    row_cdf = _cdf(rows)
    safe = np.where(rows > 0, rows, 1.0)[:, None]
    # A black row is never picked; its uniform cdf only keeps the table well formed.
    cols = np.where(rows[:, None] > 0, func / safe, 1.0 / w)
    col_cdf = np.zeros((h, w + 1))
    col_cdf[:, 1:] = np.cumsum(cols, axis=1)
    col_cdf[:, -1] = 1.0
    info[INFO_NORM] = h * w / total if total > 0 else 0.0
    return (image, func, row_cdf, np.ascontiguousarray(col_cdf), rot, info)


def mean_radiance(env: Environment) -> np.ndarray:
    """(3,) radiance averaged over the sphere of directions: the light's power / (4 pi)
    per unit area, for choosing among lights."""
    if env.radiance_map is None:
        return np.asarray(env.radiance, np.float64)
    if env.projection == "mirror_ball":
        image, tint = _grid_radiance(_reader(env)), np.ones(3)  # the grid's radiance holds the tint
    else:
        image, tint = np.asarray(env.radiance_map, np.float64), np.asarray(env.radiance, np.float64)
    h, w = image.shape[:2]
    sin_theta = np.sin(math.pi * (np.arange(h) + 0.5) / h)
    solid = sin_theta * (2.0 * math.pi / w) * (math.pi / h)  # solid angle of a pixel of row i
    integral = np.einsum("ijc,i->c", image, solid)
    return integral / (4.0 * math.pi) * tint


def _reader(env: Environment) -> tuple:
    """The kernel tuple without its distribution: what the map's lookup reads."""
    image = np.ascontiguousarray(env.radiance_map, np.float32)
    info = np.zeros(6)
    info[INFO_TINT:INFO_TINT + 3] = env.radiance
    info[INFO_INTERP] = ENV_INTERPOLATIONS[env.interpolation]
    info[INFO_PROJ] = ENV_PROJECTIONS[env.projection]
    # world -> map: the inverse of an orthogonal matrix is its transpose
    rot = np.ascontiguousarray(np.asarray(env.to_world, np.float64)[:3, :3].T)
    return (image, None, None, None, rot, info)


def _grid_radiance(reader: tuple) -> np.ndarray:
    """(rows, 2 rows, 3) radiance of a map of any projection averaged over the cells of an
    equirectangular grid (2 x 2 points each), as Cycles evaluates its background map."""
    rows = int(min(max(reader[0].shape[0], 16), MAX_GRID_ROWS))
    out = np.zeros((rows, 2 * rows, 3))
    evaluate_grid(reader, out)
    return out


def _grid_density(rgb: np.ndarray) -> np.ndarray:
    """f over the grid: the cells' mean luminance, raised to the largest of each 3 x 3
    neighbourhood (a bright spot between a cell's evaluation points keeps a positive pdf
    around it) x sin(theta) at the row's centre."""
    lum = rgb @ np.asarray(LUMINANCE)
    lum = np.maximum.reduce([np.roll(lum, k, axis=1) for k in (-1, 0, 1)])
    padded = np.concatenate([lum[:1], lum, lum[-1:]])
    lum = np.maximum.reduce([padded[:-2], padded[1:-1], padded[2:]])
    h = lum.shape[0]
    sin_theta = np.sin(math.pi * (np.arange(h) + 0.5) / h)
    return np.ascontiguousarray(np.maximum(lum, 0.0) * sin_theta[:, None])


def _pixel_density(image: np.ndarray, interpolation: int) -> np.ndarray:
    """f: the mean interpolated luminance over each cell x sin(theta) at the cell's centre.
    Cells are the pixels (H, W) for Closest and for an image of MAP_COLUMNS / 2 columns or
    more (Linear's mean over a pixel weighs it and its neighbours 3/4 and 1/8 along each
    axis: the integral of the tent functions over the pixel, wrapping in u, clamped in v);
    else k x k per pixel (k H, k W), k even so that no cell straddles a pixel centre: each
    lies within one bilinear patch, whose mean over it is its value at the cell's centre."""
    lum = image.astype(np.float64) @ np.asarray(LUMINANCE)
    h, w = lum.shape
    k = 2 * (MAP_COLUMNS // (2 * w))
    if interpolation != CLOSEST and k >= 2:
        x = (np.arange(k * w) + 0.5) / k - 0.5  # cell centres in pixel units (pixel centres at integers)
        j0 = np.floor(x).astype(np.int64)
        tx = x - j0
        lum = (1.0 - tx) * lum[:, j0 % w] + tx * lum[:, (j0 + 1) % w]
        y = (np.arange(k * h) + 0.5) / k - 0.5
        i0 = np.floor(y).astype(np.int64)
        ty = (y - i0)[:, None]
        lum = (1.0 - ty) * lum[np.clip(i0, 0, h - 1)] + ty * lum[np.clip(i0 + 1, 0, h - 1)]
    elif interpolation != CLOSEST:
        lum = 0.75 * lum + 0.125 * (np.roll(lum, 1, axis=1) + np.roll(lum, -1, axis=1))
        below = np.concatenate([lum[:1], lum[:-1]])
        above = np.concatenate([lum[1:], lum[-1:]])
        lum = 0.75 * lum + 0.125 * (below + above)
    rows = lum.shape[0]
    sin_theta = np.sin(math.pi * (np.arange(rows) + 0.5) / rows)
    return np.ascontiguousarray(np.maximum(lum, 0.0) * sin_theta[:, None])


def _cdf(weights: np.ndarray) -> np.ndarray:
    cdf = np.zeros(weights.size + 1)
    total = weights.sum()
    if total > 0:
        cdf[1:] = np.cumsum(weights) / total
        cdf[-1] = 1.0
    return cdf
