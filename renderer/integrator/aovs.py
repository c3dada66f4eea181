"""The render passes' per-path values, written by the surface stage into L's AOV columns
(integrator.paths AOV_*) when CFG_AOVS is on; renderer.passes turns the film's sums of them
into Blender's passes. Definitions follow Cycles (kernel/film/data_passes.h and
denoising_passes.h in the bpy 5.0 source):

* Data passes, at the first hit of a camera path that has not scattered (Cycles'
  PATH_RAY_TRANSPARENT_BACKGROUND) on a surface that is not mostly transparent (alpha >= 0.5,
  Cycles' default pass alpha threshold): Position (and the hit flag Depth is made from) from
  the pixel's sample 0 only (Cycles overwrites them on sample 0), Normal summed over every
  sample (Cycles adds it, and a miss adds 0). Interfaces without lobes (medium boundaries)
  are skipped, as Cycles skips SD_HAS_ONLY_VOLUME surfaces.
* Denoising features: at each surface with lobes, while not yet written, the closures are
  split into diffuse-like (Lambertian, plastic, GGX with alpha = roughness^2 > 0.075) and
  specular-like (smooth glass, mirrors, transparent, GGX alpha <= 0.075). Unless 75% or more
  of the selection weight is specular-like, the normal (selection-weighted mean, facing the
  ray) and albedo = feature throughput x diffuse-like albedo are written and the features
  are done; otherwise the feature throughput is multiplied by the specular-like albedo and
  the path looks further (a glass's albedo is Cycles' estimate, _dielectric_albedo: below 1
  seen from inside near total internal reflection). Emission or background found before that adds
  feature throughput x radiance x MIS weight to the albedo (Cycles' light_passes.h), and the
  background ends the features.
* Light passes by category (Cycles' light_passes.h): a path's first scattering event sets
  its category (PATH_RAY_VOLUME_PASS in a volume). Light it brings to the camera after
  that goes to the category's Direct pass when it comes from that first vertex (its
  next-event ray, or emission the path found right after it, at depth 1) and to its
  Indirect pass otherwise. Only the volume's category is written (Volume Direct and
  Indirect); a shadow ray carries its column (Shadows.col) from where it was emitted.
Lobe albedos are the lobe's weight x colour, except a glass's, which is Cycles' estimate
(_dielectric_albedo). (Cycles' bsdf_albedo also folds in Fresnel for the other microfacet
lobes; Haze's plastic and conductors are not corrected for it.)
"""

import math

from ..bsdfs import (
    CONDUCTOR,
    DIELECTRIC,
    DIFFUSE,
    PLASTIC,
    ROUGH_CONDUCTOR,
    SIDE_BACK,
    SIDE_FRONT,
    TRANSPARENT,
)
from ..bsdfs.fresnel import fresnel_dielectric
from ..bsdfs.layout import L_COLOR, L_IOR, L_KIND, L_ROUGH, L_SIDES, L_TINT, L_WEIGHT, M_COUNT, M_FIRST
from ..bsdfs.material import _lobe_selection
from ..bsdfs.spec_albedo import spec_albedo
from ..camera import ORTHOGRAPHIC, PROJ_KIND
from ..kernels import inline_kernel, kernel
from .paths import (
    AOV_DALBEDO,
    AOV_DATA_DONE,
    AOV_DIFFUSE_COLOR,
    AOV_DNORMAL,
    AOV_DNORMAL_VOLUME,
    AOV_EMISSION,
    AOV_FEAT_DEPTH,
    AOV_FEAT_DONE,
    AOV_FEAT_T,
    AOV_FIRST_KIND,
    AOV_GLOSSY_COLOR,
    AOV_HIT0,
    AOV_MIST,
    AOV_NORMAL,
    AOV_POSITION,
    AOV_SAMPLE0,
    AOV_TRANSMISSION_COLOR,
    AOV_VOLUME_DIRECT,
    AOV_VOLUME_INDIRECT,
    KIND_NONE,
    KIND_VOLUME,
    NO_PASS,
)

ROUGH_ALPHA = 0.075  # Cycles: a closure with alpha_x alpha_y > 0.075^2 counts as diffuse-like
ALPHA_THRESHOLD = 0.5  # Cycles' film pass_alpha_threshold default


@kernel
def aov_emission(L, pid, beta, le, w):
    """Emission or background radiance le x MIS weight w found along the path before its
    denoising features were written adds to Denoising Albedo (beta is the path throughput;
    features are written by the first camera path only, so beta is 1 where Cycles writes)."""
    if L[pid, AOV_FEAT_DONE] != 0.0:
        return
    for c in range(3):
        L[pid, AOV_DALBEDO + c] += L[pid, AOV_FEAT_T + c] * le[c] * w


@kernel
def aov_emission_pass(L, pid, beta, le, w):
    """Emission (surface or volume) found by a camera path before it scattered: the Emission
    pass (Cycles writes it where PATH_RAY_ANY_PASS is not yet set; the world goes to its own
    Background pass, not written)."""
    for c in range(3):
        L[pid, AOV_EMISSION + c] += beta[c] * le[c] * w


@inline_kernel
def _category_column(kind, direct):
    """The light pass column of category `kind` (KIND_*), Direct or Indirect."""
    if kind == KIND_VOLUME:
        return AOV_VOLUME_DIRECT if direct else AOV_VOLUME_INDIRECT
    return NO_PASS


@inline_kernel
def shadow_pass_column(L, pid, depth, in_volume, light_aovs):
    """The light pass a next-event ray from a scattering vertex at `depth` (in a volume or
    on a surface) also adds to: the vertex's own category's Direct pass at the path's first
    scattering event, else its first event's category's Indirect pass."""
    if not light_aovs:
        return NO_PASS
    if depth == 0:
        return _category_column(KIND_VOLUME if in_volume else KIND_NONE, True)
    return _category_column(L[pid, AOV_FIRST_KIND], False)


@inline_kernel
def aov_first_scatter(L, pid, depth, in_volume):
    """The path scattered (its depth-th event): the first one sets its category."""
    if depth == 0 and in_volume:
        L[pid, AOV_FIRST_KIND] = KIND_VOLUME


@kernel
def aov_scattered_emission(L, pid, depth, beta, le, w):
    """Emission or background radiance le x MIS weight w that a path found after `depth`
    >= 1 scattering events: its category's Direct pass right after the first (depth 1),
    Indirect later."""
    col = _category_column(L[pid, AOV_FIRST_KIND], depth == 1)
    if col != NO_PASS:
        for c in range(3):
            L[pid, col + c] += beta[c] * le[c] * w


@kernel
def aov_colors(L, pid, mt, m, front, mu, beta):
    """Diffuse, Glossy and Transmission Color at a hit before the path scattered (Cycles
    writes them at every such hit: transparent surfaces in front add theirs): beta x the
    diffuse-like, glossy and transmission lobes' albedo for the view direction with cosine
    mu. Diffuse lobes give weight x
    colour; the Principled base its share left by the layer, colour x (1 - E(mu)), and the
    layer E(mu) (Cycles' tabulated estimate, renderer.bsdfs.spec_albedo); mirrors and GGX
    reflection weight x colour (Cycles' Glossy BSDF, no Fresnel); glass its refraction,
    weight x (1 - F(mu)) x its refraction tint (Cycles' bsdf_albedo of a smooth glass
    closure: exact Fresnel). Transparent lobes go to none (Cycles counts them as no
    transmission closure), and glass's reflectance, which Cycles adds to Glossy Color,
    is not written."""
    mats, lobes = mt
    start = mats[m, M_FIRST]
    side = SIDE_FRONT if front else SIDE_BACK
    for j in range(start, start + mats[m, M_COUNT]):
        if (int(lobes[j, L_SIDES]) & side) == 0:
            continue
        kind = int(lobes[j, L_KIND])
        if kind == DIFFUSE or kind == PLASTIC:
            left = 1.0
            if kind == PLASTIC:
                ior = float(lobes[j, L_IOR])
                e = spec_albedo(mu, float(lobes[j, L_ROUGH]), ior if ior >= 1.0 else 1.0 / max(ior, 1e-6))
                left = 1.0 - e
                for c in range(3):
                    L[pid, AOV_GLOSSY_COLOR + c] += beta[c] * float(lobes[j, L_WEIGHT + c]) * e
            for c in range(3):
                a = float(lobes[j, L_WEIGHT + c]) * float(lobes[j, L_COLOR + c])
                L[pid, AOV_DIFFUSE_COLOR + c] += beta[c] * a * left
        elif kind == ROUGH_CONDUCTOR or kind == CONDUCTOR:
            for c in range(3):
                a = float(lobes[j, L_WEIGHT + c]) * float(lobes[j, L_COLOR + c])
                L[pid, AOV_GLOSSY_COLOR + c] += beta[c] * a
        elif kind == DIELECTRIC:
            ior = float(lobes[j, L_IOR])
            t = 1.0 - fresnel_dielectric(mu, ior if front else 1.0 / max(ior, 1e-6))[0]
            for c in range(3):
                a = float(lobes[j, L_WEIGHT + c]) * float(lobes[j, L_COLOR + c])
                L[pid, AOV_TRANSMISSION_COLOR + c] += beta[c] * a * t


@kernel
def aov_after_medium(L, pid, depth):
    """At the start of a path's stage: if it scattered in a medium since its features last
    looked (its depth grew), that scatter ends them with Cycles' volume normal."""
    if L[pid, AOV_FEAT_DONE] == 0.0 and depth > L[pid, AOV_FEAT_DEPTH]:
        L[pid, AOV_DNORMAL_VOLUME] += 1.0
        L[pid, AOV_FEAT_DONE] = 1.0


@kernel
def aov_medium_segment(L, pid, depth, beta, sa, ss, length):
    """A homogeneous segment of `length` with summed coefficients sa, ss crossed with the
    features open: albedo += feature throughput x beta x ss/st x (1 - exp(-st length))."""
    aov_after_medium(L, pid, depth)
    if L[pid, AOV_FEAT_DONE] != 0.0:
        return
    for c in range(3):
        st = sa[c] + ss[c]
        if st > 0.0:
            single = ss[c] / st * (1.0 - math.exp(-st * length))
            L[pid, AOV_DALBEDO + c] += L[pid, AOV_FEAT_T + c] * beta[c] * single


@kernel
def aov_background(L, pid):
    """The path reached the world: its features end (the background radiance was added by
    aov_emission); the data passes stay 0 (Depth reads 0 as 1e10, as Cycles)."""
    L[pid, AOV_FEAT_DONE] = 1.0


@kernel
def aov_past_limit(L, pid):
    """A surface hit past the bounce limit (depth > max_bounces, which the path does not
    shade): Cycles evaluates no closures there (surface_shader_eval with PATH_RAY_TERMINATE),
    so open denoising features end with a zero normal and albedo. (Data passes are written
    at depth 0, which is never past the limit.)"""
    L[pid, AOV_FEAT_DONE] = 1.0


@kernel
def mist_amount(cam, mist, x):
    """Cycles' mist at point x: saturate((distance - start) / depth) ^ falloff, the distance
    from the camera (along its view axis for an orthographic camera: camera_distance)."""
    to_world = cam.to_world
    dx, dy, dz = x[0] - to_world[0, 3], x[1] - to_world[1, 3], x[2] - to_world[2, 3]
    if int(cam.projection[PROJ_KIND]) == ORTHOGRAPHIC:
        ax, ay, az = to_world[0, 2], to_world[1, 2], to_world[2, 2]
        dist = abs(dx * ax + dy * ay + dz * az) / math.sqrt(ax * ax + ay * ay + az * az)
    else:
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    amount = min(max((dist - mist[0]) * mist[1], 0.0), 1.0)
    return amount ** mist[2]


@inline_kernel
def _dielectric_albedo(lobes, j, front, mu):
    """Cycles' bsdf_albedo of a glass closure seen at cosine mu (its estimate, closure/
    bsdf_microfacet.h bsdf_microfacet_estimate_albedo): the reflectance read from the
    tabulated outside Fresnel curve (ggx_gen_schlick_ior_s, which cannot tell eta from 1/eta:
    seen from inside it ignores total internal reflection) x the reflection tint, plus the
    exact transmittance 1 - F(mu, eta of this side) x the refraction tint, times the lobe's
    weight. Seen from outside it is about 1 for a clear glass; from inside near and past the
    critical angle it falls toward F0 (0.04 at IOR 1.5), and the denoising features of
    paths through a glass ball's outline carry that loss."""
    ior = float(lobes[j, L_IOR])
    eta_up = ior if ior >= 1.0 else 1.0 / max(ior, 1e-6)
    reflect = spec_albedo(mu, float(lobes[j, L_ROUGH]), eta_up)
    transmit = 1.0 - fresnel_dielectric(mu, ior if front else 1.0 / max(ior, 1e-6))[0]
    a0 = float(lobes[j, L_WEIGHT]) * (float(lobes[j, L_TINT]) * reflect + float(lobes[j, L_COLOR]) * transmit)
    a1 = float(lobes[j, L_WEIGHT + 1]) * (float(lobes[j, L_TINT + 1]) * reflect
                                         + float(lobes[j, L_COLOR + 1]) * transmit)
    a2 = float(lobes[j, L_WEIGHT + 2]) * (float(lobes[j, L_TINT + 2]) * reflect
                                         + float(lobes[j, L_COLOR + 2]) * transmit)
    return a0, a1, a2


@kernel
def aov_surface(L, pid, mt, m, front, x, facing, mu, depth, beta, cam, mist):
    """The passes at a surface hit with lobes at point x, shading normal `facing` (turned
    toward the incoming ray) at cosine mu to the ray, after `depth` scattering events, path
    throughput beta."""
    mats, lobes = mt
    start = mats[m, M_FIRST]
    end = start + mats[m, M_COUNT]
    side = SIDE_FRONT if front else SIDE_BACK
    sum_w = 0.0
    diffuse_w = 0.0
    transparent_w = 0.0
    d0 = d1 = d2 = 0.0  # diffuse-like albedo
    s0 = s1 = s2 = 0.0  # specular-like albedo
    for j in range(start, end):
        if (int(lobes[j, L_SIDES]) & side) == 0:
            continue
        kind = int(lobes[j, L_KIND])
        sw = _lobe_selection(lobes, j)
        sum_w += sw
        alpha = float(lobes[j, L_ROUGH]) ** 2
        diffuse_like = kind == DIFFUSE or kind == PLASTIC or (kind == ROUGH_CONDUCTOR and alpha > ROUGH_ALPHA)
        if kind == TRANSPARENT:
            transparent_w += sw
        if kind == DIELECTRIC:
            a0, a1, a2 = _dielectric_albedo(lobes, j, front, mu)
        else:
            a0 = float(lobes[j, L_WEIGHT]) * float(lobes[j, L_COLOR])
            a1 = float(lobes[j, L_WEIGHT + 1]) * float(lobes[j, L_COLOR + 1])
            a2 = float(lobes[j, L_WEIGHT + 2]) * float(lobes[j, L_COLOR + 2])
        if diffuse_like:
            diffuse_w += sw
            d0, d1, d2 = d0 + a0, d1 + a1, d2 + a2
        else:
            s0, s1, s2 = s0 + a0, s1 + a1, s2 + a2

    # Data passes: the first hit that is not mostly transparent, before any scattering.
    mostly_transparent = sum_w > 0.0 and transparent_w > ALPHA_THRESHOLD * sum_w
    if depth == 0 and L[pid, AOV_DATA_DONE] == 0.0 and not mostly_transparent:
        if L[pid, AOV_SAMPLE0] != 0.0:
            L[pid, AOV_HIT0] = 1.0
            for c in range(3):
                L[pid, AOV_POSITION + c] = x[c]
        for c in range(3):
            L[pid, AOV_NORMAL + c] += facing[c]
        # Cycles writes (1 - mist) x mean throughput and reads Mist as 1 - the mean.
        L[pid, AOV_MIST] += (1.0 - mist_amount(cam, mist, x)) * (beta[0] + beta[1] + beta[2]) / 3.0
        L[pid, AOV_DATA_DONE] = 1.0

    if L[pid, AOV_FEAT_DONE] != 0.0:
        return
    # Wait for the next bounce when 75% or more of the weight is specular-like (Cycles).
    if sum_w == 0.0 or diffuse_w * 4.0 > sum_w:
        # All lobes share the one shading normal, so their weighted mean is that normal
        # (and 0 when every lobe is black, as in Cycles).
        if sum_w > 0.0:
            for c in range(3):
                L[pid, AOV_DNORMAL + c] += facing[c]
        L[pid, AOV_DALBEDO] += L[pid, AOV_FEAT_T] * d0
        L[pid, AOV_DALBEDO + 1] += L[pid, AOV_FEAT_T + 1] * d1
        L[pid, AOV_DALBEDO + 2] += L[pid, AOV_FEAT_T + 2] * d2
        L[pid, AOV_FEAT_DONE] = 1.0
    else:
        L[pid, AOV_FEAT_DEPTH] = depth + 1  # the scatter at this surface is not a medium's
        L[pid, AOV_FEAT_T] *= s0
        L[pid, AOV_FEAT_T + 1] *= s1
        L[pid, AOV_FEAT_T + 2] *= s2
