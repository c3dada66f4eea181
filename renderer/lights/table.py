"""The light table: every light of a scene as one row, chosen in proportion to power.

Rows (structure of arrays, float32 unless noted), L lights:
  kind    (L,) int32    TRIANGLE, POINT, SPOT, SUN or ENVIRONMENT
  prim    (L,) int32    global triangle index for TRIANGLE, else -1
  pos     (L, 3)        POINT/SPOT position; TRIANGLE vertex 0
  vec_a   (L, 3)        TRIANGLE edge v1 - v0; SPOT/SUN unit axis (SUN: toward the sun)
  vec_b   (L, 3)        TRIANGLE edge v2 - v0
  color   (L, 3)        TRIANGLE front radiance; POINT/SPOT intensity (W/sr); SUN radiance
                        (or irradiance for a delta sun); ENVIRONMENT radiance (its
                        mean over the sphere with a map, renderer.lights.environment)
  color_b (L, 3)        TRIANGLE back radiance
  param   (L, 4)        TRIANGLE: area; SPOT: cos(half angle), blend width in cos;
                        SUN: cos(half angle) (1 = delta), solid angle
  pmf     (L,) float64  probability of choosing the light
  cdf     (L + 1,) float64

tri_light (T,) int32 maps a triangle to its row (-1 when it does not emit), so a BSDF-sampled
ray that hits an emitter finds the light-sampling pdf for MIS.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from renderer.scene import LUMINANCE

from .environment_map import mean_radiance

TRIANGLE, POINT, SPOT, SUN, ENVIRONMENT = 0, 1, 2, 3, 4


class LightTable(NamedTuple):
    """The kernels take the table as it is, one record argument `lt`, and read its fields
    by name (lt.cdf, lt.kind[light])."""

    kind: np.ndarray
    prim: np.ndarray
    pos: np.ndarray
    vec_a: np.ndarray
    vec_b: np.ndarray
    color: np.ndarray
    color_b: np.ndarray
    param: np.ndarray
    pmf: np.ndarray
    cdf: np.ndarray
    tri_light: np.ndarray
    env_light: int  # row of the environment, -1 if black
    sun_rows: np.ndarray  # (S,) int32 rows of suns with a disc (angle > 0), hit by escaping rays


def _luminance(c) -> float:
    return LUMINANCE[0] * c[0] + LUMINANCE[1] * c[1] + LUMINANCE[2] * c[2]


def build_light_table(tris, materials_emission, materials_sides, scene_lights, environment, scene_radius):
    """Collect emitting triangles, analytic lights and the environment into a LightTable.

    tris: (v0, v1, v2, material) arrays of the merged mesh; materials_emission (M, 3);
    materials_sides (M,) int32 bitmask (1 front, 2 back); scene_radius bounds the scene and
    gives the environment and suns a power comparable with local lights.
    """
    v0, v1, v2, tri_mat = tris
    tri_light = np.full(v0.shape[0], -1, np.int32)

    emission = np.asarray(materials_emission, np.float64).reshape(-1, 3)
    sides = np.asarray(materials_sides, np.int32)
    if emission.shape[0] and v0.shape[0]:
        mat_lum = emission @ np.array(LUMINANCE)
        emits = mat_lum[tri_mat] > 0
        e1 = v1 - v0
        e2 = v2 - v0
        area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
        emits &= area > 0
        idx = np.nonzero(emits)[0]
        nsides = np.array([0, 1, 1, 2])[sides[tri_mat[idx]] & 3]
        power = area[idx] * mat_lum[tri_mat[idx]] * math.pi * nsides
        tri_light[idx] = np.arange(idx.size, dtype=np.int32)
        tri_rows = dict(idx=idx, e1=e1[idx], e2=e2[idx], v0=v0[idx], area=area[idx], power=power,
                        mat=tri_mat[idx])
    else:
        tri_rows = None

    n_tri = 0 if tri_rows is None else tri_rows["idx"].size
    extra: list[tuple] = []  # (kind, pos, vec_a, color, param, power)
    for light in scene_lights:
        if light.type == "point":
            i = np.array(light.intensity, np.float64)
            extra.append((POINT, light.position, (0, 0, 1), i, (0, 0, 0, 0), 4 * math.pi * _luminance(i)))
        elif light.type == "spot":
            i = np.array(light.intensity, np.float64)
            axis = np.array(light.direction, np.float64)
            axis /= np.linalg.norm(axis)
            half = math.radians(light.spot_size) * 0.5
            cos_outer = math.cos(half)
            # Blender's blend: smoothstep over the outer `blend` share of the cone (in cos space).
            blend_width = (1.0 - cos_outer) * light.blend
            power = 2 * math.pi * (1 - cos_outer) * _luminance(i)
            extra.append((SPOT, light.position, axis, i, (cos_outer, blend_width, 0, 0), power))
        elif light.type == "sun":
            e = np.array(light.irradiance, np.float64)
            axis = np.array(light.direction, np.float64)
            axis /= np.linalg.norm(axis)
            half = math.radians(light.angle) * 0.5
            if half > 0:
                cos_half = math.cos(half)
                solid = 2 * math.pi * (1 - cos_half)
                # A uniform disc of solid angle `solid` whose irradiance at normal incidence is E
                # (cos ~ 1 across a small disc): L = E / solid, as Cycles normalises its sun.
                color = e / solid
            else:
                cos_half, solid, color = 1.0, 0.0, e
            power = _luminance(e) * math.pi * scene_radius**2
            extra.append((SUN, (0, 0, 0), axis, color, (cos_half, solid, 0, 0), power))
    env = mean_radiance(environment)  # the colour of a constant world
    if _luminance(env) > 0:
        power = _luminance(env) * math.pi * 4 * math.pi * scene_radius**2
        extra.append((ENVIRONMENT, (0, 0, 0), (0, 0, 1), env, (0, 0, 0, 0), power))

    n = n_tri + len(extra)
    kind = np.zeros(n, np.int32)
    prim = np.full(n, -1, np.int32)
    pos = np.zeros((n, 3), np.float32)
    vec_a = np.zeros((n, 3), np.float32)
    vec_b = np.zeros((n, 3), np.float32)
    color = np.zeros((n, 3), np.float32)
    color_b = np.zeros((n, 3), np.float32)
    param = np.zeros((n, 4), np.float32)
    power = np.zeros(n, np.float64)
    if n_tri:
        kind[:n_tri] = TRIANGLE
        prim[:n_tri] = tri_rows["idx"]
        pos[:n_tri] = tri_rows["v0"]
        vec_a[:n_tri] = tri_rows["e1"]
        vec_b[:n_tri] = tri_rows["e2"]
        m = tri_rows["mat"]
        front = (sides[m] & 1) != 0
        back = (sides[m] & 2) != 0
        color[:n_tri] = emission[m] * front[:, None]
        color_b[:n_tri] = emission[m] * back[:, None]
        param[:n_tri, 0] = tri_rows["area"]
        power[:n_tri] = tri_rows["power"]
    env_light = -1
    sun_rows = []
    for j, (k, p, a, c, prm, pw) in enumerate(extra):
        r = n_tri + j
        kind[r] = k
        pos[r] = p
        vec_a[r] = a
        color[r] = c
        param[r] = prm
        power[r] = pw
        if k == ENVIRONMENT:
            env_light = r
        if k == SUN and prm[0] < 1.0:
            sun_rows.append(r)
    total = power.sum()
    pmf = power / total if total > 0 else np.zeros(n)
    cdf = np.zeros(n + 1)
    cdf[1:] = np.cumsum(pmf)
    if n:
        cdf[-1] = 1.0
    return LightTable(kind, prim, pos, vec_a, vec_b, color, color_b, param, pmf, cdf, tri_light,
                      env_light, np.array(sun_rows, np.int32))
