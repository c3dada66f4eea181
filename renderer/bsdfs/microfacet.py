"""GGX (Trowbridge-Reitz) microfacet distribution, isotropic, in the local frame (z = normal).

alpha = roughness^2 (Blender). Masking-shadowing is Smith's height-correlated form
G2 = 1 / (1 + Lambda(wo) + Lambda(wi)), the same as Cycles' bsdf_G; visible normals are
sampled with Heitz 2018, "Sampling the GGX Distribution of Visible Normals".
"""

import math

from renderer.kernels import fastmath as fm
from renderer.kernels import kernel
from renderer.kernels.vecmath import cross, normalize


@kernel
def ggx_D(alpha, h):
    """Distribution of normals, normalised so that integral D(h) h.z dh = 1."""
    cos2 = h[2] * h[2]
    if h[2] <= 0.0:
        return 0.0
    a2 = alpha * alpha
    d = cos2 * (a2 - 1.0) + 1.0
    return a2 / (math.pi * d * d)


@kernel
def ggx_lambda(alpha, w):
    """Smith's Lambda for GGX: (-1 + sqrt(1 + alpha^2 tan^2 theta)) / 2."""
    cos2 = w[2] * w[2]
    if cos2 <= 0.0:
        return math.inf
    a2_tan2 = alpha * alpha * max(0.0, 1.0 - cos2) / cos2
    return 0.5 * (math.sqrt(1.0 + a2_tan2) - 1.0)


@kernel
def ggx_G1(alpha, w):
    return 1.0 / (1.0 + ggx_lambda(alpha, w))


@kernel
def ggx_G2(alpha, wo, wi):
    """Height-correlated masking-shadowing (symmetric in wo, wi)."""
    return 1.0 / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi))


@kernel
def ggx_sample_visible_normal(alpha, wo, u1, u2):
    """A microfacet normal h with density D_wo(h) = G1(wo) max(0, wo.h) D(h) / wo.z (wo.z > 0)."""
    # Stretch wo so the GGX ellipsoid becomes the unit hemisphere.
    vh = normalize((alpha * wo[0], alpha * wo[1], wo[2]))
    lensq = vh[0] * vh[0] + vh[1] * vh[1]
    if lensq > 0.0:
        inv = 1.0 / math.sqrt(lensq)
        t1 = (-vh[1] * inv, vh[0] * inv, 0.0)
    else:
        t1 = (1.0, 0.0, 0.0)
    t2 = cross(vh, t1)
    # Uniform point on the disk, squeezed onto the part of it visible from vh.
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    sin_phi, cos_phi = fm.sincos(phi)
    p1 = r * cos_phi
    p2 = r * sin_phi
    s = 0.5 * (1.0 + vh[2])
    p2 = (1.0 - s) * math.sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2
    p3 = math.sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2))
    nh = (p1 * t1[0] + p2 * t2[0] + p3 * vh[0],
          p1 * t1[1] + p2 * t2[1] + p3 * vh[1],
          p1 * t1[2] + p2 * t2[2] + p3 * vh[2])
    # Unstretch back to the rough configuration.
    return normalize((alpha * nh[0], alpha * nh[1], max(0.0, nh[2])))


@kernel
def ggx_reflection_pdf(alpha, wo, wi):
    """Solid-angle pdf of wi = reflect(wo, h) with h from ggx_sample_visible_normal.

    D_wo(h) / (4 wo.h), the Jacobian of reflection, simplifies to G1(wo) D(h) / (4 wo.z).
    """
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return 0.0
    h = normalize((wo[0] + wi[0], wo[1] + wi[1], wo[2] + wi[2]))
    return ggx_G1(alpha, wo) * ggx_D(alpha, h) / (4.0 * wo[2])


@kernel
def reflect(w, h):
    """Mirror w about h: 2 (w.h) h - w."""
    c = 2.0 * (w[0] * h[0] + w[1] * h[1] + w[2] * h[2])
    return (c * h[0] - w[0], c * h[1] - w[1], c * h[2] - w[2])
