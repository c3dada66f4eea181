"""The records the stage kernels take besides the batch's own state (state.py): what Embree
found, the scene as the stages read it, where a hit's material is read, the shader
programs, and which samples a batch starts.

Each is a NamedTuple of arrays (and a few integers): numba passes one as cheaply as its
fields one by one, and a kernel unpacks the fields it reads by name. The arguments numba
prunes branches on when they are None stay arguments of their own: the environment map
(`env`) and the grid media (`grid_md`), since `x is None` folds to a constant only for an
argument, not for a record's field.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..compile import CameraParams, Geometry
from ..lights.table import LightTable


class Hits(NamedTuple):
    """Embree's answer for rows 0..n-1: prim (n,) int32, the triangle hit (-1: none); bu, bv
    (n,) float32, its barycentrics; t (n,) float32, the distance (for paths, Paths.tmax
    itself: Embree writes it there)."""

    prim: np.ndarray
    bu: np.ndarray
    bv: np.ndarray
    t: np.ndarray


class SceneArrays(NamedTuple):
    """The scene as the stages read it, unchanged over a render: its geometry, its light
    table, its camera, and the Mist pass's start, 1 / depth and falloff ((3,) float64)."""

    geometry: Geometry
    lights: LightTable
    camera: CameraParams
    mist: np.ndarray


class Materials(NamedTuple):
    """Where a stage reads the material of a hit: table, the material table (mats, lobes),
    with one scratch material per row in scenes with programs (shading.apply.scratch_table);
    override (N,) int32, the scratch material to read for row i instead of its triangle's
    (-1: its triangle's; empty without programs); out (N, 6) float32, the program's factor
    on the emitter's radiance (0:3) and its shading normal (3:6, zero: the mesh's), for
    paths only ((0, 6) for shadow rays and without programs)."""

    table: tuple
    override: np.ndarray
    out: np.ndarray


class Programs(NamedTuple):
    """The scene's shader programs (shading.table) and what running one needs: registers
    (R,) float32, the interpreter's address (shading.interpreter.program_entry), the most
    lobes a material has (the scratch lobes per row) and the lobe offsets of the bound
    fields (shading.apply.FIELD_OFFSETS)."""

    table: tuple
    regs: np.ndarray
    entry: int
    max_lobes: int
    field_offsets: np.ndarray


class Tile(NamedTuple):
    """Which samples a batch starts: a pass over the tile of `rows` rows of the rendered
    window from first_row on, `width` pixels wide, samples from sample_base on, with this
    seed (camera_rays.start_paths)."""

    width: int
    rows: int
    first_row: int
    seed: int
    sample_base: int
