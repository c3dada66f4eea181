"""Null-collision tracking through medium stacks that contain grid media.

The stack's majorant mu (per channel) is the sum of its entries' majorants: constant
sigma_t for homogeneous entries, (density bound of the current coarse cell) x sigma_t for
grid entries, walked by one DDA per grid entry (majorant.py). Where the stack emits, every
channel's mu is raised to at least an emission rate lambda so that emission is sampled
even where the extinction is ~0 (as Cycles raises its majorant to the emission).

Spectral MIS (pbrt-v4 style, balance heuristic over the three channels' techniques).
Technique c samples tentative collisions with rate mu_c and calls a collision real with
probability sigma_t,c(x) / mu_c. For a sampled walk, q_c is its pdf under technique c
(products of exp(-mu_c dt) and sigma_n,c = mu_c - sigma_t,c or sigma_t,c), kept only up
to a common factor (renormalised every step, so it never under- or overflows). Because
the null-scattering contribution f_k of channel k has the same factors as q_k except at
the final event, every estimate is a ratio q_k / sum_c p_c q_c:

    scattered at t:   weight_k = q_k sigma_s,k / sum_c p_c q_c sigma_t,c
    passed to t1:     weight_k = q_k / sum_c p_c q_c
    emission at every tentative collision x:  Le_k += E_k(x) q_k / sum_c p_c q_c mu_c

Each is bounded by (albedo or E/mu) / p_k, whatever the channels' contrast (sigma_t of 0
next to 1e6), and unbiased per channel as long as p_k > 0. Channels the caller gives
p_k = 0 (zero throughput) get weight 0.

Ratio tracking (transmittance): technique c places points as a Poisson process of rate
mu_c; channel k's estimate is f_k / sum_c p_c pdf_c with f_k = prod sigma_n,k(x_i) exp(-int
mu_k) and pdf_c = prod mu_c exp(-int mu_c). Russian roulette once every channel's running
estimate is below RR_THRESHOLD keeps it unbiased and cheap in dense media.

Regular tracking (regular.py) crosses the majorant cells compile.py flags (a bound far
above the density somewhere in the cell), when the piece has one grid entry and samples no
emission: technique c then samples the exact free-flight distribution of channel c, its
pdf is sigma_t,c(x) exp(-tau_c) (collision) or exp(-tau_c) (passing) with no null events,
so q_c gains exp(-tau_c) and the estimates above keep their form. Ratio tracking multiplies
f_k by the exact transmittance exp(-tau_k) of the piece, which all techniques share.
"""

import math

import numpy as np

from renderer.kernels import fastmath as fm
from renderer.kernels import inline_kernel, kernel
from renderer.kernels.rng import hashed_uniform
from renderer.media.emission import stack_emission
from renderer.media.grid import medium_density, to_unit_point, to_unit_vector
from renderer.media.homogeneous import optical_depth
from renderer.media.layout import DDA_EMITS, DDA_END, DDA_EXACT, DDA_MAJ, DDA_MEDIUM
from renderer.media.majorant import dda_advance, dda_init
from renderer.media.regular import optical_depths, sample_flight
from renderer.media.spectral import THIRD, pick_channel
from renderer.media.stack import EMPTY, MAX_STACK, stack_has_emission
from renderer.media.table import emission_rate, emits, is_grid, sigma_a, sigma_s, sigma_t

RR_THRESHOLD = 0.1
# Tentative collisions spent on a segment inside an emitting homogeneous entry of a grid
# stack (its emission is constant: a few samples of the segment suffice).
HOMOGENEOUS_EMISSION_COLLISIONS = 4.0
# Safety net against a walk that cannot advance (t + dt == t at absurd distances).
MAX_COLLISIONS = 10_000_000


@inline_kernel
def _sigma_at(mt, stack, x):
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
def _start_walk(mt, stack, o, d, t0, rows):
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
def _decay(q, mu, dt):
    """q_c * exp(-mu_c dt) per channel (0 * inf safe)."""
    return (
        q[0] * math.exp(-optical_depth(mu[0], dt)),
        q[1] * math.exp(-optical_depth(mu[1], dt)),
        q[2] * math.exp(-optical_depth(mu[2], dt)),
    )


@inline_kernel
def _mix(p, q):
    return p[0] * q[0] + p[1] * q[1] + p[2] * q[2]


@inline_kernel
def _scaled(q, s):
    return (q[0] / s, q[1] / s, q[2] / s)


@inline_kernel
def _attenuated(q, tau, p):
    """q_k exp(-tau_k), renormalised (the common factor exp(-min tau) is dropped first, so a
    channel that sampled the flight, tau_c <= ~37, cannot underflow)."""
    low = min(tau[0], tau[1], tau[2])
    q = (q[0] * math.exp(low - tau[0]), q[1] * math.exp(low - tau[1]), q[2] * math.exp(low - tau[2]))
    return _scaled(q, _mix(p, q))


@inline_kernel
def _unit_ray(mt, rows, j, o, d):
    """(medium, uo, ud, sigma_t) of walker j's grid: the ray in its unit cube."""
    m = int(rows[j, DDA_MEDIUM])
    return m, to_unit_point(mt, m, o), to_unit_vector(mt, m, d), sigma_t(mt, m)


@inline_kernel
def _roulette(f, key, dim):
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
    return _scaled(f, survive), True, dim


@kernel
def delta_track(mt, stack, o, d, t0, t1, p, key, dim, with_emission, rows):
    """Delta tracking with spectral MIS over [t0, t1): (t, collided, weight3, Le3, dim).

    collided: a real collision at t with weight3 = q sigma_s / sum p q sigma_t (scattering;
    for transmittance the caller treats it as 0). Otherwise t = t1 and weight3 = q / sum p q.
    """
    hom_sigma_t, hom_emits, n = _start_walk(mt, stack, o, d, t0, rows)
    rate = -1.0
    if with_emission:
        rate = 0.0
        if hom_emits and t1 - t0 < math.inf:
            rate = HOMOGENEOUS_EMISSION_COLLISIONS / (t1 - t0)
    q = (1.0 if p[0] > 0.0 else 0.0, 1.0 if p[1] > 0.0 else 0.0, 1.0 if p[2] > 0.0 else 0.0)
    q = _scaled(q, _mix(p, q))
    le0 = le1 = le2 = 0.0
    c = pick_channel(p, hashed_uniform(key, dim))
    dim += 1
    t = t0
    collisions = 0
    while t < t1:
        mu, end, ex = _piece(mt, rows, n, hom_sigma_t, rate)
        end = min(end, t1)
        if ex >= 0:  # regular tracking across the piece
            m, uo, ud, st_grid = _unit_ray(mt, rows, ex, o, d)
            depth = -fm.log1p(-hashed_uniform(key, dim))
            dim += 1
            t, hit, tau = sample_flight(mt, m, uo, ud, t, end, depth, c, st_grid, hom_sigma_t)
            q = _attenuated(q, tau, p)
            if hit:
                x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
                sa, ss = _sigma_at(mt, stack, x)
                st = (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])
                denom = p[0] * q[0] * st[0] + p[1] * q[1] * st[1] + p[2] * q[2] * st[2]
                if denom > 0.0:  # (0 only for a zero-length flight onto zero density: walk on)
                    w = (q[0] * ss[0] / denom, q[1] * ss[1] / denom, q[2] * ss[2] / denom)
                    return t, True, w, (le0, le1, le2), dim
            _advance_walk(mt, rows, n, t)
            continue
        while True:
            dt = math.inf
            if mu[c] > 0.0:
                dt = -fm.log1p(-hashed_uniform(key, dim)) / mu[c]
                dim += 1
            if t + dt >= end or collisions >= MAX_COLLISIONS:
                q = _decay(q, mu, end - t)
                q = _scaled(q, _mix(p, q))
                t = end
                break
            collisions += 1
            t += dt
            q = _decay(q, mu, dt)
            x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
            sa, ss = _sigma_at(mt, stack, x)
            st = (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])
            if rate >= 0.0:
                e = stack_emission(mt, stack, x)
                denom = p[0] * q[0] * mu[0] + p[1] * q[1] * mu[1] + p[2] * q[2] * mu[2]
                le0 += e[0] * q[0] / denom
                le1 += e[1] * q[1] / denom
                le2 += e[2] * q[2] / denom
            u = hashed_uniform(key, dim)
            dim += 1
            if u * mu[c] < st[c]:
                denom = p[0] * q[0] * st[0] + p[1] * q[1] * st[1] + p[2] * q[2] * st[2]
                w = (q[0] * ss[0] / denom, q[1] * ss[1] / denom, q[2] * ss[2] / denom)
                return t, True, w, (le0, le1, le2), dim
            # null collision: sigma_n = mu - sigma_t (>= 0 up to rounding: mu bounds sigma_t)
            q = (
                q[0] * max(mu[0] - st[0], 0.0),
                q[1] * max(mu[1] - st[1], 0.0),
                q[2] * max(mu[2] - st[2], 0.0),
            )
            q = _scaled(q, _mix(p, q))
        _advance_walk(mt, rows, n, t)
    return t1, False, q, (le0, le1, le2), dim


@kernel
def ratio_track(mt, stack, o, d, t0, t1, p, key, dim, rows):
    """Ratio tracking with spectral MIS and Russian roulette: (Tr3 estimate, dim)."""
    hom_sigma_t, _, n = _start_walk(mt, stack, o, d, t0, rows)
    f = (1.0, 1.0, 1.0)
    q = (1.0, 1.0, 1.0)
    c = pick_channel(p, hashed_uniform(key, dim))
    dim += 1
    t = t0
    collisions = 0
    while t < t1:
        mu, end, ex = _piece(mt, rows, n, hom_sigma_t, -1.0)
        end = min(end, t1)
        if ex >= 0:  # exact transmittance of the piece: every technique's pdf is 1 on it
            m, uo, ud, st_grid = _unit_ray(mt, rows, ex, o, d)
            tau = optical_depths(mt, m, uo, ud, t, end, st_grid, hom_sigma_t)
            f = (f[0] * math.exp(-tau[0]), f[1] * math.exp(-tau[1]), f[2] * math.exp(-tau[2]))
            f, alive, dim = _roulette(f, key, dim)
            if not alive:
                return (0.0, 0.0, 0.0), dim
            t = end
            _advance_walk(mt, rows, n, t)
            continue
        while True:
            dt = math.inf
            if mu[c] > 0.0:
                dt = -fm.log1p(-hashed_uniform(key, dim)) / mu[c]
                dim += 1
            if t + dt >= end or collisions >= MAX_COLLISIONS:
                f = _decay(f, mu, end - t)
                q = _decay(q, mu, end - t)
                s = _mix(p, q)
                f = _scaled(f, s)
                q = _scaled(q, s)
                t = end
                break
            collisions += 1
            t += dt
            x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
            sa, ss = _sigma_at(mt, stack, x)
            f = _decay(f, mu, dt)
            q = _decay(q, mu, dt)
            f = (
                f[0] * max(mu[0] - sa[0] - ss[0], 0.0),
                f[1] * max(mu[1] - sa[1] - ss[1], 0.0),
                f[2] * max(mu[2] - sa[2] - ss[2], 0.0),
            )
            q = (q[0] * mu[0], q[1] * mu[1], q[2] * mu[2])
            s = _mix(p, q)
            f = _scaled(f, s)
            q = _scaled(q, s)
            # Russian roulette on the running estimate f_k / sum p q (= f_k now).
            f, alive, dim = _roulette(f, key, dim)
            if not alive:
                return (0.0, 0.0, 0.0), dim
        _advance_walk(mt, rows, n, t)
    return f, dim


@kernel
def track_free_flight(mt, stack, o, d, tmax, p, key, dim):
    """sample_distance for grid stacks (see medium.sample_distance)."""
    rows = mt.scratch
    return delta_track(mt, stack, o, d, 0.0, tmax, p, key, dim, stack_has_emission(mt, stack), rows)


@kernel
def track_transmittance(mt, stack, o, d, t0, t1, key, dim, use_delta):
    """transmittance for grid stacks: ratio tracking, or delta tracking with use_delta.
    Channels are picked uniformly (a shadow ray has no throughput to follow)."""
    rows = mt.scratch
    p = (THIRD, THIRD, THIRD)
    if use_delta:
        _, collided, w, _, dim = delta_track(mt, stack, o, d, t0, t1, p, key, dim, np.bool_(False), rows)
        if collided:
            return (0.0, 0.0, 0.0), dim
        return w, dim
    return ratio_track(mt, stack, o, d, t0, t1, p, key, dim, rows)
