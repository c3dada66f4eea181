"""The path's random numbers (renderer.kernels.rng and the stratified dimensions of
renderer.kernels.sobol): stratified where they should be, uniform and independent
everywhere. The stratified dimensions are tested directly, since rng.STRATIFIED_DIMS is 0
for now (see there)."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from renderer.kernels.rng import path_key, uniform
from renderer.kernels.sobol import stratified

STRATIFIED = 16  # the dimensions tested stratified


@njit(cache=False)
def draw(seed, pixel, first, n, dims):
    """(n, dims): dimensions 0..dims-1 of samples first..first+n-1 of one pixel, stratified
    below STRATIFIED, the renderer's uniform (hashed) above."""
    out = np.empty((n, dims))
    for s in range(n):
        key = path_key(seed, pixel, first + s)
        for d in range(dims):
            out[s, d] = stratified(key, d) if d < STRATIFIED else uniform(key, d + 1000)
    return out


def strata(values: np.ndarray, n: int) -> int:
    return len(np.unique(np.floor(values * n).astype(np.int64)))


@pytest.mark.parametrize("first", [0, 1 << 16])  # and in the pixel's second block of 2^16 samples
def test_stratified_dimensions_put_one_sample_per_stratum(first):
    for n in (4, 32, 256):
        u = draw(5, 777, first, n, STRATIFIED + 4)
        assert all(strata(u[:, d], n) == n for d in range(STRATIFIED)), n
        # the hashed dimensions are independent uniforms: some stratum is empty or doubled
        assert any(strata(u[:, d], n) < n for d in range(STRATIFIED, STRATIFIED + 4))


def test_pairs_of_dimensions_are_nets():
    """Dimensions (2k - 1, 2k) form a (0, m, 2)-net over the first 2^m samples: one point
    in each of the 2^m elementary boxes of every shape 2^-a x 2^-(m - a)."""
    m = 8
    u = draw(9, 31, 0, 1 << m, STRATIFIED)
    for first in range(1, STRATIFIED - 1, 2):
        x, y = u[:, first], u[:, first + 1]
        for a in range(m + 1):
            boxes = np.floor(x * 2**a) * 2 ** (m - a) + np.floor(y * 2 ** (m - a))
            assert len(np.unique(boxes)) == 1 << m, (first, a)


def test_values_are_uniform_and_independent_across_pixels():
    """One sample of many pixels: every dimension is uniform (chi-square over 16 bins) and
    neighbouring dimensions are uncorrelated (|r| within 4 sigma of 0)."""
    pixels = 4096
    u = np.concatenate([draw(2, p, 3, 1, STRATIFIED + 2) for p in range(pixels)])
    expected = pixels / 16
    chi2_limit = 45.0  # chi-square with 15 degrees of freedom: P(> 45) ~ 1e-4
    for d in range(u.shape[1]):
        counts = np.bincount(np.floor(u[:, d] * 16).astype(int), minlength=16)
        assert ((counts - expected) ** 2 / expected).sum() < chi2_limit, d
    for d in range(u.shape[1] - 1):
        r = np.corrcoef(u[:, d], u[:, d + 1])[0, 1]
        assert abs(r) < 4.0 / np.sqrt(pixels), d
