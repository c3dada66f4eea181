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

from renderer.kernels import inline_kernel, kernel
from renderer.kernels.rng import hashed_uniform
from renderer.media.emission import stack_emission
from renderer.media.majorant_walk import (
    KILLED,
    STOPPED,
    WALK_ON,
    attenuated,
    decay,
    decay_both,
    emission_sampling_rate,
    exponential_depth,
    make_walk,
    mix,
    roulette,
    scaled,
    sigma_at,
    sigma_t_majorant,
    start_walk,
    unit_ray,
)
from renderer.media.regular import optical_depths, sample_flight
from renderer.media.spectral import THIRD, pick_channel
from renderer.media.stack import stack_has_emission

_sigma_at = sigma_at  # (the name tests know it by)


# Delta tracking's decisions (majorant_walk.make_walk). state: (q, Le); at a collision q is
# replaced by the scattering weight.

@inline_kernel
def _delta_regular(mt, stack, o, d, t, end, p, key, dim, c, rows, j, hom_sigma_t, env, state):
    q, le = state
    m, uo, ud, st_grid = unit_ray(mt, rows, j, o, d)
    depth = exponential_depth(key, dim)
    dim += 1
    t, hit, tau = sample_flight(mt, m, uo, ud, t, end, depth, c, st_grid, hom_sigma_t)
    q = attenuated(q, tau, p)
    if hit:
        x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
        sa, ss = sigma_at(mt, stack, x)
        st = (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])
        denom = p[0] * q[0] * st[0] + p[1] * q[1] * st[1] + p[2] * q[2] * st[2]
        if denom > 0.0:  # (0 only for a zero-length flight onto zero density: walk on)
            w = (q[0] * ss[0] / denom, q[1] * ss[1] / denom, q[2] * ss[2] / denom)
            return t, STOPPED, (w, le), dim
    return t, WALK_ON, (q, le), dim


@inline_kernel
def _delta_collide(mt, stack, o, d, t, x, mu, dt, p, c, key, dim, rate, env, state):
    q, le = state
    q = decay(q, mu, dt)
    sa, ss = sigma_at(mt, stack, x)
    st = (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])
    if rate >= 0.0:
        e = stack_emission(mt, stack, x)
        denom = p[0] * q[0] * mu[0] + p[1] * q[1] * mu[1] + p[2] * q[2] * mu[2]
        le = (le[0] + e[0] * q[0] / denom, le[1] + e[1] * q[1] / denom, le[2] + e[2] * q[2] / denom)
    u = hashed_uniform(key, dim)
    dim += 1
    if u * mu[c] < st[c]:
        denom = p[0] * q[0] * st[0] + p[1] * q[1] * st[1] + p[2] * q[2] * st[2]
        w = (q[0] * ss[0] / denom, q[1] * ss[1] / denom, q[2] * ss[2] / denom)
        return STOPPED, (w, le), dim
    # null collision: sigma_n = mu - sigma_t (>= 0 up to rounding: mu bounds sigma_t)
    q = (
        q[0] * max(mu[0] - st[0], 0.0),
        q[1] * max(mu[1] - st[1], 0.0),
        q[2] * max(mu[2] - st[2], 0.0),
    )
    return WALK_ON, (scaled(q, mix(p, q)), le), dim


@inline_kernel
def _delta_passed(mu, dt, p, state):
    q, le = state
    q = decay(q, mu, dt)
    return scaled(q, mix(p, q)), le


_delta_walk = make_walk(_delta_regular, sigma_t_majorant, _delta_collide, _delta_passed)


@kernel
def delta_track(mt, stack, o, d, t0, t1, p, key, dim, with_emission, rows):
    """Delta tracking with spectral MIS over [t0, t1): (t, collided, weight3, Le3, dim).

    collided: a real collision at t with weight3 = q sigma_s / sum p q sigma_t (scattering;
    for transmittance the caller treats it as 0). Otherwise t = t1 and weight3 = q / sum p q.
    """
    hom_sigma_t, hom_emits, n = start_walk(mt, stack, o, d, t0, rows)
    rate = emission_sampling_rate(with_emission, hom_emits, t0, t1)
    q = (1.0 if p[0] > 0.0 else 0.0, 1.0 if p[1] > 0.0 else 0.0, 1.0 if p[2] > 0.0 else 0.0)
    q = scaled(q, mix(p, q))
    c = pick_channel(p, hashed_uniform(key, dim))
    dim += 1
    t, event, (w, le), dim = _delta_walk(mt, stack, o, d, t0, t1, p, key, dim, c, rows, n, hom_sigma_t, rate,
                                         0, (q, (0.0, 0.0, 0.0)))
    return t, event == STOPPED, w, le, dim


# Ratio tracking's decisions. state: (f, q), both renormalised by sum p q; f is zeroed when
# Russian roulette ends the walk.

@inline_kernel
def _ratio_regular(mt, stack, o, d, t, end, p, key, dim, c, rows, j, hom_sigma_t, env, state):
    """Exact transmittance of the piece: every technique's pdf is 1 on it."""
    f, q = state
    m, uo, ud, st_grid = unit_ray(mt, rows, j, o, d)
    tau = optical_depths(mt, m, uo, ud, t, end, st_grid, hom_sigma_t)
    f = (f[0] * math.exp(-tau[0]), f[1] * math.exp(-tau[1]), f[2] * math.exp(-tau[2]))
    f, alive, dim = roulette(f, key, dim)
    if not alive:
        return t, KILLED, ((0.0, 0.0, 0.0), q), dim
    return end, WALK_ON, (f, q), dim


@inline_kernel
def _ratio_collide(mt, stack, o, d, t, x, mu, dt, p, c, key, dim, rate, env, state):
    f, q = state
    sa, ss = sigma_at(mt, stack, x)
    f = decay(f, mu, dt)
    q = decay(q, mu, dt)
    f = (
        f[0] * max(mu[0] - sa[0] - ss[0], 0.0),
        f[1] * max(mu[1] - sa[1] - ss[1], 0.0),
        f[2] * max(mu[2] - sa[2] - ss[2], 0.0),
    )
    q = (q[0] * mu[0], q[1] * mu[1], q[2] * mu[2])
    s = mix(p, q)
    f = scaled(f, s)
    q = scaled(q, s)
    # Russian roulette on the running estimate f_k / sum p q (= f_k now).
    f, alive, dim = roulette(f, key, dim)
    if not alive:
        return KILLED, ((0.0, 0.0, 0.0), q), dim
    return WALK_ON, (f, q), dim


@inline_kernel
def _ratio_passed(mu, dt, p, state):
    f, q = state
    return decay_both(f, q, mu, dt, p)


_ratio_walk = make_walk(_ratio_regular, sigma_t_majorant, _ratio_collide, _ratio_passed)


@kernel
def ratio_track(mt, stack, o, d, t0, t1, p, key, dim, rows):
    """Ratio tracking with spectral MIS and Russian roulette: (Tr3 estimate, dim)."""
    hom_sigma_t, _, n = start_walk(mt, stack, o, d, t0, rows)
    c = pick_channel(p, hashed_uniform(key, dim))
    dim += 1
    one = (1.0, 1.0, 1.0)
    _, _, (f, _), dim = _ratio_walk(mt, stack, o, d, t0, t1, p, key, dim, c, rows, n, hom_sigma_t, -1.0, 0,
                                    (one, one))
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
