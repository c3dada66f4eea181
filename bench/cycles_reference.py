"""Render a Haze scene folder with Cycles, timed: the Cycles side of the convergence benchmark.

    .venv/bin/python -m bench cycles_reference SCENE_DIR OUT_DIR --samples 1 2 4 --seeds 1 [--threads 2]

The scene (renderer.scenefile format) is rebuilt in bpy with the same world coordinates the
add-on exports (Blender's world space is the renderer's), then rendered once per (seed,
sample count) with Cycles set up as an unbiased reference (examples/bpy_helpers.configure_cycles:
box filter of width 1, no denoising, clamping or adaptive sampling; every bounce limit equal
to the scene's max_bounces). Each render writes OUT_DIR/cycles_s{seed}_n{samples}.exr; the
wall time of each render call (scene sync, BVH build, sampling, EXR write) goes to
OUT_DIR/timings.json. A 1-sample warm-up render first loads Cycles' kernels, so the timings
are those of a Blender session that has rendered before.

A .blend instead of a scene folder (`python -m bench blend_scene` writes one beside its export) is
rendered as it is, with Cycles configured the same way and --max-bounces as the limit.

Supported: diffuse lobes, front/back/both-sided emission, homogeneous media (world or
inside closed meshes) and grid media of density only. Anything else raises, so a benchmark
never silently compares different scenes.

Grid media become Volume objects made by geometry nodes (no files, no baking): a Volume
Cube whose voxel centres are the grid's ((k + 1/2)/n in the grid's unit box), each reading
its value from a helper point mesh by nearest-point lookup, so Cycles interpolates the same
voxel values trilinearly. Haze clamps to the edge voxels where Cycles fades to 0 over the
outermost half voxel, so grids must be 0 on their faces (the paper's generator is).

The command re-runs itself in a private Blender environment (bench.blender's); that re-run
is the Blender side, and puts examples/ on its own sys.path for the Blender-side helpers of
examples/bpy_helpers.py (configure_cycles, render_exr, new_object: the tests' Cycles set-up)
and examples/blender_cornell.py, as run_blender's scripts do. Nothing here imports from
tests/.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from renderer.scene import Camera, Material, Medium, Mesh, Scene
from renderer.scenefile import load_scene

REPO = Path(__file__).resolve().parents[1]
ISOLATED = "HAZE_CYCLES_ISOLATED"


def command(argv: list[str]) -> list[str]:
    """The command line that renders: `python -m bench cycles_reference ARGV`, to run from the
    repository root (bench/convergence.py runs it as a subprocess there)."""
    return [sys.executable, "-m", "bench", "cycles_reference", *argv]


def isolate_blender(argv: list[str]) -> None:
    """Re-run the command with private HOME / Blender user folders (bench.blender's
    environment), so nothing of the developer's own Blender setup is read or changed; in the
    re-run (the Blender side), put examples/ on sys.path for its Blender-side helpers."""
    if os.environ.get(ISOLATED):
        for path in (REPO / "examples",):
            if str(path) not in sys.path:
                sys.path.append(str(path))
        return
    from bench.blender import blender_environment

    env = blender_environment(Path(tempfile.mkdtemp(prefix="haze-cycles-")), None)
    env[ISOLATED] = "1"
    os.execve(sys.executable, command(argv), env)


# ---------------------------------------------------------------------------- bpy building


def add_camera(scene, camera: Camera, width: int, height: int) -> None:
    """A Blender camera with the renderer camera's matrix, field of view, shift and clipping."""
    import math

    import bpy
    from mathutils import Matrix

    data = bpy.data.cameras.new("Camera")
    data.sensor_fit = "HORIZONTAL" if camera.fov_axis == "x" else "VERTICAL"
    data.sensor_width = data.sensor_height = 36.0
    data.lens = 36.0 / (2.0 * math.tan(math.radians(camera.fov) / 2.0))
    # Haze's shift is in units of the larger image side, Blender's in units of the fitted one.
    fitted = width if camera.fov_axis == "x" else height
    factor = max(width, height) / fitted
    data.shift_x, data.shift_y = camera.shift[0] * factor, camera.shift[1] * factor
    data.clip_start = camera.clip_start
    data.clip_end = min(camera.clip_end, 1e6)  # Blender caps the far plane; the scenes are small
    obj = bpy.data.objects.new("Camera", data)
    obj.matrix_world = Matrix(np.asarray(camera.to_world, np.float64).tolist())
    scene.collection.objects.link(obj)
    scene.camera = obj


def sided(tree, shader_output, sides: str):
    """`shader_output` on front faces, back faces or both (Mix Shader on Geometry > Backfacing)."""
    if sides == "both":
        return shader_output
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    mix = tree.nodes.new("ShaderNodeMixShader")
    tree.links.new(geometry.outputs["Backfacing"], mix.inputs["Fac"])
    tree.links.new(shader_output, mix.inputs[1 if sides == "front" else 2])  # other input empty: black
    return mix.outputs["Shader"]


def add_shaders(tree, outputs: list):
    """The sum of shader outputs (Add Shader chain), or None for none."""
    total = outputs[0] if outputs else None
    for extra in outputs[1:]:
        add = tree.nodes.new("ShaderNodeAddShader")
        tree.links.new(total, add.inputs[0])
        tree.links.new(extra, add.inputs[1])
        total = add.outputs["Shader"]
    return total


def surface_shaders(tree, material: Material) -> list:
    outputs = []
    for lobe in material.lobes:
        if lobe.kind != "diffuse" or lobe.sides != "both":
            raise NotImplementedError(f"material {material.name}: {lobe.kind} lobe on {lobe.sides} sides")
        bsdf = tree.nodes.new("ShaderNodeBsdfDiffuse")
        bsdf.inputs["Color"].default_value = (*np.multiply(lobe.color, lobe.weight), 1.0)
        outputs.append(bsdf.outputs["BSDF"])
    if any(material.emission):
        # Emission radiance = Color x Strength; colour kept in [0, 1] by the strength.
        emission = tree.nodes.new("ShaderNodeEmission")
        strength = max(material.emission)
        emission.inputs["Color"].default_value = (*np.divide(material.emission, strength), 1.0)
        emission.inputs["Strength"].default_value = strength
        outputs.append(sided(tree, emission.outputs["Emission"], material.emission_sides))
    return outputs


def volume_shader(tree, medium: Medium):
    """Volume Coefficients with the medium's sigmas (times its `scale`; for grids times the
    "density" attribute, which the Volume object carries)."""
    if any(medium.emission) or medium.flame is not None or medium.temperature is not None:
        raise NotImplementedError(f"medium {medium.name}: emission")
    node = tree.nodes.new("ShaderNodeVolumeCoefficients")
    node.inputs["Anisotropy"].default_value = medium.g
    pairs = (("Absorption Coefficients", medium.sigma_a), ("Scatter Coefficients", medium.sigma_s))
    for socket, sigma in pairs:
        coefficients = tuple(float(s) * medium.scale for s in sigma)
        if medium.type == "grid":
            attribute = tree.nodes.new("ShaderNodeAttribute")
            attribute.attribute_name = "density"
            scale = tree.nodes.new("ShaderNodeVectorMath")
            scale.operation = "MULTIPLY"
            scale.inputs[1].default_value = coefficients
            tree.links.new(attribute.outputs["Fac"], scale.inputs[0])
            tree.links.new(scale.outputs["Vector"], node.inputs[socket])
        else:
            node.inputs[socket].default_value = coefficients
    return node.outputs["Volume"]


def blender_material(name: str, material: Material | None, medium: Medium | None):
    """One Blender material: Haze's surface material plus the medium the mesh encloses.
    A surface with no lobes and no emission stays unlinked: Cycles' invisible boundary."""
    from blender_cornell import node_material

    blend, tree, output = node_material(name)
    surface = add_shaders(tree, surface_shaders(tree, material)) if material is not None else None
    if surface is not None:
        tree.links.new(surface, output.inputs["Surface"])
    elif medium is None:
        transparent = tree.nodes.new("ShaderNodeBsdfTransparent")  # nothing at all: let rays through
        tree.links.new(transparent.outputs["BSDF"], output.inputs["Surface"])
    if medium is not None:
        tree.links.new(volume_shader(tree, medium), output.inputs["Volume"])
    return blend


def add_mesh(mesh: Mesh, materials: dict[str, Material], media: dict[str, Medium]) -> None:
    import bpy
    from bpy_helpers import new_object

    if mesh.normals is not None:
        raise NotImplementedError(f"mesh {mesh.name}: shading normals")
    medium = media[mesh.medium] if mesh.medium else None
    obj = new_object(mesh.name, mesh.vertices.tolist(), mesh.indices.tolist())
    for slot in mesh.materials:
        obj.data.materials.append(blender_material(f"{slot}|{mesh.medium}", materials[slot], medium))
    if mesh.material_ids is not None:
        obj.data.polygons.foreach_set("material_index", np.asarray(mesh.material_ids, np.int32))
    obj.data.update()
    bpy.context.view_layer.update()


def density_points(medium: Medium):
    """A vertex-only mesh (never rendered) with one point per voxel centre of the grid's
    box p0..p1 and the voxel's value as its "density" attribute."""
    import bpy

    nz, ny, nx = medium.density.shape
    p0, p1 = np.asarray(medium.p0), np.asarray(medium.p1)
    axes = [p0[a] + (np.arange(n) + 0.5) * (p1[a] - p0[a]) / n for a, n in enumerate((nx, ny, nz))]
    z, y, x = np.meshgrid(axes[2], axes[1], axes[0], indexing="ij")  # the density's [z, y, x] order
    points = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1).astype(np.float32)
    data = bpy.data.meshes.new(f"{medium.name} voxels")
    data.vertices.add(len(points))
    data.vertices.foreach_set("co", points.ravel())
    attribute = data.attributes.new("density", "FLOAT", "POINT")
    attribute.data.foreach_set("value", np.asarray(medium.density, np.float32).ravel())
    obj = bpy.data.objects.new(f"{medium.name} voxels", data)
    bpy.context.scene.collection.objects.link(obj)
    return obj, points[0], points[-1], (nx, ny, nz)


def volume_tree(medium: Medium, points_object, low, high, resolution, material):
    """Geometry nodes: Volume Cube over the voxel centres, density = nearest voxel's value."""
    import bpy

    tree = bpy.data.node_groups.new(f"{medium.name} grid", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    nodes, links = tree.nodes, tree.links
    info = nodes.new("GeometryNodeObjectInfo")
    info.inputs["Object"].default_value = points_object
    info.transform_space = "ORIGINAL"  # the points' own coordinates = the grid's local ones
    nearest = nodes.new("GeometryNodeSampleNearest")
    position = nodes.new("GeometryNodeInputPosition")
    links.new(info.outputs["Geometry"], nearest.inputs["Geometry"])
    links.new(position.outputs["Position"], nearest.inputs["Sample Position"])
    value = nodes.new("GeometryNodeInputNamedAttribute")
    value.data_type = "FLOAT"
    value.inputs["Name"].default_value = "density"
    sample = nodes.new("GeometryNodeSampleIndex")
    sample.data_type, sample.domain = "FLOAT", "POINT"
    links.new(info.outputs["Geometry"], sample.inputs["Geometry"])
    links.new(value.outputs["Attribute"], sample.inputs["Value"])
    links.new(nearest.outputs["Index"], sample.inputs["Index"])
    cube = nodes.new("GeometryNodeVolumeCube")
    cube.inputs["Min"].default_value, cube.inputs["Max"].default_value = low.tolist(), high.tolist()
    for axis, count in zip("XYZ", resolution):
        cube.inputs[f"Resolution {axis}"].default_value = count
    links.new(sample.outputs["Value"], cube.inputs["Density"])
    set_material = nodes.new("GeometryNodeSetMaterial")
    set_material.inputs["Material"].default_value = material
    links.new(cube.outputs["Volume"], set_material.inputs["Geometry"])
    out = nodes.new("NodeGroupOutput")
    links.new(set_material.outputs["Geometry"], out.inputs[0])
    return tree


def add_grid_medium(medium: Medium) -> None:
    """A Volume object carrying the grid's density, placed by the medium's to_world."""
    import bpy
    from mathutils import Matrix

    if any(s != 1 for s in medium.density.shape) and not _zero_faces(medium.density):
        raise NotImplementedError(f"medium {medium.name}: grid not 0 on its faces (edge handling differs)")
    points_object, low, high, resolution = density_points(medium)
    material = blender_material(f"{medium.name} volume", None, medium)
    carrier = bpy.data.objects.new(medium.name, bpy.data.meshes.new(medium.name))
    bpy.context.scene.collection.objects.link(carrier)
    modifier = carrier.modifiers.new("grid", "NODES")
    modifier.node_group = volume_tree(medium, points_object, low, high, resolution, material)
    carrier.matrix_world = Matrix(np.asarray(medium.to_world, np.float64).tolist())


def _zero_faces(grid: np.ndarray) -> bool:
    return all(not np.any(face) for face in (grid[0], grid[-1], grid[:, 0], grid[:, -1], grid[:, :, 0],
                                              grid[:, :, -1]))


def world_setup(scene, haze: Scene, media: dict[str, Medium]) -> None:
    """Background radiance, and the scene-wide medium as the world volume."""
    import bpy

    world = bpy.data.worlds.new("World")
    if world.node_tree is None:  # Blender 5 worlds come with nodes; use_nodes is deprecated there
        world.use_nodes = True
    tree = world.node_tree
    background = tree.nodes["Background"]
    radiance = haze.environment.radiance
    strength = max(radiance)
    color = np.divide(radiance, strength) if strength else radiance
    background.inputs["Color"].default_value = (*color, 1.0)
    background.inputs["Strength"].default_value = strength
    if haze.medium is not None:
        if media[haze.medium].type != "homogeneous":
            raise NotImplementedError("a grid medium as the world medium")
        output = tree.nodes["World Output"]
        tree.links.new(volume_shader(tree, media[haze.medium]), output.inputs["Volume"])
    scene.world = world


def build_scene(haze: Scene):
    """The bpy scene for `haze`: same geometry, materials, media and camera."""
    from blender_cornell import clear_scene

    if haze.lights:
        raise NotImplementedError("lamp lights (the benchmark scenes light with emissive meshes)")
    scene = clear_scene()
    materials = {m.name: m for m in haze.materials}
    media = {m.name: m for m in haze.media}
    for mesh in haze.meshes:
        enclosed = media.get(mesh.medium) if mesh.medium else None
        if enclosed is not None and enclosed.type == "grid":
            continue  # the Volume object below is the grid; its Haze interface box has no look of its own
        add_mesh(mesh, materials, media)
    for medium in haze.media:
        if medium.type == "grid":
            add_grid_medium(medium)
    world_setup(scene, haze, media)
    add_camera(scene, haze.camera, haze.film.width, haze.film.height)
    render = scene.render
    render.resolution_x, render.resolution_y = haze.film.width, haze.film.height
    render.resolution_percentage = 100
    return scene


# ---------------------------------------------------------------------------- rendering


def timed_render(scene, path: Path, samples: int, max_bounces: int, seed: int, threads: int) -> float:
    from bpy_helpers import configure_cycles, render_exr

    configure_cycles(scene, samples, max_bounces, seed, threads)
    start = time.perf_counter()
    render_exr(scene, str(path))
    return time.perf_counter() - start


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m bench cycles_reference",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("scene", type=Path, help="a Haze scene folder (scene.json + arrays), or a .blend")
    parser.add_argument("out", type=Path)
    parser.add_argument("--samples", type=int, nargs="+", required=True)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--max-bounces", type=int, default=0,
                        help="for a .blend (a scene folder has its own)")
    parser.add_argument("--time-limit", type=float, default=0.0,
                        help="per seed: skip larger sample counts once a render took this long")
    return parser.parse_args(argv)


def check_files() -> None:
    """Raise if a Volume object's or an image's file cannot be read: Cycles would render the
    scene without it (an empty volume, a pink texture), and the benchmark would compare
    different scenes (a .blend copied without its relative //assets once made Cycles render
    the smoke ball's Cornell box empty)."""
    import bpy

    for image in bpy.data.images:
        if image.source in ("FILE", "SEQUENCE", "TILED") and image.packed_file is None \
                and not Path(bpy.path.abspath(image.filepath)).is_file():
            raise RuntimeError(f"Image '{image.name}': {bpy.path.abspath(image.filepath)} not found")
    for volume in bpy.data.volumes:
        volume.grids.load()
        if not volume.grids.is_loaded or len(volume.grids) == 0:
            raise RuntimeError(f"Volume '{volume.name}': {volume.grids.error_message or 'no grids'} "
                               f"({bpy.path.abspath(volume.filepath)})")


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    arguments = parse_arguments(argv)  # --help and bad arguments before any Blender
    isolate_blender(argv)
    if arguments.scene.suffix == ".blend":  # an artist's scene as it is (bench/blend_scene.py)
        import bpy

        bpy.ops.wm.open_mainfile(filepath=str(arguments.scene))
        scene, bounces = bpy.context.scene, arguments.max_bounces
        check_files()
    else:
        haze = load_scene(arguments.scene)
        scene, bounces = build_scene(haze), haze.integrator.max_bounces
    arguments.out.mkdir(parents=True, exist_ok=True)
    warmup = timed_render(scene, arguments.out / "warmup.exr", 1, bounces, 0, arguments.threads)
    renders = []
    for seed in arguments.seeds:
        for samples in sorted(arguments.samples):
            path = arguments.out / f"cycles_s{seed}_n{samples}.exr"
            seconds = timed_render(scene, path, samples, bounces, seed, arguments.threads)
            renders.append({"seed": seed, "samples": samples, "seconds": seconds, "path": str(path)})
            print(f"cycles seed {seed} samples {samples}: {seconds:.3f} s", flush=True)
            if arguments.time_limit and seconds >= arguments.time_limit:
                break
    timings = {"warmup_seconds": warmup, "threads": arguments.threads, "renders": renders}
    (arguments.out / "timings.json").write_text(json.dumps(timings, indent=1))
    return 0
