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
import math
import os
import re
import tempfile
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from renderer.errors import SceneError
from renderer.scene import LIGHT_TYPES, SCENE_FORMAT_VERSION, Scene
from renderer.validate import validate_scene
from renderer.validate.checks import check_choice
from renderer.validate.conform import (
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

SCENE_FILE = "scene.json"
ARRAY_DIR = "arrays"
# Optional top-level key naming the program that wrote the folder. The add-on's exporter
# writes EXPORT_GENERATOR and recognises its own previous exports by it (see addon/export/folder.py).
GENERATOR_KEY = "generator"
EXPORT_GENERATOR = "haze-export"
# Real scenes nest five levels deep; far deeper JSON is an attack or a bug, not a scene.
MAX_JSON_DEPTH = 16
# scene.json holds no bulk data (arrays live in .npy files): a larger one is not a scene, and
# reading it whole could exhaust memory.
MAX_SCENE_JSON_BYTES = 64 * 1024 * 1024
# Python refuses to convert integers of more than 4300 digits (a traceback); longer ones are
# read as +-inf, so the field they sit in reports them as not finite (or not an integer).
MAX_INTEGER_DIGITS = 4000
# Versions this Haze reads. 2 differs from 3 only in how save_scene named array files: it
# named a corner attribute's file after the attribute alone, so meshes sharing an attribute
# name (every Blender mesh has "uv:UVMap") shared one file and kept the last mesh's values.
# A version 2 folder is read unless two fields name one file (_refuse_shared_v2_files).
READABLE_VERSIONS = (2, SCENE_FORMAT_VERSION)
# An array file is named by where its field sits in the scene, never by a user's name:
# list items by their kind and index, then field names, joined by ".", e.g.
# arrays/mesh1.attribute0.values.npy. Every part is an identifier (plus an index), so two
# fields can never share a name, on case-insensitive file systems too, and no name leaves
# arrays/. The kind of an item of each list field:
_ITEM_KINDS = {
    "meshes": "mesh",
    "media": "medium",
    "materials": "material",
    "images": "image",
    "attributes": "attribute",
    "lights": "light",
    "lobes": "lobe",
}
_ARRAY_STEM = re.compile(r"[a-z][a-z0-9_]*(\.[a-z][a-z0-9_]*)*")


# ----------------------------------------------------------------------------- public API


def save_scene(scene: Scene, folder: str | Path, generator: str | None = None) -> Path:
    """Validate (and so normalise) `scene`, write it to `folder`, return the scene.json path.

    Only scene.json and our own array files are (over)written; nothing else in the folder
    is touched, so a scene can live next to a user's other files. `generator`, if given, is
    written as scene.json's "generator" key (the exporter's mark on its folders).
    """
    validate_scene(scene)
    folder = Path(folder)
    header: dict[str, Any] = {"version": SCENE_FORMAT_VERSION}
    if generator is not None:
        header[GENERATOR_KEY] = generator
    # Everything is named and checked before the first file is written: a refused scene
    # leaves the folder as it was.
    arrays = _ArrayWriter(folder)
    text = _to_readable_json({**header, **_encode(scene, "", _Place(), arrays)})
    (folder / ARRAY_DIR).mkdir(parents=True, exist_ok=True)
    arrays.write_all()
    return _write_text_atomically(folder / SCENE_FILE, text)


def load_scene(folder: str | Path) -> Scene:
    """Read the scene in `folder` (its scene.json and arrays) and validate it."""
    return load_scene_and_inputs(folder)[0]


def load_scene_and_inputs(folder: str | Path) -> tuple[Scene, list[Path]]:
    """The validated scene in `folder` and the files it was read from (scene.json first).

    The command line refuses to write its output over any of these files.
    """
    source = _Source(Path(folder))
    data = _read_json(source.folder / SCENE_FILE)
    source.files.append(source.folder / SCENE_FILE)
    version = _check_version(data)
    _check_generator(data)
    body = {key: value for key, value in data.items() if key not in ("version", GENERATOR_KEY)}
    scene = _decode_object(body, Scene, "", source)
    if version == 2:
        _refuse_shared_v2_files(source)
    validate_scene(scene)
    return scene, source.files


def read_generator(folder: str | Path) -> str | None:
    """The "generator" of the scene.json in `folder`, or None if it has none or is no scene."""
    try:
        data = _read_json(Path(folder) / SCENE_FILE)
    except SceneError:
        return None
    generator = data.get(GENERATOR_KEY)
    return generator if isinstance(generator, str) else None


# -------------------------------------------------------------------------------- loading


@dataclasses.dataclass
class _Source:
    """The scene folder being read, and every file read from it so far."""

    folder: Path
    files: list[Path] = dataclasses.field(default_factory=list)
    # Each array file read, and the fields (paths like meshes[0].vertices) that named it.
    readers: dict[Path, list[str]] = dataclasses.field(default_factory=dict)


def _read_json(file: Path) -> dict:
    if not file.is_file():
        raise SceneError(SCENE_FILE, f"not found in {file.parent}")
    try:
        size = file.stat().st_size
        too_large = f"is {size} bytes, more than the {MAX_SCENE_JSON_BYTES} bytes a scene.json may have"
        require(size <= MAX_SCENE_JSON_BYTES, SCENE_FILE, too_large)
        text = file.read_text(encoding="utf-8")
        data = json.loads(text, object_pairs_hook=_reject_duplicate_keys, parse_int=_parse_bounded_int)
    except SceneError:
        raise
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise SceneError(SCENE_FILE, f"not valid JSON: {error}") from None
    except RecursionError:
        raise SceneError(SCENE_FILE, f"nested deeper than {MAX_JSON_DEPTH} levels") from None
    except (OSError, ValueError) as error:
        raise SceneError(SCENE_FILE, f"cannot read: {error}") from None
    except MemoryError:
        raise SceneError(SCENE_FILE, "too large to read into memory") from None
    require(isinstance(data, dict), SCENE_FILE, f"must hold a JSON object, got {show(data)}")
    depth = _nesting_depth(data)
    require(depth <= MAX_JSON_DEPTH, SCENE_FILE, f"nested {depth} levels deep (at most {MAX_JSON_DEPTH})")
    return data


def _parse_bounded_int(text: str) -> int | float:
    if len(text.lstrip("-")) <= MAX_INTEGER_DIGITS:
        return int(text)
    return -math.inf if text.startswith("-") else math.inf


def _nesting_depth(data: Any) -> int:
    """How many objects and lists deep `data` nests, measured without recursion."""
    deepest = 0
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        deepest = max(deepest, depth)
        children = value.values() if isinstance(value, dict) else value
        stack.extend((child, depth + 1) for child in children if isinstance(child, dict | list))
    return deepest


def _reject_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict:
    # json keeps the last of repeated keys silently; a repeated key is almost always a mistake.
    data: dict = {}
    for key, value in pairs:
        require(key not in data, SCENE_FILE, f"duplicate key {key!r} in one object")
        data[key] = value
    return data


def _check_version(data: dict) -> int:
    require("version" in data, "version", "missing required key")
    version = data["version"]
    is_int = isinstance(version, int) and not isinstance(version, bool)
    require(is_int, "version", f"must be an integer, got {show(version)}")
    readable = " and ".join(str(v) for v in READABLE_VERSIONS)
    require(
        version in READABLE_VERSIONS,
        "version",
        f"unsupported format version {show(version)} (this Haze reads versions {readable}; "
        "export or save the scene again with this Haze)",
    )
    return version


def _refuse_shared_v2_files(source: _Source) -> None:
    """A version 2 folder in which two fields name one file lost data when it was written.

    save_scene of format 2 named corner-attribute files after the attribute alone, so every
    mesh with a "uv:UVMap" wrote the same file and only the last mesh's values survived:
    reading such a folder would silently put one mesh's UVs on another.
    """
    for file, fields in source.readers.items():
        if len(fields) > 1:
            shown = show(file.relative_to(source.folder.resolve()).as_posix())
            raise SceneError(
                fields[0],
                f"this folder is scene format version 2, and {' and '.join(fields)} all name "
                f"the file {shown}: the Haze that wrote it saved the values of meshes sharing "
                "an attribute name to one file, keeping only the last; export or save the "
                f"scene again with this Haze (format {SCENE_FORMAT_VERSION})",
            )


def _check_generator(data: dict) -> None:
    generator = data.get(GENERATOR_KEY, "")
    require(isinstance(generator, str), GENERATOR_KEY, f"must be a string, got {show(generator)}")


def _decode(value: Any, hint: Any, path: str, field_name: str, source: _Source) -> Any:
    """Turn JSON `value` into the Python value annotated by `hint`."""
    hint, optional = split_optional(hint)
    if value is None and optional:
        return None
    if dataclasses.is_dataclass(hint):
        return _decode_object(value, hint, path, source)
    if is_union(hint):
        return _decode_object(value, _light_class(value, path), path, source)
    if typing.get_origin(hint) is list:
        require(isinstance(value, list), path, f"must be a list, got {show(value)}")
        item_hint = typing.get_args(hint)[0]
        return [_decode(item, item_hint, f"{path}[{i}]", "", source) for i, item in enumerate(value)]
    if hint is np.ndarray and field_name not in MATRIX_FIELDS:
        return _read_array(value, ARRAY_DTYPES[field_name], path, source)
    return conform(value, hint, path, field_name)  # leaves: the same checks as in-memory values


def _decode_object(value: Any, cls: type, path: str, source: _Source) -> Any:
    require(isinstance(value, dict), path or SCENE_FILE, f"must be a JSON object, got {show(value)}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    for key in value:
        expected = ", ".join(fields)
        require(key in fields, join(path, key), f"unknown key (expected one of {expected})")
    for f in fields.values():
        required = f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
        require(not required or f.name in value, join(path, f.name), "missing required key")
    hints = field_hints(cls)
    decoded = {key: _decode(item, hints[key], join(path, key), key, source) for key, item in value.items()}
    return cls(**decoded)


def _light_class(value: Any, path: str) -> type:
    require(isinstance(value, dict), path, f"must be a JSON object, got {show(value)}")
    require("type" in value, f"{path}.type", "missing required key")
    kind = value["type"]
    require(isinstance(kind, str), f"{path}.type", f"must be a string, got {show(kind)}")
    check_choice(kind, LIGHT_TYPES, f"{path}.type", "light type")
    return LIGHT_TYPES[kind]


def _read_array(value: Any, dtype: np.dtype, path: str, source: _Source) -> np.ndarray:
    require(isinstance(value, str), path, f"must be the name of a .npy file, got {show(value)}")
    file = _file_inside(source.folder, value, path)
    shown = show(value)
    try:
        _check_npy_header(file, dtype, path, shown)
        array = np.load(file, allow_pickle=False)
    except SceneError:
        raise
    except (OSError, ValueError, EOFError, MemoryError) as error:
        raise SceneError(path, f"cannot read {shown} as .npy: {error}") from None
    if not isinstance(array, np.ndarray):  # an .npz archive
        array.close()
        raise SceneError(path, f"{shown} is not a single-array .npy file")
    source.files.append(file)
    source.readers.setdefault(file, []).append(path)
    return array


def _file_inside(folder: Path, value: str, path: str) -> Path:
    """The file `value` names inside the scene folder, which it must not leave.

    The folder is a sandbox: absolute paths, `..` and symbolic links leading out of it are
    refused with one message, whether or not the target exists, so a scene cannot read (or
    probe for) files elsewhere.
    """
    outside = f"must be relative to the scene folder and stay in it (no '..' or link out), got {show(value)}"
    relative = Path(value)
    require(value != "" and not relative.is_absolute() and ".." not in relative.parts, path, outside)
    try:
        root = folder.resolve()
        file = (folder / relative).resolve()
        inside = file.is_relative_to(root)
        exists = inside and file.is_file()
    except (OSError, RuntimeError, ValueError):  # a link loop, a NUL byte, a name too long
        raise SceneError(path, outside) from None
    require(inside, path, outside)
    require(exists, path, f"file {show(value)} not found")
    return file


def _check_npy_header(file: Path, dtype: np.dtype, path: str, shown: str) -> None:
    """Refuse a .npy file whose header lies before numpy allocates what it claims.

    A negative dimension, or a shape whose data is not exactly the rest of the file, would
    otherwise be accepted or make numpy try to allocate terabytes.
    """
    readers = {(1, 0): np.lib.format.read_array_header_1_0, (2, 0): np.lib.format.read_array_header_2_0}
    with open(file, "rb") as stream:
        zipped = stream.read(4) == b"PK\x03\x04"
        require(not zipped, path, f"{shown} is not a single-array .npy file (it is a zip/.npz archive)")
        stream.seek(0)
        version = np.lib.format.read_magic(stream)
        require(version in readers, path, f"{shown} is .npy version {version}, not 1.0 or 2.0")
        shape, _, file_dtype = readers[version](stream)
        data_bytes = file.stat().st_size - stream.tell()
    require(all(n >= 0 for n in shape), path, f"{shown} has a negative dimension in its shape {shape}")
    # Object arrays are pickles, which are never loaded: they could run code.
    require(not file_dtype.hasobject, path, f"cannot read {shown} as .npy: it holds Python objects")
    require(file_dtype == dtype, path, f"file {shown} holds {file_dtype}; files must hold exactly {dtype}")
    needed = math.prod(shape) * file_dtype.itemsize
    require(
        needed == data_bytes, path, f"{shown} has {data_bytes} data bytes; its shape {shape} needs {needed}"
    )


# --------------------------------------------------------------------------------- saving


@dataclasses.dataclass(frozen=True)
class _Place:
    """Where a value sits in the scene: its field path for messages (meshes[1].vertices)
    and the stem of its array file (mesh1.vertices), both from field names and indices only."""

    path: str = ""
    stem: tuple[str, ...] = ()

    def field(self, name: str) -> _Place:
        return _Place(join(self.path, name), (*self.stem, name))

    def item(self, list_field: str, index: int) -> _Place:
        # The list's own part (e.g. "meshes") is replaced by the item's kind and index.
        kind = _ITEM_KINDS.get(list_field, list_field)
        return _Place(f"{self.path}[{index}]", (*self.stem[:-1], f"{kind}{index}"))


def _encode(value: Any, field_name: str, place: _Place, write_array: _ArrayWriter) -> Any:
    """The JSON form of `value`; data arrays are written by `write_array`, named by `place`."""
    from renderer.media.bricks import SparseGrid  # lazily: renderer.media imports the scene modules

    if isinstance(value, SparseGrid):  # the format holds dense grids: written out in full
        return write_array(value.to_dense, place)  # made dense when written, one at a time
    if dataclasses.is_dataclass(value):
        fields = dataclasses.fields(value)
        encoded = {f.name: _encode(getattr(value, f.name), f.name, place.field(f.name), write_array)
                   for f in fields}
        return _type_first(encoded) if isinstance(value, tuple(LIGHT_TYPES.values())) else encoded
    if isinstance(value, list):
        return [_encode(item, "", place.item(field_name, i), write_array) for i, item in enumerate(value)]
    if isinstance(value, np.ndarray) and field_name in MATRIX_FIELDS:
        return value.tolist()
    if isinstance(value, np.ndarray):
        return write_array(lambda: value, place)
    if isinstance(value, tuple):
        return list(value)
    if isinstance(value, str):
        # A lone surrogate (possible in a Python str, never in Blender's UTF-8 names) cannot
        # be written as UTF-8: say which field, rather than fail halfway through the write.
        unicode = not any("\ud800" <= char <= "\udfff" for char in value)
        require(unicode, place.path, "is not valid Unicode text (it holds a lone surrogate)")
    return value


def _type_first(encoded: dict) -> dict:
    # A light's `type` says how to read the rest of it, so it reads best first.
    return {"type": encoded.pop("type"), **encoded}


class _ArrayWriter:
    """Names a scene's arrays, each its own file in folder/arrays (or refuses), and then
    writes them all."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.written: dict[str, str] = {}  # case-folded file name -> the field written there
        self.pending: list[tuple[Path, Callable[[], np.ndarray]]] = []

    def write_all(self) -> None:
        for file, array in self.pending:
            _write_array_atomically(file, array())

    def __call__(self, array: Callable[[], np.ndarray], place: _Place) -> str:
        stem = ".".join(place.stem)
        # Both hold by construction (_Place); checked because a lost array is silent.
        require(_ARRAY_STEM.fullmatch(stem) is not None, place.path, f"no safe file name from {stem!r}")
        relative = f"{ARRAY_DIR}/{stem}.npy"
        earlier = self.written.get(relative.casefold())
        require(earlier is None, place.path, f"would be written to {relative}, the file of {earlier}")
        self.written[relative.casefold()] = place.path
        self.pending.append((self.folder / relative, array))
        return relative


def _write_array_atomically(file: Path, array: np.ndarray) -> None:
    # A new file renamed over the old: never written through a link, never left half-written.
    handle, temporary = tempfile.mkstemp(dir=file.parent, prefix=f".{file.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as stream:
            np.save(stream, array, allow_pickle=False)
        os.replace(temporary, file)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


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
