"""The film: per-pixel sum, sum of squares and count of path samples, and the sum of
their alpha, over the rendered window or a tile of it (a band of whole rows,
renderer.units).

Films of disjoint sample ranges merge by addition, so workers can render anywhere. The
error of the current image is estimated while it renders from the sum of a pixel's odd
samples beside the sum of all: the two halves are independent estimates of the pixel
(kernels.rng.SAMPLE_HALVES), while its samples, stratified, are not independent of each
other, so the second moment (kept for the variance of independent samples) overstates it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# relMSE = mean((x - ref)^2 / (ref^2 + REL_EPS)); the offset keeps black pixels from dominating.
REL_EPS = 1e-2


class FilmSums(NamedTuple):
    """A Film's arrays as the splat kernel (integrator.splat) adds to them: P pixels, float64
    unless noted. sum, sq (P, 3); n (P,) int64; odd (P, 4), the odd samples' sum (0-2) and
    count (3); nonfinite (1,) int64; alpha (P,); aov (P, C), the passes' sums, or (0, C)
    when the render has none."""

    sum: np.ndarray
    sq: np.ndarray
    n: np.ndarray
    odd: np.ndarray
    nonfinite: np.ndarray
    alpha: np.ndarray
    aov: np.ndarray


class Film:
    def __init__(self, width: int, height: int, first_row: int = 0):
        """width x height pixels, rows first_row .. first_row + height - 1 of the window."""
        self.width = width
        self.height = height
        self.first_row = first_row
        p = width * height
        self.sum = np.zeros((p, 3), np.float64)  # per pixel and channel
        self.sq = np.zeros((p, 3), np.float64)
        self.n = np.zeros(p, np.int64)  # samples per pixel
        self.odd = np.zeros((p, 4), np.float64)  # the odd samples' sum (0-2) and count (3)
        self.alpha = np.zeros(p, np.float64)  # sum of the samples' alpha (1 unless Film > Transparent)
        self.nonfinite = np.zeros(1, np.int64)  # path values that were NaN or inf (added as 0)
        # Sums of the render passes' columns (integrator.paths AOV_*), only once a tracer with
        # passes requested adds to this film (ensure_aov): a film without passes holds none.
        self.aov: np.ndarray | None = None

    def ensure_aov(self, columns: int) -> np.ndarray:
        """The passes' sums: integrator.paths.AOV_COUNT columns, + LIGHT_AOV_COUNT with the
        light passes."""
        if self.aov is None:
            self.aov = np.zeros((self.width * self.height, columns), np.float64)
        assert self.aov.shape[1] == columns, "films with different passes cannot be added"
        return self.aov

    def add(self, other: Film) -> None:
        """Add other's samples into place: other may hold some of this film's rows (a tile)."""
        start = (other.first_row - self.first_row) * self.width
        at = slice(start, start + other.n.size)
        assert other.width == self.width and 0 <= start and at.stop <= self.n.size, "a tile outside the film"
        self.sum[at] += other.sum
        self.sq[at] += other.sq
        self.n[at] += other.n
        self.odd[at] += other.odd
        self.alpha[at] += other.alpha
        self.nonfinite += other.nonfinite
        if other.aov is not None:
            self.ensure_aov(other.aov.shape[1])[at] += other.aov

    def sums(self, aov: np.ndarray) -> FilmSums:
        """The arrays the splat adds to, with `aov` for the passes' sums (ensure_aov, or an
        empty array when the render has no passes)."""
        return FilmSums(self.sum, self.sq, self.n, self.odd, self.nonfinite, self.alpha, aov)

    @property
    def spp(self) -> int:
        return int(self.n.min()) if self.n.size else 0

    def mean(self) -> np.ndarray:
        """(P, 3) float64 per-pixel mean."""
        return self.sum / np.maximum(self.n, 1)[:, None]

    def image(self) -> np.ndarray:
        """(H, W, 3) float32 image, row 0 at the top."""
        return self.mean().reshape(self.height, self.width, 3).astype(np.float32)

    def alpha_image(self) -> np.ndarray:
        """(H, W) float32 mean alpha, row 0 at the top."""
        mean = self.alpha / np.maximum(self.n, 1)
        return mean.reshape(self.height, self.width).astype(np.float32)

    def variance_of_mean(self) -> np.ndarray:
        """(P, 3) estimate of each pixel mean's variance from the samples' second moment
        (nan where n < 2): unbiased for independent samples, too high (never too low) for
        stratified ones (kernels.rng.STRATIFIED_DIMS), by up to 2x and more where
        stratification helps most. What a z-score per pixel needs (many degrees of
        freedom); split_variance_of_mean is unbiased but has one."""
        n = self.n[:, None].astype(np.float64)
        mean = self.sum / np.maximum(n, 1)
        var = (self.sq - n * mean * mean) / np.maximum(n - 1, 1)
        out = np.maximum(var, 0.0) / np.maximum(n, 1)
        out[self.n < 2] = np.nan
        return out

    def split_variance_of_mean(self) -> np.ndarray:
        """(P, 3) unbiased estimate of each pixel mean's variance from its two independent
        halves (kernels.rng.SAMPLE_HALVES), nan where a half is empty. With n0 even and n1
        odd samples of means m0 and m1 (each of variance ~ c / n_h), the mean's variance
        c / n is estimated by (m0 - m1)^2 n0 n1 / n^2: one degree of freedom per pixel,
        so it is for means over many pixels (Film.rel_mse_estimate, bench.metrics)."""
        n1 = self.odd[:, 3:4]
        n = self.n[:, None].astype(np.float64)
        n0 = n - n1
        m1 = self.odd[:, :3] / np.maximum(n1, 1)
        m0 = (self.sum - self.odd[:, :3]) / np.maximum(n0, 1)
        out = (m0 - m1) ** 2 * n0 * n1 / np.maximum(n * n, 1)
        out[(n0[:, 0] < 1) | (n1[:, 0] < 1)] = np.nan
        return out

    def rel_mse_estimate(self) -> float:
        """Expected relMSE of the current image against the converged one, from the
        per-pixel variance of the mean (split_variance_of_mean, from the two independent
        halves of the pixel's samples: unbiased with stratified samples, where the second
        moment overstated it by more than 2x): mean(var(mean) / (level^2 + REL_EPS)), where
        a pixel's level is the smaller of its mean and the mean of its 5x5 neighbourhood.

        With the pixel's own mean as the level (the textbook form), a firefly raises a
        pixel's variance and its mean together, so its term stays below ~1 however wrong
        the pixel is, and the estimate fell 3-14x below the true error at 4-16 spp in fog
        (g = 0.9); the neighbourhood barely moves with one firefly. Measured by
        `python -m bench convergence` on five scenes: within 0.94-1.8x of the true
        relMSE from 4 spp on (docs/convergence/tables.md)."""
        if self.spp < 2:
            return float("nan")
        shape = (self.height, self.width, 3)
        m = self.mean().reshape(shape)
        level = np.minimum(m, box_mean(m, 2))
        return float(np.mean(self.split_variance_of_mean().reshape(shape) / (level * level + REL_EPS)))


def box_mean(image: np.ndarray, radius: int) -> np.ndarray:
    """Mean over the (2 radius + 1)^2 window around each pixel of an (H, W, C) image, edges
    repeated (summed-area table: cost independent of the radius)."""
    padded = np.pad(image, ((radius, radius), (radius, radius), (0, 0)), mode="edge").astype(np.float64)
    sums = np.pad(np.cumsum(np.cumsum(padded, axis=0), axis=1), ((1, 0), (1, 0), (0, 0)))
    w = 2 * radius + 1
    h, wd = image.shape[:2]
    return (sums[w:w + h, w:w + wd] - sums[:h, w:w + wd] - sums[w:w + h, :wd] + sums[:h, :wd]) / (w * w)
