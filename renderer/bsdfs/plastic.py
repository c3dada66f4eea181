"""Plastic: Cycles' Principled BSDF dielectric part, a GGX specular layer over a diffuse base.

    f = f_spec(wo, wi) + color / pi * (1 - max(E(wo), E_ss(wo)))

f_spec = F(wo.h) D G2 / (4 wo.z wi.z) is the layer's own (uncoloured) reflection with the
exact dielectric Fresnel of index `ior`. The base is Lambertian, weighted by what Cycles
estimates the layer leaves for the view direction: 1 - E(wo), with E Cycles' tabulated
albedo estimate (renderer.bsdfs.spec_albedo; svm/closure.h `closure_layering_weight`).
There is no (1 - E(wi)) factor, exactly as in Cycles, so f is not reciprocal; a path tracer
that only follows paths from the camera never needs it to be.

The albedo is E_ss(wo) + color (1 - E(wo)), E_ss being the layer's single-scattering
albedo. The exact E is >= E_ss, but Cycles' coarse table interpolates below E_ss near
grazing at low roughness (by up to 0.03 for mu < 0.15), where Cycles' Principled BSDF
reflects a little more than it receives. Haze takes the larger of E and its own tabulated
E_ss (renderer.bsdfs.coat_albedo, within 4e-3 of exact for mu >= 0.01, 6e-3 at mu = 0.005),
so the albedo stays <= 1 within that accuracy, and differs from Cycles only where Cycles
creates energy.

Below SMOOTH_ROUGHNESS the layer is a smooth interface: its reflection is a delta lobe
(weight F), sampled with `is_delta` True and absent from eval; the base stays diffuse.
The layer's index is max(ior, 1/ior) (E_ss is looked up at most at index 4, its table's range).
"""


from renderer.bsdfs import SMOOTH_ROUGHNESS
from renderer.bsdfs.coat_albedo import coat_albedo, coat_eta
from renderer.bsdfs.fresnel import fresnel_dielectric
from renderer.bsdfs.microfacet import (
    ggx_D,
    ggx_G2,
    ggx_reflection_pdf,
    ggx_sample_visible_normal,
    reflect,
)
from renderer.bsdfs.spec_albedo import spec_albedo
from renderer.bsdfs.warp import square_to_cosine_hemisphere
from renderer.kernels import kernel
from renderer.kernels.vecmath import INV_PI, normalize

_ZERO3 = (0.0, 0.0, 0.0)


@kernel
def _coat_probability(color, e_o):
    """Chance of sampling the layer: its share of E(wo) + avg(color) (1 - E(wo))."""
    base = (color[0] + color[1] + color[2]) / 3.0 * (1.0 - e_o)
    total = e_o + max(base, 0.0)
    return e_o / total if total > 0.0 else 1.0


@kernel
def _layer_eta(ior):
    """The layer's relative index, >= 1 (the layer is seen from outside)."""
    return ior if ior >= 1.0 else 1.0 / max(ior, 1e-6)


@kernel
def layer_albedo(mu, roughness, eta):
    """max(Cycles' estimate E, the single-scattering E_ss) of the layer for wo.z = mu."""
    e = spec_albedo(mu, roughness, eta)
    e_ss = coat_albedo(mu, roughness, coat_eta(eta))
    return min(max(e, e_ss, 0.0), 1.0)


@kernel
def plastic_eval(color, roughness, ior, wo, wi):
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return _ZERO3, 0.0
    eta = _layer_eta(ior)
    e_o = layer_albedo(wo[2], roughness, eta)
    kd = (1.0 - e_o) * INV_PI
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


@kernel
def plastic_sample(color, roughness, ior, wo, u1, u2, u3):
    """u3 picks layer or base; (u1, u2) sample the chosen one. The weight uses the full
    mixture f and pdf (of the non-delta parts), so it equals eval's f cos / pdf."""
    if wo[2] <= 0.0:
        return (0.0, 0.0, 1.0), _ZERO3, 0.0, False
    eta = _layer_eta(ior)
    e_o = layer_albedo(wo[2], roughness, eta)
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
