"""Scene folder format: round trips, and one case per class of bad input, each required to
name the exact field at fault."""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from renderer.errors import SceneError
from renderer.scene import (
    SCENE_FORMAT_VERSION,
    Camera,
    Environment,
    Film,
    IntegratorSettings,
    Lobe,
    Material,
    Medium,
    Mesh,
    PointLight,
    Scene,
    SpotLight,
    SunLight,
)
from renderer.scenefile import load_scene, save_scene
from renderer.validate import validate_scene

NAN, INF = float("nan"), float("inf")
DELETE = object()  # marks a key to remove in `_assign`
# Columns x and y differ by 1e-13 of their length: singular relative to the matrix's scale.
_NEARLY_PARALLEL_COLUMNS = np.array([[1, 1, 0, 0], [0, 1e-13, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]], np.float64)


def _rotation_about_z(degrees: float, translation: tuple[float, float, float]) -> np.ndarray:
    c, s = math.cos(math.radians(degrees)), math.sin(math.radians(degrees))
    matrix = np.eye(4)
    matrix[:2, :2] = [[c, -s], [s, c]]
    matrix[:3, 3] = translation
    return matrix


def _good_scene() -> Scene:
    """A valid scene that uses every field, with values that do not round-trip by accident."""
    rng = np.random.default_rng(7)
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    tetrahedron = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
    glass_lobes = [
        Lobe("dielectric", ior=1.45),
        Lobe("rough_conductor", weight=(0.5, 0.25, 0.125), roughness=0.3, sides="front"),
    ]
    return Scene(
        camera=Camera(_rotation_about_z(33.0, (0.1, 2.0, 5.0)), 50.0, "y", (0.1, -0.05), 0.01, 1000.0),
        film=Film(64, 32),
        integrator=IntegratorSettings(16, 4, 12345, 2, "nee", "delta", "uniform", False, False, 4096, 1.5),
        materials=[
            Material("white", [Lobe("diffuse", color=(0.7, 0.6, 0.5))]),
            Material("glass", glass_lobes, emission=(0.1, 0.2, 0.3), emission_sides="both"),
            Material("boundary"),
        ],
        meshes=[
            Mesh(
                "floor",
                square,
                np.array([[0, 1, 2], [0, 2, 3]], np.int32),
                ["white", "glass"],
                material_ids=np.array([0, 1], np.int32),
                normals=rng.random((4, 3), dtype=np.float32),
            ),
            Mesh(
                "fog box/1",
                tetrahedron,
                np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.int32),
                ["boundary"],
                medium="smoke",
            ),
        ],
        lights=[
            PointLight((0.0, 1.0, 2.0), (10.0, 10.0, 10.0)),
            SpotLight((0.0, 2.0, 0.0), (0.0, -1.0, 0.0), (5.0, 4.0, 3.0), spot_size=30.0, blend=0.2),
            SunLight((1.0, 1.0, 1.0), (3.0, 3.0, 3.0), angle=0.5),
        ],
        media=[
            Medium("air", sigma_s=(0.01, 0.02, 0.03), g=0.3),
            Medium(
                "smoke",
                type="grid",
                sigma_a=(0.5, 0.5, 0.5),
                sigma_s=(2.0, 2.0, 2.0),
                scale=3.0,
                g=-0.2,
                emission=(1.0, 0.5, 0.1),
                density=rng.random((4, 5, 6), dtype=np.float32),
                p0=(-1.0, -1.0, -1.0),
                p1=(1.0, 2.0, 3.0),
                to_world=_rotation_about_z(1.0 / 3.0, (0.3, 0.2, 0.1)),
                flame=rng.random((2, 2, 2), dtype=np.float32),
                temperature=1500.0 * rng.random((3, 3, 3), dtype=np.float32),
                blackbody_intensity=0.7,
            ),
        ],
        environment=Environment((0.1, 0.2, 0.3)),
        medium="air",
    )


def _assert_identical(a: Any, b: Any, path: str = "scene") -> None:
    """Equal field by field, with the same types; arrays bitwise equal with the same dtype."""
    assert type(a) is type(b), f"{path}: {type(a).__name__} != {type(b).__name__}"
    if dataclasses.is_dataclass(a):
        for f in dataclasses.fields(a):
            _assert_identical(getattr(a, f.name), getattr(b, f.name), f"{path}.{f.name}")
    elif isinstance(a, list | tuple):
        assert len(a) == len(b), path
        for i, (x, y) in enumerate(zip(a, b)):
            _assert_identical(x, y, f"{path}[{i}]")
    elif isinstance(a, np.ndarray):
        assert (a.dtype, a.shape) == (b.dtype, b.shape), path
        assert a.tobytes() == b.tobytes(), path
    else:
        assert a == b, path


def _tokens(path: str) -> list[str]:
    return re.findall(r"[A-Za-z_]\w*|\[\d+\]", path)


def _step(node: Any, token: str) -> Any:
    if token.startswith("["):
        return node[int(token[1:-1])]
    return node[token] if isinstance(node, dict) else getattr(node, token)


def _assign(root: Any, path: str, value: Any) -> None:
    """Set (or with DELETE remove) the field at a path like `meshes[0].vertices`."""
    *parents, last = _tokens(path)
    node = root
    for token in parents:
        node = _step(node, token)
    key: Any = int(last[1:-1]) if last.startswith("[") else last
    if value is DELETE:
        del node[key]
    elif isinstance(node, dict | list):
        node[key] = value
    else:
        setattr(node, key, value)


def _lookup(root: Any, path: str) -> Any:
    node = root
    for token in _tokens(path):
        node = _step(node, token)
    return node


def _expect_error(expected_path: str, fragment: str) -> Any:
    return pytest.raises(SceneError, match=f"^{re.escape(expected_path)}: .*{re.escape(fragment)}")


# ------------------------------------------------------------------------------ good input


def test_round_trip_keeps_every_field_and_array_bits(tmp_path: Path) -> None:
    scene = _good_scene()
    save_scene(scene, tmp_path)
    _assert_identical(load_scene(tmp_path), _good_scene())


def test_saving_a_loaded_scene_writes_the_same_json(tmp_path: Path) -> None:
    first = save_scene(_good_scene(), tmp_path / "a").read_text()
    second = save_scene(load_scene(tmp_path / "a"), tmp_path / "b").read_text()
    assert first == second


def test_scene_json_is_versioned_and_refers_to_arrays_by_relative_name(tmp_path: Path) -> None:
    data = json.loads(save_scene(_good_scene(), tmp_path).read_text())
    assert data["version"] == SCENE_FORMAT_VERSION
    assert data["meshes"][1]["vertices"] == "arrays/mesh1.vertices.npy"
    assert data["media"][1]["density"] == "arrays/medium1.density.npy"
    assert (tmp_path / data["media"][1]["density"]).is_file()


def test_saving_over_a_folder_keeps_unrelated_files(tmp_path: Path) -> None:
    (tmp_path / "arrays").mkdir()
    (tmp_path / "notes.txt").write_text("mine")
    np.save(tmp_path / "arrays" / "my_grid.npy", np.ones(3))
    save_scene(_good_scene(), tmp_path)
    save_scene(_good_scene(), tmp_path)  # overwriting our own files is fine
    assert (tmp_path / "notes.txt").read_text() == "mine"
    assert np.load(tmp_path / "arrays" / "my_grid.npy").tolist() == [1.0, 1.0, 1.0]


def test_missing_optional_keys_take_dataclass_defaults(tmp_path: Path) -> None:
    mesh = {"name": "m", "vertices": "v.npy", "indices": "i.npy", "materials": []}
    np.save(tmp_path / "v.npy", np.zeros((0, 3), np.float32))
    np.save(tmp_path / "i.npy", np.zeros((0, 3), np.int32))
    data = {
        "version": SCENE_FORMAT_VERSION,
        "meshes": [mesh],
        "lights": [{"type": "sun", "direction": [0, 0, 1], "irradiance": [1, 1, 1]}],
    }
    (tmp_path / "scene.json").write_text(json.dumps(data))
    scene = load_scene(tmp_path)
    expected = Scene(
        meshes=[Mesh("m", np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), [])],
        lights=[SunLight((0.0, 0.0, 1.0), (1.0, 1.0, 1.0))],
    )
    _assert_identical(scene, expected)


def test_the_documented_example_loads(tmp_path: Path) -> None:
    doc = (Path(__file__).parent.parent / "docs" / "scene-format.md").read_text()
    example = re.search(r"```json\n(.*?)```", doc, re.DOTALL).group(1)
    (tmp_path / "scene.json").write_text(example)
    (tmp_path / "arrays").mkdir()
    np.save(tmp_path / "arrays" / "mesh0.vertices.npy", np.eye(3, dtype=np.float32))
    np.save(tmp_path / "arrays" / "mesh0.indices.npy", np.array([[0, 1, 2]], np.int32))
    scene = load_scene(tmp_path)
    assert (scene.film.width, scene.lights[0].irradiance) == (320, (3.0, 3.0, 3.0))


def test_validate_normalises_in_memory_values() -> None:
    scene = _good_scene()
    scene.meshes[0].vertices = scene.meshes[0].vertices.astype(np.float64)
    scene.meshes[0].indices = scene.meshes[0].indices.astype(np.int64)
    scene.media[1].density = np.asfortranarray(scene.media[1].density)
    scene.lights[0].intensity = (1, 2, 3)
    scene.camera.to_world = scene.camera.to_world.tolist()
    validate_scene(scene)
    assert scene.meshes[0].vertices.dtype == np.float32
    assert scene.meshes[0].indices.dtype == np.int32
    assert scene.media[1].density.flags.c_contiguous
    assert scene.lights[0].intensity == (1.0, 2.0, 3.0) and type(scene.lights[0].intensity[0]) is float
    assert isinstance(scene.camera.to_world, np.ndarray) and scene.camera.to_world.dtype == np.float64


def test_degenerate_triangles_and_empty_meshes_are_allowed() -> None:
    scene = _good_scene()
    scene.meshes[0].indices = np.array([[0, 0, 0], [1, 2, 3]], np.int32)
    scene.meshes.append(Mesh("empty", np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), []))
    validate_scene(scene)


# ------------------------------------------------------------------- bad in-memory scenes

_BAD_VALUES = [
    # NaN and inf, in arrays and in numbers
    ("meshes[0].vertices", np.array([[NAN, 0, 0]] * 4, np.float32), "meshes[0].vertices", "contains NaN"),
    ("media[1].density", np.full((2, 2, 2), INF, np.float32), "media[1].density", "contains inf"),
    ("meshes[0].normals", np.full((4, 3), NAN, np.float64), "meshes[0].normals", "contains NaN"),
    ("camera.to_world", np.full((4, 4), NAN), "camera.to_world", "contains NaN"),
    ("camera.fov", NAN, "camera.fov", "must be finite"),
    ("integrator.time_limit", INF, "integrator.time_limit", "must be finite"),
    ("materials[0].lobes[0].color", (0.5, NAN, 0.5), "materials[0].lobes[0].color", "must be finite"),
    ("meshes[0].vertices", np.full((4, 3), 1e39), "meshes[0].vertices", "exceed the float32 range"),
    # negative where not allowed
    ("materials[0].lobes[0].color", (0.5, -0.1, 0.5), "materials[0].lobes[0].color", "must not be negative"),
    (
        "materials[1].lobes[1].weight",
        (-1.0, 0.0, 0.0),
        "materials[1].lobes[1].weight",
        "must not be negative",
    ),
    ("materials[1].emission", (0.0, 0.0, -2.0), "materials[1].emission", "must not be negative"),
    ("media[0].sigma_a", (-0.1, 0.0, 0.0), "media[0].sigma_a", "must not be negative"),
    ("media[0].sigma_s", (0.0, -0.1, 0.0), "media[0].sigma_s", "must not be negative"),
    ("media[1].emission", (0.0, -0.1, 0.0), "media[1].emission", "must not be negative"),
    ("media[0].scale", -1.0, "media[0].scale", "must be >= 0"),
    ("media[1].blackbody_intensity", -1.0, "media[1].blackbody_intensity", "must be >= 0"),
    ("media[1].density", np.full((2, 2, 2), -1.0, np.float32), "media[1].density", "must not be negative"),
    ("media[1].flame", np.full((2, 2, 2), -1.0, np.float32), "media[1].flame", "must not be negative"),
    ("lights[0].intensity", (-1.0, 0.0, 0.0), "lights[0].intensity", "must not be negative"),
    ("lights[2].irradiance", (-1.0, 0.0, 0.0), "lights[2].irradiance", "must not be negative"),
    ("environment.radiance", (-1.0, 0.0, 0.0), "environment.radiance", "must not be negative"),
    ("integrator.time_limit", -1.0, "integrator.time_limit", "must be >= 0"),
    ("integrator.seed", -1, "integrator.seed", "must be in [0, 2**64)"),
    # out of range
    ("materials[0].lobes[0].roughness", 1.5, "materials[0].lobes[0].roughness", "must be in [0, 1]"),
    ("materials[0].lobes[0].ior", 0.0, "materials[0].lobes[0].ior", "must be > 0"),
    ("media[0].g", 1.0, "media[0].g", "must satisfy |g| < 1, got 1.0"),
    ("media[0].g", -1.0, "media[0].g", "must satisfy |g| < 1, got -1.0"),
    ("camera.fov", 180.0, "camera.fov", "must be in (0, 180)"),
    ("camera.fov", 0.0, "camera.fov", "must be in (0, 180)"),
    ("camera.clip_start", 0.0, "camera.clip_start", "must be > 0"),
    ("camera.clip_end", 0.01, "camera.clip_end", "must be > clip_start"),
    ("film.width", 0, "film.width", "must be in [1, 16384]"),
    ("film.height", 16385, "film.height", "must be in [1, 16384]"),
    ("integrator.spp", 0, "integrator.spp", "must be in [1, 16777216]"),
    ("integrator.max_bounces", -1, "integrator.max_bounces", "must be in [0, 1024]"),
    ("integrator.rr_depth", -1, "integrator.rr_depth", "must be in [0, 2**31)"),
    ("integrator.batch_size", 1023, "integrator.batch_size", "must be in [1024, 4194304]"),
    ("integrator.batch_size", (1 << 22) + 1, "integrator.batch_size", "must be in [1024, 4194304]"),
    ("lights[1].spot_size", 0.0, "lights[1].spot_size", "must be in (0, 180]"),
    ("lights[1].blend", 1.5, "lights[1].blend", "must be in [0, 1]"),
    ("lights[2].angle", 180.0, "lights[2].angle", "must be in [0, 180)"),
    ("lights[1].direction", (0.0, 0.0, 0.0), "lights[1].direction", "non-zero"),
    ("lights[2].direction", (0.0, 0.0, 0.0), "lights[2].direction", "non-zero"),
    # unknown names in closed sets
    ("materials[1].lobes[0].kind", "velvet", "materials[1].lobes[0].kind", "unknown lobe kind 'velvet'"),
    ("materials[1].lobes[1].sides", "top", "materials[1].lobes[1].sides", "unknown sides value 'top'"),
    ("materials[1].emission_sides", "up", "materials[1].emission_sides", "unknown sides value 'up'"),
    ("camera.fov_axis", "z", "camera.fov_axis", "unknown fov axis 'z'"),
    ("media[0].type", "vdb", "media[0].type", "unknown medium type 'vdb'"),
    ("integrator.sampling", "path", "integrator.sampling", "unknown sampling mode"),
    ("integrator.transmittance", "exact", "integrator.transmittance", "unknown transmittance mode"),
    ("integrator.distance_sampling", "hero", "integrator.distance_sampling", "unknown distance sampling"),
    ("lights[0].type", "area", "lights[0].type", "unknown light type 'area'"),
    ("lights[0].type", "sun", "lights[0].type", "does not match a PointLight"),
    # wrong shapes, dtypes and Python types
    ("meshes[0].vertices", np.zeros((4, 2), np.float32), "meshes[0].vertices", "must have shape (V, 3)"),
    ("meshes[0].indices", np.zeros((2, 4), np.int32), "meshes[0].indices", "must have shape (T, 3)"),
    ("meshes[0].normals", np.zeros((3, 3), np.float32), "meshes[0].normals", "must have shape (4, 3)"),
    ("meshes[0].material_ids", np.zeros(3, np.int32), "meshes[0].material_ids", "must have shape (2,)"),
    ("media[1].density", np.ones((4, 4), np.float32), "media[1].density", "must be 3-D"),
    ("media[1].temperature", np.ones((0, 4, 4), np.float32), "media[1].temperature", "must not be empty"),
    ("meshes[0].vertices", np.zeros((4, 3), np.int32), "meshes[0].vertices", "must be a float array"),
    ("meshes[0].indices", np.zeros((2, 3), np.float32), "meshes[0].indices", "must be an integer array"),
    ("meshes[0].indices", np.full((2, 3), 1 << 40), "meshes[0].indices", "do not fit int32"),
    ("meshes[0].vertices", [[0.0, 0.0, 0.0]], "meshes[0].vertices", "must be a numpy array"),
    ("camera.to_world", np.eye(3), "camera.to_world", "must be a 4x4 matrix"),
    ("camera.fov", "40", "camera.fov", "must be a number"),
    ("film.width", 12.0, "film.width", "must be an integer"),
    ("integrator.equiangular", 1, "integrator.equiangular", "must be true or false"),
    ("camera.shift", (0.0,), "camera.shift", "must be a list of 2 numbers"),
    ("camera", Film(), "camera", "must be a Camera"),
    ("lights[0]", Environment(), "lights[0]", "must be a PointLight or SpotLight or SunLight"),
    # indices out of range
    (
        "meshes[0].indices",
        np.array([[0, 1, 4], [0, 1, 2]], np.int32),
        "meshes[0].indices",
        "index 4 out of range",
    ),
    (
        "meshes[0].indices",
        np.array([[0, 1, -1], [0, 1, 2]], np.int32),
        "meshes[0].indices",
        "negative index -1",
    ),
    ("meshes[0].material_ids", np.array([0, 2], np.int32), "meshes[0].material_ids", "index 2 out of range"),
    ("meshes[0].material_ids", np.array([0, -1], np.int32), "meshes[0].material_ids", "negative index"),
    ("meshes[0].materials", [], "meshes[0].material_ids", "out of range for 0 materials"),
    ("meshes[1].materials", [], "meshes[1].materials", "must name at least one material"),
    # unknown references
    ("meshes[0].materials", ["white", "steel"], "meshes[0].materials[1]", "unknown material 'steel'"),
    ("meshes[1].medium", "fog", "meshes[1].medium", "unknown medium 'fog'"),
    ("medium", "vacuum", "medium", "unknown medium 'vacuum'"),
    # duplicate and empty names
    ("materials[2].name", "white", "materials[2].name", "duplicate name 'white' (also materials[0])"),
    ("media[1].name", "air", "media[1].name", "duplicate name 'air' (also media[0])"),
    ("meshes[1].name", "floor", "meshes[1].name", "duplicate name 'floor' (also meshes[0])"),
    ("materials[0].name", "", "materials[0].name", "must not be empty"),
    # singular and non-affine matrices, flat grid boxes
    ("camera.to_world", np.diag([1.0, 0.0, 1.0, 1.0]), "camera.to_world", "singular matrix"),
    ("camera.to_world", np.diag([1.0, 1.0, 1.0, 2.0]), "camera.to_world", "last row must be (0, 0, 0, 1)"),
    ("media[1].to_world", _NEARLY_PARALLEL_COLUMNS, "media[1].to_world", "singular matrix"),
    ("media[1].p1", (1.0, -1.0, 3.0), "media[1].p1", "equals p0 on the y axis"),
    # grid arrays on the wrong kind of medium
    ("media[1].density", None, "media[1].density", "required for grid media"),
    ("media[0].flame", np.ones((2, 2, 2), np.float32), "media[0].flame", "only grid media"),
]


@pytest.mark.parametrize(("field", "value", "expected_path", "fragment"), _BAD_VALUES)
def test_validate_names_the_bad_field(field: str, value: Any, expected_path: str, fragment: str) -> None:
    scene = _good_scene()
    _assign(scene, field, value)
    with _expect_error(expected_path, fragment) as caught:
        validate_scene(scene)
    assert caught.value.path == expected_path


def test_scaling_alone_is_not_singular() -> None:
    # A huge or tiny but well-conditioned scale is a valid placement of a grid box.
    scene = _good_scene()
    scene.media[1].to_world = np.diag([1e-9, 1.0, 1e9, 1.0])
    scene.camera.to_world = np.diag([1e-6, 1e-6, 1e-6, 1.0])
    validate_scene(scene)


def test_a_grid_box_too_large_for_floats_is_singular() -> None:
    # to_world and p0..p1 are each fine; their product overflows and cannot be inverted.
    scene = _good_scene()
    scene.media[1].to_world = np.diag([1e300, 1.0, 1.0, 1.0])
    scene.media[1].p1 = (1e10, 2.0, 3.0)
    with _expect_error("media[1].to_world", "singular matrix (combined with p0..p1)"):
        validate_scene(scene)


def test_validate_rejects_something_that_is_not_a_scene() -> None:
    with _expect_error("scene", "must be a Scene"):
        validate_scene(Camera())  # type: ignore[arg-type]


def test_save_refuses_an_invalid_scene(tmp_path: Path) -> None:
    scene = _good_scene()
    scene.media[0].g = 1.0
    with _expect_error("media[0].g", "|g| < 1"):
        save_scene(scene, tmp_path)
    assert not (tmp_path / "scene.json").exists()


# ------------------------------------------------------------------------ bad scene folders

Edit = Callable[[Path, dict], None]


def _json_set(field: str, value: Any) -> Edit:
    return lambda folder, data: _assign(data, field, value)


def _array_file(field: str, array: np.ndarray) -> Edit:
    """Replace the .npy file that `field` names."""
    return lambda folder, data: np.save(folder / _lookup(data, field), array)


def _file_bytes(field: str, content: bytes) -> Edit:
    return lambda folder, data: (folder / _lookup(data, field)).write_bytes(content)


def _file_removed(field: str) -> Edit:
    return lambda folder, data: (folder / _lookup(data, field)).unlink()


def _npz_file(field: str) -> Edit:
    def edit(folder: Path, data: dict) -> None:
        with open(folder / _lookup(data, field), "wb") as stream:
            np.savez(stream, a=np.zeros((4, 3), np.float32))

    return edit


_BAD_FOLDERS = [
    # format version
    (_json_set("version", 1), "version", "unsupported format version 1"),
    (_json_set("version", DELETE), "version", "missing required key"),
    (_json_set("version", "1"), "version", "must be an integer"),
    # unknown keys, at every level
    (_json_set("focus", 1.0), "focus", "unknown key"),
    (_json_set("camera.aperture", 1.0), "camera.aperture", "unknown key"),
    (_json_set("materials[1].lobes[0].anisotropy", 0.5), "materials[1].lobes[0].anisotropy", "unknown key"),
    (_json_set("lights[2].spot_size", 30.0), "lights[2].spot_size", "unknown key"),
    # unknown and missing light types
    (_json_set("lights[0].type", "area"), "lights[0].type", "unknown light type 'area'"),
    (_json_set("lights[0].type", DELETE), "lights[0].type", "missing required key"),
    # missing required keys
    (_json_set("meshes[0].vertices", DELETE), "meshes[0].vertices", "missing required key"),
    (_json_set("materials[0].name", DELETE), "materials[0].name", "missing required key"),
    (_json_set("lights[1].direction", DELETE), "lights[1].direction", "missing required key"),
    # wrong JSON types
    (_json_set("camera", []), "camera", "must be a JSON object"),
    (_json_set("materials", {}), "materials", "must be a list"),
    (_json_set("camera.fov", "40"), "camera.fov", "must be a number"),
    (_json_set("film.width", 64.0), "film.width", "must be an integer"),
    (_json_set("camera.fov", 10**400), "camera.fov", "must be finite"),
    (_json_set("lights[0].position", [0, 10**400, 0]), "lights[0].position", "must be finite"),
    (_json_set("integrator.majorant_grid", "yes"), "integrator.majorant_grid", "must be true or false"),
    (_json_set("materials[0].lobes[0].color", [1, 1]), "materials[0].lobes[0].color", "list of 3 numbers"),
    (_json_set("camera.to_world", [[1, 0, 0, 0]] * 3), "camera.to_world", "must be a 4x4 matrix"),
    (_json_set("camera.to_world", [[1, 0, 0, "0"]] * 4), "camera.to_world", "matrix of numbers"),
    (_json_set("meshes[0].vertices", 3), "meshes[0].vertices", "must be the name of a .npy file"),
    (_json_set("meshes[0].medium", 0), "meshes[0].medium", "must be a string"),
    # array files: missing, unreadable, absolute, wrong dtype
    (_file_removed("meshes[0].vertices"), "meshes[0].vertices", "not found"),
    (_json_set("media[1].flame", "arrays/nowhere.npy"), "media[1].flame", "'arrays/nowhere.npy' not found"),
    (_file_bytes("meshes[0].indices", b"not an array"), "meshes[0].indices", "cannot read"),
    (_array_file("meshes[0].normals", np.array([None, 1], object)), "meshes[0].normals", "cannot read"),
    (_npz_file("meshes[0].vertices"), "meshes[0].vertices", "not a single-array .npy file"),
    (_json_set("media[1].density", "/tmp/density.npy"), "media[1].density", "must be relative"),
    (_array_file("meshes[0].vertices", np.zeros((4, 3))), "meshes[0].vertices", "holds float64"),
    (_array_file("meshes[0].indices", np.zeros((2, 3), np.int64)), "meshes[0].indices", "exactly int32"),
    (_array_file("meshes[0].material_ids", np.zeros(2, np.uint8)), "meshes[0].material_ids", "holds uint8"),
    (_array_file("media[1].density", np.ones((2, 2, 2))), "media[1].density", "exactly float32"),
    # semantic problems in files reach validate_scene
    (
        _array_file("meshes[0].vertices", np.full((4, 3), NAN, np.float32)),
        "meshes[0].vertices",
        "contains NaN",
    ),
    (_array_file("meshes[1].indices", np.full((1, 3), 9, np.int32)), "meshes[1].indices", "out of range"),
    (_json_set("materials[1].lobes[1].roughness", 2), "materials[1].lobes[1].roughness", "must be in [0, 1]"),
    (
        _json_set("media[0].density", "arrays/medium1.density.npy"),
        "media[0].density",
        "only grid media",
    ),
]


@pytest.mark.parametrize(("edit", "expected_path", "fragment"), _BAD_FOLDERS)
def test_load_names_the_bad_field(tmp_path: Path, edit: Edit, expected_path: str, fragment: str) -> None:
    scene_file = save_scene(_good_scene(), tmp_path)
    data = json.loads(scene_file.read_text())
    edit(tmp_path, data)
    scene_file.write_text(json.dumps(data))
    with _expect_error(expected_path, fragment) as caught:
        load_scene(tmp_path)
    assert caught.value.path == expected_path


@pytest.mark.parametrize(
    ("text", "fragment"),
    [
        ("{ not json", "not valid JSON"),
        ("[1, 2]", "must hold a JSON object"),
        ('{"version": 1, "film": {"width": 8, "width": 9}}', "duplicate key 'width'"),
    ],
)
def test_load_rejects_a_broken_scene_json(tmp_path: Path, text: str, fragment: str) -> None:
    (tmp_path / "scene.json").write_text(text)
    with _expect_error("scene.json", fragment):
        load_scene(tmp_path)


def test_load_reports_nan_written_into_the_json(tmp_path: Path) -> None:
    scene_file = save_scene(_good_scene(), tmp_path)
    scene_file.write_text(scene_file.read_text().replace('"fov": 50.0', '"fov": NaN'))
    with _expect_error("camera.fov", "must be finite"):
        load_scene(tmp_path)


def test_load_reports_a_folder_without_scene_json(tmp_path: Path) -> None:
    with _expect_error("scene.json", "not found"):
        load_scene(tmp_path)
