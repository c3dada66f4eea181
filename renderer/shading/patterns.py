"""Cycles' Wave, Magic and Brick textures (svm/wave.h, magic.h, brick.h).

The steep steps (Wave's phase of up to hundreds of radians, Brick's cell division) are
rounded to float32 where Cycles computes in float32, so that the same input gives the same
band and the same brick.

Output ranges (for interval bounds of programs): Wave in [0, 1] (every profile); Magic's
colour channels in [0.5 - 1/2, 0.5 + 1/2] = [0, 1] for distortion >= 1 (each term is a
sine scaled by the distortion, then divided by twice the distortion), unbounded as the
distortion nears 0 only through depth 0's sines: [0, 1] too; Magic Fac their average;
Brick Fac (mortar) in [0, 1], Brick colour within the hull of Color1, Color2 and Mortar.
"""

import math

import numpy as np

from renderer.kernels import inline_kernel, kernel

from .fractal import T_FBM, _f32, fractal

PI_2 = 1.5707963705062866  # M_PI_2_F: pi / 2 as float32
TWO_PI = 6.2831854820251465  # M_2PI_F: 2 pi as float32
WAVE_TYPES = ("BANDS", "RINGS")
BANDS_DIRECTIONS = ("X", "Y", "Z", "DIAGONAL")
RINGS_DIRECTIONS = ("X", "Y", "Z", "SPHERICAL")
WAVE_PROFILES = ("SIN", "SAW", "TRI")


@kernel
def wave(kind, direction, profile, x, y, z, distortion, detail, dscale, droughness, phase):
    """svm_wave at the scaled point (x, y, z); direction is the bands' or the rings' one."""
    # Cycles nudges the point off unit coordinates.
    x, y, z = _f32(_f32(x + 0.000001) * 0.999999), _f32(_f32(y + 0.000001) * 0.999999), \
        _f32(_f32(z + 0.000001) * 0.999999)
    if kind == 0:
        if direction == 3:
            n = _f32(_f32(_f32(x + y) + z) * 10.0)
        else:
            n = _f32((x if direction == 0 else y if direction == 1 else z) * 20.0)
    else:
        rx = 0.0 if direction == 0 else x
        ry = 0.0 if direction == 1 else y
        rz = 0.0 if direction == 2 else z
        n = _f32(math.sqrt(rx * rx + ry * ry + rz * rz) * 20.0)
    n = _f32(n + phase)
    if distortion != 0.0:
        f = fractal(3, T_FBM, _f32(x * dscale), _f32(y * dscale), _f32(z * dscale), 0.0, detail, droughness,
                    2.0, 0.0, 0.0, True)
        n = _f32(n + distortion * (f * 2.0 - 1.0))
    if profile == 0:
        return 0.5 + 0.5 * math.sin(_f32(n - PI_2))
    n = _f32(n / TWO_PI)
    if profile == 1:
        return n - math.floor(n)
    return abs(n - math.floor(n + 0.5)) * 2.0


@kernel
def magic(x, y, z, scale, depth, d):
    """svm_magic: the colour at point (x, y, z) (unscaled; the scale multiplies the phases)."""
    px, py, pz = _f32(np.fmod(x, TWO_PI)), _f32(np.fmod(y, TWO_PI)), _f32(np.fmod(z, TWO_PI))
    a = math.sin(_f32(_f32(_f32(_f32(px + py) + pz) * 5.0) * scale))
    b = math.cos(_f32(_f32(_f32(_f32(-px + py) - pz) * 5.0) * scale))
    c = -math.cos(_f32(_f32(_f32(_f32(-px - py) + pz) * 5.0) * scale))
    if depth > 0:
        a, b, c = a * d, b * d, c * d
        b = -math.cos(a - b + c) * d
        if depth > 1:
            a = math.cos(a - b - c) * d
        if depth > 2:
            c = math.sin(-a - b - c) * d
        if depth > 3:
            a = -math.cos(-a + b - c) * d
        if depth > 4:
            b = -math.sin(-a + b + c) * d
        if depth > 5:
            b = -math.cos(-a + b + c) * d
        if depth > 6:
            a = math.cos(a + b + c) * d
        if depth > 7:
            c = math.sin(a + b - c) * d
        if depth > 8:
            a = -math.cos(-a - b + c) * d
        if depth > 9:
            b = -math.sin(a - b + c) * d
    if d != 0.0:
        a, b, c = a / (2.0 * d), b / (2.0 * d), c / (2.0 * d)
    return (0.5 - a, 0.5 - b, 0.5 - c)


@inline_kernel
def _brick_noise(n):
    """brick_noise: Cycles' integer hash of a brick, in [0, 1)."""
    n = (n + 1013) & 0x7FFFFFFF
    n = (n >> 13) ^ n
    inner = ((n * n) & 0xFFFFFFFF) * 60493 + 19990303
    nn = (n * (inner & 0xFFFFFFFF) + 1376312589) & 0x7FFFFFFF
    return 0.5 * (float(nn) / 1073741824.0)


@kernel
def brick(x, y, mortar_size, mortar_smooth, bias, brick_width, row_height, offset_amount, offset_frequency,
          squash_amount, squash_frequency):
    """svm_brick at the scaled point: (tint, mortar)."""
    rownum = int(math.floor(_f32(y / row_height)))
    offset = 0.0
    if offset_frequency != 0 and squash_frequency != 0:
        if rownum % squash_frequency == 0:
            brick_width = _f32(brick_width * squash_amount)
        if rownum % offset_frequency == 0:
            offset = _f32(brick_width * offset_amount)
    xo = _f32(x + offset)
    bricknum = int(math.floor(_f32(xo / brick_width)))
    bx = _f32(xo - _f32(brick_width * bricknum))
    by = _f32(y - _f32(row_height * rownum))
    tint = min(max(_brick_noise(((rownum << 16) + (bricknum & 0xFFFF)) & 0xFFFFFFFF) + bias, 0.0), 1.0)
    min_dist = min(min(bx, by), min(brick_width - bx, row_height - by))
    if min_dist >= mortar_size:
        return tint, 0.0
    if mortar_smooth == 0.0:
        return tint, 1.0
    f = (1.0 - min_dist / mortar_size) / mortar_smooth
    if f <= 0.0:
        return tint, 0.0
    if f >= 1.0:
        return tint, 1.0
    return tint, 3.0 * f * f - 2.0 * f * f * f
