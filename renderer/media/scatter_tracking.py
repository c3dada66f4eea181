"""Scatter tracking: free flights through grid stacks that collide on scattering only.

Every medium here has sigma_a(x) = rho(x) a and sigma_s(x) = rho(x) s with constant
colours a, s (density x coefficient, table.py), so the transmittance factors per channel:

    T_k(t0, t) = exp(-int sigma_s,k) exp(-int sigma_a,k)

Delta tracking (tracking.py) samples a real collision against sigma_t and then scatters
with weight albedo: in a dark medium (the smoke ball: albedo 0.1) a path makes many short
flights, each one a scatter vertex with its next-event shadow ray, carrying weights of
0.1, 0.01, ... Here a tracker samples a real collision against sigma_s only, and the
absorption is folded into the path weight. Tentative collisions come at rate mu_c; one at
x is a real scatter with probability sigma_s,c(x) / mu_c, else a null collision. Two ways
to fold the absorption in, chosen per walk (the same for every technique):

  * exact (no emission sampled): mu_c = (density bound of the piece) x s_c plus the
    homogeneous entries' sigma_s,c, and exp(-tau_a,k) over every stretch the walk crosses
    is computed in closed form: the density integral of a grid between two planes of
    voxel centres is a cubic, which two-point Gauss-Legendre integrates exactly
    (regular.optical_depths). Its cost is one step per voxel plane crossed, whatever the
    density (a voxel of 1e8 costs no more than a voxel of 1), and only inside the grid's
    box (in sparse grids, empty bricks read 0 at once). It is applied once per flight, where the
    weight is used (at the scatter or at t1), so a tentative collision costs one density
    lookup, as in delta tracking, and a flight one integral.
  * by null-collision ratios (emission sampled): the emission estimate needs the weight at
    every tentative collision, where the integral would double the cost. mu_c is then the
    sigma_t majorant (raised to the emission rate, as in tracking.py), and channel k's own
    null coefficient mu_k - sigma_t,k (not mu_k - sigma_s,k) carries the absorption: in
    [0, 1] x the technique's, so no weight grows.

Spectral MIS as in tracking.py: technique c's walk pdf q_c has factors exp(-mu_c dt) and
(mu_c - sigma_s,c) at null collisions, sigma_s,c at the scatter. Channel k's contribution
f_k has the same factors with k for c, times exp(-tau_a,k) (exact), or with mu_k - sigma_t,k
at the null collisions (ratios). The estimates (f and q kept renormalised by
sum_c p_c q_c, so the weight is f_k itself):

    scattered at t:   weight_k = f_k sigma_s,k / sum_c p_c q_c sigma_s,c
    passed to t1:     weight_k = f_k / sum_c p_c q_c
    emission at every tentative collision x:  Le_k += E_k(x) f_k / sum_c p_c q_c mu_c

Each is at most the delta-tracking bound (f_k <= q_k), so 1 / p_k. Russian roulette on f
once every channel is below RR_THRESHOLD stops walks whose weight has become negligible
(unbiased: survivors are divided by the survival probability; in the exact mode f lacks the
pending absorption there, an upper bound, which only makes the roulette less eager).

Pieces that compile.py flags for regular tracking (a bound far above the density in the
cell: a lone dense voxel) are crossed as tracking.py crosses them: the exact free-flight
distribution of sigma_t,c, pdf sigma_t,c exp(-tau_t,c), where f and q both gain exp(-tau_t)
and a collision scatters with weight f_k sigma_s,k / sum_c p_c q_c sigma_t,c.

Procedural media have no density grid to integrate: scenes with one keep delta tracking for
every grid stack (free_flight chooses per table type).
"""

import math

from numba.core import types
from numba.extending import overload

from renderer.kernels import JIT_OPTIONS, inline_kernel, kernel
from renderer.kernels.rng import hashed_uniform
from renderer.media.emission import stack_emission
from renderer.media.grid import to_unit_point, to_unit_vector
from renderer.media.layout import DDA_MAJ, DDA_MEDIUM
from renderer.media.majorant_walk import (
    KILLED,
    STOPPED,
    WALK_ON,
    decay,
    decay_both,
    emission_sampling_rate,
    exponential_depth,
    make_walk,
    mix,
    roulette,
    scaled,
    sigma_at,
    start_walk,
    unit_ray,
)
from renderer.media.regular import optical_depths, sample_flight
from renderer.media.spectral import pick_channel
from renderer.media.stack import EMPTY, MAX_STACK, stack_has_emission
from renderer.media.table import is_grid, sigma_a, sigma_s
from renderer.media.tracking import track_free_flight

_OVERLOAD_OPTIONS = {k: v for k, v in JIT_OPTIONS.items() if k != "cache"}


@inline_kernel
def _homogeneous_parts(mt, stack):
    """(sigma_s, sigma_a) summed over the stack's homogeneous entries."""
    s0 = s1 = s2 = a0 = a1 = a2 = 0.0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        if not is_grid(mt, m):
            s = sigma_s(mt, m)
            a = sigma_a(mt, m)
            s0 += s[0]
            s1 += s[1]
            s2 += s[2]
            a0 += a[0]
            a1 += a[1]
            a2 += a[2]
    return (s0, s1, s2), (a0, a1, a2)


@inline_kernel
def _scatter_majorant(mt, rows, n, hom_s):
    """mu_c of the current piece: the grid entries' density bounds x s_c plus hom_s."""
    mu0, mu1, mu2 = hom_s
    for j in range(n):
        m = int(rows[j, DDA_MEDIUM])
        rho = rows[j, DDA_MAJ]
        if rho > 0.0:
            s = sigma_s(mt, m)
            mu0 += rho * s[0]
            mu1 += rho * s[1]
            mu2 += rho * s[2]
    return (mu0, mu1, mu2)


@inline_kernel
def _clip_to_box(uo, ud, a, b):
    """[a, b] cut to the part of the ray uo + t ud inside the unit cube (lo >= hi: empty)."""
    lo, hi = a, b
    for k in range(3):
        if ud[k] != 0.0:
            ta = (0.0 - uo[k]) / ud[k]
            tb = (1.0 - uo[k]) / ud[k]
            lo = max(lo, min(ta, tb))
            hi = min(hi, max(ta, tb))
        elif not (0.0 <= uo[k] <= 1.0):
            return b, a
    return lo, hi


@kernel
def _absorption(mt, stack, o, d, a, b, hom_a):
    """tau_a per channel over [a, b]: hom_a (b - a) plus, for every grid entry that
    absorbs, a x (exact density integral over the part of [a, b] inside its box)."""
    h = b - a
    t0, t1, t2 = hom_a[0] * h, hom_a[1] * h, hom_a[2] * h
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        if not is_grid(mt, m):
            continue
        ac = sigma_a(mt, m)
        if ac[0] <= 0.0 and ac[1] <= 0.0 and ac[2] <= 0.0:
            continue
        uo = to_unit_point(mt, m, o)
        ud = to_unit_vector(mt, m, d)
        lo, hi = _clip_to_box(uo, ud, a, b)
        if lo < hi:
            tau = optical_depths(mt, m, uo, ud, lo, hi, ac, (0.0, 0.0, 0.0))
            t0 += tau[0]
            t1 += tau[1]
            t2 += tau[2]
    return (t0, t1, t2)


@inline_kernel
def _absorb(f, tau):
    """f_k exp(-tau_a,k)."""
    return (f[0] * math.exp(-tau[0]), f[1] * math.exp(-tau[1]), f[2] * math.exp(-tau[2]))


@inline_kernel
def _times(v, w):
    return (v[0] * w[0], v[1] * w[1], v[2] * w[2])


@inline_kernel
def _null(mu, sigma):
    """mu - sigma per channel (>= 0 up to rounding: mu bounds sigma)."""
    return (max(mu[0] - sigma[0], 0.0), max(mu[1] - sigma[1], 0.0), max(mu[2] - sigma[2], 0.0))


@inline_kernel
def _scatter_weight(f, q, p, ss, sigma):
    """f_k sigma_s,k / sum_c p_c q_c sigma_c (sigma: what the technique collided against)."""
    denom = p[0] * q[0] * sigma[0] + p[1] * q[1] * sigma[1] + p[2] * q[2] * sigma[2]
    return (f[0] * ss[0] / denom, f[1] * ss[1] / denom, f[2] * ss[2] / denom)


# Scatter tracking's decisions (majorant_walk.make_walk). env: (hom_s, hom_a, folded);
# state: (f, q, Le, ta), ta where f's absorption was last applied (exact mode: lazily, see
# the docstring); at a scatter f is replaced by the weight.

@inline_kernel
def _scatter_regular(mt, stack, o, d, t, end, p, key, dim, c, rows, j, hom_sigma_t, env, state):
    """Regular tracking of sigma_t across the piece (see the docstring)."""
    _, hom_a, folded = env
    f, q, le, ta = state
    if not folded:  # (never: no regular pieces where emission is sampled)
        f = _absorb(f, _absorption(mt, stack, o, d, ta, t, hom_a))
    m, uo, ud, st_grid = unit_ray(mt, rows, j, o, d)
    depth = exponential_depth(key, dim)
    dim += 1
    t, hit, tau = sample_flight(mt, m, uo, ud, t, end, depth, c, st_grid, hom_sigma_t)
    ta = t  # tau_t holds the absorption of the regular piece
    # f and q share the factor exp(-tau_t) here: drop the common exp(-min tau) first so
    # that neither underflows, then renormalise both by sum p q.
    low = min(tau[0], tau[1], tau[2])
    g = (math.exp(low - tau[0]), math.exp(low - tau[1]), math.exp(low - tau[2]))
    f = _times(f, g)
    q = _times(q, g)
    s = mix(p, q)
    f = scaled(f, s)
    q = scaled(q, s)
    if hit:
        x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
        sa, ss = sigma_at(mt, stack, x)
        st = (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])
        if mix(p, _times(q, st)) > 0.0:  # (0 only for a zero-length flight onto zero density)
            return t, STOPPED, (_scatter_weight(f, q, p, ss, st), q, le, ta), dim
    return t, WALK_ON, (f, q, le, ta), dim


@inline_kernel
def _scatter_majorant_of(mt, rows, n, mu_t, env):
    """Emission sampled (folded): the sigma_t majorant; else the sigma_s one."""
    hom_s, _, folded = env
    return mu_t if folded else _scatter_majorant(mt, rows, n, hom_s)


@inline_kernel
def _scatter_collide(mt, stack, o, d, t, x, mu, dt, p, c, key, dim, rate, env, state):
    _, hom_a, folded = env
    f, q, le, ta = state
    f = decay(f, mu, dt)
    q = decay(q, mu, dt)
    sa, ss = sigma_at(mt, stack, x)
    if folded:
        e = stack_emission(mt, stack, x)
        denom = mix(p, _times(q, mu))
        le = (le[0] + e[0] * f[0] / denom, le[1] + e[1] * f[1] / denom, le[2] + e[2] * f[2] / denom)
    u = hashed_uniform(key, dim)
    dim += 1
    if u * mu[c] < ss[c]:
        if not folded:
            f = _absorb(f, _absorption(mt, stack, o, d, ta, t, hom_a))
        return STOPPED, (_scatter_weight(f, q, p, ss, ss), q, le, ta), dim
    sn = _null(mu, ss)
    q = _times(q, sn)
    if folded:  # channel k's own null coefficient mu_k - sigma_t,k
        f = _times(f, _null(mu, (sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2])))
    else:
        f = _times(f, sn)
    s = mix(p, q)
    f = scaled(f, s)
    q = scaled(q, s)
    # (exact mode: f still lacks the absorption over [ta, t]; roulette on this
    # upper bound is as unbiased, only less eager.)
    f, alive, dim = roulette(f, key, dim)
    if not alive:
        return KILLED, ((0.0, 0.0, 0.0), q, le, ta), dim
    return WALK_ON, (f, q, le, ta), dim


@inline_kernel
def _scatter_passed(mu, dt, p, state):
    f, q, le, ta = state
    f, q = decay_both(f, q, mu, dt, p)
    return f, q, le, ta


_scatter_walk = make_walk(_scatter_regular, _scatter_majorant_of, _scatter_collide, _scatter_passed)


@kernel
def scatter_track(mt, stack, o, d, t0, t1, p, key, dim, with_emission, rows):
    """Scatter tracking with spectral MIS over [t0, t1): (t, scattered, weight3, Le3, dim),
    as tracking.delta_track. A walk ended by Russian roulette returns weight (0, 0, 0)."""
    hom_sigma_t, hom_emits, n = start_walk(mt, stack, o, d, t0, rows)
    hom_s, hom_a = _homogeneous_parts(mt, stack)
    folded = with_emission  # absorption by null-collision ratios, not by its integral
    rate = emission_sampling_rate(with_emission, hom_emits, t0, t1)
    q = (1.0 if p[0] > 0.0 else 0.0, 1.0 if p[1] > 0.0 else 0.0, 1.0 if p[2] > 0.0 else 0.0)
    q = scaled(q, mix(p, q))
    c = pick_channel(p, hashed_uniform(key, dim))
    dim += 1
    env = (hom_s, hom_a, folded)
    state = (q, q, (0.0, 0.0, 0.0), t0)  # f = q at the start
    t, event, (f, _, le, ta), dim = _scatter_walk(mt, stack, o, d, t0, t1, p, key, dim, c, rows, n,
                                                  hom_sigma_t, rate, env, state)
    if event != WALK_ON:
        return t, event == STOPPED, f, le, dim
    if not folded:
        f = _absorb(f, _absorption(mt, stack, o, d, ta, t1, hom_a))
    return t1, False, f, le, dim


def free_flight(mt, stack, o, d, tmax, p, key, dim):
    """sample_distance for grid stacks (see medium.sample_distance): scatter tracking, or
    delta tracking (tracking.py) in scenes with a procedural medium. Chosen per table type
    (an overload, below), not per stack: a ProceduralMediaTable's kernels then compile one
    tracker, not both (with both, the add-on's cold compile of shade_media for a procedural
    scene was still running after 13 CPU minutes)."""
    raise TypeError("free_flight runs inside kernels only")


@overload(free_flight, jit_options=_OVERLOAD_OPTIONS)
def _free_flight(mt, stack, o, d, tmax, p, key, dim):
    fields = tuple(getattr(mt, "fields", ()))
    if "programs" in fields and not isinstance(mt.types[fields.index("programs")], types.NoneType):
        def delta(mt, stack, o, d, tmax, p, key, dim):
            return track_free_flight(mt, stack, o, d, tmax, p, key, dim)

        return delta

    def scatter(mt, stack, o, d, tmax, p, key, dim):
        emission = stack_has_emission(mt, stack)
        return scatter_track(mt, stack, o, d, 0.0, tmax, p, key, dim, emission, mt.scratch)

    return scatter
