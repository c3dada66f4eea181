"""Transparent: the path continues straight on (wi = -wo), tinted by `color`.

Cycles' Transparent BSDF; the integrator treats it as a pass-through, not a bounce.
"""

from renderer.kernels import kernel

_ZERO3 = (0.0, 0.0, 0.0)


@kernel
def transparent_eval(color, roughness, ior, wo, wi):
    """A delta lobe has no density to evaluate."""
    return _ZERO3, 0.0


@kernel
def transparent_sample(color, roughness, ior, wo, u1, u2, u3):
    """wi = -wo exactly, weight = color; pdf is the discrete probability of the branch (1)."""
    return (-wo[0], -wo[1], -wo[2]), (color[0], color[1], color[2]), 1.0, True
