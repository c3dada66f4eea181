"""Bob Jenkins' lookup3 hashes of 1 to 4 uint32 keys as Cycles computes them (util/hash.h
hash_uint..hash_uint4), bit-exact on uint32 values kept in 64-bit integers masked to 32 bits:
the lattice hash of Perlin noise (fractal.py) and White Noise's hash (white_noise.py)."""

from renderer.kernels import inline_kernel

_M = 0xFFFFFFFF


@inline_kernel
def _rot(x, k):
    return ((x << k) | (x >> (32 - k))) & _M


@inline_kernel
def _final(a, b, c):
    c = ((c ^ b) - _rot(b, 14)) & _M
    a = ((a ^ c) - _rot(c, 11)) & _M
    b = ((b ^ a) - _rot(a, 25)) & _M
    c = ((c ^ b) - _rot(b, 16)) & _M
    a = ((a ^ c) - _rot(c, 4)) & _M
    b = ((b ^ a) - _rot(a, 14)) & _M
    c = ((c ^ b) - _rot(b, 24)) & _M
    return a, b, c


@inline_kernel
def hash_uint(kx):
    a = b = c = (0xDEADBEEF + (1 << 2) + 13) & _M
    a = (a + kx) & _M
    return _final(a, b, c)[2]


@inline_kernel
def hash_uint2(kx, ky):
    a = b = c = (0xDEADBEEF + (2 << 2) + 13) & _M
    b = (b + ky) & _M
    a = (a + kx) & _M
    return _final(a, b, c)[2]


@inline_kernel
def hash_uint3(kx, ky, kz):
    a = b = c = (0xDEADBEEF + (3 << 2) + 13) & _M
    c = (c + kz) & _M
    b = (b + ky) & _M
    a = (a + kx) & _M
    return _final(a, b, c)[2]


@inline_kernel
def hash_uint4(kx, ky, kz, kw):
    a = b = c = (0xDEADBEEF + (4 << 2) + 13) & _M
    a = (a + kx) & _M
    b = (b + ky) & _M
    c = (c + kz) & _M
    # lookup3's mix(a, b, c), then the fourth key, then final.
    a = ((a - c) & _M) ^ _rot(c, 4)
    c = (c + b) & _M
    b = ((b - a) & _M) ^ _rot(a, 6)
    a = (a + c) & _M
    c = ((c - b) & _M) ^ _rot(b, 8)
    b = (b + a) & _M
    a = ((a - c) & _M) ^ _rot(c, 16)
    c = (c + b) & _M
    b = ((b - a) & _M) ^ _rot(a, 19)
    a = (a + c) & _M
    c = ((c - b) & _M) ^ _rot(b, 4)
    b = (b + a) & _M
    a = (a + kw) & _M
    return _final(a, b, c)[2]
