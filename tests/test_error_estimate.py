"""Haze's online error estimate (Film.rel_mse_estimate) against the true error.

The estimate is what the progress line shows and what --target-error stops on, so it must
track the relMSE a converged reference would measure. For every benchmark scene of
`python -m bench convergence`, at 32x32:

* a reference of REFERENCE_SPP samples per pixel (seed 1000), whose own noise is subtracted
  from the measured error (relMSE against a noisy reference = true relMSE + its noise);
* RUNS independent renders (seeds 1..RUNS), measured after SPP_LEVELS samples each;
* mean estimate and mean true relMSE over the runs must agree within a factor of 2.

The test checks that it can resolve a factor of 2 before it judges: the reference's noise
must be at most a tenth of the measured error, and the relative standard error of the
mean true error (from the spread of the runs) at most ln(2) / 3, so that a correct
estimate sits at least three standard errors from either limit. A setup that fails
these is wrong, not the estimator.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bench.metrics import Reference, film_reference
from bench.scenes import SCENES as BENCH_SCENES
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer

pytestmark = pytest.mark.slow

# The benchmark's scenes in Haze's own format (those built in Blender need a Blender export).
SCENES = {name: bench for name, bench in BENCH_SCENES.items() if bench.blend is None}
SIZE = 32
REFERENCE_SPP = 2048
REFERENCE_SEED = 1000
RUNS = 8
SPP_LEVELS = (16, 64)
FACTOR = 2.0
MAX_RELATIVE_STANDARD_ERROR = math.log(FACTOR) / 3.0
MAX_REFERENCE_NOISE_SHARE = 0.1

# Measured with this test's seeds: the estimate divides each pixel's variance by its own
# noisy mean squared, so a firefly inflates numerator and denominator together and the
# pixel's term stays below ~1 while its true error is far larger. With the reference's
# mean in the denominator instead, the same variances give ratios 0.97-1.06 everywhere.
# Known failures, each with its measured ratio: none since the estimate floors each pixel's
# level by its neighbourhood (fog g 0.9 was 7.9x at 16 spp and 2.8x at 64 spp before; fog
# g 0 was 3.5x at 16 spp before triangle lights were sampled by solid angle).
KNOWN_UNDERESTIMATES: dict[tuple[str, int], str] = {}


class Measurement:
    """Per run and spp level: the true relMSE and the film's estimate."""

    def __init__(self) -> None:
        self.true: dict[int, list[float]] = {n: [] for n in SPP_LEVELS}
        self.estimate: dict[int, list[float]] = {n: [] for n in SPP_LEVELS}


@pytest.fixture(scope="module")
def measurements() -> dict[str, tuple[Reference, Measurement]]:
    results = {}
    for name, bench in SCENES.items():
        scene = bench.build(SIZE)
        compiled = compile_scene(scene)
        tracer = Tracer(compiled, scene.integrator)
        reference_film = Film(SIZE, SIZE)
        tracer.trace(reference_film, 0, REFERENCE_SPP, REFERENCE_SEED)
        reference = film_reference(reference_film, 0.0)
        measurement = Measurement()
        for run in range(1, RUNS + 1):
            film, done = Film(SIZE, SIZE), 0
            for n in SPP_LEVELS:  # one progressive film per run, read at each level
                tracer.trace(film, done, n - done, run)
                done = n
                measurement.true[n].append(reference.relmse(film.mean().reshape(SIZE, SIZE, 3)))
                measurement.estimate[n].append(film.rel_mse_estimate())
        results[name] = (reference, measurement)
    return results


def case(name: str, n: int):
    reason = KNOWN_UNDERESTIMATES.get((name, n))
    marks = [pytest.mark.xfail(strict=True, reason=reason)] if reason else []
    return pytest.param(name, n, marks=marks, id=f"{name}-{n}spp")


@pytest.mark.parametrize(("scene", "spp"), [case(name, n) for name in SCENES for n in SPP_LEVELS])
def test_estimate_within_factor_2_of_true_error(measurements, scene, spp):
    reference, measurement = measurements[scene]
    true = np.asarray(measurement.true[spp])
    estimate = float(np.mean(measurement.estimate[spp]))
    mean_true = float(true.mean())
    relative_standard_error = float(true.std(ddof=1) / math.sqrt(len(true)) / mean_true)
    figures = (f"true relMSE {mean_true:.4g} (relative standard error {relative_standard_error:.2f}), "
               f"estimate {estimate:.4g}, ratio {mean_true / estimate:.2f}; reference noise "
               f"{reference.noise_relmse:.2g}")
    print(f"{scene} {spp} spp: {figures}")
    assert reference.noise_relmse <= MAX_REFERENCE_NOISE_SHARE * mean_true, "reference too noisy: " + figures
    assert relative_standard_error <= MAX_RELATIVE_STANDARD_ERROR, "too few runs to judge: " + figures
    assert 1.0 / FACTOR <= mean_true / estimate <= FACTOR, figures
