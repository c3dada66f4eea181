"""Emission of media: a source per unit length (Cycles' convention).

Along a ray a path gains integral T(t) E(t) dt, with E in W/(m^3 sr) (radiance per unit
length). As in Cycles' Principled Volume, emission is NOT multiplied by density:

    homogeneous:  E = emission                          (wherever the stack holds it)
    grid:         E = emission * flame(u)               (flame grid given)
                    = emission                          (no flame grid)
                    + blackbody(u)                      (temperature grid given)
    inside the grid's unit box, and 0 outside it (u = grid unit-cube coordinates), where
    blackbody(u) is the trilinear mix of blackbody_emission(temperature, intensity) of the
    voxels around u: emission interpolated, not temperature, as Cycles renders it (see
    renderer.media.blackbody).
"""

from renderer.kernels import inline_kernel, kernel
from renderer.media.grid import grid_lookup, grid_lookup3, to_unit_point
from renderer.media.layout import GRID_BLACKBODY, GRID_FLAME
from renderer.media.stack import EMPTY, MAX_STACK
from renderer.media.table import emission, emits, grid_offset, is_grid


@inline_kernel
def medium_emission(mt, m, p):
    """Emission of medium m at world point p (per unit length, RGB)."""
    if not emits(mt, m):
        return (0.0, 0.0, 0.0)
    e = emission(mt, m)
    if not is_grid(mt, m):
        return e
    u = to_unit_point(mt, m, p)
    if not (0.0 <= u[0] <= 1.0 and 0.0 <= u[1] <= 1.0 and 0.0 <= u[2] <= 1.0):
        return (0.0, 0.0, 0.0)
    if grid_offset(mt, m, GRID_FLAME) >= 0:
        f = grid_lookup(mt, m, GRID_FLAME, u)
        e = (e[0] * f, e[1] * f, e[2] * f)
    if grid_offset(mt, m, GRID_BLACKBODY) >= 0:
        b = grid_lookup3(mt, m, GRID_BLACKBODY, u)
        e = (e[0] + b[0], e[1] + b[1], e[2] + b[2])
    return e


@kernel
def stack_emission(mt, stack, p):
    """Emission of the whole stack at p: the entries' emission added."""
    e0 = e1 = e2 = 0.0
    for i in range(MAX_STACK):
        m = stack[i]
        if m == EMPTY:
            break
        if emits(mt, m):
            e = medium_emission(mt, m, p)
            e0 += e[0]
            e1 += e[1]
            e2 += e[2]
    return (e0, e1, e2)
