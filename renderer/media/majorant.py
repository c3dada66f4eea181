"""Walking a ray through a grid medium's coarse majorant grid (3-D DDA, Amanatides & Woo).

Along a ray o + t d a grid medium's majorant is piecewise constant: 0 before its unit box,
then one value per majorant cell crossed, then 0 again. A walker holds the state of that
walk in one float64 row (layout.DDA, so a stack of walkers is a small 2-D array) and
exposes the current piece: it lasts until row[DDA_END], with density bound row[DDA_MAJ],
emission flag row[DDA_EMITS] and regular-tracking flag row[DDA_EXACT] (regular.py).
dda_advance moves to the next piece.

The ray is mapped to the unit cube once (an affine map keeps the ray parameter t), and
the walk steps cell by cell in integer coordinates, so a ray through a large empty region
costs one step per coarse cell and no density lookups. Cell values are padded by one voxel
(see compile.py), so a rounding error at a crossing cannot make the bound wrong.
"""

import math

import numpy as np

from renderer.kernels import inline_kernel, kernel
from renderer.media.grid import to_unit_point, to_unit_vector
from renderer.media.layout import (
    CELL_DENSITY_BOUND,
    CELL_EMITS,
    CELL_EXACT,
    DDA_CELL,
    DDA_DT,
    DDA_EMITS,
    DDA_END,
    DDA_ENTER,
    DDA_EXACT,
    DDA_EXIT,
    DDA_MAJ,
    DDA_MEDIUM,
    DDA_NEXT,
    DDA_STATE,
    DDA_STEP,
)
from renderer.media.table import maj_dim, maj_offset

# Values of the walker's state field.
BEFORE, INSIDE, PAST = 0.0, 1.0, 2.0


@inline_kernel
def _set_piece(row, end, maj, emits, exact):
    row[DDA_END] = end
    row[DDA_MAJ] = maj
    row[DDA_EMITS] = emits
    row[DDA_EXACT] = exact


@inline_kernel
def _load_cell(mt, row):
    """Current piece = the current cell, up to its first crossing or the box exit."""
    m = int(row[DDA_MEDIUM])
    cx = maj_dim(mt, m, 0)
    cy = maj_dim(mt, m, 1)
    i = int(row[DDA_CELL])
    j = int(row[DDA_CELL + 1])
    k = int(row[DDA_CELL + 2])
    cell = maj_offset(mt, m) + (k * cy + j) * cx + i
    end = min(row[DDA_NEXT], row[DDA_NEXT + 1], row[DDA_NEXT + 2], row[DDA_EXIT])
    _set_piece(row, end, np.float64(mt.maj_data[cell, CELL_DENSITY_BOUND]),
               np.float64(mt.maj_data[cell, CELL_EMITS]), np.float64(mt.maj_data[cell, CELL_EXACT]))


@inline_kernel
def _next_axis(row):
    """Axis whose cell boundary the ray crosses first."""
    a = 0
    if row[DDA_NEXT + 1] < row[DDA_NEXT + a]:
        a = 1
    if row[DDA_NEXT + 2] < row[DDA_NEXT + a]:
        a = 2
    return a


@kernel
def _merge_empty(mt, row):
    """If the current cell is empty (no density, no emission), extend the piece over the
    following empty cells, so that a sparse grid's empty space is one zero-majorant piece
    and costs the tracker nothing per cell."""
    if row[DDA_MAJ] != 0.0 or row[DDA_EMITS] != 0.0:
        return
    m = int(row[DDA_MEDIUM])
    cx = maj_dim(mt, m, 0)
    cy = maj_dim(mt, m, 1)
    base = maj_offset(mt, m)
    while True:
        a = _next_axis(row)
        if row[DDA_NEXT + a] >= row[DDA_EXIT]:
            break
        c = row[DDA_CELL + a] + row[DDA_STEP + a]
        if c < 0.0 or c >= maj_dim(mt, m, a):
            break
        i = int(row[DDA_CELL]) if a != 0 else int(c)
        j = int(row[DDA_CELL + 1]) if a != 1 else int(c)
        k = int(row[DDA_CELL + 2]) if a != 2 else int(c)
        cell = base + (k * cy + j) * cx + i
        if mt.maj_data[cell, CELL_DENSITY_BOUND] != 0.0 or mt.maj_data[cell, CELL_EMITS] != 0.0:
            break
        row[DDA_CELL + a] = c
        row[DDA_NEXT + a] += row[DDA_DT + a]
    row[DDA_END] = min(row[DDA_NEXT], row[DDA_NEXT + 1], row[DDA_NEXT + 2], row[DDA_EXIT])


@kernel
def dda_init(mt, m, o, d, t_start, row):
    """Start walking grid medium m along o + t d from t_start."""
    uo = to_unit_point(mt, m, o)
    ud = to_unit_vector(mt, m, d)
    row[DDA_MEDIUM] = m
    # Slab test against [0, 1]^3 in unit coordinates (same t as the world ray).
    t_enter = -math.inf
    t_exit = math.inf
    for a in range(3):
        if ud[a] != 0.0:
            ta = (0.0 - uo[a]) / ud[a]
            tb = (1.0 - uo[a]) / ud[a]
            t_enter = max(t_enter, min(ta, tb))
            t_exit = min(t_exit, max(ta, tb))
        elif not (0.0 <= uo[a] <= 1.0):
            t_exit = -math.inf
    t_enter = max(t_enter, t_start)
    if not t_enter < t_exit:
        row[DDA_STATE] = PAST
        _set_piece(row, math.inf, 0.0, 0.0, 0.0)
        return
    row[DDA_ENTER] = t_enter
    row[DDA_EXIT] = t_exit
    # Cell and crossings where the ray enters (or starts inside) the box.
    for a in range(3):
        n = maj_dim(mt, m, a)
        x = (uo[a] + ud[a] * t_enter) * n
        c = min(max(int(math.floor(x)), 0), n - 1)
        row[DDA_CELL + a] = c
        if ud[a] > 0.0:
            row[DDA_NEXT + a] = ((c + 1.0) / n - uo[a]) / ud[a]
            row[DDA_DT + a] = 1.0 / (n * ud[a])
            row[DDA_STEP + a] = 1.0
        elif ud[a] < 0.0:
            row[DDA_NEXT + a] = (c / n - uo[a]) / ud[a]
            row[DDA_DT + a] = -1.0 / (n * ud[a])
            row[DDA_STEP + a] = -1.0
        else:
            row[DDA_NEXT + a] = math.inf
            row[DDA_DT + a] = math.inf
            row[DDA_STEP + a] = 0.0
    if t_enter > t_start:
        row[DDA_STATE] = BEFORE
        _set_piece(row, t_enter, 0.0, 0.0, 0.0)
    else:
        row[DDA_STATE] = INSIDE
        _load_cell(mt, row)
        _merge_empty(mt, row)


@kernel
def dda_advance(mt, row):
    """Move to the piece after the current one."""
    if row[DDA_STATE] == BEFORE:
        row[DDA_STATE] = INSIDE
        _load_cell(mt, row)
        _merge_empty(mt, row)
        return
    if row[DDA_STATE] == PAST or row[DDA_END] >= row[DDA_EXIT]:
        row[DDA_STATE] = PAST
        _set_piece(row, math.inf, 0.0, 0.0, 0.0)
        return
    # Step across the nearest crossing.
    a = _next_axis(row)
    m = int(row[DDA_MEDIUM])
    c = row[DDA_CELL + a] + row[DDA_STEP + a]
    if c < 0.0 or c >= maj_dim(mt, m, a):
        row[DDA_STATE] = PAST
        _set_piece(row, math.inf, 0.0, 0.0, 0.0)
        return
    row[DDA_CELL + a] = c
    row[DDA_NEXT + a] += row[DDA_DT + a]
    _load_cell(mt, row)
    _merge_empty(mt, row)
