"""Any density contrast in bounded time (issue 18, item 5): regular tracking in the majorant
cells where the bound overshoots the density (renderer/media/regular.py).

Rays run along x, off a dense voxel's centre by a fraction of a voxel in y, so the
trilinear density along them is piecewise linear in x with known weights and the optical
depth is known in closed form: a voxel of value C at y-weight w adds C w / n (its tent's
integral). Estimators are checked against exp(-sigma_t tau) (ratio tracking is then
deterministic, so to rounding; delta tracking and free flight by z-scores), and their cost
is counted in random numbers drawn, which a majorant of C would make ~C sigma_t per unit
length (a million and more here). Fixed seeds.
"""

import math

import numpy as np
import pytest
from numba import njit

from renderer.kernels.rng import path_key
from renderer.media import compile_media, sample_distance, transmittance
from renderer.media.layout import CELL_EXACT
from renderer.scene import Medium

Z = 5.0
N = 16  # voxels per axis
SIGMA_A, SIGMA_S = (0.25, 0.5, 1.5), (0.25, 0.5, 0.5)  # sigma_t (0.5, 1, 2)
SIGMA_T = np.add(SIGMA_A, SIGMA_S)
SPIKE = (N // 2, N // 2, N // 2)  # (z, y, x) of the dense voxel


def spiked_grid(contrast: float, background: float) -> np.ndarray:
    density = np.full((N, N, N), background, np.float32)
    density[SPIKE] = contrast
    return density


def spiked_ray(contrast: float, background: float):
    """(o, d, tmax, tau): a ray along +x through the whole box whose optical depth per
    unit sigma_t is tau = background x 1 + spike x w / N = background + 1, the spike's
    y-weight w chosen to make its share exactly 1 (in float64, as the kernel computes it)."""
    spike = float(np.float32(contrast)) - background
    y = (SPIKE[1] + 0.5 + 1.0 - N / spike) / N  # just under one voxel off the centre in y
    w = 1.0 - ((y * N - 0.5) - SPIKE[1])  # the dense voxel's weight, as the kernel gets it
    z = (SPIKE[0] + 0.5) / N
    return (-0.5, y, z), (1.0, 0.0, 0.0), 2.0, background + spike * w / N


@njit(cache=True)
def _moments(mt, stack, o, d, tmax, n):
    """Per channel (sum, sum of squares) of: ratio Tr, delta Tr, free-flight weight not
    scattered, free-flight weight scattered; and the mean random numbers each tracker drew."""
    out = np.zeros((8, 3))
    dims = np.zeros(3)
    for i in range(n):
        key = path_key(11, i, 0)
        tr_r, dim_r = transmittance(mt, stack, o, d, 0.0, tmax, key, 0, False)
        tr_d, dim_d = transmittance(mt, stack, o, d, 0.0, tmax, key, 100, True)
        _, scattered, w, _, dim_f = sample_distance(mt, stack, o, d, tmax, (1.0, 0.5, 0.25), key, 200, False)
        row = 6 if scattered else 4
        for k in range(3):
            out[0, k] += tr_r[k]
            out[1, k] += tr_r[k] * tr_r[k]
            out[2, k] += tr_d[k]
            out[3, k] += tr_d[k] * tr_d[k]
            out[row, k] += w[k]
            out[row + 1, k] += w[k] * w[k]
        dims[0] += dim_r
        dims[1] += dim_d - 100
        dims[2] += dim_f - 200
    return out, dims / n


def _check(mean_sum, sq_sum, n, want, what):
    for k in range(3):
        mean = mean_sum[k] / n
        se = math.sqrt(max(sq_sum[k] / n - mean * mean, 0.0) / n)
        tol = Z * se + 1e-9 * abs(want[k]) + 1e-300
        assert abs(mean - want[k]) <= tol, f"{what} channel {k}: {mean:.9g} vs {want[k]:.9g} (se {se:.3g})"


CASES = [(1e2, 1.0), (1e4, 1.0), (1e6, 1.0), (1e8, 1.0), (1e8, 0.0)]


@pytest.mark.parametrize("contrast, background", CASES, ids=["1e2", "1e4", "1e6", "1e8", "lone_1e8"])
def test_contrast_estimates_are_exact_and_cheap(contrast, background):
    med = Medium("spike", "grid", sigma_a=SIGMA_A, sigma_s=SIGMA_S, density=spiked_grid(contrast, background))
    mt = compile_media([med])
    assert mt.maj_data[:, CELL_EXACT].any()  # the cells around the spike are regular-tracked
    stack = np.array([0, -1, -1, -1], np.int32)
    o, d, tmax, tau = spiked_ray(contrast, background)
    tr = np.exp(-np.float32(SIGMA_A).astype(float) * tau - np.float32(SIGMA_S).astype(float) * tau)
    n = 20_000
    m, dims = _moments(mt, stack, o, d, tmax, n)
    _check(m[0], m[1], n, tr, "ratio tracking Tr")
    _check(m[2], m[3], n, tr, "delta tracking Tr")
    _check(m[4], m[5], n, tr, "free flight E[w; not scattered] = T")
    albedo = np.float32(SIGMA_S).astype(float) / (np.float32(SIGMA_A).astype(float) + np.float32(SIGMA_S))
    _check(m[6], m[7], n, albedo * (1.0 - tr), "free flight E[w; scattered] = int T sigma_s")
    # Bounded cost: a handful of random numbers per ray, whatever the contrast.
    assert (dims < 16.0).all(), dims


def test_smooth_grid_cells_stay_null_collision_tracked():
    """A smooth grid (the bound within a few optical depths of the density) flags no cell:
    its images and speed are those of null-collision tracking."""
    c = (np.arange(32) + 0.5) / 32 - 0.5
    z, y, x = np.meshgrid(c, c, c, indexing="ij")
    density = np.exp(-(x * x + y * y + z * z) / 0.08).astype(np.float32)
    mt = compile_media([Medium("smooth", "grid", sigma_a=(5.0,) * 3, sigma_s=(5.0,) * 3, density=density)])
    assert not mt.maj_data[:, CELL_EXACT].any()
