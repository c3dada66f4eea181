"""Smooth dielectric (glass): Fresnel-weighted choice of mirror reflection or refraction.

`ior` is n_inside / n_outside, inside being behind the front face (wo.z > 0 is outside).
Seen from the back (wo.z < 0) the relative index inverts.

`color` tints the refraction and `tint` the reflection: Cycles' Glass BSDF tints both by its
Color (the exporter gives both), the Principled BSDF's transmission only its refraction, by
sqrt(Base Color) (svm/closure.h: reflection_tint 1, transmission_tint sqrt(base)). The
choice between them is made with probability F, so each branch's weight is its tint.
Cycles does NOT scale refracted radiance by 1/eta^2 (its sampled eval is the transmittance
tint over pdf 1 - F, with no eta factor); we follow Cycles, so a white dielectric is a
perfect white furnace (R + T = 1) and renders match Cycles. The price is the usual one: the
BSDF is not symmetric under swapping wo and wi across the interface, which a unidirectional
path tracer never needs.
"""

from renderer.bsdfs.fresnel import fresnel_dielectric
from renderer.kernels import kernel

_ZERO3 = (0.0, 0.0, 0.0)


@kernel
def dielectric_eval(color, roughness, ior, wo, wi):
    """Both branches are delta: no density to evaluate."""
    return _ZERO3, 0.0


@kernel
def dielectric_reflectance(ior, cos_o):
    """Fresnel reflectance seen from the side of `wo` (cos_o = wo.z, signed)."""
    eta = ior if cos_o >= 0.0 else 1.0 / ior
    return fresnel_dielectric(abs(cos_o), eta)[0]


@kernel
def dielectric_sample(color, roughness, ior, tint, wo, u1, u2, u3):
    """Reflect with probability F, else refract. pdf = discrete probability of the branch.

    Only u1 is used (the branch choice); both branches are deterministic given wo.
    """
    outside = wo[2] >= 0.0
    eta = ior if outside else 1.0 / ior  # n_t / n_i for light crossing toward -wo's side
    cos_i = abs(wo[2])
    F, cos_t = fresnel_dielectric(cos_i, eta)
    if u1 < F:
        return (-wo[0], -wo[1], wo[2]), (tint[0], tint[1], tint[2]), F, True
    # Snell: the tangential part shrinks by 1/eta, the normal part flips to the far side.
    side = 1.0 if outside else -1.0
    wi = (-wo[0] / eta, -wo[1] / eta, -side * cos_t)
    return wi, (color[0], color[1], color[2]), 1.0 - F, True
