"""Counter-based random numbers keyed by (seed, pixel, sample index, dimension).

A path's random numbers depend only on those four integers, never on the batch it was
traced in or the process that traced it, so any sample range can be rendered anywhere
and merged. `path_key` packs a hash of (seed, pixel, sample // 2^16) with the sample's
low 16 bits once per path; `uniform(key, dim)` gives the path's number for one dimension:

* below STRATIFIED_DIMS (0 for now: see there), a stratified one (kernels.sobol.stratified): over a pixel's
  samples each such dimension is a randomised Sobol sequence, so the first 2^m samples of
  a pixel put exactly one value in each interval of width 2^-m (and pairs of dimensions
  one point in each elementary box of area 2^-m). The lens and the first surface's
  choices (which light, where on it, which lobe) then split a pixel's samples in nearly
  exact proportions:
  Cycles stratifies the same way, and a small bright light (a sun in an HDRI) shows the
  difference in noise most;
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
_INV_2_24 = 1.0 / 16777216.0

# Off for now (0: every dimension is hashed). Stratifying the first 16 dimensions (the
# lens, the first surface's light pick, light point and lobe choice) cut relMSE x spp of an
# HDRI scene with a small sun from 0.314 to 0.171, but the online error estimate
# (renderer.film) assumes independent samples and then overstates the error by more than
# 2x (tests/test_error_estimate.py), so the time limit by target error would stop late.
# Turn it on together with an estimate from independent sub-estimates (e.g. per-unit means).
STRATIFIED_DIMS = 0


@kernel
def path_key(seed, pixel, sample):
    """Key of one path: a hash of (seed, pixel, sample's high bits) above the sample's
    SAMPLE_BITS low bits, bit-reversed (the form kernels.sobol.stratified reads them in)."""
    s = np.uint64(sample)
    k = mix64(np.uint64(seed) * GOLDEN + np.uint64(1))
    k = mix64(k ^ (np.uint64(pixel) * GOLDEN))
    k = mix64(k ^ ((s >> _SAMPLE_SHIFT) * _M1 + GOLDEN))
    return (k & _HIGH) | reverse16(s & _LOW)


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
