"""Cycles' Voronoi Texture node (svm/voronoi.h svm_node_tex_voronoi): the fractal sum of
voronoi_cells' octaves (Blender 4's detail, roughness, lacunarity and normalize) for F1,
F2, Smooth F1 and Distance to Edge, and N-Sphere Radius, in 1D to 4D and every metric.

Output ranges (for interval bounds of programs): Color channels in [0, 1] for F1 and F2
(hashes; fractal sums are normalized by the amplitude only with normalize on); Distance
>= 0 (F1, F2, Distance to Edge; with normalize on, F1 and Distance to Edge in [0, 1]
for randomness <= 1, F2 about [0, 1]); Smooth F1 may leave [0, 1] slightly (its
correction terms); Radius in [0, (1 + randomness) sqrt(dim) / 2]; Position and W unbounded
(the point's own cell).
"""

import math

from renderer.kernels import inline_kernel, kernel

from .fractal import _f32
from .voronoi_cells import (
    DISTANCE_TO_EDGE,
    F2,
    MANHATTAN,
    N_SPHERE_RADIUS,
    SMOOTH_F1,
    distance,
    distance_to_edge,
    f1_f2,
    n_sphere_radius,
    smooth_f1,
)


@inline_kernel
def _scaled(p, s):
    return (_f32(p[0] * s), _f32(p[1] * s), _f32(p[2] * s), _f32(p[3] * s))


@inline_kernel
def _mix(a, b, t):
    return a + t * (b - a)


@kernel
def _octave(dim, p, feature, metric, exponent, randomness, smoothness):
    if feature == SMOOTH_F1 and smoothness != 0.0:
        return smooth_f1(dim, p, metric, exponent, randomness, smoothness)
    return f1_f2(dim, p, feature, metric, exponent, randomness)


@inline_kernel
def _fractal_features(dim, p, feature, metric, exponent, detail, roughness, lacunarity, smoothness,
                      randomness, normalize, max_distance, scale0):
    """fractal_voronoi_x_fx: (distance, colour, position (4)) for F1, F2 and Smooth F1."""
    amp, max_amp, scale = 1.0, 0.0, 1.0
    dist = 0.0
    col = (0.0, 0.0, 0.0)
    pos = (0.0, 0.0, 0.0, 0.0)
    zero_input = detail == 0.0 or roughness == 0.0
    for i in range(int(math.ceil(detail)) + 1):
        od, oc, op = _octave(dim, _scaled(p, scale), feature, metric, exponent, randomness, smoothness)
        if zero_input:
            max_amp, dist, col, pos = 1.0, od, oc, op
            break
        if i <= detail:
            max_amp += amp
            dist += od * amp
            col = (col[0] + oc[0] * amp, col[1] + oc[1] * amp, col[2] + oc[2] * amp)
            pos = (_mix(pos[0], op[0] / scale, amp), _mix(pos[1], op[1] / scale, amp),
                   _mix(pos[2], op[2] / scale, amp), _mix(pos[3], op[3] / scale, amp))
            scale = _f32(scale * lacunarity)
            amp *= roughness
        else:
            rmd = detail - math.floor(detail)
            if rmd != 0.0:
                max_amp = _mix(max_amp, max_amp + amp, rmd)
                dist = _mix(dist, dist + od * amp, rmd)
                col = (_mix(col[0], col[0] + oc[0] * amp, rmd), _mix(col[1], col[1] + oc[1] * amp, rmd),
                       _mix(col[2], col[2] + oc[2] * amp, rmd))
                pos = (_mix(pos[0], _mix(pos[0], op[0] / scale, amp), rmd),
                       _mix(pos[1], _mix(pos[1], op[1] / scale, amp), rmd),
                       _mix(pos[2], _mix(pos[2], op[2] / scale, amp), rmd),
                       _mix(pos[3], _mix(pos[3], op[3] / scale, amp), rmd))
    if normalize:
        dist /= max_amp * max_distance
        col = (col[0] / max_amp, col[1] / max_amp, col[2] / max_amp)
    if scale0 == 0.0:  # safe_divide
        return dist, col, (0.0, 0.0, 0.0, 0.0)
    return dist, col, (pos[0] / scale0, pos[1] / scale0, pos[2] / scale0, pos[3] / scale0)


@inline_kernel
def _fractal_edge(dim, p, detail, roughness, lacunarity, randomness, normalize, max_distance):
    """fractal_voronoi_distance_to_edge."""
    amp, max_amp, scale, dist = 1.0, max_distance, 1.0, 8.0
    zero_input = detail == 0.0 or roughness == 0.0
    for i in range(int(math.ceil(detail)) + 1):
        od = distance_to_edge(dim, _scaled(p, scale), randomness)
        if zero_input:
            dist = od
            break
        if i <= detail:
            max_amp = _mix(max_amp, max_distance / scale, amp)
            dist = _mix(dist, min(dist, od / scale), amp)
            scale = _f32(scale * lacunarity)
            amp *= roughness
        else:
            rmd = detail - math.floor(detail)
            if rmd != 0.0:
                lerp_amp = _mix(max_amp, max_distance / scale, amp)
                max_amp = _mix(max_amp, lerp_amp, rmd)
                lerp_dist = _mix(dist, min(dist, od / scale), amp)
                dist = _mix(dist, min(dist, lerp_dist), rmd)
    return dist / max_amp if normalize else dist


@kernel
def voronoi_texture(dim, feature, metric, normalize, x, y, z, w, scale, detail, roughness, lacunarity,
                    smoothness, exponent, randomness):
    """(distance, colour, position (4), radius) of the Voronoi Texture at vector (x, y, z)
    and W (1D: W alone; 2D: x, y; 4D: all four) before scaling."""
    detail = min(max(detail, 0.0), 15.0)
    roughness = min(max(roughness, 0.0), 1.0)
    randomness = min(max(randomness, 0.0), 1.0)
    smoothness = min(max(smoothness / 2.0, 0.0), 0.5)
    if dim == 1:
        p = (_f32(w * scale), 0.0, 0.0, 0.0)
        metric = MANHATTAN  # 1D: the plain |b - a| for every metric
    else:
        p = (_f32(x * scale), _f32(y * scale), _f32(z * scale) if dim > 2 else 0.0,
             _f32(w * scale) if dim > 3 else 0.0)
    zero3 = (0.0, 0.0, 0.0)
    zero4 = (0.0, 0.0, 0.0, 0.0)
    if feature == DISTANCE_TO_EDGE:
        max_distance = 0.5 + 0.5 * randomness
        d = _fractal_edge(dim, p, detail, roughness, lacunarity, randomness, normalize, max_distance)
        return d, zero3, zero4, 0.0
    if feature == N_SPHERE_RADIUS:
        return 0.0, zero3, zero4, n_sphere_radius(dim, p, randomness)
    c = 0.5 + 0.5 * randomness
    corner = (c, c if dim > 1 else 0.0, c if dim > 2 else 0.0, c if dim > 3 else 0.0)
    max_distance = distance(zero4, corner, metric, exponent) * (2.0 if feature == F2 else 1.0)
    d, col, pos = _fractal_features(dim, p, feature, metric, exponent, detail, roughness, lacunarity,
                                    smoothness, randomness, normalize, max_distance, scale)
    if dim == 1:  # voronoi_position(float): the 1D position is W
        pos = (0.0, 0.0, 0.0, pos[0])
    return d, col, pos, 0.0
