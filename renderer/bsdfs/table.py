"""Flatten scene materials into the material table the BSDF kernels read (renderer.bsdfs.material)."""

from __future__ import annotations

import numpy as np

from renderer.bsdfs import FRESNEL_MODES, LOBE_KINDS, SIDE_BACK, SIDE_FRONT
from renderer.scene import Material

_SIDES = {"front": SIDE_FRONT, "back": SIDE_BACK, "both": SIDE_FRONT | SIDE_BACK}


def build_material_table(materials: list[Material]) -> tuple:
    """(mats int32 (M, 2), lobes float32 (L, 14)): material m owns lobes
    mats[m, 0] .. mats[m, 0] + mats[m, 1] - 1; lobe columns as in renderer.bsdfs.material
    (kind, weight rgb, color rgb, roughness, ior, sides, fresnel, tint rgb). Empty inputs
    give valid zero-length arrays."""
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
        if lobe.fresnel not in FRESNEL_MODES:
            raise ValueError(f"unknown lobe fresnel {lobe.fresnel!r}; expected one of "
                             f"{sorted(FRESNEL_MODES)}")
    mats = np.zeros((len(materials), 2), np.int32)
    mats[:, 0] = starts
    mats[:, 1] = counts
    table = np.zeros((len(lobes), 14), np.float32)
    for j, lobe in enumerate(lobes):
        table[j, 0] = LOBE_KINDS[lobe.kind]
        table[j, 1:4] = lobe.weight
        table[j, 4:7] = lobe.color
        table[j, 7] = lobe.roughness
        table[j, 8] = lobe.ior
        table[j, 9] = _SIDES[lobe.sides]
        table[j, 10] = FRESNEL_MODES[lobe.fresnel]
        table[j, 11:14] = lobe.tint
    return mats, table
