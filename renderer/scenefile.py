"""The scene folder format: `scene.json` plus `.npy` arrays, read and written.

`load_scene` checks what only a file can get wrong (JSON structure and types, unknown keys,
missing keys and files, array dtypes in files, the format version), then hands the Scene
to the validator (renderer.validate), which checks what any Scene can get wrong; `save_scene`
validates before writing. Every problem is a `SceneError` naming the field, e.g.
`meshes[2].vertices`. The format itself is described in docs/scene-format.md.
"""

from __future__ import annotations

import dataclasses
import json
import os
import re
import tempfile
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from renderer.conform import (
    ARRAY_DTYPES,
    MATRIX_FIELDS,
    conform,
    field_hints,
    is_union,
    join,
    require,
    show,
    split_optional,
)
from renderer.errors import SceneError
from renderer.scene import LIGHT_TYPES, SCENE_FORMAT_VERSION, Scene
from renderer.validate import check_choice, validate_scene

SCENE_FILE = "scene.json"
ARRAY_DIR = "arrays"
# Array file names start with the owner's kind and index: mesh0_Cube_vertices.npy.
_OWNER_PREFIXES = {"meshes": "mesh", "media": "medium"}


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
    require(isinstance(data, dict), SCENE_FILE, f"must hold a JSON object, got {show(data)}")
    return data


def _reject_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict:
    # json keeps the last of repeated keys silently; a repeated key is almost always a mistake.
    data: dict = {}
    for key, value in pairs:
        require(key not in data, SCENE_FILE, f"duplicate key {key!r} in one object")
        data[key] = value
    return data


def _check_version(data: dict) -> None:
    require("version" in data, "version", "missing required key")
    version = data["version"]
    is_int = isinstance(version, int) and not isinstance(version, bool)
    require(is_int, "version", f"must be an integer, got {show(version)}")
    supported = version == SCENE_FORMAT_VERSION
    require(
        supported, "version", f"unsupported format version {version} (this Haze reads {SCENE_FORMAT_VERSION})"
    )


def _decode(value: Any, hint: Any, path: str, field_name: str, folder: Path) -> Any:
    """Turn JSON `value` into the Python value annotated by `hint`."""
    hint, optional = split_optional(hint)
    if value is None and optional:
        return None
    if dataclasses.is_dataclass(hint):
        return _decode_object(value, hint, path, folder)
    if is_union(hint):
        return _decode_object(value, _light_class(value, path), path, folder)
    if typing.get_origin(hint) is list:
        require(isinstance(value, list), path, f"must be a list, got {show(value)}")
        item_hint = typing.get_args(hint)[0]
        return [_decode(item, item_hint, f"{path}[{i}]", "", folder) for i, item in enumerate(value)]
    if hint is np.ndarray and field_name not in MATRIX_FIELDS:
        return _read_array(value, ARRAY_DTYPES[field_name], path, folder)
    return conform(value, hint, path, field_name)  # leaves: the same checks as in-memory values


def _decode_object(value: Any, cls: type, path: str, folder: Path) -> Any:
    require(isinstance(value, dict), path or SCENE_FILE, f"must be a JSON object, got {show(value)}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key in value:
        expected = ", ".join(fields)
        require(key in fields, join(path, key), f"unknown key (expected one of {expected})")
    for f in fields.values():
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        require(not required or f.name in value, join(path, f.name), "missing required key")
    hints = field_hints(cls)
    decoded = {key: _decode(item, hints[key], join(path, key), key, folder) for key, item in value.items()}
    return cls(**decoded)


def _light_class(value: Any, path: str) -> type:
    require(isinstance(value, dict), path, f"must be a JSON object, got {show(value)}")
    require("type" in value, f"{path}.type", "missing required key")
    kind = value["type"]
    require(isinstance(kind, str), f"{path}.type", f"must be a string, got {show(kind)}")
    check_choice(kind, LIGHT_TYPES, f"{path}.type", "light type")
    return LIGHT_TYPES[kind]


def _read_array(value: Any, dtype: np.dtype, path: str, folder: Path) -> np.ndarray:
    require(isinstance(value, str), path, f"must be the name of a .npy file, got {show(value)}")
    require(not Path(value).is_absolute(), path, f"must be relative to the scene folder, got {value!r}")
    file = folder / value
    require(file.is_file(), path, f"file {value!r} not found")
    try:
        array = np.load(file, allow_pickle=False)
    except (OSError, ValueError, EOFError, MemoryError) as error:
        raise SceneError(path, f"cannot read {value!r} as .npy: {error}") from None
    if not isinstance(array, np.ndarray):  # an .npz archive
        array.close()
        raise SceneError(path, f"{value!r} is not a single-array .npy file")
    require(
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
