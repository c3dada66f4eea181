"""Smooth conductor: a perfect mirror tinted by `color` (Cycles' Glossy BSDF at roughness 0).

Cycles' Glossy BSDF uses a constant Fresnel equal to its colour, so the mirror reflects
`color` at every angle.
"""

from numba import njit

_ZERO3 = (0.0, 0.0, 0.0)


@njit(cache=True, error_model="numpy", _nrt=False)
def conductor_eval(color, roughness, ior, wo, wi):
    """A delta lobe has no density to evaluate."""
    return _ZERO3, 0.0


@njit(cache=True, error_model="numpy", _nrt=False)
def conductor_sample(color, roughness, ior, wo, u1, u2, u3):
    """Mirror direction; weight = color. pdf is the discrete probability of the branch (1)."""
    wi = (-wo[0], -wo[1], wo[2])
    if wo[2] <= 0.0:
        return wi, _ZERO3, 0.0, True
    return wi, (color[0], color[1], color[2]), 1.0, True
