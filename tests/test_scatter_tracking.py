"""Scatter tracking (renderer.media.scatter_tracking) against quadrature.

A free flight over [0, tmax) is unbiased when, per channel k,

    E[w_k; not scattered]            = T_k(tmax)
    E[w_k; scattered at t < s]       = int_0^s T_k(t) sigma_s,k(t) dt   for every s
    E[Le_k]                          = int_0^tmax T_k(t) E_k(t) dt

(the second, at several s, checks the distribution of the scatter point, not only its
total). The references come from an exponential integrator on a fine step (O(h^2));
the Monte Carlo means must match within Z standard errors estimated from the same samples
(fixed seeds). The weights must also respect the bound 1 / p_k of the module docstring.
"""

import math

import numpy as np
import pytest
from numba import njit

from renderer.kernels.rng import path_key
from renderer.media import compile_media
from renderer.media.emission import stack_emission
from renderer.media.generators import smoke_ball_density
from renderer.media.scatter_tracking import scatter_track
from renderer.media.tracking import _sigma_at
from renderer.scene import Medium

Z = 5.0
CUTS = (0.25, 0.5, 0.75)  # fractions of tmax at which the scatter distribution is checked
ROWS = 2 + len(CUTS) + 1  # not scattered, scattered (all), scattered before each cut, Le


@njit  # not cached: numba would not see edits to the renderer kernels it inlines
def _reference(mt, stack, o, d, tmax, steps):
    """Rows as _moments' means: T(tmax), int T sigma_s over [0, tmax) and over [0, cut tmax)
    for each cut, int T E; by midpoint coefficients integrated exactly on each step."""
    h = tmax / steps
    ref = np.zeros((ROWS, 3))
    tr = np.ones(3)
    for i in range(steps):
        t = (i + 0.5) * h
        x = (o[0] + d[0] * t, o[1] + d[1] * t, o[2] + d[2] * t)
        sa, ss = _sigma_at(mt, stack, x)
        e = stack_emission(mt, stack, x)
        for k in range(3):
            st = sa[k] + ss[k]
            step = -math.expm1(-st * h) / st if st > 0.0 else h
            ref[1, k] += tr[k] * ss[k] * step
            for j in range(len(CUTS)):
                if t < CUTS[j] * tmax:
                    ref[2 + j, k] += tr[k] * ss[k] * step
            ref[ROWS - 1, k] += tr[k] * e[k] * step
            tr[k] *= math.exp(-st * h)
    ref[0] = tr
    return ref


@njit  # not cached: numba would not see edits to the renderer kernels it inlines
def _moments(mt, stack, o, d, tmax, p, emission, n, seed):
    """(sums, sums of squares) of the ROWS estimates per channel, out-of-bound weights (w_k
    above 1 / p_k, negative or not finite) and the mean random numbers used per flight."""
    s1 = np.zeros((ROWS, 3))
    s2 = np.zeros((ROWS, 3))
    bad = 0
    dims = 0
    for i in range(n):
        t, scattered, w, le, dim = scatter_track(mt, stack, o, d, 0.0, tmax, p, path_key(seed, i, 0), 0,
                                                 emission, mt.scratch)
        dims += dim
        for k in range(3):
            v = np.zeros(ROWS)
            if scattered:
                v[1] = w[k]
                for j in range(len(CUTS)):
                    if t < CUTS[j] * tmax:
                        v[2 + j] = w[k]
            else:
                v[0] = w[k]
            v[ROWS - 1] = le[k]
            bound = (1.0 + 1e-9) / p[k] if p[k] > 0.0 else 0.0
            if not (math.isfinite(w[k]) and 0.0 <= w[k] <= bound):
                bad += 1
            for r in range(ROWS):
                s1[r, k] += v[r]
                s2[r, k] += v[r] * v[r]
    return s1, s2, bad, dims / n


def check(mt, o, d, tmax, p=(1 / 3, 1 / 3, 1 / 3), emission=False, n=100_000, seed=5):
    """Every row and channel within Z standard errors of the quadrature; returns the mean
    random numbers used per flight (a measure of its cost)."""
    d = tuple(float(v) for v in np.asarray(d, float) / np.linalg.norm(d))
    o = tuple(float(v) for v in o)
    stack = np.array([0, -1, -1, -1], np.int32)
    ref = _reference(mt, stack, o, d, tmax, 400_000)
    s1, s2, bad, dims = _moments(mt, stack, o, d, tmax, p, emission, n, seed)
    assert bad == 0
    mean = s1 / n
    se = np.sqrt(np.maximum(s2 / n - mean * mean, 0.0) / n)
    tol = Z * se + 1e-9 * np.abs(ref) + 1e-300
    assert np.all(np.abs(mean - ref) < tol), (mean, ref, (mean - ref) / np.maximum(se, 1e-300))
    return dims


def grid(density, sigma_a, sigma_s, **kw) -> Medium:
    return Medium("grid", type="grid", sigma_a=sigma_a, sigma_s=sigma_s,
                  density=np.asarray(density, np.float32), **kw)


# The smoke ball's albedo (0.1), a chromatic one with a pure absorber in blue, and a pure
# scatterer (then scatter tracking is delta tracking).
SIGMAS = [
    ((9.0, 9.0, 9.0), (1.0, 1.0, 1.0)),
    ((2.0, 5.0, 3.0), (4.0, 1.0, 0.0)),
    ((0.0, 0.0, 0.0), (3.0, 2.0, 1.0)),
]


@pytest.mark.parametrize("sigma_a, sigma_s", SIGMAS)
@pytest.mark.parametrize("p", [(1 / 3, 1 / 3, 1 / 3), (0.7, 0.2, 0.1)])
@pytest.mark.parametrize("use_majorant_grid", [True, False])
def test_smoke_ball_grid(sigma_a, sigma_s, p, use_majorant_grid):
    """The Fig. 3 ball (density 1/4 at the centre, halving per voxel) scaled to optical
    depths of a few, crossed off-centre."""
    mt = compile_media([grid(8.0 * smoke_ball_density(11), sigma_a, sigma_s)], use_majorant_grid)
    check(mt, (-0.5, 0.45, 0.52), (1.0, 0.1, -0.05), 2.0, p)


@pytest.mark.parametrize("use_majorant_grid", [True, False])
def test_emission_with_flame_and_temperature(use_majorant_grid):
    """Emission gathered at the tentative collisions, weighted by the exact absorption up
    to them; a sparse density (empty slab) and a transformed box."""
    rng = np.random.default_rng(7)
    density = rng.uniform(0.0, 2.0, (6, 7, 8))
    density[2:4] = 0.0
    med = grid(density, (0.5, 2.0, 0.0), (1.0, 0.5, 3.0), p0=(-0.5, -0.5, -0.5), p1=(0.5, 0.5, 0.5),
               to_world=np.diag([2.0, 1.0, 1.5, 1.0]))
    med.emission, med.flame = (1.0, 0.5, 0.2), rng.uniform(0.0, 1.0, (3, 3, 4))
    med.temperature, med.blackbody_intensity = rng.uniform(1000.0, 3000.0, (2, 5, 3)), 1.0
    mt = compile_media([med], use_majorant_grid)
    check(mt, (-1.5, -0.1, -0.2), (1.0, 0.15, 0.2), 3.0, (0.5, 0.3, 0.2), emission=True, n=60_000)


@pytest.mark.parametrize("background", [0.0, 0.5])
def test_lone_voxel_of_1e8(background):
    """One voxel of 1e8 (issue 18 item 5), among zeros or over a background: its majorant
    cell is crossed by regular tracking, so a flight costs a handful of random numbers (null
    collisions against its bound would take ~1e8 per unit length), and stays unbiased. The
    ray passes the voxel at 0.99 voxel in y and 0.9999 in z, where the trilinear density
    peaks near 1e8 x 0.01 x 1e-4 = 100: optical depth ~3."""
    n = 32
    density = np.full((n, n, n), background, np.float32)
    density[16, 16, 16] = 1e8  # (z, y, x)
    mt = compile_media([grid(density, (0.5, 0.4, 0.3), (0.5, 0.6, 0.7))], True)
    y = (16.5 + 0.99) / n
    z = (16.5 + 0.9999) / n
    dims = check(mt, (-0.5, y, z), (1.0, 0.0, 0.0), 2.0, (0.5, 0.25, 0.25), n=40_000)
    assert dims < 50


def _mirrored_rotation() -> np.ndarray:
    axis, angle = np.array([1.0, 0.0, 1.0]) / math.sqrt(2.0), math.radians(25.0)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.diag([-1.0, 1.0, 1.0]) @ (np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * k @ k)


STEPS = 4_000_000


def test_pure_absorber_flight_is_the_exact_transmittance():
    """Nothing scatters: every flight passes with weight exp(-tau_a), the exact integral (no
    random number but the channel pick), on rays that cross a mirrored, rotated box, some
    of them only through a corner. Against the quadrature to its O(h^2) accuracy."""
    to_world = np.eye(4)
    to_world[:3, :3], to_world[:3, 3] = _mirrored_rotation(), (0.05, 0.0, 0.0)
    density = 4.0 * (np.random.default_rng(9).uniform(size=(3, 4, 5)) < 0.5)
    mt = compile_media([grid(density, (1.0, 0.5, 2.0), (0.0, 0.0, 0.0), p0=(-0.6, -0.5, -0.4),
                             p1=(0.5, 0.6, 0.7), to_world=to_world)])
    stack = np.array([0, -1, -1, -1], np.int32)
    rng = np.random.default_rng(3)
    for i in range(40):
        target = rng.uniform(-0.9, 0.9, 3)  # some rays miss the box or clip its corners
        o = rng.normal(0.0, 1.0, 3)
        o = tuple(float(v) for v in target - 2.0 * o / np.linalg.norm(o))
        d = tuple(float(v) for v in (np.subtract(target, o)) / np.linalg.norm(np.subtract(target, o)))
        t, scattered, w, le, dim = scatter_track(mt, stack, o, d, 0.0, 4.0, (1 / 3, 1 / 3, 1 / 3),
                                                 np.uint64(path_key(1, i, 0)), 0, False, mt.scratch)
        ref = _reference(mt, stack, o, d, 4.0, STEPS)[0]
        assert not scattered and t == 4.0 and dim == 1
        # The midpoint rule errs by at most h/2 x the jump (sigma_a 2 x density 4) at each of
        # the box's two faces, O(h^2) elsewhere.
        np.testing.assert_allclose(w, ref, rtol=2 * (4.0 / STEPS) / 2 * 8.0 + 1e-9)
