"""Warps from the unit square to directions (local frame, z up)."""

import math

from renderer.kernels import fastmath as fm
from renderer.kernels import kernel
from renderer.kernels.vecmath import INV_PI


@kernel
def square_to_cosine_hemisphere(u1, u2):
    """Cosine-weighted direction on the upper hemisphere: pdf = cos(theta) / pi.

    Malley's method: a uniform point on the unit disk (r = sqrt(u1)) lifted to the
    hemisphere has density proportional to cos(theta).
    """
    r = math.sqrt(u1)
    phi = 2.0 * math.pi * u2
    z = math.sqrt(max(0.0, 1.0 - u1))
    sin_phi, cos_phi = fm.sincos(phi)
    return (r * cos_phi, r * sin_phi, z)


@kernel
def cosine_hemisphere_pdf(cos_theta):
    return cos_theta * INV_PI if cos_theta > 0.0 else 0.0
