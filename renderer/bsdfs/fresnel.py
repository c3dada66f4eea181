"""Fresnel reflectance of a smooth dielectric interface."""

import math

from numba import njit


@njit(cache=True, error_model="numpy", _nrt=False)
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
