"""Henyey-Greenstein phase function.

    p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^(3/2)),   cos = dot(d, wi)

with d the propagation direction, so g > 0 scatters forward. Sampling inverts the CDF of
cos exactly, hence pdf == value. Both formulas are written so that g = 0 is the uniform
sphere exactly and |g| up to 0.9999 stays finite (see the comments on each).
"""

import math

from renderer.kernels import fastmath as fm
from renderer.kernels import inline_kernel
from renderer.kernels.vecmath import INV_4PI, onb, to_world


@inline_kernel
def hg_denominator(g, cos_theta):
    """1 + g^2 - 2 g cos as a sum of two non-negative terms: (1 - g)^2 + 2 g (1 - cos) for
    g >= 0, (1 + g)^2 - 2 g (1 + cos) for g < 0. At the lobe's peak (|g| -> 1, cos -> sign g)
    both terms are small and are computed without the textbook form's cancellation."""
    if g >= 0.0:
        return (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - cos_theta)
    return (1.0 + g) * (1.0 + g) - 2.0 * g * (1.0 + cos_theta)


@inline_kernel
def hg_eval(g, cos_theta):
    """Phase function value (== pdf, per steradian) for cos_theta = dot(d, wi)."""
    denom = hg_denominator(g, cos_theta)
    return INV_4PI * (1.0 - g * g) / (denom * math.sqrt(denom))


@inline_kernel
def hg_sample_cos_s(g, u):
    """cos_theta with density 2 pi p(cos) on [-1, 1] by inverting the CDF, and
    s = sqrt(1 + g^2 - 2 g cos) (the pdf's denominator) at that cos.

    The textbook inverse cos = (1 + g^2 - s^2) / (2 g) with s = (1 - g^2) / (1 + g (2u - 1))
    divides a cancelling difference by g. Factoring the difference instead gives

        1 - cos = (1 - g)(1 - u)(1 - g + s) / a,   1 + cos = (1 + g) u (1 + g + s) / a,

    a = 1 + g (2u - 1): products of positive terms, no division by g, exact (cos = 2u - 1)
    at g = 0. The smaller of the two is used so that cos is accurate near both poles, and a
    is summed from positive terms so that it keeps its precision as |g| -> 1.
    """
    if g >= 0.0:
        a = (1.0 - g) + 2.0 * g * u
    else:
        a = (1.0 + g) - 2.0 * g * (1.0 - u)
    s = (1.0 - g * g) / a
    one_minus = (1.0 - g) * (1.0 - u) * (1.0 - g + s) / a
    if one_minus <= 1.0:
        c = 1.0 - one_minus
    else:
        c = (1.0 + g) * u * (1.0 + g + s) / a - 1.0
    return min(1.0, max(-1.0, c)), s


@inline_kernel
def hg_sample_cos(g, u):
    """cos_theta with density 2 pi p(cos) on [-1, 1] (see hg_sample_cos_s)."""
    return hg_sample_cos_s(g, u)[0]


@inline_kernel
def hg_sample(g, d, u1, u2):
    """Sample a scattered direction around the propagation direction d: (wi, pdf)."""
    sin_phi, cos_phi = fm.sincos(2.0 * math.pi * u2)
    return hg_direction(g, d, u1, sin_phi, cos_phi)


@inline_kernel
def hg_direction(g, d, u1, sin_phi, cos_phi):
    """hg_sample given the sine and cosine of the azimuth 2 pi u2 (so that SIMD loops can
    compute them with simdmath)."""
    c, s = hg_sample_cos_s(g, u1)
    sin_theta = math.sqrt(max(0.0, (1.0 - c) * (1.0 + c)))
    tx, ty = onb(d)
    wi = to_world((sin_theta * cos_phi, sin_theta * sin_phi, c), tx, ty, d)
    # s^2 = 1 + g^2 - 2 g cos by construction, so the pdf needs no cancelling difference.
    return wi, INV_4PI * (1.0 - g * g) / (s * s * s)
