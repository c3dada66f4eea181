"""Small vector helpers for numba kernels. A vector is a 3-tuple of floats."""

import math

from renderer.kernels import inline_kernel
from renderer.scene import LUMINANCE

LUM_R, LUM_G, LUM_B = LUMINANCE  # module-level floats: numba folds them as constants
INV_PI = 1.0 / math.pi
INV_4PI = 1.0 / (4.0 * math.pi)


@inline_kernel
def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


@inline_kernel
def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@inline_kernel
def mul(a, b):
    """Component-wise product (colours)."""
    return (a[0] * b[0], a[1] * b[1], a[2] * b[2])


@inline_kernel
def scale(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


@inline_kernel
def madd(a, b, s):
    """a + b * s."""
    return (a[0] + b[0] * s, a[1] + b[1] * s, a[2] + b[2] * s)


@inline_kernel
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@inline_kernel
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@inline_kernel
def length(a):
    return math.sqrt(dot(a, a))


@inline_kernel
def normalize(a):
    n = math.sqrt(dot(a, a))
    if n > 0.0:
        return (a[0] / n, a[1] / n, a[2] / n)
    return (0.0, 0.0, 1.0)


@inline_kernel
def neg(a):
    return (-a[0], -a[1], -a[2])


@inline_kernel
def luminance(c):
    """Rec. 709 luminance of a linear RGB colour."""
    return LUM_R * c[0] + LUM_G * c[1] + LUM_B * c[2]


@inline_kernel
def max3(c):
    return max(c[0], max(c[1], c[2]))


@inline_kernel
def onb(n):
    """Orthonormal basis (s, t) around unit n (Duff et al. 2017, branchless)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    s = (1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    t = (b, sign + n[1] * n[1] * a, -n[1])
    return s, t


@inline_kernel
def to_local(v, s, t, n):
    return (dot(v, s), dot(v, t), dot(v, n))


@inline_kernel
def to_world(v, s, t, n):
    return (
        s[0] * v[0] + t[0] * v[1] + n[0] * v[2],
        s[1] * v[0] + t[1] * v[1] + n[1] * v[2],
        s[2] * v[0] + t[2] * v[1] + n[2] * v[2],
    )
