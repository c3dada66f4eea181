"""Rough conductor: GGX microfacet reflection, Cycles' Glossy and Metallic BSDFs and the
Principled BSDF's metallic component.

f = F(wo.h) D G2 / (4 |wo.z| |wi.z|) with alpha = roughness^2 and height-correlated Smith
G2. The Fresnel F follows the lobe's mode (renderer.bsdfs FRESNEL_*): constant = `color`, as
Cycles' Glossy BSDF (which bakes the colour into the closure weight, svm/closure.h +
bsdf_microfacet_setup_fresnel_constant), or Cycles' F82-tint curve with F0 = `color` and
edge tint `tint` (Principled metallic, Metallic BSDF; bsdf_microfacet_setup_fresnel_f82_tint).
With `ms` (Cycles' Multiscatter GGX distribution) the lobe is scaled by Cycles' energy
compensation, a factor of wo alone (renderer.bsdfs.multiscatter), which adds back the light
the single-scattering lobe loses at high roughness (up to ~1/3 at roughness 1 and grazing
view); without it, the single-scattering lobe, which is what Cycles' GGX distribution renders.
"""

from renderer.bsdfs.fresnel import conductor_fresnel, conductor_fresnel_average
from renderer.bsdfs.microfacet import (
    ggx_D,
    ggx_G1,
    ggx_G2,
    ggx_reflection_pdf,
    ggx_sample_visible_normal,
    reflect,
)
from renderer.bsdfs.multiscatter import energy_factor
from renderer.kernels import inline_kernel, kernel
from renderer.kernels.vecmath import mul, normalize, scale

_ZERO3 = (0.0, 0.0, 0.0)


@inline_kernel
def _fresnel(fresnel, color, tint, roughness, ms, wo, cos_oh):
    """The lobe's Fresnel, times the multiscatter compensation when `ms`."""
    f = conductor_fresnel(fresnel, color, tint, cos_oh)
    if ms:
        f = mul(f, energy_factor(conductor_fresnel_average(fresnel, color, tint), roughness, wo[2]))
    return f


@kernel
def rough_conductor_eval(color, roughness, ior, fresnel, tint, ms, wo, wi):
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return _ZERO3, 0.0
    alpha = max(roughness * roughness, 1e-7)
    h = normalize((wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]))
    d = ggx_D(alpha, h)
    f = d * ggx_G2(alpha, wo, wi) / (4.0 * wo[2] * wi[2])
    cos_oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]
    fresnel_rgb = _fresnel(fresnel, color, tint, roughness, ms, wo, cos_oh)
    return scale(fresnel_rgb, f), ggx_reflection_pdf(alpha, wo, wi)


@kernel
def rough_conductor_sample(color, roughness, ior, fresnel, tint, ms, wo, u1, u2, u3):
    """Visible-normal sampling; the weight f cos / pdf reduces to F(wo.h) G2 / G1(wo)."""
    if wo[2] <= 0.0:
        return (0.0, 0.0, 1.0), _ZERO3, 0.0, False
    alpha = max(roughness * roughness, 1e-7)
    h = ggx_sample_visible_normal(alpha, wo, u1, u2)
    wi = reflect(wo, h)
    if wi[2] <= 0.0:
        return wi, _ZERO3, 0.0, False
    pdf = ggx_G1(alpha, wo) * ggx_D(alpha, h) / (4.0 * wo[2])
    if pdf <= 0.0:
        return wi, _ZERO3, 0.0, False
    w = ggx_G2(alpha, wo, wi) / ggx_G1(alpha, wo)
    cos_oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]
    return wi, scale(_fresnel(fresnel, color, tint, roughness, ms, wo, cos_oh), w), pdf, False
