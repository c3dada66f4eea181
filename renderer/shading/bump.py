"""The Bump node (Cycles' svm_node_set_bump in svm/displace.h, reimplemented).

Cycles evaluates the Height at the shading point and at the point moved along the ray
differentials dP/dx and dP/dy (one pixel's footprint), and tilts the normal by the height's
surface gradient. Haze's programs have no ray differentials, so the two offsets are a fixed
small step h along two orthonormal tangents t1, t2 of the hit triangle's plane, with
h = OFFSET * max(1, |x|_inf) (scaled to the hit so float32 heights still resolve the step;
Cycles' step is Filter Width (default 0.1) times a pixel's footprint).
The barycentrics move with the point, so UVs and other corner attributes are read at the
offset points too. Cycles' formula with dP/dx = h t1, dP/dy = h t2 then gives
normalize(N - distance * grad_s(height)): the exact surface gradient, where Cycles' is the
finite difference over a pixel, which differs only where the height changes within a pixel.
The triangle's world-space corners come from the corner column CORNER_POSITION.
"""

import math

from renderer.kernels import inline_kernel
from renderer.kernels.vecmath import add, cross, dot, neg, scale, sub

CORNER_POSITION = "corner_position"
# Of the hit's largest coordinate (at least 1 scene unit): registers are float32, so a height
# of magnitude H changes by a rounding error of ~6e-8 H, and the gradient carries about
# 6e-8 H / (h |grad|). On a linear height (tests/test_shader_programs.py, bump cases) the
# normals were 3.9e-4 off Cycles' bake with 2e-4 and 4.8e-5 with 1e-3, which still resolves
# millimetre detail in a metre scene.
OFFSET = 1e-3


@inline_kernel
def _corner(corner, p, k, col):
    return (float(corner[p, k, col]), float(corner[p, k, col + 1]), float(corner[p, k, col + 2]))


@inline_kernel
def _unit(v):
    length = math.sqrt(dot(v, v))
    return scale(v, 1.0 / length) if length > 0.0 else (0.0, 0.0, 0.0)


@inline_kernel
def _frame(corner, p, col, x, n):
    """(t1, t2, h): orthonormal tangents of triangle p's plane (t1 x t2 on n's side) and the step."""
    p0 = _corner(corner, p, 0, col)
    e1 = sub(_corner(corner, p, 1, col), p0)
    e2 = sub(_corner(corner, p, 2, col), p0)
    ng = _unit(cross(e1, e2))
    if dot(ng, n) < 0.0:
        ng = neg(ng)
    t1 = _unit(e1)
    t2 = cross(ng, t1)
    h = OFFSET * max(max(1.0, abs(x[0])), max(abs(x[1]), abs(x[2])))
    return t1, t2, h


@inline_kernel
def bump_point(corner, p, col, b0, b1, b2, x, n, axis):
    """(b0, b1, b2, x) of the shading point moved by h along tangent `axis` (1: t1, 2: t2;
    0: the point itself)."""
    here = (float(b0), float(b1), float(b2), (float(x[0]), float(x[1]), float(x[2])))
    if axis == 0:
        return here
    p0 = _corner(corner, p, 0, col)
    e1 = sub(_corner(corner, p, 1, col), p0)
    e2 = sub(_corner(corner, p, 2, col), p0)
    t1, t2, h = _frame(corner, p, col, x, n)
    d = scale(t1 if axis == 1 else t2, h)
    a, b, c = dot(e1, e1), dot(e1, e2), dot(e2, e2)
    det = a * c - b * b
    if det <= 0.0:
        return here
    r1, r2 = dot(e1, d), dot(e2, d)
    u = (c * r1 - b * r2) / det
    v = (a * r2 - b * r1) / det
    return here[0] - u - v, here[1] + u, here[2] + v, add(here[3], d)


@inline_kernel
def bump_normal(corner, p, col, x, n, normal_in, hc, hx, hy, strength, distance, invert):
    """The Bump node's Normal: normal_in tilted by the heights hc (at the point), hx, hy
    (at the offsets of bump_point), as Cycles with dP/dx = h t1, dP/dy = h t2."""
    t1, t2, h = _frame(corner, p, col, x, n)
    dpdx, dpdy = scale(t1, h), scale(t2, h)
    rx = cross(dpdy, normal_in)
    ry = cross(normal_in, dpdx)
    det = dot(dpdx, rx)
    surfgrad = add(scale(rx, hx - hc), scale(ry, hy - hc))
    s = -distance if invert else distance
    sign = 1.0 if det > 0.0 else (-1.0 if det < 0.0 else 0.0)
    out = _unit(sub(scale(normal_in, abs(det)), scale(surfgrad, s * sign)))
    if dot(out, out) == 0.0:
        return normal_in
    w = max(strength, 0.0)
    return _unit(add(scale(out, w), scale(normal_in, 1.0 - w)))
