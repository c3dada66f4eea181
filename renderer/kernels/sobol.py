"""Stratified sample positions within a pixel: the first two dimensions of Sobol's sequence,
digitally shifted per pixel.

Independent uniform positions leave a pixel on an edge (an emitter against a dark ceiling)
with the binomial noise of how many samples fell on each side; that noise is in the image
and, identically, in the albedo feature, so a denoiser keeps it as detail. Sobol's first
two dimensions form a (0, 2)-sequence: the first 2^m points of it put exactly one point in
each of the 2^m elementary intervals of any shape, so a pixel's coverage is nearly exact
at every power-of-two sample count (Cycles also stratifies its pixel samples). XOR with a
random 32-bit shift per pixel and seed keeps that property (a digital shift of a net is a
net) and makes pixels and seeds independent. A sample's position depends only on (seed,
pixel, sample index), like every other random number (renderer.kernels.rng).
"""

import numpy as np

from renderer.kernels import inline_kernel

from .rng import mix64

_SCRAMBLE = np.uint64(0xD1B54A32D192ED03)
_MASK32 = np.uint64(0xFFFFFFFF)
_S32 = np.uint64(32)
_INV_2_24 = 1.0 / 16777216.0


@inline_kernel
def pixel_shift(seed, pixel):
    """64 random bits per (seed, pixel): the two 32-bit digital shifts."""
    return mix64(mix64(np.uint64(seed) * _SCRAMBLE + np.uint64(3)) ^ (np.uint64(pixel) * _SCRAMBLE))


@inline_kernel
def sobol_2d(index, shift):
    """Point `index` of Sobol's first two dimensions (base-2 radical inverse, and the
    dimension whose direction numbers are v_k = v_(k-1) xor (v_(k-1) >> 1)), each XORed with
    a 32-bit half of `shift`. Returns two floats in [0, 1) with 24 bits, as rng.uniform."""
    x = 0
    y = 0
    v = 1 << 31
    i = index
    bit = 31
    while i > 0 and bit >= 0:
        if i & 1:
            x ^= 1 << bit
            y ^= v
        v ^= v >> 1
        i >>= 1
        bit -= 1
    x ^= int(shift & _MASK32)
    y ^= int((shift >> _S32) & _MASK32)
    return float(x >> 8) * _INV_2_24, float(y >> 8) * _INV_2_24
