"""Flatten scene materials into the material table the BSDF kernels read (renderer.bsdfs.material)."""

from __future__ import annotations

import numpy as np

from renderer.bsdfs import LOBE_KINDS, SIDE_BACK, SIDE_FRONT
from renderer.scene import Material

_SIDES = {"front": SIDE_FRONT, "back": SIDE_BACK, "both": SIDE_FRONT | SIDE_BACK}


def build_material_table(materials: list[Material]) -> tuple:
    """(mat_lobe_start, mat_lobe_count, lobe_kind, lobe_weight, lobe_color, lobe_rough,
    lobe_ior, lobe_sides): contiguous int32/float32 arrays, material m owning lobes
    start[m] .. start[m] + count[m] - 1. Empty inputs give valid zero-length arrays."""
    lobes = [lobe for mat in materials for lobe in mat.lobes]
    counts = np.array([len(mat.lobes) for mat in materials], dtype=np.int32)
    starts = np.zeros(len(materials), dtype=np.int32)
    if len(materials) > 1:
        starts[1:] = np.cumsum(counts)[:-1]
    for lobe in lobes:
        if lobe.kind not in LOBE_KINDS:
            raise ValueError(f"unknown lobe kind {lobe.kind!r}; expected one of {sorted(LOBE_KINDS)}")
        if lobe.sides not in _SIDES:
            raise ValueError(f"unknown lobe sides {lobe.sides!r}; expected one of {sorted(_SIDES)}")
    return (
        np.ascontiguousarray(starts, dtype=np.int32),
        np.ascontiguousarray(counts.reshape(len(materials)), dtype=np.int32),
        np.array([LOBE_KINDS[lobe.kind] for lobe in lobes], dtype=np.int32).reshape(len(lobes)),
        np.array([lobe.weight for lobe in lobes], dtype=np.float32).reshape(len(lobes), 3),
        np.array([lobe.color for lobe in lobes], dtype=np.float32).reshape(len(lobes), 3),
        np.array([lobe.roughness for lobe in lobes], dtype=np.float32).reshape(len(lobes)),
        np.array([lobe.ior for lobe in lobes], dtype=np.float32).reshape(len(lobes)),
        np.array([_SIDES[lobe.sides] for lobe in lobes], dtype=np.int32).reshape(len(lobes)),
    )
