"""Shading-normal nodes and the normal a program binds (Cycles' svm_node_normal_map in
svm/tex_coord.h and ensure_valid_specular_reflection in closure/bsdf_util.h, reimplemented).

Haze has no per-object transform at a hit: tangents arrive in world space (the exporter
turns them with the object), so the tangent frame is built in world space, where Cycles
builds it in object space and transforms the result; the two agree for rotations and
uniform scales. Object-space normal maps are not compiled (the exporter warns).
"""

import math

from renderer.kernels import inline_kernel
from renderer.kernels.vecmath import add, cross, dot, neg, scale, sub

SPACE_TANGENT, SPACE_OBJECT, SPACE_WORLD, SPACE_BLENDER_OBJECT, SPACE_BLENDER_WORLD = 0, 1, 2, 3, 4


@inline_kernel
def _safe_normalize(v):
    length = math.sqrt(dot(v, v))
    return scale(v, 1.0 / length) if length > 0.0 else (0.0, 0.0, 0.0)


@inline_kernel
def normal_map(color, strength, tangent, sign, space, n, back):
    """The Normal Map node's Normal: colour in [0, 1]^3, n the shading normal facing the
    side the ray came from (Cycles' sd->N), back whether the back face was hit."""
    c = (2.0 * (color[0] - 0.5), 2.0 * (color[1] - 0.5), 2.0 * (color[2] - 0.5))
    if space == SPACE_TANGENT:
        if dot(tangent, tangent) == 0.0:
            return n  # no tangents (no UV map): the unperturbed normal, as Cycles
        normal = neg(n) if back else n  # the mesh's own side, as Cycles' interpolated normal
        s = min(max(strength, 0.0), 1.0)
        c = (c[0] * strength, c[1] * strength, (1.0 - s) + s * c[2])
        b = scale(cross(normal, tangent), sign)
        out = _safe_normalize(add(add(scale(tangent, c[0]), scale(b, c[1])), scale(normal, c[2])))
        out = neg(out) if back else out
    else:
        if space == SPACE_BLENDER_WORLD or space == SPACE_BLENDER_OBJECT:
            c = (c[0], -c[1], -c[2])
        out = _safe_normalize(c)
        out = neg(out) if back else out
        if strength != 1.0:
            out = _safe_normalize(add(n, scale(sub(out, n), max(strength, 0.0))))
    finite = math.isfinite(out[0]) and math.isfinite(out[1]) and math.isfinite(out[2])
    if not finite or dot(out, out) == 0.0:
        return n
    return out


@inline_kernel
def valid_specular_normal(ng, wi, n):
    """Cycles' ensure_valid_specular_reflection: n raised toward the geometric normal ng
    (both on the side of wi, the direction toward the viewer) just enough that the mirror
    reflection of wi stays above the surface."""
    r = sub(scale(n, 2.0 * dot(n, wi)), wi)
    iz = dot(wi, ng)
    threshold = min(0.9 * iz, 0.01)
    if dot(ng, r) >= threshold:
        return n
    x = sub(n, scale(ng, dot(n, ng)))
    length = math.sqrt(dot(x, x))
    x = scale(x, 1.0 / length) if length > 0.0 else n
    ix = dot(wi, x)
    a = ix * ix + iz * iz
    b = 2.0 * (a + iz * threshold)
    c = (threshold + iz) * (threshold + iz)
    root = math.sqrt(max(b * b - 4.0 * a * c, 0.0))
    nz2 = 0.25 * (b + root) / a if ix < 0.0 else 0.25 * (b - root) / a
    nx = math.sqrt(max(1.0 - nz2, 0.0))
    nz = math.sqrt(max(nz2, 0.0))
    return add(scale(x, nx), scale(ng, nz))


@inline_kernel
def bump_visible(ns, n, w):
    """The first test of Cycles' bump_shadowing_term (closure/bsdf.h): False where direction w
    lies on the wrong side of the mesh's own smooth normal ns for a closure of normal n
    (light through the geometry). Unchanged when ns and n both turn around."""
    return dot(ns, w) * dot(ns, n) * dot(n, w) >= 0.0


@inline_kernel
def bump_shadowing(ns, n, w):
    """Cycles' bump_shadowing_term (closure/bsdf.h) for a diffuse closure of normal n (a
    program's) and a direction w leaving the surface, ns the mesh's own (smooth) normal: 0
    where bump_visible fails, else the GGX shadowing that softens the terminator of the tilted
    normal. Which closures get which part: renderer.bsdfs.closure_normals."""
    if not bump_visible(ns, n, w):
        return 0.0
    cos_i = abs(dot(ns, w))
    cos_d = abs(dot(ns, n))
    if cos_d >= 1.0 or cos_i >= 1.0:
        return 1.0
    if cos_i < 1e-6:
        return 0.0
    alpha2 = min(max(0.125 * (1.0 / (cos_d * cos_d) - 1.0), 0.0), 1.0)
    tan2_i = 1.0 / (cos_i * cos_i) - 1.0
    return 2.0 / (1.0 + math.sqrt(1.0 + alpha2 * tan2_i))
