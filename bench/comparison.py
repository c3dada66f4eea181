"""Haze against a reference renderer (Cycles), statistically: `compare_images` of K
independent renders of each, `assert_agree` the verdict the tests use (image means within
1 %, block means within their noise, chi-square of the blocks)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass
class Comparison:
    """Haze against a reference renderer, from K independent renders of each."""

    relative_mean_difference: np.ndarray  # (3,) (mean_haze - mean_ref) / mean_ref per channel
    relative_mean_sigma: np.ndarray  # (3,) standard deviation of that difference (noise)
    block_z: np.ndarray  # (blocks_y, blocks_x, 3) z-scores of block-mean differences
    chi_square: float  # sum of squared z of the blocks' channel sums (see compare_images)
    degrees: int  # number of block z-scores (blocks x channels)
    chi_degrees: int  # number of blocks in chi_square

    def summary(self) -> str:
        worst = float(np.nanmax(np.abs(self.block_z))) if self.block_z.size else 0.0
        return (f"relative mean difference {np.round(100 * self.relative_mean_difference, 3)} % "
                f"(noise sigma {np.round(100 * self.relative_mean_sigma, 3)} %), "
                f"max |block z| {worst:.2f} of {self.degrees}, "
                f"chi2 {self.chi_square:.1f} for {self.chi_degrees} blocks (channel sums)")


def block_sums(images: np.ndarray, block: int) -> np.ndarray:
    """(K, H, W, C) -> (K, H/block, W/block, C) sums over square blocks."""
    k, h, w, c = images.shape
    return images.reshape(k, h // block, block, w // block, block, c).sum(axis=(2, 4))


def mean_and_variance(images: np.ndarray, block: int) -> tuple[np.ndarray, ...]:
    """Block means of the average of K renders and their variances.

    Pixels are independent (box filter of width 1: each sample lands in one pixel), so the
    variance of a block mean is the sum of its pixels' variances over block^2 squared; each
    pixel's variance is estimated from the spread of the K independent renders.
    """
    k = images.shape[0]
    pixel_variance = images.var(axis=0, ddof=1) / k  # variance of the K-average, per pixel
    means = block_sums(images.mean(axis=0)[None], block)[0] / block**2
    variances = block_sums(pixel_variance[None], block)[0] / block**4
    image_mean = images.mean(axis=(0, 1, 2))
    image_variance = pixel_variance.sum(axis=(0, 1)) / (images.shape[1] * images.shape[2]) ** 2
    return means, variances, image_mean, image_variance


# Both renderers compute in float32; Cycles' sun normalisation alone is only good to ~2e-4
# (1 - cos of a small angle in float32). Block sigmas are floored at this share of the block
# mean, so that deterministic regions (a uniformly lit floor, the sky) compare by precision.
FLOAT32_PRECISION = 3e-4


def compare_images(haze: np.ndarray, reference: np.ndarray, block: int = 8) -> Comparison:
    """Statistical comparison of (K, H, W, 3) stacks of independent renders of one scene."""
    h_mean, h_var, h_image, h_image_var = mean_and_variance(np.asarray(haze, np.float64), block)
    r_mean, r_var, r_image, r_image_var = mean_and_variance(np.asarray(reference, np.float64), block)
    precision = (FLOAT32_PRECISION * 0.5 * (np.abs(h_mean) + np.abs(r_mean))) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = (h_image - r_image) / r_image
        sigma = np.sqrt(h_image_var + r_image_var) / r_image
        z = (h_mean - r_mean) / np.sqrt(h_var + r_var + precision)
    z, counted = _lit_blocks(z, h_mean, h_var, r_mean, r_var)
    chi_square, chi_degrees = _channel_sum_chi_square(haze, reference, block)
    return Comparison(relative, sigma, z, chi_square, counted, chi_degrees)


def _lit_blocks(z, h_mean, h_var, r_mean, r_var) -> tuple[np.ndarray, int]:
    """Blocks without any light in either renderer (both exactly zero, no variance) carry no
    test: their z is 0 and they are not counted."""
    both_dark = (h_var + r_var == 0.0) & (h_mean == r_mean)
    return np.where(both_dark, 0.0, z), int(np.count_nonzero(~both_dark))


def _channel_sum_chi_square(haze: np.ndarray, reference: np.ndarray, block: int) -> tuple[float, int]:
    """Chi-square of the blocks' channel sums, and the number of blocks in it.

    The three channels of a block are not independent (in a grey scene their z-scores are
    nearly equal), so the sum of all 3 x blocks squared z-scores is about 3 chi2(blocks), not
    chi2(3 x blocks): its 1e-3 quantile is about half again the threshold for 3 x blocks
    independent ones (measured on the smoke ball: z of R, G and B within 0.5 of each other).
    The channel sum's variance comes from the K renders like each channel's, covariances
    included, so its z-scores are independent between blocks.
    """
    h_mean, h_var, _, _ = mean_and_variance(np.asarray(haze, np.float64).sum(-1, keepdims=True), block)
    r_mean, r_var, _, _ = mean_and_variance(np.asarray(reference, np.float64).sum(-1, keepdims=True), block)
    precision = (FLOAT32_PRECISION * 0.5 * (np.abs(h_mean) + np.abs(r_mean))) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        z = (h_mean - r_mean) / np.sqrt(h_var + r_var + precision)
    z, counted = _lit_blocks(z, h_mean, h_var, r_mean, r_var)
    return float(np.nansum(z**2)), counted


def z_threshold(tests: int, family_alpha: float = 1e-3) -> float:
    """Two-sided normal threshold with a Bonferroni correction for `tests` z-scores."""
    from statistics import NormalDist

    return NormalDist().inv_cdf(1.0 - family_alpha / (2.0 * tests))


def chi_square_threshold(degrees: int, alpha: float = 1e-3) -> float:
    """Upper quantile of chi-square(degrees) by the Wilson-Hilferty approximation."""
    from statistics import NormalDist

    z = NormalDist().inv_cdf(1.0 - alpha)
    d = float(degrees)
    return d * (1.0 - 2.0 / (9.0 * d) + z * math.sqrt(2.0 / (9.0 * d))) ** 3


def assert_agree(comparison: Comparison, mean_tolerance: float = 0.01) -> None:
    """Image means within `mean_tolerance` and block means within noise.

    The mean test is meaningful only if noise cannot fake a 1 % difference: its sigma must be
    at most a third of the tolerance (a 3-sigma margin), otherwise the test setup is wrong.
    """
    assert np.all(comparison.relative_mean_sigma <= mean_tolerance / 3.0), (
        "too noisy for a 1% mean comparison: " + comparison.summary())
    assert np.all(np.abs(comparison.relative_mean_difference) <= mean_tolerance), comparison.summary()
    limit = z_threshold(max(comparison.degrees, 1))
    worst = float(np.max(np.abs(comparison.block_z)))
    assert worst <= limit, f"block z > {limit:.2f}: " + comparison.summary()
    chi_limit = chi_square_threshold(max(comparison.chi_degrees, 1))
    assert comparison.chi_square <= chi_limit, f"chi2 > {chi_limit:.1f}: " + comparison.summary()
