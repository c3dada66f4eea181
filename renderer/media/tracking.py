"""Null-collision tracking through stacks that contain grid media (stage 2: stub)."""

from numba import njit


@njit(cache=True)
def track_free_flight(mt, stack, o, d, tmax, p, key, dim):
    return tmax, False, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), dim


@njit(cache=True)
def track_transmittance(mt, stack, o, d, t0, t1, key, dim, use_delta):
    return (1.0, 1.0, 1.0), dim
