"""A world lit by an HDRI with a small, very bright sun: Haze agrees with Cycles.

One Blender process writes an equirectangular EXR (a coloured sky, a dim ground and a 2x2
pixel sun of radiance 900 over a sky of 0.04 to 1.1), lights a floor, a diffuse ball and a
rough metal ball with it through Texture Coordinate > Mapping (rotated) > Environment
Texture > Background (Strength 1.5), and renders K independent images with Cycles and with
Haze (as tests/test_addon_cycles.py, whose statistics it uses); then again with the same
image read as a mirror ball. The sky is in view, so the direction mapping and the rotation
are checked pixel by pixel as well as the lighting.

It also prints each renderer's noise per sample, relMSE x spp (relMSE estimated from the
spread of the K renders per pixel), and the seconds each took, for the benchmark report's figures;
it asserts nothing about them. Four runs make a rough estimate (the noise is heavy-tailed
around the sun); python -m bench hdri_variance measures it from more. Printed here (2-core VM,
loaded): Haze 0.42, Cycles 0.090 per sample with hashed random numbers and an environment
density constant per map pixel; with the first bounce stratified (renderer.kernels.rng) and
k x k cells per pixel of this 256-column map (renderer.lights.environment_map), Haze 0.123
against Cycles 0.090 (equirectangular) and 0.334 against 0.183 (mirror ball, sampled
through an equirectangular grid evaluated from the ball); with the mirror ball sampled on
its own image cells (renderer.lights.environment_ball), 0.186 against 0.180. With
`python -m bench hdri_variance --runs 24 --spp 32` (both engines at 32 spp, jackknife standard
errors): equirectangular Haze 0.125 +- 0.021, Cycles 0.182 +- 0.028; mirror ball Haze
0.666 +- 0.065 through the grid, 0.179 +- 0.026 on its own cells, Cycles 0.207 +- 0.030.
Haze's 4 x 128 spp took 11 s and Cycles' 4 x 32 spp 29 s before those changes.
"""

from __future__ import annotations

import numpy as np
import pytest

from bench.comparison import assert_agree, compare_images
from helpers.blender_runs import blender_fixture
from renderer.imageio import read_exr

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

RUNS = 4
SIZE = 64
# The same EXR read as an equirectangular map and as a mirror ball (the sun then lights the
# scene from behind, up about 33 degrees): (Cycles, Haze) samples per run, chosen so that
# noise on the compared image mean stays below a third of the 1 % tolerance (measured at
# 32 and 128: 0.18 % equirectangular, 0.35 % for the mirror ball's rim-free columns).
SAMPLES = {"EQUIRECTANGULAR": (32, 128), "MIRROR_BALL": (64, 256)}
PROJECTIONS = tuple(SAMPLES)

BODY = rf'''
import os
import time
import bpy_helpers as H
import blender_materials as M

SIZE = {SIZE}
RUNS = {RUNS}


def main():
    H.enable_addon()
    report = {{}}
    for projection, (cycles_samples, haze_samples) in {SAMPLES!r}.items():
        folder = os.path.join(os.getcwd(), projection)
        os.makedirs(folder, exist_ok=True)
        scene = M.hdri_scene(SIZE, folder, projection)
        paths = {{"cycles": [], "haze": []}}
        seconds = {{}}
        for engine, samples, configure in (("cycles", cycles_samples, H.configure_cycles),
                                           ("haze", haze_samples, H.configure_haze)):
            start = time.perf_counter()
            for run in range(RUNS):
                configure(scene, samples, 3, seed=run + 1)
                paths[engine].append(H.render_exr(scene, f"{{folder}}/{{engine}}_{{run}}.exr"))
            seconds[engine] = time.perf_counter() - start
        report[projection] = {{"paths": paths, "seconds": seconds}}
    return report
'''


renders = blender_fixture(BODY, "hdri", timeout=1800)


def stack(paths: list[str]) -> np.ndarray:
    return np.stack([read_exr(p)[..., :3] for p in paths])


def rel_mse_times_spp(images: np.ndarray, reference: np.ndarray, spp: int) -> float:
    """relMSE of one render (the variance across the K renders per pixel over the reference
    squared, Cycles' and pbrt's relMSE with a 1e-2 floor), times its samples per pixel."""
    variance = images.var(axis=0, ddof=1)
    return float((variance / (reference**2 + 1e-2)).mean() * spp)


# Where the mirror ball's image is read at its rim (map directions within a few degrees of
# +Y, which the ball reflects from its whole edge), Cycles and Haze differ: Haze clamps the
# read at the image's border, Cycles extends the image its own way (not in the shipped
# kernel source). The camera sees that direction in the sky at the frame's right edge
# (columns 56-63, rows 8-39); the rest of the frame must agree.
RIM_FREE_COLUMNS = slice(0, 48)


@pytest.mark.parametrize("projection", PROJECTIONS)
def test_hdri_world_agrees_with_cycles(renders, projection):
    renders = renders[projection]
    haze, cycles = stack(renders["paths"]["haze"]), stack(renders["paths"]["cycles"])
    assert haze.shape == cycles.shape == (RUNS, SIZE, SIZE, 3)
    assert cycles.mean() > 0.05, "the reference image is black: the scene is broken"
    reference = np.concatenate([haze, cycles]).mean(axis=0)
    cycles_samples, haze_samples = SAMPLES[projection]
    print(f"{projection} relMSE x spp: Haze {rel_mse_times_spp(haze, reference, haze_samples):.4g}, "
          f"Cycles {rel_mse_times_spp(cycles, reference, cycles_samples):.4g}; seconds {renders['seconds']}")
    if projection == "MIRROR_BALL":
        haze, cycles = haze[:, :, RIM_FREE_COLUMNS], cycles[:, :, RIM_FREE_COLUMNS]
    assert_agree(compare_images(haze, cycles))


@pytest.mark.xfail(strict=True, reason="the mirror ball's rim is read differently (see RIM_FREE_COLUMNS)")
def test_mirror_ball_rim_matches_cycles(renders):
    paths = renders["MIRROR_BALL"]["paths"]
    assert_agree(compare_images(stack(paths["haze"]), stack(paths["cycles"])))
