"""Error measures of the convergence benchmark: converged references, relMSE and RMSE with
the reference's own noise subtracted, curves of error against wall time, and the time a
curve takes to reach a target relMSE.

relMSE = mean((x - ref)^2 / (ref^2 + 1e-2)) minus the reference's own noise, i.e. minus the
mean of its per-pixel variance of the mean over the same denominator (both are independent,
so the expected squared differences add)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from renderer.film import REL_EPS, Film

TARGETS = (1e-2, 1e-3)


@dataclass
class Reference:
    """A converged image and the variance of each pixel's mean (its remaining noise)."""

    mean: np.ndarray  # (H, W, 3) float64
    variance: np.ndarray  # (H, W, 3) float64
    spp: int
    seconds: float

    @property
    def noise_relmse(self) -> float:
        return float(np.mean(self.variance / (self.mean**2 + REL_EPS)))

    def relmse(self, image: np.ndarray) -> float:
        """relMSE of `image` against the converged image: the reference's noise subtracted."""
        return float(np.mean((image - self.mean) ** 2 / (self.mean**2 + REL_EPS))) - self.noise_relmse

    def rmse(self, image: np.ndarray) -> float:
        return math.sqrt(max(float(np.mean((image - self.mean) ** 2) - np.mean(self.variance)), 0.0))


def film_reference(film: Film, seconds: float) -> Reference:
    shape = (film.height, film.width, 3)
    # The split estimate: unbiased with stratified samples, and these are means over pixels.
    variance = film.split_variance_of_mean().reshape(shape)
    return Reference(film.mean().reshape(shape), variance, film.spp, seconds)


def stack_reference(images: np.ndarray, spp: int, seconds: float) -> Reference:
    """Reference from K independent renders: their mean, and its variance from their spread."""
    k = images.shape[0]
    return Reference(images.mean(axis=0), images.var(axis=0, ddof=1) / k, spp * k, seconds)


# ------------------------------------------------------------------------------ curves


@dataclass
class Curve:
    """Error against wall time of one renderer / setting on one scene."""

    label: str
    seconds: list[float] = field(default_factory=list)
    spp: list[int] = field(default_factory=list)
    relmse: list[float] = field(default_factory=list)
    rmse: list[float] = field(default_factory=list)
    estimate: list[float] = field(default_factory=list)  # Haze's own running estimate (nan for Cycles)
    startup: float = math.nan  # fixed cost per render: intercept of seconds against spp

    def add(self, seconds: float, spp: int, relmse: float, rmse: float, estimate: float = math.nan) -> None:
        self.seconds.append(seconds)
        self.spp.append(spp)
        self.relmse.append(relmse)
        self.rmse.append(rmse)
        self.estimate.append(estimate)

    def fit_startup(self) -> None:
        """The part of the wall time that does not grow with samples (compile, process start,
        Cycles' scene sync and volume octree): the time to the first image less the sampling
        in it, at the steady seconds per sample of the later half of the curve."""
        if len(self.spp) >= 3:
            half = len(self.spp) // 2
            slope = (self.seconds[-1] - self.seconds[half]) / max(self.spp[-1] - self.spp[half], 1)
            self.startup = max(self.seconds[0] - self.spp[0] * slope, 0.0)

    def at_budget(self, budget: float) -> int | None:
        """Index of the last image available within `budget` seconds."""
        inside = [i for i, t in enumerate(self.seconds) if t <= budget]
        return inside[-1] if inside else None

    def time_to(self, target: float) -> tuple[float, bool]:
        """(seconds to reach relMSE `target`, extrapolated?) on the log-log curve."""
        t, e = np.asarray(self.seconds), np.asarray(self.relmse)
        for i in range(len(e)):
            if 0 < e[i] <= target:
                if i == 0 or e[i - 1] <= 0:
                    return float(t[i]), False
                s = (math.log(target) - math.log(e[i - 1])) / (math.log(e[i]) - math.log(e[i - 1]))
                return float(math.exp(math.log(t[i - 1]) + s * (math.log(t[i]) - math.log(t[i - 1])))), False
        return self._extrapolate(target), True

    def _extrapolate(self, target: float) -> float:
        """Past the last point: error ~ c / (t - startup), c fitted on the last third."""
        start = 0.0 if math.isnan(self.startup) else self.startup
        t, e = np.asarray(self.seconds), np.asarray(self.relmse)
        tail = slice(2 * len(t) // 3, None)
        keep = (e[tail] > 0) & (t[tail] > start)
        if not np.any(keep):
            return math.nan
        c = math.exp(float(np.mean(np.log(e[tail][keep]) + np.log(t[tail][keep] - start))))
        return start + c / target
