"""One octave of Cycles' Voronoi Texture (svm/voronoi.h) in 1D to 4D: the cell hashes,
the distance metrics and the five features on the unit lattice.

A point of any dimension travels as a 4-tuple (x, y, z, w) with the unused components 0
(1D uses x), so one implementation serves every dimension: an unused component adds 0 to
every metric. Cells are visited in Cycles' order (x fastest), which decides ties.

Cell points: 2D to 4D hash the integer cell with PCG (util/hash.h hash_pcg{2,3,4}d_i on
wrapping int32, scaled by 2^-31 in float32); 1D hashes the cell's float bits (lookup3).
Every hash is in [0, 1].
"""

import math

import numpy as np

from renderer.kernels import inline_kernel

from .white_noise import hash1, hash2

EUCLIDEAN, MANHATTAN, CHEBYCHEV, MINKOWSKI = range(4)
F1, F2, SMOOTH_F1, DISTANCE_TO_EDGE, N_SPHERE_RADIUS = range(5)
FEATURES = ("F1", "F2", "SMOOTH_F1", "DISTANCE_TO_EDGE", "N_SPHERE_RADIUS")
METRICS = ("EUCLIDEAN", "MANHATTAN", "CHEBYCHEV", "MINKOWSKI")
BIG = 3.4028234663852886e38  # FLT_MAX


@inline_kernel
def _i32(v):
    """v wrapped to a signed 32-bit integer (C's int overflow on the GPU and CPU alike)."""
    return ((v + 0x80000000) & 0xFFFFFFFF) - 0x80000000


@inline_kernel
def _unit31(h):
    return float(np.float32(h)) * (1.0 / 2147483648.0)


@inline_kernel
def pcg2d(x, y):
    x, y = _i32(x * 1664525 + 1013904223), _i32(y * 1664525 + 1013904223)
    x = _i32(x + y * 1664525)
    y = _i32(y + x * 1664525)
    x, y = x ^ (x >> 16), y ^ (y >> 16)
    x = _i32(x + y * 1664525)
    y = _i32(y + x * 1664525)
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF


@inline_kernel
def pcg3d(x, y, z):
    x, y, z = (_i32(x * 1664525 + 1013904223), _i32(y * 1664525 + 1013904223),
               _i32(z * 1664525 + 1013904223))
    x = _i32(x + y * z)
    y = _i32(y + z * x)
    z = _i32(z + x * y)
    x, y, z = x ^ (x >> 16), y ^ (y >> 16), z ^ (z >> 16)
    x = _i32(x + y * z)
    y = _i32(y + z * x)
    z = _i32(z + x * y)
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF


@inline_kernel
def pcg4d(x, y, z, w):
    x, y, z, w = (_i32(x * 1664525 + 1013904223), _i32(y * 1664525 + 1013904223),
                  _i32(z * 1664525 + 1013904223), _i32(w * 1664525 + 1013904223))
    x = _i32(x + y * w)
    y = _i32(y + z * x)
    z = _i32(z + x * y)
    w = _i32(w + y * z)
    x, y, z, w = x ^ (x >> 16), y ^ (y >> 16), z ^ (z >> 16), w ^ (w >> 16)
    x = _i32(x + y * w)
    y = _i32(y + z * x)
    z = _i32(z + x * y)
    w = _i32(w + y * z)
    return x & 0x7FFFFFFF, y & 0x7FFFFFFF, z & 0x7FFFFFFF, w & 0x7FFFFFFF


@inline_kernel
def cell_offset(dim, c):
    """The feature point's offset in cell c (integers, 4-tuple): hash_int*_to_float*."""
    if dim == 1:
        return (hash1(float(c[0])), 0.0, 0.0, 0.0)
    if dim == 2:
        h = pcg2d(c[0], c[1])
        return (_unit31(h[0]), _unit31(h[1]), 0.0, 0.0)
    if dim == 3:
        h3 = pcg3d(c[0], c[1], c[2])
        return (_unit31(h3[0]), _unit31(h3[1]), _unit31(h3[2]), 0.0)
    h4 = pcg4d(c[0], c[1], c[2], c[3])
    return (_unit31(h4[0]), _unit31(h4[1]), _unit31(h4[2]), _unit31(h4[3]))


@inline_kernel
def cell_color(dim, c):
    """The cell's colour: hash_float_to_float3 (1D), hash_int3_to_float3 (2D with z = 0, 3D),
    the first three of hash_int4_to_float4 (4D)."""
    if dim == 1:
        f = float(c[0])
        return (hash1(f), hash2(f, 1.0), hash2(f, 2.0))
    if dim == 4:
        h4 = pcg4d(c[0], c[1], c[2], c[3])
        return (_unit31(h4[0]), _unit31(h4[1]), _unit31(h4[2]))
    h = pcg3d(c[0], c[1], c[2] if dim == 3 else 0)
    return (_unit31(h[0]), _unit31(h[1]), _unit31(h[2]))


@inline_kernel
def distance(a, b, metric, exponent):
    d0, d1, d2, d3 = abs(a[0] - b[0]), abs(a[1] - b[1]), abs(a[2] - b[2]), abs(a[3] - b[3])
    if metric == EUCLIDEAN:
        return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3)
    if metric == MANHATTAN:
        return d0 + d1 + d2 + d3
    if metric == CHEBYCHEV:
        return max(max(d0, d1), max(d2, d3))
    return (d0 ** exponent + d1 ** exponent + d2 ** exponent + d3 ** exponent) ** (1.0 / exponent)


@inline_kernel
def distance_bound(a, b, metric, exponent):
    """A cheaper distance that orders points as `distance` does (no root)."""
    if metric == EUCLIDEAN:
        d0, d1, d2, d3 = a[0] - b[0], a[1] - b[1], a[2] - b[2], a[3] - b[3]
        return d0 * d0 + d1 * d1 + d2 * d2 + d3 * d3
    if metric == MINKOWSKI:
        return (abs(a[0] - b[0]) ** exponent + abs(a[1] - b[1]) ** exponent + abs(a[2] - b[2]) ** exponent
                + abs(a[3] - b[3]) ** exponent)
    return distance(a, b, metric, exponent)


@inline_kernel
def _offset(dim, k, reach):
    """The k-th of the (2 reach + 1)^dim cell offsets, x fastest (unused components 0)."""
    n = 2 * reach + 1
    i = k % n - reach
    j = (k // n) % n - reach if dim > 1 else 0
    l = (k // (n * n)) % n - reach if dim > 2 else 0  # noqa: E741
    u = (k // (n * n * n)) % n - reach if dim > 3 else 0
    return (i, j, l, u)


@inline_kernel
def _add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3])


@inline_kernel
def _point(dim, cell, off, randomness):
    """The feature point of cell `cell + off`, relative to cell `cell`."""
    h = cell_offset(dim, _add(cell, off))
    return (off[0] + h[0] * randomness, off[1] + h[1] * randomness, off[2] + h[2] * randomness,
            off[3] + h[3] * randomness)


@inline_kernel
def _split(dim, p):
    """(integer cell, position within it) of point p."""
    c = (int(math.floor(p[0])), int(math.floor(p[1])) if dim > 1 else 0,
         int(math.floor(p[2])) if dim > 2 else 0, int(math.floor(p[3])) if dim > 3 else 0)
    return c, (p[0] - c[0], p[1] - c[1], p[2] - c[2], p[3] - c[3])


@inline_kernel
def _position(cell, q):
    return (cell[0] + q[0], cell[1] + q[1], cell[2] + q[2], cell[3] + q[3])


@inline_kernel
def f1_f2(dim, p, feature, metric, exponent, randomness):
    """(distance, colour, position) of the nearest (F1) or second nearest (F2) point."""
    cell, local = _split(dim, p)
    d1 = d2 = BIG
    o1 = o2 = (0, 0, 0, 0)
    q1 = q2 = (0.0, 0.0, 0.0, 0.0)
    for k in range(3 ** dim):
        off = _offset(dim, k, 1)
        q = _point(dim, cell, off, randomness)
        if feature == F1:  # Cycles' F1 orders by the bound (1D: the plain distance)
            d = distance_bound(q, local, metric, exponent)
        else:
            d = distance(q, local, metric, exponent)
        if d < d1:
            d2, o2, q2 = d1, o1, q1
            d1, o1, q1 = d, off, q
        elif d < d2:
            d2, o2, q2 = d, off, q
    if feature == F1:
        return distance(q1, local, metric, exponent), cell_color(dim, _add(cell, o1)), _position(cell, q1)
    return d2, cell_color(dim, _add(cell, o2)), _position(cell, q2)


@inline_kernel
def _smoothstep01(x):
    if x < 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    return (3.0 - 2.0 * x) * (x * x)


@inline_kernel
def smooth_f1(dim, p, metric, exponent, randomness, smoothness):
    """(distance, colour, position) of Smooth F1 over the 5^dim nearest cells."""
    cell, local = _split(dim, p)
    sd = 0.0
    col = (0.0, 0.0, 0.0)
    pos = (0.0, 0.0, 0.0, 0.0)
    h = -1.0
    for k in range(5 ** dim):
        off = _offset(dim, k, 2)
        q = _point(dim, cell, off, randomness)
        d = distance(q, local, metric, exponent)
        h = 1.0 if h == -1.0 else _smoothstep01(0.5 + 0.5 * (sd - d) / smoothness)
        corr = smoothness * h * (1.0 - h)
        sd = sd + h * (d - sd) - corr
        corr /= 1.0 + 3.0 * smoothness
        c = cell_color(dim, _add(cell, off))
        col = (col[0] + h * (c[0] - col[0]) - corr, col[1] + h * (c[1] - col[1]) - corr,
               col[2] + h * (c[2] - col[2]) - corr)
        pos = (pos[0] + h * (q[0] - pos[0]) - corr, pos[1] + h * (q[1] - pos[1]) - corr,
               pos[2] + h * (q[2] - pos[2]) - corr, pos[3] + h * (q[3] - pos[3]) - corr)
    # Unused components exist only here: keep them 0 (their correction terms are not Cycles').
    pos = (pos[0], pos[1] if dim > 1 else 0.0, pos[2] if dim > 2 else 0.0, pos[3] if dim > 3 else 0.0)
    return sd, col, _position(cell, pos)


@inline_kernel
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]


@inline_kernel
def distance_to_edge(dim, p, randomness):
    """Distance to the nearest Voronoi edge (Euclidean, as Cycles for every metric)."""
    cell, local = _split(dim, p)
    if dim == 1:
        mid = hash1(float(cell[0])) * randomness
        left = -1.0 + hash1(float(cell[0] - 1)) * randomness
        right = 1.0 + hash1(float(cell[0] + 1)) * randomness
        return min(abs((mid + left) / 2.0 - local[0]), abs((mid + right) / 2.0 - local[0]))
    closest = (0.0, 0.0, 0.0, 0.0)
    best = BIG
    for k in range(3 ** dim):
        q = _point(dim, cell, _offset(dim, k, 1), randomness)
        v = (q[0] - local[0], q[1] - local[1], q[2] - local[2], q[3] - local[3])
        if _dot(v, v) < best:
            best, closest = _dot(v, v), v
    best = BIG
    for k in range(3 ** dim):
        q = _point(dim, cell, _offset(dim, k, 1), randomness)
        v = (q[0] - local[0], q[1] - local[1], q[2] - local[2], q[3] - local[3])
        e = (v[0] - closest[0], v[1] - closest[1], v[2] - closest[2], v[3] - closest[3])
        ee = _dot(e, e)
        if ee > 0.0001:
            mid = ((closest[0] + v[0]) / 2.0, (closest[1] + v[1]) / 2.0, (closest[2] + v[2]) / 2.0,
                   (closest[3] + v[3]) / 2.0)
            best = min(best, _dot(mid, e) / math.sqrt(ee))
    return best


@inline_kernel
def n_sphere_radius(dim, p, randomness):
    """Half the distance from the nearest feature point to its own nearest neighbour."""
    cell, local = _split(dim, p)
    closest = (0.0, 0.0, 0.0, 0.0)
    closest_off = (0, 0, 0, 0)
    best = BIG
    for k in range(3 ** dim):
        off = _offset(dim, k, 1)
        q = _point(dim, cell, off, randomness)
        d = distance_bound(q, local, EUCLIDEAN, 1.0)
        if d < best:
            best, closest, closest_off = d, q, off
    best = BIG
    other = (0.0, 0.0, 0.0, 0.0)
    centre = (3 ** dim) // 2  # the offset (0, ..., 0) itself
    for k in range(3 ** dim):
        if k == centre:
            continue
        q = _point(dim, cell, _add(_offset(dim, k, 1), closest_off), randomness)
        d = distance_bound(closest, q, EUCLIDEAN, 1.0)
        if d < best:
            best, other = d, q
    return distance(other, closest, EUCLIDEAN, 1.0) / 2.0
