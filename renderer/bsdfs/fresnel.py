"""Fresnel reflectance: a smooth dielectric interface, and the conductor lobes' modes."""

import math

from renderer.bsdfs import FRESNEL_F82
from renderer.kernels import inline_kernel, kernel


@kernel
def fresnel_dielectric(cos_i, eta):
    """Unpolarised Fresnel reflectance and the cosine of the refracted direction.

    cos_i: cosine between the incident direction and the normal on its side (>= 0).
    eta:   n_t / n_i, the index of the medium being entered over the one left.
    Returns (F, cos_t) with cos_t >= 0; total internal reflection gives (1, 0).
    """
    cos_i = min(abs(cos_i), 1.0)
    sin2_t = (1.0 - cos_i * cos_i) / (eta * eta)  # Snell: sin_t = sin_i / eta
    if sin2_t >= 1.0:
        return 1.0, 0.0
    cos_t = math.sqrt(1.0 - sin2_t)
    r_s = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    r_p = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    return 0.5 * (r_s * r_s + r_p * r_p), cos_t


@inline_kernel
def _f82_b(f0, tint):
    """b of the F82-tint curve: at cos = 1/7 (about 82 degrees) it is Schlick's value x tint."""
    c82 = 6.0 / 7.0
    c82_5 = c82 * c82 * c82 * c82 * c82
    return (f0 + (1.0 - f0) * c82_5) * 7.0 / (c82_5 * c82) * (1.0 - tint)


@kernel
def _f82_channel(cos_i, f0, tint):
    """One channel of Cycles' F82-tint curve (Kutz et al., "Novel aspects of the Adobe
    Standard Material"): Schlick's F0 + (1 - F0)(1 - cos)^5 minus b cos (1 - cos)^6."""
    b = _f82_b(f0, tint)
    s = min(max(1.0 - cos_i, 0.0), 1.0)
    s5 = s * s * s * s * s
    return min(max(f0 + (1.0 - f0) * s5 - b * cos_i * s5 * s, 0.0), 1.0)


@inline_kernel
def conductor_fresnel(fresnel, color, tint, cos_i):
    """Reflectance (rgb) of a conductor lobe at cos_i = wo.h (see renderer.bsdfs FRESNEL_*)."""
    if fresnel == FRESNEL_F82:
        return (_f82_channel(cos_i, color[0], tint[0]), _f82_channel(cos_i, color[1], tint[1]),
                _f82_channel(cos_i, color[2], tint[2]))
    return (color[0], color[1], color[2])


@inline_kernel
def _f82_average(f0, tint):
    return f0 + (1.0 - f0) / 21.0 - _f82_b(f0, tint) / 126.0


@inline_kernel
def conductor_fresnel_average(fresnel, color, tint):
    """Hemispherical average of conductor_fresnel (rgb), as Cycles computes it for its
    Multiscatter GGX (fresnel_f82_Fss; the colour itself for a constant Fresnel)."""
    if fresnel == FRESNEL_F82:
        return (_f82_average(color[0], tint[0]), _f82_average(color[1], tint[1]),
                _f82_average(color[2], tint[2]))
    return (color[0], color[1], color[2])
