"""Spectral MIS: which colour channel drives distance sampling in a chromatic medium.

Each of the three channels is a sampling technique (exponential with that channel's
extinction); a technique c is picked with probability p_c and the sample is weighted by the
balance heuristic, i.e. divided by the mixture pdf sum_c p_c pdf_c. p_c proportional to the
path throughput (the default) spends samples where the colour still matters; uniform 1/3
is the paper's choice. Either way every channel with p_c > 0 stays unbiased and its weight
is bounded by albedo / p_c.

channel_probabilities_simd and channel_value are the branch-free forms for the SIMD batch
of homogeneous segments (renderer.integrator.nee_batch); pick_channel is branch-free as it
is (LLVM turns its returns into selects).
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


@inline_kernel
def channel_probabilities_simd(throughput, uniform_channel):
    """channel_probabilities without its early returns, for loops LLVM vectorises."""
    a = max(throughput[0], 0.0)
    b = max(throughput[1], 0.0)
    c = max(throughput[2], 0.0)
    total = a + b + c
    by_throughput = not uniform_channel and total > 0.0 and total < math.inf
    inv = 1.0 / total if by_throughput else 1.0
    return (a * inv if by_throughput else THIRD, b * inv if by_throughput else THIRD,
            c * inv if by_throughput else THIRD)


@inline_kernel
def channel_value(c, v0, v1, v2):
    """Channel c of (v0, v1, v2) by selects (a tuple indexed at run time would not
    vectorise)."""
    return v0 if c == 0 else (v1 if c == 1 else v2)
