"""An environment light from an equirectangular or mirror-ball radiance map (a world lit by an HDRI, as
Cycles' Environment Texture on the Background), evaluated per escaped ray and sampled by
importance.

Reading the map (directions to (u, v), `lookup`) is renderer.lights.environment_lookup.

Importance sampling (pbrt's 2-D piecewise-constant distribution; Cycles' background map).
The density over (u, v) is constant per cell, proportional to f[i, j] = (the mean of the
interpolated luminance over the cell: a pixel, or k x k cells per pixel of a small image,
renderer.lights.environment_map) x sin(theta at the row's centre); a direction's
solid-angle pdf is p(u, v) / (2 pi^2 sin theta). A mirror-ball image is sampled on its own
cells over the ball's disk, an equal-area map of the sphere (renderer.lights.environment_ball:
the mapping's Jacobian, and the rim). Using the interpolated function's mean,
not the pixel's own value, keeps the pdf positive wherever Linear spreads a bright pixel,
so a tiny sun in the map cannot be reached only by BSDF sampling (fireflies).

The kernels take the map's tables as one tuple, `env` (renderer.lights.environment_map);
None for a constant world, so that no kernel compiles any of this (numba prunes the
`env is None` branches).
"""

from __future__ import annotations

import math

import numpy as np

from ..kernels import inline_kernel
from ..kernels.vecmath import add
from .environment_ball import ball_direction, ball_pdf, rim_point
from .environment_lookup import (
    ENV_COL_CDF,
    ENV_FUNC,
    ENV_INFO,
    ENV_ROW_CDF,
    INFO_NORM,
    INFO_PROJ,
    INFO_RIM_PROB,
    MIRROR_BALL,
    direction_to_uv,
    lookup,
    mirror_ball_uv,
    to_map,
    uv_to_direction,
)
from .sample import connect_light, escaped_radiance, pick_light
from .table import ENVIRONMENT

INV_2PI2 = 1.0 / (2.0 * math.pi * math.pi)


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
    if env[ENV_INFO][INFO_PROJ] == MIRROR_BALL:
        m = to_map(env, d)
        n = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
        bu, bv = mirror_ball_uv((m[0] / n, m[1] / n, m[2] / n))
        return le, ball_pdf(env, 2.0 * bu - 1.0, 2.0 * bv - 1.0)
    pdf = _pdf_uv(env, u, v) * INV_2PI2 / sin_t if sin_t > 0.0 else 0.0
    return le, pdf


@inline_kernel
def _pick_cell(env, u1, u2):
    """(i, j, x, y): a cell of the distribution drawn in proportion to f, and a point in
    [0, 1]^2 uniform within it."""
    row_cdf = env[ENV_ROW_CDF]
    h = row_cdf.shape[0] - 1
    i = pick_light(row_cdf, u2)
    width = row_cdf[i + 1] - row_cdf[i]
    y = (i + ((u2 - row_cdf[i]) / width if width > 0.0 else 0.5)) / h
    col_cdf = env[ENV_COL_CDF][i]
    w = col_cdf.shape[0] - 1
    j = pick_light(col_cdf, u1)
    width = col_cdf[j + 1] - col_cdf[j]
    x = (j + ((u1 - col_cdf[j]) / width if width > 0.0 else 0.5)) / w
    return i, j, x, y


@inline_kernel
def sample_environment(env, u1, u2):
    """(direction, radiance, solid-angle pdf): a direction drawn in proportion to f (for a
    mirror ball, the mixture of renderer.lights.environment_ball)."""
    info = env[ENV_INFO]
    if info[INFO_PROJ] == MIRROR_BALL:
        rim = info[INFO_RIM_PROB]
        if u2 < rim:
            a, b = rim_point(env, u1, u2 / rim)
        else:
            _, _, x, y = _pick_cell(env, u1, (u2 - rim) / (1.0 - rim))
            a, b = 2.0 * x - 1.0, 2.0 * y - 1.0
        d = ball_direction(env, a, b)
        u, v, _ = direction_to_uv(env, d)
        return d, lookup(env, u, v), ball_pdf(env, a, b)
    i, j, u, v = _pick_cell(env, u1, u2)
    d, sin_t = uv_to_direction(env, u, v)
    if not sin_t > 0.0:
        return d, (0.0, 0.0, 0.0), 0.0
    pdf = env[ENV_FUNC][i, j] * info[INFO_NORM] * INV_2PI2 / sin_t
    return d, lookup(env, u, v), pdf


@inline_kernel
def escaped_radiance_env(lt, env_light, sun_rows, env, d):
    """escaped_radiance with the environment read from its map when the world has one (env
    not None): radiance along d from infinity and its light-sampling pdf with selection."""
    if env is not None:
        if env_light >= 0:
            le, pdf = escaped_radiance(lt, np.int64(-1), sun_rows, d)  # the sun discs
            le_env, pdf_env = environment_radiance(env, d)
            return add(le, le_env), pdf + lt.pmf[env_light] * pdf_env
    return escaped_radiance(lt, env_light, sun_rows, d)


@inline_kernel
def connect_light_env(lt, env, light, lp, x, u1, u2):
    """connect_light, with the environment row sampled from its map when the world has one
    (env not None); for a constant world (env None) exactly connect_light."""
    if env is not None:
        if lt.kind[light] == ENVIRONMENT:
            wi, le, pdf = sample_environment(env, u1, u2)
            return wi, 1e30, le, pdf, False
    return connect_light(lt, light, lp, x, u1, u2)
