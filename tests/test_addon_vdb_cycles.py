"""Volumes loaded from OpenVDB files, rendered by the installed extension against Cycles.

One Blender run (module fixture `renders`) builds three small scenes (a floor, a back wall,
a point lamp and a volume), writes their .vdb files with Blender's openvdb module and
renders each with Cycles and with Haze, K seeds each; the tests compare the stacks with
bpy_helpers.assert_agree (image means within 1 %, 8x8 block means within their noise):

* a Volume object loading a float `density` grid (large enough that Haze reads it sparsely,
  into bricks, as it reads real files), Principled Volume with Density Attribute `density`;
* a Volume object whose density comes from a vec3 grid: Attribute `velocity` > Vector >
  Separate XYZ > Z x 12 into the Principled Volume's Density (no Density Attribute). The
  file also holds a float `density` grid of 1 everywhere that the material does not read,
  and the vectors' X components are negative in places: reading the wrong grid or the wrong
  component would show. (What Haze reads of vec3 grids today: the dense sampler path,
  Attribute Vector / Color as the vector, Fac as its average, Separate XYZ; Vector Math is
  not a voxel value node. Haze zeroes negative vector components, with a warning - here
  only X's, which the material does not read; Cycles keeps them.)
* a Mantaflow gas domain (Fluid modifier, MODULAR cache with a synthesised
  data/fluid_data_0003.vdb, nothing simulated), at frame 3. Blender 5.0.1's bpy module
  cannot load that cache: its Mantaflow Python classes have lost their base classes (every
  manta type's MRO is (type, object), so the solver's set-up script fails with
  "'LevelsetGrid' object has no attribute 'setConst'") and Cycles renders the domain as
  empty. The domain comparison is therefore an expected failure (strict: it tells when a
  Blender fixes it), and Haze's domain render is compared with Cycles rendering the same
  cached grid through a Volume object placed as Cycles places a domain's grid (cell i
  centred at (i + 0.5) / res of the domain mesh's bounds).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bench.blender import BlenderRun
from bench.comparison import assert_agree, compare_images
from helpers.blender_runs import blender_fixture
from renderer.imageio import read_exr

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

RUNS = 4
SIZE = 32
BOUNCES = 2
SAMPLES = {"float": (128, 128), "vector": (128, 128), "smoke": (128, 128)}  # Cycles, Haze per run

BODY = r'''
import time
from pathlib import Path

import numpy as np
import bpy

import bpy_helpers as H
import blender_cornell as C

RUNS, SIZE, BOUNCES, SAMPLES = {runs}, {size}, {bounces}, {samples}
OUT = Path(os.getcwd())
H.enable_addon()
VDB = H.addon_module("volume_grids").import_openvdb()
export_scene = H.addon_module("export.scene").export_scene
TIMES = {{}}


def float_grid(name, values, index_to_object):
    """A FloatGrid of the (nz, ny, nx) array, voxel [0, 0, 0] at index (0, 0, 0)."""
    grid = VDB.FloatGrid()
    grid.copyFromArray(np.ascontiguousarray(values.transpose(2, 1, 0)), ijk=(0, 0, 0), tolerance=0.0)
    grid.name = name
    grid.transform = VDB.createLinearTransform(np.asarray(index_to_object).T.tolist())
    return grid


def vector_grid(name, values, index_to_object):
    """A Vec3SGrid of the (nz, ny, nx, 3) array (zero vectors stay inactive)."""
    grid = VDB.Vec3SGrid()
    grid.copyFromArray(np.ascontiguousarray(values.transpose(2, 1, 0, 3)), ijk=(0, 0, 0),
                       tolerance=(0.0, 0.0, 0.0))
    grid.name = name
    grid.transform = VDB.createLinearTransform(np.asarray(index_to_object).T.tolist())
    return grid


def cube_transform(count, side):
    """Index -> object matrix of `count`^3 voxels filling a cube of `side` centred at 0."""
    voxel = side / count
    matrix = np.diag([voxel, voxel, voxel, 1.0])
    matrix[:3, 3] = -0.5 * side + 0.5 * voxel
    return matrix


def lumps(shape, seed, count=3, width=0.18):
    """Gaussian lumps of noisy density, 0 below 0.05: the active voxels are the lumps."""
    rng = np.random.default_rng(seed)
    z, y, x = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    total = np.zeros(shape)
    for c in rng.uniform(0.3, 0.7, (count, 3)) * np.array(shape):
        r2 = ((z - c[0]) ** 2 + (y - c[1]) ** 2 + (x - c[2]) ** 2) / (width * min(shape)) ** 2
        total += np.exp(-r2)
    values = total * rng.uniform(0.6, 1.4, shape)
    return np.where(values > 0.05, values, 0.0).astype(np.float32)


def stage():
    """Floor, back wall, point lamp, black world, camera."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    H.enable_addon()
    scene = bpy.context.scene
    C.black_world(scene)
    C.quad("Floor", [(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)],
           C.diffuse_material("Floor", (0.7, 0.7, 0.7)))
    C.quad("Back", [(-4, 1.5, 0), (4, 1.5, 0), (4, 1.5, 4), (-4, 1.5, 4)],
           C.diffuse_material("Back", (0.6, 0.6, 0.6)))
    C.add_camera(scene, (0.0, -3.2, 1.4), (75.0, 0.0, 0.0), lens=35.0)
    H.add_light("POINT", "Lamp", (1.2, -1.0, 3.0), energy=400.0, shadow_soft_size=0.0)
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    return scene


def principled(name, color, density, attribute="density"):
    material, tree, output = C.node_material(name)
    node = tree.nodes.new("ShaderNodeVolumePrincipled")
    node.inputs["Color"].default_value = (*color, 1.0)
    node.inputs["Density"].default_value = density
    node.inputs["Density Attribute"].default_value = attribute
    tree.links.new(node.outputs[0], output.inputs["Volume"])
    return material, tree, node


def volume_object(name, path, material, location, rotation=(0.0, 0.0, 0.4), scale=(1.0, 1.0, 1.0),
                  clipping=0.001, space="OBJECT"):
    volume = bpy.data.volumes.new(name)
    volume.filepath = str(path)
    volume.render.clipping = clipping
    volume.render.space = space
    volume.materials.append(material)
    obj = bpy.data.objects.new(name, volume)
    bpy.context.scene.collection.objects.link(obj)
    obj.location, obj.rotation_euler, obj.scale = location, rotation, scale
    return obj


def exported():
    """What Haze makes of the scene's volume: read sparsely or not, and its warnings."""
    result = export_scene(bpy.context.evaluated_depsgraph_get(), render_depsgraph=False)
    media = [m for m in result.scene.media if m.type == "grid"]
    return {{"media": len(media), "sparse": [not isinstance(m.density, np.ndarray) for m in media],
            "warnings": list(result.warnings)}}


def float_scene():
    scene = stage()
    values = lumps((80, 80, 80), 3)
    path = OUT / "cloud.vdb"
    VDB.write(str(path), grids=[float_grid("density", values, cube_transform(80, 1.3))])
    material, _, _ = principled("Cloud", (0.8, 0.6, 0.4), 12.0)
    volume_object("Cloud", path, material, (0.0, 0.0, 0.8))
    return scene


def vector_scene():
    scene = stage()
    shape = (24, 24, 24)
    rng = np.random.default_rng(8)
    smoke = lumps(shape, 5, count=2, width=0.25)
    active = smoke > 0.0
    velocity = np.zeros(shape + (3,), np.float32)
    velocity[..., 0] = np.where(active, rng.uniform(-1.0, 1.0, shape), 0.0)
    velocity[..., 1] = np.where(active, rng.uniform(0.0, 2.0, shape), 0.0)
    velocity[..., 2] = smoke
    transform = cube_transform(24, 1.3)
    path = OUT / "velocity.vdb"
    VDB.write(str(path), grids=[float_grid("density", np.ones(shape, np.float32), transform),
                                vector_grid("velocity", velocity, transform)])
    material, tree, node = principled("Flow", (0.5, 0.7, 0.9), 1.0, attribute="")
    attribute = tree.nodes.new("ShaderNodeAttribute")
    attribute.attribute_name = "velocity"
    separate = tree.nodes.new("ShaderNodeSeparateXYZ")
    tree.links.new(attribute.outputs["Vector"], separate.inputs[0])
    scale = tree.nodes.new("ShaderNodeMath")
    scale.operation = "MULTIPLY"
    scale.inputs[1].default_value = 12.0
    tree.links.new(separate.outputs["Z"], scale.inputs[0])
    tree.links.new(scale.outputs[0], node.inputs["Density"])
    volume_object("Flow", path, material, (0.0, 0.0, 0.8))
    return scene


DOMAIN_RES = (21, 21, 32)  # x, y, z cells of the 1 x 1 x 1.5 domain at resolution 32


def smoke_scene():
    """A gas domain over the floor whose frame-3 cache file is written here, not baked."""
    scene = stage()
    domain, mesh, settings = H.gas_domain(scene, (0.5, 0.5, 0.75), str(OUT / "smoke_cache"), 32,
                                          location=(0.0, 0.0, 0.05))
    settings.domain_type = "GAS"
    shape = DOMAIN_RES[::-1]
    density = lumps(shape, 7, count=3, width=0.22)
    density[[0, -1]] = 0.0
    density[:, [0, -1]] = 0.0
    density[:, :, [0, -1]] = 0.0
    cache = OUT / "smoke_cache" / "data"
    cache.mkdir(parents=True)
    voxel = np.diag([0.1, 0.1, 0.1, 1.0])  # Mantaflow's own transform: a domain ignores it
    VDB.write(str(cache / "fluid_data_0003.vdb"), grids=[float_grid("density", density, voxel)])
    material, _, _ = principled("Smoke", (0.7, 0.7, 0.7), 16.0)
    mesh.materials.append(material)
    scene.frame_set(3)
    # The same grid as Cycles places a domain's: cell i centred at (i + 0.5) / res of the
    # domain mesh's bounds (object space), in a Volume object with the domain's transform;
    # render space World, since a domain's density has no object density factor (with
    # Object, this scale would make the proxy 1.68 times denser in Cycles and in Haze).
    low, high = np.array([-1.0, -1.0, 0.0]), np.array([1.0, 1.0, 2.0])
    size = (high - low) / np.array(DOMAIN_RES)
    placed = np.diag([*size, 1.0])
    placed[:3, 3] = low + 0.5 * size
    path = OUT / "smoke_proxy.vdb"
    VDB.write(str(path), grids=[float_grid("density", density, placed)])
    proxy = volume_object("Proxy", path, material, tuple(domain.location), (0.0, 0.0, 0.0),
                          tuple(domain.scale), clipping=settings.clipping, space="WORLD")
    proxy.hide_render = True
    return scene, domain, proxy


def render_cycles(scene, folder, samples, stem="cycles"):
    paths = []
    for run in range(RUNS):
        H.configure_cycles(scene, samples, BOUNCES, seed=run + 1)
        paths.append(H.render_exr(scene, f"{{folder}}/{{stem}}_{{run}}.exr"))
    return paths


def render_haze(scene, folder, samples):
    paths = []
    for run in range(RUNS):
        H.configure_haze(scene, samples, BOUNCES, seed=run + 1)
        paths.append(H.render_exr(scene, f"{{folder}}/haze_{{run}}.exr"))
    return paths


def timed(key, function, *args, **kwargs):
    start = time.perf_counter()
    value = function(*args, **kwargs)
    TIMES[key] = time.perf_counter() - start
    return value


def main():
    result = {{}}
    for name, build in (("float", float_scene), ("vector", vector_scene)):
        scene = build()
        folder = OUT / name
        folder.mkdir()
        result[name] = {{"export": exported(),
                        "cycles": timed(name + " cycles", render_cycles, scene, folder, SAMPLES[name][0]),
                        "haze": timed(name + " haze", render_haze, scene, folder, SAMPLES[name][1])}}
    scene, domain, proxy = smoke_scene()
    folder = OUT / "smoke"
    folder.mkdir()
    cycles_samples, haze_samples = SAMPLES["smoke"]
    smoke = result["smoke"] = {{"export": exported()}}
    smoke["cycles"] = timed("smoke cycles", render_cycles, scene, folder, cycles_samples)
    smoke["haze"] = timed("smoke haze", render_haze, scene, folder, haze_samples)
    domain.hide_render, proxy.hide_render = True, False
    smoke["proxy"] = timed("proxy cycles", render_cycles, scene, folder, cycles_samples, "proxy")
    proxy.hide_render = True
    H.configure_cycles(scene, cycles_samples, BOUNCES, seed=1)
    smoke["bare"] = H.render_exr(scene, f"{{folder}}/bare.exr")  # neither: what no smoke looks like
    result["times"] = TIMES
    return result
'''


def timed(run: BlenderRun, folder: Path) -> dict:
    print("render times (s):", {k: round(v, 1) for k, v in run.result["times"].items()})
    return run.result


renders = blender_fixture(BODY.format(runs=RUNS, size=SIZE, bounces=BOUNCES, samples=SAMPLES), "vdb_cycles",
                          timeout=1800, read=timed)


def stacks(case: dict, *keys: str) -> list[np.ndarray]:
    return [np.stack([read_exr(path) for path in case[key]]) for key in keys]


def compared(haze: np.ndarray, cycles: np.ndarray, label: str):
    assert haze.shape == cycles.shape == (RUNS, SIZE, SIZE, 3)
    comparison = compare_images(haze, cycles)
    print(f"{label}: {comparison.summary()}")
    return comparison


def not_rendered(warnings: list[str]) -> list[str]:
    return [w for w in warnings if "not rendered" in w or "cannot be read" in w or "reads 0" in w]


def test_vdb_density_grid_agrees_with_cycles(renders):
    """A float density grid read sparsely (into bricks) from its file, under a lamp."""
    case = renders["float"]
    assert case["export"]["media"] == 1 and case["export"]["sparse"] == [True], case["export"]
    assert not case["export"]["warnings"], case["export"]["warnings"]
    haze, cycles = stacks(case, "haze", "cycles")
    assert cycles.mean() > 0.05, "the Cycles image is black: the scene is broken"
    assert_agree(compared(haze, cycles, "float density grid"))


def test_vdb_vector_grid_as_density_agrees_with_cycles(renders):
    """Density from a vec3 grid's Z component (Attribute Vector > Separate XYZ > Math); the
    file's float density grid is not read."""
    case = renders["vector"]
    assert case["export"]["media"] == 1, case["export"]
    assert not not_rendered(case["export"]["warnings"]), case["export"]["warnings"]
    haze, cycles = stacks(case, "haze", "cycles")
    assert cycles.mean() > 0.05, "the Cycles image is black: the scene is broken"
    assert_agree(compared(haze, cycles, "vec3 grid density"))


def smoke_effect(images: np.ndarray, bare: np.ndarray) -> float:
    """How much the smoke changes the image mean (relative), against a render without it."""
    return float(abs(images.mean() / bare.mean() - 1.0))


def test_smoke_domain_cache_renders_in_haze_like_cycles_reads_the_file(renders):
    """Haze's smoke domain against Cycles rendering the same cached grid as a Volume object
    placed where a domain's cells are (Cycles itself cannot load the cache in this bpy)."""
    case = renders["smoke"]
    assert case["export"]["media"] == 1, case["export"]
    assert not case["export"]["warnings"], case["export"]["warnings"]
    haze, proxy = stacks(case, "haze", "proxy")
    bare = read_exr(case["bare"])
    assert smoke_effect(haze, bare) > 0.05, "Haze renders no smoke"
    assert smoke_effect(proxy, bare) > 0.05, "Cycles renders no smoke from the cache file"
    assert_agree(compared(haze, proxy, "smoke domain (Haze) vs its cache file as a volume (Cycles)"))


@pytest.mark.xfail(strict=True, reason="Blender 5.0.1's bpy module cannot load a Mantaflow cache: its manta "
                   "classes have no base classes ('LevelsetGrid' object has no attribute 'setConst' in the "
                   "solver set-up), so Cycles renders the domain empty")
def test_smoke_domain_agrees_with_cycles(renders):
    case = renders["smoke"]
    haze, cycles = stacks(case, "haze", "cycles")
    bare = read_exr(case["bare"])
    broken = "'LevelsetGrid' object has no attribute 'setConst'" in renders.stderr
    assert smoke_effect(cycles, bare) > 0.05, (
        f"Cycles renders no smoke from the domain's cache (image mean {cycles.mean():.4f}, without the "
        f"domain {bare.mean():.4f}); Mantaflow's set-up script {'failed' if broken else 'ran'}")
    assert_agree(compared(haze, cycles, "smoke domain"))
