"""The medium interface the integrator calls: sample a distance, give a transmittance.

Both act on a whole medium stack (see stack.py) along a world-space ray o + t d with unit d.
Stacks of homogeneous media use Beer's law in closed form; a stack with any grid medium is
tracked with null collisions against a majorant walked through coarse majorant grids
(tracking.py; free flights by scatter tracking, scatter_tracking.py). Random numbers come
from hashed_uniform(key, dim); every function returns the advanced dimension counter.
"""

from renderer.kernels import inline_kernel, kernel
from renderer.kernels.rng import hashed_uniform
from renderer.media.homogeneous import (
    beer,
    emission_integral,
    free_flight_segment,
    segment,
    stack_constant_emission,
    stack_sigma,
)
from renderer.media.scatter_tracking import free_flight
from renderer.media.spectral import channel_probabilities
from renderer.media.stack import stack_has_emission, stack_has_grid, stack_is_empty
from renderer.media.tracking import track_transmittance


@kernel
def sample_distance(mt, stack, o, d, tmax, throughput, key, dim, uniform_channel):
    """Free-flight sampling over [0, tmax): (t, scattered, weight3, Le3, dim).

    scattered:     the path scatters at t (sample the phase function there) and its
                   throughput is multiplied by weight3 = T(t) sigma_s(t) / pdf(t).
    not scattered: t = tmax and weight3 = T(tmax) / P(no collision); the path goes on to
                   whatever ends the segment (surface, boundary, escape).
    Le3: emission gathered on the segment, to be added as throughput * Le3 with the
         throughput from BEFORE multiplying by weight3. Homogeneous stacks give the whole
         segment's integral_0^tmax T(t) E dt in closed form (whether or not the path
         scatters, as Cycles does); grid stacks give an unbiased collision estimate.
    Channel selection for spectral MIS is proportional to `throughput` (uniform 1/3 with
    uniform_channel). Absorption stays in the weight: no path is terminated here.
    """
    if stack_is_empty(stack):
        return tmax, False, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), dim
    p = channel_probabilities(throughput, uniform_channel)
    if stack_has_grid(mt, stack):
        return free_flight(mt, stack, o, d, tmax, p, key, dim)
    return sample_segment(mt, stack, segment(mt, stack, tmax), tmax, p, key, dim)


@kernel
def sample_segment(mt, stack, seg, tmax, p, key, dim):
    """sample_distance for a HOMOGENEOUS stack given its segment constants
    (homogeneous.segment) and channel probabilities p."""
    sa, ss, st, tr_end, _ = seg
    if ss[0] <= 0.0 and ss[1] <= 0.0 and ss[2] <= 0.0:
        # Nothing scatters: the segment's transmittance is the whole answer, exactly (a
        # sampled collision could only absorb the path, adding noise and no information).
        t, scattered, weight = tmax, False, tr_end
    else:
        t, scattered, weight = free_flight_segment(ss, st, tr_end, tmax, p, hashed_uniform(key, dim),
                                                   hashed_uniform(key, dim + 1))
    return t, scattered, weight, segment_emission(mt, stack, st, tmax), dim + 2


@inline_kernel
def segment_emission(mt, stack, sigma_t, tmax):
    """integral_0^tmax T(t) E dt of a HOMOGENEOUS stack (0 when nothing in it emits)."""
    if stack_has_emission(mt, stack):
        return emission_integral(stack_constant_emission(mt, stack), sigma_t, tmax)
    return (0.0, 0.0, 0.0)


@inline_kernel
def transmittance(mt, stack, o, d, t0, t1, key, dim, use_delta):
    """Transmittance of the stack between o + t0 d and o + t1 d: (Tr3, dim).

    Homogeneous stacks: exp(-sigma_t (t1 - t0)) exactly (no random numbers used).
    Grid stacks: an unbiased estimate per channel, by ratio tracking with Russian roulette
    (default) or delta tracking (use_delta, the paper's choice; values 0 or a per-channel
    MIS weight).
    """
    if stack_is_empty(stack) or not t1 > t0:
        return (1.0, 1.0, 1.0), dim
    if stack_has_grid(mt, stack):
        return track_transmittance(mt, stack, o, d, t0, t1, key, dim, use_delta)
    return homogeneous_transmittance(mt, stack, t0, t1), dim


@inline_kernel
def homogeneous_transmittance(mt, stack, t0, t1):
    """transmittance of a stack WITHOUT grids: exp(-sigma_t (t1 - t0)), no random numbers."""
    if stack_is_empty(stack) or not t1 > t0:
        return (1.0, 1.0, 1.0)
    sa, ss = stack_sigma(mt, stack)
    return beer((sa[0] + ss[0], sa[1] + ss[1], sa[2] + ss[2]), t1 - t0)


@kernel
def grid_sample_distance(grid_mt, stack, o, d, tmax, throughput, key, dim, uniform_channel):
    """sample_distance for the integrator, with grid_mt the media table of a scene that has
    grid media and None otherwise: then numba prunes the call (a branch on an argument's
    None type) and compiles no tracker for the scene (the integrator calls this only for
    stacks with grids, which such a scene never has)."""
    if grid_mt is None:
        return tmax, False, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), dim
    return sample_distance(grid_mt, stack, o, d, tmax, throughput, key, dim, uniform_channel)
