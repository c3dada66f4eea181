"""Volume Direct and Volume Indirect through Blender's pass system, against Cycles' same
passes of the same scene.

One Blender process renders a stage (diffuse floor and wall lit by a sun and a grey sky, a
cube of scattering fog in front of the wall: tests/helpers/pass_stage.py's geometry without the
balls) RUNS times with Cycles and with Haze (different seeds) into multilayer EXRs.

Cycles' definitions (kernel/film/light_passes.h, integrator/path_state.h): a camera path's
first scattering event sets its category; light it brings back after a first scatter in a
volume goes to Volume Direct when it comes from that vertex (its next-event ray, or the
emission the path finds right after it) and to Volume Indirect otherwise. Cycles' Combined
is then the sum of its light passes: Emission + Environment + (Direct + Indirect) x Color
for diffuse, glossy and transmission + Volume Direct + Volume Indirect. Checked here:
* that identity in Cycles' own passes (the partition is what the test relies on);
* Haze's Volume Direct and Indirect against Cycles' within the runs' noise: Welch t-tests of
  8x8 block means (tests/helpers/block_stats.py) and of each run's image total (the stronger test
  of a scale error: its relative sigma is about 2%, measured), and Haze's remainder
  Combined - Volume Direct - Volume Indirect against the sum of Cycles' world, emission and
  surface passes the same way;
* both renderers' volume passes are exactly 0 where no camera ray crosses the fog (their
  first scatter is the wall's or the floor's), and far from 0 in the fog.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.blender_runs import blender_fixture
from helpers.block_stats import block_tests, t_quantile, worst
from helpers.pass_stage import fog_length, pixel_rays, read_runs

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

SIZE = (32, 24)
SAMPLES = 16
RUNS = 5
VOLUME = ("Volume Direct", "Volume Indirect")
SURFACE = ("Diffuse", "Glossy", "Transmission")

BODY = rf'''
import os
import bpy_helpers as H
from helpers import pass_stage as S

SIZE = {SIZE!r}
SAMPLES = {SAMPLES}
RUNS = {RUNS}


def main():
    H.enable_addon()
    scene = S.build_stage(SIZE, balls=False)
    view_layer = scene.view_layers[0]
    view_layer.cycles.use_pass_volume_direct = view_layer.cycles.use_pass_volume_indirect = True
    view_layer.use_pass_emit = view_layer.use_pass_environment = True
    for kind in ("diffuse", "glossy", "transmission"):
        for part in ("direct", "indirect", "color"):
            setattr(view_layer, f"use_pass_{{kind}}_{{part}}", True)
    out = S.render_runs(scene, RUNS, SAMPLES)
    return out
'''


renders = blender_fixture(BODY, "volume_passes", timeout=1800, read=read_runs)


def stack(renders, name: str) -> np.ndarray:
    return np.stack([r[name][..., :3] for r in renders])


def cycles_surface_and_world(passes: dict[str, np.ndarray]) -> np.ndarray:
    """Cycles' light that did not come back through a volume: world and emission seen
    directly, and each surface category's (Direct + Indirect) x Color."""
    total = passes["Environment"] + passes["Emission"]
    for kind in SURFACE:
        total = total + (passes[f"{kind} Direct"] + passes[f"{kind} Indirect"]) * passes[f"{kind} Color"]
    return total


def haze_surface_and_world(passes: dict[str, np.ndarray]) -> np.ndarray:
    return passes["Combined"][..., :3] - passes["Volume Direct"] - passes["Volume Indirect"]


def fogless() -> np.ndarray:
    """(H, W) pixels none of whose camera rays crosses the fog cube, with a pixel's margin."""
    crossing = (fog_length(pixel_rays(SIZE, 16)) > 0.0).any(axis=-1)
    padded = np.pad(crossing, 1)
    h, w = crossing.shape
    return ~np.any([padded[y:y + h, x:x + w] for y in range(3) for x in range(3)], axis=0)


def assert_within_noise(haze: np.ndarray, cycles: np.ndarray, name: str) -> None:
    tests = block_tests(haze, cycles)
    test, ratio = worst(tests)
    assert ratio <= 1.0, (f"{name}: block {test.block} channel {test.channel} differs by "
                          f"{test.difference:.4f}, t {test.t:.1f} (dof {test.dof:.0f}) of {len(tests)}")


def test_cycles_light_passes_sum_to_combined(renders):
    """The partition the comparison relies on, in Cycles' own passes."""
    for passes in renders["cycles"]:
        total = cycles_surface_and_world(passes) + passes["Volume Direct"] + passes["Volume Indirect"]
        combined = passes["Combined"][..., :3]
        np.testing.assert_allclose(total, combined, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("name", VOLUME)
def test_volume_passes_agree_with_cycles_within_noise(renders, name):
    haze, cycles = stack(renders["haze"], name), stack(renders["cycles"], name)
    assert haze.shape == cycles.shape == (RUNS, SIZE[1], SIZE[0], 3)
    assert_within_noise(haze, cycles, name)


@pytest.mark.parametrize("name", VOLUME)
def test_volume_pass_totals_agree_with_cycles_within_noise(renders, name):
    """Each run's image total: Welch t over the RUNS runs of each renderer, alpha 1e-3."""
    haze = stack(renders["haze"], name).sum(axis=(1, 2, 3))
    cycles = stack(renders["cycles"], name).sum(axis=(1, 2, 3))
    a, b = haze.var(ddof=1) / RUNS, cycles.var(ddof=1) / RUNS
    t = (haze.mean() - cycles.mean()) / np.sqrt(a + b)
    dof = (a + b) ** 2 / (a * a / (RUNS - 1) + b * b / (RUNS - 1))
    limit = t_quantile(1.0 - 1e-3 / 2.0, dof)
    assert abs(t) <= limit, f"{name}: Haze {haze.mean():.3f} against Cycles {cycles.mean():.3f}, t {t:.1f}"


def test_surface_and_world_light_agree_with_cycles_within_noise(renders):
    """What Haze's Combined holds beyond its volume passes is Cycles' surface and world light."""
    haze = np.stack([haze_surface_and_world(p) for p in renders["haze"]])
    cycles = np.stack([cycles_surface_and_world(p) for p in renders["cycles"]])
    assert_within_noise(haze, cycles, "Combined - Volume Direct - Volume Indirect")


def test_volume_passes_are_zero_without_fog_and_seen_in_it(renders):
    clear = fogless()
    assert 0.3 < clear.mean() < 0.9, "the fog cube is not where the test expects it"
    for name in VOLUME:
        for engine in ("haze", "cycles"):
            images = stack(renders[engine], name)
            assert (images[:, clear] == 0.0).all(), f"{engine} {name}: light outside the fog"
            assert (images.mean(axis=0).max(axis=-1) > 0.02).sum() >= 20, f"{engine} {name}: too little"
