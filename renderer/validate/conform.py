"""Conforming a scene value to its annotation in renderer.scene: types, finiteness, dtypes.

`conform(value, hint, path, field)` checks a value against the dataclass field annotation
`hint` and returns it in canonical form (number tuples as tuples of floats, transforms as
float64 4x4 arrays, data arrays as contiguous arrays of exactly the kernels' dtypes). The
validator (renderer.validate) conforms in-memory scenes with it, and the loader
(renderer.scenefile) the leaves of a scene.json, so both report the same problems with the
same messages. Every problem is a SceneError naming the field.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import numbers
import types
import typing
from typing import Any

import numpy as np

from renderer.errors import SceneError

# Data arrays must hold exactly these dtypes (the kernels' dtypes), so a file never silently
# loses precision or range on load; in-memory arrays are converted when the values fit.
ARRAY_DTYPES: dict[str, np.dtype] = {
    "vertices": np.dtype(np.float32),
    "indices": np.dtype(np.int32),
    "material_ids": np.dtype(np.int32),
    "normals": np.dtype(np.float32),
    "density": np.dtype(np.float32),
    "flame": np.dtype(np.float32),
    "temperature": np.dtype(np.float32),
    # shader programs (renderer.shading.program) and the data they read
    "code": np.dtype(np.int32),
    "registers": np.dtype(np.float32),
    "bindings": np.dtype(np.int32),
    "data": np.dtype(np.float32),
    "values": np.dtype(np.float32),
    "pixels": np.dtype(np.float32),
    "radiance_map": np.dtype(np.float32),
}
# Transforms are 16 numbers: written inline in the JSON, where a person can read them.
MATRIX_FIELDS = frozenset({"to_world"})


# ----------------------------------------------------------------------------- helpers


def join(path: str, name: str) -> str:
    """The path of field `name` of the object at `path` ("" is the scene itself)."""
    return f"{path}.{name}" if path else name


def require(condition: bool, path: str, problem: str) -> None:
    """Raise SceneError(path, problem) unless `condition` holds."""
    if not condition:
        raise SceneError(path, problem)


# Longest bad value quoted in a message: errors stay one readable line whatever the input.
_MAX_SHOWN = 80


def show(value: Any) -> str:
    """A short description of a bad value for a message (containers by type, not content)."""
    if isinstance(value, int) and abs(value) >= 10**30:
        # repr of a huge integer is long (and raises beyond 4300 digits): give its size.
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    if value is None or isinstance(value, str | numbers.Number | bool | tuple):
        try:
            text = repr(value)
        except ValueError:  # a tuple holding a huge integer
            return f"a {type(value).__name__} of {len(value)} items"
        return text if len(text) <= _MAX_SHOWN else text[: _MAX_SHOWN - 3] + "..."
    return type(value).__name__


@functools.cache
def field_hints(cls: type) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def is_union(hint: Any) -> bool:
    return typing.get_origin(hint) in (types.UnionType, typing.Union)


def split_optional(hint: Any) -> tuple[Any, bool]:
    """(hint without None, whether None is allowed) for `X | None` annotations."""
    if not is_union(hint) or type(None) not in typing.get_args(hint):
        return hint, False
    rest = tuple(arg for arg in typing.get_args(hint) if arg is not type(None))
    return (rest[0] if len(rest) == 1 else typing.Union[rest]), True  # noqa: UP007


SPARSE_FIELDS = ("density", "flame", "temperature")  # Medium's grids


# ----------------------------------------------- conforming: types, finiteness, normalising


def conform(value: Any, hint: Any, path: str, field_name: str) -> Any:
    """Check `value` against its annotation and return it in canonical form."""
    hint, optional = split_optional(hint)
    if value is None and optional:
        return None
    if dataclasses.is_dataclass(hint):
        return conform_object(value, (hint,), path)
    if is_union(hint):
        return conform_object(value, typing.get_args(hint), path)
    if typing.get_origin(hint) is list:
        return _conform_list(value, typing.get_args(hint)[0], path)
    if typing.get_origin(hint) is tuple:
        return _conform_numbers(value, len(typing.get_args(hint)), path)
    if hint is np.ndarray and field_name in MATRIX_FIELDS:
        return _conform_matrix(value, path)
    if hint is np.ndarray:
        if _is_sparse_grid(value, field_name):
            return value  # checked as a grid by renderer.validate
        return _conform_array(value, ARRAY_DTYPES[field_name], path)
    return _conform_scalar(value, hint, path)


def _is_sparse_grid(value: Any, field_name: str) -> bool:
    """A Medium grid field may hold a SparseGrid (renderer.media.bricks) instead of an array."""
    if field_name not in SPARSE_FIELDS or isinstance(value, np.ndarray):
        return False
    from renderer.media.bricks import SparseGrid  # lazily: renderer.media imports this module

    return isinstance(value, SparseGrid)


def conform_object(value: Any, classes: tuple[type, ...], path: str) -> Any:
    if not isinstance(value, classes):
        names = " or ".join(cls.__name__ for cls in classes)
        raise SceneError(path or "scene", f"must be a {names}, got {show(value)}")
    hints = field_hints(type(value))
    for f in dataclasses.fields(value):
        conformed = conform(getattr(value, f.name), hints[f.name], join(path, f.name), f.name)
        setattr(value, f.name, conformed)
    return value


def _conform_list(value: Any, item_hint: Any, path: str) -> list:
    if not isinstance(value, list):
        raise SceneError(path, f"must be a list, got {show(value)}")
    return [conform(item, item_hint, f"{path}[{i}]", "") for i, item in enumerate(value)]


def _conform_numbers(value: Any, length: int, path: str) -> tuple[float, ...]:
    is_sequence = isinstance(value, list | tuple) or (isinstance(value, np.ndarray) and value.ndim == 1)
    if not is_sequence or len(value) != length:
        raise SceneError(path, f"must be a list of {length} numbers, got {show(value)}")
    if not all(_is_real(x) for x in value):
        raise SceneError(path, f"must be a list of {length} numbers, got {show(tuple(value))}")
    floats = tuple(_to_float(x) for x in value)
    require(all(math.isfinite(x) for x in floats), path, f"must be finite, got {floats}")
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
        require(_is_real(value), path, f"must be a number, got {show(value)}")
        number = _to_float(value)
        require(math.isfinite(number), path, f"must be finite, got {number}")
        return number
    if hint is int:
        is_int = isinstance(value, numbers.Integral) and not isinstance(value, bool | np.bool_)
        require(is_int, path, f"must be an integer, got {show(value)}")
        require(-(2**63) <= int(value) < 2**64, path, f"integer out of range, got {show(int(value))}")
        return int(value)
    if hint is bool:
        require(isinstance(value, bool | np.bool_), path, f"must be true or false, got {show(value)}")
        return bool(value)
    if hint is str:
        require(isinstance(value, str), path, f"must be a string, got {show(value)}")
        return value
    raise TypeError(f"{path}: no conversion for annotation {hint!r}")  # a scene.py change


def _conform_matrix(value: Any, path: str) -> np.ndarray:
    try:
        raw = np.asarray(value)
    except ValueError:  # ragged nested lists
        raise SceneError(path, "must be a 4x4 matrix of numbers") from None
    require(raw.dtype.kind in "iuf", path, f"must be a 4x4 matrix of numbers, got dtype {raw.dtype}")
    require(raw.shape == (4, 4), path, f"must be a 4x4 matrix, got shape {raw.shape}")
    matrix = np.array(raw, dtype=np.float64)  # a copy: the scene owns its transforms
    _check_finite_array(matrix, path)
    return matrix


def _conform_array(value: Any, dtype: np.dtype, path: str) -> np.ndarray:
    if not isinstance(value, np.ndarray):
        raise SceneError(path, f"must be a numpy array, got {show(value)}")
    if dtype.kind == "f":
        return _conform_float_array(value, dtype, path)
    return _conform_int_array(value, dtype, path)


def _conform_float_array(value: np.ndarray, dtype: np.dtype, path: str) -> np.ndarray:
    require(value.dtype.kind == "f", path, f"must be a float array, got dtype {value.dtype}")
    _check_finite_array(value, path)
    with np.errstate(over="ignore"):
        converted = value.astype(dtype, order="C", copy=False)
    if converted is not value:
        require(bool(np.isfinite(converted).all()), path, f"values exceed the {dtype} range")
    return converted


def _conform_int_array(value: np.ndarray, dtype: np.dtype, path: str) -> np.ndarray:
    require(value.dtype.kind in "iu", path, f"must be an integer array, got dtype {value.dtype}")
    if value.dtype != dtype and value.size:
        limits = np.iinfo(dtype)
        fits = limits.min <= int(value.min()) and int(value.max()) <= limits.max
        require(fits, path, f"values do not fit {dtype}")
    return value.astype(dtype, order="C", copy=False)


def _check_finite_array(array: np.ndarray, path: str) -> None:
    if not np.isfinite(array).all():
        raise SceneError(path, "contains NaN" if np.isnan(array).any() else "contains inf")
