"""Branch-free exp, log1p, atan2 and sincos, for loops that LLVM vectorises across paths.

fastmath.py's versions branch (argument reduction by cases, libm for arguments outside the
reduced ranges); a branch or a call inside a loop body stops LLVM's loop vectoriser. These
compute every case and choose with selects, so a loop that calls them compiles to SIMD code
(AVX-512: 8 paths per instruction). They assume what their callers guarantee (stated on each
function): finite arguments inside the renderer's ranges, no NaN handling beyond
propagation. Same series and reductions as fastmath.py, so the same accuracy (below 2e-15
relative; tests/test_fastmath.py checks both against numpy).
"""

import math

from renderer.kernels import inline_kernel
from renderer.kernels.fastmath import (
    LN2_HI,
    LN2_LO,
    PIO2_HI,
    PIO2_LO,
    SQRT2,
    TAN_3PI_16,
    TAN_PI_8,
    TAN_PI_16,
    TWO_OVER_PI,
    _atan_series,
    _bits_from_f64,
    _f64_from_bits,
)

_EXPONENT_ONE = 1023 << 52
_MANTISSA = (1 << 52) - 1
INV_LN2 = 1.0 / math.log(2.0)
EXP_NEG_MAX = 708.0  # exp(-708) = 3.3e-308, the last value above the normal range's floor


@inline_kernel
def exp_neg(x):
    """exp(-x) for x >= 0 (+inf allowed). -x = r - k ln 2 with k = round(x / ln 2), so
    |r| <= ln(2) / 2 and exp(-x) = exp(r) 2^-k; exp(r) to r^13 / 13! (next term < 4e-18
    relative). Past x = 708 the result would be subnormal: it is 0 here (libm gives < 3e-308)."""
    xc = min(x, EXP_NEG_MAX)
    k = math.floor(xc * INV_LN2 + 0.5)
    r = (k * LN2_HI - xc) + k * LN2_LO
    p = 1.0 / 6227020800.0
    p = p * r + 1.0 / 479001600.0
    p = p * r + 1.0 / 39916800.0
    p = p * r + 1.0 / 3628800.0
    p = p * r + 1.0 / 362880.0
    p = p * r + 1.0 / 40320.0
    p = p * r + 1.0 / 5040.0
    p = p * r + 1.0 / 720.0
    p = p * r + 1.0 / 120.0
    p = p * r + 1.0 / 24.0
    p = p * r + 1.0 / 6.0
    p = p * r + 0.5
    p = p * r + 1.0
    e = 1.0 + r * p
    scale = _f64_from_bits((1023 - int(k)) << 52)
    return e * scale if x <= EXP_NEG_MAX else 0.0


@inline_kernel
def log_normal(x):
    """Natural log of a normal double x > 0 (fastmath.log without its libm cases)."""
    bits = _bits_from_f64(x)
    e = (bits >> 52) - 1023
    m = _f64_from_bits((bits & _MANTISSA) | _EXPONENT_ONE)
    big = m > SQRT2
    m = m * 0.5 if big else m
    e = e + 1 if big else e
    f = (m - 1.0) / (m + 1.0)
    s = f * f
    p = 1.0 / 19.0
    p = p * s + 1.0 / 17.0
    p = p * s + 1.0 / 15.0
    p = p * s + 1.0 / 13.0
    p = p * s + 1.0 / 11.0
    p = p * s + 1.0 / 9.0
    p = p * s + 1.0 / 7.0
    p = p * s + 1.0 / 5.0
    p = p * s + 1.0 / 3.0
    log_m = 2.0 * f + 2.0 * f * s * p
    return e * LN2_HI + (log_m + e * LN2_LO)


@inline_kernel
def log1p(x):
    """log(1 + x) for 1 + x a normal double (x > -1 + 2^-1022), as fastmath.log1p."""
    u = 1.0 + x
    exact = u == 1.0
    v = log_normal(u) * (x / (u - 1.0 if not exact else 1.0))
    return x if exact else v


@inline_kernel
def atan2(y, x):
    """fastmath.atan2 for finite (x, y) not both 0 (then the result is NaN)."""
    ax = abs(x)
    ay = abs(y)
    big = max(ax, ay)
    z = min(ax, ay) / big
    # atan z = c + atan((z - tan c) / (1 + z tan c)), c in {0, pi/8, pi/4} nearest atan z;
    # c = 0 gives the argument z / 1 = z exactly, as fastmath's first case.
    mid = z > TAN_PI_16
    high = z > TAN_3PI_16
    tan_c = 1.0 if high else (TAN_PI_8 if mid else 0.0)
    c = math.pi / 4.0 if high else (math.pi / 8.0 if mid else 0.0)
    a = c + _atan_series((z - tan_c) / (1.0 + z * tan_c))
    a = math.pi / 2.0 - a if ay > ax else a
    a = math.pi - a if x < 0.0 else a
    return -a if y < 0.0 else a


@inline_kernel
def sincos(x):
    """fastmath.sincos for |x| < 1e5."""
    q = math.floor(x * TWO_OVER_PI + 0.5)
    r = (x - q * PIO2_HI) - q * PIO2_LO
    s = r * r
    ps = -1.0 / 1307674368000.0
    ps = ps * s + 1.0 / 6227020800.0
    ps = ps * s - 1.0 / 39916800.0
    ps = ps * s + 1.0 / 362880.0
    ps = ps * s - 1.0 / 5040.0
    ps = ps * s + 1.0 / 120.0
    ps = ps * s - 1.0 / 6.0
    sin_r = r + r * s * ps
    pc = 1.0 / 20922789888000.0
    pc = pc * s - 1.0 / 87178291200.0
    pc = pc * s + 1.0 / 479001600.0
    pc = pc * s - 1.0 / 3628800.0
    pc = pc * s + 1.0 / 40320.0
    pc = pc * s - 1.0 / 720.0
    pc = pc * s + 1.0 / 24.0
    pc = pc * s - 0.5
    cos_r = 1.0 + s * pc
    quadrant = int(q) & 3
    odd = (quadrant & 1) == 1
    sin_x = cos_r if odd else sin_r
    cos_x = sin_r if odd else cos_r
    sin_x = -sin_x if quadrant >= 2 else sin_x
    cos_x = -cos_x if (quadrant == 1 or quadrant == 2) else cos_x
    return sin_x, cos_x
