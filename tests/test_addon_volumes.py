"""Volumes from Blender: Volume objects, smoke domains and the Add > Volume operators.

Three kinds of tests:

* bpy-free unit tests of the export's pure helpers (factorisation of per-voxel coefficients,
  cropping, cleaning, boundary boxes, smoke resolution, the generators and file readers);
* one Blender run (module fixture `exported`) that builds every test scene, exports it with
  the add-on and hands back arrays, warnings and scene folders; the tests below check them
  (dense extraction to float precision, exact arrays, placement, materials, bad input...);
* renders: the exported smoke ball against the same grid written directly in the renderer's
  scene format (same seed: the same image to float precision), cropped against uncropped
  grids (same field exactly, same image within noise), and Haze against Cycles on a smoke
  ball in a Cornell box (bench.comparison.assert_agree: image mean within 1 %, 8x8 block means
  within their noise).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from addon.export import grid_fields
from addon.export.grid_fields import clean_grid, crop, crop_box, evaluate_fields, factor_rank_one
from addon.export.mesh import edge_problems
from addon.export.smoke import base_resolution
from addon.export.volume_shader import Blackbody, VoxelCoefficients
from addon.export.volumes import boundary_box, box_mesh, object_density_factor
from addon.volume_grids import (
    GridFileError,
    box_index_to_object,
    gaussian_smoke_density,
    read_npy,
    read_pbrt,
    smoke_ball_density,
    write_pbrt,
)
from bench.comparison import assert_agree, compare_images
from examples import media_scenes
from helpers.blender_runs import blender_fixture, blender_result, with_arrays
from renderer.imageio import read_exr
from renderer.media import generators
from renderer.render import render
from renderer.scene import Material, Medium
from renderer.scenefile import load_scene

FLOAT32_EPS = float(np.finfo(np.float32).eps)


class Collect:
    """A stand-in for export.messages.Messages that keeps every warning."""

    def __init__(self) -> None:
        self.warnings: list[str] = []

    def warn(self, subject: str, problem: str) -> None:
        self.warnings.append(f"{subject}: {problem}")


# ------------------------------------------------------------------------------ trilinear reference


def grid_density(medium: Medium, points: np.ndarray) -> np.ndarray:
    """The density of a grid medium at world points, as renderer/scene.py defines it: voxel
    centres at (i + 0.5) / n of the box p0..p1 placed by to_world, trilinear with clamp to
    the edge inside the box, 0 outside. An independent numpy implementation."""
    p0, p1 = np.asarray(medium.p0), np.asarray(medium.p1)
    local = np.c_[points, np.ones(len(points))] @ np.linalg.inv(medium.to_world).T
    u = (local[:, :3] - p0) / (p1 - p0)
    inside = np.all((u >= 0.0) & (u <= 1.0), axis=1)
    grid = np.asarray(medium.density, np.float64)
    n = np.array(grid.shape[::-1])
    x = np.clip(u * n - 0.5, 0.0, n - 1)
    i0 = np.minimum(np.floor(x).astype(int), n - 1)
    i1 = np.minimum(i0 + 1, n - 1)
    f = x - i0
    value = np.zeros(len(points))
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                ix = (i1 if dx else i0)[:, 0]
                iy = (i1 if dy else i0)[:, 1]
                iz = (i1 if dz else i0)[:, 2]
                w = (f[:, 0] if dx else 1 - f[:, 0]) * (f[:, 1] if dy else 1 - f[:, 1]) * \
                    (f[:, 2] if dz else 1 - f[:, 2])
                value += w * grid[iz, iy, ix]
    return np.where(inside, value, 0.0)


# ------------------------------------------------------------------------------ unit tests


def test_factor_prefers_the_volume_grid_and_is_exact():
    rng = np.random.default_rng(1)
    grid = rng.random(50)
    values = np.outer(grid, [1.4, 2.8, 4.2, 1.5, 1.5, 1.5])
    field, constants, exact = factor_rank_one(values, [rng.random(50), grid])
    assert exact and field is not None
    np.testing.assert_array_equal(field, grid)
    np.testing.assert_allclose(constants, [1.4, 2.8, 4.2, 1.5, 1.5, 1.5], rtol=1e-12)


def test_factor_of_a_nonlinear_field_keeps_the_product():
    grid = np.linspace(0.0, 2.0, 40)
    values = np.outer(grid**2, [0.3, 0.6, 0.9])  # e.g. a Math Power node on the density
    field, constants, exact = factor_rank_one(values, [grid])
    assert exact
    np.testing.assert_allclose(np.outer(field, constants), values, rtol=4 * FLOAT32_EPS)  # float32 field


def test_factor_flags_a_varying_colour():
    rng = np.random.default_rng(2)
    values = rng.random((30, 3))  # a colour grid: no single colour fits
    _, _, exact = factor_rank_one(values, [values[:, 0]])
    assert not exact


def fake_material(grids: dict[str, np.ndarray]) -> VoxelCoefficients:
    """Scattering 2 x density, absorption 0.25 where there is flame (one row where a chunk has
    none, as the shader gives for values the same in every voxel), blackbody at 1000 x flame."""
    density, flame = grids["density"][:, None], grids["flame"][:, None]
    absorption = np.where(flame > 0.0, 0.25, 0.0) * np.ones(3)
    if not np.any(absorption):
        absorption = np.zeros((1, 3))
    return VoxelCoefficients(2.0 * density * np.array([0.2, 0.4, 0.6]), absorption, np.zeros((1, 3)),
                             [(np.full((1, 1), 0.3), 2.0 * density)],
                             [Blackbody(1000.0 * flame, np.ones((1, 1)), np.ones((1, 3)), np.ones((1, 1)))])


def test_chunked_evaluation_equals_one_pass(monkeypatch):
    rng = np.random.default_rng(5)
    grids = {"density": rng.random(100).astype(np.float32), "flame": rng.random(100).astype(np.float32)}
    grids["flame"][:50] = 0.0
    whole = evaluate_fields(fake_material, grids, 100)
    monkeypatch.setattr(grid_fields, "CHUNK", 7)
    pieces = evaluate_fields(fake_material, grids, 100)
    for name in ("sigma_s", "sigma_a", "emission", "temperature"):
        chunked, single = np.broadcast_arrays(getattr(pieces, name), getattr(whole, name))
        np.testing.assert_allclose(chunked, single, rtol=1e-6)
    assert pieces.sigma_a.shape == (100, 3)  # one row per chunk at first, a full column once it varies
    assert pieces.emission.shape == (1, 3)  # the same in every chunk: stays one row
    assert pieces.anisotropy == pytest.approx(0.3) and pieces.anisotropy_spread < 1e-6
    assert pieces.blackbody_intensity == 1.0 and pieces.blackbody_scale == (1.0, 1.0)


def test_crop_keeps_the_density_field_and_one_empty_voxel():
    rng = np.random.default_rng(3)
    full = np.zeros((20, 18, 16), np.float32)
    full[5:9, 4:12, 7:10] = rng.random((4, 8, 3)).astype(np.float32) + 0.1
    lo, hi = crop_box([full > 0.0])
    np.testing.assert_array_equal(lo, [5, 4, 7])
    np.testing.assert_array_equal(hi, [8, 11, 9])
    cropped = crop(full, lo, hi)
    assert cropped.shape == (6, 10, 5)
    assert not cropped[0].any() and not cropped[-1].any() and not cropped[:, :, 0].any()
    # Placement as the exporter does it: voxel [0,0,0] of a grid at index `start` spans
    # index coordinates start - 0.5 .. start + shape - 0.5; to_world is a rotation + scale.
    angle = 0.4
    cos, sin = math.cos(angle), math.sin(angle)
    rotation = np.array([[cos, -sin, 0, 1.0], [sin, cos, 0, 2.0], [0, 0, 1.5, -1.0], [0, 0, 0, 1]])
    to_world = rotation @ np.diag([0.1, 0.2, 0.3, 1.0])

    def medium(values, start):
        p0 = np.asarray(start, float) - 0.5
        return Medium("m", "grid", density=values, p0=tuple(p0), p1=tuple(p0 + values.shape[::-1]),
                      to_world=to_world)

    index = rng.uniform((lo - 2)[::-1], (hi + 2)[::-1], (4000, 3))  # around the kept voxels, x y z
    points = (np.c_[index, np.ones(4000)] @ to_world.T)[:, :3]
    before = grid_density(medium(full, (0, 0, 0)), points)
    after = grid_density(medium(cropped, (lo - 1)[::-1]), points)
    assert np.count_nonzero(before) > 100
    np.testing.assert_allclose(after, before, rtol=1e-12, atol=1e-12)


def test_crop_pads_when_voxels_touch_the_read_box():
    values = np.ones((3, 3, 3), np.float32)
    lo, hi = crop_box([values > 0])
    cropped = crop(values, lo, hi)
    assert cropped.shape == (5, 5, 5) and cropped.sum() == 27 and cropped[1:-1, 1:-1, 1:-1].all()


def test_clean_grid_drops_nan_negative_and_clipped_voxels():
    values = np.array([[[np.nan, -1.0, 5e-4, 2e-3, np.inf, 0.5]]], np.float32)
    messages = Collect()
    cleaned = clean_grid(values, 1e-3, "Object 'V'", "density", messages)
    np.testing.assert_array_equal(cleaned, np.float32([[[0.0, 0.0, 0.0, 2e-3, 0.0, 0.5]]]))
    text = " ".join(messages.warnings)
    assert "Object 'V'" in text and "2 NaN or infinite" in text and "1 negative" in text
    no_clip = clean_grid(np.array([[[1e-6, 0.0]]], np.float32), 0.0, "s", "density", Collect())
    np.testing.assert_array_equal(no_clip, np.float32([[[1e-6, 0.0]]]))


@pytest.mark.parametrize("mirror", [False, True])
def test_box_mesh_is_closed_with_outward_faces(mirror):
    to_world = np.diag([1.0, -2.0 if mirror else 2.0, 0.5, 1.0])
    to_world[:3, 3] = (1.0, 2.0, 3.0)
    mesh = box_mesh("b", "m", (-1.0, 0.0, 2.0), (3.0, 1.0, 5.0), to_world)
    assert edge_problems(mesh.indices) == (0, 0)
    v = mesh.vertices.astype(np.float64)[mesh.indices]
    signed = np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0
    assert signed == pytest.approx(4.0 * 1.0 * 3.0 * 2.0 * 0.5, rel=1e-6)  # box volume x |det|: outward


def test_object_density_factor_follows_cycles():
    matrix = np.diag([1.0, 2.0, 3.0, 1.0])
    assert object_density_factor(matrix, "OBJECT") == pytest.approx(1.0 / math.sqrt(14.0 / 3.0))
    assert object_density_factor(matrix, "WORLD") == 1.0
    assert object_density_factor(np.eye(4), "OBJECT") == pytest.approx(1.0)


def test_boundary_box_stops_at_the_empty_border_voxels():
    """Half a voxel inside the grid box where the medium is 0 anyway (the outer voxel layer
    empty in every grid, no flame-less constant emission); the whole grid box otherwise."""
    inner = np.zeros((5, 4, 6), np.float32)
    inner[1:-1, 1:-1, 1:-1] = 1.0

    def grid(density, flame=None, temperature=None, emission=(0.0, 0.0, 0.0), intensity=1.0):
        return grid_fields.GridMedium(density, flame, temperature, np.ones(3), np.ones(3), np.array(emission),
                                      0.0, intensity, 1.0, np.array([10, 20, 30]), np.eye(4))

    start, high = np.array([10.0, 20.0, 30.0]), np.array([15.0, 23.0, 34.0])  # start + (nx, ny, nz) - 1
    full = (start - 0.5, high + 0.5)
    cases = [(grid(inner), (start, high)),
             (grid(inner, temperature=3000.0 * inner), (start, high)),
             (grid(inner, flame=inner, emission=(1.0, 1.0, 1.0)), (start, high)),
             (grid(np.ones_like(inner)), full),  # density up to the box: its last half voxel counts
             (grid(inner, flame=np.ones_like(inner), emission=(1.0, 0.0, 0.0)), full),
             (grid(inner, emission=(0.0, 0.5, 0.0)), full),  # constant emission fills the grid box
             (grid(inner, temperature=np.zeros_like(inner), intensity=0.5), full),  # 0 K emits below b 1
             (grid(np.ones((2, 4, 6), np.float32) * 0.0), (start - 0.5, np.array([15.5, 23.5, 31.5])))]
    for medium, expected in cases:
        low, top = boundary_box(medium)
        np.testing.assert_array_equal(low, expected[0])
        np.testing.assert_array_equal(top, expected[1])


def test_smoke_base_resolution():
    np.testing.assert_array_equal(base_resolution(np.array([2.0, 2.0, 3.0]), 16), [11, 11, 16])
    np.testing.assert_array_equal(base_resolution(np.array([4.0, 0.1, 1.0]), 32), [32, 4, 8])


def test_generators_are_the_paper_scenes():
    """One generator each, in renderer/media/generators.py, used by the add-on and the examples
    (the add-on imports it when first called, so that registering does not import numba)."""
    assert media_scenes.smoke_ball_density is generators.smoke_ball_density
    assert media_scenes.gaussian_smoke_density is generators.gaussian_smoke_density
    np.testing.assert_array_equal(smoke_ball_density(11), generators.smoke_ball_density(11))
    np.testing.assert_array_equal(gaussian_smoke_density(8, 3, 4), generators.gaussian_smoke_density(8, 3, 4))


def test_box_index_to_object_places_voxel_centres():
    matrix = box_index_to_object((-1.0, 0.0, 2.0), (1.0, 3.0, 3.0), (4, 3, 2))  # nz, ny, nx
    centre = matrix @ np.array([1.0, 2.0, 3.0, 1.0])
    np.testing.assert_allclose(centre[:3], [-1.0 + 1.5 * 1.0, 0.0 + 2.5 * 1.0, 2.0 + 3.5 * 0.25])


def test_pbrt_round_trip_and_bad_files(tmp_path):
    rng = np.random.default_rng(4)
    density = rng.random((3, 4, 5)).astype(np.float32)
    path = tmp_path / "m.pbrt"
    write_pbrt(path, density, (0, 1, 2), (1, 3, 5))
    values, p0, p1 = read_pbrt(path)
    np.testing.assert_array_equal(values, density)
    np.testing.assert_array_equal(p0, [0, 1, 2])
    np.testing.assert_array_equal(p1, [1, 3, 5])
    bad = tmp_path / "bad.pbrt"
    bad.write_text(path.read_text().replace('"integer nz" 3', '"integer nz" 4'))
    with pytest.raises(GridFileError, match="density.*60 values, expected 80"):
        read_pbrt(bad)
    bad.write_text('MakeNamedMedium "x" "string type" "homogeneous"')
    with pytest.raises(GridFileError, match="heterogeneous"):
        read_pbrt(bad)


def test_npy_bad_arrays(tmp_path):
    np.save(tmp_path / "flat.npy", np.zeros((3, 4)))
    with pytest.raises(GridFileError, match="3-D"):
        read_npy(tmp_path / "flat.npy")
    np.save(tmp_path / "nan.npy", np.full((2, 2, 2), np.nan))
    with pytest.raises(GridFileError, match="8 density values are NaN"):
        read_npy(tmp_path / "nan.npy")
    (tmp_path / "junk.npy").write_bytes(b"not numpy")
    with pytest.raises(GridFileError, match="not a readable"):
        read_npy(tmp_path / "junk.npy")


# ------------------------------------------------------------------------------ Blender run

EXPORT_BODY = r'''
import math
import numpy as np
import bpy
from pathlib import Path
from mathutils import Matrix

import bpy_helpers as H
import blender_cornell as C

H.enable_addon()
V = H.addon_module("export.volume_read")
GridSampler, index_box = H.addon_names("export.grid_sampler", "GridSampler", "index_box")
export_scene = H.addon_module("export.scene").export_scene
import_openvdb, smoke_ball_density, write_pbrt = H.addon_names(
    "volume_grids", "import_openvdb", "smoke_ball_density", "write_pbrt")
from renderer.scenefile import save_scene

OUT = Path(os.getcwd())
ARRAYS = {}
VDB = import_openvdb()


def write_grids(path, grids, index_to_object, start=(0, 0, 0)):
    """Float grids ((nz, ny, nx) arrays, voxel [0,0,0] at index `start`) into an OpenVDB file."""
    written = []
    for name, values in grids.items():
        grid = VDB.FloatGrid()
        grid.copyFromArray(np.ascontiguousarray(values.transpose(2, 1, 0)), ijk=tuple(start), tolerance=0.0)
        grid.name = name
        grid.transform = VDB.createLinearTransform(np.asarray(index_to_object).T.tolist())
        written.append(grid)
    VDB.write(str(path), grids=written)
    return str(path)


def node_material(name):
    return C.node_material(name)


def principled(name, color=(0.5, 0.5, 0.5), density=1.0, **inputs):
    material, tree, output = node_material(name)
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Density"].default_value = density
    node.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    for key, value in inputs.items():
        node.inputs[key.replace("_", " ")].default_value = value
    tree.links.new(node.outputs[0], output.inputs["Volume"])
    return material


def file_volume(name, path, material=None, location=(0, 0, 0), rotation=(0, 0, 0), scale=(1, 1, 1),
                clipping=0.0, space="OBJECT"):
    volume = bpy.data.volumes.new(name)
    volume.filepath = path
    volume.render.clipping = clipping
    volume.render.space = space
    if material is not None:
        volume.materials.append(material)
    obj = bpy.data.objects.new(name, volume)
    bpy.context.scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler, obj.scale = location, [math.radians(a) for a in rotation], scale
    return obj


def analytic_volume(name, resolution, low, high, material=None):
    """A geometry-node Volume Cube of density 0.5 + x^2 + 2 y + 3 z^2 (object space)."""
    tree = bpy.data.node_groups.new(name, "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    out = tree.nodes.new("NodeGroupOutput")
    cube = tree.nodes.new("GeometryNodeVolumeCube")
    separate = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(tree.nodes.new("GeometryNodeInputPosition").outputs[0], separate.inputs[0])

    def math_node(operation, a, b, c=None):
        node = tree.nodes.new("ShaderNodeMath")
        node.operation = operation
        for socket, value in zip(node.inputs, (a, b, c)):
            if isinstance(value, float):
                socket.default_value = value
            elif value is not None:
                tree.links.new(value, socket)
        return node.outputs[0]

    x, y, z = separate.outputs[0], separate.outputs[1], separate.outputs[2]
    x2 = math_node("MULTIPLY", x, x)
    z2 = math_node("MULTIPLY", z, z)
    total = math_node("ADD", math_node("MULTIPLY_ADD", y, 2.0, x2), math_node("MULTIPLY_ADD", z2, 3.0, 0.5))
    tree.links.new(total, cube.inputs["Density"])
    cube.inputs["Min"].default_value, cube.inputs["Max"].default_value = low, high
    for axis, count in zip("XYZ", resolution):
        cube.inputs[f"Resolution {axis}"].default_value = count
    last = cube.outputs[0]
    if material is not None:
        setter = tree.nodes.new("GeometryNodeSetMaterial")
        setter.inputs["Material"].default_value = material
        tree.links.new(last, setter.inputs[0])
        last = setter.outputs[0]
    tree.links.new(last, out.inputs[0])
    obj = bpy.data.objects.new(name, bpy.data.volumes.new(name))
    bpy.context.scene.collection.objects.link(obj)
    obj.modifiers.new("Grid", "NODES").node_group = tree
    return obj


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    scene = bpy.context.scene
    C.add_camera(scene, (0.0, -4.0, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    scene.render.resolution_x = scene.render.resolution_y = 32
    return scene


def export():
    return export_scene(bpy.context.evaluated_depsgraph_get(), render_depsgraph=False)


def datablock_counts():
    return [len(c) for c in (bpy.data.scenes, bpy.data.objects, bpy.data.meshes, bpy.data.node_groups,
                             bpy.data.volumes, bpy.data.materials)]


def media_by_object(result):
    return {m.name.split(" (volume)")[0]: m for m in result.scene.media}


def keep(prefix, medium):
    ARRAYS[f"{prefix}.density"] = medium.density
    ARRAYS[f"{prefix}.to_world"] = medium.to_world
    ARRAYS[f"{prefix}.box"] = np.array([medium.p0, medium.p1])
    for name in ("flame", "temperature"):
        if getattr(medium, name) is not None:
            ARRAYS[f"{prefix}.{name}"] = getattr(medium, name)
    return {"sigma_a": medium.sigma_a, "sigma_s": medium.sigma_s, "emission": medium.emission, "g": medium.g,
            "scale": medium.scale, "blackbody": medium.blackbody_intensity}


# -------------------------------------------------------------------- scenes


def analytic_case():
    """Dense reads of a known field, on an identity and a rotated, non-uniformly scaled object."""
    empty_scene()
    material = principled("Analytic", density=1.0)
    low, high, resolution = (0.1, 0.2, 0.3), (1.1, 1.7, 2.3), (12, 15, 18)
    plain = analytic_volume("Plain", resolution, low, high, material)
    turned = analytic_volume("Turned", resolution, low, high, material)
    turned.rotation_euler = (0.3, -0.5, 1.1)
    turned.scale = (0.7, 1.9, 1.3)
    turned.location = (0.5, -0.25, 2.0)
    before = datablock_counts()
    report = {}
    with GridSampler(1) as sampler:
        for obj in (plain, turned):
            info = sampler.inspect(obj)
            grid = info.grids["density"]
            start, shape = index_box(grid, info.bounds)
            ARRAYS[f"read.{obj.name}"] = sampler.read(obj, grid, start, shape)
            ARRAYS[f"read.{obj.name}.start"] = np.asarray(start)
            ARRAYS[f"read.{obj.name}.index_to_object"] = grid.index_to_object
    result = export()
    report["cleanup"] = [before, datablock_counts()]
    media = media_by_object(result)
    for name in ("Plain", "Turned"):
        report[name] = keep(f"analytic.{name}", media[name])
        ARRAYS[f"analytic.{name}.matrix_world"] = np.array(bpy.data.objects[name].matrix_world)
    report["lattice"] = {"low": low, "high": high, "resolution": resolution}
    report["warnings"] = result.warnings
    return report


def exact_vdb_case():
    """A VDB written from an array (offset, sheared index transform): read back bit for bit."""
    empty_scene()
    rng = np.random.default_rng(7)
    values = (rng.random((6, 7, 9)) * 2.0 + 0.01).astype(np.float32)
    transform = np.array([[0.1, 0.02, 0.0, 1.0], [0.0, 0.2, 0.05, 2.0], [0.01, 0.0, 0.3, 3.0], [0, 0, 0, 1]])
    path = write_grids(OUT / "exact.vdb", {"density": values}, transform, start=(2, 3, 4))
    obj = file_volume("Exact", path, principled("Exact"), rotation=(10, 20, 30), scale=(1, 2, 0.5))
    ARRAYS["exact.values"] = values
    result = export()
    report = keep("exact", media_by_object(result)["Exact"])
    ARRAYS["exact.matrix_world"] = np.array(obj.matrix_world)
    ARRAYS["exact.transform"] = transform
    return report


def render_case(name, crop=True, haze=0.0):
    """The smoke ball as a rotated, non-uniformly scaled Volume object (render space World),
    over a floor under a point light; `haze`: a faint fill (below clipping) around it."""
    scene = empty_scene()
    V.CROP_GRIDS = crop
    ball = smoke_ball_density(11)
    values = ball
    if haze > 0.0:
        values = np.full((40, 40, 40), haze, np.float32)
        values[5:16, 6:17, 7:18] = np.maximum(ball, haze)
    p0, p1 = np.array([-0.6, -0.5, -0.4]), np.array([0.6, 0.5, 0.4])
    size = (p1 - p0) / np.array(ball.shape[::-1])
    offset = np.array([7, 6, 5]) if haze > 0.0 else np.zeros(3)
    index_to_object = np.eye(4)
    index_to_object[:3, :3] = np.diag(size)
    index_to_object[:3, 3] = p0 + 0.5 * size - offset * size
    path = write_grids(OUT / f"{name}.vdb", {"density": values}, index_to_object)
    material = principled("Smoke", color=(0.3, 0.5, 0.7), density=20.0, Anisotropy=0.2)
    obj = file_volume("Smoke", path, material, location=(0.1, 0.2, 1.0), rotation=(20, 30, 40),
                      scale=(1.0, 1.3, 0.8), clipping=0.001, space="WORLD")
    H.floor_plane("Floor", 3.0, C.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    H.add_light("POINT", "Lamp", (1.0, -1.5, 3.0), energy=300.0, shadow_soft_size=0.0)
    C.black_world(scene)
    H.configure_haze(scene, 64, 4, 1)
    result = export()
    V.CROP_GRIDS = True
    save_scene(result.scene, OUT / name)
    ARRAYS[f"{name}.density"] = next(m for m in result.scene.media if m.type == "grid").density
    ARRAYS[f"{name}.matrix_world"] = np.array(obj.matrix_world)
    ARRAYS[f"{name}.object_box"] = np.array([p0, p1])
    return {"folder": str(OUT / name), "stats": result.volume_stats, "warnings": result.warnings}


def material_case():
    """Materials reading grids through Math nodes, emission from flame, blackbody temperature."""
    empty_scene()
    rng = np.random.default_rng(9)
    shape = (5, 6, 7)
    grids = {"density": (rng.random(shape) + 0.1).astype(np.float32),
             "flame": (rng.random(shape) * 0.8 + 0.05).astype(np.float32),
             "temperature": (rng.random(shape) * 2.0 + 0.1).astype(np.float32)}
    for key, value in grids.items():
        ARRAYS[f"material.{key}"] = value
    path = write_grids(OUT / "material.vdb", grids, np.eye(4))

    # Volume Scatter + Volume Absorption with Density = grid x constant (Math nodes).
    linear, tree, output = node_material("Linear")
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "density"
    add = tree.nodes.new("ShaderNodeAddShader")
    tree.links.new(add.outputs[0], output.inputs["Volume"])
    for index, (kind, color, factor) in enumerate((("ShaderNodeVolumeScatter", (0.2, 0.4, 0.6), 7.0),
                                                   ("ShaderNodeVolumeAbsorption", (0.5, 0.25, 0.0), 3.0))):
        node = tree.nodes.new(kind)
        node.inputs["Color"].default_value = (*color, 1.0)
        multiply = tree.nodes.new("ShaderNodeMath")
        multiply.operation = "MULTIPLY"
        multiply.inputs[1].default_value = factor
        tree.links.new(attribute.outputs["Fac"], multiply.inputs[0])
        tree.links.new(multiply.outputs[0], node.inputs["Density"])
        tree.links.new(node.outputs[0], add.inputs[index])
    file_volume("Linear", path, linear)

    # Principled Volume whose Density is grid^2 (Math Power), no density attribute.
    squared = principled("Squared", color=(0.25, 0.5, 1.0), density=1.0)
    tree = squared.node_tree
    node = tree.nodes["Principled Volume"]
    node.inputs["Density Attribute"].default_value = ""
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "density"
    power = tree.nodes.new("ShaderNodeMath")
    power.operation = "POWER"
    power.inputs[1].default_value = 2.0
    tree.links.new(attribute.outputs["Fac"], power.inputs[0])
    tree.links.new(power.outputs[0], node.inputs["Density"])
    file_volume("Squared", path, squared)

    # Emission from the flame grid x 5, and blackbody from temperature x 1500 K.
    fire = principled("Fire", color=(0.5, 0.5, 0.5), density=2.0, Emission_Color=(1.0, 0.5, 0.2, 1.0),
                      Blackbody_Intensity=1.0, Temperature=1500.0)
    tree = fire.node_tree
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "flame"
    scale = tree.nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = 5.0
    tree.links.new(attribute.outputs["Fac"], scale.inputs[0])
    tree.links.new(scale.outputs[0], tree.nodes["Principled Volume"].inputs["Emission Strength"])
    file_volume("Fire", path, fire, space="WORLD")

    # A material that reads only "density" of a file that also holds flame and temperature.
    file_volume("Plain", path, principled("Plain", density=2.0))
    hidden = file_volume("Hidden", path, principled("Hidden"))
    hidden.hide_render = True
    result = export()
    media = media_by_object(result)
    report = {name: keep(f"material.{name}", media[name]) for name in ("Linear", "Squared", "Fire", "Plain")}
    report["names"] = sorted(media)
    report["stats"] = result.volume_stats
    report["warnings"] = result.warnings
    return report


def instance_case():
    """One volume three times (object, two collection instances): one shared density array."""
    empty_scene()
    grids = {"density": smoke_ball_density(11)}
    path = write_grids(OUT / "instanced.vdb", grids, np.diag([0.1, 0.1, 0.1, 1.0]))
    collection = bpy.data.collections.new("Smokes")
    bpy.context.scene.collection.children.link(collection)
    obj = file_volume("Puff", path, principled("Puff"))
    bpy.context.scene.collection.objects.unlink(obj)
    collection.objects.link(obj)
    for index in range(2):
        empty = bpy.data.objects.new(f"Copy{index}", None)
        empty.instance_type = "COLLECTION"
        empty.instance_collection = collection
        empty.location = (2.0 * (index + 1), 0.0, 0.0)
        empty.scale = (2.0, 2.0, 2.0)
        bpy.context.scene.collection.objects.link(empty)
    result = export()
    grids = [m for m in result.scene.media if m.type == "grid"]
    return {"count": len(grids), "shared": all(m.density is grids[0].density for m in grids),
            "scales": [m.scale for m in grids], "names": [m.name for m in grids],
            "boxes": len([m for m in result.scene.meshes if m.medium is not None])}


def bad_case():
    """NaN, negative, empty, missing, grid-less, unreadable-attribute and oversized volumes."""
    empty_scene()
    ball = smoke_ball_density(11)
    infinite = ball.copy()
    infinite[2, 2, 2] = np.inf
    negative = ball - 0.01
    nan_path = write_grids(OUT / "nan.vdb", {"density": infinite}, np.eye(4))
    grid = VDB.read(nan_path, "density")
    grid.getAccessor().setValueOn((5, 5, 5), float("nan"))  # copyFromArray would drop a NaN
    VDB.write(nan_path, grids=[grid])
    file_volume("NaN", nan_path, principled("A"), clipping=0.001)
    file_volume("Negative", write_grids(OUT / "neg.vdb", {"density": negative}, np.eye(4)), principled("B"),
                clipping=0.001)
    file_volume("Faint", write_grids(OUT / "faint.vdb", {"density": ball * 1e-3}, np.eye(4)), principled("C"),
                clipping=0.001)
    file_volume("Missing", str(OUT / "no-such-file.vdb"), principled("D"))
    file_volume("Gridless", "", principled("E"))
    other, tree, output = node_material("Other")
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "smoke"
    scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    tree.links.new(attribute.outputs["Fac"], scatter.inputs["Density"])
    tree.links.new(scatter.outputs[0], output.inputs["Volume"])
    file_volume("Unread", write_grids(OUT / "unread.vdb", {"density": ball}, np.eye(4)), other)
    sparse = np.zeros((2, 2, 2), np.float32)
    sparse[0, 0, 0] = sparse[1, 1, 1] = 1.0
    huge = write_grids(OUT / "huge.vdb", {"density": sparse[:1, :1, :1]}, np.eye(4))
    far = VDB.read(huge, "density")
    far.getAccessor().setValueOn((1200, 1200, 1200), 1.0)
    VDB.write(huge, grids=[far])
    file_volume("Huge", huge, principled("F"))  # read sparsely: two occupied bricks
    file_volume("HugeGlow", huge, principled("G", Emission_Strength=1.0))  # emits where empty: dense
    before = datablock_counts()
    result = export()
    media = media_by_object(result)
    grids = [m.density if isinstance(m.density, np.ndarray) else m.density.bricks for m in media.values()]
    return {"warnings": result.warnings, "media": sorted(media),
            "finite": all(np.isfinite(g).all() and (g >= 0).all() for g in grids),
            "huge": [len(media["Huge"].density.bricks), int(media["Huge"].density.index.size)],
            "cleanup": [before, datablock_counts()]}


def smoke_case():
    """A gas fluid domain read from a synthesised OpenVDB cache file (nothing is simulated)."""
    scene = empty_scene()
    domain, mesh, settings = H.gas_domain(scene, (1.0, 1.0, 1.5), str(OUT / "smoke_cache"), 16,
                                          location=(0.2, 0.0, 0.0))
    settings.flame_ignition, settings.flame_max_temp = 1.5, 3.0
    density, flame = H.fire_grids()
    ARRAYS["smoke.values"], ARRAYS["smoke.flame_values"] = density, flame
    cache = OUT / "smoke_cache" / "data"
    cache.mkdir(parents=True)
    voxel = np.diag([0.1, 0.1, 0.1, 1.0])  # Mantaflow's own transform: the exporter ignores it
    write_grids(cache / "fluid_data_0003.vdb", {"density": density, "flame": flame}, voxel)
    material = principled("Smoke Domain", density=5.0, Blackbody_Intensity=1.0, Temperature=1000.0)
    mesh.materials.append(material)
    scene.frame_set(3)
    result = export()
    media = media_by_object(result)
    report = keep("smoke", media["Domain"]) if "Domain" in media else {}
    ARRAYS["smoke.matrix_world"] = np.array(domain.matrix_world)
    scene.frame_set(4)
    missing = export()
    report["warnings"] = result.warnings
    report["missing_frame"] = missing.warnings
    report["meshes"] = [m.name for m in result.scene.meshes]
    return report


def operators_case():
    """Add > Volume operators: what Haze exports equals the operator's array exactly."""
    empty_scene()
    rng = np.random.default_rng(11)
    grid = (rng.random((5, 6, 7)) + 0.01).astype(np.float32)
    np.save(OUT / "grid.npy", grid)
    write_pbrt(OUT / "grid.pbrt", grid, (0.0, 0.0, 0.0), (1.0, 2.0, 3.0), (0.5, 0.25, 0.1), (2.0, 3.0, 4.0))
    np.save(OUT / "flat.npy", np.zeros((3, 3)))
    ARRAYS["operators.grid"] = grid
    results = {
        "ball": bpy.ops.object.haze_add_smoke_ball(resolution=11, size=1.2),
        "gauss": bpy.ops.object.haze_add_gaussian_smoke(resolution=20, seed=3, blobs=10),
        "npy": bpy.ops.object.haze_import_density_grid(filepath=str(OUT / "grid.npy")),
        "pbrt": bpy.ops.object.haze_import_density_grid(filepath=str(OUT / "grid.pbrt")),
    }
    try:
        results["flat"] = bpy.ops.object.haze_import_density_grid(filepath=str(OUT / "flat.npy"))
    except RuntimeError as error:  # an operator reporting ERROR raises in background mode
        results["flat"] = str(error)
    result = export()
    report = {key: sorted(value) if isinstance(value, set) else value for key, value in results.items()}
    for name, medium in media_by_object(result).items():
        report[name] = keep(f"operators.{name}", medium)
    report["names"] = sorted(media_by_object(result))
    report["warnings"] = result.warnings
    return report


def main():
    report = {}
    for name, case in (("analytic", analytic_case), ("exact", exact_vdb_case),
                       ("render", lambda: render_case("render")),
                       ("cropped", lambda: render_case("cropped", True, 1e-4)),
                       ("uncropped", lambda: render_case("uncropped", False, 1e-4)),
                       ("material", material_case), ("instances", instance_case), ("bad", bad_case),
                       ("smoke", smoke_case), ("operators", operators_case)):
        report[name] = case()
    np.savez(OUT / "arrays.npz", **ARRAYS)
    return json.loads(json.dumps(report, default=lambda o: np.asarray(o).tolist()))
'''


exported = blender_fixture(EXPORT_BODY, "volumes", timeout=900, compiles=False, read=with_arrays)


def placed_in(array: np.ndarray, box: np.ndarray, shape) -> np.ndarray:
    """An exported (cropped, bordered) grid put back at its index position in an array of
    `shape` whose voxel [0, 0, 0] is index (0, 0, 0); voxels outside `shape` must be empty."""
    start = np.round(box[0] + 0.5).astype(int)[::-1]  # (z, y, x) index of array[0, 0, 0]
    border = 2
    out = np.zeros(np.add(shape, 2 * border), np.float32)
    stop = start + array.shape
    assert np.all(start + border >= 0) and np.all(stop <= np.add(shape, border)), (start, array.shape)
    out[tuple(slice(a + border, b + border) for a, b in zip(start, stop))] = array
    inner = out[tuple(slice(border, border + n) for n in shape)]
    assert inner.sum() == out.sum(), "voxels outside the source array"
    return inner


def lattice_positions(lattice: dict, indices: np.ndarray) -> np.ndarray:
    """Object-space positions of Volume Cube voxels (i, j, k): low + index (high - low) / (res - 1)."""
    low, high = np.array(lattice["low"]), np.array(lattice["high"])
    step = (high - low) / (np.array(lattice["resolution"]) - 1)
    return low + indices * step


def analytic_field(positions: np.ndarray) -> np.ndarray:
    x, y, z = positions[..., 0], positions[..., 1], positions[..., 2]
    return 0.5 + x * x + 2.0 * y + 3.0 * z * z


@pytest.mark.bpy
@pytest.mark.parametrize("name", ["Plain", "Turned"])
def test_dense_read_matches_the_field_to_float_precision(exported, name):
    report, arrays = exported
    read = arrays[f"read.{name}"]
    start = arrays[f"read.{name}.start"]
    lattice = report["analytic"]["lattice"]
    nz, ny, nx = read.shape
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    index = np.stack([i, j, k], axis=-1) + start
    resolution = np.array(lattice["resolution"])
    inside = np.all((index >= 0) & (index < resolution), axis=-1)
    expected = analytic_field(lattice_positions(lattice, index))
    scale = np.abs(expected[inside]).max()
    # Blender evaluates the field in float32: a few rounding steps of the largest value.
    assert np.max(np.abs(read[inside] - expected[inside])) <= 8 * FLOAT32_EPS * scale
    assert not read[~inside].any(), "voxels outside the grid must read as its background 0"
    # The sampler's index-to-object matrix is the Volume Cube's lattice.
    np.testing.assert_allclose(arrays[f"read.{name}.index_to_object"] @ [1, 2, 3, 1],
                               [*lattice_positions(lattice, np.array([1, 2, 3])), 1], rtol=1e-6, atol=1e-7)


@pytest.mark.bpy
@pytest.mark.parametrize("name", ["Plain", "Turned"])
def test_exported_grid_sits_where_blender_puts_its_voxels(exported, name):
    """Every exported voxel centre maps to the world position of that voxel (object matrix x
    Volume Cube lattice) and holds the field's value there."""
    report, arrays = exported
    density = arrays[f"analytic.{name}.density"]
    to_world, box = arrays[f"analytic.{name}.to_world"], arrays[f"analytic.{name}.box"]
    matrix_world = arrays[f"analytic.{name}.matrix_world"]
    lattice = report["analytic"]["lattice"]
    nz, ny, nx = density.shape
    k, j, i = np.meshgrid(np.arange(nz), np.arange(ny), np.arange(nx), indexing="ij")
    voxel = np.stack([i, j, k], axis=-1).reshape(-1, 3)
    local = box[0] + (voxel + 0.5) * (box[1] - box[0]) / np.array([nx, ny, nz])  # Haze's voxel centres
    world = (np.c_[local, np.ones(len(local))] @ to_world.T)[:, :3]
    index = np.round(local).astype(int)  # the exporter's local space is the grid's index space
    np.testing.assert_allclose(local, index, atol=1e-9)
    blender = (np.c_[lattice_positions(lattice, index), np.ones(len(index))] @ matrix_world.T)[:, :3]
    np.testing.assert_allclose(world, blender, atol=1e-5)
    inside = np.all((index >= 0) & (index < np.array(lattice["resolution"])), axis=1)
    expected = analytic_field(lattice_positions(lattice, index[inside]))
    values = density.reshape(-1)
    np.testing.assert_allclose(values[inside], expected, rtol=8 * FLOAT32_EPS, atol=0)
    assert not values[~inside].any(), "the one-voxel border around the grid must be empty"
    assert report["analytic"]["cleanup"][0] == report["analytic"]["cleanup"][1], \
        "the sampler must leave no datablock behind"


@pytest.mark.bpy
def test_vdb_arrays_come_back_bit_for_bit(exported):
    report, arrays = exported
    values, density = arrays["exact.values"], arrays["exact.density"]
    assert density.shape == tuple(s + 2 for s in values.shape)
    np.testing.assert_array_equal(density[1:-1, 1:-1, 1:-1], values)
    box = arrays["exact.box"]
    np.testing.assert_allclose(box[0], np.array([2, 3, 4]) - 1.5)  # one empty voxel before index (2, 3, 4)
    expected = arrays["exact.matrix_world"] @ arrays["exact.transform"]
    np.testing.assert_allclose(arrays["exact.to_world"], expected, rtol=1e-6, atol=1e-7)
    # Principled Volume, Color 0.5, Density 1, black absorption; object scale (1, 2, 0.5).
    factor = 1.0 / np.linalg.norm(np.diag([1.0, 2.0, 0.5]) @ np.ones(3) / math.sqrt(3.0))
    assert report["exact"]["scale"] == pytest.approx(factor, rel=1e-5)
    np.testing.assert_allclose(report["exact"]["sigma_s"], [0.5] * 3, rtol=1e-6)
    np.testing.assert_allclose(report["exact"]["sigma_a"], [0.5] * 3, rtol=1e-6)


@pytest.mark.bpy
def test_materials_map_to_the_grid_as_cycles_shades_them(exported):
    report, arrays = exported
    material = report["material"]
    density, flame = arrays["material.density"], arrays["material.flame"]
    temperature = arrays["material.temperature"]
    interior = (slice(1, -1),) * 3
    f32 = lambda v: np.float64(np.float32(v))  # noqa: E731 - Blender stores inputs as float32
    # Scatter (Color x grid x 7) + Absorption ((1 - Color) x grid x 3): the grid itself.
    np.testing.assert_array_equal(arrays["material.Linear.density"][interior], density)
    np.testing.assert_allclose(material["Linear"]["sigma_s"], [f32(0.2) * 7, f32(0.4) * 7, f32(0.6) * 7],
                               rtol=1e-6)
    np.testing.assert_allclose(material["Linear"]["sigma_a"], [1.5, 2.25, 3.0], rtol=1e-6)
    # Principled Density = grid^2 (Math Power): applied per voxel, which is what Cycles'
    # stochastic (one voxel per lookup) interpolation renders on average.
    field = arrays["material.Squared.density"][interior][..., None].astype(np.float64)
    color = np.array([0.25, 0.5, 1.0])
    squared = density.astype(np.float64)[..., None] ** 2
    np.testing.assert_allclose(field * material["Squared"]["sigma_s"], squared * color, rtol=1e-5, atol=1e-9)
    np.testing.assert_allclose(field * material["Squared"]["sigma_a"], squared * (1 - color), rtol=1e-5,
                               atol=1e-9)
    # Emission Strength = flame x 5, Emission Color (1, 0.5, 0.2): the flame grid scales it.
    np.testing.assert_array_equal(arrays["material.Fire.flame"][interior], flame)
    np.testing.assert_allclose(material["Fire"]["emission"], [5.0, 2.5, f32(0.2) * 5.0], rtol=1e-6)
    # Blackbody: Temperature 1500 x the temperature grid, intensity 1.
    np.testing.assert_allclose(arrays["material.Fire.temperature"][interior], 1500.0 * temperature, rtol=1e-6)
    assert material["Fire"]["blackbody"] == 1.0
    # Grids no material reads are not read; hidden volumes are not exported.
    assert material["names"] == ["Fire", "Linear", "Plain", "Squared"]
    plain = [line for line in material["stats"] if line.startswith("Object 'Plain'")]
    assert len(plain) == 1 and "density grid" in plain[0]
    assert "material.Plain.flame" not in arrays and "material.Plain.temperature" not in arrays


@pytest.mark.bpy
def test_instances_share_one_grid(exported):
    instances = exported[0]["instances"]
    assert instances["count"] == 3 and instances["boxes"] == 3
    assert instances["shared"], "instances of one volume must share its density array"
    assert len(set(instances["names"])) == 3
    assert sorted(instances["scales"]) == pytest.approx([0.5, 0.5, 1.0])  # scale 2 halves the density


@pytest.mark.bpy
def test_bad_volumes_warn_by_name_and_do_not_stop_the_export(exported):
    bad = exported[0]["bad"]
    text = "\n".join(bad["warnings"])
    expectations = {
        "NaN": "2 NaN or infinite voxel",
        "Negative": "negative voxel values",
        "Faint": "no voxels above the clipping value",
        "Missing": "has no grids",
        "Gridless": "has no grids",
        "Unread": "reads none of its grids",
        "HugeGlow": "more than Haze's dense grids hold",
    }
    for name, problem in expectations.items():
        assert any(line.startswith(f"Object '{name}'") and problem in line for line in bad["warnings"]), \
            f"{name}: {problem}\n{text}"
    assert bad["media"] == ["Huge", "NaN", "Negative"], "only the volumes with usable voxels are rendered"
    # A 1201^3 box with two voxels: read sparsely, 2 bricks stored (and their lower neighbours,
    # whose apron holds a voxel), never the dense box.
    stored, lattice = bad["huge"]
    assert stored <= 16 and lattice > 150**3
    assert bad["finite"]
    assert bad["cleanup"][0] == bad["cleanup"][1]


@pytest.mark.bpy
def test_smoke_domain_reads_its_cache_file(exported):
    report, arrays = exported
    smoke = report["smoke"]
    assert "smoke.density" in arrays, smoke["warnings"]
    values, density = arrays["smoke.values"], arrays["smoke.density"]
    box = arrays["smoke.box"]
    np.testing.assert_array_equal(placed_in(density, box, values.shape), values)
    # Cell (i, j, k) centred at (i + 0.5) / res of the domain box [-1, 1]^2 x [0, 2], object space.
    to_world = arrays["smoke.to_world"]
    centre = to_world @ [0.0, 0.0, 0.0, 1.0]
    expected = arrays["smoke.matrix_world"] @ [-1 + 1 / 11, -1 + 1 / 11, 1 / 16, 1]
    np.testing.assert_allclose(centre, expected, atol=1e-6)
    # Temperature attribute: ignition + flame x (max - ignition) where flame > 0.01, x 1000.
    flame = arrays["smoke.flame_values"]
    expected_t = 1000.0 * np.where(flame > 0.01, 1.5 + flame * 1.5, 0.0)
    temperature = placed_in(arrays["smoke.temperature"], box, values.shape)
    np.testing.assert_allclose(temperature, expected_t, rtol=1e-6)
    assert smoke["scale"] == 1.0  # smoke domains have no object density factor
    assert "Domain" not in smoke["meshes"], "a smoke domain renders as a volume, not as its mesh box"
    assert any("no cached smoke for frame 4" in line for line in smoke["missing_frame"])


@pytest.mark.bpy
def test_operators_export_their_arrays_exactly(exported):
    report, arrays = exported
    operators = report["operators"]
    for key in ("ball", "gauss", "npy", "pbrt"):
        assert operators[key] == ["FINISHED"], (key, operators[key])
    assert "flat" in operators and "3-D" in str(operators["flat"])
    expected = {
        "Smoke Ball": smoke_ball_density(11),
        "Gaussian Smoke": gaussian_smoke_density(20, 3, 10),
        "grid": arrays["operators.grid"],
    }
    names = operators["names"]
    assert names.count("grid") == 1 and len(names) == 4, names
    for name in names:
        reference = expected["grid" if name.startswith("grid") else name]
        exported_grid = placed_in(arrays[f"operators.{name}.density"], arrays[f"operators.{name}.box"],
                                  reference.shape)
        np.testing.assert_array_equal(exported_grid, reference, err_msg=name)
    # The pbrt import (the second "grid"): Volume Scatter + Absorption give the file's sigmas.
    np.testing.assert_allclose(operators["grid.001"]["sigma_s"], [2.0, 3.0, 4.0], rtol=1e-6)
    np.testing.assert_allclose(operators["grid.001"]["sigma_a"], [0.5, 0.25, 0.1], rtol=1e-6)


# ------------------------------------------------------------------------------ renders


def reference_scene(report: dict, arrays: dict, name: str):
    """The exported render scene with its volume replaced by the same grid written directly:
    the Fig. 3 ball filling the object's box, placed by the object's matrix, sigmas from
    Principled Volume's formulas."""
    scene = load_scene(report[name]["folder"])
    color = np.float64(np.float32([0.3, 0.5, 0.7]))
    density = np.float64(np.float32(20.0))
    p0, p1 = arrays[f"{name}.object_box"]
    medium = Medium("reference", "grid", sigma_a=tuple((1.0 - color) * density),
                    sigma_s=tuple(color * density), g=float(np.float32(0.2)), density=smoke_ball_density(11),
                    p0=tuple(p0), p1=tuple(p1), to_world=arrays[f"{name}.matrix_world"])
    exported_medium = next(m for m in scene.media if m.type == "grid")
    scene.media = [m for m in scene.media if m is not exported_medium] + [medium]
    scene.materials.append(Material("reference boundary"))
    for mesh in scene.meshes:
        if mesh.medium == exported_medium.name:
            # The export's boundary stops at the empty border voxels' centres (the ball's faces
            # are 0): half a voxel inside the grid box.
            half = 0.5 * (np.asarray(p1) - np.asarray(p0)) / np.array(medium.density.shape[::-1])
            boundary = box_mesh("reference boundary", "reference", p0 + half, p1 - half, medium.to_world)
            mesh.vertices, mesh.indices, mesh.medium = boundary.vertices, boundary.indices, "reference"
            mesh.materials, mesh.material_ids = ["reference boundary"], None
    return scene, exported_medium, medium


@pytest.mark.bpy
@pytest.mark.slow
def test_volume_object_renders_like_the_scene_format(exported):
    report, arrays = exported
    scene, exported_medium, medium = reference_scene(report, arrays, "render")
    np.testing.assert_array_equal(exported_medium.density, medium.density)
    np.testing.assert_allclose(exported_medium.sigma_s, medium.sigma_s, rtol=1e-6)
    np.testing.assert_allclose(exported_medium.sigma_a, medium.sigma_a, rtol=1e-6)
    rng = np.random.default_rng(12)
    points = (np.c_[rng.uniform(-0.7, 0.7, (20000, 3)), np.ones(20000)] @ medium.to_world.T)[:, :3]
    np.testing.assert_allclose(grid_density(exported_medium, points), grid_density(medium, points),
                               rtol=1e-4, atol=1e-6)
    original = load_scene(report["render"]["folder"])
    for candidate in (original, scene):
        candidate.integrator.spp, candidate.integrator.seed = 32, 7
    image_exported, image_reference = render(original), render(scene)
    assert image_reference.mean() > 1e-3, "the reference render is black: the scene is broken"
    # Same seed, same grid: the images differ only by float rounding in the two placements.
    # (measured: at most 3e-8 apart, pixel values up to 0.5).
    difference = np.abs(image_exported - image_reference)
    assert difference.max() <= 1e-5 * image_reference.max(), difference.max()


@pytest.mark.bpy
@pytest.mark.slow
def test_cropping_keeps_the_image_and_saves_memory(exported):
    report, arrays = exported
    cropped, uncropped = arrays["cropped.density"], arrays["uncropped.density"]
    assert cropped.nbytes * 10 < uncropped.nbytes, (cropped.shape, uncropped.shape)
    assert "MB" in report["cropped"]["stats"][0] and "before cropping" in report["cropped"]["stats"][0]
    scenes = {name: load_scene(report[name]["folder"]) for name in ("cropped", "uncropped")}
    media = {name: next(m for m in s.media if m.type == "grid") for name, s in scenes.items()}
    rng = np.random.default_rng(13)
    to_world = media["uncropped"].to_world
    np.testing.assert_allclose(media["cropped"].to_world, to_world)  # both in the grid's index space
    box = np.array([media["cropped"].p0, media["cropped"].p1])
    local = rng.uniform(box[0] - 2.0, box[1] + 2.0, (30000, 3))  # the ball and empty voxels around it
    points = (np.c_[local, np.ones(len(local))] @ to_world.T)[:, :3]
    field_cropped = grid_density(media["cropped"], points)
    field_full = grid_density(media["uncropped"], points)
    assert np.count_nonzero(field_full) > 1000
    np.testing.assert_allclose(field_cropped, field_full, rtol=1e-5, atol=1e-7)
    runs = {}
    for name, scene in scenes.items():
        images = []
        for seed in range(4):
            scene.integrator.spp, scene.integrator.seed = 64, 100 + seed
            images.append(render(scene))
        runs[name] = np.stack(images)
    assert_agree(compare_images(runs["cropped"], runs["uncropped"]))


# ------------------------------------------------------------------------------ Haze vs Cycles

CYCLES_RUNS = 4
CYCLES_SIZE = 32
CYCLES_SAMPLES = (512, 1024)  # Cycles, Haze per run: noise on the mean ~0.2 % (measured)
CYCLES_BOUNCES = 3

CYCLES_BODY = r'''
import math
import bpy
import numpy as np
from pathlib import Path
import bpy_helpers as H
import blender_gallery as G

RUNS, SIZE, SAMPLES, BOUNCES = {runs}, {size}, {samples}, {bounces}


def main():
    H.enable_addon()
    scene = G.smoke_ball(SIZE, Path(os.getcwd()) / "volumes", bounces=BOUNCES)
    paths = H.render_both(scene, os.getcwd(), RUNS, SAMPLES[0], SAMPLES[1], BOUNCES)
    # A render of broken volumes through the engine must finish (warnings, no crash).
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    scene = G.smoke_ball(16, Path(os.getcwd()) / "volumes", bounces=1)
    broken = bpy.data.volumes.new("Broken")
    broken.filepath = "/nonexistent/broken.vdb"
    scene.collection.objects.link(bpy.data.objects.new("Broken", broken))
    H.configure_haze(scene, 4, 1, 1)
    paths["broken"] = H.render_exr(scene, os.path.join(os.getcwd(), "broken.exr"))
    return paths
'''


@pytest.mark.bpy
@pytest.mark.slow
def test_smoke_ball_volume_agrees_with_cycles(tmp_path):
    body = CYCLES_BODY.format(runs=CYCLES_RUNS, size=CYCLES_SIZE, samples=CYCLES_SAMPLES,
                              bounces=CYCLES_BOUNCES)
    run = blender_result(body, tmp_path, timeout=1800)
    haze = np.stack([read_exr(p) for p in run.result["haze"]])
    cycles = np.stack([read_exr(p) for p in run.result["cycles"]])
    assert haze.shape == cycles.shape == (CYCLES_RUNS, CYCLES_SIZE, CYCLES_SIZE, 3)
    assert cycles.mean() > 0.01, "the Cycles image is black: the scene is broken"
    assert_agree(compare_images(haze, cycles))
    broken = read_exr(run.result["broken"])
    assert np.isfinite(broken).all() and broken.mean() > 0.0
    assert "Object 'Broken'" in run.stdout + run.stderr



# Fire: a Principled Volume with blackbody emission from a temperature grid (3000-4500 K in its
# inner 4^3 voxels, 0 around them), seen directly and lighting a wall behind it. Haze used to
# interpolate the temperature between voxels, while Cycles samples the grid stochastically (one
# voxel picked with the trilinear weights), i.e. interpolates the voxels' emission: Haze's fire
# and wall came out 35-52 % darker here. The fire stays one voxel inside the smoke's active
# voxels: where emission reaches the last active voxel, Cycles renders the faint tail of the
# fire's silhouette up to ~2x dimmer (about -1 % of a whole fire's light, measured), a
# volume-bounds effect not modelled by Haze.
FIRE_RUNS = 4
FIRE_SIZE = 24
FIRE_SAMPLES = (2048, 2048)  # Cycles, Haze per run
FIRE_BODY = r'''
import bpy
import numpy as np
from pathlib import Path
import bpy_helpers as H
import blender_cornell as C

RUNS, SIZE, SAMPLES = {runs}, {size}, {samples}


def fire_scene(folder):
    add_volume_object = H.addon_module("operators_volume").add_volume_object

    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    scene = bpy.context.scene
    C.black_world(scene)
    C.quad("Wall", [(-2, 0.45, -2), (2, 0.45, -2), (2, 0.45, 2), (-2, 0.45, 2)],
           C.diffuse_material("Wall", (0.8, 0.8, 0.8)))
    C.add_camera(scene, (0.0, -3.0, 0.0), (90.0, 0.0, 0.0), lens=50.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    material, tree, output = C.node_material("Fire")
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    node.inputs["Density"].default_value = 3.0
    node.inputs["Absorption Color"].default_value = (0.0, 0.0, 0.0, 1.0)
    node.inputs["Blackbody Intensity"].default_value = 1.0
    node.inputs["Temperature"].default_value = 1.0  # times the grid: kelvin
    tree.links.new(node.outputs[0], output.inputs["Volume"])
    n = 8
    z, y, x = np.meshgrid(*(np.arange(n),) * 3, indexing="ij")
    inside = np.zeros((n, n, n), np.float32)
    inside[1:-1, 1:-1, 1:-1] = 1.0
    hot = np.zeros((n, n, n), np.float32)  # one voxel inside the smoke (see above)
    hot[2:-2, 2:-2, 2:-2] = 1.0
    temperature = (3000.0 + 1500.0 * x / (n - 1)) * hot
    grids = {{"density": inside, "temperature": temperature.astype(np.float32)}}
    add_volume_object(bpy.context, "Fire", grids, (-0.3,) * 3, (0.3,) * 3, material, folder)
    return scene


def main():
    folder = Path(os.getcwd()) / "volumes"
    folder.mkdir()
    scene = fire_scene(folder)
    return H.render_both(scene, os.getcwd(), RUNS, SAMPLES[0], SAMPLES[1], 0)  # the wall: direct light
'''


@pytest.mark.bpy
@pytest.mark.slow
def test_fire_volume_lights_a_wall_like_cycles(tmp_path):
    body = FIRE_BODY.format(runs=FIRE_RUNS, size=FIRE_SIZE, samples=FIRE_SAMPLES)
    run = blender_result(body, tmp_path, timeout=1800)
    haze = np.stack([read_exr(p) for p in run.result["haze"]])
    cycles = np.stack([read_exr(p) for p in run.result["cycles"]])
    assert cycles.mean() > 1e-4, "the Cycles image is black: the scene is broken"
    fire = np.zeros((FIRE_SIZE, FIRE_SIZE), bool)
    fire[FIRE_SIZE // 3: -(FIRE_SIZE // 3), FIRE_SIZE // 3: -(FIRE_SIZE // 3)] = True
    print("whole image:", compare_images(haze, cycles).summary())
    for name, images in (("haze", haze), ("cycles", cycles)):
        means = images.mean(axis=(1, 2))
        noise = means.std(0, ddof=1) / np.sqrt(len(means)) / means.mean(0)
        print(name, "mean", means.mean(0), "relative noise", noise)
    for name, mask in (("fire", fire), ("wall", ~fire)):
        h, c = haze[:, mask].mean(axis=1), cycles[:, mask].mean(axis=1)
        print(f"{name}: haze/cycles {h.mean(0) / c.mean(0)} +- "
              f"{np.sqrt(h.var(0, ddof=1) / len(h) + c.var(0, ddof=1) / len(c)) / c.mean(0)}")
    assert_agree(compare_images(haze, cycles))


# Fire resting on a floor: the grid's box (cropped to the fire's voxels plus one empty voxel)
# has its bottom face in the floor's plane. Haze's invisible boundary box used to be that grid
# box, so a ray reaching the floor under the fire met the floor and the boundary at the same
# distance; when the boundary won, the path left the fire below the floor and was lost (the
# gallery's fire_ball lost 3-4 % of its wall light this way, at 0.01 above the floor none).
# The boundary now stops at the border voxels' centres, where the medium is already 0.
FLOOR_FIRE_BODY = FIRE_BODY.replace(
    "RUNS, SIZE, SAMPLES", "BOUNCES = {bounces}\nRUNS, SIZE, SAMPLES"
).replace(
    "    return H.render_both(scene, os.getcwd(), RUNS, SAMPLES[0], SAMPLES[1], 0)",
    "    C.quad('Floor', [(-2, -2, -0.3), (2, -2, -0.3), (2, 2, -0.3), (-2, 2, -0.3)],\n"
    "           C.diffuse_material('Floor', (0.8, 0.8, 0.8)))\n"
    "    camera = scene.camera\n"
    "    camera.location, camera.rotation_euler = (0.0, -2.6, 1.2), (math.radians(62.0), 0.0, 0.0)\n"
    "    return H.render_both(scene, os.getcwd(), RUNS, SAMPLES[0], SAMPLES[1], BOUNCES)").replace(
    "import bpy\n", "import bpy\nimport math\n", 1)
FLOOR_FIRE_RUNS = 4
FLOOR_FIRE_SAMPLES = (2048, 2048)


@pytest.mark.bpy
@pytest.mark.slow
def test_fire_on_a_floor_lights_it_like_cycles(tmp_path):
    body = FLOOR_FIRE_BODY.format(runs=FLOOR_FIRE_RUNS, size=FIRE_SIZE, samples=FLOOR_FIRE_SAMPLES, bounces=1)
    assert "Floor" in body and "BOUNCES = 1" in body
    run = blender_result(body, tmp_path, timeout=1800)
    haze = np.stack([read_exr(p) for p in run.result["haze"]])
    cycles = np.stack([read_exr(p) for p in run.result["cycles"]])
    assert cycles.mean() > 1e-4, "the Cycles image is black: the scene is broken"
    comparison = compare_images(haze, cycles)
    print(comparison.summary())
    assert_agree(comparison)
