"""The paper's gallery as Blender scenes, rendered headless with Haze.

Run with the project's Python (bpy installed as a module):

    .venv/bin/python examples/blender_gallery.py [--size 128] [--samples N] [--only NAME ...] [--out DIR]

Each scene is built with Blender data (objects, materials, volumes, world) the way a user
would build it, then rendered through the Haze add-on into DIR/<name>.exr and .png (default
out/blender_gallery), with its time printed. Volumes are Volume objects loading OpenVDB
files written into DIR/volumes by the add-on's own helpers (the Add > Volume operators use
the same ones). Scenes (figures of seed/volumetric-path-tracing.txt):

  fog_isotropic, fog_backward, fog_forward  Fig. 1: the Cornell box filled with fog (a world
                                            volume) of g = 0, -0.9, 0.9
  smoke_ball                                Fig. 5: the Fig. 3 smoke ball
  yellow_smoke                              Fig. 6: gaussian-random yellow smoke, g = -0.7
  fire_ball                                 Fig. 7: a metal bust in a ball of fire (blackbody)
  underwater                                Fig. 8: a glass sphere full of water
  cloud                                     Fig. 2's idea: a cloud imported from a pbrt-v3
                                            'heterogeneous' medium file, under sun and sky
  procedural_cloud                          a cube whose Principled Volume Density is Noise
                                            through Map Range (a procedural medium), sun and sky

and two scenes whose look comes from shader nodes (examples/blender_materials.py):

  textured_box                              the Cornell box with a checker/noise Principled
                                            floor, an image on the back wall, a marbled cube
  hdri                                      two balls on a floor under an HDRI with a small sun

Coordinates: Blender's z is up; the Cornell box of examples/blender_cornell.py spans x, y in
[-1, 1] and z in [0, 2], seen from -y. Positions from examples/media_scenes.py (y up, box
[-1, 1]^3, camera on +z) map by (x, y, z) -> (x, -z, y + 1).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import bpy
import numpy as np
from mathutils import Matrix

REPO = Path(__file__).resolve().parents[1]
for _path in (REPO, REPO / "examples"):
    if str(_path) not in sys.path:  # appended: an installed Haze's renderer comes first
        sys.path.append(str(_path))

import blender_cornell as C  # noqa: E402
import blender_materials as M  # noqa: E402

from examples.scenes import FIG1_SIGMA_A, FIG1_SIGMA_S, icosphere  # noqa: E402

# examples.media_scenes (Fig. 6 to 8 constants) is imported by the builders that need it: it
# imports numba and the renderer's kernels, which the other scenes must not load before their
# render (python -m bench first_image times F12 as a user gets it, renderer not yet imported).

OUT = REPO / "out" / "blender_gallery"
PREVIEW_SAMPLES = {  # samples per pixel at the preview size: each scene well under 2 minutes
    "fog_isotropic": 512, "fog_backward": 512, "fog_forward": 512, "smoke_ball": 256, "yellow_smoke": 256,
    "fire_ball": 256, "underwater": 512, "cloud": 128, "procedural_cloud": 128, "textured_box": 256,
    "hdri": 256,
}
MAX_BOUNCES = {"fog_isotropic": 4, "fog_backward": 4, "fog_forward": 4}  # Fig. 1's depth; others 16
MEDIA_BOUNCES = 16


def paper_to_blender(points) -> np.ndarray:
    """media_scenes coordinates (y up, Cornell box [-1, 1]^3) to Blender's (z up, floor at 0)."""
    p = np.asarray(points, np.float64)
    return np.stack([p[..., 0], -p[..., 2], p[..., 1] + 1.0], axis=-1)


def mesh_object(name: str, vertices, triangles, material) -> bpy.types.Object:
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata([tuple(map(float, v)) for v in vertices], [], [tuple(map(int, t)) for t in triangles])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def cornell(size: int, bounces: int, light_radiance: float = C.LIGHT_RADIANCE, light_color=(1.0, 1.0, 1.0),
            light_scale: float = 1.0) -> bpy.types.Scene:
    """blender_cornell's box, camera and black world; the lamp optionally wider and tinted."""
    scene = C.clear_scene()
    C.build_cornell_walls(scene)
    lamp = bpy.data.objects["Light"]
    if light_scale != 1.0:  # the lamp's quad is centred on the z axis: widen it in x and y
        lamp.data.transform(Matrix.Diagonal((light_scale, light_scale, 1.0, 1.0)))
    emission = lamp.data.materials[0].node_tree.nodes["Emission"]
    emission.inputs["Strength"].default_value = light_radiance / light_scale**2
    emission.inputs["Color"].default_value = (*light_color, 1.0)
    C.add_camera(scene, (0.0, -3.4, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    C.black_world(scene)
    return use_haze(scene, size, bounces)


def use_haze(scene: bpy.types.Scene, size: int, bounces: int) -> bpy.types.Scene:
    """Render `scene` with Haze at size x size pixels and `bounces` bounces."""
    render = scene.render
    render.resolution_x = render.resolution_y = size
    render.resolution_percentage = 100
    render.engine = "HAZE"
    scene.haze.max_bounces = bounces
    return scene


def volume_scatter_absorb(material_name: str, sigma_a, sigma_s, g: float,
                          world: bpy.types.World | None = None):
    """Volume Scatter + Volume Absorption giving exactly sigma_s and sigma_a (constants)."""
    if world is not None:
        tree = world.node_tree
        output = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputWorld")
        target = world
    else:
        target, tree, output = C.node_material(material_name)
    scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    s_peak, a_peak = max(sigma_s), max(sigma_a)
    scatter.inputs["Color"].default_value = (*(v / s_peak for v in sigma_s), 1.0)
    scatter.inputs["Density"].default_value = s_peak
    scatter.inputs["Anisotropy"].default_value = g
    absorb = tree.nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (*(1.0 - v / a_peak for v in sigma_a), 1.0)
    absorb.inputs["Density"].default_value = a_peak
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(scatter.outputs[0], add.inputs[0])
    tree.links.new(absorb.outputs[0], add.inputs[1])
    tree.links.new(add.outputs[0], output.inputs["Volume"])
    return target


def _volumes():
    """The enabled add-on's Add > Volume helpers (its operators_volume module)."""
    return C.haze_module("operators_volume")


def _grids():
    """The enabled add-on's grid file helpers (its volume_grids module)."""
    return C.haze_module("volume_grids")


def grid_volume(name: str, grids, center, size: float, material, folder: Path) -> bpy.types.Object:
    """A Volume object whose grid(s) fill a cube of edge `size` centred at `center` (Blender)."""
    add_volume_object = _volumes().add_volume_object

    half = size / 2.0
    obj = add_volume_object(bpy.context, name, grids, (-half,) * 3, (half,) * 3, material, folder)
    obj.location = tuple(float(c) for c in center)
    return obj


# ------------------------------------------------------------------------------ scenes


def fog(size: int, g: float) -> bpy.types.Scene:
    """Fig. 1: the box filled with the fog (world volume: the camera is inside it too)."""
    scene = cornell(size, MAX_BOUNCES["fog_isotropic"])
    volume_scatter_absorb("Fog", FIG1_SIGMA_A, FIG1_SIGMA_S, g, world=scene.world)
    for name, center, half, angle in (("Short Block", (0.35, -0.35, 0.3), (0.3, 0.3, 0.3), -17.0),
                                      ("Tall Block", (-0.35, 0.3, 0.6), (0.3, 0.3, 0.6), 17.0)):
        block = C.box(name, (0.0, 0.0, 0.0), 1.0, C.diffuse_material(name, (0.73, 0.73, 0.73)))
        block.location, block.scale = center, half
        block.rotation_euler = (0.0, 0.0, math.radians(angle))
    return scene


def smoke_ball(size: int, folder: Path, bounces: int = MEDIA_BOUNCES) -> bpy.types.Scene:
    """Fig. 5: the Fig. 3 ball (11^3 voxels) as a Volume object, Principled Volume reading its
    density: Color 0.1 and Density 100 give sigma_s 10 and sigma_a 90 per unit density."""
    principled_volume_material = _volumes().principled_volume_material

    scene = cornell(size, bounces)
    material = principled_volume_material("Smoke", (0.1, 0.1, 0.1), 100.0)
    center = paper_to_blender((0.0, -0.25, 0.0))
    grid_volume("Smoke Ball", _grids().smoke_ball_density(11), center, 1.2, material, folder)
    return scene


def yellow_smoke(size: int, folder: Path) -> bpy.types.Scene:
    """Fig. 6: Color (0.7, 0.4375, 0.1) and Density 8 give sigma_s (5.6, 3.5, 0.8) and sigma_a
    (2.4, 4.5, 7.2); times the gallery's peak density 0.6."""
    principled_volume_material = _volumes().principled_volume_material
    from examples.media_scenes import FIG6_G

    scene = cornell(size, MEDIA_BOUNCES)
    material = principled_volume_material("Yellow Smoke", (0.7, 0.4375, 0.1), 8.0 * 0.6, FIG6_G)
    grid_volume("Yellow Smoke", _grids().gaussian_smoke_density(), paper_to_blender((0.0, -0.35, 0.0)), 1.3,
                material, folder)
    return scene


def fire_ball(size: int, folder: Path) -> bpy.types.Scene:
    """Fig. 7: a rough metal bust inside fire: a temperature grid (kelvin) with blackbody
    emission and a thin smoke (Color 2/3, Density 0.9: sigma_s 0.6, sigma_a 0.3) under a
    dimmed orange lamp."""
    principled_volume_material = _volumes().principled_volume_material
    from examples.media_scenes import fire_temperature

    scene = cornell(size, MEDIA_BOUNCES, light_radiance=1.7, light_color=(1.0, 0.7, 0.24))
    temperature = fire_temperature()
    smoke = (np.clip(temperature / temperature.max(), 0.0, 1.0) ** 2).astype(np.float32)
    material = principled_volume_material("Fire", (2.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0), 0.9, 0.3)
    principled = material.node_tree.nodes["Principled Volume"]
    principled.inputs["Blackbody Intensity"].default_value = 1.0
    principled.inputs["Temperature"].default_value = 1.0  # times the grid: kelvin
    grid_volume("Fire", {"density": smoke, "temperature": temperature}, paper_to_blender((0.0, -0.35, 0.0)),
                1.3, material, folder)
    metal = C.node_material("Bronze")
    bsdf = metal[1].nodes.new("ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.95, 0.64, 0.54, 1.0)
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.35
    metal[1].links.new(bsdf.outputs[0], metal[2].inputs["Surface"])
    vertices, triangles = icosphere(3, 0.28)
    mesh_object("Bust Head", paper_to_blender(vertices + np.float32([0.0, -0.45, 0.0])), triangles, metal[0])
    plinth = C.box("Bust Plinth", (0.0, 0.0, 0.0), 1.0, metal[0])
    plinth.location, plinth.scale = tuple(paper_to_blender((0.0, -0.85, 0.0))), (0.22, 0.22, 0.15)
    return scene


def underwater(size: int) -> bpy.types.Scene:
    """Fig. 8: a sphere of water (Glass BSDF, IOR 1.33, around the Fig. 8 medium scaled by 4:
    the paper's bust is tens of units tall); the lamp 2.5 times wider at the same power."""
    from examples.media_scenes import FIG8_G, FIG8_SIGMA_A, FIG8_SIGMA_S

    scene = cornell(size, MEDIA_BOUNCES, light_scale=2.5)
    material = volume_scatter_absorb("Water", tuple(4.0 * v for v in FIG8_SIGMA_A),
                                     tuple(4.0 * v for v in FIG8_SIGMA_S), FIG8_G)
    tree = material.node_tree
    glass = tree.nodes.new("ShaderNodeBsdfGlass")
    glass.inputs["IOR"].default_value = 1.33
    glass.inputs["Roughness"].default_value = 0.0
    glass.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    output = next(n for n in tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    tree.links.new(glass.outputs[0], output.inputs["Surface"])
    vertices, triangles = icosphere(4, 0.55)
    center = np.float32([0.0, -0.42, 0.0])
    water = mesh_object("Water", paper_to_blender(vertices + center), triangles, material)
    water.data.shade_smooth()
    return scene


def cloud_density(nx: int = 64, ny: int = 48, nz: int = 28, seed: int = 11) -> np.ndarray:
    """A cumulus-like cloud: seeded gaussian puffs, larger and denser at the bottom middle, in a
    flat box; (nz, ny, nx), faded to 0 at the box's faces."""
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*((np.arange(n) + 0.5) / n for n in (nz, ny, nx)), indexing="ij")
    density = np.zeros((nz, ny, nx))
    for _ in range(80):
        cx, cy = rng.normal(0.5, 0.17, 2)
        cz = abs(rng.normal(0.0, 0.2)) + 0.3
        r = rng.uniform(0.08, 0.18) * (1.3 - 0.6 * cz)
        distance2 = (x - cx) ** 2 + ((y - cy) * 1.3) ** 2 + ((z - cz) * 0.9) ** 2
        density += np.exp(-distance2 / (2 * r * r))
    fade = np.minimum.reduce([x, 1 - x, y, 1 - y, z, 1 - z])
    density *= np.clip(fade / 0.12, 0.0, 1.0)
    return (np.clip(density / np.percentile(density, 99.5), 0.0, 1.0)).astype(np.float32)


def cloud(size: int, folder: Path) -> bpy.types.Scene:
    """A cloud written as a pbrt-v3 'heterogeneous' medium and imported like Add > Volume >
    Density Grid does (Volume Scatter + Absorption reading its density), under a sun and a
    blue sky, over a grey ground."""
    volumes = _volumes()
    add_volume_object, coefficient_material = volumes.add_volume_object, volumes.coefficient_material

    scene = C.clear_scene()
    pbrt = folder / "cloud.pbrt"
    _grids().write_pbrt(pbrt, cloud_density(), (-2.5, -1.9, 0.0), (2.5, 1.9, 2.2), sigma_a=(0.05, 0.05, 0.05),
               sigma_s=(6.0, 6.0, 6.0))
    values, p0, p1 = _grids().read_pbrt(pbrt)
    material = coefficient_material("Cloud", (0.05, 0.05, 0.05), (6.0, 6.0, 6.0), 0.6)
    cloud_object = add_volume_object(bpy.context, "Cloud", values, p0, p1, material, folder)
    cloud_object.location = (0.0, 1.0, 0.9)
    ground = C.quad("Ground", [(-30, -30, 0), (30, -30, 0), (30, 30, 0), (-30, 30, 0)],
                    C.diffuse_material("Ground", (0.35, 0.35, 0.33)))
    ground.name = "Ground"
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = math.radians(1.0)
    sun_object = bpy.data.objects.new("Sun", sun)
    sun_object.rotation_euler = (math.radians(40.0), 0.0, math.radians(30.0))
    scene.collection.objects.link(sun_object)
    world = bpy.data.worlds.new("Sky")
    C.ensure_nodes(world)
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.35, 0.55, 0.9, 1.0)
    background.inputs["Strength"].default_value = 0.6
    scene.world = world
    C.add_camera(scene, (0.0, -4.2, 0.9), (92.0, 0.0, 0.0), lens=22.0)
    return use_haze(scene, size, MEDIA_BOUNCES)


def procedural_cloud(size: int) -> bpy.types.Scene:
    """The usual procedural cloud (issue 18 item 4): a cube whose material's Principled
    Volume Density is Noise (Object coordinates) through Map Range, under a sun and a blue
    sky, over a grey ground. Haze renders it as a procedural medium (renderer.media.procedural)."""
    scene = C.clear_scene()
    material, tree, output = C.node_material("Procedural Cloud")
    n, link = tree.nodes.new, tree.links.new
    coordinates = n("ShaderNodeTexCoord")
    noise = n("ShaderNodeTexNoise")
    for socket, value in (("Scale", 1.5), ("Detail", 3.0), ("Roughness", 0.55)):
        noise.inputs[socket].default_value = value
    ranged = n("ShaderNodeMapRange")
    for socket, value in (("From Min", 0.45), ("From Max", 0.75), ("To Min", 0.0), ("To Max", 8.0)):
        ranged.inputs[socket].default_value = value
    volume = n("ShaderNodeVolumePrincipled")
    volume.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
    link(coordinates.outputs["Object"], noise.inputs["Vector"])
    link(noise.outputs["Fac"], ranged.inputs["Value"])
    link(ranged.outputs["Result"], volume.inputs["Density"])
    link(volume.outputs["Volume"], output.inputs["Volume"])
    cube = C.box("Cloud", (0.0, 0.0, 0.0), 1.0, material)
    cube.location, cube.scale = (0.0, 1.0, 1.0), (1.6, 1.0, 0.7)
    cube.rotation_euler = (0.0, 0.0, math.radians(20.0))
    C.quad("Ground", [(-30, -30, 0), (30, -30, 0), (30, 30, 0), (-30, 30, 0)],
           C.diffuse_material("Ground", (0.35, 0.35, 0.33)))
    sun = bpy.data.lights.new("Sun", "SUN")
    sun.energy = 3.0
    sun.angle = math.radians(2.0)
    sun_object = bpy.data.objects.new("Sun", sun)
    sun_object.rotation_euler = (math.radians(40.0), 0.0, math.radians(30.0))
    scene.collection.objects.link(sun_object)
    world = bpy.data.worlds.new("Sky")
    C.ensure_nodes(world)
    background = world.node_tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.35, 0.55, 0.9, 1.0)
    background.inputs["Strength"].default_value = 0.6
    scene.world = world
    C.add_camera(scene, (0.0, -4.2, 1.0), (90.0, 0.0, 0.0), lens=26.0)
    return use_haze(scene, size, MEDIA_BOUNCES)


def build(name: str, size: int, folder: Path) -> bpy.types.Scene:
    builders = {
        "fog_isotropic": lambda: fog(size, 0.0),
        "fog_backward": lambda: fog(size, -0.9),
        "fog_forward": lambda: fog(size, 0.9),
        "smoke_ball": lambda: smoke_ball(size, folder),
        "yellow_smoke": lambda: yellow_smoke(size, folder),
        "fire_ball": lambda: fire_ball(size, folder),
        "underwater": lambda: underwater(size),
        "cloud": lambda: cloud(size, folder),
        "procedural_cloud": lambda: procedural_cloud(size),
        "textured_box": lambda: use_haze(M.textured_cornell(size), size, 3),
        "hdri": lambda: use_haze(M.hdri_scene(size, folder), size, 3),
    }
    return builders[name]()


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128, help="image width and height in pixels")
    parser.add_argument("--samples", type=int, default=0, help="samples per pixel (default: per scene)")
    parser.add_argument("--only", nargs="+", choices=sorted(PREVIEW_SAMPLES), help="render only these scenes")
    parser.add_argument("--workers", type=int, default=0, help="render processes (0 = all cores)")
    parser.add_argument("--out", type=Path, default=OUT, help="output folder")
    arguments = parser.parse_args(argv)
    if arguments.size < 1 or arguments.samples < 0 or arguments.workers < 0:
        parser.error("--size must be >= 1, --samples and --workers >= 0")
    return arguments


def main(argv: list[str]) -> int:
    arguments = parse_arguments(argv)
    C.enable_haze()
    folder = arguments.out / "volumes"
    folder.mkdir(parents=True, exist_ok=True)
    total = 0.0
    for name in arguments.only or list(PREVIEW_SAMPLES):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        C.enable_haze()
        scene = build(name, arguments.size, folder)
        scene.haze.samples = arguments.samples or PREVIEW_SAMPLES[name]
        scene.haze.workers = arguments.workers
        start = time.perf_counter()
        C.render_to(scene, arguments.out, name)
        seconds = time.perf_counter() - start
        total += seconds
        print(f"{name:14s} {arguments.size}x{arguments.size} {scene.haze.samples:4d} spp {seconds:7.1f} s",
              flush=True)
    print(f"{'total':14s} {total:7.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
