"""Regular tracking through a grid medium: exact optical depth, no majorant.

Between two consecutive planes of voxel centres (u_a = (i + 1/2) / n_a on every axis) the
trilinear density along a ray is a product of three affine functions of t (a clamped axis
contributes a constant), so a cubic in t. Two-point Gauss-Legendre quadrature integrates
a cubic exactly, so on such a piece [a, b]

    R(a, b) = int_a^b rho(t) dt = (b - a) / 2 (rho(a + g0 (b - a)) + rho(a + g1 (b - a)))

with g0,1 = 1/2 -+ 1/(2 sqrt 3), also for every sub-interval [a, s]: transmittance is
exp(-sigma_t R) in closed form, and a free-flight distance is the root of a monotone
quartic, found by safeguarded Newton. The cost of a piece is a few lookups whatever the
density, which null-collision tracking cannot offer next to a lone voxel of 1e8: there the
majorant overshoots the density by 1e8 over the whole cell and every ray through the cell
makes ~1e8 x length tentative collisions. compile.py flags the cells where that overshoot
is large (CELL_EXACT); tracking.py crosses them here.

The ray is given in the grid's unit cube (uo + ud t, the world t kept), with the stack's
homogeneous extinction `hom` (per world unit, RGB) added as a constant along it.
"""

import math

from renderer.kernels import inline_kernel
from renderer.media.grid import grid_lookup
from renderer.media.layout import GRID_DENSITY
from renderer.media.table import grid_dim

GAUSS0 = 0.5 - 0.5 / math.sqrt(3.0)
GAUSS1 = 0.5 + 0.5 / math.sqrt(3.0)
# Newton steps at most per free-flight root (each halves the bracket at worst; 60 reach
# float64 resolution on any piece).
MAX_NEWTON = 60


@inline_kernel
def _rho(mt, m, uo, ud, t):
    return grid_lookup(mt, m, GRID_DENSITY, (uo[0] + ud[0] * t, uo[1] + ud[1] * t, uo[2] + ud[2] * t))


@inline_kernel
def density_integral(mt, m, uo, ud, a, b):
    """Exact integral of the density over [a, b], inside one piece between voxel-centre planes."""
    h = b - a
    return 0.5 * h * (_rho(mt, m, uo, ud, a + GAUSS0 * h) + _rho(mt, m, uo, ud, a + GAUSS1 * h))


@inline_kernel
def next_plane(mt, m, uo, ud, t):
    """Smallest t' > t at which the ray crosses a plane of voxel centres (inf if none)."""
    best = math.inf
    for a in range(3):
        if ud[a] == 0.0:
            continue
        n = grid_dim(mt, m, GRID_DENSITY, a)
        f = (uo[a] + ud[a] * t) * n - 0.5  # voxel-centre coordinate at t
        step = 1.0 if ud[a] > 0.0 else -1.0
        k = math.floor(f) + 1.0 if ud[a] > 0.0 else math.ceil(f) - 1.0
        tc = ((k + 0.5) / n - uo[a]) / ud[a]
        while not tc > t:  # rounding put the plane at or behind t: take the next one
            k += step
            tc = ((k + 0.5) / n - uo[a]) / ud[a]
        best = min(best, tc)
    return best


@inline_kernel
def optical_depths(mt, m, uo, ud, a, b, st, hom):
    """Optical depth per channel over [a, b]: hom_k (b - a) + st_k R(a, b), piece by piece."""
    r = 0.0
    t = a
    while t < b:
        e = min(next_plane(mt, m, uo, ud, t), b)
        r += density_integral(mt, m, uo, ud, t, e)
        t = e
    h = b - a
    return (hom[0] * h + st[0] * r, hom[1] * h + st[1] * r, hom[2] * h + st[2] * r)


@inline_kernel
def _root(mt, m, uo, ud, a, b, target, st_c, hom_c):
    """s in [a, b] where hom_c (s - a) + st_c R(a, s) = target, given that it is <= target at
    a and >= target at b (one polynomial piece): Newton kept inside a shrinking bracket."""
    lo, hi = a, b
    total = hom_c * (b - a) + st_c * density_integral(mt, m, uo, ud, a, b)
    s = a + (b - a) * min(max(target / total, 0.0), 1.0) if total > 0.0 else b
    for _ in range(MAX_NEWTON):
        g = hom_c * (s - a) + st_c * density_integral(mt, m, uo, ud, a, s) - target
        if g > 0.0:
            hi = s
        else:
            lo = s
        slope = hom_c + st_c * _rho(mt, m, uo, ud, s)
        nxt = s - g / slope if slope > 0.0 else 0.5 * (lo + hi)
        if not lo < nxt < hi:
            nxt = 0.5 * (lo + hi)
        if abs(nxt - s) <= 1e-15 * (abs(s) + (b - a)) or hi - lo <= 1e-15 * (abs(s) + (b - a)):
            return nxt
        s = nxt
    return s


@inline_kernel
def sample_flight(mt, m, uo, ud, a, b, depth, c, st, hom):
    """Walk [a, b] until channel c's optical depth reaches `depth`: (t, collided, tau3)
    with tau3 the optical depth per channel over [a, t] (t = b when not collided)."""
    t = a
    tau0 = tau1 = tau2 = 0.0
    left = depth
    while t < b:
        e = min(next_plane(mt, m, uo, ud, t), b)
        r = density_integral(mt, m, uo, ud, t, e)
        h = e - t
        piece_c = hom[c] * h + st[c] * r
        if piece_c >= left and piece_c > 0.0:
            s = _root(mt, m, uo, ud, t, e, left, st[c], hom[c])
            r = density_integral(mt, m, uo, ud, t, s)
            h = s - t
            return s, True, (tau0 + hom[0] * h + st[0] * r, tau1 + hom[1] * h + st[1] * r,
                             tau2 + hom[2] * h + st[2] * r)
        left -= piece_c
        tau0 += hom[0] * h + st[0] * r
        tau1 += hom[1] * h + st[1] * r
        tau2 += hom[2] * h + st[2] * r
        t = e
    return b, False, (tau0, tau1, tau2)
