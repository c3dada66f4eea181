"""Per-object values the Object Info node reads (Cycles' KernelObject: location, color,
alpha, pass_id, random_number), exported as corner attributes constant over the object:
"info:location" (world-space origin), "info:color" (the object's Color RGB) and
"info:values" (alpha, pass index, random) and "info:scale" (the transform's uniform
scale, for object-space displacement), so shader programs read them with the
ordinary attribute operation. Only objects whose materials read them carry them.

Random, as Cycles' blender/object.cpp sets random_id: for an instance, the dependency
graph's random_id; otherwise hash_uint2(hash_string(name), 0); then uint_to_float_incl.
"""

from __future__ import annotations

import numpy as np

_M = 0xFFFFFFFF


def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & _M


def hash_uint2(kx: int, ky: int) -> int:
    """util/hash.h hash_uint2 (lookup3 final mix) on Python ints."""
    a = b = c = (0xDEADBEEF + (2 << 2) + 13) & _M
    b = (b + ky) & _M
    a = (a + kx) & _M
    c = ((c ^ b) - _rot(b, 14)) & _M
    a = ((a ^ c) - _rot(c, 11)) & _M
    b = ((b ^ a) - _rot(a, 25)) & _M
    c = ((c ^ b) - _rot(b, 16)) & _M
    a = ((a ^ c) - _rot(c, 4)) & _M
    b = ((b ^ a) - _rot(a, 14)) & _M
    c = ((c ^ b) - _rot(b, 24)) & _M
    return c


def hash_string(name: str) -> int:
    """util/hash.h hash_string over the name's UTF-8 bytes."""
    h = 0
    for byte in name.encode("utf-8"):
        h = (h * 37 + byte) & _M
    return h


def random_number(name: str, instance_random_id: int | None = None) -> float:
    rid = instance_random_id if instance_random_id is not None else hash_uint2(hash_string(name), 0)
    return float(np.float32(rid & _M) * np.float32(1.0 / 0xFFFFFFFF))


OBJECT_SCALE = "info:scale"  # the object's uniform scale, for object-space displacement


def uniform_scale(matrix: np.ndarray) -> float:
    """The scale of a 4x4 transform as one number: the cube root of its volume change."""
    return float(abs(np.linalg.det(np.asarray(matrix, np.float64)[:3, :3])) ** (1.0 / 3.0))


def object_info_values(obj, matrix: np.ndarray, instance_random_id: int | None = None) -> dict:
    """The attributes' values (3,) float32 of object `obj` placed by `matrix` (4x4)."""
    color = [float(c) for c in obj.color]
    return {"info:location": np.asarray(matrix[:3, 3], np.float32),
            OBJECT_SCALE: np.full(3, uniform_scale(matrix), np.float32),
            "info:color": np.asarray(color[:3], np.float32),
            "info:values": np.array([color[3], float(obj.pass_index),
                                     random_number(obj.name, instance_random_id)], np.float32)}


def add_object_info(attributes: dict[str, np.ndarray], needed, triangles: int, obj, matrix: np.ndarray,
                    instance_random_id: int | None = None) -> None:
    """Fill the needed "info:" attributes of one object's `triangles` triangles in place."""
    names = [name for name in needed if name.startswith("info:")]
    if not names:
        return
    values = object_info_values(obj, matrix, instance_random_id)
    for name in names:
        attributes[name] = np.broadcast_to(values[name], (triangles, 3, 3)).copy()
