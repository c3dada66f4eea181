"""Branch-free exp, log1p, atan2 and sincos, for loops that LLVM vectorises across paths.

A branch or a call inside a loop body stops LLVM's loop vectoriser, so these compute every
case and choose with selects; a loop that calls them compiles to SIMD code (AVX-512: 8 paths
per instruction). They leave out fastmath.py's range checks (and its libm fallbacks), so
they assume what their callers guarantee, stated on each function. atan2, sincos and the log
are fastmath.py's own branch-free series; exp(-x), log1p and 1 - exp(-x) are written here.
"""

import math

from renderer.kernels import inline_kernel
from renderer.kernels.fastmath import (
    LN2_HI,
    LN2_LO,
    _f64_from_bits,
    log_normal,
)
from renderer.kernels.fastmath import atan2_finite as atan2
from renderer.kernels.fastmath import sincos_reduced as sincos

__all__ = ["atan2", "exp_neg", "log1p", "log_normal", "one_minus_exp_neg", "sincos"]

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
def log1p(x):
    """log(1 + x) for 1 + x a normal double (x > -1 + 2^-1022), as fastmath.log1p."""
    u = 1.0 + x
    exact = u == 1.0
    v = log_normal(u) * (x / (u - 1.0 if not exact else 1.0))
    return x if exact else v


@inline_kernel
def one_minus_exp_neg(x, tr):
    """1 - exp(-x) given tr = exp(-x) (homogeneous._one_minus): 1 - tr above 0.1, and below
    it -expm1(-x) by its series x - x^2/2! + ... - x^12/12! (next term < 1e-17 relative)."""
    xs = min(x, 0.1)
    p = -1.0 / 479001600.0
    p = p * xs + 1.0 / 39916800.0
    p = p * xs - 1.0 / 3628800.0
    p = p * xs + 1.0 / 362880.0
    p = p * xs - 1.0 / 40320.0
    p = p * xs + 1.0 / 5040.0
    p = p * xs - 1.0 / 720.0
    p = p * xs + 1.0 / 120.0
    p = p * xs - 1.0 / 24.0
    p = p * xs + 1.0 / 6.0
    p = p * xs - 0.5
    p = p * xs + 1.0
    return 1.0 - tr if x > 0.1 else xs * p
