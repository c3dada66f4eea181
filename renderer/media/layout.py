"""The flat layouts of the media kernels' data, declared by field name (renderer.layout).

The kernels take one argument for all media, a MediaTable: four immutable arrays built by
renderer.media.compile (a MediaData, kept by the compiled scene) plus the mutable scratch
of the majorant-grid walk (owned by whoever runs the kernels: the tracer). M = number of
media; a medium id is its index in the scene's list.

    params    (M, PARAMS.size) float32  per-medium floats, fields of PARAMS:
        sigma_a, sigma_s   absorption and scattering per world unit, RGB, already times `scale`
        g                  Henyey-Greenstein asymmetry
        emission           emission per unit length, RGB (see renderer.media.emission)
        blackbody          blackbody intensity (already applied in the GRID_BLACKBODY grid)
        emission_rate      tentative-collision rate (per world unit) guaranteed in emitting
                           cells of a grid, so that emission where the density is ~0 is
                           still estimated (see tracking.py)
        to_unit            world -> grid unit cube affine [A | b] (3x4, row-major), u = A x + b
                           (identity for homogeneous media)
    index     (M, INDEX.size) int64     per-medium integers, fields of INDEX:
        kind               MEDIUM_HOMOGENEOUS or MEDIUM_GRID
        has_emission       1 if the medium can emit anywhere (else emission costs nothing)
        grid_offset        [w]: start of grid w (GRID_DENSITY, GRID_FLAME, GRID_BLACKBODY) in
                           grid_data, -1 when absent
        grid_dims          [3 w + a]: size of grid w along axis a (x, y, z); voxel (i, j, k) of a
                           dense grid is grid_data[offset + (k * ny + j) * nx + i];
                           GRID_BLACKBODY holds three values per voxel, its channel c at
                           3 (that index) + c
        grid_bricks        [w]: -1 for a dense grid; for a sparse one (bricks.py) the start of
                           its brick lattice in brick_index: the stored brick of voxel
                           (i, j, k) is b = brick_index[that + ((k >> 3) by + (j >> 3)) bx +
                           (i >> 3)] (brick 0 is all zeros: empty bricks point at it) and the
                           voxel is grid_data[offset + 729 b + ((k & 7) 9 + (j & 7)) 9 + (i & 7)]
                           (times 3, + c, for GRID_BLACKBODY)
        maj_offset         first cell of the medium's majorant grid in maj_data (-1 if none)
        maj_dims           [a]: majorant cells along unit-cube axis a
        program            procedural media: the program giving the density (procedural.py),
                           else -1
    grid_data (N,)        float32  every grid, x fastest. The temperature grid is stored as
                                   GRID_BLACKBODY, the RGB blackbody emission of every voxel
                                   (intensity applied), which the kernels interpolate: Cycles'
                                   semantics (see renderer.media.blackbody)
    brick_index (L,)      int32    the brick lattices of sparse grids, x fastest (see grid_bricks)
    maj_data  (K, CELL.size) float32  per majorant cell (x fastest): the max density that
                                   trilinear interpolation can reach inside the cell, 1.0
                                   if the cell can emit else 0.0, and 1.0 if rays cross the
                                   cell by regular tracking (exact optical depth, regular.py)
                                   rather than against its bound
    scratch   (MAX_STACK, DDA.size) float64  one walker row per stack entry (majorant.py)
    programs  ProceduralMediaTable only: the procedural media's programs and a scratch to run
              them in (DensityPrograms, below)

A few wide arrays rather than one per field: every non-inlined call passes each array of
the tuple, so a 15-array table made a trilinear lookup ~5x slower. A homogeneous medium has
density 1 everywhere: the medium stack says where it applies.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from renderer.layout import Layout
from renderer.scene import MAX_STACK, MEDIUM_TYPES
from renderer.shading.interpreter import program_entry
from renderer.shading.table import PROG

MEDIUM_HOMOGENEOUS = MEDIUM_TYPES["homogeneous"]
MEDIUM_GRID = MEDIUM_TYPES["grid"]

# The grids a grid medium may carry, by their index in the grid_offset / grid_dims fields.
GRID_DENSITY = 0
GRID_FLAME = 1
GRID_BLACKBODY = 2  # from the medium's temperature grid: per-voxel blackbody emission, RGB
GRID_NAMES = ("density", "flame", "temperature")  # the Medium fields behind the indices above

PARAMS = Layout("medium params", [
    ("sigma_a", 3),
    ("sigma_s", 3),
    ("g", 1),
    ("emission", 3),
    ("blackbody", 1),
    ("emission_rate", 1),
    ("to_unit", 12),
])
P_SIGMA_A = PARAMS.offset("sigma_a")
P_SIGMA_S = PARAMS.offset("sigma_s")
P_G = PARAMS.offset("g")
P_EMISSION = PARAMS.offset("emission")
P_BLACKBODY = PARAMS.offset("blackbody")
P_EMISSION_RATE = PARAMS.offset("emission_rate")
P_TO_UNIT = PARAMS.offset("to_unit")
P_SIZE = PARAMS.size

INDEX = Layout("medium index", [
    ("kind", 1),
    ("has_emission", 1),
    ("grid_offset", len(GRID_NAMES)),
    ("grid_dims", 3 * len(GRID_NAMES)),
    ("grid_bricks", len(GRID_NAMES)),
    ("maj_offset", 1),
    ("maj_dims", 3),
    ("program", 1),
])
I_KIND = INDEX.offset("kind")
I_HAS_EMISSION = INDEX.offset("has_emission")
I_GRID_OFFSET = INDEX.offset("grid_offset")
I_GRID_DIMS = INDEX.offset("grid_dims")
I_GRID_BRICKS = INDEX.offset("grid_bricks")
I_MAJ_OFFSET = INDEX.offset("maj_offset")
I_MAJ_DIMS = INDEX.offset("maj_dims")
I_PROGRAM = INDEX.offset("program")
I_SIZE = INDEX.size

CELL = Layout("majorant cell", [("density_bound", 1), ("emits", 1), ("exact", 1)])
CELL_DENSITY_BOUND = CELL.offset("density_bound")
CELL_EMITS = CELL.offset("emits")
CELL_EXACT = CELL.offset("exact")

# A walker row of the majorant-grid DDA (renderer.media.majorant).
DDA = Layout("dda walker", [
    ("end", 1),  # t where the current piece ends
    ("maj", 1),  # density majorant on the current piece
    ("emits", 1),  # 1.0 if the medium may emit on the current piece
    ("exact", 1),  # 1.0 if the current piece is crossed by regular tracking (a flagged cell)
    ("state", 1),  # before the box, inside, past it
    ("cell", 3),  # current cell
    ("next", 3),  # t of the next crossing along x, y, z
    ("dt", 3),  # t between crossings along x, y, z
    ("step", 3),  # +1 / -1 / 0 along x, y, z
    ("enter", 1),  # t where the ray enters the box
    ("exit", 1),  # t where the ray leaves the box
    ("medium", 1),  # medium id
])
DDA_END = DDA.offset("end")
DDA_MAJ = DDA.offset("maj")
DDA_EMITS = DDA.offset("emits")
DDA_EXACT = DDA.offset("exact")
DDA_STATE = DDA.offset("state")
DDA_CELL = DDA.offset("cell")
DDA_NEXT = DDA.offset("next")
DDA_DT = DDA.offset("dt")
DDA_STEP = DDA.offset("step")
DDA_ENTER = DDA.offset("enter")
DDA_EXIT = DDA.offset("exit")
DDA_MEDIUM = DDA.offset("medium")
DDA_SIZE = DDA.size


class MediaTable(NamedTuple):
    """The media kernels' argument: a scene's tables and a walker scratch (see above)."""

    params: np.ndarray
    index: np.ndarray
    grid_data: np.ndarray
    brick_index: np.ndarray
    maj_data: np.ndarray
    scratch: np.ndarray


class ProceduralMediaTable(NamedTuple):
    """A MediaTable with the procedural media's programs (procedural.py): a type of its own,
    so that the kernels compiled for scenes without procedural media stay exactly as they
    are, and only scenes with one compile the program into their trackers."""

    params: np.ndarray
    index: np.ndarray
    grid_data: np.ndarray
    brick_index: np.ndarray
    maj_data: np.ndarray
    scratch: np.ndarray
    programs: tuple  # a DensityPrograms (below)


class MediaData(NamedTuple):
    """A scene's media tables, built once and never written: what a compiled scene keeps."""

    params: np.ndarray
    index: np.ndarray
    grid_data: np.ndarray
    brick_index: np.ndarray
    maj_data: np.ndarray
    programs: tuple | None = None  # procedural media's program tables (procedural.build_program_tables)

    @property
    def has_grids(self) -> bool:
        """Whether any medium is a grid (else the integrator compiles no grid tracker)."""
        return bool((self.index[:, I_KIND] == MEDIUM_GRID).any())

    def with_scratch(self, scratch: np.ndarray) -> MediaTable:
        """The kernels' argument over these tables, walking the majorant grid in `scratch`."""
        if self.programs is None:
            return MediaTable(self.params, self.index, self.grid_data, self.brick_index, self.maj_data,
                              scratch)
        return ProceduralMediaTable(self.params, self.index, self.grid_data, self.brick_index, self.maj_data,
                                    scratch, program_scratch(self.programs))


def dda_scratch() -> np.ndarray:
    """Working rows for the majorant-grid walk: one per medium a stack can hold. Kernels
    run one path at a time per process, so one scratch serves a whole tracer; it is
    allocated outside the kernels because they are compiled without reference counting
    and so cannot allocate."""
    return np.zeros((MAX_STACK, DDA_SIZE), np.float64)


class DensityPrograms(NamedTuple):
    """ProceduralMediaTable.programs: MediaData.programs (the shading tuple and the density
    register of each program) with what running them needs in one process
    (program_scratch): a register file of its own and the address of the interpreter
    compiled for these tables (renderer.shading.interpreter.program_entry), which the
    trackers call (renderer.kernels.native_call). The address is this process's: a
    DensityPrograms is made where it is used, never pickled."""

    tables: tuple
    density: np.ndarray  # (K,) int64
    regs: np.ndarray  # (R,) float32
    entry: int  # run_program's address in this process


def program_scratch(programs: tuple) -> DensityPrograms:
    """MediaData.programs with a register file and the interpreter's address (see DensityPrograms)."""
    tables, density = programs
    nregs = int(tables[0][:, PROG.offset("nregs")].max())
    regs = np.zeros(max(1, nregs), np.float32)
    return DensityPrograms(tables, density, regs, program_entry(tables, regs))
