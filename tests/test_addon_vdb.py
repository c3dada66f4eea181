"""Volume objects loading .vdb files: read sparsely into bricks (addon/export/vdb_reader.py),
and .vdb sequences rendered with the frame's file.

One Blender run (module fixture) writes small .vdb files with Blender's openvdb module,
exports them with the add-on and hands back arrays: the sparse read must equal the
geometry-node sampler's dense read voxel for voxel (same file values, same placement,
same coefficients), and a two-frame sequence must export each frame's own grid.
"""

from __future__ import annotations

import numpy as np
import pytest

from helpers.blender_runs import blender_fixture, with_arrays

BODY = r'''
from pathlib import Path

import numpy as np
import bpy

import bpy_helpers as H
import blender_cornell as C

H.enable_addon()
V = H.addon_module("export.volume_read")
export_scene = H.addon_module("export.scene").export_scene
import_openvdb = H.addon_module("volume_grids").import_openvdb

VDB = import_openvdb()
ARRAYS = {}


def write_grid(path, values, index_to_object, start, more=()):
    """A .vdb file of the density grid `values` and `more` (name, values) grids beside it."""
    grids = []
    for name, data in (("density", values),) + tuple(more):
        grid = VDB.FloatGrid()
        grid.copyFromArray(np.ascontiguousarray(data.transpose(2, 1, 0)), ijk=tuple(start), tolerance=0.0)
        grid.name = name
        grid.transform = VDB.createLinearTransform(np.asarray(index_to_object).T.tolist())
        grids.append(grid)
    VDB.write(str(path), grids=grids)
    return str(path)


def cloud(shape, seed):
    """Two lumps of noisy density in a mostly empty box: many empty bricks."""
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    lumps = np.zeros(shape)
    for c in rng.uniform(0.25, 0.75, (2, 3)) * np.array(shape):
        r2 = ((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2) / (0.15 * min(shape)) ** 2
        lumps += np.exp(-r2)
    values = lumps * rng.uniform(0.5, 1.5, shape)
    return np.where(values > 0.05, values, 0.0).astype(np.float32)


def principled(name):
    material, tree, output = C.node_material(name)
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    node.inputs["Color"].default_value = (0.7, 0.5, 0.3, 1.0)
    node.inputs["Density"].default_value = 2.0
    tree.links.new(node.outputs[0], output.inputs["Volume"])
    return material


def fire(name):
    """A fire's material: Principled Volume with the flame grid as Emission Strength and
    blackbody emission from the temperature grid (x 1500 K)."""
    material = principled(name)
    tree = material.node_tree
    node = tree.nodes["Principled Volume"]
    node.inputs["Emission Color"].default_value = (1.0, 0.6, 0.2, 1.0)
    node.inputs["Blackbody Intensity"].default_value = 1.0
    node.inputs["Temperature"].default_value = 1500.0
    flame = tree.nodes.new("ShaderNodeAttribute")
    flame.attribute_name = "flame"
    tree.links.new(flame.outputs["Fac"], node.inputs["Emission Strength"])
    return material


def smoke_domain(transform):
    """A fire's gas domain (2 x 2 x 3 box, resolution 16) with a synthesised cache file for
    frame 3 (density and flame; nothing is simulated); its material reads the density and
    the temperature Cycles derives from the flame."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    scene = bpy.context.scene
    C.add_camera(scene, (0.0, -4.0, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    _, mesh, settings = H.gas_domain(scene, (1.0, 1.0, 1.5), str(Path("smoke_cache").resolve()), 16)
    settings.flame_ignition, settings.flame_max_temp = 1.5, 3.0
    density, flame = H.fire_grids()
    ARRAYS["smoke.values"] = density
    Path("smoke_cache/data").mkdir(parents=True)
    write_grid("smoke_cache/data/fluid_data_0003.vdb", density, transform, (0, 0, 0), (("flame", flame),))
    material = principled("Smoke Domain")
    node = material.node_tree.nodes["Principled Volume"]
    node.inputs["Blackbody Intensity"].default_value = 1.0
    node.inputs["Temperature"].default_value = 1000.0
    mesh.materials.append(material)
    scene.frame_set(3)


def volume_object(name, path, material):
    volume = bpy.data.volumes.new(name)
    volume.filepath = path
    volume.render.clipping = 0.1
    volume.materials.append(material)
    obj = bpy.data.objects.new(name, volume)
    bpy.context.scene.collection.objects.link(obj)
    obj.rotation_euler = (0.2, -0.4, 0.9)
    obj.scale = (1.0, 1.5, 0.8)
    return obj


def export():
    return export_scene(bpy.context.evaluated_depsgraph_get(), render_depsgraph=False)


def medium_arrays(prefix, result):
    (medium,) = result.scene.media
    density = medium.density
    ARRAYS[prefix + ".sparse"] = np.array(not isinstance(density, np.ndarray))
    ARRAYS[prefix + ".density"] = density if isinstance(density, np.ndarray) else density.to_dense()
    if not isinstance(density, np.ndarray):
        ARRAYS[prefix + ".bricks"] = np.array([len(density.bricks), density.index.size])
    for name in ("flame", "temperature"):
        grid = getattr(medium, name)
        if grid is not None:
            ARRAYS[f"{prefix}.{name}"] = grid if isinstance(grid, np.ndarray) else grid.to_dense()
    ARRAYS[prefix + ".blackbody"] = np.array(medium.blackbody_intensity)
    ARRAYS[prefix + ".p0"] = np.array(medium.p0)
    ARRAYS[prefix + ".to_world"] = medium.to_world
    ARRAYS[prefix + ".coefficients"] = np.array([medium.sigma_a, medium.sigma_s, medium.emission])
    ARRAYS[prefix + ".scale_g"] = np.array([medium.scale, medium.g])
    mesh = [m for m in result.scene.meshes if m.medium == medium.name][0]
    ARRAYS[prefix + ".boundary"] = np.array(mesh.vertices)
    return result.warnings


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    C.add_camera(bpy.context.scene, (0.0, -4.0, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    report = {}
    transform = np.array([[0.05, 0.01, 0.0, 0.3], [0.0, 0.06, 0.01, -0.2], [0.0, 0.0, 0.04, 0.1],
                          [0, 0, 0, 1]])
    values = cloud((21, 26, 30), 4)
    ARRAYS["values"] = values
    path = write_grid(str(Path("cloud.vdb").resolve()), values, transform, (-7, 5, 11))
    volume_object("Cloud", path, principled("Cloud"))
    V.SPARSE_MIN_VOXELS = 0
    report["sparse"] = medium_arrays("sparse", export())
    V.SPARSE_MIN_VOXELS = 1 << 62
    report["dense"] = medium_arrays("dense", export())
    # The same volume through a geometry-nodes modifier that passes it on: no longer a file
    # Haze reads, so the sampler reads it, into bricks one row at a time (sampled_bricks).
    tree = bpy.data.node_groups.new("Pass", "GeometryNodeTree")
    tree.interface.new_socket("Geometry", in_out="INPUT", socket_type="NodeSocketGeometry")
    tree.interface.new_socket("Geometry", in_out="OUTPUT", socket_type="NodeSocketGeometry")
    tree.links.new(tree.nodes.new("NodeGroupInput").outputs[0], tree.nodes.new("NodeGroupOutput").inputs[0])
    bpy.data.objects["Cloud"].modifiers.new("Pass", "NODES").node_group = tree
    V.SPARSE_MIN_VOXELS = 0
    report["sampled"] = medium_arrays("sampled", export())
    # A fire: density, flame and temperature grids (the flame and heat inside the smoke).
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    C.add_camera(bpy.context.scene, (0.0, -4.0, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    flame = np.where(values > 0.8, values - 0.5, 0.0).astype(np.float32)
    ARRAYS["fire.flame"], ARRAYS["fire.temperature"] = flame, (0.5 * values).astype(np.float32)
    path = write_grid(str(Path("fire.vdb").resolve()), values, transform, (-7, 5, 11),
                      (("flame", flame), ("temperature", ARRAYS["fire.temperature"])))
    volume_object("Fire", path, fire("Fire"))
    V.SPARSE_MIN_VOXELS = 0
    report["fire_sparse"] = medium_arrays("fire_sparse", export())
    V.SPARSE_MIN_VOXELS = 1 << 62
    report["fire_dense"] = medium_arrays("fire_dense", export())
    smoke_domain(transform)
    for kind, least in (("sparse", 0), ("dense", 1 << 62)):
        V.SPARSE_MIN_VOXELS = least
        report[f"smoke_{kind}"] = medium_arrays(f"smoke_{kind}", export())
    # A two-frame sequence: frame f loads seq_000f.vdb (another cloud each).
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    C.add_camera(bpy.context.scene, (0.0, -4.0, 1.0), (90.0, 0.0, 0.0), lens=35.0)
    for frame in (1, 2):
        ARRAYS[f"seq{frame}.values"] = cloud((18, 16, 20), 10 + frame)
        write_grid(f"seq_000{frame}.vdb", ARRAYS[f"seq{frame}.values"], transform, (0, 0, 0))
    obj = volume_object("Sequence", str(Path("seq_0001.vdb").resolve()), principled("Sequence"))
    obj.data.is_sequence = True
    obj.data.frame_start, obj.data.frame_duration = 1, 2
    V.SPARSE_MIN_VOXELS = 0
    for frame in (1, 2):
        bpy.context.scene.frame_set(frame)
        report[f"seq{frame}"] = medium_arrays(f"seq{frame}", export())
    # Frame 3 of a three-frame sequence whose third file is missing: Blender loads no grids
    # (Cycles renders nothing there), so Haze renders nothing and says why, never a
    # neighbouring frame's file.
    obj.data.frame_duration = 3
    bpy.context.scene.frame_set(3)
    missing = export()
    grids = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data.grids
    report["seq_missing"] = {"media": len(missing.scene.media), "warnings": missing.warnings,
                             "grids": len(grids)}
    np.savez("arrays.npz", **ARRAYS)
    return report
'''


exported = blender_fixture(BODY, "vdb", timeout=600, compiles=False, read=with_arrays)


def placed(arrays, prefix, start, shape, pad=4, name="density"):
    """The exported grid `name` put at its index position on a canvas whose voxel [pad, pad,
    pad] is index `start` (x, y, z) and which reaches `pad` voxels past `shape`."""
    density = arrays[f"{prefix}.{name}"]
    first = np.round(arrays[f"{prefix}.p0"] + 0.5).astype(int)[::-1] - np.asarray(start)[::-1] + pad
    out = np.zeros(np.add(shape, 2 * pad), np.float32)
    assert np.all(first >= 0) and np.all(first + density.shape <= out.shape), (first, density.shape)
    out[tuple(slice(a, a + n) for a, n in zip(first, density.shape))] = density
    return out


def written(values, pad=4):
    """The file's values as the volume renders them (clipping 0.1) on placed()'s canvas."""
    return np.pad(np.where(values >= 0.1, values, 0.0).astype(np.float32), pad)


@pytest.mark.bpy
def test_sparse_read_equals_the_samplers_dense_read(exported):
    """The same Volume object read sparsely (bricks from the file) and by the sampler
    (dense, cropped): the same voxels bit for bit at the same index positions, the same
    transform, coefficients and boundary box, no warnings."""
    report, arrays = exported
    assert arrays["sparse.sparse"] and not arrays["dense.sparse"]
    values = arrays["values"]
    for prefix in ("sparse", "dense"):
        np.testing.assert_array_equal(placed(arrays, prefix, (-7, 5, 11), values.shape), written(values))
        assert report[prefix] == []
    for key in ("to_world", "coefficients", "scale_g"):
        np.testing.assert_allclose(arrays[f"sparse.{key}"], arrays[f"dense.{key}"], rtol=1e-6, atol=1e-9)
    # p0 differs only by the crop (the dense path crops to the non-zero voxels); the
    # boundary boxes both stop at the outermost non-zero voxels' neighbours' centres.
    stored, total = arrays["sparse.bricks"]
    assert 0 < stored < total  # empty bricks are not stored


@pytest.mark.bpy
def test_sampler_reads_a_node_volume_into_bricks(exported):
    """A volume that is not a file (here the file's volume passed through a geometry-nodes
    modifier) is read by the geometry-node sampler brick row by brick row: the same voxels
    at the same index positions as the file holds, the same transform and coefficients,
    empty bricks not kept. (Its index box comes from the evaluated volume's bounds, a few
    voxels wider than the file's.)"""
    report, arrays = exported
    assert arrays["sampled.sparse"]
    values = arrays["values"]
    np.testing.assert_array_equal(placed(arrays, "sampled", (-7, 5, 11), values.shape, pad=12),
                                  written(values, pad=12))
    assert report["sampled"] == []
    for key in ("to_world", "coefficients", "scale_g"):
        np.testing.assert_allclose(arrays[f"sampled.{key}"], arrays[f"sparse.{key}"], rtol=1e-6, atol=1e-9)
    stored, total = arrays["sampled.bricks"]
    assert 0 < stored < total


@pytest.mark.bpy
def test_vdb_sequence_exports_each_frames_file(exported):
    report, arrays = exported
    for frame in (1, 2):
        values = arrays[f"seq{frame}.values"]
        assert arrays[f"seq{frame}.sparse"]
        np.testing.assert_array_equal(placed(arrays, f"seq{frame}", (0, 0, 0), values.shape), written(values))
    assert not np.array_equal(arrays["seq1.density"], arrays["seq2.density"])


@pytest.mark.bpy
def test_a_missing_sequence_frame_renders_nothing_and_says_so(exported):
    missing = exported[0]["seq_missing"]
    assert missing["grids"] == 0  # Blender itself loads nothing for the frame
    assert missing["media"] == 0
    assert missing["warnings"] == ["Object 'Sequence': has no grids (an empty volume or a file that did not "
                                   "load); it is not rendered"]


def test_a_fire_is_read_sparsely_as_the_sampler_reads_it(exported):
    """A .vdb fire (density, flame and temperature grids; flame as Emission Strength,
    blackbody from the temperature): read into bricks, flame and temperature included, with
    every voxel of the three grids equal to the sampler's dense read, and the same constants."""
    report, arrays = exported
    assert arrays["fire_sparse.sparse"] and not arrays["fire_dense.sparse"]
    values = arrays["values"]

    def grid(prefix, name):
        return placed(arrays, prefix, (-7, 5, 11), values.shape, name=name)

    assert report["fire_sparse"] == report["fire_dense"]  # the object's scale on the blackbody: the same
    for name in ("density", "flame", "temperature"):
        np.testing.assert_array_equal(grid("fire_sparse", name), grid("fire_dense", name))
    np.testing.assert_array_equal(grid("fire_sparse", "density"), written(values))
    flame = np.pad(np.where(values >= 0.1, arrays["fire.flame"], 0.0).astype(np.float32), 4)
    np.testing.assert_array_equal(grid("fire_sparse", "flame"), flame)
    heat = arrays["fire.temperature"]
    kelvin = (1500.0 * np.where(heat >= 0.1, heat, 0.0).astype(np.float64)).astype(np.float32)
    np.testing.assert_array_equal(grid("fire_sparse", "temperature"), np.pad(kelvin, 4))  # the grid x 1500 K
    for key in ("to_world", "coefficients", "scale_g", "blackbody"):
        np.testing.assert_allclose(arrays[f"fire_sparse.{key}"], arrays[f"fire_dense.{key}"], rtol=1e-6,
                                   atol=1e-9)
    assert np.all(arrays["fire_sparse.coefficients"][2] > 0.0)  # the flame's colour


@pytest.mark.bpy
def test_a_smoke_domain_cache_is_read_sparsely_as_the_sampler_reads_it(exported):
    """A gas domain's cache file (density and flame; the temperature Cycles derives from the
    flame): the sparse read's density and temperature equal the sampler's voxel for voxel,
    placed in the domain box as the dense path places them."""
    report, arrays = exported
    assert arrays["smoke_sparse.sparse"] and not arrays["smoke_dense.sparse"]
    assert report["smoke_sparse"] == report["smoke_dense"]
    shape = arrays["smoke.values"].shape
    for name in ("density", "temperature"):
        np.testing.assert_array_equal(placed(arrays, "smoke_sparse", (0, 0, 0), shape, name=name),
                                      placed(arrays, "smoke_dense", (0, 0, 0), shape, name=name))
    assert arrays["smoke_sparse.temperature"].max() > 1000.0  # kelvin, from the flame
    for key in ("to_world", "coefficients", "scale_g", "blackbody"):
        np.testing.assert_allclose(arrays[f"smoke_sparse.{key}"], arrays[f"smoke_dense.{key}"], rtol=1e-6,
                                   atol=1e-9)


def test_a_vdb_slab_is_cleaned_as_clean_grid_cleans_a_grid():
    """vdb_reader's in-place cleaning: NaN, infinite, negative and clipped voxels read 0,
    counted in the slab's own 8 layers (the ninth is the next row's first)."""
    from addon.export.vdb_reader import clean_slab

    rng = np.random.default_rng(7)
    slab = rng.uniform(-0.5, 2.0, (9, 10, 12)).astype(np.float32)
    slab.flat[rng.choice(slab.size, 40, replace=False)] = [np.nan, np.inf, -np.inf, -0.0] * 10
    for clipping in (0.0, 0.3):
        counts = [0, 0]
        got = clean_slab(slab.copy(), clipping, counts)
        values = np.where(np.isfinite(slab), slab, 0.0)
        keep = values >= clipping if clipping > 0.0 else values > 0.0
        np.testing.assert_array_equal(got, np.where(keep, values, 0.0).astype(np.float32))
        assert not np.signbit(got).any()
        core = slab[:8]
        negative = np.where(np.isfinite(core), core, 0.0) < 0.0
        assert counts == [int((~np.isfinite(core)).sum()), int(negative.sum())]
