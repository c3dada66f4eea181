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
from bpy_helpers import run_blender

BODY = r'''
from pathlib import Path

import numpy as np
import bpy

import bpy_helpers as H
import blender_cornell as C

H.enable_dev_addon()
from addon.export import volumes as V
from addon.export.scene import export_scene
from addon.volume_grids import import_openvdb

VDB = import_openvdb()
ARRAYS = {}


def write_grid(path, values, index_to_object, start):
    grid = VDB.FloatGrid()
    grid.copyFromArray(np.ascontiguousarray(values.transpose(2, 1, 0)), ijk=tuple(start), tolerance=0.0)
    grid.name = "density"
    grid.transform = VDB.createLinearTransform(np.asarray(index_to_object).T.tolist())
    VDB.write(str(path), grids=[grid])
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
    ARRAYS[prefix + ".p0"] = np.array(medium.p0)
    ARRAYS[prefix + ".to_world"] = medium.to_world
    ARRAYS[prefix + ".coefficients"] = np.array([medium.sigma_a, medium.sigma_s, medium.emission])
    ARRAYS[prefix + ".scale_g"] = np.array([medium.scale, medium.g])
    mesh = [m for m in result.scene.meshes if m.medium == medium.name][0]
    ARRAYS[prefix + ".boundary"] = np.array(mesh.vertices)
    return result.warnings


def main():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_dev_addon()
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
    # A two-frame sequence: frame f loads seq_000f.vdb (another cloud each).
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_dev_addon()
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
    np.savez("arrays.npz", **ARRAYS)
    return report
'''


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    folder = tmp_path_factory.mktemp("vdb")
    run = run_blender(BODY, folder, timeout=600)
    assert run.returncode == 0 and run.result, run.describe()
    return run.result, dict(np.load(folder / "arrays.npz"))


def placed(arrays, prefix, start, shape, pad=4):
    """The exported density put at its index position on a canvas whose voxel [pad, pad,
    pad] is index `start` (x, y, z) and which reaches `pad` voxels past `shape`."""
    density = arrays[f"{prefix}.density"]
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
