"""The environment map's tables: what renderer.lights.environment's kernels read.

`build_environment` turns an Environment's radiance map (equirectangular or mirror ball)
into the kernel tuple below (the importance-sampling distribution included);
`mean_radiance` gives the light table the environment's power. For an equirectangular map
the density over its (u, v) is constant per cell, proportional to f[i, j] = (the mean of
the interpolated luminance over the cell) x sin(theta at the row's centre), as pbrt's 2-D
piecewise-constant distribution and Cycles' background map; a cell is a pixel, or for an
image under MAP_COLUMNS / 2 columns a k x k part of one.

Kernel tuple: laid out in renderer.lights.environment_lookup (None for a constant world,
so that no kernel compiles the map's code).
A mirror-ball image is sampled on its own cells too, over the ball's disk (_ball_density;
the mapping, its Jacobian and the rim are in renderer.lights.environment_ball).
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
    INFO_RIM_PROB,
    INFO_RIM_S,
    INFO_TINT,
    MIRROR_BALL,
)

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
    image, _, _, _, rot, info = _reader(env)
    interpolation = ENV_INTERPOLATIONS[env.interpolation]
    rim = 0.0
    if info[INFO_PROJ] == MIRROR_BALL:
        func, rim, info[INFO_RIM_S] = _ball_density(image, interpolation)
    else:
        func = _pixel_density(image, interpolation)
    h, w = func.shape
    rows = func.sum(axis=1)
    total = rows.sum()
    if not total > 0.0:
        rim = 1.0 if rim > 0.0 else 0.0  # nothing to sample in the cells: the rim takes all
    info[INFO_RIM_PROB] = rim
    row_cdf = _cdf(rows)
    safe = np.where(rows > 0, rows, 1.0)[:, None]
    # A black row is never picked; its uniform cdf only keeps the table well formed.
    cols = np.where(rows[:, None] > 0, func / safe, 1.0 / w)
    col_cdf = np.zeros((h, w + 1))
    col_cdf[:, 1:] = np.cumsum(cols, axis=1)
    col_cdf[:, -1] = 1.0
    info[INFO_NORM] = (1.0 - rim) * h * w / total if total > 0 else 0.0
    return (image, func, row_cdf, np.ascontiguousarray(col_cdf), rot, info)


def mean_radiance(env: Environment) -> np.ndarray:
    """(3,) radiance averaged over the sphere of directions: the light's power / (4 pi)
    per unit area, for choosing among lights."""
    if env.radiance_map is None:
        return np.asarray(env.radiance, np.float64)
    image, tint = np.asarray(env.radiance_map, np.float64), np.asarray(env.radiance, np.float64)
    h, w = image.shape[:2]
    if env.projection == "mirror_ball":
        # d omega = 16 du dv (renderer.lights.environment_ball): the mean over the sphere is
        # 4 / pi x the integral over the disk, a pixel's integral its value / (h w) (Linear's
        # tents integrate to one pixel each), times the part of the pixel inside the disk.
        inside = np.einsum("ijc,ij->c", image, _disk_fraction(h, w)) / (h * w)
        return 4.0 / math.pi * inside * tint
    sin_theta = np.sin(math.pi * (np.arange(h) + 0.5) / h)
    solid = sin_theta * (2.0 * math.pi / w) * (math.pi / h)  # solid angle of a pixel of row i
    integral = np.einsum("ijc,i->c", image, solid)
    return integral / (4.0 * math.pi) * tint


def _reader(env: Environment) -> tuple:
    """The kernel tuple without its distribution: what the map's lookup reads."""
    image = np.ascontiguousarray(env.radiance_map, np.float32)
    info = np.zeros(8)
    info[INFO_TINT:INFO_TINT + 3] = env.radiance
    info[INFO_INTERP] = ENV_INTERPOLATIONS[env.interpolation]
    info[INFO_PROJ] = ENV_PROJECTIONS[env.projection]
    # world -> map: the inverse of an orthogonal matrix is its transpose
    rot = np.ascontiguousarray(np.asarray(env.to_world, np.float64)[:3, :3].T)
    return (image, None, None, None, rot, info)


def _pixel_density(image: np.ndarray, interpolation: int) -> np.ndarray:
    """f of an equirectangular map: the mean interpolated luminance over each cell
    (_cell_luminance, wrapping in u) x sin(theta) at the cell's centre."""
    lum = _cell_luminance(image, interpolation, wrap=True)
    rows = lum.shape[0]
    sin_theta = np.sin(math.pi * (np.arange(rows) + 0.5) / rows)
    return np.ascontiguousarray(lum * sin_theta[:, None])


def _ball_density(image: np.ndarray, interpolation: int) -> tuple[np.ndarray, float, float]:
    """(f, rim probability, s_min) of a mirror-ball map, sampled on its own cells (see
    renderer.lights.environment_ball: the ball is an equal-area map of the sphere, so f needs no
    Jacobian). f is the cells' mean luminance (_cell_luminance, clamped in u) on the cells
    wholly inside the ball's disk, 0 elsewhere. The rest of the disk, a ragged ring at the
    rim, is covered by a second technique drawn with the rim probability: uniform over the
    ring s = a^2 + b^2 in [s_min, 1] (a spherical cap), s_min the smallest s of a cell that
    crosses the rim; the probability is the crossing cells' share of the luminance (their
    whole area counted, which errs towards sampling the rim more)."""
    lum = _cell_luminance(image, interpolation, wrap=False)
    near, far = _disk_reach(*lum.shape)
    inner = far <= 1.0  # a cell is inside the (convex) disk when its farthest corner is
    crossing = (near < 1.0) & ~inner
    s_min = float(near[crossing].min()) if crossing.any() else 1.0
    inner_power, rim_power = lum[inner].sum(), lum[crossing].sum()
    rim = rim_power / (inner_power + rim_power) if rim_power > 0.0 else 0.0
    return np.ascontiguousarray(np.where(inner, lum, 0.0)), float(rim), s_min


def _disk_reach(h: int, w: int) -> tuple[np.ndarray, np.ndarray]:
    """(near, far): the smallest and largest s = a^2 + b^2 over each of h x w cells of a ball
    image, in ball coordinates (a, b) = 2 (u, v) - 1."""
    a = 2.0 * np.arange(w + 1) / w - 1.0  # the cells' edges
    b = 2.0 * np.arange(h + 1) / h - 1.0
    far = np.maximum(b[:-1] ** 2, b[1:] ** 2)[:, None] + np.maximum(a[:-1] ** 2, a[1:] ** 2)[None, :]
    near_a = np.where(a[:-1] * a[1:] < 0.0, 0.0, np.minimum(a[:-1] ** 2, a[1:] ** 2))
    near_b = np.where(b[:-1] * b[1:] < 0.0, 0.0, np.minimum(b[:-1] ** 2, b[1:] ** 2))
    return near_b[:, None] + near_a[None, :], far


def _disk_fraction(h: int, w: int, points: int = 8) -> np.ndarray:
    """(h, w) part of each cell of a ball image inside the disk: 1 or 0 for cells wholly in
    or out, a midpoint rule on points x points for those the rim crosses."""
    near, far = _disk_reach(h, w)
    fraction = (far <= 1.0).astype(np.float64)
    i, j = np.nonzero((near < 1.0) & (far > 1.0))
    t = (np.arange(points) + 0.5) / points
    a = 2.0 * (j[:, None] + t) / w - 1.0
    b = 2.0 * (i[:, None] + t) / h - 1.0
    fraction[i, j] = (a[:, None, :] ** 2 + b[:, :, None] ** 2 <= 1.0).mean(axis=(1, 2))
    return fraction


def _cell_luminance(image: np.ndarray, interpolation: int, wrap: bool) -> np.ndarray:
    """The mean interpolated luminance over each cell, >= 0. Cells are the pixels (H, W) for
    Closest and for an image of MAP_COLUMNS / 2 columns or more (Linear's mean over a pixel
    weighs it and its neighbours 3/4 and 1/8 along each axis: the integral of the tent
    functions over the pixel, wrapping in u or clamped, clamped in v); else k x k per pixel
    (k H, k W), k even so that no cell straddles a pixel centre: each lies within one
    bilinear patch, whose mean over it is its value at the cell's centre."""
    lum = image.astype(np.float64) @ np.asarray(LUMINANCE)
    h, w = lum.shape
    k = 2 * (MAP_COLUMNS // (2 * w))
    if interpolation != CLOSEST and k >= 2:
        x = (np.arange(k * w) + 0.5) / k - 0.5  # cell centres in pixel units (pixel centres at integers)
        j0 = np.floor(x).astype(np.int64)
        tx = x - j0
        j1 = j0 + 1
        j0, j1 = (j0 % w, j1 % w) if wrap else (np.clip(j0, 0, w - 1), np.clip(j1, 0, w - 1))
        lum = (1.0 - tx) * lum[:, j0] + tx * lum[:, j1]
        y = (np.arange(k * h) + 0.5) / k - 0.5
        i0 = np.floor(y).astype(np.int64)
        ty = (y - i0)[:, None]
        lum = (1.0 - ty) * lum[np.clip(i0, 0, h - 1)] + ty * lum[np.clip(i0 + 1, 0, h - 1)]
    elif interpolation != CLOSEST:
        left = np.roll(lum, 1, axis=1) if wrap else np.concatenate([lum[:, :1], lum[:, :-1]], axis=1)
        right = np.roll(lum, -1, axis=1) if wrap else np.concatenate([lum[:, 1:], lum[:, -1:]], axis=1)
        lum = 0.75 * lum + 0.125 * (left + right)
        below = np.concatenate([lum[:1], lum[:-1]])
        above = np.concatenate([lum[1:], lum[-1:]])
        lum = 0.75 * lum + 0.125 * (below + above)
    return np.maximum(lum, 0.0)


def _cdf(weights: np.ndarray) -> np.ndarray:
    cdf = np.zeros(weights.size + 1)
    total = weights.sum()
    if total > 0:
        cdf[1:] = np.cumsum(weights) / total
        cdf[-1] = 1.0
    return cdf
