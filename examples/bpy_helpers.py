"""Blender-side helpers for the tests' and benchmarks' Blender scripts (the bpy module).

The scripts run_blender (bench/blender.py) writes import this file (`import bpy_helpers`)
with tests/ and examples/ on sys.path but not the repository root, so that Haze, and with it `renderer`,
comes from the installed extension: nothing here imports the repository's packages, and bpy
is imported inside the functions, so pytest can import this file without Blender. Scene
builders and render helpers: enable_addon, addon_module, configure_cycles, render_exr, ...

The host side (run_blender, shared_numba_cache, isolated_site, ...) is bench/blender.py and
the statistical comparison of two renderers (compare_images, assert_agree) is
bench/comparison.py; tests import them from there.
"""

from __future__ import annotations

import importlib
import math
import os
from pathlib import Path

ADDON_MODE_ENV = "HAZE_TEST_ADDON"  # bench.blender.ADDON_MODE_ENV (not imported: Blender side)
EXTENSION_PACKAGE = "bl_ext.user_default.haze"  # bench.installed.PACKAGE (not imported: Blender side)

# ------------------------------------------------------------------------------ Blender side


def addon_package():
    """Haze's package in this Blender run (see bench.blender.addon_mode), imported but not registered:
    `bl_ext.user_default.haze` of the installed extension, or the clone's `addon`."""
    mode = os.environ.get(ADDON_MODE_ENV)
    if mode not in ("installed", "clone"):
        raise RuntimeError("this Blender run was not started with Haze (run_blender(dev_paths=False))")
    return importlib.import_module(EXTENSION_PACKAGE if mode == "installed" else "addon")


def addon_module(name: str):
    """A module of Haze's package by its name inside the package, e.g. "export.scene"."""
    return importlib.import_module(f"{addon_package().__name__}.{name}")


def addon_names(module: str, *names: str) -> tuple:
    """Attributes of one of Haze's modules, as `from <package>.<module> import names` would."""
    found = addon_module(module)
    return tuple(getattr(found, name) for name in names)


def enable_addon():
    """Enable Haze as a user does (the clone's add-on is registered directly); returns its package."""
    import bpy

    package = addon_package()
    if hasattr(bpy.types.Scene, "haze"):
        return package
    if package.__name__ == "addon":
        package.register()
        return package
    import addon_utils

    def fail(error):
        raise error

    addon_utils.enable(package.__name__, default_set=True, handle_error=fail)
    _require_bundled_renderer()
    return package


def _require_bundled_renderer() -> None:
    """The installed mode's promise: `renderer` is the zip's wheel, never the checkout's (an
    example that put the repository first on sys.path would break it silently)."""
    import importlib.util

    origin = Path(importlib.util.find_spec("renderer").origin).resolve()
    bundled = Path(os.environ["BLENDER_USER_RESOURCES"]).resolve() / "extensions"
    if not origin.is_relative_to(bundled):
        raise RuntimeError(f"the renderer would be imported from {origin}, not from the installed extension")


def configure_cycles(scene, samples: int, max_bounces: int, seed: int, threads: int = 2) -> None:
    """Cycles set up as an unbiased reference with Haze's conventions.

    Same bounce limit for every kind of bounce (volume_bounces too: its default 0 would
    drop multiple scattering), box pixel filter of width 1, no denoising, no clamping, no
    glossy blur, no light threshold, no adaptive sampling.
    """
    scene.render.engine = "CYCLES"
    cycles = scene.cycles
    cycles.device = "CPU"
    cycles.samples = samples
    cycles.seed = seed
    cycles.use_animated_seed = False
    cycles.use_adaptive_sampling = False
    cycles.use_denoising = False
    cycles.max_bounces = max_bounces
    for name in ("diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces"):
        setattr(cycles, name, max_bounces)
    cycles.transparent_max_bounces = 64
    cycles.sample_clamp_direct = 0.0
    cycles.sample_clamp_indirect = 0.0
    cycles.blur_glossy = 0.0
    cycles.caustics_reflective = True
    cycles.caustics_refractive = True
    cycles.light_sampling_threshold = 0.0
    cycles.pixel_filter_type = "BOX"
    cycles.filter_width = 1.0
    scene.render.film_transparent = False
    scene.render.threads_mode = "FIXED"
    scene.render.threads = threads


def configure_haze(scene, samples: int, max_bounces: int, seed: int, workers: int = 1) -> None:
    scene.render.engine = "HAZE"
    scene.haze.samples = samples
    scene.haze.max_bounces = max_bounces
    scene.haze.seed = seed
    scene.haze.workers = workers
    scene.haze.time_limit = 0.0
    scene.haze.target_error = 0.0


def render_exr(scene, path: str) -> str:
    """Render the scene with its current engine into a 32-bit float EXR (linear, lossless)."""
    import bpy

    settings = scene.render.image_settings
    settings.file_format = "OPEN_EXR"
    settings.color_depth = "32"
    settings.exr_codec = "ZIP"
    settings.color_mode = "RGBA"
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)
    return path


def render_both(scene, out_dir: str, runs: int, cycles_samples: int, haze_samples: int,
                max_bounces: int) -> dict:
    """K independent renders (seeds 1..K) with Cycles and with Haze: their EXR paths."""
    paths: dict[str, list[str]] = {"cycles": [], "haze": []}
    for run in range(runs):
        configure_cycles(scene, cycles_samples, max_bounces, seed=run + 1)
        paths["cycles"].append(render_exr(scene, f"{out_dir}/cycles_{run}.exr"))
    for run in range(runs):
        configure_haze(scene, haze_samples, max_bounces, seed=run + 1)
        paths["haze"].append(render_exr(scene, f"{out_dir}/haze_{run}.exr"))
    return paths


def new_object(name: str, vertices, faces, material=None):
    """A mesh object from vertex and face lists, linked to the scene."""
    import bpy

    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(v) for v in vertices], [], [tuple(f) for f in faces])
    if material is not None:
        mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def uv_quad(name: str, vertices, material, scale: float = 1.0):
    """A quad (vertices in order around it) with a UV map "UVMap" from (0, 0) at the first
    vertex to (scale, scale) at the third."""
    obj = new_object(name, vertices, [(0, 1, 2, 3)], material)
    uv = obj.data.uv_layers.new(name="UVMap")
    for loop, (u, v) in zip(obj.data.loops, [(0, 0), (1, 0), (1, 1), (0, 1)], strict=True):
        uv.data[loop.index].uv = (u * scale, v * scale)
    return obj


def uv_sphere(name: str, center, radius: float, material, rings: int = 24, segments: int = 48):
    """A closed, smooth-shaded UV sphere with outward normals."""
    vertices = [(center[0], center[1], center[2] + radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2.0 * math.pi * j / segments
            vertices.append((center[0] + radius * math.sin(theta) * math.cos(phi),
                             center[1] + radius * math.sin(theta) * math.sin(phi),
                             center[2] + radius * math.cos(theta)))
    vertices.append((center[0], center[1], center[2] - radius))
    bottom = len(vertices) - 1
    faces = [(0, 1 + j, 1 + (j + 1) % segments) for j in range(segments)]
    for i in range(rings - 2):
        a, b = 1 + i * segments, 1 + (i + 1) * segments
        faces += [(a + j, b + j, b + (j + 1) % segments, a + (j + 1) % segments) for j in range(segments)]
    last = 1 + (rings - 2) * segments
    faces += [(last + (j + 1) % segments, last + j, bottom) for j in range(segments)]
    obj = new_object(name, vertices, faces, material)
    obj.data.shade_smooth()
    return obj


def floor_plane(name: str, half: float, material, z: float = 0.0):
    return new_object(name, [(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)],
                      [(0, 1, 2, 3)], material)


def gas_domain(scene, scale, cache_directory: str, resolution: int, location=(0.0, 0.0, 0.0)):
    """A fluid domain "Domain" linked to `scene`: the box from (-1, -1, 0) to (1, 1, 2) in
    object space, scaled and placed, whose Fluid modifier reads a modular cache in
    `cache_directory` that the test writes (nothing is simulated; the viewport depsgraph
    never runs the modifier). Returns (object, mesh, domain settings)."""
    import bpy

    mesh = bpy.data.meshes.new("Domain")
    corners = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (0, 2)]
    mesh.from_pydata(corners, [], [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
                                   (1, 5, 7, 3)])
    domain = bpy.data.objects.new("Domain", mesh)
    scene.collection.objects.link(domain)
    domain.scale = scale
    domain.location = location
    modifier = domain.modifiers.new("Fluid", "FLUID")
    modifier.show_viewport = False
    modifier.fluid_type = "DOMAIN"
    settings = modifier.domain_settings
    settings.cache_directory = cache_directory
    settings.cache_type = "MODULAR"
    settings.resolution_max = resolution
    return domain, mesh, settings


def fire_grids():
    """The density and flame, (nz, ny, nx) = (16, 11, 11), of a fire in a 2 x 2 x 3 gas domain
    at resolution 16 (gas_domain scaled (1, 1, 1.5)), that the tests write as its cache
    frame: random lumps (seed 5), flame inside the density."""
    import numpy as np

    rng = np.random.default_rng(5)
    shape = (16, 11, 11)
    density = np.zeros(shape, np.float32)
    density[3:12, 2:9, 3:8] = rng.random((9, 7, 5)).astype(np.float32) + 0.05
    flame = np.zeros(shape, np.float32)
    flame[4:8, 3:7, 4:7] = rng.random((4, 4, 3)).astype(np.float32)
    return density, flame


def ensure_nodes(datablock) -> None:
    """Turn on node shading; Blender 5.0 always uses nodes and deprecates the switch."""
    import bpy

    if bpy.app.version < (5, 0, 0):
        datablock.use_nodes = True


def principled_material(name: str, **inputs):
    """A Principled BSDF material; keyword names are input names with spaces as underscores."""
    import bpy

    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    bsdf = material.node_tree.nodes["Principled BSDF"]
    for key, value in inputs.items():
        if key == "distribution":
            bsdf.distribution = value
            continue
        socket = bsdf.inputs[key.replace("_", " ")]
        socket.default_value = (*value, 1.0) if isinstance(value, tuple) and len(value) == 3 else value
    return material


def add_light(kind: str, name: str, location, rotation_deg=(0.0, 0.0, 0.0), **settings):
    import bpy

    data = bpy.data.lights.new(name, kind)
    for key, value in settings.items():
        setattr(data, key, value)
    obj = bpy.data.objects.new(name, data)
    obj.location = location
    obj.rotation_euler = tuple(math.radians(a) for a in rotation_deg)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def world_color(scene, color, strength: float = 1.0) -> None:
    import bpy

    world = bpy.data.worlds.new("World")
    ensure_nodes(world)
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    scene.world = world
