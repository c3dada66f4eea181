"""Closed forms for stacks of homogeneous media (Beer's law): no tracking loop ever.

Coefficients of the stack's entries add (Cycles' rule), so a homogeneous stack is one
homogeneous medium with sigma = sum of the entries' sigma.

The segment constants, Beer's law, truncated and free-flight sampling also come in a
branch-free form (*_simd, at the end) for the SIMD batch of homogeneous segments
(renderer.integrator.nee_batch): every case computed and one kept by a select, with
simdmath's exp and log1p (no libm fallback, no errno), so that a loop calling them
vectorises across paths. tests/test_nee_batch.py holds the two forms to 1e-11.
"""

import math

from renderer.kernels import fastmath as fm
from renderer.kernels import inline_kernel
from renderer.kernels import simdmath as sm
from renderer.media.spectral import channel_value, pick_channel
from renderer.media.stack import EMPTY, MAX_STACK
from renderer.media.table import emission, emits, sigma_a, sigma_s


@inline_kernel
def stack_sigma(mt, stack):
    """(sigma_a, sigma_s) summed over the stack; valid for stacks without grids."""
    a0 = a1 = a2 = 0.0
    s0 = s1 = s2 = 0.0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        a = sigma_a(mt, m)
        s = sigma_s(mt, m)
        a0 += a[0]
        a1 += a[1]
        a2 += a[2]
        s0 += s[0]
        s1 += s[1]
        s2 += s[2]
    return (a0, a1, a2), (s0, s1, s2)


@inline_kernel
def stack_constant_emission(mt, stack):
    """Emission summed over the stack's emitting entries (homogeneous entries only)."""
    e0 = e1 = e2 = 0.0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        if emits(mt, m):
            e = emission(mt, m)
            e0 += e[0]
            e1 += e[1]
            e2 += e[2]
    return (e0, e1, e2)


@inline_kernel
def optical_depth(sigma, t):
    # Written out so that sigma = 0 over an infinite segment is 0, not 0 * inf = NaN.
    return sigma * t if sigma > 0.0 else 0.0


@inline_kernel
def _exp_neg(x):
    # exp(-x) for x >= 0; past 745 the result is 0 anyway, and libm's underflow path (errno)
    # costs five times a plain exp: infinite segments (rays leaving into world fog) hit it.
    return math.exp(-x) if x < 745.0 else 0.0


@inline_kernel
def beer(sigma_t, t):
    """Transmittance exp(-sigma_t t) per channel (one exp for a grey medium)."""
    if sigma_t[0] == sigma_t[1] and sigma_t[1] == sigma_t[2]:
        e = _exp_neg(optical_depth(sigma_t[0], t))
        return (e, e, e)
    return (
        _exp_neg(optical_depth(sigma_t[0], t)),
        _exp_neg(optical_depth(sigma_t[1], t)),
        _exp_neg(optical_depth(sigma_t[2], t)),
    )


@inline_kernel
def _one_minus(tr, x):
    # 1 - exp(-x) from tr = exp(-x): exact enough unless x is small, where the difference
    # cancels; there expm1 keeps full precision (and 1 - tr would be 0 below x ~ 1e-16).
    return 1.0 - tr if x > 0.1 else -math.expm1(-x)


@inline_kernel
def segment(mt, stack, tmax):
    """Constants of a homogeneous stack over [0, tmax), computed once per path segment and
    shared by the next-event vertex and free-flight sampling (exp dominated the medium
    kernel's maths): (sigma_a, sigma_s, sigma_t, T(tmax), 1 - T(tmax)), each per channel."""
    sa, ss = stack_sigma(mt, stack)
    st = (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])
    tr = beer(st, tmax)
    miss = (
        _one_minus(tr[0], optical_depth(st[0], tmax)),
        _one_minus(tr[1], optical_depth(st[1], tmax)),
        _one_minus(tr[2], optical_depth(st[2], tmax)),
    )
    return sa, ss, st, tr, miss


@inline_kernel
def _transmitted_length(sigma, t):
    # integral_0^t exp(-sigma s) ds = (1 - exp(-sigma t)) / sigma, written with expm1 so
    # that it tends to t without cancellation as sigma t -> 0 (and is exactly t at 0).
    if sigma > 0.0:
        return -math.expm1(-sigma * t) / sigma
    return t


@inline_kernel
def emission_integral(emission, sigma_t, t):
    """integral_0^t exp(-sigma_t s) emission ds per channel (constant emission)."""
    return (
        emission[0] * _transmitted_length(sigma_t[0], t),
        emission[1] * _transmitted_length(sigma_t[1], t),
        emission[2] * _transmitted_length(sigma_t[2], t),
    )


@inline_kernel
def sample_exponential(sigma, u):
    """Free-flight distance with density sigma exp(-sigma t); inf when sigma is 0.
    u < 1 (24-bit uniforms) keeps -log1p(-u) <= 16.7, so t <= 16.7 / sigma."""
    if sigma > 0.0:
        return -fm.log1p(-u) / sigma
    return math.inf


@inline_kernel
def sample_truncated(sigma, tmax, miss, u):
    """Distance on [0, tmax) with density sigma exp(-sigma t) / (1 - exp(-sigma tmax)), given
    miss = 1 - exp(-sigma tmax) (see segment)."""
    if sigma > 0.0 and miss > 0.0:
        return min(-fm.log1p(-u * miss) / sigma, tmax)
    return u * tmax


@inline_kernel
def truncated_pdf(sigma, tmax, miss, tr_t):
    """Density of sample_truncated at t, given miss = 1 - exp(-sigma tmax) and
    tr_t = exp(-sigma t)."""
    if sigma > 0.0 and miss > 0.0:
        return sigma * tr_t / miss
    return 1.0 / tmax


@inline_kernel
def free_flight_segment(sigma_s, st, tr_end, tmax, p, u_channel, u_distance):
    """Sample the next collision on [0, tmax) in a homogeneous medium by spectral MIS, given
    sigma_t = st and tr_end = T(tmax) (see segment).

    Channel c (probability p_c) proposes t ~ sigma_t,c exp(-sigma_t,c t). Returns
    (t, scattered, weight):
      scattered:     weight = T(t) sigma_s / sum_c p_c sigma_t,c T_c(t)
      not scattered: t = tmax, weight = T(tmax) / sum_c p_c T_c(tmax)   (P(no collision))
    Absorption stays in the weight (the albedo factor), so no path is terminated here.
    Both denominators contain the picked channel's own term, which cannot underflow
    (sigma_t,c t <= 16.7), so the weights are finite for any mix of coefficients.
    """
    c = pick_channel(p, u_channel)
    t = sample_exponential(st[c], u_distance)
    if t < tmax:
        tr = beer(st, t)
        pdf = p[0] * st[0] * tr[0] + p[1] * st[1] * tr[1] + p[2] * st[2] * tr[2]
        return t, True, (tr[0] * sigma_s[0] / pdf, tr[1] * sigma_s[1] / pdf, tr[2] * sigma_s[2] / pdf)
    tr = tr_end
    prob = p[0] * tr[0] + p[1] * tr[1] + p[2] * tr[2]
    return tmax, False, (tr[0] / prob, tr[1] / prob, tr[2] / prob)


# ------------------------------------------------------------------------- branch-free forms


@inline_kernel
def segment_simd(sigma_t, tmax):
    """(T(tmax), 1 - T(tmax)) per channel: segment's constants given the stack's sigma_t."""
    x0 = optical_depth(sigma_t[0], tmax)
    x1 = optical_depth(sigma_t[1], tmax)
    x2 = optical_depth(sigma_t[2], tmax)
    tr0, tr1, tr2 = sm.exp_neg(x0), sm.exp_neg(x1), sm.exp_neg(x2)
    miss = (sm.one_minus_exp_neg(x0, tr0), sm.one_minus_exp_neg(x1, tr1), sm.one_minus_exp_neg(x2, tr2))
    return (tr0, tr1, tr2), miss


@inline_kernel
def beer_simd(sigma_t, t):
    """beer without its grey-medium shortcut."""
    return (sm.exp_neg(optical_depth(sigma_t[0], t)), sm.exp_neg(optical_depth(sigma_t[1], t)),
            sm.exp_neg(optical_depth(sigma_t[2], t)))


@inline_kernel
def sample_truncated_simd(sigma, tmax, miss, u):
    """sample_truncated without branches."""
    ok = sigma > 0.0 and miss > 0.0
    t = min(-sm.log1p(-u * miss) / (sigma if ok else 1.0), tmax)
    return t if ok else u * tmax


@inline_kernel
def free_flight_segment_simd(sigma_s, st, tr_end, tmax, p, u_channel, u_distance):
    """free_flight_segment without branches, as medium.sample_segment uses it: where nothing
    scatters (sigma_s = 0) no collision is sampled and the weight is T(tmax) itself.
    Returns (t, scattered, weight)."""
    ss0, ss1, ss2 = sigma_s
    st0, st1, st2 = st
    te0, te1, te2 = tr_end
    p0, p1, p2 = p
    scatters = ss0 > 0.0 or ss1 > 0.0 or ss2 > 0.0
    sigma = channel_value(pick_channel(p, u_channel), st0, st1, st2)
    t = -sm.log1p(-u_distance) / (sigma if sigma > 0.0 else 1.0)
    hit = scatters and sigma > 0.0 and t < tmax
    t = t if hit else tmax
    tr0, tr1, tr2 = beer_simd(st, t if hit else 0.0)  # a finite exponent on the branch not taken
    pdf = p0 * st0 * tr0 + p1 * st1 * tr1 + p2 * st2 * tr2
    prob = p0 * te0 + p1 * te1 + p2 * te2
    inv = 1.0 / (pdf if hit else (prob if scatters else 1.0))
    w0 = (tr0 * ss0 if hit else te0) * inv
    w1 = (tr1 * ss1 if hit else te1) * inv
    w2 = (tr2 * ss2 if hit else te2) * inv
    return t, hit, (w0, w1, w2)
