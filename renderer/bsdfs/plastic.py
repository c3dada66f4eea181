"""Plastic: a GGX dielectric coat (ior, roughness) over a Lambertian base of albedo `color`.

    f = f_coat(wo, wi) + color / pi * (1 - E(wo)) (1 - E(wi)) / (1 - E_avg)

f_coat = F(wo.h) D G2 / (4 wo.z wi.z) is the coat's own (uncoloured) reflection with the
exact dielectric Fresnel; E is its directional albedo and E_avg its cosine-weighted mean
(renderer.bsdfs.coat_albedo). The base only receives what the coat does not reflect, so
the albedo is E(wo) + color (1 - E(wo)) <= 1 whatever the colour, and f stays reciprocal.
This is an energy-coupling model, not a simulation of light bouncing inside the layer.

Below SMOOTH_ROUGHNESS the coat is a smooth interface: its reflection is a delta lobe
(E = Fresnel), sampled with `is_delta` True and absent from eval; the base stays diffuse.
The coat index is max(ior, 1/ior) clamped to [1, 4] (the table's range).
"""

import math

from numba import njit

from renderer.bsdfs import SMOOTH_ROUGHNESS
from renderer.bsdfs.coat_albedo import coat_albedo, coat_albedo_avg, coat_eta
from renderer.bsdfs.fresnel import fresnel_dielectric
from renderer.bsdfs.microfacet import (
    ggx_D,
    ggx_G2,
    ggx_reflection_pdf,
    ggx_sample_visible_normal,
    reflect,
)
from renderer.bsdfs.warp import square_to_cosine_hemisphere
from renderer.kernels.vecmath import INV_PI, normalize

_ZERO3 = (0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy", _nrt=False)
def _coat_probability(color, e_o):
    """Chance of sampling the coat: its share of the albedo E(wo) + avg(color) (1 - E(wo))."""
    base = (color[0] + color[1] + color[2]) / 3.0 * (1.0 - e_o)
    total = e_o + max(base, 0.0)
    return e_o / total if total > 0.0 else 1.0


@njit(cache=True, error_model="numpy", _nrt=False)
def plastic_eval(color, roughness, ior, wo, wi):
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return _ZERO3, 0.0
    eta = coat_eta(ior)
    e_o = coat_albedo(wo[2], roughness, eta)
    e_i = coat_albedo(wi[2], roughness, eta)
    kd = (1.0 - e_o) * (1.0 - e_i) / (math.pi * (1.0 - coat_albedo_avg(roughness, eta)))
    p_coat = _coat_probability(color, e_o)
    spec = 0.0
    pdf = (1.0 - p_coat) * wi[2] * INV_PI
    if roughness >= SMOOTH_ROUGHNESS:
        alpha = roughness * roughness
        h = normalize((wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]))
        cos_oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]
        F = fresnel_dielectric(cos_oh, eta)[0]
        spec = F * ggx_D(alpha, h) * ggx_G2(alpha, wo, wi) / (4.0 * wo[2] * wi[2])
        pdf += p_coat * ggx_reflection_pdf(alpha, wo, wi)
    f = (color[0] * kd + spec, color[1] * kd + spec, color[2] * kd + spec)
    return f, pdf


@njit(cache=True, error_model="numpy", _nrt=False)
def plastic_sample(color, roughness, ior, wo, u1, u2, u3):
    """u3 picks coat or base; (u1, u2) sample the chosen one. The weight uses the full
    mixture f and pdf (of the non-delta parts), so it equals eval's f cos / pdf."""
    if wo[2] <= 0.0:
        return (0.0, 0.0, 1.0), _ZERO3, 0.0, False
    eta = coat_eta(ior)
    e_o = coat_albedo(wo[2], roughness, eta)
    p_coat = _coat_probability(color, e_o)
    smooth = roughness < SMOOTH_ROUGHNESS
    if u3 < p_coat:
        if smooth:
            wi = (-wo[0], -wo[1], wo[2])
            F = fresnel_dielectric(wo[2], eta)[0]
            w = F / p_coat
            return wi, (w, w, w), p_coat, True
        h = ggx_sample_visible_normal(roughness * roughness, wo, u1, u2)
        wi = reflect(wo, h)
    else:
        wi = square_to_cosine_hemisphere(u1, u2)
    if wi[2] <= 0.0:
        return wi, _ZERO3, 0.0, False
    f, pdf = plastic_eval(color, roughness, ior, wo, wi)
    if pdf <= 0.0:
        return wi, _ZERO3, 0.0, False
    s = wi[2] / pdf
    return wi, (f[0] * s, f[1] * s, f[2] * s), pdf, False
