"""Build a foggy Cornell box in Blender and render it headless with Haze.

Run with the project's Python (bpy installed as a module):

    .venv/bin/python examples/blender_cornell.py [--samples N] [--size PIXELS] [--out DIR]

It writes out/blender_cornell.exr (linear) and out/blender_cornell.png (view transform
applied). The Haze add-on is taken from the installed extension if it is enabled, otherwise
from this checkout. The scene is built with bpy.data only (no operators), so the same
`build_fog_cornell` serves the tests, which compare it with Cycles.
"""

from __future__ import annotations

import argparse
import importlib
import math
import sys
from pathlib import Path

import bpy

REPO = Path(__file__).resolve().parents[1]

BOX_HALF = 1.0  # the box spans x, y in [-1, 1] and z in [0, 2] (metres)
LIGHT_HALF = 0.25
LIGHT_RADIANCE = 12.0  # W/(m^2 sr), white
WALL_COLORS = {
    "Floor": (0.73, 0.73, 0.73),
    "Ceiling": (0.73, 0.73, 0.73),
    "Back": (0.73, 0.73, 0.73),
    "Left": (0.63, 0.065, 0.05),
    "Right": (0.14, 0.45, 0.091),
}


def quad(name: str, corners: list[tuple[float, float, float]], material) -> bpy.types.Object:
    """A one-quad mesh object; corners counter-clockwise seen from its front."""
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(corners, [], [(0, 1, 2, 3)])
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def box(name: str, center: tuple[float, float, float], half: float, material) -> bpy.types.Object:
    """A closed cube with outward-facing normals."""
    cx, cy, cz = center
    vertices = [(cx + sx * half, cy + sy * half, cz + sz * half)
                for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(vertices, [], faces)
    mesh.materials.append(material)
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def ensure_nodes(datablock) -> None:
    """Turn on node shading; Blender 5.0 always uses nodes and deprecates the switch."""
    if bpy.app.version < (5, 0, 0):
        datablock.use_nodes = True


def node_material(name: str) -> tuple[bpy.types.Material, bpy.types.NodeTree, bpy.types.Node]:
    """A material with an empty node tree and its output node."""
    material = bpy.data.materials.new(name)
    ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.clear()
    output = tree.nodes.new("ShaderNodeOutputMaterial")
    return material, tree, output


def diffuse_material(name: str, color: tuple[float, float, float]) -> bpy.types.Material:
    material, tree, output = node_material(name)
    bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (*color, 1.0)
    tree.links.new(bsdf.outputs["BSDF"], output.inputs["Surface"])
    return material


def one_sided_emitter(name: str, radiance: float) -> bpy.types.Material:
    """Emission on front faces only: Mix Shader with factor Geometry > Backfacing (Cycles idiom)."""
    material, tree, output = node_material(name)
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    emission = tree.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = radiance
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
    tree.links.new(emission.outputs["Emission"], mix.inputs[1])  # second shader input left empty: black
    tree.links.new(mix.outputs["Shader"], output.inputs["Surface"])
    return material


def fog_material(name: str, scatter: float, absorb: float, anisotropy: float) -> bpy.types.Material:
    """Volume only (no surface): Volume Scatter + Volume Absorption through an Add Shader."""
    material, tree, output = node_material(name)
    scatter_node = tree.nodes.new("ShaderNodeVolumeScatter")
    scatter_node.inputs["Color"].default_value = (0.9, 0.9, 0.9, 1.0)
    scatter_node.inputs["Density"].default_value = scatter
    scatter_node.inputs["Anisotropy"].default_value = anisotropy
    absorb_node = tree.nodes.new("ShaderNodeVolumeAbsorption")
    absorb_node.inputs["Color"].default_value = (0.6, 0.7, 0.9, 1.0)
    absorb_node.inputs["Density"].default_value = absorb
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(scatter_node.outputs["Volume"], add.inputs[0])
    tree.links.new(absorb_node.outputs["Volume"], add.inputs[1])
    tree.links.new(add.outputs["Shader"], output.inputs["Volume"])
    return material


def add_camera(scene: bpy.types.Scene, location, rotation_deg, lens: float = 35.0) -> bpy.types.Object:
    data = bpy.data.cameras.new("Camera")
    data.lens = lens
    camera = bpy.data.objects.new("Camera", data)
    camera.location = location
    camera.rotation_euler = tuple(math.radians(a) for a in rotation_deg)
    scene.collection.objects.link(camera)
    scene.camera = camera
    return camera


def black_world(scene: bpy.types.Scene) -> None:
    world = bpy.data.worlds.new("Black")
    ensure_nodes(world)
    background = world.node_tree.nodes.get("Background")
    background.inputs["Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    background.inputs["Strength"].default_value = 0.0
    scene.world = world


def clear_scene() -> bpy.types.Scene:
    """Start from an empty scene (factory startup has a cube, light and camera)."""
    scene = bpy.context.scene
    for obj in list(scene.collection.all_objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    return scene


def build_cornell_walls(scene: bpy.types.Scene) -> None:
    h, top = BOX_HALF, 2.0 * BOX_HALF
    walls = {
        "Floor": [(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)],
        "Ceiling": [(-h, -h, top), (-h, h, top), (h, h, top), (h, -h, top)],
        "Back": [(-h, h, 0), (h, h, 0), (h, h, top), (-h, h, top)],
        "Left": [(-h, -h, 0), (-h, h, 0), (-h, h, top), (-h, -h, top)],
        "Right": [(h, -h, 0), (h, -h, top), (h, h, top), (h, h, 0)],
    }
    for name, corners in walls.items():
        quad(name, corners, diffuse_material(f"{name} Wall", WALL_COLORS[name]))
    z, s = 2.0 * BOX_HALF - 0.01, LIGHT_HALF
    # Counter-clockwise seen from below: the front (emitting) face looks down into the box.
    emitter = one_sided_emitter("Light", LIGHT_RADIANCE)
    quad("Light", [(-s, -s, z), (-s, s, z), (s, s, z), (s, -s, z)], emitter)


def build_fog_cornell(width: int = 64, height: int = 64, max_bounces: int = 3) -> bpy.types.Scene:
    """The fog Cornell box: Diffuse walls, a one-sided emitter, a fog cube; camera at the open side."""
    scene = clear_scene()
    build_cornell_walls(scene)
    box("Fog", (0.25, 0.1, 0.55), 0.5, fog_material("Fog", scatter=1.5, absorb=0.5, anisotropy=0.3))
    add_camera(scene, (0.0, -3.4, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    black_world(scene)
    render = scene.render
    render.resolution_x, render.resolution_y, render.resolution_percentage = width, height, 100
    scene.render.engine = "HAZE"
    scene.haze.max_bounces = max_bounces
    return scene


def enable_haze() -> None:
    """Use the installed Haze extension if present, else the add-on of this checkout."""
    if haze_engine() is not None:
        return
    import addon_utils

    for module in addon_utils.modules():
        if module.__name__.endswith(".haze") or module.__name__ == "haze":
            addon_utils.enable(module.__name__, default_set=True)
            if hasattr(bpy.types.Scene, "haze"):
                return
    sys.path.insert(0, str(REPO))
    import addon

    addon.register()


def haze_engine() -> type | None:
    """The registered Haze render engine class, if any."""
    return next((e for e in bpy.types.RenderEngine.__subclasses__() if getattr(e, "bl_idname", "") == "HAZE"),
                None)


def haze_module(name: str):
    """A module of the enabled Haze add-on by its name inside the package ("operators_volume"):
    installed, the package is bl_ext.<repository>.haze; from a clone, addon."""
    enable_haze()
    package = sys.modules[haze_engine().__module__].__package__
    return importlib.import_module(f"{package}.{name}")


def render_to(scene: bpy.types.Scene, out_dir: Path, stem: str) -> tuple[Path, Path]:
    """Render once and save a linear EXR and a display-referred PNG of the same result."""
    out_dir.mkdir(parents=True, exist_ok=True)
    exr, png = out_dir / f"{stem}.exr", out_dir / f"{stem}.png"
    settings = scene.render.image_settings
    settings.file_format, settings.color_depth, settings.exr_codec = "OPEN_EXR", "32", "ZIP"
    scene.render.filepath = str(exr)
    bpy.ops.render.render(write_still=True)
    # Headless, the Render Result holds no pixels: convert the written EXR instead, with the
    # scene's view transform (save_render applies colour management for PNG).
    settings.file_format, settings.color_depth = "PNG", "8"
    image = bpy.data.images.load(str(exr))
    try:
        image.save_render(str(png), scene=scene)
    finally:
        bpy.data.images.remove(image)
    return exr, png


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=256)
    parser.add_argument("--size", type=int, default=256, help="image width and height in pixels")
    parser.add_argument("--max-bounces", type=int, default=8)
    parser.add_argument("--out", type=Path, default=REPO / "out")
    return parser.parse_args(argv)


def main(argv: list[str]) -> None:
    arguments = parse_arguments(argv)
    enable_haze()
    scene = build_fog_cornell(arguments.size, arguments.size, arguments.max_bounces)
    scene.haze.samples = arguments.samples
    exr, png = render_to(scene, arguments.out, "blender_cornell")
    print(f"wrote {exr} and {png}")


if __name__ == "__main__":
    main(sys.argv[1:])
