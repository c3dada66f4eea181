"""Cycles' Noise Texture in every dimension and fractal type (svm/noise.h, fractal_noise.h,
noisetex.h): signed Perlin noise in 1D, 2D, 3D and 4D on Bob Jenkins' lookup3 lattice hash
(util/hash.h, bit-exact on uint32 kept in 64-bit integers masked to 32 bits), and fBM,
Multifractal, Hybrid Multifractal, Ridged Multifractal and Hetero Terrain over it.

A point of any dimension travels as four floats (x, y, z, w); 1D uses x only, 2D x and y,
3D x, y and z (the unused ones stay 0, so scaling them by the lacunarity changes nothing).

The distortion's noise is computed apart, bit-exact in float32 as Cycles rounds it
(perlin32.py): the colour's offset points would amplify its round-off.

Output ranges (for interval bounds of programs): snoise in [-1, 1] (Cycles' scale factors
keep Perlin noise there); normalized fBM in [0, 1]; un-normalized fBM in
[-S, S] with S = sum of the octave amplitudes (roughness^i, the fractional octave included);
Multifractal, Hybrid, Ridged and Hetero Terrain are unbounded in general (products and sums
of (noise + offset) terms), bounded only for given offset, gain and roughness.
"""

import math

import numpy as np

from renderer.kernels import inline_kernel, kernel

from .hash import _M, hash_uint, hash_uint2, hash_uint3, hash_uint4
from .perlin32 import displaced, snoise32

TYPES = ("MULTIFRACTAL", "FBM", "HYBRID_MULTIFRACTAL", "RIDGED_MULTIFRACTAL", "HETERO_TERRAIN")
T_MULTI, T_FBM, T_HYBRID, T_RIDGED, T_HETERO = range(5)
# noise_scale1..4: keeps each dimension's Perlin noise within [-1, 1].
_SCALE = (0.0, 0.2500, 0.6616, 0.9820, 0.8344)


# ------------------------------------------------------------------ the offsets (seeds)
def _py_final(a: int, b: int, c: int) -> int:
    def rot(x, k):
        return ((x << k) | (x >> (32 - k))) & _M
    for x, y, k in (("c", "b", 14), ("a", "c", 11), ("b", "a", 25), ("c", "b", 16), ("a", "c", 4),
                    ("b", "a", 14), ("c", "b", 24)):
        v = {"a": a, "b": b, "c": c}
        v[x] = ((v[x] ^ v[y]) - rot(v[y], k)) & _M
        a, b, c = v["a"], v["b"], v["c"]
    return c


def _bits(x: float) -> int:
    return int(np.array([x], np.float32).view(np.uint32)[0])


def _to_offset(h: int) -> float:
    """100 + uint_to_float_incl(h) * 100 in float32 (noisetex.h random_float*_offset)."""
    u = np.float32(h) * np.float32(1.0 / 0xFFFFFFFF)
    return float(np.float32(100.0) + np.float32(u) * np.float32(100.0))


def _offset_1d(seed: float) -> float:
    s = (0xDEADBEEF + (1 << 2) + 13) & _M
    return _to_offset(_py_final((s + _bits(seed)) & _M, s, s))


def _offset_nd(seed: float, k: float) -> float:
    s = (0xDEADBEEF + (2 << 2) + 13) & _M
    return _to_offset(_py_final((s + _bits(seed)) & _M, (s + _bits(k)) & _M, s))


# OFFSET_1D[seed]: random_float_offset; OFFSET_ND[seed, k]: random_float{2,3,4}_offset.
OFFSET_1D = np.array([_offset_1d(float(s)) for s in range(3)], np.float64)
OFFSET_ND = np.array([[_offset_nd(float(s), float(k)) for k in range(4)] for s in range(6)], np.float64)


# ------------------------------------------------------------------ Perlin noise
@inline_kernel
def _fade(t):
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@inline_kernel
def _wrap(p):
    """fmod(p, 100000) + 0.5 beyond 1e6 (Cycles repeats the noise to keep float precision)."""
    return np.fmod(p, 100000.0) + (0.5 if abs(p) >= 1000000.0 else 0.0)


@inline_kernel
def _perlin_1d(x):
    X = int(math.floor(x))
    fx = x - X
    h0 = hash_uint(X & _M) & 15
    h1 = hash_uint((X + 1) & _M) & 15
    g0 = (1.0 + (h0 & 7)) * (-1.0 if h0 & 8 else 1.0) * fx
    g1 = (1.0 + (h1 & 7)) * (-1.0 if h1 & 8 else 1.0) * (fx - 1.0)
    return g0 + _fade(fx) * (g1 - g0)


@inline_kernel
def _grad2(h, x, y):
    h = h & 7
    u = x if h < 4 else y
    v = 2.0 * (y if h < 4 else x)
    return (-u if h & 1 else u) + (-v if h & 2 else v)


@inline_kernel
def _perlin_2d(x, y):
    X, Y = int(math.floor(x)), int(math.floor(y))
    fx, fy = x - X, y - Y
    u, v = _fade(fx), _fade(fy)
    total = 0.0
    for k in range(4):  # bilinear blend of the four corners' gradients
        i, j = k & 1, k >> 1
        g = _grad2(hash_uint2((X + i) & _M, (Y + j) & _M), fx - i, fy - j)
        total += (u if i else 1.0 - u) * (v if j else 1.0 - v) * g
    return total


@inline_kernel
def _grad3(h, x, y, z):
    h = h & 15
    u = x if h < 8 else y
    vt = x if (h == 12 or h == 14) else z
    v = y if h < 4 else vt
    return (-u if h & 1 else u) + (-v if h & 2 else v)


@inline_kernel
def _perlin_3d(x, y, z):
    X, Y, Z = int(math.floor(x)), int(math.floor(y)), int(math.floor(z))
    fx, fy, fz = x - X, y - Y, z - Z
    u, v, t = _fade(fx), _fade(fy), _fade(fz)
    total = 0.0
    for k in range(8):  # trilinear blend of the eight corners' gradients
        i, j, l = k & 1, (k >> 1) & 1, k >> 2
        g = _grad3(hash_uint3((X + i) & _M, (Y + j) & _M, (Z + l) & _M), fx - i, fy - j, fz - l)
        total += (u if i else 1.0 - u) * (v if j else 1.0 - v) * (t if l else 1.0 - t) * g
    return total


@inline_kernel
def _grad4(h, x, y, z, w):
    h = h & 31
    u = x if h < 24 else y
    v = y if h < 16 else z
    s = z if h < 8 else w
    return (-u if h & 1 else u) + (-v if h & 2 else v) + (-s if h & 4 else s)


@kernel
def _perlin_4d(x, y, z, w):
    X, Y, Z, W = int(math.floor(x)), int(math.floor(y)), int(math.floor(z)), int(math.floor(w))
    fx, fy, fz, fw = x - X, y - Y, z - Z, w - W
    u, v, t, s = _fade(fx), _fade(fy), _fade(fz), _fade(fw)
    total = 0.0
    for k in range(16):  # quadrilinear blend of the sixteen corners' gradients
        i, j, l, m = k & 1, (k >> 1) & 1, (k >> 2) & 1, k >> 3
        g = _grad4(hash_uint4((X + i) & _M, (Y + j) & _M, (Z + l) & _M, (W + m) & _M),
                   fx - i, fy - j, fz - l, fw - m)
        total += ((u if i else 1.0 - u) * (v if j else 1.0 - v) * (t if l else 1.0 - t)
                  * (s if m else 1.0 - s) * g)
    return total


@kernel
def snoise(dim, x, y, z, w):
    """Signed noise in [-1, 1] of dimension dim at (x, y, z, w) (snoise_1d..4d), repeated
    every 100000 as Cycles does for float precision."""
    if dim == 1:
        return _SCALE[1] * _perlin_1d(_wrap(x))
    if dim == 2:
        return _SCALE[2] * _perlin_2d(_wrap(x), _wrap(y))
    if dim == 3:
        return _SCALE[3] * _perlin_3d(_wrap(x), _wrap(y), _wrap(z))
    return _SCALE[4] * _perlin_4d(_wrap(x), _wrap(y), _wrap(z), _wrap(w))


# ------------------------------------------------------------------ fractals
# Cycles moves the point in float32 (scaling by the lacunarity, adding seed offsets near
# 150, where a float32 step is 1.5e-5): rounding those coordinates as it does keeps the
# lattice inputs bit-equal, so high octaves and offset seeds match to round-off of the
# noise itself instead of amplified coordinate differences (measured: 2.2e-4 -> see tests).
@inline_kernel
def _f32(x):
    return float(np.float32(x))


@inline_kernel
def _scaled(x, y, z, w, f):
    return _f32(x * f), _f32(y * f), _f32(z * f), _f32(w * f)


@inline_kernel
def _fbm(dim, x, y, z, w, detail, roughness, lacunarity, normalize):
    fscale, amp, maxamp, total = 1.0, 1.0, 0.0, 0.0
    for _ in range(int(detail) + 1):
        sx, sy, sz, sw = _scaled(x, y, z, w, fscale)
        total += snoise(dim, sx, sy, sz, sw) * amp
        maxamp += amp
        amp *= roughness
        fscale = _f32(fscale * lacunarity)
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        sx, sy, sz, sw = _scaled(x, y, z, w, fscale)
        total2 = total + snoise(dim, sx, sy, sz, sw) * amp
        if normalize:
            a = 0.5 * total / maxamp + 0.5
            return a + rmd * ((0.5 * total2 / (maxamp + amp) + 0.5) - a)
        return total + rmd * (total2 - total)
    return 0.5 * total / maxamp + 0.5 if normalize else total


@inline_kernel
def _multi(dim, x, y, z, w, detail, roughness, lacunarity):
    value, pwr = 1.0, 1.0
    for _ in range(int(detail) + 1):
        value *= pwr * snoise(dim, x, y, z, w) + 1.0
        pwr *= roughness
        x, y, z, w = _scaled(x, y, z, w, lacunarity)
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        value *= rmd * pwr * snoise(dim, x, y, z, w) + 1.0
    return value


@inline_kernel
def _hetero(dim, x, y, z, w, detail, roughness, lacunarity, offset):
    pwr = roughness
    value = offset + snoise(dim, x, y, z, w)
    x, y, z, w = _scaled(x, y, z, w, lacunarity)
    for _ in range(1, int(detail) + 1):
        value += (snoise(dim, x, y, z, w) + offset) * pwr * value
        pwr *= roughness
        x, y, z, w = _scaled(x, y, z, w, lacunarity)
    rmd = detail - math.floor(detail)
    if rmd != 0.0:
        value += rmd * ((snoise(dim, x, y, z, w) + offset) * pwr * value)
    return value


@inline_kernel
def _hybrid(dim, x, y, z, w, detail, roughness, lacunarity, offset, gain):
    pwr, value, weight = 1.0, 0.0, 1.0
    i = 0
    while weight > 0.001 and i <= int(detail):
        weight = min(weight, 1.0)
        signal = (snoise(dim, x, y, z, w) + offset) * pwr
        pwr *= roughness
        value += weight * signal
        weight *= gain * signal
        x, y, z, w = _scaled(x, y, z, w, lacunarity)
        i += 1
    rmd = detail - math.floor(detail)
    if rmd != 0.0 and weight > 0.001:
        weight = min(weight, 1.0)
        value += rmd * weight * ((snoise(dim, x, y, z, w) + offset) * pwr)
    return value


@inline_kernel
def _ridged(dim, x, y, z, w, detail, roughness, lacunarity, offset, gain):
    pwr = roughness
    signal = offset - abs(snoise(dim, x, y, z, w))
    signal *= signal
    value = signal
    for _ in range(1, int(detail) + 1):
        x, y, z, w = _scaled(x, y, z, w, lacunarity)
        weight = min(max(signal * gain, 0.0), 1.0)
        signal = offset - abs(snoise(dim, x, y, z, w))
        signal = signal * signal * weight
        value += signal * pwr
        pwr *= roughness
    return value


@kernel
def fractal(dim, kind, x, y, z, w, detail, roughness, lacunarity, offset, gain, normalize):
    """noise_select: the fractal `kind` (an index into TYPES) of dimension dim's noise."""
    if kind == T_FBM:
        return _fbm(dim, x, y, z, w, detail, roughness, lacunarity, normalize)
    if kind == T_MULTI:
        return _multi(dim, x, y, z, w, detail, roughness, lacunarity)
    if kind == T_HYBRID:
        return _hybrid(dim, x, y, z, w, detail, roughness, lacunarity, offset, gain)
    if kind == T_RIDGED:
        return _ridged(dim, x, y, z, w, detail, roughness, lacunarity, offset, gain)
    return _hetero(dim, x, y, z, w, detail, roughness, lacunarity, offset)


@inline_kernel
def _seed(dim, seed, k):
    return OFFSET_1D[seed] if dim == 1 else OFFSET_ND[seed, k]


@inline_kernel
def _seeded(dim, seed, x, y, z, w):
    """The point moved by seed `seed`'s offset (random_float*_offset), in float32."""
    return (_f32(x + _seed(dim, seed, 0)), _f32(y + _seed(dim, seed, 1)), _f32(z + _seed(dim, seed, 2)),
            _f32(w + _seed(dim, seed, 3)))


@inline_kernel
def _distorted(dim, axis, x, y, z, w, distortion):
    """Coordinate `axis` of (x, y, z, w) moved by the noise at seed `axis`, in float32
    exactly as Cycles rounds it (perlin32: the colour's offset points amplify a float32
    step of it)."""
    sx, sy, sz, sw = _seeded(dim, axis, x, y, z, w)
    return float(displaced(dim, axis, (x, y, z, w)[axis], snoise32(dim, sx, sy, sz, sw), distortion))


@kernel
def noise_texture(dim, kind, x, y, z, w, detail, roughness, lacunarity, offset, gain, distortion,
                  normalize, color):
    """(value, colour) of the Noise Texture at the scaled point (svm_node_tex_noise): the
    distortion moves the point by noise at seeded offsets; the colour's green and blue are
    the same fractal at two more offsets (seeds dim and dim + 1), computed only when `color`
    (as Cycles, only for a linked Color output: they are two thirds of the work); else the
    colour is (value, 0, 0)."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = max(roughness, 0.0)
    x, y, z, w = _scaled(x, y, z, w, 1.0)
    if distortion != 0.0:
        # One noise per used component, at seeds 0 .. dim - 1, all at the undistorted point
        # (unused components stay 0). A loop: literal axes would compile _distorted four times.
        dx, dy, dz, dw = x, y, z, w
        for axis in range(dim):
            moved = _distorted(dim, axis, x, y, z, w, distortion)
            if axis == 0:
                dx = moved
            elif axis == 1:
                dy = moved
            elif axis == 2:
                dz = moved
            else:
                dw = moved
        x, y, z, w = dx, dy, dz, dw
    value = fractal(dim, kind, x, y, z, w, detail, roughness, lacunarity, offset, gain, normalize)
    if not color:
        return value, (value, 0.0, 0.0)
    gx, gy, gz, gw = _seeded(dim, dim, x, y, z, w)
    g = fractal(dim, kind, gx, gy, gz, gw, detail, roughness, lacunarity, offset, gain, normalize)
    bx, by, bz, bw = _seeded(dim, dim + 1, x, y, z, w)
    b = fractal(dim, kind, bx, by, bz, bw, detail, roughness, lacunarity, offset, gain, normalize)
    return value, (value, g, b)
