"""Flatten a list of Medium descriptions into the media tables (layout in layout.py).

build_media_data() gives the immutable MediaData a compiled scene keeps; compile_media()
adds a fresh walker scratch, for callers that run the media kernels directly (tests, tools).
Every medium is validated first (renderer.validate.validate_medium), so the kernels never
see a bad grid or transform even when the scene skipped validate_scene.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from renderer.mapped import concatenate
from renderer.media.blackbody import blackbody_emission_voxels
from renderer.media.bricks import BRICK, SPAN, SparseGrid
from renderer.media.layout import (
    CELL,
    CELL_DENSITY_BOUND,
    CELL_EMITS,
    CELL_EXACT,
    GRID_BLACKBODY,
    GRID_NAMES,
    I_HAS_EMISSION,
    I_PROGRAM,
    INDEX,
    MEDIUM_GRID,
    MEDIUM_HOMOGENEOUS,
    PARAMS,
    MediaData,
    MediaTable,
    dda_scratch,
)
from renderer.media.procedural import PROC_CELLS, build_program_tables, check_program, density_bounds
from renderer.scene import MEDIUM_TYPES, Medium
from renderer.validate import validate_medium

# Majorant cells aim at MAJ_VOXELS voxels per axis, capped at MAJ_MAX_CELLS per axis: small
# cells bound sparse data tightly, and a 64^3 cap keeps the DDA walk short.
MAJ_VOXELS = 4
MAJ_MAX_CELLS = 64
# Sparse grids (bricks.py) get one cell per brick up to this many per axis (a 1024^3 grid:
# 128^3 cells of 12 bytes, 25 MB).
SPARSE_MAX_CELLS = 128
# Tentative collisions per majorant cell crossed inside emitting cells (see emission_rate).
EMISSION_COLLISIONS_PER_CELL = 2.0
# A cell is crossed by regular tracking (regular.py) when its bound exceeds the least density
# in it by more than this optical depth along the cell's diagonal: null-collision tracking
# would spend up to that many tentative collisions per crossing, about what regular tracking
# costs (two lookups per voxel plane crossed), so no crossing costs more than a few dozen
# lookups however high one voxel's density is.
EXACT_DEPTH = 32.0


def compile_media(media: list[Medium], use_majorant_grid: bool = True) -> MediaTable:
    """build_media_data() with a walker scratch of its own: the media kernels' argument."""
    return build_media_data(media, use_majorant_grid).with_scratch(dda_scratch())


def build_media_data(media: list[Medium], use_majorant_grid: bool = True) -> MediaData:
    """Validate `media` and flatten them into MediaData (an empty list gives M = 0).

    With use_majorant_grid False every grid medium gets a single majorant cell holding its
    global maximum density (the paper's single bound), which is correct but slower; it is
    then always null-collision tracked (no cell is flagged for regular tracking), as the
    paper's estimator.
    """
    params = np.zeros((len(media), PARAMS.size), np.float32)
    index = np.zeros((len(media), INDEX.size), np.int64)
    store = _ArrayStore()
    programs: list = []
    for i, med in enumerate(media):
        validate_medium(med, f"media[{i}]")
        if med.program is not None:
            check_program(med.program, med.program_density, f"media[{i}]")
        _fill_medium(params[i], index[i], med, store, use_majorant_grid)
        if med.program is not None:
            index[i, I_PROGRAM] = len(programs)
            programs.append(med)
    tables = None
    if programs:
        tables = build_program_tables([m.program for m in programs], [m.program_density for m in programs])
    return MediaData(params, index, store.grid_data(), store.brick_index(), store.maj_data(), tables)


class _ArrayStore:
    """grid_data, brick_index and maj_data under construction. Instances of one volume share
    their arrays (the exporter passes the same objects), so each array is stored once, keyed
    by identity (the media list keeps the arrays alive meanwhile). A sparse grid is stored as
    an all-zero brick, then its bricks; its lattice (brick numbers + 1, so empty ones point
    at the zero brick) once per index array, which the grids of one volume share."""

    def __init__(self) -> None:
        self.grids: list[np.ndarray] = []
        self.grid_size = 0
        self.grid_at: dict[tuple, tuple[int, tuple[int, int, int], object, int]] = {}
        self.lattices: list[np.ndarray] = []
        self.lattice_size = 0
        self.lattice_at: dict[int, tuple[int, np.ndarray]] = {}
        self.majs: list[np.ndarray] = []
        self.maj_size = 0
        self.maj_at: dict[tuple, tuple[int, tuple[int, int, int]]] = {}

    def grid(self, key: tuple, make) -> tuple[int, tuple[int, int, int], object, int]:
        """(offset, (nx, ny, nz), grid, lattice offset or -1 if dense) of the grid `make()`
        gives (an array or a SparseGrid), stored once per key."""
        if key not in self.grid_at:
            grid = make()
            if isinstance(grid, SparseGrid):
                lattice = self._lattice(grid.index)
                flat = np.ascontiguousarray(grid.zero_led(), np.float32).reshape(-1)  # a view if built so
                shape = grid.shape
            else:
                grid = np.ascontiguousarray(grid, dtype=np.float32)
                flat, shape, lattice = grid.ravel(), grid.shape, -1
            self.grid_at[key] = (self.grid_size, (shape[2], shape[1], shape[0]), grid, lattice)
            self.grids.append(flat)
            self.grid_size += flat.size
        return self.grid_at[key]

    def _lattice(self, index: np.ndarray) -> int:
        if id(index) not in self.lattice_at:  # the array is kept too, so its id stays its own
            self.lattice_at[id(index)] = (self.lattice_size, index)
            self.lattices.append((index.astype(np.int64).ravel() + 1).astype(np.int32))
            self.lattice_size += index.size
        return self.lattice_at[id(index)][0]

    def brick_index(self) -> np.ndarray:
        data = np.concatenate(self.lattices) if self.lattices else np.zeros(1, np.int32)
        return np.ascontiguousarray(data, np.int32)

    def majorant(self, key: tuple, make) -> tuple[int, tuple[int, int, int]]:
        """(offset, (cx, cy, cz)) of the (cz, cy, cx, CELL.size) cells `make()` gives."""
        if key not in self.maj_at:
            maj = make()
            cz, cy, cx = maj.shape[:3]
            self.maj_at[key] = (self.maj_size, (cx, cy, cz))
            self.majs.append(maj.reshape(-1, CELL.size))
            self.maj_size += cx * cy * cz
        return self.maj_at[key]

    def grid_data(self) -> np.ndarray:
        """Every grid in one array; a single grid is not copied (a large sparse grid is then
        shared with the scene's SparseGrid, not held twice)."""
        if len(self.grids) == 1:
            return self.grids[0]
        data = concatenate(self.grids) if self.grids else np.zeros(1, np.float32)  # large: a mapped file
        return np.ascontiguousarray(data, np.float32)

    def maj_data(self) -> np.ndarray:
        data = np.concatenate(self.majs) if self.majs else np.zeros((1, CELL.size), np.float32)
        return np.ascontiguousarray(data, np.float32)


def _fill_medium(params: np.ndarray, index: np.ndarray, med: Medium, store: _ArrayStore,
                 use_majorant_grid: bool) -> None:
    """Write a validated medium's params and index rows (grids and majorants into `store`)."""
    params[PARAMS.slice("sigma_a")] = np.asarray(med.sigma_a, np.float64) * med.scale
    params[PARAMS.slice("sigma_s")] = np.asarray(med.sigma_s, np.float64) * med.scale
    params[PARAMS.slice("g")] = med.g
    params[PARAMS.slice("emission")] = med.emission
    params[PARAMS.slice("blackbody")] = med.blackbody_intensity
    kind = MEDIUM_TYPES[med.type]
    emits_constant = any(e > 0.0 for e in med.emission)
    emits_blackbody = med.temperature is not None and med.blackbody_intensity > 0.0
    index[INDEX.slice("kind")] = kind
    index[INDEX.slice("has_emission")] = int(emits_constant or (kind == MEDIUM_GRID and emits_blackbody))
    index[INDEX.slice("grid_offset")] = -1
    index[INDEX.slice("maj_offset")] = -1
    index[INDEX.slice("program")] = -1
    if kind == MEDIUM_HOMOGENEOUS:
        params[PARAMS.slice("to_unit")] = np.eye(3, 4).ravel()
        return
    to_unit, axis_lengths = _world_to_unit(med)
    params[PARAMS.slice("to_unit")] = to_unit.ravel()
    if med.program is not None:
        _fill_procedural(params, index, med, store, emits_constant, axis_lengths)
        return
    blackbody_grid = _store_grids(index, med, store, emits_blackbody)
    cells = _majorant_cells(med.density, use_majorant_grid)
    emits = bool(index[I_HAS_EMISSION])
    diagonal = math.sqrt(sum((n / c) ** 2 for c, n in zip(cells, axis_lengths)))
    exact_excess = math.inf  # the paper's single bound: null collisions only
    if use_majorant_grid:  # in density units
        exact_excess = EXACT_DEPTH / max(_max_sigma_t(med) * diagonal, 1e-300)
    key = (id(med.density), cells, emits, emits_constant, id(med.flame), id(med.temperature),
           med.blackbody_intensity, exact_excess)
    offset, dims = store.majorant(key, lambda: _majorant(med, cells, emits, emits_constant, blackbody_grid,
                                                         exact_excess))
    index[INDEX.slice("maj_offset")] = offset
    index[INDEX.slice("maj_dims")] = dims
    params[PARAMS.slice("emission_rate")] = EMISSION_COLLISIONS_PER_CELL * max(
        c / n for c, n in zip(cells, axis_lengths))


def _fill_procedural(params: np.ndarray, index: np.ndarray, med: Medium, store: _ArrayStore,
                     emits_constant: bool, axis_lengths: tuple[float, float, float]) -> None:
    """A procedural medium: no grid (its density is never looked up in grid_data, see
    grid.medium_density) and majorant cells bounding its program's density (procedural.py);
    no regular tracking."""
    index[INDEX.slice("grid_bricks")] = -1
    unit_to_world = _unit_to_world(med)
    bound = density_bounds(med, unit_to_world, f"medium {med.name!r}")
    cells = (PROC_CELLS,) * 3

    def make():
        maj = np.zeros(bound.shape + (CELL.size,), np.float32)
        maj[..., CELL_DENSITY_BOUND] = bound
        maj[..., CELL_EMITS] = 1.0 if emits_constant else 0.0
        return maj

    offset, dims = store.majorant(("program", id(med)), make)
    index[INDEX.slice("maj_offset")] = offset
    index[INDEX.slice("maj_dims")] = dims
    params[PARAMS.slice("emission_rate")] = EMISSION_COLLISIONS_PER_CELL * max(
        c / n for c, n in zip(cells, axis_lengths))


def _store_grids(index: np.ndarray, med: Medium, store: _ArrayStore, emits_blackbody: bool):
    """Store a grid medium's grids and write their offsets and sizes into its index row;
    returns its GRID_BLACKBODY array (None without one)."""
    offsets = index[INDEX.slice("grid_offset")]
    dims = index[INDEX.slice("grid_dims")].reshape(len(GRID_NAMES), 3)
    lattices = index[INDEX.slice("grid_bricks")]
    lattices[:] = -1
    blackbody_grid = None
    for which, name in enumerate(GRID_NAMES):
        source = getattr(med, name)
        if source is None or (which == GRID_BLACKBODY and not emits_blackbody):
            continue
        if which == GRID_BLACKBODY:  # stored as emission, so the intensity is part of the key
            key = (which, id(source), med.blackbody_intensity)
            make = functools.partial(_blackbody_grid, source, med.blackbody_intensity)
        else:
            # A SparseGrid is stored as it is (np.asarray would wrap it in an object array).
            keep = isinstance(source, SparseGrid)
            make = (lambda s=source: s) if keep else functools.partial(np.asarray, source)
            key = (which, id(source), 0.0)
        offsets[which], dims[which], stored, lattices[which] = store.grid(key, make)
        if which == GRID_BLACKBODY:
            blackbody_grid = stored
    return blackbody_grid


def _majorant(med: Medium, cells: tuple[int, int, int], emits: bool, emits_constant: bool,
              blackbody_grid: np.ndarray | None, exact_excess: float) -> np.ndarray:
    """(cz, cy, cx, CELL.size) majorant cells of a grid medium. Cells whose bound exceeds
    their least density by more than `exact_excess` are flagged for regular tracking, unless
    they emit (emission is estimated at tentative collisions, which regular tracking has not)."""
    maj = np.zeros((cells[2], cells[1], cells[0], CELL.size), np.float32)
    density = med.density
    if not isinstance(density, SparseGrid):
        density = np.ascontiguousarray(density, np.float32)
    bound = _cell_max(density, cells)
    maj[..., CELL_DENSITY_BOUND] = bound
    if emits:
        maj[..., CELL_EMITS] = _emitting_cells(med, cells, emits_constant, blackbody_grid)
    excess = bound.astype(np.float64) - _cell_max(density, cells, np.min)
    maj[..., CELL_EXACT] = (excess > exact_excess) & (maj[..., CELL_EMITS] == 0.0)
    return maj


def _max_sigma_t(med: Medium) -> float:
    """Largest extinction per unit density over the three channels."""
    return float(np.max(np.add(med.sigma_a, med.sigma_s))) * med.scale


def _unit_to_world(med: Medium) -> np.ndarray:
    """(4, 4) float64: to_world * T(p0) * S(p1 - p0), the grid's unit cube to the world."""
    w = med.to_world
    assert w.shape == (4, 4) and np.all(np.isfinite(w)), "validate_medium conforms to_world"
    p0 = np.asarray(med.p0, np.float64)
    extent = np.asarray(med.p1, np.float64) - p0
    assert np.all(extent != 0.0), "validate_medium rejects a flat grid box"
    box = np.eye(4)
    box[:3, :3] = np.diag(extent)
    box[:3, 3] = p0
    return w @ box


def _world_to_unit(med: Medium) -> tuple[np.ndarray, tuple[float, float, float]]:
    """D = (to_world * T(p0) * S(p1 - p0))^-1 as a 3x4 affine, and the world length of the
    unit cube's three edges (for the emission collision rate). The validator has made sure
    the box is not flat and the transform is affine and invertible."""
    unit_to_world = _unit_to_world(med)
    lin = unit_to_world[:3, :3]
    inv = np.linalg.inv(unit_to_world)
    lengths = tuple(float(np.linalg.norm(lin[:, a])) for a in range(3))
    return inv[:3, :].astype(np.float32), lengths


# ------------------------------------------------------------------------------ majorants


def _majorant_cells(grid, use_majorant_grid: bool) -> tuple[int, int, int]:
    if not use_majorant_grid:
        return (1, 1, 1)
    nz, ny, nx = grid.shape[:3]
    if isinstance(grid, SparseGrid):  # bounds come per brick: finer cells would not be tighter
        return tuple(max(1, min(SPARSE_MAX_CELLS, -(-n // BRICK))) for n in (nx, ny, nz))
    return tuple(max(1, min(MAJ_MAX_CELLS, -(-n // MAJ_VOXELS))) for n in (nx, ny, nz))


def _voxel_range(c: int, cells: int, n: int) -> tuple[int, int]:
    """Voxels (inclusive range) that trilinear interpolation can touch inside majorant cell c.

    The cell spans unit coordinates [c/cells, (c+1)/cells]; a point u reads voxels
    floor(u n - 1/2) and the next one. One extra voxel on each side keeps the bound valid
    for points a rounding error outside the cell (the DDA's boundary crossings).
    """
    lo = math.floor(c * n / cells) - 1
    hi = math.ceil((c + 1) * n / cells)
    return max(0, lo), min(n - 1, hi)


def _cell_max(grid, cells: tuple[int, int, int], reduce=np.max) -> np.ndarray:
    """(cz, cy, cx) max (or `reduce`) of `grid` over each cell's voxel range: three
    separable 1-D passes. For a SparseGrid, over the bricks that hold part of that range
    (a bound as valid, a brick looser at most)."""
    if isinstance(grid, SparseGrid):
        return _sparse_cell_reduce(grid, cells, reduce)
    out = grid
    for axis, c in zip((2, 1, 0), cells):  # numpy axis 2 is x
        n = out.shape[axis]
        parts = []
        for k in range(c):
            lo, hi = _voxel_range(k, c, n)
            parts.append(reduce(np.take(out, np.arange(lo, hi + 1), axis=axis), axis=axis, keepdims=True))
        out = np.concatenate(parts, axis=axis)
    return out


def _sparse_cell_reduce(grid: SparseGrid, cells: tuple[int, int, int], reduce) -> np.ndarray:
    """_cell_max over a SparseGrid's per-brick reductions (empty bricks give 0). Brick b
    stores voxels 8 b .. 8 b + 8 on each axis, so the bricks b with 8 b <= hi and
    8 b + 8 >= lo hold the voxels lo..hi of a cell's range."""
    out = grid.brick_reduce(reduce)
    for axis, c, n in zip((2, 1, 0), cells, grid.shape[::-1]):
        parts = []
        for k in range(c):
            lo, hi = _voxel_range(k, c, n)
            first, last = max(0, -(-(lo - SPAN + 1) // BRICK)), min(out.shape[axis] - 1, hi // BRICK)
            block = np.take(out, np.arange(first, last + 1), axis=axis)
            parts.append(reduce(block, axis=axis, keepdims=True))
        out = np.concatenate(parts, axis=axis)
    return out


def _blackbody_grid(temperature, intensity: float):
    """(nz, ny, nx, 3) float32 blackbody emission of every voxel (see GRID_BLACKBODY), or a
    3-channel SparseGrid of it for a sparse temperature grid (dense when 0 K emits, since
    its empty bricks would then not read 0)."""
    def emission(t):
        return blackbody_emission_voxels(np.asarray(t, np.float32), float(intensity)).astype(np.float32)

    if isinstance(temperature, SparseGrid):
        if np.any(emission(np.zeros(1))):
            return emission(temperature.to_dense())
        return temperature.map(emission)
    return emission(temperature)


def _emitting_cells(med: Medium, cells: tuple[int, int, int], constant: bool,
                    blackbody: np.ndarray | None) -> np.ndarray:
    """1.0 where the emission term can be non-zero inside the cell (within the unit box);
    `blackbody` is the GRID_BLACKBODY array, if the medium has one."""
    if constant and med.flame is None:
        return np.ones((cells[2], cells[1], cells[0]), np.float32)
    emits = np.zeros((cells[2], cells[1], cells[0]), np.float32)
    if constant:
        flame = med.flame if isinstance(med.flame, SparseGrid) else np.asarray(med.flame, np.float32)
        emits = np.maximum(emits, _cell_max(flame, cells) > 0.0)
    if blackbody is not None:
        # Voxels of any temperature emit when b < 1: Cycles' mix(1, T^4, b) is then positive at T = 0.
        sparse = isinstance(blackbody, SparseGrid)
        strength = blackbody.map(np.abs) if sparse else np.abs(blackbody).max(axis=-1)
        emits = np.maximum(emits, _cell_max(strength, cells) > 0.0)
    return emits.astype(np.float32)
