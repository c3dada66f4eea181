"""Plastic: Cycles' Principled BSDF dielectric part, a GGX specular layer over a diffuse base.

    f = f_spec(wo, wi) + color / pi * (1 - max(E(wo), E_ss(wo)))

f_spec = F(wo.h) D G2 / (4 wo.z wi.z) is the layer's own reflection with Cycles' remapped
dielectric Fresnel of index `ior`: F = mix(F0 x tint, 1, s), s = where the exact Fresnel lies
between F0 and 1 (generalized Schlick with a negative exponent), so `tint` is the
Principled BSDF's Specular Tint and white gives the exact Fresnel. The base is Lambertian,
weighted by what Cycles estimates the layer leaves for the view direction: 1 - E(wo), with E
Cycles' tabulated albedo estimate (renderer.bsdfs.spec_albedo; svm/closure.h
`closure_layering_weight`), per channel and the largest channel taken, as Cycles does.
With `ms` (Multiscatter GGX) f_spec is scaled by Cycles' energy compensation
(renderer.bsdfs.multiscatter) and E by its part beyond the white-Fresnel scale.
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

On a bumped surface (renderer.bsdfs.closure_normals) the base lies on the program's normal and
the layer on its specular-corrected one, each part weighed by its own bump factor:
plastic_eval_bumped and plastic_sample_bumped.
"""


from renderer.bsdfs import SMOOTH_ROUGHNESS
from renderer.bsdfs.closure_normals import diffuse_factor, specular_factor
from renderer.bsdfs.coat_albedo import coat_albedo, coat_eta
from renderer.bsdfs.fresnel import fresnel_dielectric
from renderer.bsdfs.microfacet import (
    ggx_D,
    ggx_G2,
    ggx_reflection_pdf,
    ggx_sample_visible_normal,
    reflect,
)
from renderer.bsdfs.multiscatter import dielectric_fss, energy_factor, ggx_energy
from renderer.bsdfs.spec_albedo import f0_from_eta, spec_albedo
from renderer.bsdfs.warp import square_to_cosine_hemisphere
from renderer.kernels import inline_kernel, kernel
from renderer.kernels.vecmath import INV_PI, add, dot, mul, normalize, onb, scale, to_world

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


@inline_kernel
def _remap(x, f0):
    """(x - f0) / (1 - f0) clamped to [0, 1]: where x lies between F0 and 1."""
    return min(max((x - f0) / (1.0 - f0), 0.0), 1.0) if f0 < 1.0 else 1.0


@kernel
def _layer(roughness, eta, tint, ms, mu):
    """The layer seen from wo.z = mu: (f0 (rgb): F0 x tint; scale (rgb) of its reflection,
    the multiscatter compensation or 1; base: the diffuse base's weight 1 - max over channels
    of the layer's albedo; e_mean: the layer's mean albedo, for the lobe choice)."""
    f0_real = f0_from_eta(eta)
    f0 = (min(max(f0_real * tint[0], 0.0), 1.0), min(max(f0_real * tint[1], 0.0), 1.0),
          min(max(f0_real * tint[2], 0.0), 1.0))
    s = _remap(layer_albedo(mu, roughness, eta), f0_real)
    albedo = (f0[0] + (1.0 - f0[0]) * s, f0[1] + (1.0 - f0[1]) * s, f0[2] + (1.0 - f0[2]) * s)
    factor = (1.0, 1.0, 1.0)
    darkening = (1.0, 1.0, 1.0)
    if ms:
        s_avg = _remap(dielectric_fss(eta), f0_real)
        fss = (f0[0] + (1.0 - f0[0]) * s_avg, f0[1] + (1.0 - f0[1]) * s_avg, f0[2] + (1.0 - f0[2]) * s_avg)
        factor = energy_factor(fss, roughness, mu)
        e, _ = ggx_energy(roughness, mu)
        # Cycles weighs the base by the albedo estimate times the lobe's weight, which holds
        # the compensation over its white-Fresnel part (energy_scale): factor / (1 + (1 - E) / E).
        inv_scale = e if e > 0.0 else 1.0
        darkening = scale(factor, inv_scale)
    layered = mul(albedo, darkening)
    base = min(max(1.0 - max(layered[0], layered[1], layered[2]), 0.0), 1.0)
    return f0, factor, base, (layered[0] + layered[1] + layered[2]) / 3.0


@inline_kernel
def _fresnel(f0, f0_real, eta, cos_oh, factor):
    """Cycles' remapped Fresnel mix(F0 x tint, 1, s(real F)) per channel, times `factor`."""
    s = _remap(fresnel_dielectric(cos_oh, eta)[0], f0_real)
    return ((f0[0] + (1.0 - f0[0]) * s) * factor[0], (f0[1] + (1.0 - f0[1]) * s) * factor[1],
            (f0[2] + (1.0 - f0[2]) * s) * factor[2])


@inline_kernel
def _layer_reflection(f0, factor, eta, roughness, wo, wi):
    """(f, pdf) of the rough layer's own reflection, F(wo.h) D G2 / (4 wo.z wi.z)."""
    alpha = roughness * roughness
    h = normalize((wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]))
    cos_oh = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]
    F = _fresnel(f0, f0_from_eta(eta), eta, cos_oh, factor)
    return (scale(F, ggx_D(alpha, h) * ggx_G2(alpha, wo, wi) / (4.0 * wo[2] * wi[2])),
            ggx_reflection_pdf(alpha, wo, wi))


@kernel
def plastic_eval(color, roughness, ior, tint, ms, wo, wi):
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return _ZERO3, 0.0
    eta = _layer_eta(ior)
    f0, factor, base, e_o = _layer(roughness, eta, tint, ms, wo[2])
    kd = base * INV_PI
    p_coat = _coat_probability(color, e_o)
    spec = _ZERO3
    pdf = (1.0 - p_coat) * wi[2] * INV_PI
    if roughness >= SMOOTH_ROUGHNESS:
        spec, pdf_layer = _layer_reflection(f0, factor, eta, roughness, wo, wi)
        pdf += p_coat * pdf_layer
    f = (color[0] * kd + spec[0], color[1] * kd + spec[1], color[2] * kd + spec[2])
    return f, pdf


@kernel
def plastic_sample(color, roughness, ior, tint, ms, wo, u1, u2, u3):
    """u3 picks layer or base; (u1, u2) sample the chosen one. The weight uses the full
    mixture f and pdf (of the non-delta parts), so it equals eval's f cos / pdf."""
    if wo[2] <= 0.0:
        return (0.0, 0.0, 1.0), _ZERO3, 0.0, False
    eta = _layer_eta(ior)
    f0, factor, base, e_o = _layer(roughness, eta, tint, ms, wo[2])
    p_coat = _coat_probability(color, e_o)
    smooth = roughness < SMOOTH_ROUGHNESS
    if u3 < p_coat:
        if smooth:
            wi = (-wo[0], -wo[1], wo[2])
            F = _fresnel(f0, f0_from_eta(eta), eta, wo[2], factor)
            return wi, scale(F, 1.0 / p_coat), p_coat, True
        h = ggx_sample_visible_normal(roughness * roughness, wo, u1, u2)
        wi = reflect(wo, h)
    else:
        wi = square_to_cosine_hemisphere(u1, u2)
    if wi[2] <= 0.0:
        return wi, _ZERO3, 0.0, False
    f, pdf = plastic_eval(color, roughness, ior, tint, ms, wo, wi)
    if pdf <= 0.0:
        return wi, _ZERO3, 0.0, False
    s = wi[2] / pdf
    return wi, (f[0] * s, f[1] * s, f[2] * s), pdf, False


# A bumped surface (renderer.bsdfs.closure_normals): the base, a diffuse closure, lies on the
# program's normal nb and the layer, a specular one, on the shading frame's z. wo, wi and the
# normals nb, n_mesh are given in that frame with the viewer above it (wo.z > 0).


@kernel
def plastic_eval_bumped(color, roughness, ior, tint, ms, wo, wi, nb, n_mesh):
    """(f cos, pdf): the layer's f wi.z (times its side test) plus the base's color / pi
    (1 - E(wo)) nb.wi (times its bump shadowing); the base's weight and the lobe choice depend
    on wo through the layer, as in Cycles' closure_layering_weight. The mixture's pdf is
    p_coat pdf_layer + (1 - p_coat) max(nb.wi, 0) / pi, each part's in its own frame."""
    if wo[2] <= 0.0:
        return _ZERO3, 0.0
    eta = _layer_eta(ior)
    f0, factor, base, e_o = _layer(roughness, eta, tint, ms, wo[2])
    p_coat = _coat_probability(color, e_o)
    cos_b = max(dot(nb, wi), 0.0)
    f = scale(color, base * INV_PI * cos_b * diffuse_factor(n_mesh, nb, wi))
    pdf = (1.0 - p_coat) * cos_b * INV_PI
    if roughness >= SMOOTH_ROUGHNESS and wi[2] > 0.0:
        spec, pdf_layer = _layer_reflection(f0, factor, eta, roughness, wo, wi)
        f = add(f, scale(spec, wi[2] * specular_factor(n_mesh, wi)))
        pdf += p_coat * pdf_layer
    return f, pdf


@kernel
def plastic_sample_bumped(color, roughness, ior, tint, ms, wo, nb, n_mesh, u1, u2, u3):
    """(wi, weight, pdf, is_delta) drawn as plastic_sample's, the base about nb; the weight is
    plastic_eval_bumped's f cos / pdf. (Written apart from plastic_sample: sharing its code
    moved LLVM's fused multiply-adds there, and unbumped images must not change.)"""
    if wo[2] <= 0.0:
        return (0.0, 0.0, 1.0), _ZERO3, 0.0, False
    eta = _layer_eta(ior)
    f0, factor, base, e_o = _layer(roughness, eta, tint, ms, wo[2])
    p_coat = _coat_probability(color, e_o)
    if u3 < p_coat:
        if roughness < SMOOTH_ROUGHNESS:
            wi = (-wo[0], -wo[1], wo[2])
            F = _fresnel(f0, f0_from_eta(eta), eta, wo[2], factor)
            return wi, scale(F, specular_factor(n_mesh, wi) / p_coat), p_coat, True
        wi = reflect(wo, ggx_sample_visible_normal(roughness * roughness, wo, u1, u2))
        if wi[2] <= 0.0:  # lost below the layer, where its pdf is 0 (the base's may not be)
            return wi, _ZERO3, 0.0, False
    else:
        s, t = onb(nb)
        wi = to_world(square_to_cosine_hemisphere(u1, u2), s, t, nb)
    f, pdf = plastic_eval_bumped(color, roughness, ior, tint, ms, wo, wi, nb, n_mesh)
    if pdf <= 0.0:
        return wi, _ZERO3, 0.0, False
    return wi, scale(f, 1.0 / pdf), pdf, False
