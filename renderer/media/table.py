"""Named, float64 reads of a MediaTable's fields (the layout is in layout.py).

Inlined into the kernels; each returns float64 (numba keeps float32 * float32 in float32,
so values are widened on the way out) or int.
"""

import numpy as np

from renderer.kernels import inline_kernel
from renderer.media.layout import (
    I_GRID_BRICKS,
    I_GRID_DIMS,
    I_GRID_OFFSET,
    I_HAS_EMISSION,
    I_KIND,
    I_MAJ_DIMS,
    I_MAJ_OFFSET,
    MEDIUM_GRID,
    P_BLACKBODY,
    P_EMISSION,
    P_EMISSION_RATE,
    P_G,
    P_SIGMA_A,
    P_SIGMA_S,
)


@inline_kernel
def is_grid(mt, m):
    return mt.index[m, I_KIND] == MEDIUM_GRID


@inline_kernel
def emits(mt, m):
    return mt.index[m, I_HAS_EMISSION] != 0


@inline_kernel
def _rgb(mt, m, col):
    # Index the 2-D table directly: a row view (mt.params[m]) costs an atomic reference-count
    # round trip per call, which dominated homogeneous free-flight sampling.
    a = mt.params
    return (np.float64(a[m, col]), np.float64(a[m, col + 1]), np.float64(a[m, col + 2]))


@inline_kernel
def sigma_a(mt, m):
    return _rgb(mt, m, P_SIGMA_A)


@inline_kernel
def sigma_s(mt, m):
    return _rgb(mt, m, P_SIGMA_S)


@inline_kernel
def sigma_t(mt, m):
    a = _rgb(mt, m, P_SIGMA_A)
    s = _rgb(mt, m, P_SIGMA_S)
    return (a[0] + s[0], a[1] + s[1], a[2] + s[2])


@inline_kernel
def emission(mt, m):
    return _rgb(mt, m, P_EMISSION)


@inline_kernel
def phase_g(mt, m):
    return np.float64(mt.params[m, P_G])


@inline_kernel
def blackbody_intensity(mt, m):
    return np.float64(mt.params[m, P_BLACKBODY])


@inline_kernel
def emission_rate(mt, m):
    return np.float64(mt.params[m, P_EMISSION_RATE])


@inline_kernel
def grid_offset(mt, m, which):
    return mt.index[m, I_GRID_OFFSET + which]


@inline_kernel
def grid_dim(mt, m, which, axis):
    return mt.index[m, I_GRID_DIMS + 3 * which + axis]


@inline_kernel
def maj_offset(mt, m):
    return mt.index[m, I_MAJ_OFFSET]


@inline_kernel
def maj_dim(mt, m, axis):
    return mt.index[m, I_MAJ_DIMS + axis]


@inline_kernel
def grid_bricks(mt, m, which):
    return mt.index[m, I_GRID_BRICKS + which]
