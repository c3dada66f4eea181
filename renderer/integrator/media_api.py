"""The medium operations the integrator calls (adapter over renderer.media).

TEMPORARY: stand-ins until renderer.media lands; surface scenes never reach them.
"""

import math

from numba import njit


@njit(cache=True)
def stack_is_empty(stack):
    for j in range(stack.shape[0]):
        if stack[j] >= 0:
            return False
    return True


@njit(cache=True)
def stack_has_grid(md, stack):
    return False


@njit(cache=True)
def stack_push(stack, m):
    for j in range(stack.shape[0]):
        if stack[j] < 0:
            stack[j] = m
            return


@njit(cache=True)
def stack_remove(stack, m):
    for j in range(stack.shape[0]):
        if stack[j] == m:
            stack[j] = -1
            return


@njit(cache=True)
def sample_distance(md, stack, o, d, tmax, throughput, key, dim, uniform_channel):
    return tmax, False, (1.0, 1.0, 1.0), (0.0, 0.0, 0.0), dim


@njit(cache=True)
def transmittance(md, stack, o, d, t0, t1, key, dim, use_delta):
    return (1.0, 1.0, 1.0), dim


@njit(cache=True)
def sample_phase(md, stack, p, d, u_sel, u1, u2):
    z = 1.0 - 2.0 * u1
    r = math.sqrt(max(0.0, 1.0 - z * z))
    return (r * math.cos(2 * math.pi * u2), r * math.sin(2 * math.pi * u2), z), 0.25 / math.pi


@njit(cache=True)
def phase_pdf(md, stack, p, d, wi):
    return 0.25 / math.pi


@njit(cache=True)
def nee_vertex(md, stack, o, d, tmax, light_p, throughput, key, dim, use_equiangular, uniform_channel):
    return 0.0, (0.0, 0.0, 0.0), dim
