"""The light and colour passes (Emission, Diffuse, Glossy and Transmission Color) through
Blender's pass system, against Cycles' same passes of the same scene.

One Blender process renders a stage (diffuse floor and wall, a Glossy BSDF ball, a
Principled BSDF ball, a clear Glass BSDF ball, an Emission quad on the wall, a sun and a
grey sky) RUNS times with Cycles and with Haze (different seeds) into multilayer EXRs with
the View Layer's colour and Emission toggles on, then Haze once with them off.

Cycles' definitions (kernel/film/data_passes.h, light_passes.h): Diffuse, Glossy and
Transmission Color are throughput x the diffuse / glossy / transmission closures' albedo at
the hits before the camera path scatters (a smooth glass's transmission albedo is its
tint x (1 - Fresnel) for the view angle); Emission is the emission it finds before
scattering. Cycles also adds a glass's reflectance to Glossy Color, which Haze does not
write: Glossy Color is compared away from the glass ball. Where every sample of a
pixel sees the same surface the passes are deterministic in both renderers and must agree
to float precision; elsewhere (silhouettes, and the Principled layer's albedo, which
varies with the view angle across a pixel) 8x8 block means agree within the runs' noise
(Welch t-tests, tests/helpers/block_stats.py).
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.blender_runs import blender_fixture
from helpers.block_stats import PRECISION, block_tests, worst
from helpers.pass_stage import dilate, hits_sphere, pixel_rays, read_runs

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

SIZE = (48, 32)
SAMPLES = 16
RUNS = 6
NAMES = ("Diffuse Color", "Glossy Color", "Transmission Color", "Emission")
CAMERA, TILT = np.array([0.0, -4.5, 1.4]), np.radians(78.0)
PLASTIC_CENTER, PLASTIC_RADIUS = np.array([0.3, -0.3, 0.45]), 0.45
GLASS_CENTER, GLASS_RADIUS = np.array([1.5, -0.8, 0.35]), 0.35


def sphere_region(center: np.ndarray, radius: float) -> np.ndarray:
    """(H, W) pixels that see the ball, with their neighbours."""
    rays = pixel_rays(SIZE, 16, TILT)
    return dilate(hits_sphere(rays, center, radius, CAMERA).any(axis=-1))


def plastic_region() -> np.ndarray:
    return sphere_region(PLASTIC_CENTER, PLASTIC_RADIUS)


def glass_region() -> np.ndarray:
    return sphere_region(GLASS_CENTER, GLASS_RADIUS)

BODY = rf'''
import math
import os
import bpy
import bpy_helpers as H
import blender_cornell as C
from helpers import pass_stage as S

SIZE = {SIZE!r}
SAMPLES = {SAMPLES}
RUNS = {RUNS}


def shader(name, kind, **inputs):
    material, tree, output = C.node_material(name)
    node = tree.nodes.new(kind)
    for key, value in inputs.items():
        if key == "distribution":
            node.distribution = value
        else:
            node.inputs[key].default_value = value
    socket = node.outputs[0]
    tree.links.new(socket, output.inputs["Surface"])
    return material


def stage():
    scene = C.clear_scene()
    scene.render.use_compositing = False
    H.world_color(scene, (0.3, 0.3, 0.3), 1.0)
    H.floor_plane("Floor", 4.0, C.diffuse_material("Floor", (0.7, 0.7, 0.7)))
    H.new_object("Wall", [(-4, 2.0, 0), (4, 2.0, 0), (4, 2.0, 2.5), (-4, 2.0, 2.5)], [(0, 1, 2, 3)],
                 C.diffuse_material("Wall", (0.6, 0.5, 0.4)))
    lamp = shader("Lamp", "ShaderNodeEmission", Color=(1.0, 0.8, 0.6, 1.0), Strength=4.0)
    H.new_object("Lamp", [(0.6, 1.99, 0.9), (1.6, 1.99, 0.9), (1.6, 1.99, 1.6), (0.6, 1.99, 1.6)],
                 [(0, 1, 2, 3)], lamp)
    H.uv_sphere("Glossy", (-1.0, 0.0, 0.5), 0.5,
                shader("Glossy", "ShaderNodeBsdfGlossy", Color=(0.8, 0.6, 0.3, 1.0), Roughness=0.3,
                       distribution="GGX"))
    H.uv_sphere("Plastic", (0.3, -0.3, 0.45), 0.45,
                shader("Plastic", "ShaderNodeBsdfPrincipled", **{{"Base Color": (0.2, 0.5, 0.8, 1.0),
                                                                 "Roughness": 0.4}}))
    H.uv_sphere("Glass", (1.5, -0.8, 0.35), 0.35,
                shader("Glass", "ShaderNodeBsdfGlass", Color=(0.9, 0.7, 0.5, 1.0), Roughness=0.0, IOR=1.5))
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (40.0, 0.0, 30.0), energy=2.0, angle=math.radians(5.0))
    C.add_camera(scene, (0.0, -4.5, 1.4), (78.0, 0.0, 0.0), lens=35.0)
    scene.render.resolution_x, scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    return scene


def passes(view_layer, on):
    view_layer.use_pass_diffuse_color = view_layer.use_pass_glossy_color = view_layer.use_pass_emit = on
    view_layer.use_pass_transmission_color = on


def main():
    H.enable_addon()
    scene = stage()
    view_layer = scene.view_layers[0]
    passes(view_layer, True)
    out = S.render_runs(scene, RUNS, SAMPLES)
    passes(view_layer, False)
    out["plain"] = S.write_multilayer(scene, os.path.join(os.getcwd(), "plain.exr"))
    return out
'''


renders = blender_fixture(BODY, "light_passes", timeout=3600, read=read_runs)


def stack(renders, name: str) -> np.ndarray:
    return np.stack([r[name] for r in renders])


@pytest.mark.parametrize("name", NAMES)
def test_light_passes_exact_where_deterministic(renders, name):
    haze, cycles = stack(renders["haze"], name), stack(renders["cycles"], name)
    assert haze.shape == cycles.shape == (RUNS, SIZE[1], SIZE[0], 3)
    fixed = (np.ptp(cycles, axis=0).max(axis=-1) < 1e-6) & (np.ptp(haze, axis=0).max(axis=-1) < 1e-6)
    assert fixed.mean() > 0.4, "too few deterministic pixels: the scene is broken"
    scale = np.maximum(np.abs(cycles[0]), 1.0)[fixed]
    worst_difference = (np.abs(haze[0] - cycles[0])[fixed] / scale).max()
    assert worst_difference < PRECISION, f"{name}: deterministic pixels differ by {worst_difference:.3g}"


def assert_within_noise(renders, name: str, mask: np.ndarray) -> None:
    haze, cycles = stack(renders["haze"], name), stack(renders["cycles"], name)
    tests = block_tests(haze, cycles, mask)
    test, ratio = worst(tests)
    assert ratio <= 1.0, (f"{name}: block {test.block} channel {test.channel} differs by "
                          f"{test.difference:.4f}, t {test.t:.1f} (dof {test.dof:.0f}) of {len(tests)}")


@pytest.mark.parametrize("name", NAMES)
def test_light_passes_agree_with_cycles_within_noise(renders, name):
    """Everywhere but the Principled ball (below), and for Glossy Color the glass ball."""
    mask = ~plastic_region()
    if name == "Glossy Color":
        mask &= ~glass_region()
    assert_within_noise(renders, name, mask)


PRINCIPLED_LAYER_DIFFERS = pytest.mark.xfail(strict=True, reason=(
    "the Principled BSDF's specular layer albedo E: Haze's Glossy Color there is 0.041 where "
    "Cycles' is 0.039 at normal incidence (roughness 0.4, IOR 1.5; t 8 over a block) and up to "
    "0.015 higher towards the rim, and Haze's Diffuse Color 0.767 against 0.768 (t 13). "
    "Cycles' Diffuse Color there is base x (1 - 0.040) while its Glossy Color is 0.039: its "
    "layering weight and its glossy albedo are not one E; Haze uses its tabulated estimate "
    "(renderer.bsdfs.spec_albedo) for both. Not resolved yet"))


@pytest.mark.parametrize("name", [pytest.param(n, marks=PRINCIPLED_LAYER_DIFFERS) for n in NAMES[:2]])
def test_light_passes_of_the_principled_ball(renders, name):
    assert_within_noise(renders, name, plastic_region())


def test_light_passes_are_seen(renders):
    """The scene exercises every pass: the lamp in Emission, the balls in Glossy Color."""
    haze = renders["haze"][0]
    assert (haze["Emission"].max(axis=-1) > 1.0).sum() >= 20
    assert (haze["Glossy Color"].max(axis=-1) > 0.3).sum() >= 50
    transmission = haze["Transmission Color"].max(axis=-1)
    assert (transmission > 0.5).sum() >= 20 and (transmission[~glass_region()] == 0.0).all()
    assert (haze["Diffuse Color"].max(axis=-1) > 0.3).mean() > 0.5


def test_unrequested_light_passes_are_absent(renders):
    assert set(renders["plain"]) == {"Combined"}
    assert set(NAMES) <= set(renders["haze"][0])
