"""Counter-based random numbers keyed by (seed, pixel, sample index, dimension).

A path's random numbers depend only on those four integers, never on the batch it was
traced in or the process that traced it, so any sample range can be rendered anywhere
and merged. `path_key` packs a hash of (seed, pixel, the sample's half, its index in the
half // 2^16) with the low 16 bits of that index once per path; `uniform(key, dim)` gives
the path's number for one dimension:

* below STRATIFIED_DIMS, a stratified one (kernels.sobol.stratified): over each half of a
  pixel's samples (even, odd: SAMPLE_HALVES) each such dimension is a randomised Sobol
  sequence, so the first 2^m samples of a half put exactly one value in each interval of
  width 2^-m (and pairs of dimensions one point in each elementary box of area 2^-m). The
  position in the pixel is such a pair too (integrator.camera_rays). The lens and the
  first surface's choices (which light, where on it, which lobe) then split a pixel's
  samples in nearly exact proportions: Cycles stratifies the same way, and a small bright
  light (a sun in an HDRI) shows the difference in noise most;
* above, and for every event in a medium (`hashed_uniform`), the splitmix64 hash of the
  key and the dimension.

Either way every value is uniform on [0, 1) and dimensions are independent of each other,
so estimates stay unbiased.
"""

import numpy as np

from renderer.kernels import inline_kernel, kernel

from .hash64 import GOLDEN, mix64
from .sobol import SAMPLE_BITS, reverse16, stratified

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_S40 = np.uint64(40)
_LOW = np.uint64((1 << SAMPLE_BITS) - 1)
_HIGH = ~_LOW
_SAMPLE_SHIFT = np.uint64(SAMPLE_BITS)
_H = np.uint64(1)  # the bit of the sample index that says its half
_INV_2_24 = 1.0 / 16777216.0

# The first bounce's light pick, light point and environment direction, the lens and a
# surface's lobe choice fall below this (integrator.dims); deeper events keep the cheaper
# hash: stratifying the second bounce's too (90) did not measurably lower the HDRI scene's
# noise (relMSE x spp 0.169 / 0.209 at 16 / 64 spp against 0.183 / 0.175 with 16, 8 runs).
STRATIFIED_DIMS = 16

# SAMPLE_HALVES: a pixel's even and odd samples are two independent stratified sequences
# (path_key hashes the sample's parity into the key and stratifies over its index in its
# half), so the means of the two halves are independent estimates of the pixel, and the
# difference between them estimates the error of the image (renderer.film.Film.
# rel_mse_estimate) without assuming that samples are independent, which stratified ones
# are not: the sum of squares overstated the error by more than 2x with them. Two
# sequences of n / 2 could stratify a little less than one of n; not measurably on the HDRI
# scene (relMSE x spp at 8 x 16 spp 0.183, against 0.186 with one sequence before).


@kernel
def path_key(seed, pixel, sample):
    """Key of one path: a hash of (seed, pixel, the sample's half, the high bits of its
    index in that half) above the low SAMPLE_BITS bits of that index, bit-reversed (the
    form kernels.sobol.stratified reads them in). See SAMPLE_HALVES."""
    s = np.uint64(sample)
    j = s >> _H  # the sample's index in its half
    block = ((j >> _SAMPLE_SHIFT) << _H) | (s & _H)
    k = mix64(np.uint64(seed) * GOLDEN + np.uint64(1))
    k = mix64(k ^ (np.uint64(pixel) * GOLDEN))
    k = mix64(k ^ (block * _M1 + GOLDEN))
    return (k & _HIGH) | reverse16(j & _LOW)


@inline_kernel
def uniform(key, dim):
    """Uniform float in [0, 1) for dimension `dim` of the path with `key`: stratified over
    the pixel's samples below STRATIFIED_DIMS, hashed above.

    24 bits, so the value is exactly representable in float32 and never rounds to 1.
    """
    if dim < STRATIFIED_DIMS:
        return stratified(key, dim)
    return hashed_uniform(key, dim)


@inline_kernel
def hashed_uniform(key, dim):
    """Uniform float in [0, 1) for dimension `dim`, never stratified: what media events
    draw, since their SIMD batch (integrator.nee_batch) must stay free of branches and the
    scalar media code must draw the same numbers as the batch."""
    h = mix64(key + (np.uint64(dim) + np.uint64(1)) * GOLDEN)
    return float(h >> _S40) * _INV_2_24
