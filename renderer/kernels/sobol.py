"""Stratified random numbers: the first two dimensions of Sobol's sequence over a pixel's
samples, randomised (nested shuffle and digital shift) per pixel, half and pair.

Independent uniform positions leave a pixel on an edge (an emitter against a dark ceiling)
with the binomial noise of how many samples fell on each side; that noise is in the image
and, identically, in the albedo feature, so a denoiser keeps it as detail. Sobol's first
two dimensions form a (0, 2)-sequence: the first 2^m points of it put exactly one point in
each of the 2^m elementary intervals of any shape, so a pixel's coverage is nearly exact
at every power-of-two sample count (Cycles also stratifies its pixel samples). The
randomisation below keeps that property and makes pixels, seeds and the two halves of a
pixel's samples (kernels.rng.SAMPLE_HALVES) independent. A sample's position depends only
on (seed, pixel, sample index), like every other random number (renderer.kernels.rng).
"""

import numpy as np

from renderer.kernels import inline_kernel

from .hash64 import GOLDEN, mix64

_INV_2_24 = 1.0 / 16777216.0


# ------------------------------------------------------------------ stratified dimensions
# rng.uniform's dimensions below rng.STRATIFIED_DIMS. Dimensions go in pairs (dim + 1) // 2
# (so the first bounce's two-dimensional samples, at odd offsets in integrator.dims, are
# pairs); each pair is Sobol's first two dimensions over the pixel's samples, made
# independent of every other pair and pixel by
#   1. a random nested permutation of the sample index (Burley 2020, "Practical hash-based
#      Owen scrambling"): bit k of the permuted index is bit k flipped by a hash of the bits
#      above it, so the first 2^m samples map onto one aligned block of 2^m indices, and any
#      such block of Sobol's sequence is a (0, m, 2)-net; and
#   2. an independent random digital shift (XOR) of each coordinate, which keeps the net
#      and makes every single value uniform on [0, 1).
# The index has SAMPLE_BITS bits (rng.path_key packs them); the sample's higher bits go into
# the key's hash, so a pixel's samples beyond 2^16 start a fresh, independent sequence.

SAMPLE_BITS = 16


def _byte_tables() -> np.ndarray:
    """(2 x 2 x 256,) uint32, [table, byte, value] for a 16-bit index given bit-reversed (r):
    table 0, the reversal of each byte of r (so reverse16(r) is two lookups); table 1, each
    byte's XOR contribution to Sobol's dimension 1 (32-bit fixed point: direction numbers
    v_0 = 2^31, v_k = v_(k-1) xor (v_(k-1) >> 1)). Dimension 0, the radical inverse of the
    index, is r itself."""
    v, directions = 1 << 31, []
    for _ in range(16):
        directions.append(v)
        v ^= v >> 1
    tables = np.zeros((2, 2, 256), np.uint32)
    for byte in range(2):
        for b in range(256):
            for k in range(8):
                if b >> k & 1:
                    bit = 15 - (8 * byte + k)  # the index's bit that bit 8 byte + k of r is
                    tables[0, byte, b] |= 1 << bit
                    tables[1, byte, b] ^= directions[bit]
    return tables.reshape(-1)


_TABLES = _byte_tables()
_LOW16 = np.uint64(0xFFFF)
_LOW24 = np.uint64(0xFFFFFF)
_S8 = np.uint64(8)
_S16 = np.uint64(16)
_S40 = np.uint64(40)
_LK0 = np.uint64(0x6C50B47C)
_LK1 = np.uint64(0xB82F1E52)
_LK2 = np.uint64(0xC7AFE638)
_LK3 = np.uint64(0x8D22F6E6)


@inline_kernel
def _lookup(table, r):
    """The XOR of the two byte entries of 16-bit r in `table`."""
    return np.uint64(_TABLES[512 * table + int(r & np.uint64(255))]
                     ^ _TABLES[512 * table + 256 + int(r >> _S8)])


@inline_kernel
def reverse16(x):
    """The bits of a 16-bit integer in reverse order (rng.path_key stores the sample index so)."""
    return _lookup(0, x)


@inline_kernel
def nested_shuffle(r, seed):
    """A bijection of 16-bit integers, applied to a bit-reversed index r: Laine and Karras'
    hash, in which bit k of the result depends only on bits 0..k of r (additions and
    products by even constants carry only upwards), i.e. on the index's bits 15 - k..15."""
    x = r + seed
    x ^= x * _LK0
    x ^= x * _LK1
    x ^= x * _LK2
    x ^= x * _LK3
    return x & _LOW16


@inline_kernel
def stratified(key, dim):
    """Dimension `dim` of the path with `key` (rng.path_key: its low 16 bits are the sample
    index, bit-reversed): coordinate (dim + 1) % 2 of the randomised Sobol pair
    (dim + 1) // 2 at the path's sample. A float in [0, 1) with 24 bits, as rng.uniform."""
    h = mix64((key >> _S16) * GOLDEN + np.uint64((dim + 1) >> 1))
    r = nested_shuffle(key & _LOW16, h & _LOW16)
    if (dim + 1) & 1:
        return float((_lookup(1, r) >> _S8) ^ ((h >> _S40) & _LOW24)) * _INV_2_24
    return float((r << _S8) ^ ((h >> _S16) & _LOW24)) * _INV_2_24
