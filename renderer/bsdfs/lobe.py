"""Dispatch on the lobe kind, and make the opaque lobes two-sided.

Reflection-only lobes (diffuse, conductors, plastic) are written for wo.z > 0. Like Cycles,
they reflect on both faces: seen from the back (wo.z < 0) we mirror the frame through the
surface (flip z of wo and wi), evaluate, and flip back; the pdf is a solid-angle density and
does not change. Dielectric and transparent lobes see both sides themselves.

lobe_is_delta(kind, roughness) is True when the lobe has no density at all (eval always
returns zero). Plastic with a smooth coat is a mixture: its sample reports `is_delta` per
sample, so lobe_is_delta is False for it.

lobe_eval_bumped and lobe_sample_bumped are the same lobes on a bumped surface, each on its
own normal with its own bump factor (renderer.bsdfs.closure_normals).
"""

from renderer.bsdfs import (
    CONDUCTOR,
    DIELECTRIC,
    DIFFUSE,
    PLASTIC,
    ROUGH_CONDUCTOR,
    SMOOTH_ROUGHNESS,
    TRANSPARENT,
)
from renderer.bsdfs.closure_normals import (
    diffuse_eval_bumped,
    diffuse_sample_bumped,
    specular_factor,
)
from renderer.bsdfs.conductor import conductor_sample
from renderer.bsdfs.dielectric import dielectric_sample
from renderer.bsdfs.diffuse import diffuse_eval, diffuse_sample
from renderer.bsdfs.plastic import (
    plastic_eval,
    plastic_eval_bumped,
    plastic_sample,
    plastic_sample_bumped,
)
from renderer.bsdfs.rough_conductor import rough_conductor_eval, rough_conductor_sample
from renderer.bsdfs.transparent import transparent_sample
from renderer.kernels import inline_kernel, kernel
from renderer.kernels.vecmath import neg, scale

_ZERO3 = (0.0, 0.0, 0.0)


@kernel
def lobe_is_delta(kind, roughness):
    if kind == DIELECTRIC or kind == CONDUCTOR or kind == TRANSPARENT:
        return True
    if kind == ROUGH_CONDUCTOR:
        return roughness < SMOOTH_ROUGHNESS
    return False


@inline_kernel
def lobe_eval(kind, color, roughness, ior, fresnel, tint, ms, wo, wi):
    """(f, pdf) of one lobe; zero for delta lobes. `fresnel` is the conductor lobes' Fresnel
    mode (renderer.bsdfs FRESNEL_*); `tint` their edge tint, plastic's specular tint and the
    dielectric's reflection tint; `ms` (bool) Multiscatter GGX for the GGX lobes."""
    if kind == DIELECTRIC or kind == TRANSPARENT or kind == CONDUCTOR:
        return _ZERO3, 0.0
    if wo[2] < 0.0:  # back face of an opaque lobe: mirror the frame
        wo = (wo[0], wo[1], -wo[2])
        wi = (wi[0], wi[1], -wi[2])
    if kind == DIFFUSE:
        return diffuse_eval(color, roughness, ior, wo, wi)
    if kind == ROUGH_CONDUCTOR:
        if roughness < SMOOTH_ROUGHNESS:
            return _ZERO3, 0.0
        return rough_conductor_eval(color, roughness, ior, fresnel, tint, ms, wo, wi)
    if kind == PLASTIC:
        return plastic_eval(color, roughness, ior, tint, ms, wo, wi)
    return _ZERO3, 0.0


@inline_kernel
def lobe_sample(kind, color, roughness, ior, fresnel, tint, ms, wo, u1, u2, u3):
    """(wi, weight = f |cos| / pdf, pdf, is_delta) of one lobe.

    For a delta sample `pdf` is the discrete probability of the chosen branch (1 for a
    mirror, F or 1 - F for glass) and `weight` already divides by it. A failed sample has
    weight (0, 0, 0) and pdf 0.
    """
    if kind == DIELECTRIC:
        return dielectric_sample(color, roughness, ior, tint, wo, u1, u2, u3)
    if kind == TRANSPARENT:
        return transparent_sample(color, roughness, ior, wo, u1, u2, u3)
    flip = wo[2] < 0.0
    if flip:
        wo = (wo[0], wo[1], -wo[2])
    if kind == DIFFUSE:
        wi, w, pdf, delta = diffuse_sample(color, roughness, ior, wo, u1, u2, u3)
    elif kind == CONDUCTOR or (kind == ROUGH_CONDUCTOR and roughness < SMOOTH_ROUGHNESS):
        wi, w, pdf, delta = conductor_sample(color, roughness, ior, fresnel, tint, wo, u1, u2, u3)
    elif kind == ROUGH_CONDUCTOR:
        wi, w, pdf, delta = rough_conductor_sample(color, roughness, ior, fresnel, tint, ms, wo, u1, u2,
                                                   u3)
    elif kind == PLASTIC:
        wi, w, pdf, delta = plastic_sample(color, roughness, ior, tint, ms, wo, u1, u2, u3)
    else:
        wi, w, pdf, delta = (0.0, 0.0, 1.0), _ZERO3, 0.0, False
    if flip:
        wi = (wi[0], wi[1], -wi[2])
    return wi, w, pdf, delta


@inline_kernel
def lobe_eval_bumped(kind, color, roughness, ior, fresnel, tint, ms, bump, wo, wi):
    """(f cos, pdf) of one lobe of a bumped surface: wo, wi in the specular normal's frame,
    bump = (the program's normal, the mesh's) in it (closure_normals). Unlike lobe_eval, f
    holds the lobe's own cosine, since the lobes' normals differ, and its bump factor."""
    n_map, n_mesh = bump
    if kind == DIFFUSE or kind == PLASTIC:
        if wo[2] < 0.0:  # back face: turn all directions around; the normals then face the viewer
            wo, wi = neg(wo), neg(wi)
        if kind == DIFFUSE:
            return diffuse_eval_bumped(color, n_map, n_mesh, wi)
        return plastic_eval_bumped(color, roughness, ior, tint, ms, wo, wi, n_map, n_mesh)
    f, pdf = lobe_eval(kind, color, roughness, ior, fresnel, tint, ms, wo, wi)
    return scale(f, abs(wi[2]) * specular_factor(n_mesh, wi)), pdf


@inline_kernel
def lobe_sample_bumped(kind, color, roughness, ior, fresnel, tint, ms, bump, wo, u1, u2, u3):
    """lobe_sample on a bumped surface, as lobe_eval_bumped."""
    n_map, n_mesh = bump
    if kind == DIFFUSE or kind == PLASTIC:
        flip = wo[2] < 0.0
        if flip:
            wo = neg(wo)
        if kind == DIFFUSE:
            wi, w, pdf, delta = diffuse_sample_bumped(color, n_map, n_mesh, u1, u2)
        else:
            wi, w, pdf, delta = plastic_sample_bumped(color, roughness, ior, tint, ms, wo, n_map, n_mesh, u1,
                                                      u2, u3)
        return (neg(wi) if flip else wi), w, pdf, delta
    wi, w, pdf, delta = lobe_sample(kind, color, roughness, ior, fresnel, tint, ms, wo, u1, u2, u3)
    if kind == TRANSPARENT:
        return wi, w, pdf, delta
    return wi, scale(w, specular_factor(n_mesh, wi)), pdf, delta
