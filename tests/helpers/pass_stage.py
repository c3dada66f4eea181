"""The stage of the pass tests (tests/test_addon_passes.py, test_addon_volume_passes.py,
test_addon_light_passes.py), in three parts:

* Blender side (imported by their Blender scripts; bpy is imported inside the functions, so
  pytest can import this module without Blender): `build_stage` (floor, wall, fog cube, sun,
  sky and camera, and the two balls), `write_multilayer`, `render_runs` (the renders by
  Cycles and by Haze the tests compare).
* Host side: `read_passes` of the multilayer EXRs they write, `read_runs` (a fixture's
  `read`: every EXR of a run's result).
* The stage's analytic geometry seen by its camera: which pixels see the fog cube's
  silhouette or the glass ball, and the exact mean transmittance through the fog cube of
  every pixel (numpy only, no renderer).

Camera: at (0, -4.5, 1.6), rotated 75 degrees about X, 35 mm lens on a 36 mm sensor fitted
horizontally, box pixel filter of width 1. Row 0 of every image is the top row.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

CAMERA = np.array([0.0, -4.5, 1.6])
TILT = math.radians(75.0)
LENS, SENSOR = 35.0, 36.0
FOG_LOW, FOG_HIGH = np.array([0.9, 0.7, 0.1]), np.array([1.9, 1.7, 1.1])  # C.box("Fog", ...)
FOG_SIGMA_T = 0.9  # Volume Scatter: colour 0.9 x density 1; no absorption
GLASS_CENTER, GLASS_RADIUS = np.array([0.3, -0.5, 0.45]), 0.45
WALL_Y, WALL_TOP = 2.0, 1.5


def build_stage(size: tuple[int, int], balls: bool = True):
    """Blender side: a cleared scene holding the stage (Combined composited off): a grey sky,
    a diffuse floor and wall, the cube of fog (optical depth 1 across, floating above the
    floor: a face coplanar with the floor would make the order of the two hits arbitrary),
    the sun and the camera; with `balls`, a diffuse ball and the clear glass ball too."""
    import blender_cornell as C
    import bpy_helpers as H

    scene = C.clear_scene()
    scene.render.use_compositing = False
    H.world_color(scene, (0.4, 0.45, 0.5), 1.0)
    H.floor_plane("Floor", 4.0, C.diffuse_material("Floor", (0.7, 0.7, 0.7)))
    H.new_object("Wall", [(-4, 2.0, 0), (4, 2.0, 0), (4, 2.0, 1.5), (-4, 2.0, 1.5)], [(0, 1, 2, 3)],
                 C.diffuse_material("Wall", (0.6, 0.5, 0.4)))  # WALL_Y, WALL_TOP
    if balls:
        H.uv_sphere("Ball", (-1.0, 0.0, 0.5), 0.5, C.diffuse_material("Ball", (0.2, 0.5, 0.8)))
        material, tree, output = C.node_material("Glass")
        node = tree.nodes.new("ShaderNodeBsdfGlass")
        node.inputs["Roughness"].default_value = 0.0
        tree.links.new(node.outputs["BSDF"], output.inputs["Surface"])
        H.uv_sphere("Glass", (0.3, -0.5, 0.45), 0.45, material)  # GLASS_CENTER, GLASS_RADIUS
    C.box("Fog", (1.4, 1.2, 0.6), 0.5, C.fog_material("Fog", 1.0, 0.0, 0.0))  # FOG_LOW .. FOG_HIGH
    H.add_light("SUN", "Sun", (0.0, 0.0, 5.0), (40.0, 0.0, 30.0), energy=2.0, angle=math.radians(5.0))
    C.add_camera(scene, (0.0, -4.5, 1.6), (75.0, 0.0, 0.0), lens=35.0)  # CAMERA, TILT, LENS
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    return scene


def write_multilayer(scene, path: str) -> str:
    """Blender side: render `scene` into a 32-bit multilayer EXR at `path`; returns the path."""
    import bpy

    settings = scene.render.image_settings
    settings.media_type = "MULTI_LAYER_IMAGE"
    settings.file_format = "OPEN_EXR_MULTILAYER"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    return path


def render_runs(scene, runs: int, samples: int, max_bounces: int = 3) -> dict[str, list[str]]:
    """Blender side: `runs` renders of `scene` by Cycles and as many by Haze (seeds 1 .. runs,
    `samples` each), multilayer EXRs in the working folder: {"cycles": paths, "haze": paths}."""
    import bpy_helpers as H

    out: dict[str, list[str]] = {"cycles": [], "haze": []}
    for run in range(runs):
        H.configure_cycles(scene, samples, max_bounces, seed=run + 1)
        out["cycles"].append(write_multilayer(scene, os.path.join(os.getcwd(), f"cycles_{run}.exr")))
        H.configure_haze(scene, samples, max_bounces, seed=run + 1)
        out["haze"].append(write_multilayer(scene, os.path.join(os.getcwd(), f"haze_{run}.exr")))
    return out


def read_runs(run, folder: Path) -> dict:
    """Host side (a blender_fixture's `read`): the run's result with each EXR path, alone or
    in a list, replaced by its passes (read_passes)."""
    return {key: [read_passes(p) for p in value] if isinstance(value, list) else read_passes(value)
            for key, value in run.result.items()}


def read_passes(path: str | Path) -> dict[str, np.ndarray]:
    """Pass name -> (H, W, C) float64 (row 0 at the top) of a multilayer EXR from Blender."""
    import OpenEXR

    channels: dict[str, dict[str, np.ndarray]] = {}
    for part in OpenEXR.File(str(path), separate_channels=True).parts:
        for name, channel in part.channels.items():
            _, pass_name, letter = name.split(".")
            channels.setdefault(pass_name, {})[letter] = channel.pixels
    out = {}
    for pass_name, letters in channels.items():
        order = [c for c in ("R", "G", "B", "A", "X", "Y", "Z") if c in letters]
        if set(letters) == {"X", "Y", "Z"}:
            order = ["X", "Y", "Z"]
        out[pass_name] = np.stack([letters[c] for c in order], axis=-1).astype(np.float64)
    return out


def pixel_rays(size: tuple[int, int], n: int, tilt: float = TILT) -> np.ndarray:
    """(H, W, n*n, 3) world directions of an n x n grid of points in every pixel, for the
    camera turned `tilt` radians about X."""
    width, height = size
    u = (np.arange(n) + 0.5) / n
    py, px, vy, vx = np.meshgrid(np.arange(height), np.arange(width), u, u, indexing="ij")
    x = (px + vx) / width - 0.5
    y = 0.5 - (py + vy) / height
    local = np.stack([x * SENSOR / LENS, y * SENSOR * height / width / LENS, -np.ones_like(x)], -1)
    c, s = math.cos(tilt), math.sin(tilt)
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    directions = local @ rotation.T
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    return directions.reshape(height, width, n * n, 3)


def fog_length(directions: np.ndarray) -> np.ndarray:
    """Length of each ray's path through the fog cube (slab method), 0 if it misses."""
    with np.errstate(divide="ignore", invalid="ignore"):
        t1, t2 = (FOG_LOW - CAMERA) / directions, (FOG_HIGH - CAMERA) / directions
    enter = np.nanmax(np.minimum(t1, t2), axis=-1)
    leave = np.nanmin(np.maximum(t1, t2), axis=-1)
    return np.clip(leave - np.maximum(enter, 0.0), 0.0, None)


def hits_sphere(directions: np.ndarray, center: np.ndarray, radius: float,
                camera: np.ndarray = CAMERA) -> np.ndarray:
    oc = camera - center
    b = directions @ oc
    return b * b - (oc @ oc - radius**2) > 0.0


def hits_glass(directions: np.ndarray) -> np.ndarray:
    return hits_sphere(directions, GLASS_CENTER, GLASS_RADIUS)


def dilate(mask: np.ndarray) -> np.ndarray:
    """A pixel and its 8 neighbours."""
    padded = np.pad(mask, 1)
    h, w = mask.shape
    return np.any([padded[y:y + h, x:x + w] for y in range(3) for x in range(3)], axis=0)


def fog_silhouette(size: tuple[int, int]) -> np.ndarray:
    """(H, W) pixels that see the fog cube but where some rays cross less than optical depth
    0.5 of it (its outline), with their neighbours."""
    depth = fog_length(pixel_rays(size, 16)) * FOG_SIGMA_T
    return dilate((depth.max(axis=-1) > 0.0) & (depth.min(axis=-1) < 0.5))


def glass_region(size: tuple[int, int]) -> np.ndarray:
    """(H, W) pixels that see any of the glass ball, with their neighbours."""
    return dilate(hits_glass(pixel_rays(size, 16)).any(axis=-1))


def wall_behind_fog(size: tuple[int, int], n: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """Pixels whose rays all reach the wall (through the fog cube or beside it) and no glass,
    and their mean transmittance through the fog: ((H, W) bool, (H, W) float)."""
    directions = pixel_rays(size, n)
    t_wall = (WALL_Y - CAMERA[1]) / directions[..., 1]
    z_wall = CAMERA[2] + t_wall * directions[..., 2]
    on_wall = ((t_wall > 0) & (z_wall > 0.0) & (z_wall < WALL_TOP)).all(axis=-1)
    clear = ~dilate(hits_glass(directions).any(axis=-1))
    transmittance = np.exp(-FOG_SIGMA_T * fog_length(directions)).mean(axis=-1)
    return on_wall & clear, transmittance
