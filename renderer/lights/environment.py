"""An environment light from an equirectangular radiance map (a world lit by an HDRI, as
Cycles' Environment Texture on the Background), evaluated per escaped ray and sampled by
importance.

Directions and the map (Cycles' direction_to_equirectangular, Blender's world axes). A
world direction d is first taken into the map's frame, m = R d (R: world -> map, the
rotation a Mapping node applies to the texture coordinate), then
    u = 1/2 - atan2(m_y, m_x) / (2 pi)      (u = 1/2 looks down +X)
    v = 1 - acos(m_z) / pi                  (v = 1 at the zenith)
The map is (H, W, 3) float32 radiance with row 0 at the bottom (Blender's pixel order), so
pixel (i, j) covers v in [i, i + 1] / H and u in [j, j + 1] / W. It is read with the image's
interpolation: Closest, or Linear (bilinear between pixel centres, wrapping in u and
clamped in v). A mirror-ball image (Cycles' direction_to_mirrorball) is read at the ball's
point that reflects the direction, clamped at its rim; its distribution is built over an
equirectangular grid evaluated from it (renderer.lights.environment_map).

Importance sampling (pbrt's 2-D piecewise-constant distribution; Cycles' background map).
The density over (u, v) is constant per pixel, proportional to f[i, j] = (the mean of the
interpolated luminance over the pixel) x sin(theta at the row's centre); a direction's
solid-angle pdf is p(u, v) / (2 pi^2 sin theta). Using the interpolated function's mean,
not the pixel's own value, keeps the pdf positive wherever Linear spreads a bright pixel,
so a tiny sun in the map cannot be reached only by BSDF sampling (fireflies).

Where the radiance comes from is one function, `lookup`: a later world program swaps it for
its own evaluation, and `build_environment` builds the distribution from whatever map it
is handed.

The kernels take the map's tables as one tuple, `env` (renderer.lights.environment_map);
None for a constant world, so that no kernel compiles any of this (numba prunes the
`env is None` branches).
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels import inline_kernel, kernel
from ..kernels.vecmath import add
from .environment_map import (
    CLOSEST,
    ENV_COL_CDF,
    ENV_FUNC,
    ENV_IMAGE,
    ENV_INFO,
    ENV_ROT,
    ENV_ROW_CDF,
    INFO_INTERP,
    INFO_NORM,
    INFO_PROJ,
    MIRROR_BALL,
)
from .sample import connect_light, escaped_radiance, pick_light
from .table import ENVIRONMENT, LT_KIND, LT_PMF

INV_2PI2 = 1.0 / (2.0 * math.pi * math.pi)


@inline_kernel
def direction_to_uv(env, d):
    """(u, v, sin theta) of world direction d (need not be unit) in the map's frame."""
    r = env[ENV_ROT]
    mx = r[0, 0] * d[0] + r[0, 1] * d[1] + r[0, 2] * d[2]
    my = r[1, 0] * d[0] + r[1, 1] * d[1] + r[1, 2] * d[2]
    mz = r[2, 0] * d[0] + r[2, 1] * d[1] + r[2, 2] * d[2]
    n = math.sqrt(mx * mx + my * my + mz * mz)
    z = min(1.0, max(-1.0, mz / n)) if n > 0.0 else 1.0
    u = 0.5 - math.atan2(my, mx) * (0.5 / math.pi)
    v = 1.0 - math.acos(z) / math.pi
    return u, v, math.sqrt(max(0.0, 1.0 - z * z))


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
    r = env[ENV_ROT]  # orthogonal: map -> world is its transpose
    d = (r[0, 0] * m[0] + r[1, 0] * m[1] + r[2, 0] * m[2],
         r[0, 1] * m[0] + r[1, 1] * m[1] + r[2, 1] * m[2],
         r[0, 2] * m[0] + r[1, 2] * m[1] + r[2, 2] * m[2])
    return d, sin_t


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


@kernel
def evaluate_grid(env, out):
    """out (rows, cols, 3): the map's radiance averaged over 2 x 2 points of every cell of an
    equirectangular grid (renderer.lights.environment_map builds a distribution from it)."""
    rows, cols = out.shape[0], out.shape[1]
    for i in range(rows):
        for j in range(cols):
            for a in range(2):
                for b in range(2):
                    le = lookup(env, (j + 0.25 + 0.5 * b) / cols, (i + 0.25 + 0.5 * a) / rows)
                    for c in range(3):
                        out[i, j, c] += 0.25 * le[c]


@inline_kernel
def _pdf_uv(env, u, v):
    """p(u, v) of the piecewise-constant distribution."""
    func = env[ENV_FUNC]
    h, w = func.shape[0], func.shape[1]
    j = min(max(int(u * w), 0), w - 1)
    i = min(max(int(v * h), 0), h - 1)
    return func[i, j] * env[ENV_INFO][INFO_NORM]


@inline_kernel
def environment_radiance(env, d):
    """(radiance along d, solid-angle pdf of sampling d, without the light's selection)."""
    u, v, sin_t = direction_to_uv(env, d)
    le = lookup(env, u, v)
    pdf = _pdf_uv(env, u, v) * INV_2PI2 / sin_t if sin_t > 0.0 else 0.0
    return le, pdf


@inline_kernel
def sample_environment(env, u1, u2):
    """(direction, radiance, solid-angle pdf): a direction drawn in proportion to f."""
    row_cdf = env[ENV_ROW_CDF]
    h = row_cdf.shape[0] - 1
    i = pick_light(row_cdf, u2)
    width = row_cdf[i + 1] - row_cdf[i]
    v = (i + ((u2 - row_cdf[i]) / width if width > 0.0 else 0.5)) / h
    col_cdf = env[ENV_COL_CDF][i]
    w = col_cdf.shape[0] - 1
    j = pick_light(col_cdf, u1)
    width = col_cdf[j + 1] - col_cdf[j]
    u = (j + ((u1 - col_cdf[j]) / width if width > 0.0 else 0.5)) / w
    d, sin_t = uv_to_direction(env, u, v)
    if not sin_t > 0.0:
        return d, (0.0, 0.0, 0.0), 0.0
    pdf = env[ENV_FUNC][i, j] * env[ENV_INFO][INFO_NORM] * INV_2PI2 / sin_t
    return d, lookup(env, u, v), pdf


@inline_kernel
def escaped_radiance_env(lt, env_light, sun_rows, env, d):
    """escaped_radiance with the environment read from its map when the world has one (env
    not None): radiance along d from infinity and its light-sampling pdf with selection."""
    if env is not None:
        if env_light >= 0:
            le, pdf = escaped_radiance(lt, np.int64(-1), sun_rows, d)  # the sun discs
            le_env, pdf_env = environment_radiance(env, d)
            return add(le, le_env), pdf + lt[LT_PMF][env_light] * pdf_env
    return escaped_radiance(lt, env_light, sun_rows, d)


@inline_kernel
def connect_light_env(lt, env, light, lp, x, u1, u2):
    """connect_light, with the environment row sampled from its map when the world has one
    (env not None); for a constant world (env None) exactly connect_light."""
    if env is not None:
        if lt[LT_KIND][light] == ENVIRONMENT:
            wi, le, pdf = sample_environment(env, u1, u2)
            return wi, 1e30, le, pdf, False
    return connect_light(lt, light, lp, x, u1, u2)
