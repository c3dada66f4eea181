"""Grid media: density (and flame, blackbody emission) looked up in the grid's unit cube.

World -> unit cube is the affine D = (to_world * T(p0) * S(p1 - p0))^-1 stored as a 3x4
matrix. Voxel (i, j, k) of an (nx, ny, nz) grid sits at ((i + 0.5)/nx, (j + 0.5)/ny,
(k + 0.5)/nz); values are trilinear between voxel centres and clamp to the edge voxels
inside [0, 1]^3 (so a constant grid is exactly a homogeneous medium and a 1x1x1 grid a
homogeneous box); outside the box every grid reads 0. Homogeneous media have density 1.

A grid is dense or sparse (bricks.py, layout.grid_bricks): both find the same eight voxels
and mix them with the same arithmetic, so they give bit-identical values; a sparse grid
only adds one read of its brick index.
"""

import numpy as np

from renderer.kernels import inline_kernel
from renderer.media.layout import GRID_DENSITY, P_TO_UNIT
from renderer.media.procedural import program_density
from renderer.media.table import grid_bricks, grid_dim, grid_offset, is_grid

_SPAN = 9  # stored voxels per brick and axis (bricks.SPAN: 8 and the next brick's first)


@inline_kernel
def to_unit_point(mt, m, p):
    a = mt.params  # indexed in 2-D: a row view would cost a reference-count round trip
    k = P_TO_UNIT
    return (
        a[m, k + 0] * p[0] + a[m, k + 1] * p[1] + a[m, k + 2] * p[2] + a[m, k + 3],
        a[m, k + 4] * p[0] + a[m, k + 5] * p[1] + a[m, k + 6] * p[2] + a[m, k + 7],
        a[m, k + 8] * p[0] + a[m, k + 9] * p[1] + a[m, k + 10] * p[2] + a[m, k + 11],
    )


@inline_kernel
def to_unit_vector(mt, m, v):
    a = mt.params
    k = P_TO_UNIT
    return (
        a[m, k + 0] * v[0] + a[m, k + 1] * v[1] + a[m, k + 2] * v[2],
        a[m, k + 4] * v[0] + a[m, k + 5] * v[1] + a[m, k + 6] * v[2],
        a[m, k + 8] * v[0] + a[m, k + 9] * v[1] + a[m, k + 10] * v[2],
    )


@inline_kernel
def _axis(x, n):
    """Lower voxel index and weight of the upper one for unit coordinate x on n voxels."""
    f = x * n - 0.5
    if f <= 0.0:
        return 0, 0.0
    if f >= n - 1:
        return n - 1, 0.0
    i = int(f)
    return i, f - i


@inline_kernel
def _cell(mt, m, which, u, channels):
    """Where the trilinear stencil of grid `which` (values of `channels` floats interleaved)
    sits at unit-cube point u: (base index, steps di, dj, dk, upper weights fx, fy, fz).
    A clamped axis has weight 0 on its "+1" voxel; its step is 0 there so nothing past the
    edge is read."""
    nx = grid_dim(mt, m, which, 0)
    ny = grid_dim(mt, m, which, 1)
    nz = grid_dim(mt, m, which, 2)
    i, fx = _axis(u[0], nx)
    j, fy = _axis(u[1], ny)
    k, fz = _axis(u[2], nz)
    lattice = grid_bricks(mt, m, which)
    if lattice < 0:  # dense
        di = channels if i + 1 < nx else 0
        dj = channels * nx if j + 1 < ny else 0
        dk = channels * nx * ny if k + 1 < nz else 0
        b = grid_offset(mt, m, which) + channels * ((k * ny + j) * nx + i)
        return b, di, dj, dk, fx, fy, fz
    # Sparse: the brick holding voxel (i, j, k) holds the whole stencil (its apron).
    bx = (nx + 7) >> 3
    by = (ny + 7) >> 3
    brick = np.int64(mt.brick_index[lattice + ((k >> 3) * by + (j >> 3)) * bx + (i >> 3)])
    di = channels if i + 1 < nx else 0
    dj = channels * _SPAN if j + 1 < ny else 0
    dk = channels * _SPAN * _SPAN if k + 1 < nz else 0
    local = ((k & 7) * _SPAN + (j & 7)) * _SPAN + (i & 7)
    b = grid_offset(mt, m, which) + channels * (brick * (_SPAN * _SPAN * _SPAN) + local)
    return b, di, dj, dk, fx, fy, fz


@inline_kernel
def _trilinear(data, b, di, dj, dk, fx, fy, fz):
    """Trilinear mix of the 8 values at b, b + di, b + dj, ... with upper weights fx, fy, fz."""
    c00 = data[b] * (1.0 - fx) + data[b + di] * fx
    c10 = data[b + dj] * (1.0 - fx) + data[b + dj + di] * fx
    c01 = data[b + dk] * (1.0 - fx) + data[b + dk + di] * fx
    c11 = data[b + dk + dj] * (1.0 - fx) + data[b + dk + dj + di] * fx
    c0 = c00 * (1.0 - fy) + c10 * fy
    c1 = c01 * (1.0 - fy) + c11 * fy
    return c0 * (1.0 - fz) + c1 * fz


@inline_kernel
def _inside(u):
    return 0.0 <= u[0] <= 1.0 and 0.0 <= u[1] <= 1.0 and 0.0 <= u[2] <= 1.0


@inline_kernel
def grid_lookup(mt, m, which, u):
    """Trilinear value of grid `which` of medium m at unit-cube point u (0 outside)."""
    if not _inside(u):
        return 0.0
    b, di, dj, dk, fx, fy, fz = _cell(mt, m, which, u, 1)
    return _trilinear(mt.grid_data, b, di, dj, dk, fx, fy, fz)


@inline_kernel
def grid_lookup3(mt, m, which, u):
    """Trilinear RGB value of three-channel grid `which` (channels interleaved, see
    layout.GRID_BLACKBODY) of medium m at unit-cube point u ((0, 0, 0) outside)."""
    if not _inside(u):
        return (0.0, 0.0, 0.0)
    b, di, dj, dk, fx, fy, fz = _cell(mt, m, which, u, 3)
    data = mt.grid_data
    return (
        _trilinear(data, b, di, dj, dk, fx, fy, fz),
        _trilinear(data, b + 1, di, dj, dk, fx, fy, fz),
        _trilinear(data, b + 2, di, dj, dk, fx, fy, fz),
    )


@inline_kernel
def medium_density(mt, m, p):
    """Density of medium m at world point p: 1 for homogeneous media; a procedural medium's
    program inside its box (procedural.py)."""
    if not is_grid(mt, m):
        return 1.0
    u = to_unit_point(mt, m, p)
    rho = program_density(mt, m, u, p)  # the constant -1 for tables without programs
    if rho >= 0.0:
        return rho
    return grid_lookup(mt, m, GRID_DENSITY, u)
