"""The film: per-pixel sum, sum of squares and count of path samples.

Keeping the second moment lets callers estimate the error of the current image while it
renders (the variance of each pixel's mean), and films of disjoint sample ranges merge by
addition, so workers can render anywhere.
"""

from __future__ import annotations

import numpy as np

# relMSE = mean((x - ref)^2 / (ref^2 + REL_EPS)); the offset keeps black pixels from dominating.
REL_EPS = 1e-2


class Film:
    def __init__(self, width: int, height: int):
        self.width = width
        self.height = height
        p = width * height
        self.sum = np.zeros((p, 3), np.float64)  # per pixel and channel
        self.sq = np.zeros((p, 3), np.float64)
        self.n = np.zeros(p, np.int64)  # samples per pixel
        self.nonfinite = np.zeros(1, np.int64)  # path values that were NaN or inf (added as 0)

    def add(self, other: Film) -> None:
        self.sum += other.sum
        self.sq += other.sq
        self.n += other.n
        self.nonfinite += other.nonfinite

    @property
    def spp(self) -> int:
        return int(self.n.min()) if self.n.size else 0

    def mean(self) -> np.ndarray:
        """(P, 3) float64 per-pixel mean."""
        return self.sum / np.maximum(self.n, 1)[:, None]

    def image(self) -> np.ndarray:
        """(H, W, 3) float32 image, row 0 at the top."""
        return self.mean().reshape(self.height, self.width, 3).astype(np.float32)

    def variance_of_mean(self) -> np.ndarray:
        """(P, 3) unbiased estimate of each pixel mean's variance (nan where n < 2)."""
        n = self.n[:, None].astype(np.float64)
        mean = self.sum / np.maximum(n, 1)
        var = (self.sq - n * mean * mean) / np.maximum(n - 1, 1)
        out = np.maximum(var, 0.0) / np.maximum(n, 1)
        out[self.n < 2] = np.nan
        return out

    def rel_mse_estimate(self) -> float:
        """Expected relMSE of the current image against the converged one, from the
        per-pixel variance: mean(var(mean) / (mean^2 + REL_EPS))."""
        if self.spp < 2:
            return float("nan")
        m = self.mean()
        return float(np.mean(self.variance_of_mean() / (m * m + REL_EPS)))
