"""Sampling a triangle light by the solid angle it subtends (Arvo 1995).

Area sampling picks a point on the triangle uniformly, so a shading point near the light
gets the weight A cos / r^2, which swings by orders of magnitude across the triangle: the
walls and the fog next to a Cornell box's ceiling light were 20-100 times noisier than
Cycles' (which samples lights by solid angle). Sampling the spherical triangle uniformly
makes the pdf the constant 1 / Omega, so the only variation left is the emitted radiance.

Let a, b, c be the unit vectors from x to the vertices. The solid angle is (Van Oosterom &
Strackee) Omega = 2 atan2(|a . (b x c)|, 1 + a.b + b.c + c.a). Arvo's method picks the
sub-triangle of area u1 Omega that shares the edge ab, which fixes a new third vertex c' on
the arc ac, and then a point on the arc b c' with the cosine toward b uniform in u2: the
direction is uniform in solid angle.

Tiny or degenerate spherical triangles (far lights, grazing views) lose precision in the
angle formulas, and there area sampling is as good anyway, so both the sampler and the pdf
fall back to it below MIN_SOLID_ANGLE, a rule that depends only on (x, triangle), so light
sampling and the MIS weights of emitters hit by BSDF sampling always agree.
"""

import math

from ..kernels import fastmath as fm
from ..kernels import inline_kernel
from ..kernels.vecmath import cross, dot, length, madd, scale, sub

MIN_SOLID_ANGLE = 1e-4  # steradians


@inline_kernel
def unit_or_zero(v):
    """v / |v|, or the zero vector for v = 0."""
    n = length(v)
    return scale(v, 1.0 / n) if n > 0.0 else (0.0, 0.0, 0.0)


@inline_kernel
def spherical_triangle(x, p0, p1, p2):
    """(omega, a, b, c): the solid angle (sr) subtended at x by the triangle p0 p1 p2 (0 when
    x is in its plane, outside it) and the unit vectors from x to its vertices."""
    a = unit_or_zero(sub(p0, x))
    b = unit_or_zero(sub(p1, x))
    c = unit_or_zero(sub(p2, x))
    triple = abs(dot(a, cross(b, c)))
    return 2.0 * fm.atan2(triple, 1.0 + dot(a, b) + dot(b, c) + dot(c, a)), a, b, c


@inline_kernel
def solid_angle(x, p0, p1, p2):
    return spherical_triangle(x, p0, p1, p2)[0]


@inline_kernel
def use_solid_angle(omega):
    return omega >= MIN_SOLID_ANGLE and math.isfinite(omega)


@inline_kernel
def _orthogonal_unit(v, axis):
    """The unit component of v orthogonal to the unit vector axis."""
    return unit_or_zero(madd(v, axis, -dot(v, axis)))


@inline_kernel
def sample_direction(x, p0, p1, p2, omega, u1, u2):
    """A unit direction from x toward the triangle, uniform in solid angle (pdf 1 / omega,
    omega = solid_angle(x, p0, p1, p2))."""
    _, a, b, c = spherical_triangle(x, p0, p1, p2)
    return sample_spherical_triangle(a, b, c, omega, u1, u2)


@inline_kernel
def sample_spherical_triangle(a, b, c, omega, u1, u2):
    """sample_direction given the unit vertex directions a, b, c and the solid angle."""
    # Interior angle alpha at vertex a, between the great circles ab and ac.
    n_ab = unit_or_zero(cross(a, b))
    n_ac = unit_or_zero(cross(a, c))
    cos_alpha = min(max(dot(n_ab, n_ac), -1.0), 1.0)
    sin_alpha = math.sqrt(max(0.0, 1.0 - cos_alpha * cos_alpha))
    # Sub-triangle a b c' of area u1 omega: sin and cos of (area - alpha), expanded.
    area = u1 * omega
    # area <= 4 pi, so the series needs no range check: without its libm branch this
    # function also runs inside the SIMD loops of renderer.integrator.nee_batch.
    sin_area, cos_area = fm.sincos_reduced(area)
    s = sin_area * cos_alpha - cos_area * sin_alpha
    t = cos_area * cos_alpha + sin_area * sin_alpha
    u = t - cos_alpha
    v = s + sin_alpha * dot(a, b)
    denom = (v * s + u * t) * sin_alpha
    q = ((v * t - u * s) * cos_alpha - v) / denom if denom != 0.0 else 1.0
    q = min(max(q, -1.0), 1.0)
    c_new = madd(scale(a, q), _orthogonal_unit(c, a), math.sqrt(max(0.0, 1.0 - q * q)))
    # A point on the arc b c' with its cosine toward b uniform.
    z = 1.0 - u2 * (1.0 - dot(c_new, b))
    z = min(max(z, -1.0), 1.0)
    return unit_or_zero(madd(scale(b, z), _orthogonal_unit(c_new, b), math.sqrt(max(0.0, 1.0 - z * z))))
