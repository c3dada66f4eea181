"""The scene folder format (`scene.json` plus `.npy` arrays) and the scene validator.

`load_scene` checks what only a file can get wrong (JSON structure and types, unknown keys,
missing keys and files, array dtypes in files, the format version); `validate_scene` checks
what any Scene can get wrong, so the Blender exporter's in-memory scenes get the same checks
as files. Every problem is a `SceneError` naming the field, e.g. `meshes[2].vertices`.
The format itself is described in docs/scene-format.md.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import numbers
import os
import re
import tempfile
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from renderer.errors import SceneError
from renderer.scene import (
    SCENE_FORMAT_VERSION,
    Camera,
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

SCENE_FILE = "scene.json"
ARRAY_DIR = "arrays"

# The one registry of light kinds: the JSON `type` tag of each light class.
LIGHT_TYPES: dict[str, type] = {"point": PointLight, "spot": SpotLight, "sun": SunLight}

MEDIUM_TYPES = ("homogeneous", "grid")
LOBE_KINDS = ("diffuse", "dielectric", "conductor", "rough_conductor", "plastic", "transparent")
SIDES = ("front", "back", "both")
FRESNEL_MODES = ("constant", "f82")
CONDUCTOR_KINDS = ("conductor", "rough_conductor")
FOV_AXES = ("x", "y")
SAMPLING_MODES = ("mis", "nee", "bsdf")
TRANSMITTANCE_MODES = ("ratio", "delta")
DISTANCE_SAMPLING_MODES = ("spectral_mis", "uniform")
MAX_FILM_SIDE = 16384
MIN_BATCH_SIZE, MAX_BATCH_SIZE = 1024, 1 << 22

# Data arrays live in .npy files and must hold exactly these dtypes there (the kernels'
# dtypes), so a file never silently loses precision or range on load.
ARRAY_DTYPES: dict[str, np.dtype] = {
    "vertices": np.dtype(np.float32),
    "indices": np.dtype(np.int32),
    "material_ids": np.dtype(np.int32),
    "normals": np.dtype(np.float32),
    "density": np.dtype(np.float32),
    "flame": np.dtype(np.float32),
    "temperature": np.dtype(np.float32),
}
# Transforms are 16 numbers: written inline in the JSON, where a person can read them.
MATRIX_FIELDS = frozenset({"to_world"})
GRID_ARRAYS = ("density", "flame", "temperature")
# Array file names start with the owner's kind and index: mesh0_Cube_vertices.npy.
_OWNER_PREFIXES = {"meshes": "mesh", "media": "medium"}
# Relative singularity threshold, see _is_singular.
_SINGULAR_TOLERANCE = 1e-12


# ----------------------------------------------------------------------------- public API


def save_scene(scene: Scene, folder: str | Path) -> Path:
    """Validate (and so normalise) `scene`, write it to `folder`, return the scene.json path.

    Only scene.json and our own array files are (over)written; nothing else in the folder
    is touched, so a scene can live next to a user's other files.
    """
    validate_scene(scene)
    folder = Path(folder)
    (folder / ARRAY_DIR).mkdir(parents=True, exist_ok=True)
    data = {"version": SCENE_FORMAT_VERSION, **_encode(scene, "", "scene", _array_writer(folder))}
    return _write_text_atomically(folder / SCENE_FILE, _to_readable_json(data))


def load_scene(folder: str | Path) -> Scene:
    """Read the scene in `folder` (its scene.json and arrays) and validate it."""
    folder = Path(folder)
    data = _read_json(folder / SCENE_FILE)
    _check_version(data)
    body = {key: value for key, value in data.items() if key != "version"}
    scene = _decode_object(body, Scene, "", folder)
    validate_scene(scene)
    return scene


def validate_scene(scene: Scene) -> None:
    """Raise SceneError for the first problem in `scene`.

    Normalises in place on the way: arrays become contiguous float32/int32 (float64 and
    int64 are converted when the values fit), number tuples become tuples of floats and
    matrices float64 arrays, so the compiler can trust the types afterwards.
    """
    if not isinstance(scene, Scene):
        raise SceneError("scene", f"must be a Scene, got {type(scene).__name__}")
    _conform_object(scene, (Scene,), "")
    _check_camera(scene.camera, "camera")
    _check_film(scene.film, "film")
    _check_integrator(scene.integrator, "integrator")
    material_names = _check_unique_names(scene.materials, "materials")
    medium_names = _check_unique_names(scene.media, "media")
    _check_unique_names(scene.meshes, "meshes")
    for i, material in enumerate(scene.materials):
        _check_material(material, f"materials[{i}]")
    for i, mesh in enumerate(scene.meshes):
        _check_mesh(mesh, f"meshes[{i}]", material_names, medium_names)
    for i, light in enumerate(scene.lights):
        _check_light(light, f"lights[{i}]")
    for i, medium in enumerate(scene.media):
        _check_medium(medium, f"media[{i}]")
    _check_nonnegative_rgb(scene.environment.radiance, "environment.radiance")
    _check_reference(scene.medium, medium_names, "medium", "medium")


# ------------------------------------------------------------------- small shared helpers


def _join(path: str, name: str) -> str:
    return f"{path}.{name}" if path else name


def _require(condition: bool, path: str, problem: str) -> None:
    if not condition:
        raise SceneError(path, problem)


def _show(value: Any) -> str:
    """A short description of a bad value for a message (containers by type, not content)."""
    if value is None or isinstance(value, str | numbers.Number | bool | tuple):
        return repr(value)
    return type(value).__name__


@functools.cache
def _field_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _is_union(hint: Any) -> bool:
    return typing.get_origin(hint) in (types.UnionType, typing.Union)


def _split_optional(hint: Any) -> tuple[Any, bool]:
    """(hint without None, whether None is allowed) for `X | None` annotations."""
    if not _is_union(hint) or type(None) not in typing.get_args(hint):
        return hint, False
    rest = tuple(arg for arg in typing.get_args(hint) if arg is not type(None))
    return (rest[0] if len(rest) == 1 else typing.Union[rest]), True  # noqa: UP007


# ----------------------------------------------- conforming: types, finiteness, normalising


def _conform(value: Any, hint: Any, path: str, field_name: str) -> Any:
    """Check `value` against its annotation and return it in canonical form."""
    hint, optional = _split_optional(hint)
    if value is None and optional:
        return None
    if dataclasses.is_dataclass(hint):
        return _conform_object(value, (hint,), path)
    if _is_union(hint):
        return _conform_object(value, typing.get_args(hint), path)
    if typing.get_origin(hint) is list:
        return _conform_list(value, typing.get_args(hint)[0], path)
    if typing.get_origin(hint) is tuple:
        return _conform_numbers(value, len(typing.get_args(hint)), path)
    if hint is np.ndarray and field_name in MATRIX_FIELDS:
        return _conform_matrix(value, path)
    if hint is np.ndarray:
        return _conform_array(value, ARRAY_DTYPES[field_name], path)
    return _conform_scalar(value, hint, path)


def _conform_object(value: Any, classes: tuple[type, ...], path: str) -> Any:
    if not isinstance(value, classes):
        names = " or ".join(cls.__name__ for cls in classes)
        raise SceneError(path or "scene", f"must be a {names}, got {_show(value)}")
    hints = _field_hints(type(value))
    for f in dataclasses.fields(value):
        conformed = _conform(getattr(value, f.name), hints[f.name], _join(path, f.name), f.name)
        setattr(value, f.name, conformed)
    return value


def _conform_list(value: Any, item_hint: Any, path: str) -> list:
    if not isinstance(value, list):
        raise SceneError(path, f"must be a list, got {_show(value)}")
    return [_conform(item, item_hint, f"{path}[{i}]", "") for i, item in enumerate(value)]


def _conform_numbers(value: Any, length: int, path: str) -> tuple[float, ...]:
    is_sequence = isinstance(value, list | tuple) or (isinstance(value, np.ndarray) and value.ndim == 1)
    if not is_sequence or len(value) != length:
        raise SceneError(path, f"must be a list of {length} numbers, got {_show(value)}")
    if not all(_is_real(x) for x in value):
        raise SceneError(path, f"must be a list of {length} numbers, got {_show(tuple(value))}")
    floats = tuple(_to_float(x) for x in value)
    _require(all(math.isfinite(x) for x in floats), path, f"must be finite, got {floats}")
    return floats


def _to_float(value: numbers.Real) -> float:
    # float() of a huge JSON integer (e.g. 400 digits) raises; report it as non-finite instead.
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _is_real(value: Any) -> bool:
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def _conform_scalar(value: Any, hint: type, path: str) -> Any:
    if hint is float:
        _require(_is_real(value), path, f"must be a number, got {_show(value)}")
        number = _to_float(value)
        _require(math.isfinite(number), path, f"must be finite, got {number}")
        return number
    if hint is int:
        is_int = isinstance(value, numbers.Integral) and not isinstance(value, bool | np.bool_)
        _require(is_int, path, f"must be an integer, got {_show(value)}")
        _require(-(2**63) <= int(value) < 2**64, path, f"integer out of range, got {int(value)}")
        return int(value)
    if hint is bool:
        _require(isinstance(value, bool | np.bool_), path, f"must be true or false, got {_show(value)}")
        return bool(value)
    if hint is str:
        _require(isinstance(value, str), path, f"must be a string, got {_show(value)}")
        return value
    raise TypeError(f"{path}: no conversion for annotation {hint!r}")  # a scene.py change


def _conform_matrix(value: Any, path: str) -> np.ndarray:
    try:
        raw = np.asarray(value)
    except ValueError:  # ragged nested lists
        raise SceneError(path, "must be a 4x4 matrix of numbers") from None
    _require(raw.dtype.kind in "iuf", path, f"must be a 4x4 matrix of numbers, got dtype {raw.dtype}")
    _require(raw.shape == (4, 4), path, f"must be a 4x4 matrix, got shape {raw.shape}")
    matrix = np.array(raw, dtype=np.float64)  # a copy: the scene owns its transforms
    _check_finite_array(matrix, path)
    return matrix


def _conform_array(value: Any, dtype: np.dtype, path: str) -> np.ndarray:
    if not isinstance(value, np.ndarray):
        raise SceneError(path, f"must be a numpy array, got {_show(value)}")
    if dtype.kind == "f":
        return _conform_float_array(value, dtype, path)
    return _conform_int_array(value, dtype, path)


def _conform_float_array(value: np.ndarray, dtype: np.dtype, path: str) -> np.ndarray:
    _require(value.dtype.kind == "f", path, f"must be a float array, got dtype {value.dtype}")
    _check_finite_array(value, path)
    with np.errstate(over="ignore"):
        converted = value.astype(dtype, order="C", copy=False)
    if converted is not value:
        _require(bool(np.isfinite(converted).all()), path, f"values exceed the {dtype} range")
    return converted


def _conform_int_array(value: np.ndarray, dtype: np.dtype, path: str) -> np.ndarray:
    _require(value.dtype.kind in "iu", path, f"must be an integer array, got dtype {value.dtype}")
    if value.dtype != dtype and value.size:
        limits = np.iinfo(dtype)
        fits = limits.min <= int(value.min()) and int(value.max()) <= limits.max
        _require(fits, path, f"values do not fit {dtype}")
    return value.astype(dtype, order="C", copy=False)


def _check_finite_array(array: np.ndarray, path: str) -> None:
    if not np.isfinite(array).all():
        raise SceneError(path, "contains NaN" if np.isnan(array).any() else "contains inf")


# ------------------------------------------------------------------------ semantic checks


def _check_choice(value: str, allowed: tuple[str, ...], path: str, what: str) -> None:
    expected = ", ".join(repr(a) for a in allowed)
    _require(value in allowed, path, f"unknown {what} {value!r} (expected one of {expected})")


def _check_nonnegative_rgb(rgb: tuple[float, ...], path: str) -> None:
    _require(min(rgb) >= 0.0, path, f"must not be negative, got {rgb}")


def _check_nonzero_vector(vector: tuple[float, ...], path: str) -> None:
    _require(any(x != 0.0 for x in vector), path, "must be a non-zero vector")


def _check_reference(name: str | None, known: set[str], path: str, what: str) -> None:
    _require(name is None or name in known, path, f"unknown {what} {name!r}")


def _check_unique_names(items: list, path: str) -> set[str]:
    """The names of `items`, which must be non-empty and unique."""
    first_index: dict[str, int] = {}
    for i, item in enumerate(items):
        _require(item.name != "", f"{path}[{i}].name", "must not be empty")
        if item.name in first_index:
            also = f"{path}[{first_index[item.name]}]"
            raise SceneError(f"{path}[{i}].name", f"duplicate name {item.name!r} (also {also})")
        first_index[item.name] = i
    return set(first_index)


def _is_singular(linear: np.ndarray) -> bool:
    """Whether a 3x3 matrix is singular relative to its scale: |det| <= tol * prod(column norms).

    Columns are first divided by their largest entry, so huge or tiny scales neither
    overflow nor count as singular; a column that overflowed to inf does.
    """
    largest = np.abs(linear).max(axis=0)
    if not np.all(largest > 0.0) or not np.all(np.isfinite(largest)):
        return True
    scaled = linear / largest
    return abs(np.linalg.det(scaled)) <= _SINGULAR_TOLERANCE * np.prod(np.linalg.norm(scaled, axis=0))


def _check_transform(matrix: np.ndarray, path: str) -> None:
    """An invertible affine 4x4 transform (the kernels use only its top three rows)."""
    affine = np.allclose(matrix[3], (0.0, 0.0, 0.0, 1.0), rtol=0.0, atol=1e-9)
    _require(affine, path, f"last row must be (0, 0, 0, 1), got {tuple(matrix[3].tolist())}")
    _require(not _is_singular(matrix[:3, :3]), path, "singular matrix")


def _check_camera(camera: Camera, path: str) -> None:
    _check_transform(camera.to_world, f"{path}.to_world")
    _require(0.0 < camera.fov < 180.0, f"{path}.fov", f"must be in (0, 180) degrees, got {camera.fov}")
    _check_choice(camera.fov_axis, FOV_AXES, f"{path}.fov_axis", "fov axis")
    _require(camera.clip_start > 0.0, f"{path}.clip_start", f"must be > 0, got {camera.clip_start}")
    _require(
        camera.clip_end > camera.clip_start,
        f"{path}.clip_end",
        f"must be > clip_start ({camera.clip_start}), got {camera.clip_end}",
    )


def _check_film(film: Film, path: str) -> None:
    for name in ("width", "height"):
        size = getattr(film, name)
        _require(1 <= size <= MAX_FILM_SIDE, f"{path}.{name}", f"must be in [1, {MAX_FILM_SIDE}], got {size}")


def _check_integrator(settings: IntegratorSettings, path: str) -> None:
    _require(settings.spp >= 1, f"{path}.spp", f"must be >= 1, got {settings.spp}")
    for name in ("max_bounces", "rr_depth"):
        value = getattr(settings, name)
        _require(value >= 0, f"{path}.{name}", f"must be >= 0, got {value}")
    _require(0 <= settings.seed < 2**64, f"{path}.seed", f"must be in [0, 2**64), got {settings.seed}")
    batch = settings.batch_size
    batch_ok = MIN_BATCH_SIZE <= batch <= MAX_BATCH_SIZE
    _require(batch_ok, f"{path}.batch_size", f"must be in [{MIN_BATCH_SIZE}, {MAX_BATCH_SIZE}], got {batch}")
    _check_choice(settings.sampling, SAMPLING_MODES, f"{path}.sampling", "sampling mode")
    _check_choice(settings.transmittance, TRANSMITTANCE_MODES, f"{path}.transmittance", "transmittance mode")
    _check_choice(
        settings.distance_sampling, DISTANCE_SAMPLING_MODES, f"{path}.distance_sampling", "distance sampling"
    )
    limit = settings.time_limit
    _require(limit >= 0.0, f"{path}.time_limit", f"must be >= 0, got {limit}")


def _check_material(material: Material, path: str) -> None:
    for i, lobe in enumerate(material.lobes):
        _check_lobe(lobe, f"{path}.lobes[{i}]")
    _check_nonnegative_rgb(material.emission, f"{path}.emission")
    _check_choice(material.emission_sides, SIDES, f"{path}.emission_sides", "sides value")


def _check_lobe(lobe: Lobe, path: str) -> None:
    _check_choice(lobe.kind, LOBE_KINDS, f"{path}.kind", "lobe kind")
    _check_nonnegative_rgb(lobe.weight, f"{path}.weight")
    _check_nonnegative_rgb(lobe.color, f"{path}.color")
    roughness_ok = 0.0 <= lobe.roughness <= 1.0
    _require(roughness_ok, f"{path}.roughness", f"must be in [0, 1], got {lobe.roughness}")
    _require(lobe.ior > 0.0, f"{path}.ior", f"must be > 0, got {lobe.ior}")
    _check_choice(lobe.sides, SIDES, f"{path}.sides", "sides value")
    _check_choice(lobe.fresnel, FRESNEL_MODES, f"{path}.fresnel", "Fresnel mode")
    fresnel_ok = lobe.fresnel == "constant" or lobe.kind in CONDUCTOR_KINDS
    _require(fresnel_ok, f"{path}.fresnel", f"{lobe.fresnel!r} applies to conductors only, not {lobe.kind!r}")
    tint_ok = len(lobe.tint) == 3 and 0.0 <= min(lobe.tint) and max(lobe.tint) <= 1.0
    _require(tint_ok, f"{path}.tint", f"must be three numbers in [0, 1], got {lobe.tint}")


def _check_mesh(mesh: Mesh, path: str, material_names: set[str], medium_names: set[str]) -> None:
    vertex_count = _check_rows_of_three(mesh.vertices, f"{path}.vertices", "V")
    triangle_count = _check_rows_of_three(mesh.indices, f"{path}.indices", "T")
    _check_index_range(mesh.indices, vertex_count, f"{path}.indices", "vertices")
    if mesh.normals is not None:
        shape_ok = mesh.normals.shape == mesh.vertices.shape
        _require(
            shape_ok, f"{path}.normals", f"must have shape ({vertex_count}, 3), got {mesh.normals.shape}"
        )
    for i, name in enumerate(mesh.materials):
        _check_reference(name, material_names, f"{path}.materials[{i}]", "material")
    _check_material_ids(mesh, triangle_count, path)
    _check_reference(mesh.medium, medium_names, f"{path}.medium", "medium")


def _check_rows_of_three(array: np.ndarray, path: str, rows: str) -> int:
    shape_ok = array.ndim == 2 and array.shape[1] == 3
    _require(shape_ok, path, f"must have shape ({rows}, 3), got {array.shape}")
    return array.shape[0]


def _check_index_range(indices: np.ndarray, count: int, path: str, what: str) -> None:
    """Every index in [0, count); `what` names the indexed list in the message."""
    if indices.size == 0:
        return
    low, high = int(indices.min()), int(indices.max())
    _require(low >= 0, path, f"contains negative index {low}")
    _require(high < count, path, f"index {high} out of range for {count} {what}")


def _check_material_ids(mesh: Mesh, triangle_count: int, path: str) -> None:
    material_count = len(mesh.materials)
    if mesh.material_ids is None:
        has_material = material_count > 0 or triangle_count == 0
        _require(
            has_material, f"{path}.materials", "must name at least one material (the mesh has triangles)"
        )
        return
    ids = mesh.material_ids
    ids_path = f"{path}.material_ids"
    _require(
        ids.shape == (triangle_count,), ids_path, f"must have shape ({triangle_count},), got {ids.shape}"
    )
    _check_index_range(ids, material_count, ids_path, "materials")


def _check_light(light: Any, path: str) -> None:
    _check_choice(light.type, tuple(LIGHT_TYPES), f"{path}.type", "light type")
    matches = LIGHT_TYPES[light.type] is type(light)
    _require(matches, f"{path}.type", f"{light.type!r} does not match a {type(light).__name__}")
    for name in ("intensity", "irradiance"):
        if hasattr(light, name):
            _check_nonnegative_rgb(getattr(light, name), f"{path}.{name}")
    if hasattr(light, "direction"):
        _check_nonzero_vector(light.direction, f"{path}.direction")
    if isinstance(light, SpotLight):
        size_ok = 0.0 < light.spot_size <= 180.0
        _require(size_ok, f"{path}.spot_size", f"must be in (0, 180] degrees, got {light.spot_size}")
        _require(0.0 <= light.blend <= 1.0, f"{path}.blend", f"must be in [0, 1], got {light.blend}")
    if isinstance(light, SunLight):
        _require(
            0.0 <= light.angle < 180.0, f"{path}.angle", f"must be in [0, 180) degrees, got {light.angle}"
        )


def _check_medium(medium: Medium, path: str) -> None:
    _check_choice(medium.type, MEDIUM_TYPES, f"{path}.type", "medium type")
    for name in ("sigma_a", "sigma_s", "emission"):
        _check_nonnegative_rgb(getattr(medium, name), f"{path}.{name}")
    _require(medium.scale >= 0.0, f"{path}.scale", f"must be >= 0, got {medium.scale}")
    _require(abs(medium.g) < 1.0, f"{path}.g", f"must satisfy |g| < 1, got {medium.g}")
    bb = medium.blackbody_intensity
    _require(bb >= 0.0, f"{path}.blackbody_intensity", f"must be >= 0, got {bb}")
    if medium.type == "homogeneous":
        for name in GRID_ARRAYS:
            carries = getattr(medium, name) is not None
            _require(
                not carries, f"{path}.{name}", "only grid media take grid arrays (type is 'homogeneous')"
            )
        return
    _require(medium.density is not None, f"{path}.density", "required for grid media")
    for name in GRID_ARRAYS:
        if getattr(medium, name) is not None:
            _check_grid_array(getattr(medium, name), f"{path}.{name}")
    _check_grid_box(medium, path)


def _check_grid_array(grid: np.ndarray, path: str) -> None:
    _require(grid.ndim == 3, path, f"must be 3-D (nz, ny, nx), got shape {grid.shape}")
    _require(grid.size > 0, path, f"must not be empty, got shape {grid.shape}")
    _require(bool((grid >= 0.0).all()), path, f"must not be negative, got minimum {float(grid.min())}")


def _check_grid_box(medium: Medium, path: str) -> None:
    for axis, low, high in zip("xyz", medium.p0, medium.p1):
        _require(low != high, f"{path}.p1", f"equals p0 on the {axis} axis ({high}): the grid box is flat")
    _check_transform(medium.to_world, f"{path}.to_world")
    with np.errstate(over="ignore"):  # an overflowing box is caught as singular just below
        box_to_world = medium.to_world[:3, :3] @ np.diag(np.subtract(medium.p1, medium.p0))
    _require(not _is_singular(box_to_world), f"{path}.to_world", "singular matrix (combined with p0..p1)")


# -------------------------------------------------------------------------------- loading


def _read_json(file: Path) -> dict:
    if not file.is_file():
        raise SceneError(SCENE_FILE, f"not found in {file.parent}")
    try:
        data = json.loads(file.read_text(encoding="utf-8"), object_pairs_hook=_reject_duplicate_keys)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise SceneError(SCENE_FILE, f"not valid JSON: {error}") from None
    except OSError as error:
        raise SceneError(SCENE_FILE, f"cannot read: {error}") from None
    _require(isinstance(data, dict), SCENE_FILE, f"must hold a JSON object, got {_show(data)}")
    return data


def _reject_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict:
    # json keeps the last of repeated keys silently; a repeated key is almost always a mistake.
    data: dict = {}
    for key, value in pairs:
        _require(key not in data, SCENE_FILE, f"duplicate key {key!r} in one object")
        data[key] = value
    return data


def _check_version(data: dict) -> None:
    _require("version" in data, "version", "missing required key")
    version = data["version"]
    is_int = isinstance(version, int) and not isinstance(version, bool)
    _require(is_int, "version", f"must be an integer, got {_show(version)}")
    supported = version == SCENE_FORMAT_VERSION
    _require(
        supported, "version", f"unsupported format version {version} (this Haze reads {SCENE_FORMAT_VERSION})"
    )


def _decode(value: Any, hint: Any, path: str, field_name: str, folder: Path) -> Any:
    """Turn JSON `value` into the Python value annotated by `hint`."""
    hint, optional = _split_optional(hint)
    if value is None and optional:
        return None
    if dataclasses.is_dataclass(hint):
        return _decode_object(value, hint, path, folder)
    if _is_union(hint):
        return _decode_object(value, _light_class(value, path), path, folder)
    if typing.get_origin(hint) is list:
        _require(isinstance(value, list), path, f"must be a list, got {_show(value)}")
        item_hint = typing.get_args(hint)[0]
        return [_decode(item, item_hint, f"{path}[{i}]", "", folder) for i, item in enumerate(value)]
    if hint is np.ndarray and field_name not in MATRIX_FIELDS:
        return _read_array(value, ARRAY_DTYPES[field_name], path, folder)
    return _conform(value, hint, path, field_name)  # leaves: the same checks as in-memory values


def _decode_object(value: Any, cls: type, path: str, folder: Path) -> Any:
    _require(isinstance(value, dict), path or SCENE_FILE, f"must be a JSON object, got {_show(value)}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key in value:
        expected = ", ".join(fields)
        _require(key in fields, _join(path, key), f"unknown key (expected one of {expected})")
    for f in fields.values():
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        _require(not required or f.name in value, _join(path, f.name), "missing required key")
    hints = _field_hints(cls)
    decoded = {key: _decode(item, hints[key], _join(path, key), key, folder) for key, item in value.items()}
    return cls(**decoded)


def _light_class(value: Any, path: str) -> type:
    _require(isinstance(value, dict), path, f"must be a JSON object, got {_show(value)}")
    _require("type" in value, f"{path}.type", "missing required key")
    kind = value["type"]
    _require(isinstance(kind, str), f"{path}.type", f"must be a string, got {_show(kind)}")
    _check_choice(kind, tuple(LIGHT_TYPES), f"{path}.type", "light type")
    return LIGHT_TYPES[kind]


def _read_array(value: Any, dtype: np.dtype, path: str, folder: Path) -> np.ndarray:
    _require(isinstance(value, str), path, f"must be the name of a .npy file, got {_show(value)}")
    _require(not Path(value).is_absolute(), path, f"must be relative to the scene folder, got {value!r}")
    file = folder / value
    _require(file.is_file(), path, f"file {value!r} not found")
    try:
        array = np.load(file, allow_pickle=False)
    except (OSError, ValueError, EOFError, MemoryError) as error:
        raise SceneError(path, f"cannot read {value!r} as .npy: {error}") from None
    if not isinstance(array, np.ndarray):  # an .npz archive
        array.close()
        raise SceneError(path, f"{value!r} is not a single-array .npy file")
    _require(
        array.dtype == dtype, path, f"file {value!r} holds {array.dtype}; files must hold exactly {dtype}"
    )
    return array


# --------------------------------------------------------------------------------- saving


def _encode(value: Any, field_name: str, owner: str, write_array: Callable[[np.ndarray, str], str]) -> Any:
    """The JSON form of `value`; data arrays are written by `write_array`, which names the file."""
    if dataclasses.is_dataclass(value):
        fields = dataclasses.fields(value)
        encoded = {f.name: _encode(getattr(value, f.name), f.name, owner, write_array) for f in fields}
        return _type_first(encoded) if isinstance(value, tuple(LIGHT_TYPES.values())) else encoded
    if isinstance(value, list):
        return [
            _encode(item, "", _owner_name(field_name, i, item), write_array) for i, item in enumerate(value)
        ]
    if isinstance(value, np.ndarray) and field_name in MATRIX_FIELDS:
        return value.tolist()
    if isinstance(value, np.ndarray):
        return write_array(value, f"{owner}_{field_name}")
    if isinstance(value, tuple):
        return list(value)
    return value


def _type_first(encoded: dict) -> dict:
    # A light's `type` says how to read the rest of it, so it reads best first.
    return {"type": encoded.pop("type"), **encoded}


def _owner_name(list_field: str, index: int, item: Any) -> str:
    """File name stem of a list item's arrays: its kind, index (unique) and name (readable)."""
    prefix = _OWNER_PREFIXES.get(list_field, list_field)
    name = getattr(item, "name", "")
    safe_name = re.sub(r"[^A-Za-z0-9._-]+", "_", name)[:48]
    return f"{prefix}{index}_{safe_name}" if safe_name else f"{prefix}{index}"


def _array_writer(folder: Path) -> Callable[[np.ndarray, str], str]:
    def write_array(array: np.ndarray, stem: str) -> str:
        relative = f"{ARRAY_DIR}/{stem}.npy"
        np.save(folder / relative, array, allow_pickle=False)
        return relative

    return write_array


def _to_readable_json(data: dict) -> str:
    text = json.dumps(data, indent=2, allow_nan=False, ensure_ascii=False)
    # Put flat lists of numbers or plain strings (colours, matrix rows, material names) on one
    # line. JSON strings cannot hold raw newlines, so a match spanning newlines is always
    # structure, never text inside a name.
    item = r'(?:-?\d+(?:\.\d+)?(?:[eE][-+]?\d+)?|"[^"\\\n]*")'
    pattern = re.compile(rf"\[\n\s*({item}(?:,\n\s*{item})*)\n\s*\]")
    return pattern.sub(lambda m: "[" + re.sub(r",\n\s*", ", ", m.group(1)) + "]", text) + "\n"


def _write_text_atomically(file: Path, text: str) -> Path:
    # Write beside the target and rename, so a crash never leaves a half-written scene.json.
    handle, temporary = tempfile.mkstemp(dir=file.parent, prefix=f".{file.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.replace(temporary, file)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
    return file
