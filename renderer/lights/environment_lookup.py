"""Reading an environment map: directions to the map's (u, v) and back, and its radiance.

Directions and the map (Cycles' direction_to_equirectangular, Blender's world axes). A
world direction d is first taken into the map's frame, m = R d (R: world -> map, the
rotation a Mapping node applies to the texture coordinate), then
    u = 1/2 - atan2(m_y, m_x) / (2 pi)      (u = 1/2 looks down +X)
    v = 1 - acos(m_z) / pi                  (v = 1 at the zenith)
The map is (H, W, 3) float32 radiance with row 0 at the bottom (Blender's pixel order), so
pixel (i, j) covers v in [i, i + 1] / H and u in [j, j + 1] / W. It is read with the image's
interpolation: Closest, or Linear (bilinear between pixel centres, wrapping in u and
clamped in v). A mirror-ball image (Cycles' direction_to_mirrorball) is read at the ball's
point that reflects the direction, clamped at its rim.

Where the radiance comes from is one function, `lookup`: a later world program swaps it for
its own evaluation. The map's tables are one tuple, `env`, laid out as below (built by
renderer.lights.environment_map; sampled by renderer.lights.environment):
  ENV_IMAGE    (H, W, 3) float32  radiance, W/(m^2 sr), before the tint
  ENV_FUNC     (h, w) float64     f, the unnormalised density per cell (of the equirectangular
                                  (u, v), or of a mirror ball's image)
  ENV_ROW_CDF  (h + 1,) float64   marginal cdf over rows
  ENV_COL_CDF  (h, w + 1) float64 conditional cdf over the columns of each row
  ENV_ROT      (3, 3) float64     world -> map rotation
  ENV_INFO     (8,) float64       tint r, g, b; (1 - rim probability) h w / sum(f) (normalises
                                  f into p(u, v)); interpolation code (ENV_INTERPOLATIONS);
                                  projection code (ENV_PROJECTIONS); for a mirror ball, the
                                  probability of sampling its rim and the rim's inner s = r^2
This module imports neither the light table nor the map builder, which both use it.
"""

from __future__ import annotations

import math

from ..kernels import inline_kernel
from ..scene import ENV_INTERPOLATIONS, ENV_PROJECTIONS

ENV_IMAGE, ENV_FUNC, ENV_ROW_CDF, ENV_COL_CDF, ENV_ROT, ENV_INFO = range(6)
INFO_TINT, INFO_NORM, INFO_INTERP, INFO_PROJ, INFO_RIM_PROB, INFO_RIM_S = 0, 3, 4, 5, 6, 7
CLOSEST = ENV_INTERPOLATIONS["closest"]
MIRROR_BALL = ENV_PROJECTIONS["mirror_ball"]


@inline_kernel
def direction_to_uv(env, d):
    """(u, v, sin theta) of world direction d (need not be unit) in the map's frame."""
    mx, my, mz = to_map(env, d)
    n = math.sqrt(mx * mx + my * my + mz * mz)
    z = min(1.0, max(-1.0, mz / n)) if n > 0.0 else 1.0
    u = 0.5 - math.atan2(my, mx) * (0.5 / math.pi)
    v = 1.0 - math.acos(z) / math.pi
    return u, v, math.sqrt(max(0.0, 1.0 - z * z))


@inline_kernel
def to_map(env, d):
    """World direction d in the map's frame (R d; not normalised)."""
    r = env[ENV_ROT]
    return (r[0, 0] * d[0] + r[0, 1] * d[1] + r[0, 2] * d[2],
            r[1, 0] * d[0] + r[1, 1] * d[1] + r[1, 2] * d[2],
            r[2, 0] * d[0] + r[2, 1] * d[1] + r[2, 2] * d[2])


@inline_kernel
def from_map(env, m):
    """Map-frame direction m in the world (R^T m: R is orthogonal)."""
    r = env[ENV_ROT]
    return (r[0, 0] * m[0] + r[1, 0] * m[1] + r[2, 0] * m[2],
            r[0, 1] * m[0] + r[1, 1] * m[1] + r[2, 1] * m[2],
            r[0, 2] * m[0] + r[1, 2] * m[1] + r[2, 2] * m[2])


@inline_kernel
def _uv_to_map(u, v):
    """Unit direction in the map's frame of equirectangular (u, v), and sin theta."""
    theta = math.pi * (1.0 - v)
    phi = math.pi * (1.0 - 2.0 * u)
    sin_t = math.sin(theta)
    return (sin_t * math.cos(phi), sin_t * math.sin(phi), math.cos(theta)), sin_t


@inline_kernel
def uv_to_direction(env, u, v):
    """World direction (unit) of map coordinates (u, v), and sin theta."""
    m, sin_t = _uv_to_map(u, v)
    return from_map(env, m), sin_t


@inline_kernel
def mirror_ball_uv(m):
    """Cycles' direction_to_mirrorball: image (u, v) of map-frame direction m on a mirror
    ball seen from -Y (the image's centre looks down -Y, its rim up +Y)."""
    x, y, z = m[0], m[1] - 1.0, m[2]
    div = 2.0 * math.sqrt(max(-0.5 * y, 0.0))
    if div > 0.0:
        x /= div
        z /= div
    return 0.5 * (x + 1.0), 0.5 * (z + 1.0)


@inline_kernel
def lookup(env, u, v):
    """Radiance at equirectangular (u, v) of the map's frame, tint included, whatever the
    image's projection: the source a world program replaces."""
    if env[ENV_INFO][INFO_PROJ] == MIRROR_BALL:
        m, _ = _uv_to_map(u, v)
        bu, bv = mirror_ball_uv(m)
        return _read(env, bu, bv, False)
    return _read(env, u, v, True)


@inline_kernel
def _read(env, u, v, wrap):
    """The image at (u, v) with its interpolation, wrapping in u (else clamped), clamped in
    v; times the tint."""
    img = env[ENV_IMAGE]
    info = env[ENV_INFO]
    h, w = img.shape[0], img.shape[1]
    if info[INFO_INTERP] == CLOSEST:
        j = int(math.floor(u * w))
        j = j % w if wrap else min(max(j, 0), w - 1)
        i = min(max(int(math.floor(v * h)), 0), h - 1)
        return (img[i, j, 0] * info[0], img[i, j, 1] * info[1], img[i, j, 2] * info[2])
    x = u * w - 0.5
    y = v * h - 0.5
    fx = math.floor(x)
    fy = math.floor(y)
    tx = x - fx
    ty = y - fy
    if wrap:
        j0 = int(fx) % w
        j1 = (j0 + 1) % w
    else:
        j0 = min(max(int(fx), 0), w - 1)
        j1 = min(max(int(fx) + 1, 0), w - 1)
    i0 = min(max(int(fy), 0), h - 1)
    i1 = min(max(int(fy) + 1, 0), h - 1)
    a, b = (1.0 - tx) * (1.0 - ty), tx * (1.0 - ty)  # weights of the four pixel centres
    c, e = (1.0 - tx) * ty, tx * ty
    r = a * img[i0, j0, 0] + b * img[i0, j1, 0] + c * img[i1, j0, 0] + e * img[i1, j1, 0]
    g = a * img[i0, j0, 1] + b * img[i0, j1, 1] + c * img[i1, j0, 1] + e * img[i1, j1, 1]
    bl = a * img[i0, j0, 2] + b * img[i0, j1, 2] + c * img[i1, j0, 2] + e * img[i1, j1, 2]
    return (r * info[0], g * info[1], bl * info[2])
