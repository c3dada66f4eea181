"""Procedural media: a grid medium whose density is a shader program of the world position
(a Noise Texture through Math, Map Range or Color Ramp nodes into a volume shader's Density)
instead of voxels.

The medium keeps the grid machinery: its box (p0, p1, to_world, the enclosing mesh's
bounds) is cut into PROC_CELLS^3 majorant cells walked by the same DDA (majorant.py), and
tracking (tracking.py) asks medium_density for the density at tentative collisions, which
here runs the program (renderer.shading.interpreter). Outside the box the density is 0.

Unbiasedness needs each cell's majorant to bound the density everywhere in the cell. It is
the upper end of the program's interval bound over the cell (renderer.shading.intervals:
each operation maps input intervals to an interval holding every output, Noise by a proved
range), over the cell grown by CELL_PAD of its size on every side (points a DDA rounding
error outside the cell), times 1 + BOUND_PAD (float rounding). It is a bound, not an
estimate: Cycles instead samples the density in each cell and multiplies the largest sample
by 1.5, which a peak between samples can exceed (bias). A program with an operation the
interval rules cannot bound (its density could be anything) is refused with a SceneError.
bound_violations() checks the bound empirically (tests).

Tables (MediaData.programs, None when no medium is procedural): the interpreter's shading
tuple over the media's programs (one program per procedural medium, shading.table layout),
and per program the register that holds its density. MediaData.with_scratch adds a
scratch and gives a ProceduralMediaTable (programs: a DensityPrograms), a type of its own:
scenes without procedural media keep the plain MediaTable, for which program_density
compiles to a constant (one trivial extra compile), so their kernels are the ones they had
before procedural media, with the same types; only a scene
with a procedural medium compiles its trackers for the new type. The trackers call the
interpreter through its address (renderer.kernels.native_call), compiled once for surface
programs and media alike.
"""

from __future__ import annotations

import math

import numpy as np
from numba.core import types
from numba.extending import overload

from renderer.errors import SceneError
from renderer.kernels import JIT_OPTIONS, inline_kernel
from renderer.kernels.native_call import call_native
from renderer.media.layout import (
    CELL_DENSITY_BOUND,
    I_MAJ_DIMS,
    I_MAJ_OFFSET,
    I_PROGRAM,
    P_TO_UNIT,
    DensityPrograms,
)
from renderer.scene import Medium
from renderer.shading.evaluate import evaluate_points
from renderer.shading.intervals import run_intervals
from renderer.shading.program import BIND, INSTR, OP, OPCODES, ShaderProgram
from renderer.shading.table import PROG

PROC_CELLS = 16
CELL_PAD = 0.01
BOUND_PAD = 1e-5
FLOAT32_PAD = 2.0 ** -22  # relative: more than float32's rounding of a coordinate (2^-24)
# Operations that need a surface (UVs, normals, the view) or data a medium has not.
SURFACE_OPS = frozenset(("attribute", "normal", "fresnel", "layer_weight", "image"))
_OVERLOAD_OPTIONS = {k: v for k, v in JIT_OPTIONS.items() if k != "cache"}


def check_program(program: ShaderProgram, density: int, path: str) -> None:
    """A medium program reads only the position and writes register `density`."""
    code = np.asarray(program.code, np.int64).reshape(-1, INSTR.size)
    for row in code:
        name = OPCODES[int(row[0])] if 0 <= row[0] < len(OPCODES) else f"opcode {row[0]}"
        if name in SURFACE_OPS or name not in OP:
            raise SceneError(f"{path}.program", f"operation {name!r} has no meaning inside a volume")
    if not 0 <= density < len(program.registers):
        raise SceneError(f"{path}.program_density", f"register {density} is not in the program "
                         f"({len(program.registers)} registers)")


def build_program_tables(programs: list[ShaderProgram], density_regs: list[int]) -> tuple:
    """(shading tuple, density registers (K,) int64): MediaData.programs. The tuple has the
    types of shading.table's (ShadingTables.arrays): the interpreter runs them as it runs
    surface programs (procedural._run through its address; shading.evaluate from Python)."""
    progs = np.zeros((len(programs), PROG.size), np.int32)
    code, init, data = [], [], []
    counts = [0, 0, 0]
    for k, prog in enumerate(programs):
        c = np.array(prog.code, np.int32).reshape(-1, INSTR.size).copy()
        for row in c:
            if row[0] in (OP["ramp"], OP["curve"]):
                row[INSTR.offset("i0")] += counts[2]
        progs[k] = (counts[0], len(c), counts[1], len(prog.registers), 0, 0)
        code.append(c)
        init.append(np.asarray(prog.registers, np.float32))
        data.append(np.asarray(prog.data, np.float32))
        for j, n in enumerate((len(c), len(prog.registers), len(prog.data))):
            counts[j] += n
    data.append(np.zeros(1, np.float32))
    code.append(np.zeros((0, INSTR.size), np.int32))
    st = (progs, np.ascontiguousarray(np.concatenate(code)), np.concatenate(init), np.concatenate(data),
          np.zeros((1, BIND.size), np.int32), np.zeros((1, 3, 1), np.float32), np.zeros((1, 4), np.float32),
          np.zeros((1, 4), np.int32))
    return st, np.asarray(density_regs, np.int64)


def cell_boxes(unit_to_world: np.ndarray, cells: int = PROC_CELLS) -> tuple[np.ndarray, np.ndarray]:
    """World-space AABBs ((cells^3, 3) lo and hi, x fastest) of the unit box's cells, each
    grown by CELL_PAD of its size: the affine image of a box is inside the AABB of its
    eight corners. Each AABB is grown again by FLOAT32_PAD of its coordinates' magnitude:
    the program runs at the point rounded to float32 (one half ulp, 2^-24 relative, away)."""
    k = np.arange(cells, dtype=np.float64)
    lo1 = (k - CELL_PAD) / cells
    hi1 = (k + 1.0 + CELL_PAD) / cells
    gz, gy, gx = np.meshgrid(k, k, k, indexing="ij")
    idx = np.stack([gx.ravel(), gy.ravel(), gz.ravel()], axis=1).astype(np.int64)
    lin, off = unit_to_world[:3, :3], unit_to_world[:3, 3]
    lo = np.full((idx.shape[0], 3), np.inf)
    hi = np.full((idx.shape[0], 3), -np.inf)
    for corner in range(8):
        u = np.stack([np.where(corner >> a & 1, hi1[idx[:, a]], lo1[idx[:, a]]) for a in range(3)], axis=1)
        w = u @ lin.T + off
        lo = np.minimum(lo, w)
        hi = np.maximum(hi, w)
    return lo - np.abs(lo) * FLOAT32_PAD, hi + np.abs(hi) * FLOAT32_PAD


def density_bounds(med: Medium, unit_to_world: np.ndarray, path: str, cells: int = PROC_CELLS) -> np.ndarray:
    """(cells, cells, cells) float32 density majorants (z, y, x) of a procedural medium."""
    lo, hi = cell_boxes(unit_to_world, cells)
    iv = run_intervals(med.program, lo, hi)
    upper = iv.hi[med.program_density]
    if not np.all(np.isfinite(upper)):
        raise SceneError(f"{path}.program", "its density has no finite bound (an operation the "
                         "interval rules of renderer.shading.intervals cannot bound feeds it)")
    bound = np.maximum(upper, 0.0) * (1.0 + BOUND_PAD)  # the kernel clamps density at 0
    return bound.reshape(cells, cells, cells).astype(np.float32)


@inline_kernel
def _run(programs, k, x):
    """Program k's density at world point x, clamped at 0 as Principled Volume clamps it (NaN
    too). The point is rounded to float32 first, as Cycles' shading points are (and as
    shading.evaluate gives them). The interpreter is called through its address
    (renderer.kernels.native_call): linked into the trackers, it was optimised again inside
    each of them (over 15 CPU minutes for a procedural scene's first render), and inlined,
    it made delta_track's machine code 4x larger."""
    pos = (np.float64(np.float32(x[0])), np.float64(np.float32(x[1])), np.float64(np.float32(x[2])))
    up = (0.0, 0.0, 1.0)
    # As evaluate_points runs it: no triangle, the normal and view +z, front face.
    call_native(programs.entry, (programs.tables, k, programs.regs, np.int64(-1), 0.0, 0.0, 0.0, pos, up, up,
                                 False))
    rho = float(programs.regs[programs.density[k]])
    return rho if rho > 0.0 else 0.0


def program_density(mt, m, u, x):
    """Density of procedural medium m at world point x (unit-cube point u), or -1.0 when m
    is not procedural. Compiled per table type (an overload, below): for a MediaTable, the
    type of every scene without procedural media, it is the constant -1.0, so their kernels
    compile to what they were before procedural media existed; a ProceduralMediaTable's
    kernels run the medium's program (_run, a call, not inlined)."""
    raise TypeError("program_density runs inside kernels only")


@overload(program_density, inline="always", jit_options=_OVERLOAD_OPTIONS)
def _program_density(mt, m, u, x):
    fields = tuple(getattr(mt, "fields", ()))
    # Plain tables, and MediaData without procedural media (programs None), have none.
    if "programs" not in fields or isinstance(mt.types[fields.index("programs")], types.NoneType):
        return lambda mt, m, u, x: -1.0

    def impl(mt, m, u, x):
        k = mt.index[m, I_PROGRAM]
        if k < 0:
            return -1.0
        if 0.0 <= u[0] <= 1.0 and 0.0 <= u[1] <= 1.0 and 0.0 <= u[2] <= 1.0:
            return _run(mt.programs, k, x)
        return 0.0  # outside the box, as a grid

    return impl


def evaluate_density(programs: DensityPrograms, k: int, points: np.ndarray) -> np.ndarray:
    """(N,) density of program k at world points (N, 3), ignoring the box, as the trackers
    get it (_run: float32 points, +z normal, clamped at 0), through shading.evaluate's
    entry (tests, tools)."""
    n = len(points)
    out = np.zeros((n, 1), np.float32)
    x = np.ascontiguousarray(points, np.float32)
    normals = np.tile(np.array([[0.0, 0.0, 1.0]], np.float32), (n, 1))
    evaluate_points(programs.tables, np.int64(k), np.full(n, -1, np.int32), np.zeros((n, 3), np.float32), x,
                    normals, programs.regs, np.int64(programs.density[k]), np.int64(1), out)
    rho = out[:, 0].astype(np.float64)
    return np.where(rho > 0.0, rho, 0.0)


def bound_violations(mt, m: int, n: int, seed: int = 0) -> tuple[int, float]:
    """(count, worst excess) of points where procedural medium m's density exceeds its cell's
    majorant, over n random points of its box, half of them on cell faces (where DDA
    rounding puts tentative collisions). mt: a ProceduralMediaTable."""
    rng = np.random.default_rng(seed)
    dims = mt.index[m, I_MAJ_DIMS:I_MAJ_DIMS + 3].astype(np.int64)
    u = rng.random((n, 3))
    faces = rng.integers(0, 3, n // 2)
    u[np.arange(n // 2), faces] = np.round(u[np.arange(n // 2), faces] * dims[faces]) / dims[faces]
    to_unit = mt.params[m, P_TO_UNIT:P_TO_UNIT + 12].astype(np.float64).reshape(3, 4)
    full = np.vstack([to_unit, [0.0, 0.0, 0.0, 1.0]])
    unit_to_world = np.linalg.inv(full)
    x = u @ unit_to_world[:3, :3].T + unit_to_world[:3, 3]
    rho = evaluate_density(mt.programs, int(mt.index[m, I_PROGRAM]), x)
    cell = np.minimum((u * dims).astype(np.int64), dims - 1)
    # A point on a face belongs to both cells: check against the smaller majorant.
    below = np.maximum(np.ceil(u * dims).astype(np.int64) - 1, 0)
    offset = int(mt.index[m, I_MAJ_OFFSET])

    def maj(c):
        return mt.maj_data[offset + (c[:, 2] * dims[1] + c[:, 1]) * dims[0] + c[:, 0], CELL_DENSITY_BOUND]

    bound = np.minimum(maj(cell), maj(below))
    excess = rho - bound
    return int(np.count_nonzero(excess > 0.0)), float(excess.max(initial=-math.inf))
