"""Two-sample t-tests of block means from K independent renders, for passes whose pixels
may be deterministic in some places and noisy in others.

Each pixel's variance comes from the spread of its K renders (K - 1 degrees of freedom).
A block mean's variance is the sum of its pixels' variances (pixels are independent: box
filter of width 1), and its degrees of freedom follow from Welch-Satterthwaite: a block
with many noisy pixels is tested almost as a normal z, a block with one noisy pixel as a
t with K - 1 degrees of freedom. Thresholds are Bonferroni-corrected over all the tests.
No scipy: the t quantile is found by integrating the density.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

# Both renderers compute in float32: a block whose pixels are all deterministic agrees to
# this absolute precision (measured: 5e-7 on unit normals and albedos).
PRECISION = 1e-5


def t_cdf(t: float, nu: float) -> float:
    """Student t distribution function, by the trapezoid rule on its density."""
    x = np.linspace(0.0, abs(t), 20001)
    c = math.exp(math.lgamma((nu + 1) / 2) - math.lgamma(nu / 2)) / math.sqrt(nu * math.pi)
    half = float(np.trapz(c * (1.0 + x * x / nu) ** (-(nu + 1) / 2), x))
    return 0.5 + math.copysign(half, t)


def t_quantile(p: float, nu: float) -> float:
    """Upper quantile of Student's t (p > 0.5) with nu degrees of freedom, by bisection."""
    if nu > 1e4:
        return NormalDist().inv_cdf(p)
    low, high = 0.0, 1e4
    for _ in range(80):
        mid = 0.5 * (low + high)
        low, high = (mid, high) if t_cdf(mid, nu) < p else (low, mid)
    return high


@dataclass
class BlockTest:
    """One block and channel: difference of means, its t statistic, degrees of freedom."""

    block: tuple[int, int]
    channel: int
    difference: float
    t: float
    dof: float

    def p_threshold(self, tests: int, family_alpha: float = 1e-3) -> float:
        return t_quantile(1.0 - family_alpha / (2.0 * tests), self.dof)


def block_tests(a: np.ndarray, b: np.ndarray, mask: np.ndarray | None = None, block: int = 8
                ) -> list[BlockTest]:
    """Welch t-tests of the 8x8 block means of two (K, H, W, C) stacks of independent renders,
    over the pixels where mask (H, W) is True (blocks without any are skipped)."""
    k = a.shape[0]
    assert b.shape == a.shape and k >= 3
    h, w = a.shape[1:3]
    mask = np.ones((h, w), bool) if mask is None else mask
    mean = a.mean(axis=0) - b.mean(axis=0)
    variance = np.concatenate([a.var(axis=0, ddof=1), b.var(axis=0, ddof=1)], axis=-1) / k
    out = []
    for by in range(h // block):
        for bx in range(w // block):
            rows, cols = slice(by * block, (by + 1) * block), slice(bx * block, (bx + 1) * block)
            keep = mask[rows, cols]
            n = int(keep.sum())
            if n == 0:
                continue
            for c in range(a.shape[-1]):
                parts = variance[rows, cols][keep][:, [c, a.shape[-1] + c]].ravel() / n**2
                total = parts.sum()
                # Welch-Satterthwaite; deterministic blocks (no variance) compare by precision.
                dof = total**2 / (parts**2).sum() * (k - 1) if total > 0.0 else math.inf
                difference = float(mean[rows, cols, c][keep].mean())
                t = difference / math.sqrt(total + PRECISION**2)
                out.append(BlockTest((by, bx), c, difference, t, min(dof, 1e5)))
    return out


def worst(tests: list[BlockTest], family_alpha: float = 1e-3) -> tuple[BlockTest, float]:
    """The test furthest beyond its own threshold, and that threshold (ratio |t| / limit)."""
    ratios = [(abs(x.t) / x.p_threshold(len(tests), family_alpha), x) for x in tests]
    ratio, test = max(ratios, key=lambda r: r[0])
    return test, ratio
