"""Procedural texture and vector nodes with Cycles' semantics: Mapping
(svm/mapping_util.h), Checker (svm/checker.h), Gradient (svm/gradient.h), and the
256-entry tables Cycles bakes Color Ramp and RGB Curves into (svm/ramp_util.h)."""

import math

from renderer.kernels import inline_kernel

from .math_ops import safe_divide
from .names import RAMP_SIZE


@inline_kernel
def _euler(r):
    """Rows of Cycles' euler_to_transform(r) (X, then Y, then Z rotation)."""
    cx, cy, cz = math.cos(r[0]), math.cos(r[1]), math.cos(r[2])
    sx, sy, sz = math.sin(r[0]), math.sin(r[1]), math.sin(r[2])
    return ((cy * cz, sy * sx * cz - cx * sz, sy * cx * cz + sx * sz),
            (cy * sz, sy * sx * sz + cx * cz, sy * cx * sz - sx * cz),
            (-sy, cy * sx, cy * cx))


@inline_kernel
def _apply(m, v):
    return (m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
            m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
            m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2])


@inline_kernel
def _apply_transposed(m, v):
    return (m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
            m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
            m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2])


@inline_kernel
def mapping(kind, v, loc, rot, scale):
    m = _euler(rot)
    if kind == 0:
        p = _apply(m, (v[0] * scale[0], v[1] * scale[1], v[2] * scale[2]))
        return (p[0] + loc[0], p[1] + loc[1], p[2] + loc[2])
    if kind == 1:
        p = _apply_transposed(m, (v[0] - loc[0], v[1] - loc[1], v[2] - loc[2]))
        return (safe_divide(p[0], scale[0]), safe_divide(p[1], scale[1]), safe_divide(p[2], scale[2]))
    if kind == 2:
        return _apply(m, (v[0] * scale[0], v[1] * scale[1], v[2] * scale[2]))
    p = _apply(m, (safe_divide(v[0], scale[0]), safe_divide(v[1], scale[1]), safe_divide(v[2], scale[2])))
    ln = math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2])
    return (p[0] / ln, p[1] / ln, p[2] / ln) if ln != 0.0 else (0.0, 0.0, 0.0)


@inline_kernel
def checker(p):
    """1 or 0: Cycles' svm_checker (nudged off unit coordinates)."""
    xi = abs(int(math.floor((p[0] + 0.000001) * 0.999999)))
    yi = abs(int(math.floor((p[1] + 0.000001) * 0.999999)))
    zi = abs(int(math.floor((p[2] + 0.000001) * 0.999999)))
    return 1.0 if ((xi % 2 == yi % 2) == (zi % 2 == 1)) else 0.0


@inline_kernel
def gradient(kind, p):
    x, y, z = p
    return min(max(_gradient(kind, x, y, z), 0.0), 1.0)  # svm_node_tex_gradient saturates


@inline_kernel
def _gradient(kind, x, y, z):
    if kind == 0:
        return x
    if kind == 1:
        r = max(x, 0.0)
        return r * r
    if kind == 2:
        r = min(max(x, 0.0), 1.0)
        t = r * r
        return 3.0 * t - 2.0 * t * r
    if kind == 3:
        return (x + y) * 0.5
    if kind == 4:
        return math.atan2(y, x) / (2.0 * math.pi) + 0.5
    r = max(0.999999 - math.sqrt(x * x + y * y + z * z), 0.0)
    return r * r if kind == 5 else r


@inline_kernel
def ramp_lookup(data, start, channels, channel, f, interpolate):
    """Channel `channel` of a RAMP_SIZE-entry table at data[start:] with `channels` values
    per entry, at f in [0, 1] (clamped; NaN gives entry 0), as rgb_ramp_lookup."""
    f = min(max(f, 0.0), 1.0) * (RAMP_SIZE - 1) if f == f else 0.0
    i = min(max(int(f), 0), RAMP_SIZE - 1)
    t = f - i
    r = float(data[start + i * channels + channel])
    if interpolate and t > 0.0:
        r = (1.0 - t) * r + t * float(data[start + (i + 1) * channels + channel])
    return r


@inline_kernel
def curve_lookup(data, start, channels, channel, f, extrapolate):
    """A curve table's channel at f: ramp_lookup (interpolated) inside [0, 1]; outside, with
    `extrapolate`, the line through the end's two entries (float_ramp_lookup)."""
    if extrapolate and (f < 0.0 or f > 1.0):
        if f < 0.0:
            t0 = float(data[start + channel])
            dy = t0 - float(data[start + channels + channel])
            f = -f
        else:
            t0 = float(data[start + (RAMP_SIZE - 1) * channels + channel])
            dy = t0 - float(data[start + (RAMP_SIZE - 2) * channels + channel])
            f = f - 1.0
        return t0 + dy * f * (RAMP_SIZE - 1)
    return ramp_lookup(data, start, channels, channel, f, True)


@inline_kernel
def curves(regs, dst, data, start, channels, extrapolate, fac, src, lo, hi):
    """RGB Curves, Vector Curves (channels 3) and Float Curve (1), as svm_node_curves and
    svm_node_curve: each component of registers src.. looked up at its position in the
    curves' range [lo, hi], mixed with the input by fac."""
    for ch in range(channels):
        x = float(regs[src + ch])
        y = curve_lookup(data, start, channels, ch, (x - lo) / (hi - lo), extrapolate)
        regs[dst + ch] = (1.0 - fac) * x + fac * y
