"""The one free-flight walk over majorant segments, shared by every grid-stack tracker.

A grid stack's majorant is piecewise constant along a ray: the homogeneous entries'
sigma_t plus, per grid entry, the density bound of the coarse cell its DDA is in
(majorant.py), raised to an emission rate where emission is sampled (tracking.py explains
the estimators). The walk crosses those pieces in order. On a piece that compile.py flags
for regular tracking it hands the whole piece to the tracker; on any other piece it samples
tentative collisions with technique c's rate mu_c (exponential steps, one random number
each) and hands each one to the tracker, then the stretch to the piece's end.

What happens at those events is the tracker's (as pbrt-v4's SampleT_maj takes a callback):

    delta tracking (tracking.py):     real collision against sigma_t, or null
    ratio tracking (tracking.py):     multiply the transmittance estimate, Russian roulette
    scatter tracking (scatter_tracking.py): collide on sigma_s, absorption in the weight

Under numba the decisions are fixed at compile time: make_walk(regular, majorant, collide,
passed) builds one walk per tracker (a closure over the tracker's inline kernels, which
numba compiles as calls to those functions; LLVM inlines them all), so each tracker's
machine code is what its hand-written loop was. The tracker's estimate travels through the
walk as a tuple `state` that only the tracker reads, and its constants as `env`:

    regular(mt, stack, o, d, t, end, p, key, dim, c, rows, j, hom_sigma_t, env, state)
        -> (t, event, state, dim)        the flagged piece [t, end) of walker j's grid
    majorant(mt, rows, n, mu_t, env) -> mu    the rate to sample, given the sigma_t majorant
    collide(mt, stack, o, d, t, x, mu, dt, p, c, key, dim, rate, env, state)
        -> (event, state, dim)           a tentative collision at t (point x), dt after the last
    passed(mu, dt, p, state) -> state    the last dt of a piece, without a collision

event: WALK_ON, STOPPED (the tracker's collision: the walk returns its t) or KILLED (Russian
roulette). The walk returns (t, event, state, dim); t = t1 when it walked through.
"""

import math

from numba import njit

from renderer.kernels import JIT_OPTIONS, inline_kernel, kernel
from renderer.kernels import fastmath as fm
from renderer.kernels.rng import hashed_uniform
from renderer.media.grid import medium_density, to_unit_point, to_unit_vector
from renderer.media.homogeneous import optical_depth
from renderer.media.layout import DDA_EMITS, DDA_END, DDA_EXACT, DDA_MAJ, DDA_MEDIUM
from renderer.media.majorant import dda_advance, dda_init
from renderer.media.stack import EMPTY, MAX_STACK
from renderer.media.table import emission_rate, emits, is_grid, sigma_a, sigma_s, sigma_t

RR_THRESHOLD = 0.1
# Tentative collisions spent on a segment inside an emitting homogeneous entry of a grid
# stack (its emission is constant: a few samples of the segment suffice).
HOMOGENEOUS_EMISSION_COLLISIONS = 4.0
# Safety net against a walk that cannot advance (t + dt == t at absurd distances).
MAX_COLLISIONS = 10_000_000

# What an event did to the walk.
WALK_ON = 0
STOPPED = 1
KILLED = 2


@inline_kernel
def sigma_at(mt, stack, x):
    """(sigma_a, sigma_s) of the stack at world point x: entries' density x coefficients."""
    a0 = a1 = a2 = s0 = s1 = s2 = 0.0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        rho = medium_density(mt, m, x)
        if rho > 0.0:
            a = sigma_a(mt, m)
            s = sigma_s(mt, m)
            a0 += rho * a[0]
            a1 += rho * a[1]
            a2 += rho * a[2]
            s0 += rho * s[0]
            s1 += rho * s[1]
            s2 += rho * s[2]
    return (a0, a1, a2), (s0, s1, s2)


@kernel
def start_walk(mt, stack, o, d, t0, rows):
    """Start a DDA for every grid entry; return the homogeneous entries' summed sigma_t,
    whether any homogeneous entry emits, and the number of grid walkers in `rows`."""
    h0 = h1 = h2 = 0.0
    hom_emits = False
    n = 0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        if is_grid(mt, m):
            dda_init(mt, m, o, d, t0, rows[n])
            n += 1
        else:
            st = sigma_t(mt, m)
            h0 += st[0]
            h1 += st[1]
            h2 += st[2]
            hom_emits = hom_emits or emits(mt, m)
    return (h0, h1, h2), hom_emits, n


@inline_kernel
def emission_sampling_rate(with_emission, hom_emits, t0, t1):
    """The emission rate the walk raises the majorant to: -1 when emission is not sampled;
    else the homogeneous entries' (HOMOGENEOUS_EMISSION_COLLISIONS over the segment, when
    one of them emits), to which _piece adds the grid entries' rates in emitting cells."""
    rate = -1.0
    if with_emission:
        rate = 0.0
        if hom_emits and t1 - t0 < math.inf:
            rate = HOMOGENEOUS_EMISSION_COLLISIONS / (t1 - t0)
    return rate


@inline_kernel
def _piece(mt, rows, n, hom_sigma_t, hom_rate):
    """Majorant (per channel) of the current piece, where the piece ends, and the walker
    whose grid is crossed by regular tracking on it (-1: null-collision tracking).

    hom_rate < 0 means emission is not sampled; otherwise it is the homogeneous entries'
    emission rate and the grid entries' rates apply in their emitting cells. Regular
    tracking needs one grid entry with density on the piece, in a flagged cell, and no
    emission sampled there."""
    mu0, mu1, mu2 = hom_sigma_t
    end = math.inf
    lam = hom_rate
    dense = 0
    exact = -1
    for j in range(n):
        m = int(rows[j, DDA_MEDIUM])
        rho = rows[j, DDA_MAJ]
        if rho > 0.0:
            st = sigma_t(mt, m)
            mu0 += rho * st[0]
            mu1 += rho * st[1]
            mu2 += rho * st[2]
            dense += 1
            if rows[j, DDA_EXACT] > 0.0:
                exact = j
        if hom_rate >= 0.0 and rows[j, DDA_EMITS] > 0.0:
            lam = max(lam, emission_rate(mt, m))
        end = min(end, rows[j, DDA_END])
    if lam > 0.0:
        mu0 = max(mu0, lam)
        mu1 = max(mu1, lam)
        mu2 = max(mu2, lam)
        exact = -1
    if dense != 1:
        exact = -1
    return (mu0, mu1, mu2), end, exact


@inline_kernel
def _advance_walk(mt, rows, n, t):
    # `while`: pieces a rounding error made empty are skipped too.
    for j in range(n):
        while rows[j, DDA_END] <= t:
            dda_advance(mt, rows[j])


@inline_kernel
def exponential_depth(key, dim):
    """An optical depth with density exp(-depth): -log(1 - u), from dimension dim."""
    return -fm.log1p(-hashed_uniform(key, dim))


@inline_kernel
def decay(q, mu, dt):
    """q_c * exp(-mu_c dt) per channel (0 * inf safe)."""
    return (
        q[0] * math.exp(-optical_depth(mu[0], dt)),
        q[1] * math.exp(-optical_depth(mu[1], dt)),
        q[2] * math.exp(-optical_depth(mu[2], dt)),
    )


@inline_kernel
def mix(p, q):
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]


@inline_kernel
def scaled(q, s):
    return (q[0] / s, q[1] / s, q[2] / s)


@inline_kernel
def decay_both(f, q, mu, dt, p):
    """f and q decayed over dt, both renormalised by sum p q."""
    f = decay(f, mu, dt)
    q = decay(q, mu, dt)
    s = mix(p, q)
    return scaled(f, s), scaled(q, s)


@inline_kernel
def attenuated(q, tau, p):
    """q_k exp(-tau_k), renormalised (the common factor exp(-min tau) is dropped first, so a
    channel that sampled the flight, tau_c <= ~37, cannot underflow)."""
    low = min(tau[0], tau[1], tau[2])
    q = (q[0] * math.exp(low - tau[0]), q[1] * math.exp(low - tau[1]), q[2] * math.exp(low - tau[2]))
    return scaled(q, mix(p, q))


@inline_kernel
def unit_ray(mt, rows, j, o, d):
    """(medium, uo, ud, sigma_t) of walker j's grid: the ray in its unit cube."""
    m = int(rows[j, DDA_MEDIUM])
    return m, to_unit_point(mt, m, o), to_unit_vector(mt, m, d), sigma_t(mt, m)


@inline_kernel
def roulette(f, key, dim):
    """Russian roulette on a ratio-tracking estimate f: (f, alive, dim)."""
    m = max(f[0], f[1], f[2])
    if m >= RR_THRESHOLD:
        return f, True, dim
    if m <= 0.0:
        return f, False, dim
    survive = m / RR_THRESHOLD
    u = hashed_uniform(key, dim)
    dim += 1
    if u >= survive:
        return f, False, dim
    return scaled(f, survive), True, dim


@inline_kernel
def sigma_t_majorant(mt, rows, n, mu_t, env):
    """The `majorant` of trackers that sample the sigma_t majorant itself."""
    return mu_t


# The walk is a closure, compiled into each tracker that calls it (not cached on its own:
# its trackers are).
_WALK_OPTIONS = {**{k: v for k, v in JIT_OPTIONS.items() if k != "cache"}, "forceinline": True,
                 "no_cpython_wrapper": True, "no_cfunc_wrapper": True}


def make_walk(regular, majorant, collide, passed):
    """The walk over [t0, t1) with these decisions (see the module docstring):
    walk(mt, stack, o, d, t0, t1, p, key, dim, c, rows, n, hom_sigma_t, rate, env, state)
    -> (t, event, state, dim), for a walk started by start_walk (rows, n, hom_sigma_t) on
    technique c, with emission sampled at `rate` (emission_sampling_rate)."""

    def walk(mt, stack, o, d, t0, t1, p, key, dim, c, rows, n, hom_sigma_t, rate, env, state):
        t = t0
        collisions = 0
        while t < t1:
            mu_t, end, ex = _piece(mt, rows, n, hom_sigma_t, rate)
            end = min(end, t1)
            if ex >= 0:  # regular tracking across the piece
                t, event, state, dim = regular(mt, stack, o, d, t, end, p, key, dim, c, rows, ex, hom_sigma_t,
                                               env, state)
                if event != WALK_ON:
                    return t, event, state, dim
            else:
                mu = majorant(mt, rows, n, mu_t, env)
                while True:
                    dt = math.inf
                    if mu[c] > 0.0:
                        dt = exponential_depth(key, dim) / mu[c]
                        dim += 1
                    if t + dt >= end or collisions >= MAX_COLLISIONS:
                        state = passed(mu, end - t, p, state)
                        t = end
                        break
                    collisions += 1
                    t += dt
                    x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
                    event, state, dim = collide(mt, stack, o, d, t, x, mu, dt, p, c, key, dim, rate, env,
                                                state)
                    if event != WALK_ON:
                        return t, event, state, dim
            _advance_walk(mt, rows, n, t)
        return t1, WALK_ON, state, dim

    return njit(**_WALK_OPTIONS)(walk)
