"""Scene folders lose nothing: every field of every object comes back from save and load,
whatever the objects are called (issue 42: two meshes with "uv:UVMap" shared one file).

The comparison walks the dataclasses (every field, recursively; arrays bitwise with their
dtype), the every-field scene sets each field of each class to a value that is not its
default (checked, so the round trip cannot pass on defaults), and hypothesis draws scenes
whose meshes, materials, media and images share names, within and across their lists.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import renderer.scenefile as scenefile
from renderer.errors import SceneError
from renderer.media.bricks import SparseGrid, to_sparse
from renderer.scene import (
    SCENE_FORMAT_VERSION,
    Camera,
    CornerAttribute,
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
from renderer.shading.program import BIND, BIND_FIELDS, BIND_SET, INSTR, OP, ImageTexture, ShaderProgram

# Names a Blender user can give objects: path syntax, spaces, unicode, 200 characters,
# names equal but for case, and names that look like the file names of earlier versions.
AWKWARD_NAMES = [
    "UVMap", "uv:UVMap", "Cube", "cube", "CUBE", "a/b", "../../etc/passwd", "..", ".", "/abs",
    "sp ace", "tab\there", "ünïcødé ✓ 立方体", "x" * 200, "X" * 200, "con", "nul.txt",
    "mesh0_Cube", "mesh1.vertices", "attributes0_uv_UVMap", "-", "C:\\temp",
]


# ------------------------------------------------------------------------- comparison


def assert_same_scene(saved: Any, loaded: Any, path: str = "scene") -> None:
    """Equal on every field, recursively, with the same types; arrays bitwise equal with the
    same dtype and shape. A SparseGrid is saved dense, so it is compared as its dense array."""
    if isinstance(saved, SparseGrid):
        saved = saved.to_dense()
    assert type(saved) is type(loaded), f"{path}: {type(saved).__name__} != {type(loaded).__name__}"
    if dataclasses.is_dataclass(saved):
        for f in dataclasses.fields(saved):
            assert_same_scene(getattr(saved, f.name), getattr(loaded, f.name), f"{path}.{f.name}")
    elif isinstance(saved, list | tuple):
        assert len(saved) == len(loaded), f"{path}: {len(saved)} items != {len(loaded)}"
        for i, (a, b) in enumerate(zip(saved, loaded)):
            assert_same_scene(a, b, f"{path}[{i}]")
    elif isinstance(saved, np.ndarray):
        assert (saved.dtype, saved.shape) == (loaded.dtype, loaded.shape), path
        assert saved.tobytes() == loaded.tobytes(), f"{path}: values differ"
    else:
        assert saved == loaded, f"{path}: {saved!r} != {loaded!r}"


def _instances(value: Any) -> list[Any]:
    """Every dataclass instance in `value`, recursively."""
    found, stack = [], [value]
    while stack:
        node = stack.pop()
        if dataclasses.is_dataclass(node) and not isinstance(node, SparseGrid):
            found.append(node)
            stack.extend(getattr(node, f.name) for f in dataclasses.fields(node))
        elif isinstance(node, list | tuple):
            stack.extend(node)
    return found


def _default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return dataclasses.MISSING  # required: any value is "set"


def _is_default(value: Any, default: Any) -> bool:
    if default is dataclasses.MISSING or dataclasses.is_dataclass(value):
        return False  # required, or an object whose own fields are checked one by one
    if isinstance(default, np.ndarray) or isinstance(value, np.ndarray):
        both = isinstance(value, np.ndarray) and isinstance(default, np.ndarray)
        return both and np.array_equal(value, default)
    return value == default


def fields_left_at_default(scene: Scene) -> set[str]:
    """Class.field names no object in `scene` sets to a non-default value."""
    at_default: dict[str, bool] = {}
    for node in _instances(scene):
        for f in dataclasses.fields(node):
            key = f"{type(node).__name__}.{f.name}"
            at_default[key] = at_default.get(key, True) and _is_default(getattr(node, f.name), _default(f))
    # A light's `type` is its class's tag: always its default, and checked by the class.
    return {key for key, unset in at_default.items() if unset and not key.endswith("Light.type")}


# ------------------------------------------------------------------ programs and scenes


def _row(op: str, dst: int, a: int = 0, i0: int = 0, i1: int = 0, i2: int = 0) -> list[int]:
    row = [0] * INSTR.size
    row[INSTR.offset("op")], row[INSTR.offset("dst")], row[INSTR.offset("a")] = OP[op], dst, a
    row[INSTR.offset("i0")], row[INSTR.offset("i1")], row[INSTR.offset("i2")] = i0, i1, i2
    return row


def image_program(image: str, registers: np.ndarray) -> ShaderProgram:
    """UVs (attribute 0, "uv:UVMap") into an image's colour, which sets lobe 0's colour."""
    code = np.array([_row("attribute", 0, i0=0, i1=2), _row("image", 3, a=0, i0=0, i1=1)], np.int32)
    bind = [0] * BIND.size
    bind[BIND.offset("lobe")], bind[BIND.offset("field")] = 0, BIND_FIELDS.index("color")
    bind[BIND.offset("width")], bind[BIND.offset("reg")], bind[BIND.offset("mode")] = 3, 3, BIND_SET
    data = np.linspace(0.0, 1.0, 7, dtype=np.float32)
    return ShaderProgram(code, registers, np.array([bind], np.int32), data, ["uv:UVMap"], [image])


def density_program() -> ShaderProgram:
    """A procedural density: the x of the world position."""
    code = np.array([_row("position", 0)], np.int32)
    return ShaderProgram(code, np.zeros(3, np.float32), np.zeros((0, BIND.size), np.int32))


def _matrix(angle: float, translation: tuple[float, float, float]) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    matrix = np.eye(4)
    matrix[:2, :2] = [[c, -s], [s, c]]
    matrix[:3, 3] = translation
    return matrix


def _attribute(name: str, triangles: int, width: int, value: float) -> CornerAttribute:
    values = value + np.arange(triangles * 3 * width, dtype=np.float32).reshape(triangles, 3, width) / 64
    return CornerAttribute(name, values)


def every_field_scene() -> Scene:
    """A valid scene in which every field of every class holds a value other than its default
    (fields_left_at_default is empty), with names shared across and within kinds."""
    rng = np.random.default_rng(42)
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    two_triangles = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    lobes = [
        Lobe("plastic", (0.5, 0.6, 0.7), (0.1, 0.2, 0.3), 0.4, 1.33, "front", "constant", (0.9, 0.8, 0.7),
             True),
        Lobe("rough_conductor", color=(0.9, 0.6, 0.2), roughness=0.2, fresnel="f82", sides="back"),
    ]
    materials = [
        Material("Cube", lobes, (0.5, 0.25, 0.125), "both", image_program("Cube", rng.random(7, np.float32))),
        Material("cube", [Lobe("diffuse")], program=image_program("x" * 200, rng.random(7, np.float32))),
    ]
    meshes = [
        Mesh("Cube", quad, two_triangles, ["Cube", "cube"], np.array([1, 0], np.int32),
             rng.random((4, 3), dtype=np.float32), "Cube",
             [_attribute("uv:UVMap", 2, 2, 0.25), _attribute("generated", 2, 3, 5.0)]),
        Mesh("cube", quad + 2, two_triangles, ["cube"], attributes=[_attribute("uv:UVMap", 2, 2, 0.75)]),
        Mesh("../a/b ünï", quad - 2, two_triangles, ["Cube"], attributes=[_attribute("uv:UVMap", 2, 1, 9.0)]),
    ]
    media = [
        Medium("Cube", "grid", (0.1, 0.2, 0.3), (1.0, 2.0, 3.0), 2.5, 0.4, (0.3, 0.2, 0.1),
               rng.random((3, 4, 5), dtype=np.float32), (-1.0, -2.0, -3.0), (1.0, 2.0, 3.5),
               _matrix(0.3, (1.0, 2.0, 3.0)), rng.random((2, 2, 3), dtype=np.float32),
               1000.0 * rng.random((2, 3, 2), dtype=np.float32), 0.3),
        Medium("cube", "grid", sigma_s=(1.0, 1.0, 1.0), program=density_program(), program_density=1),
    ]
    camera = Camera(_matrix(0.7, (0.0, -5.0, 1.0)), 55.0, "y", (0.1, -0.2), 0.01, 500.0, "equirectangular",
                    3.0, 0.05, 4.0, 6, 0.2, 1.5, -2.0, 2.5, -1.0, 1.25, 3.0, 8.0, 24.0)
    film = Film(40, 30, (2, 3, 20, 10), True, True, True, 1.0, 10.0, 1.0)
    settings_ = IntegratorSettings(7, 5, 2**63 + 5, 2, "nee", "delta", "uniform", False, False, 2048, 2.5)
    environment = Environment((0.5, 0.4, 0.3), rng.random((4, 8, 3), dtype=np.float32), "closest",
                              "mirror_ball", _matrix(1.1, (0.0, 0.0, 0.0)))
    images = [
        ImageTexture("Cube", rng.random((3, 5, 4), dtype=np.float32), True),
        ImageTexture("x" * 200, rng.random((7, 2, 4), dtype=np.float32)),
    ]
    lights = [
        PointLight((1.0, 2.0, 3.0), (4.0, 5.0, 6.0)),
        SpotLight((0.0, 1.0, 2.0), (0.0, 0.0, -1.0), (3.0, 2.0, 1.0), 30.0, 0.5),
        SunLight((0.2, 0.3, 1.0), (2.0, 2.0, 2.0), 1.5),
    ]
    return Scene(camera, film, settings_, materials, meshes, lights, media, environment, "cube", images)


def _array_fields(value: Any, path: str = "") -> list[str]:
    """Field paths of every data array (not the inline matrices) in a scene."""
    if isinstance(value, np.ndarray | SparseGrid):
        return [path]
    if dataclasses.is_dataclass(value):
        return [p for f in dataclasses.fields(value) if f.name != "to_world"
                for p in _array_fields(getattr(value, f.name), f"{path}.{f.name}" if path else f.name)]
    if isinstance(value, list):
        return [p for i, item in enumerate(value) for p in _array_fields(item, f"{path}[{i}]")]
    return []


# ------------------------------------------------------------------------------- tests


def test_the_every_field_scene_sets_every_field() -> None:
    assert fields_left_at_default(every_field_scene()) == set()
    assert fields_left_at_default(Scene()) >= {"Scene.meshes", "Camera.fov"}  # the check can fail


def test_every_field_round_trips(tmp_path: Path) -> None:
    scene = every_field_scene()
    save_scene(scene, tmp_path)  # validates, and so normalises, `scene` in place
    assert_same_scene(scene, load_scene(tmp_path))


def test_two_meshes_sharing_a_uv_map_name_keep_their_own_uvs(tmp_path: Path) -> None:
    """The case of issue 42: mesh 0's UVs 0.25 came back as mesh 1's 0.75."""
    scene = every_field_scene()
    save_scene(scene, tmp_path)
    loaded = load_scene(tmp_path)
    uvs = [float(mesh.attributes[0].values[0, 0, 0]) for mesh in loaded.meshes]
    assert uvs == [0.25, 0.75, 9.0]
    assert [mesh.attributes[0].values.shape[2] for mesh in loaded.meshes] == [2, 2, 1]


def test_every_array_has_its_own_file_inside_arrays(tmp_path: Path) -> None:
    scene = every_field_scene()
    data = json.loads(save_scene(scene, tmp_path).read_text())
    fields = _array_fields(scene)
    files = [_json_at(data, field) for field in fields]
    # 8 program arrays, 12 of meshes, 7 of media, 3 images: each its own file.
    assert len(set(f.casefold() for f in files)) == len(fields) == 30
    arrays = (tmp_path / "arrays").resolve()
    for file in files:
        assert (tmp_path / file).resolve().parent == arrays and (tmp_path / file).is_file(), file
    assert data["meshes"][1]["attributes"][0]["values"] == "arrays/mesh1.attribute0.values.npy"
    assert data["materials"][0]["program"]["code"] == "arrays/material0.program.code.npy"
    assert data["environment"]["radiance_map"] == "arrays/environment.radiance_map.npy"
    assert sorted(p.name for p in arrays.iterdir()) == sorted(Path(f).name for f in files)


def _json_at(data: Any, path: str) -> Any:
    for part in path.replace("[", ".[").split("."):
        data = data[int(part[1:-1])] if part.startswith("[") else data[part]
    return data


def test_save_refuses_to_write_two_fields_to_one_file(tmp_path: Path, monkeypatch) -> None:
    """Were file names ever to repeat (here: list items named without their index, as
    version 2 named attributes), the second field is refused, not written over the first."""
    def without_index(self, list_field: str, index: int) -> scenefile._Place:
        return scenefile._Place(f"{self.path}[{index}]", (*self.stem[:-1], list_field))

    monkeypatch.setattr(scenefile._Place, "item", without_index)
    with pytest.raises(SceneError, match=r"^materials\[1\]\.program\.code: would be written to "
                                         r"arrays/materials\.program\.code\.npy, the file of materials\[0\]"):
        save_scene(every_field_scene(), tmp_path)
    assert list(tmp_path.iterdir()) == []  # refused before anything was written


def test_a_sparse_grid_is_saved_dense(tmp_path: Path) -> None:
    scene = every_field_scene()
    scene.media[0].density = to_sparse(np.pad(scene.media[0].density, ((0, 9), (0, 0), (0, 12))))
    save_scene(scene, tmp_path)
    assert_same_scene(scene, load_scene(tmp_path))


# -------------------------------------------------------------------------- versions


def _as_version_2(folder: Path, rename: dict[str, str]) -> None:
    """Rewrite a saved folder as version 2 with the given files renamed (old-style names)."""
    text = (folder / "scene.json").read_text()
    for new, old in rename.items():
        if (folder / new).exists():
            (folder / new).replace(folder / old)
        text = text.replace(f'"{new}"', f'"{old}"')
    data = json.loads(text)
    data["version"] = 2
    (folder / "scene.json").write_text(json.dumps(data))


def test_a_version_2_folder_that_lost_nothing_is_read(tmp_path: Path) -> None:
    scene = every_field_scene()
    save_scene(scene, tmp_path)
    _as_version_2(tmp_path, {"arrays/mesh0.vertices.npy": "arrays/mesh0_Cube_vertices.npy"})
    assert_same_scene(scene, load_scene(tmp_path))


def test_a_version_2_folder_whose_meshes_shared_an_attribute_file_is_refused(tmp_path: Path) -> None:
    save_scene(every_field_scene(), tmp_path)
    # What format 2's save_scene wrote: both meshes' "uv:UVMap" in one file, the last kept.
    shared = "arrays/attributes0_uv_UVMap_values.npy"
    _as_version_2(tmp_path, {"arrays/mesh0.attribute0.values.npy": "arrays/unused.npy",
                             "arrays/mesh1.attribute0.values.npy": shared})
    text = (tmp_path / "scene.json").read_text().replace('"arrays/unused.npy"', f'"{shared}"')
    (tmp_path / "scene.json").write_text(text)
    message = (r"^meshes\[0\]\.attributes\[0\]\.values: this folder is scene format version 2, and "
               r"meshes\[0\]\.attributes\[0\]\.values and meshes\[1\]\.attributes\[0\]\.values all name "
               r"the file 'arrays/attributes0_uv_UVMap_values.npy'.*export or save the scene again")
    with pytest.raises(SceneError, match=message):
        load_scene(tmp_path)


@pytest.mark.parametrize("version", [0, 1, SCENE_FORMAT_VERSION + 1])
def test_other_versions_are_refused_naming_the_version(tmp_path: Path, version: int) -> None:
    save_scene(every_field_scene(), tmp_path)
    data = json.loads((tmp_path / "scene.json").read_text())
    data["version"] = version
    (tmp_path / "scene.json").write_text(json.dumps(data))
    with pytest.raises(SceneError, match=rf"^version: unsupported format version {version} "
                                         rf"\(this Haze reads versions 2 and {SCENE_FORMAT_VERSION}"):
        load_scene(tmp_path)


# -------------------------------------------------------------------- property-based

_names = st.sampled_from(AWKWARD_NAMES) | st.text(min_size=1, max_size=12)
_unit = st.floats(0.0, 1.0, width=32)
_rgb = st.tuples(_unit, _unit, _unit)


def _floats(shape: tuple[int, ...], draw, low: float = -10.0, high: float = 10.0) -> np.ndarray:
    seed = draw(st.integers(0, 2**32 - 1))
    return np.random.default_rng(seed).uniform(low, high, shape).astype(np.float32)


@st.composite
def scenes(draw) -> Scene:
    """Valid scenes whose lists reuse names: meshes, materials, media and images draw their
    names from one pool (unique within a list, as the format requires)."""
    pool = draw(st.lists(_names, min_size=1, max_size=5, unique=True))
    pick = st.lists(st.sampled_from(pool), max_size=len(pool), unique=True)
    image_names, medium_names = draw(pick), draw(pick)
    material_names = draw(st.lists(st.sampled_from(pool), min_size=1, max_size=len(pool), unique=True))
    mesh_names = draw(st.lists(st.sampled_from(pool), min_size=1, max_size=len(pool), unique=True))
    sizes = st.integers(1, 5)
    images = [ImageTexture(name, _floats((draw(sizes), draw(sizes), 4), draw, 0.0, 1.0), draw(st.booleans()))
              for name in image_names]
    materials = []
    for name in material_names:
        program = None
        if images and draw(st.booleans()):
            program = image_program(draw(st.sampled_from(image_names)), _floats((7,), draw))
        materials.append(Material(name, [Lobe("diffuse", color=draw(_rgb))], draw(_rgb), program=program))
    media = [Medium(name, sigma_s=draw(_rgb)) if draw(st.booleans()) else
             Medium(name, "grid", sigma_a=draw(_rgb), density=_floats((2, 3, draw(sizes)), draw, 0.0, 2.0))
             for name in medium_names]
    meshes = []
    for name in mesh_names:
        vertices = _floats((draw(st.integers(3, 6)), 3), draw)
        triangles = draw(st.integers(1, 4))
        indices = np.asarray(draw(st.lists(st.integers(0, len(vertices) - 1), min_size=3 * triangles,
                                           max_size=3 * triangles)), np.int32).reshape(triangles, 3)
        names = draw(st.lists(st.sampled_from(["uv:UVMap", "uv:UVMap.001", "generated", *pool]),
                              max_size=3, unique=True))
        widths = st.integers(1, 3)
        attributes = [CornerAttribute(n, _floats((triangles, 3, draw(widths)), draw)) for n in names]
        used = draw(st.lists(st.sampled_from(material_names), min_size=1, max_size=3, unique=True))
        ids = np.asarray(draw(st.lists(st.integers(0, len(used) - 1), min_size=triangles,
                                       max_size=triangles)), np.int32)
        normals = _floats(vertices.shape, draw) if draw(st.booleans()) else None
        medium = draw(st.sampled_from(medium_names)) if medium_names and draw(st.booleans()) else None
        meshes.append(Mesh(name, vertices, indices, used, ids, normals, medium, attributes))
    width, height = draw(st.integers(1, 64)), draw(st.integers(1, 64))
    return Scene(
        camera=Camera(fov=draw(st.floats(1.0, 170.0)), clip_start=draw(st.floats(1e-6, 1.0))),
        film=Film(width, height, transparent=draw(st.booleans())),
        integrator=IntegratorSettings(spp=draw(st.integers(1, 4096)), seed=draw(st.integers(0, 2**64 - 1))),
        materials=materials, meshes=meshes, media=media, images=images,
        lights=[PointLight(draw(_rgb), draw(_rgb))] if draw(st.booleans()) else [],
        environment=Environment(draw(_rgb)),
        medium=draw(st.sampled_from(medium_names)) if medium_names and draw(st.booleans()) else None,
    )


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(scene=scenes())
def test_generated_scenes_round_trip_exactly(tmp_path_factory, scene: Scene) -> None:
    folder = tmp_path_factory.mktemp("scene")
    save_scene(scene, folder)
    assert_same_scene(scene, load_scene(folder))
    # Saving the loaded scene again changes nothing: the folder is a fixed point.
    again = tmp_path_factory.mktemp("again")
    assert save_scene(load_scene(folder), again).read_text() == (folder / "scene.json").read_text()


# ------------------------------------------------------------------ the written format

DOC = Path(__file__).resolve().parents[1] / "docs" / "scene-format.md"
# The doc's sections of keys, and the classes whose fields they must list exactly.
DOC_SECTIONS = {
    "Top level": (Scene,), "`camera`": (Camera,), "`film`": (Film,), "`integrator`": (IntegratorSettings,),
    "Material": (Material,), "Lobe": (Lobe,), "Mesh": (Mesh,), "CornerAttribute": (CornerAttribute,),
    "ShaderProgram": (ShaderProgram,), "Image": (ImageTexture,), "Light": (PointLight, SpotLight, SunLight),
    "Medium": (Medium,), "`environment`": (Environment,),
}


def _documented_keys(text: str) -> dict[str, set[str]]:
    """Section title (up to its first " (") -> the backticked names in its tables' key column."""
    keys: dict[str, set[str]] = {}
    for section in text.split("\n### ")[1:]:
        title = section.splitlines()[0].split(" (")[0].strip()
        rows = [line for line in section.splitlines() if line.startswith("| `")]
        keys[title] = {name for row in rows for name in re.findall(r"`(\w+)`", row.split("|")[1])}
    return keys


def test_the_format_doc_lists_every_key_of_every_class() -> None:
    documented = _documented_keys(DOC.read_text())
    for title, classes in DOC_SECTIONS.items():
        fields = {f.name for cls in classes for f in dataclasses.fields(cls)}
        if classes == (Scene,):
            fields |= {"version", "generator"}  # the header keys
        keys = documented[title] | ({"type"} if title == "Light" else set())  # `type`: in the prose
        assert keys == fields, (title, keys ^ fields)


def test_the_format_doc_lists_the_opcodes_in_order() -> None:
    from renderer.shading.program import OPCODES

    table = DOC.read_text().split("<!-- opcodes:")[1].split("\n\n")[0]
    cells = re.findall(r"\| (\d+) \| `(\w+)` ", table)
    assert sorted((int(code), name) for code, name in cells) == list(enumerate(OPCODES))


def test_the_format_doc_lists_every_array_field() -> None:
    text = DOC.read_text()
    for field in _array_fields(every_field_scene()):
        generic = re.sub(r"\[\d+\]", "[i]", field, count=1)
        generic = re.sub(r"\[\d+\]", "[j]", generic)
        generic = re.sub(r"(media\[i\]\.program)\.\w+", r"\1.*", generic)
        assert f"| `{generic}` |" in text, field


def test_a_name_that_is_not_unicode_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    scene = every_field_scene()
    scene.images[1].name = scene.materials[1].program.images[0] = "bad \ud800 name"
    with pytest.raises(SceneError, match=r"^materials\[1\]\.program\.images\[0\]: is not valid Unicode"):
        save_scene(scene, tmp_path)
    assert list(tmp_path.iterdir()) == []
