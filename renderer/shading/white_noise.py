"""Cycles' White Noise Texture (svm/white_noise.h): lookup3 hashes of the input's float32
bit patterns (util/hash.h hash_float*_to_float*), so equal inputs give Cycles' value
bit-exactly. Output range: Value and every Color channel in [0, 1] (1 included: the
hash is divided by 2^32 in float32, where 2^32 - 1 rounds up)."""

import math

import numpy as np

from renderer.kernels import inline_kernel, kernel

from .hash import hash_uint, hash_uint2, hash_uint3, hash_uint4


@inline_kernel
def float_bits(x):
    """The IEEE-754 bit pattern of x rounded to float32 (as __float_as_uint), as an int."""
    x = float(np.float32(x))
    sign = 0x80000000 if math.copysign(1.0, x) < 0.0 else 0
    a = abs(x)
    if a != a:
        return 0x7FC00000
    if a == 0.0:
        return sign
    if a > 3.4028234663852886e38:
        return sign | 0x7F800000
    m, e = math.frexp(a)  # a = m 2^e, m in [0.5, 1)
    biased = e + 126
    if biased <= 0:  # subnormal: a = mantissa 2^-149
        return sign | int(a * 2.0 ** 149)
    return sign | (biased << 23) | (int(m * 2.0 ** 24) - (1 << 23))


@inline_kernel
def _unit(h):
    """uint_to_float_incl: the hash as float32 times 2^-32."""
    return float(np.float32(h)) * (1.0 / 4294967296.0)


@inline_kernel
def hash1(a):
    return _unit(hash_uint(float_bits(a)))


@inline_kernel
def hash2(a, b):
    return _unit(hash_uint2(float_bits(a), float_bits(b)))


@inline_kernel
def hash3(a, b, c):
    return _unit(hash_uint3(float_bits(a), float_bits(b), float_bits(c)))


@inline_kernel
def hash4(a, b, c, d):
    return _unit(hash_uint4(float_bits(a), float_bits(b), float_bits(c), float_bits(d)))


@kernel
def white_noise(dim, x, y, z, w):
    """(value, colour) of the White Noise Texture of dimension dim at vector (x, y, z) and
    W (1D reads W alone; 2D x and y; 4D all four)."""
    if dim == 1:
        return hash1(w), (hash1(w), hash2(w, 1.0), hash2(w, 2.0))
    if dim == 2:
        return hash2(x, y), (hash2(x, y), hash3(x, y, 1.0), hash3(x, y, 2.0))
    if dim == 3:
        return hash3(x, y, z), (hash3(x, y, z), hash4(x, y, z, 1.0), hash4(x, y, z, 2.0))
    return hash4(x, y, z, w), (hash4(x, y, z, w), hash4(z, x, w, y), hash4(w, z, y, x))
