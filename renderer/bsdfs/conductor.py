"""Smooth conductor: a perfect mirror (Cycles' Glossy / Metallic BSDF at roughness 0).

The reflectance follows the lobe's Fresnel mode (renderer.bsdfs FRESNEL_*): a constant
`color` (Cycles' Glossy BSDF, which bakes its colour into the closure weight), or the F82-tint
curve at the mirror's angle, cos = wo.z (Principled metallic, Metallic BSDF).
"""

from renderer.bsdfs.fresnel import conductor_fresnel
from renderer.kernels import kernel

_ZERO3 = (0.0, 0.0, 0.0)


@kernel
def conductor_eval(color, roughness, ior, wo, wi):
    """A delta lobe has no density to evaluate."""
    return _ZERO3, 0.0


@kernel
def conductor_sample(color, roughness, ior, fresnel, tint, wo, u1, u2, u3):
    """Mirror direction; weight = the Fresnel reflectance. pdf is the discrete probability
    of the branch (1)."""
    wi = (-wo[0], -wo[1], wo[2])
    if wo[2] <= 0.0:
        return wi, _ZERO3, 0.0, True
    return wi, conductor_fresnel(fresnel, color, tint, wo[2]), 1.0, True
