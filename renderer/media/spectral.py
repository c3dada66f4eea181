"""Spectral MIS: which colour channel drives distance sampling in a chromatic medium.

Each of the three channels is a sampling technique (exponential with that channel's
extinction); a technique c is picked with probability p_c and the sample is weighted by the
balance heuristic, i.e. divided by the mixture pdf sum_c p_c pdf_c. p_c proportional to the
path throughput (the default) spends samples where the colour still matters; uniform 1/3
is the paper's choice. Either way every channel with p_c > 0 stays unbiased and its weight
is bounded by albedo / p_c.
"""

import math

from renderer.kernels import inline_kernel

THIRD = 1.0 / 3.0


@inline_kernel
def channel_probabilities(throughput, uniform_channel):
    """(p0, p1, p2): proportional to throughput, or 1/3 each when asked or when the
    throughput is zero / not finite."""
    if not uniform_channel:
        a = max(throughput[0], 0.0)
        b = max(throughput[1], 0.0)
        c = max(throughput[2], 0.0)
        s = a + b + c
        if s > 0.0 and math.isfinite(s):
            return (a / s, b / s, c / s)
    return (THIRD, THIRD, THIRD)


@inline_kernel
def pick_channel(p, u):
    """Channel c with probability p[c]; never a channel with p[c] == 0."""
    if u < p[0]:
        return 0
    if u < p[0] + p[1] or p[2] == 0.0:
        return 1 if p[1] > 0.0 else 0
    return 2
