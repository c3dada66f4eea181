"""Math, Vector Math, Map Range and Mix (colour) node operations with Cycles' semantics
(kernel/svm/math_util.h, color_util.h): the safe variants, so any input gives a finite
result where Cycles' does. Operation codes are indexes into the name tuples, which are
Blender's enum identifiers (the exporter maps node.operation / node.blend_type through them).

These scalar functions are the one implementation of the operations: the shader interpreter
calls them, and the exporter folds constant nodes with them too (math_arrays.py: the same
functions as numpy ufuncs). Their floors are `floor` and `ceil` here, not math.floor, whose
int64 result is garbage past 2^63: a folded FLOOR(1e20) stays 1e20."""

import math

import numpy as np

from renderer.kernels import inline_kernel

from .names import BLEND_TYPES, MATH_OPS, VECTOR_OPS, VECTOR_SCALAR_OPS  # noqa: F401 - re-exported

FLT_EPSILON = 1.1920929e-07


@inline_kernel
def safe_divide(a, b):
    return a / b if b != 0.0 else 0.0


@inline_kernel
def safe_pow(a, b):
    if a < 0.0 and b != float(int(b)):
        return 0.0
    if b == 0.0:
        return 1.0
    if a == 0.0:
        return 0.0
    return math.copysign(abs(a) ** b, 1.0) * (-1.0 if a < 0.0 and int(b) % 2 == 1 else 1.0)


@inline_kernel
def floor(a):
    """numpy's floor, with +0.0 for -0.0: in int64's range the float math.floor gave (the
    kernels' images stay bit for bit), beyond it the float floor, not a wrapped integer."""
    return np.floor(a) + 0.0


@inline_kernel
def ceil(a):
    """numpy's ceil, with +0.0 for -0.0 (see floor)."""
    return np.ceil(a) + 0.0


@inline_kernel
def fract(a):
    return a - floor(a)


@inline_kernel
def wrap(value, hi, lo):
    r = hi - lo
    return value - r * floor((value - lo) / r) if r != 0.0 else lo


@inline_kernel
def smooth_min(a, b, k):
    if k != 0.0:
        h = max(k - abs(a - b), 0.0) / k
        return min(a, b) - h * h * h * k * (1.0 / 6.0)
    return min(a, b)


@inline_kernel
def math_op(op, a, b, c):  # noqa: C901 - one branch per Math operation, as svm_math
    if op == 0:
        return a + b
    if op == 1:
        return a - b
    if op == 2:
        return a * b
    if op == 3:
        return safe_divide(a, b)
    if op == 4:
        return a * b + c
    if op == 5:
        return safe_pow(a, b)
    if op == 6:
        return 0.0 if a <= 0.0 or b <= 0.0 else safe_divide(math.log(a), math.log(b))
    if op == 7:
        return math.sqrt(a) if a > 0.0 else 0.0
    if op == 8:
        return 1.0 / math.sqrt(a) if a > 0.0 else 0.0
    if op == 9:
        return abs(a)
    if op == 10:
        return math.exp(min(a, 88.0))
    if op == 11:
        return min(a, b)
    if op == 12:
        return max(a, b)
    if op == 13:
        return 1.0 if a < b else 0.0
    if op == 14:
        return 1.0 if a > b else 0.0
    if op == 15:
        return 0.0 if a == 0.0 else (-1.0 if a < 0.0 else 1.0)
    if op == 16:
        return 1.0 if a == b or abs(a - b) <= max(c, FLT_EPSILON) else 0.0
    if op == 17:
        return smooth_min(a, b, c)
    if op == 18:
        return -smooth_min(-a, -b, c)
    if op == 19:
        return floor(a + 0.5)
    if op == 20:
        return floor(a)
    if op == 21:
        return ceil(a)
    if op == 22:
        return floor(a) if a >= 0.0 else ceil(a)
    if op == 23:
        return fract(a)
    if op == 24:
        return np.fmod(a, b) if b != 0.0 else 0.0
    if op == 25:
        return a - floor(a / b) * b if b != 0.0 else 0.0
    if op == 26:
        return wrap(a, b, c)
    if op == 27:
        return floor(safe_divide(a, b)) * b
    if op == 28:
        return abs(fract((a - b) / (b * 2.0)) * b * 2.0 - b) if b != 0.0 else 0.0
    if op == 29:
        return math.sin(a)
    if op == 30:
        return math.cos(a)
    if op == 31:
        return math.tan(a)
    if op == 32:
        return math.asin(min(max(a, -1.0), 1.0))
    if op == 33:
        return math.acos(min(max(a, -1.0), 1.0))
    if op == 34:
        return math.atan(a)
    if op == 35:
        return 0.0 if a == 0.0 and b == 0.0 else math.atan2(a, b)
    if op == 36:
        return math.sinh(a)
    if op == 37:
        return math.cosh(a)
    if op == 38:
        return math.tanh(a)
    if op == 39:
        return a * (math.pi / 180.0)
    if op == 40:
        return a * (180.0 / math.pi)
    return 0.0


@inline_kernel
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@inline_kernel
def _per(op, a, b):
    """A Math operation per component (the Vector Math ops that are one)."""
    return (math_op(op, a[0], b[0], 0.0), math_op(op, a[1], b[1], 0.0), math_op(op, a[2], b[2], 0.0))


@inline_kernel
def vector_op(op, a, b, c, s):  # noqa: C901 - one branch per operation, as svm_vector_math
    """(vector, value) of Vector Math operation `op` on vectors a, b, c and scale s."""
    z = (0.0, 0.0, 0.0)
    if op == 0:
        return _per(0, a, b), 0.0
    if op == 1:
        return _per(1, a, b), 0.0
    if op == 2:
        return _per(2, a, b), 0.0
    if op == 3:
        return _per(3, a, b), 0.0
    if op == 4:
        return (a[0] * b[0] + c[0], a[1] * b[1] + c[1], a[2] * b[2] + c[2]), 0.0
    if op == 5:
        return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]), 0.0
    if op == 6:
        bb = _dot(b, b)
        k = _dot(a, b) / bb if bb != 0.0 else 0.0
        return (b[0] * k, b[1] * k, b[2] * k), 0.0
    if op == 7:
        ln = math.sqrt(_dot(b, b))
        n = (b[0] / ln, b[1] / ln, b[2] / ln) if ln != 0.0 else z
        k = 2.0 * _dot(n, a)
        return (a[0] - k * n[0], a[1] - k * n[1], a[2] - k * n[2]), 0.0
    if op == 8:
        return z, _dot(a, b)
    if op == 9:
        d = (a[0] - b[0], a[1] - b[1], a[2] - b[2])
        return z, math.sqrt(_dot(d, d))
    if op == 10:
        return z, math.sqrt(_dot(a, a))
    if op == 11:
        return (a[0] * s, a[1] * s, a[2] * s), 0.0
    if op == 12:
        ln = math.sqrt(_dot(a, a))
        return ((a[0] / ln, a[1] / ln, a[2] / ln) if ln != 0.0 else z), 0.0
    if op == 13:
        return (abs(a[0]), abs(a[1]), abs(a[2])), 0.0
    if op == 14:
        return _per(11, a, b), 0.0
    if op == 15:
        return _per(12, a, b), 0.0
    if op == 16:
        return _per(20, a, b), 0.0
    if op == 17:
        return _per(21, a, b), 0.0
    if op == 18:
        return _per(23, a, b), 0.0
    if op == 19:
        return _per(24, a, b), 0.0
    if op == 20:
        return (wrap(a[0], b[0], c[0]), wrap(a[1], b[1], c[1]), wrap(a[2], b[2], c[2])), 0.0
    if op == 21:
        return _per(27, a, b), 0.0
    if op == 22:
        return _per(29, a, b), 0.0
    if op == 23:
        return _per(30, a, b), 0.0
    if op == 24:
        return _per(31, a, b), 0.0
    if op == 25:
        return _per(5, a, b), 0.0
    if op == 26:
        return _per(15, a, b), 0.0
    return z, 0.0


@inline_kernel
def smoothstep(lo, hi, x, smoother):
    if x < lo:
        return 0.0
    if x >= hi:
        return 1.0
    t = (x - lo) / (hi - lo)
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0) if smoother else (3.0 - 2.0 * t) * t * t


@inline_kernel
def map_range(v, from_min, from_max, to_min, to_max, steps, kind, clamp):
    """Map Range (float): Linear 0, Stepped 1, Smooth Step 2, Smoother Step 3, as
    svm_node_map_range; Clamp applies to Linear and Stepped (Blender adds a clamp node)."""
    if from_max == from_min:
        return 0.0
    if kind >= 2:
        smoother = kind == 3
        if from_min > from_max:
            f = 1.0 - smoothstep(from_max, from_min, v, smoother)
        else:
            f = smoothstep(from_min, from_max, v, smoother)
        return to_min + f * (to_max - to_min)
    f = (v - from_min) / (from_max - from_min)
    if kind == 1:
        f = floor(f * (steps + 1.0)) / steps if steps > 0.0 else 0.0
    r = to_min + f * (to_max - to_min)
    if clamp:
        lo, hi = min(to_min, to_max), max(to_min, to_max)
        r = min(max(r, lo), hi)
    return r


@inline_kernel
def _lerp(a, b, t):
    return (1.0 - t) * a + t * b


@inline_kernel
def mix_channel(blend, t, a, b):  # noqa: C901 - one branch per blend type, as svm_mix
    """One channel of Mix blend `blend` (BLEND_TYPES index) of a and b by t."""
    tm = 1.0 - t
    if blend == 0:
        return _lerp(a, b, t)
    if blend == 1:
        return _lerp(a, min(a, b), t)
    if blend == 2:
        return _lerp(a, a * b, t)
    if blend == 3:
        tmp = tm + t * b
        if tmp <= 0.0:
            return 0.0
        return min(max(1.0 - (1.0 - a) / tmp, 0.0), 1.0)
    if blend == 4:
        return _lerp(a, max(a, b), t)
    if blend == 5:
        return 1.0 - (tm + t * (1.0 - b)) * (1.0 - a)
    if blend == 6:
        if a == 0.0:
            return a
        tmp = 1.0 - t * b
        return 1.0 if tmp <= 0.0 else min(a / tmp, 1.0)
    if blend == 7:
        return _lerp(a, a + b, t)
    if blend == 8:
        if a < 0.5:
            return a * (tm + 2.0 * t * b)
        return 1.0 - (tm + 2.0 * t * (1.0 - b)) * (1.0 - a)
    if blend == 9:
        scr = 1.0 - (1.0 - b) * (1.0 - a)
        return tm * a + t * ((1.0 - a) * b * a + a * scr)
    if blend == 10:
        return a + t * (2.0 * b - 1.0)
    if blend == 11:
        return _lerp(a, abs(a - b), t)
    if blend == 12:
        return max(_lerp(a, a + b - 2.0 * a * b, t), 0.0)
    if blend == 13:
        return _lerp(a, a - b, t)
    if blend == 14:
        return tm * a + t * a / b if b != 0.0 else a
    return a


@inline_kernel
def mix_color(blend, t, a, b):
    return (mix_channel(blend, t, a[0], b[0]), mix_channel(blend, t, a[1], b[1]),
            mix_channel(blend, t, a[2], b[2]))
