"""A world lit by an HDRI with a small, very bright sun: Haze agrees with Cycles.

One Blender process writes an equirectangular EXR (a coloured sky, a dim ground and a 2x2
pixel sun of radiance 900 over a sky of 0.04 to 1.1), lights a floor, a diffuse ball and a
rough metal ball with it through Texture Coordinate > Mapping (rotated) > Environment
Texture > Background (Strength 1.5), and renders K independent images with Cycles and with
Haze (as tests/test_addon_cycles.py, whose statistics it uses); then again with the same
image read as a mirror ball. The sky is in view, so the direction mapping and the rotation
are checked pixel by pixel as well as the lighting.

It also prints each renderer's noise per sample, relMSE x spp (relMSE estimated from the
spread of the K renders per pixel), and the seconds each took, for the README's figures;
it asserts nothing about them. Measured (2-core VM, loaded): Haze 0.42, Cycles 0.090 per
sample (Cycles' quasi-Monte Carlo sequences stratify the sun-or-sky choice of every pixel's
samples, Haze's random numbers do not), while Haze's 4 x 128 spp took 11 s and Cycles' 4 x
32 spp 29 s: per second of rendering Haze's relMSE is about 2.2 times lower.
"""

from __future__ import annotations

import numpy as np
import pytest
from bpy_helpers import assert_agree, compare_images, run_blender, shared_numba_cache

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
import math
import time
import bpy
import numpy as np
import bpy_helpers as H
import blender_cornell as C
from renderer.imageio import write_exr

SIZE = {SIZE}
RUNS = {RUNS}
MAP_W, MAP_H = 256, 128
SUN_ROW, SUN_COL = 96, 40  # from the bottom: about 45 degrees up


def sky_pixels():
    v = (np.arange(MAP_H) + 0.5) / MAP_H
    u = (np.arange(MAP_W) + 0.5) / MAP_W
    z = -np.cos(math.pi * v)
    sky = np.clip(z, 0.0, None)[:, None] * (1.0 + 0.4 * np.sin(2 * math.pi * u))[None, :]
    rgba = np.ones((MAP_H, MAP_W, 4), np.float32)
    rgba[..., 0] = 0.06 + 0.25 * sky
    rgba[..., 1] = 0.05 + 0.4 * sky
    rgba[..., 2] = 0.04 + 0.8 * sky
    rgba[SUN_ROW:SUN_ROW + 2, SUN_COL:SUN_COL + 2, :3] = (900.0, 800.0, 650.0)
    return rgba


def hdri_world(scene, path, projection):
    # Written as an artist's HDRI arrives: a linear EXR (scanlines top-down), loaded as
    # Linear Rec.709. (Saving a generated float image from Blender instead writes it
    # display-encoded and tags it sRGB, which Cycles and Blender then decode differently.)
    write_exr(path, sky_pixels()[::-1, :, :3])
    world = bpy.data.worlds.new("HDRI")
    H.ensure_nodes(world)
    nodes, links = world.node_tree.nodes, world.node_tree.links
    background = nodes["Background"]
    background.inputs["Strength"].default_value = 1.5
    texture = nodes.new("ShaderNodeTexEnvironment")
    texture.image = bpy.data.images.load(path)
    texture.image.colorspace_settings.name = "Linear Rec.709"
    texture.projection = projection
    mapping = nodes.new("ShaderNodeMapping")
    mapping.inputs["Rotation"].default_value = (0.0, 0.0, math.radians(30.0))
    coords = nodes.new("ShaderNodeTexCoord")
    links.new(coords.outputs["Generated"], mapping.inputs["Vector"])
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], background.inputs["Color"])
    scene.world = world


def build(folder, projection):
    scene = C.clear_scene()
    hdri_world(scene, os.path.join(folder, "sky.exr"), projection)
    H.floor_plane("Floor", 3.0, C.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    H.uv_sphere("Ball", (-0.6, 0.3, 0.5), 0.5, C.diffuse_material("Ball", (0.7, 0.4, 0.3)))
    H.uv_sphere("Metal", (0.7, 0.0, 0.45), 0.45, H.principled_material(
        "Metal", Base_Color=(0.9, 0.9, 0.9), Metallic=1.0, Roughness=0.3, distribution="GGX"))
    C.add_camera(scene, (0.0, -4.5, 1.3), (80.0, 0.0, 0.0), lens=30.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    return scene


def main():
    H.enable_dev_addon()
    report = {{}}
    for projection, (cycles_samples, haze_samples) in {SAMPLES!r}.items():
        folder = os.path.join(os.getcwd(), projection)
        os.makedirs(folder, exist_ok=True)
        scene = build(folder, projection)
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


@pytest.fixture(scope="module")
def renders(tmp_path_factory):
    run = run_blender(BODY, tmp_path_factory.mktemp("hdri"), timeout=1800, numba_cache=shared_numba_cache())
    assert run.returncode == 0 and run.result, run.describe()
    return run.result


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
