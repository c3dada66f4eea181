"""Cycles' Perlin noise and fBM (svm/noise.h, fractal_noise.h, noisetex.h), 3D: the Noise
Texture's default (3D, fBM). The lattice hash is Bob Jenkins' lookup3 final mix on uint32
(util/hash.h) computed bit-exactly in 64-bit integers masked to 32 bits."""

import math

import numpy as np

from renderer.kernels import inline_kernel

_M = 0xFFFFFFFF


@inline_kernel
def _rot(x, k):
    return ((x << k) | (x >> (32 - k))) & _M


@inline_kernel
def hash_uint3(kx, ky, kz):
    a = b = c = (0xDEADBEEF + (3 << 2) + 13) & _M
    c = (c + kz) & _M
    b = (b + ky) & _M
    a = (a + kx) & _M
    c ^= b
    c = (c - _rot(b, 14)) & _M
    a ^= c
    a = (a - _rot(c, 11)) & _M
    b ^= a
    b = (b - _rot(a, 25)) & _M
    c ^= b
    c = (c - _rot(b, 16)) & _M
    a ^= c
    a = (a - _rot(c, 4)) & _M
    b ^= a
    b = (b - _rot(a, 14)) & _M
    c ^= b
    c = (c - _rot(b, 24)) & _M
    return c


def _hash_uint2(kx: int, ky: int) -> int:
    """Python twin of util/hash.h hash_uint2 (for the constant offsets below)."""
    def rot(x, k):
        return ((x << k) | (x >> (32 - k))) & _M
    a = b = c = (0xDEADBEEF + (2 << 2) + 13) & _M
    b = (b + ky) & _M
    a = (a + kx) & _M
    for x, y, k in (("c", "b", 14), ("a", "c", 11), ("b", "a", 25), ("c", "b", 16), ("a", "c", 4),
                    ("b", "a", 14), ("c", "b", 24)):
        v = {"a": a, "b": b, "c": c}
        v[x] = ((v[x] ^ v[y]) - rot(v[y], k)) & _M
        a, b, c = v["a"], v["b"], v["c"]
    return c


def _float_bits(x: float) -> int:
    return int(np.array([x], np.float32).view(np.uint32)[0])


def _offset(seed: float, k: float) -> float:
    """100 + hash_float2_to_float((seed, k)) * 100 in float32 (noisetex.h random_float3_offset)."""
    h = np.float32(_hash_uint2(_float_bits(seed), _float_bits(k))) * np.float32(1.0 / 0xFFFFFFFF)
    return float(np.float32(100.0) + np.float32(h) * np.float32(100.0))


OFFSETS = tuple(tuple(_offset(float(s), float(k)) for k in range(3)) for s in range(5))


@inline_kernel
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@inline_kernel
def _grad3(h, x, y, z):
    h = h & 15
    u = x if h < 8 else y
    vt = x if (h == 12 or h == 14) else z
    v = y if h < 4 else vt
    return (-u if h & 1 else u) + (-v if h & 2 else v)


@inline_kernel
def _corner(X, Y, Z, fx, fy, fz):
    return _grad3(hash_uint3(X & _M, Y & _M, Z & _M), fx, fy, fz)


@inline_kernel
def perlin_3d(x, y, z):
    X, Y, Z = int(math.floor(x)), int(math.floor(y)), int(math.floor(z))
    fx, fy, fz = x - X, y - Y, z - Z
    u, v, w = _fade(fx), _fade(fy), _fade(fz)
    x1, y1, z1 = 1.0 - u, 1.0 - v, 1.0 - w
    v0 = _corner(X, Y, Z, fx, fy, fz)
    v1 = _corner(X + 1, Y, Z, fx - 1.0, fy, fz)
    v2 = _corner(X, Y + 1, Z, fx, fy - 1.0, fz)
    v3 = _corner(X + 1, Y + 1, Z, fx - 1.0, fy - 1.0, fz)
    v4 = _corner(X, Y, Z + 1, fx, fy, fz - 1.0)
    v5 = _corner(X + 1, Y, Z + 1, fx - 1.0, fy, fz - 1.0)
    v6 = _corner(X, Y + 1, Z + 1, fx, fy - 1.0, fz - 1.0)
    v7 = _corner(X + 1, Y + 1, Z + 1, fx - 1.0, fy - 1.0, fz - 1.0)
    return (z1 * (y1 * (v0 * x1 + v1 * u) + v * (v2 * x1 + v3 * u))
            + w * (y1 * (v4 * x1 + v5 * u) + v * (v6 * x1 + v7 * u)))


@inline_kernel
def _wrap(p):
    """fmod(p, 100000) + 0.5 beyond 1e6 (Cycles repeats the noise to keep float precision)."""
    return np.fmod(p, 100000.0) + (0.5 if abs(p) >= 1000000.0 else 0.0)


@inline_kernel
def snoise_3d(x, y, z):
    return 0.9820 * perlin_3d(_wrap(x), _wrap(y), _wrap(z))


@inline_kernel
def fbm_3d(x, y, z, detail, roughness, lacunarity, normalize):
    fscale = 1.0
    amp = 1.0
    maxamp = 0.0
    total = 0.0
    for _ in range(int(detail) + 1):
        total += snoise_3d(fscale * x, fscale * y, fscale * z) * amp
        maxamp += amp
        amp *= roughness
        fscale *= lacunarity
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        total2 = total + snoise_3d(fscale * x, fscale * y, fscale * z) * amp
        if normalize:
            a = 0.5 * total / maxamp + 0.5
            return a + rmd * ((0.5 * total2 / (maxamp + amp) + 0.5) - a)
        return total + rmd * (total2 - total)
    return 0.5 * total / maxamp + 0.5 if normalize else total


@inline_kernel
def noise_texture_3d(x, y, z, detail, roughness, lacunarity, distortion, normalize):
    """(value, colour) of the Noise Texture (3D, fBM) at the scaled point (x, y, z)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = max(roughness, 0.0)
    if distortion != 0.0:
        o0, o1, o2 = OFFSETS[0], OFFSETS[1], OFFSETS[2]
        dx = snoise_3d(x + o0[0], y + o0[1], z + o0[2]) * distortion
        dy = snoise_3d(x + o1[0], y + o1[1], z + o1[2]) * distortion
        dz = snoise_3d(x + o2[0], y + o2[1], z + o2[2]) * distortion
        x, y, z = x + dx, y + dy, z + dz
    value = fbm_3d(x, y, z, detail, roughness, lacunarity, normalize)
    o3, o4 = OFFSETS[3], OFFSETS[4]
    g = fbm_3d(x + o3[0], y + o3[1], z + o3[2], detail, roughness, lacunarity, normalize)
    b = fbm_3d(x + o4[0], y + o4[1], z + o4[2], detail, roughness, lacunarity, normalize)
    return value, (value, g, b)
