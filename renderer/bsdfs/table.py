"""Flatten scene materials into the material table the BSDF kernels read (layout in layout.py)."""

from __future__ import annotations

import numpy as np

from renderer.bsdfs.layout import LOBE, MATERIAL
from renderer.scene import FRESNEL_MODES, LOBE_KINDS, SIDES, Material
from renderer.validate import validate_material


def build_material_table(materials: list[Material]) -> tuple:
    """(mats int32 (M, MATERIAL.size), lobes float32 (L, LOBE.size)); empty inputs give
    valid zero-length arrays. Every material is validated first (the validator's rule, so
    the kernels never meet a kind, side or Fresnel mode they lack): a SceneError otherwise."""
    for m, material in enumerate(materials):
        validate_material(material, f"materials[{m}]")
    lobes = [lobe for mat in materials for lobe in mat.lobes]
    counts = np.array([len(mat.lobes) for mat in materials], dtype=np.int32)
    starts = np.zeros(len(materials), dtype=np.int32)
    if len(materials) > 1:
        starts[1:] = np.cumsum(counts)[:-1]
    mats = np.zeros((len(materials), MATERIAL.size), np.int32)
    mats[:, MATERIAL.slice("first")] = starts[:, None]
    mats[:, MATERIAL.slice("count")] = counts[:, None]
    table = np.zeros((len(lobes), LOBE.size), np.float32)
    for j, lobe in enumerate(lobes):
        row = table[j]
        row[LOBE.slice("kind")] = LOBE_KINDS[lobe.kind]
        row[LOBE.slice("weight")] = lobe.weight
        row[LOBE.slice("color")] = lobe.color
        row[LOBE.slice("roughness")] = lobe.roughness
        row[LOBE.slice("ior")] = lobe.ior
        row[LOBE.slice("sides")] = SIDES[lobe.sides]
        row[LOBE.slice("fresnel")] = FRESNEL_MODES[lobe.fresnel]
        row[LOBE.slice("tint")] = lobe.tint
        row[LOBE.slice("multiscatter")] = float(lobe.multiscatter)
    return mats, table
