"""Light sampling kernels over the LightTable (see renderer.lights.table).

`lt` is the LightTable record itself, its arrays read by field name (numba passes a
NamedTuple of arrays as cheaply as one argument each). Light sampling is split in two so
that a medium can place its next-event vertex toward the chosen point (equiangular
sampling) before the connection is made:
  pick_light     -> a row, by power
  light_point    -> a point on that light (area lights, point and spot lights)
  connect_light  -> direction, distance, radiance and solid-angle pdf from a shading point;
                    triangles are sampled by the solid angle they subtend there (see
                    spherical_triangle.py), the light point serving only the medium's
                    equiangular vertex (and the area fallback for tiny solid angles)

The triangle's point and connection also serve the SIMD batch of homogeneous medium
segments (renderer.integrator.nee_batch), which needs them without branches:
triangle_point is, and connect_triangle_simd is connect_light's triangle case with both
techniques computed and one kept by a select.
"""

import math

from ..kernels import fastmath as fm
from ..kernels import inline_kernel
from ..kernels import simdmath as sm
from ..kernels.vecmath import INV_4PI, add, cross, dot, length, normalize, onb, scale, sub, to_world
from .spherical_triangle import (
    MIN_SOLID_ANGLE,
    sample_spherical_triangle,
    spherical_triangle,
    unit_or_zero,
    use_solid_angle,
)
from .table import (
    POINT,
    SPOT,
    SUN,
    TRIANGLE,
)

SOLID_ANGLE_GATE = 0.05  # sr; see looks_near


@inline_kernel
def light_pmf(lt, light):
    """Probability that pick_light chooses `light`."""
    return lt.pmf[light]


@inline_kernel
def triangle_emission(lt, light, front):
    """Radiance triangle light `light` emits from its front or its back side."""
    c = lt.color if front else lt.color_b
    return (float(c[light, 0]), float(c[light, 1]), float(c[light, 2]))


@inline_kernel
def pick_light(cdf, u):
    """Row whose cdf interval holds u (binary search); -1 when there are no lights."""
    n = cdf.shape[0] - 1
    if n <= 0:
        return -1
    lo, hi = 0, n
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if cdf[mid] <= u:
            lo = mid
        else:
            hi = mid
    return lo


@inline_kernel
def light_has_point(lt, light):
    k = lt.kind[light]
    return k == TRIANGLE or k == POINT or k == SPOT


@inline_kernel
def light_point(lt, light, u1, u2):
    """A point on the light, uniform by area for triangles; the position of point and spot
    lights; the origin for sun and environment (which have no point)."""
    kind, pos, vec_a, vec_b = lt.kind, lt.pos, lt.vec_a, lt.vec_b
    p = (float(pos[light, 0]), float(pos[light, 1]), float(pos[light, 2]))
    if kind[light] != TRIANGLE:
        return p
    return triangle_point(p, (vec_a[light, 0], vec_a[light, 1], vec_a[light, 2]),
                          (vec_b[light, 0], vec_b[light, 1], vec_b[light, 2]), u1, u2)


@inline_kernel
def triangle_point(p0, edge_a, edge_b, u1, u2):
    """A point uniform by area on the triangle p0, p0 + edge_a, p0 + edge_b. Branch-free:
    the SIMD batch (renderer.integrator.nee_batch) calls it too."""
    su = math.sqrt(u1)
    b1 = 1.0 - su
    b2 = u2 * su
    return (p0[0] + b1 * edge_a[0] + b2 * edge_b[0],
            p0[1] + b1 * edge_a[1] + b2 * edge_b[1],
            p0[2] + b1 * edge_a[2] + b2 * edge_b[2])


@inline_kernel
def _smoothstep(x):
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return x * x * (3.0 - 2.0 * x)


@inline_kernel
def spot_attenuation(axis, cos_outer, blend_width, wi_from_light):
    c = dot(axis, wi_from_light)
    if c <= cos_outer:
        return 0.0
    if blend_width <= 0.0:
        return 1.0
    return _smoothstep((c - cos_outer) / blend_width)


@inline_kernel
def _triangle(lt, light):
    pos, vec_a, vec_b = lt.pos, lt.vec_a, lt.vec_b
    p0 = (float(pos[light, 0]), float(pos[light, 1]), float(pos[light, 2]))
    e1 = (float(vec_a[light, 0]), float(vec_a[light, 1]), float(vec_a[light, 2]))
    e2 = (float(vec_b[light, 0]), float(vec_b[light, 1]), float(vec_b[light, 2]))
    return p0, add(p0, e1), add(p0, e2)


@inline_kernel
def looks_near(x, p0, p1, p2):
    """Whether the triangle light p0 p1 p2 looks big from x: its solid angle estimated from the
    centroid, A |cos| / r^2, at least SOLID_ANGLE_GATE. Far triangles keep area sampling,
    which is as good there and cheaper (the exact solid angle and Arvo's sampler cost about
    a fifth of a surface scene's time per sample). A rule of (x, triangle) only, so light
    sampling and the MIS weight of an emitter hit by BSDF sampling always agree."""
    d = sub(scale(add(add(p0, p1), p2), 1.0 / 3.0), x)
    r2 = dot(d, d)
    n2 = cross(sub(p1, p0), sub(p2, p0))  # |n2| = 2 area
    # A |cos| / r^2 = (|n2| / 2) |n2 . d| / (|n2| r) / r^2 = |n2 . d| / (2 r^3)
    return abs(dot(n2, d)) >= 2.0 * SOLID_ANGLE_GATE * r2 * math.sqrt(r2)


@inline_kernel
def _connect_direction(lt, light, x, p0, p1, p2, wi, omega, c):
    """connect_light for a triangle sampled uniformly in solid angle (pdf 1 / omega)."""
    n = normalize(cross(sub(p1, p0), sub(p2, p0)))
    cos_l = -dot(wi, n)
    dist = dot(sub(x, p0), n) / cos_l if cos_l != 0.0 else 0.0
    if not (dist > 0.0 and math.isfinite(dist)):
        return wi, 0.0, (0.0, 0.0, 0.0), 0.0, False
    if cos_l < 0.0:
        color_b = lt.color_b
        c = (float(color_b[light, 0]), float(color_b[light, 1]), float(color_b[light, 2]))
    return wi, dist, c, 1.0 / omega, False


@inline_kernel
def connect_light(lt, light, lp, x, u1, u2):
    """Connect shading point x to light `light` (at point lp for lights that have one).

    Returns (wi unit toward the light, dist (inf-like 1e30 for distant lights), Le (3-tuple:
    radiance, or intensity / dist^2 for delta lights), pdf (solid angle, without the light's
    selection probability; 1 for delta lights), is_delta).
    """
    kind, vec_a, vec_b, param = lt.kind, lt.vec_a, lt.vec_b, lt.param
    color, color_b = lt.color, lt.color_b
    k = kind[light]
    c = (float(color[light, 0]), float(color[light, 1]), float(color[light, 2]))
    if k == TRIANGLE:
        p0, p1, p2 = _triangle(lt, light)
        if looks_near(x, p0, p1, p2):
            omega, a, b, cv = spherical_triangle(x, p0, p1, p2)
            if use_solid_angle(omega):
                wi = sample_spherical_triangle(a, b, cv, omega, u1, u2)
                return _connect_direction(lt, light, x, p0, p1, p2, wi, omega, c)
    if k == TRIANGLE or k == POINT or k == SPOT:
        to = sub(lp, x)
        dist = length(to)
        if dist <= 0.0:
            return (0.0, 0.0, 1.0), 0.0, (0.0, 0.0, 0.0), 0.0, False
        wi = scale(to, 1.0 / dist)
        if k == TRIANGLE:
            e1 = (float(vec_a[light, 0]), float(vec_a[light, 1]), float(vec_a[light, 2]))
            e2 = (float(vec_b[light, 0]), float(vec_b[light, 1]), float(vec_b[light, 2]))
            n = normalize(cross(e1, e2))
            cos_l = -dot(wi, n)
            area = float(param[light, 0])
            if abs(cos_l) < 1e-8 or area <= 0.0:
                return wi, dist, (0.0, 0.0, 0.0), 0.0, False
            if cos_l < 0.0:
                c = (float(color_b[light, 0]), float(color_b[light, 1]), float(color_b[light, 2]))
            return wi, dist, c, dist * dist / (area * abs(cos_l)), False
        inv_d2 = 1.0 / (dist * dist)
        if k == SPOT:
            axis = (float(vec_a[light, 0]), float(vec_a[light, 1]), float(vec_a[light, 2]))
            inv_d2 *= spot_attenuation(axis, float(param[light, 0]), float(param[light, 1]),
                                       (-wi[0], -wi[1], -wi[2]))
        return wi, dist, scale(c, inv_d2), 1.0, True
    if k == SUN:
        axis = (float(vec_a[light, 0]), float(vec_a[light, 1]), float(vec_a[light, 2]))
        cos_half = float(param[light, 0])
        if cos_half >= 1.0:
            return axis, 1e30, c, 1.0, True
        # uniform direction in the sun's cone
        cos_t = 1.0 - u1 * (1.0 - cos_half)
        sin_t = math.sqrt(max(0.0, 1.0 - cos_t * cos_t))
        phi = 2.0 * math.pi * u2
        s, t = onb(axis)
        sin_phi, cos_phi = fm.sincos(phi)
        wi = to_world((sin_t * cos_phi, sin_t * sin_phi, cos_t), s, t, axis)
        return wi, 1e30, c, 1.0 / float(param[light, 1]), False
    # ENVIRONMENT: uniform sphere (a constant environment has nothing better)
    z = 1.0 - 2.0 * u1
    r = math.sqrt(max(0.0, 1.0 - z * z))
    phi = 2.0 * math.pi * u2
    sin_phi, cos_phi = fm.sincos(phi)
    return (r * cos_phi, r * sin_phi, z), 1e30, c, INV_4PI, False


@inline_kernel
def connect_triangle_simd(p0, p1, p2, lp, area, x, u1, u2):
    """(wi, dist, back_side, pdf) of connect_light for the triangle light p0 p1 p2 of the
    given area (lp: its area-sampled point), without branches, so that a loop calling it
    vectorises (the SIMD batch, renderer.integrator.nee_batch); pdf 0 when there is no
    connection. Both techniques are computed and looks_near's rule keeps one."""
    near = looks_near(x, p0, p1, p2)
    # Solid angle and Arvo's direction.
    a = unit_or_zero(sub(p0, x))
    b = unit_or_zero(sub(p1, x))
    c = unit_or_zero(sub(p2, x))
    omega = 2.0 * sm.atan2(abs(dot(a, cross(b, c))), 1.0 + dot(a, b) + dot(b, c) + dot(c, a))
    solid = near and omega >= MIN_SOLID_ANGLE and omega < math.inf
    w_sa = sample_spherical_triangle(a, b, c, omega, u1, u2)
    n = unit_or_zero(cross(sub(p1, p0), sub(p2, p0)))
    cos_sa = -dot(w_sa, n)
    dist_sa = ((x[0] - p0[0]) * n[0] + (x[1] - p0[1]) * n[1] + (x[2] - p0[2]) * n[2]) / (
        cos_sa if cos_sa != 0.0 else 1.0)
    ok_sa = cos_sa != 0.0 and dist_sa > 0.0 and dist_sa < math.inf
    # Area sampling toward the light point.
    tx, ty, tz = lp[0] - x[0], lp[1] - x[1], lp[2] - x[2]
    dist_a = math.sqrt(tx * tx + ty * ty + tz * tz)
    inv = 1.0 / dist_a if dist_a > 0.0 else 0.0
    w_a = (tx * inv, ty * inv, tz * inv)
    cos_a = -dot(w_a, n)
    ok_a = dist_a > 0.0 and abs(cos_a) >= 1e-8 and area > 0.0
    pdf_a = dist_a * dist_a / (area * abs(cos_a)) if ok_a else 0.0
    wi = w_sa if solid else w_a
    dist = dist_sa if solid else dist_a
    cos_l = cos_sa if solid else cos_a
    pdf = (1.0 / omega if ok_sa else 0.0) if solid else pdf_a
    return wi, dist, cos_l < 0.0, pdf


@inline_kernel
def escaped_radiance(lt, env_light, sun_rows, d):
    """Radiance arriving along direction d from infinity (environment and sun discs), and
    the light-sampling pdf of that direction including selection probabilities (for MIS)."""
    pmf, color, vec_a, param = lt.pmf, lt.color, lt.vec_a, lt.param
    r, g, b, pdf = 0.0, 0.0, 0.0, 0.0
    if env_light >= 0:
        r += color[env_light, 0]
        g += color[env_light, 1]
        b += color[env_light, 2]
        pdf += pmf[env_light] * INV_4PI
    for j in range(sun_rows.shape[0]):
        s = sun_rows[j]
        axis = (float(vec_a[s, 0]), float(vec_a[s, 1]), float(vec_a[s, 2]))
        if dot(axis, d) >= param[s, 0]:
            r += color[s, 0]
            g += color[s, 1]
            b += color[s, 2]
            pdf += pmf[s] / param[s, 1]
    return (r, g, b), pdf


@inline_kernel
def triangle_light_pdf(lt, light, x, p, cos_l):
    """Solid-angle pdf, with selection, of light-sampling point p on triangle light `light`
    from x, where cos_l is the cosine at the light."""
    p0, p1, p2 = _triangle(lt, light)
    if looks_near(x, p0, p1, p2):
        omega = spherical_triangle(x, p0, p1, p2)[0]
        if use_solid_angle(omega):
            return lt.pmf[light] / omega
    area = lt.param[light, 0]
    if area <= 0.0 or abs(cos_l) < 1e-8:
        return 0.0
    to = sub(p, x)
    return lt.pmf[light] * dot(to, to) / (area * abs(cos_l))


