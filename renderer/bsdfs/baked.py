"""Tables baked offline and shipped beside their module as .npz files (the coat, specular
and GGX energy albedos): one place that names, loads, checks and saves them.

A module keeps its table as module-level float64 arrays, which numba freezes into the
kernels as constants when they compile; the build key (renderer.kernels.cache) hashes the
sources, not the .npz, so regenerating a table means touching the module that loads it.
"""

from __future__ import annotations

import os

import numpy as np


def table_path(module_file: str, name: str) -> str:
    """The .npz file `name` beside the module file that owns it."""
    return os.path.join(os.path.dirname(module_file), f"{name}.npz")


def load(path: str, shapes: dict[str, tuple[int, ...]]) -> tuple[np.ndarray, ...]:
    """The arrays named in `shapes` (in that order), as contiguous float64, each checked
    against its shape: a stale table is refused, never read out of bounds."""
    with np.load(path) as stored:
        arrays = tuple(stored[key] for key in shapes)
    for (key, shape), array in zip(shapes.items(), arrays):
        if array.shape != shape:
            name = os.path.basename(path)
            raise ValueError(f"{name}: stale table, {key} is {array.shape}, expected {shape}")
    return tuple(np.ascontiguousarray(array, np.float64) for array in arrays)


def save(path: str, **arrays: np.ndarray) -> None:
    """Write a freshly built table (run as `python -m renderer.bsdfs.<module>`)."""
    np.savez_compressed(path, **arrays)
    print("wrote", path)
