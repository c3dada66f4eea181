"""The path's random numbers (renderer.kernels.rng and the stratified dimensions of
renderer.kernels.sobol): stratified where they should be, uniform and independent
everywhere, and the two halves of a pixel's samples (rng SAMPLE_HALVES) independent of
each other, which the film's error estimate relies on (renderer.film)."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from renderer.film import Film
from renderer.kernels.rng import STRATIFIED_DIMS, path_key, uniform
from renderer.kernels.sobol import stratified

PIXEL = -1  # "dimension" -1 with 0: the pair of the position in the pixel (camera_rays)


@njit(cache=False)
def draw(seed, pixel, first, n, dims, step):
    """(n, dims + 1): dimensions -1..dims-1 of samples first, first + step, ... (n of them)
    of one pixel: step 2 walks one half of the pixel's samples."""
    out = np.empty((n, dims + 1))
    for s in range(n):
        key = path_key(seed, pixel, first + step * s)
        out[s, 0] = stratified(key, PIXEL)
        for d in range(dims):
            out[s, d + 1] = uniform(key, d)
    return out


def strata(values: np.ndarray, n: int) -> int:
    return len(np.unique(np.floor(values * n).astype(np.int64)))


# each half, and in the half's second block of 2^16 samples
@pytest.mark.parametrize("first", [0, 1, 1 << 17])
def test_stratified_dimensions_put_one_sample_per_stratum(first):
    assert STRATIFIED_DIMS >= 9, "the lens and the first light sample are stratified (integrator.dims)"
    for n in (4, 32, 256):
        u = draw(5, 777, first, n, STRATIFIED_DIMS + 4, 2)
        assert all(strata(u[:, d], n) == n for d in range(STRATIFIED_DIMS + 1)), n
        # the hashed dimensions are independent uniforms: some stratum is empty or doubled
        assert any(strata(u[:, d], n) < n for d in range(STRATIFIED_DIMS + 1, STRATIFIED_DIMS + 5))


def test_pairs_of_dimensions_are_nets():
    """Dimensions (2k - 1, 2k) form a (0, m, 2)-net over the first 2^m samples of a half:
    one point in each of the 2^m elementary boxes of every shape 2^-a x 2^-(m - a)."""
    m = 8
    u = draw(9, 31, 0, 1 << m, STRATIFIED_DIMS, 2)
    for first in range(-1, STRATIFIED_DIMS - 1, 2):
        x, y = u[:, first + 1], u[:, first + 2]
        for a in range(m + 1):
            boxes = np.floor(x * 2**a) * 2 ** (m - a) + np.floor(y * 2 ** (m - a))
            assert len(np.unique(boxes)) == 1 << m, (first, a)


def test_values_are_uniform_and_independent_across_pixels():
    """One sample of many pixels: every dimension is uniform (chi-square over 16 bins) and
    neighbouring dimensions are uncorrelated (|r| within 4 sigma of 0)."""
    pixels = 4096
    u = np.concatenate([draw(2, p, 3, 1, STRATIFIED_DIMS + 2, 2) for p in range(pixels)])
    expected = pixels / 16
    chi2_limit = 45.0  # chi-square with 15 degrees of freedom: P(> 45) ~ 1e-4
    for d in range(u.shape[1]):
        counts = np.bincount(np.floor(u[:, d] * 16).astype(int), minlength=16)
        assert ((counts - expected) ** 2 / expected).sum() < chi2_limit, d
    for d in range(u.shape[1] - 1):
        r = np.corrcoef(u[:, d], u[:, d + 1])[0, 1]
        assert abs(r) < 4.0 / np.sqrt(pixels), d


def test_the_halves_of_a_pixel_are_independent():
    """Samples 0 and 1 of many pixels (the first of each half): uncorrelated in every
    dimension. Within one stratified sequence they would not be (its first two values lie
    in opposite halves of [0, 1): r about -0.75)."""
    pixels = 4096
    even = np.concatenate([draw(4, p, 0, 1, STRATIFIED_DIMS, 2) for p in range(pixels)])
    odd = np.concatenate([draw(4, p, 1, 1, STRATIFIED_DIMS, 2) for p in range(pixels)])
    for d in range(even.shape[1]):
        r = np.corrcoef(even[:, d], odd[:, d])[0, 1]
        assert abs(r) < 4.0 / np.sqrt(pixels), d


def test_split_variance_of_mean_is_unbiased():
    """Film.split_variance_of_mean from the two halves' sums, for independent samples of
    variance 1 (even and odd counts included): its mean over pixels is 1 / n within 4
    standard errors (each pixel's estimate is a chi-square with one degree of freedom)."""
    rng = np.random.default_rng(3)
    pixels = 20000
    for n in (2, 5, 16):
        film = Film(pixels, 1)
        values = rng.normal(1.0, 1.0, (pixels, n, 3))
        film.sum[:] = values.sum(axis=1)
        film.odd[:, :3] = values[:, 1::2].sum(axis=1)
        film.n[:] = n
        film.odd[:, 3] = n // 2
        got = film.split_variance_of_mean()[:, 0]
        assert abs(got.mean() * n - 1.0) < 4.0 * np.sqrt(2.0 / pixels), n
