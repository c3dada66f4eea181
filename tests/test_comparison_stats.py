"""The Haze-against-Cycles comparison's statistics (bench/comparison.py), on synthetic renders.

A grey scene's three channels carry the same noise, so their block z-scores are nearly
equal: the chi-square must count blocks, not blocks x channels, or it rejects a correct
renderer far more often than its 1e-3 level says.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.comparison import assert_agree, chi_square_threshold, compare_images

RUNS, SIZE, BLOCK = 4, 32, 8


def grey_renders(rng: np.random.Generator, mean: np.ndarray, runs: int = RUNS) -> np.ndarray:
    """`runs` renders (runs, H, W, 3) of a grey image: per-pixel noise shared by R, G and B
    (heavy-ish tailed, as path tracing's), scaled by the per-pixel mean."""
    noise = rng.gamma(2.0, 0.5, (runs, SIZE, SIZE, 1))  # mean 1, sd 0.7 per pixel and run
    return (mean[None, :, :, None] * noise).repeat(3, axis=3)


def scene_mean(rng: np.random.Generator) -> np.ndarray:
    return 0.2 + rng.random((SIZE, SIZE))


def test_grey_blocks_are_counted_once_in_the_chi_square():
    rng = np.random.default_rng(1)
    mean = scene_mean(rng)
    comparison = compare_images(grey_renders(rng, mean), grey_renders(rng, mean))
    assert comparison.degrees == 3 * (SIZE // BLOCK) ** 2
    assert comparison.chi_degrees == (SIZE // BLOCK) ** 2


def test_a_correct_grey_render_is_rejected_at_about_the_stated_rate():
    """Same distribution on both sides, 400 seeded trials: the chi-square rejects at most 1 %
    (its level is 1e-3; the per-channel sum over 48 correlated z-scores rejected ~3 %)."""
    rng = np.random.default_rng(2)
    mean = scene_mean(rng)
    rejected = 0
    for _ in range(400):
        comparison = compare_images(grey_renders(rng, mean), grey_renders(rng, mean))
        rejected += comparison.chi_square > chi_square_threshold(comparison.chi_degrees)
    assert rejected <= 4, rejected


def test_a_biased_block_is_still_found():
    """A 40 % brighter 8x8 block, one channel only, among otherwise equal renders."""
    rng = np.random.default_rng(3)
    mean = scene_mean(rng)
    haze = grey_renders(rng, mean, runs=16)
    haze[:, :BLOCK, :BLOCK, 0] *= 1.4
    with pytest.raises(AssertionError, match="block z|chi2"):
        assert_agree(compare_images(haze, grey_renders(rng, mean, runs=16)), mean_tolerance=0.05)
