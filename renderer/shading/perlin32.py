"""Cycles' signed Perlin noise (svm/noise.h snoise_1d..4d) bit for bit in float32, as its
AVX2 CPU kernel computes it, for Noise Texture's distortion (fractal.noise_texture).

Why: the distortion moves the point by this noise, and the colour's green and blue are the
fractal at that point plus an offset near 150, where a float32 step is 1.5e-5: a
displacement one float32 step off (from noise computed in float64, fractal.snoise) moved
the offset point a whole step there, 1e-5 .. 7e-5 in the colour. The fractal itself stays
in float64 (its round-off is 1e-6 of a value, and nothing amplifies it).

Operation for operation as the compiled kernel (GCC, -mfma; read from the disassembly of
Blender 5.0's AVX2 kernel and checked bit-equal against Cycles bakes at 4096 points per
dimension): fade is madd(t, madd(t, 6, -15), 10) then (t t)(t b), the scalar 1D one
((t t) t) b; every mix(a, b, t) = a + t (b - a) is fused to fma(t, b - a, a), 1D's with
its first gradient inside the fma; 3D and 4D interpolate in AVX order (4D along w first,
then x, y, z), gradient terms summed left to right. Cycles' SSE4.2 kernel (CPUs without
AVX2) rounds differently; this follows the AVX2 one.
"""

import numpy as np

from renderer.kernels.exact import exact_kernel, fma32

from .hash import _M, hash_uint, hash_uint2, hash_uint3, hash_uint4

_0 = np.float32(0.0)
_HALF = np.float32(0.5)
_1 = np.float32(1.0)
_2 = np.float32(2.0)
_6 = np.float32(6.0)
_M15 = np.float32(-15.0)
_10 = np.float32(10.0)
_PERIOD = np.float32(100000.0)
_FAR = np.float32(1000000.0)
# noise_scale1..4
_S1, _S2, _S3, _S4 = np.float32(0.25), np.float32(0.6616), np.float32(0.9820), np.float32(0.8344)


@exact_kernel
def _floorfrac(x):
    f = np.floor(x)
    return x - f, int(f)


@exact_kernel
def _fade(t):
    """The vector kernels' fade (2D, 3D, 4D)."""
    b = fma32(t, fma32(t, _6, _M15), _10)
    return (t * t) * (t * b)


@exact_kernel
def _mix(a, b, t):
    return fma32(t, b - a, a)


@exact_kernel
def _perlin_1d(x):
    fx, X = _floorfrac(x)
    h0 = hash_uint(X & _M) & 15
    h1 = hash_uint((X + 1) & _M) & 15
    c0 = np.float32(1 + (h0 & 7))
    c0 = -c0 if h0 & 8 else c0
    c1 = np.float32(1 + (h1 & 7))
    c1 = -c1 if h1 & 8 else c1
    u = ((fx * fx) * fx) * fma32(fx, fma32(fx, _6, _M15), _10)
    # mix(c0 fx, c1 (fx - 1), u), with c0 fx kept inside the two fmas.
    return fma32(fx, c0, u * fma32(-c0, fx, c1 * (fx - _1)))


@exact_kernel
def _grad2(h, x, y):
    h = h & 7
    u = x if h < 4 else y
    v = _2 * (y if h < 4 else x)
    return (-u if h & 1 else u) + (-v if h & 2 else v)


@exact_kernel
def _perlin_2d(x, y):
    fx, X = _floorfrac(x)
    fy, Y = _floorfrac(y)
    u, v = _fade(fx), _fade(fy)
    fx1, fy1 = fx - _1, fy - _1
    g00 = _grad2(hash_uint2(X & _M, Y & _M), fx, fy)
    g10 = _grad2(hash_uint2((X + 1) & _M, Y & _M), fx1, fy)
    g01 = _grad2(hash_uint2(X & _M, (Y + 1) & _M), fx, fy1)
    g11 = _grad2(hash_uint2((X + 1) & _M, (Y + 1) & _M), fx1, fy1)
    return _mix(_mix(g00, g10, u), _mix(g01, g11, u), v)


@exact_kernel
def _grad3(h, x, y, z):
    h = h & 15
    u = x if h < 8 else y
    vt = x if (h == 12 or h == 14) else z
    v = y if h < 4 else vt
    return (-u if h & 1 else u) + (-v if h & 2 else v)


@exact_kernel
def _along_x3(X, Y, Z, fx, fy, fz, u, k):
    """Corners (X, Y + j, Z + l) and (X + 1, Y + j, Z + l), k = j + 2 l, blended along x."""
    j, l = k & 1, k >> 1
    yj, zl = (Y + j) & _M, (Z + l) & _M
    fyj, fzl = fy - np.float32(j), fz - np.float32(l)
    return _mix(_grad3(hash_uint3(X & _M, yj, zl), fx, fyj, fzl),
                _grad3(hash_uint3((X + 1) & _M, yj, zl), fx - _1, fyj, fzl), u)


@exact_kernel
def _perlin_3d(x, y, z):
    fx, X = _floorfrac(x)
    fy, Y = _floorfrac(y)
    fz, Z = _floorfrac(z)
    u, v, t = _fade(fx), _fade(fy), _fade(fz)
    r = _0
    for l in range(2):  # (loop variables: literal arguments would compile a kernel per value)
        zl = _mix(_along_x3(X, Y, Z, fx, fy, fz, u, 2 * l), _along_x3(X, Y, Z, fx, fy, fz, u, 2 * l + 1), v)
        r = zl if l == 0 else _mix(r, zl, t)
    return r


@exact_kernel
def _grad4(h, x, y, z, w):
    h = h & 31
    u = x if h < 24 else y
    v = y if h < 16 else z
    s = z if h < 8 else w
    return ((-u if h & 1 else u) + (-v if h & 2 else v)) + (-s if h & 4 else s)


@exact_kernel
def _along_w4(X, Y, Z, W, fx, fy, fz, fw, s, c):
    """Corners (X + i, Y + j, Z + l, W) and (..., W + 1), c = i + 2 j + 4 l, blended along w."""
    i, j, l = c & 1, (c >> 1) & 1, c >> 2
    xi, yj, zl = (X + i) & _M, (Y + j) & _M, (Z + l) & _M
    fxi, fyj, fzl = fx - np.float32(i), fy - np.float32(j), fz - np.float32(l)
    return _mix(_grad4(hash_uint4(xi, yj, zl, W & _M), fxi, fyj, fzl, fw),
                _grad4(hash_uint4(xi, yj, zl, (W + 1) & _M), fxi, fyj, fzl, fw - _1), s)


@exact_kernel
def _perlin_4d(x, y, z, w):
    fx, X = _floorfrac(x)
    fy, Y = _floorfrac(y)
    fz, Z = _floorfrac(z)
    fw, W = _floorfrac(w)
    u, v, t, s = _fade(fx), _fade(fy), _fade(fz), _fade(fw)
    r = _0
    for l in range(2):
        # Along w, then x, for (j, l) = (0, l) and (1, l); then y; then z.
        y0 = _mix(_along_w4(X, Y, Z, W, fx, fy, fz, fw, s, 4 * l),
                  _along_w4(X, Y, Z, W, fx, fy, fz, fw, s, 4 * l + 1), u)
        y1 = _mix(_along_w4(X, Y, Z, W, fx, fy, fz, fw, s, 4 * l + 2),
                  _along_w4(X, Y, Z, W, fx, fy, fz, fw, s, 4 * l + 3), u)
        zl = _mix(y0, y1, v)
        r = zl if l == 0 else _mix(r, zl, t)
    return r


@exact_kernel
def _wrap(p):
    """fmod(p, 100000) + 0.5 beyond 1e6, in float32 (snoise_*d)."""
    return np.fmod(p, _PERIOD) + (_HALF if abs(p) >= _FAR else _0)


@exact_kernel
def snoise32(dim, x, y, z, w):
    """snoise_{dim}d at (x, y, z, w) (float32 coordinates), as a float32."""
    x, y, z, w = np.float32(x), np.float32(y), np.float32(z), np.float32(w)
    if dim == 1:
        return _S1 * _perlin_1d(_wrap(x))
    if dim == 2:
        return _S2 * _perlin_2d(_wrap(x), _wrap(y))
    if dim == 3:
        return _S3 * _perlin_3d(_wrap(x), _wrap(y), _wrap(z))
    return _S4 * _perlin_4d(_wrap(x), _wrap(y), _wrap(z), _wrap(w))


@exact_kernel
def displaced(dim, axis, p, noise, distortion):
    """Coordinate p moved by noise * distortion as noise_texture_{dim}d rounds it: fused in
    1D and for 2D's x (a scalar p += a * b), product then sum for 2D's y (GCC evaluates the
    make_float2 arguments right to left, y's noise first, and fuses only the last) and in
    3D and 4D (SSE vectors built from the products)."""
    p, d = np.float32(p), np.float32(distortion)
    if dim == 1 or (dim == 2 and axis == 0):
        return fma32(noise, d, p)
    return p + noise * d
