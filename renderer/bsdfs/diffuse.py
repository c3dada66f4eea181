"""Lambertian reflection: f = color / pi on the upper hemisphere."""

from renderer.bsdfs.warp import square_to_cosine_hemisphere
from renderer.kernels import kernel
from renderer.kernels.vecmath import INV_PI, scale

_ZERO3 = (0.0, 0.0, 0.0)


@kernel
def diffuse_eval(color, roughness, ior, wo, wi):
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return _ZERO3, 0.0
    return scale(color, INV_PI), wi[2] * INV_PI


@kernel
def diffuse_sample(color, roughness, ior, wo, u1, u2, u3):
    """Cosine-weighted sampling: f * cos / pdf = color exactly."""
    wi = square_to_cosine_hemisphere(u1, u2)
    if wo[2] <= 0.0 or wi[2] <= 0.0:
        return wi, _ZERO3, 0.0, False
    return wi, (color[0], color[1], color[2]), wi[2] * INV_PI, False
