"""Flatten a list of Medium descriptions into the arrays the media kernels read.

MediaTable is a NamedTuple of four contiguous numpy arrays; numba passes it to @njit
kernels as one argument (fine with cache=True). It is deliberately a few wide arrays
rather than one array per field: every non-inlined call passes each array of the tuple,
so a 15-array table made a trilinear lookup ~5x slower. M = number of media; a medium id
is its index in the list.

    params    (M, P_SIZE) float32  per-medium floats, columns:
        P_SIGMA_A + c      absorption per world unit of channel c, already times `scale`
        P_SIGMA_S + c      scattering per world unit, already times `scale`
        P_G                Henyey-Greenstein asymmetry
        P_EMISSION + c     emission per unit length (see renderer.media.emission)
        P_BLACKBODY        blackbody intensity (already applied in the GRID_BLACKBODY grid)
        P_EMISSION_RATE    tentative-collision rate (per world unit) guaranteed in emitting
                           cells of a grid, so that emission where the density is ~0 is
                           still estimated (see tracking.py)
        P_TO_UNIT + 4 r + k  world -> grid unit cube affine [A | b], u = A x + b, row r
                           (identity for homogeneous media)
    index     (M, I_SIZE) int64    per-medium integers, columns:
        I_KIND             MEDIUM_HOMOGENEOUS (0) or MEDIUM_GRID (1)
        I_HAS_EMISSION     1 if the medium can emit anywhere (else emission costs nothing)
        I_GRID_OFFSET + w  start of grid w (GRID_DENSITY, GRID_FLAME, GRID_BLACKBODY) in
                           grid_data, -1 when absent
        I_GRID_DIMS + 3 w + a   size of grid w along axis a (x, y, z); voxel (i, j, k) is
                           grid_data[offset + (k * ny + j) * nx + i]; GRID_BLACKBODY holds
                           three values per voxel, its channel c at 3 (that index) + c
        I_MAJ_OFFSET       first cell of the medium's majorant grid in maj_data (-1 if none)
        I_MAJ_DIMS + a     majorant cells along unit-cube axis a
    grid_data (N,)        float32  every grid, x fastest. The temperature grid is stored as
                                   GRID_BLACKBODY, the RGB blackbody emission of every voxel
                                   (intensity applied), which the kernels interpolate: Cycles'
                                   semantics (see renderer.media.blackbody)
    maj_data  (K, 2)      float32  per majorant cell (x fastest): [max density that trilinear
                                   interpolation can reach inside the cell, 1.0 if the cell
                                   can emit else 0.0]

A homogeneous medium has density 1 everywhere: the medium stack says where it applies.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from renderer.errors import SceneError
from renderer.scene import Medium

MEDIUM_HOMOGENEOUS = 0
MEDIUM_GRID = 1

GRID_DENSITY = 0
GRID_FLAME = 1
GRID_BLACKBODY = 2  # from the medium's temperature grid: per-voxel blackbody emission, RGB
GRID_NAMES = ("density", "flame", "temperature")  # the Medium fields behind the indices above

# Majorant cells aim at MAJ_VOXELS voxels per axis, capped at MAJ_MAX_CELLS per axis: small
# cells bound sparse data tightly, and a 64^3 cap keeps the DDA walk short.
MAJ_VOXELS = 4
MAJ_MAX_CELLS = 64
# Tentative collisions per majorant cell crossed inside emitting cells (see emission_rate).
EMISSION_COLLISIONS_PER_CELL = 2.0


P_SIGMA_A = 0
P_SIGMA_S = 3
P_G = 6
P_EMISSION = 7
P_BLACKBODY = 10
P_EMISSION_RATE = 11
P_TO_UNIT = 12
P_SIZE = 24

I_KIND = 0
I_HAS_EMISSION = 1
I_GRID_OFFSET = 2
I_GRID_DIMS = 5
I_MAJ_OFFSET = 14
I_MAJ_DIMS = 15
I_SIZE = 18


class MediaTable(NamedTuple):
    params: np.ndarray
    index: np.ndarray
    grid_data: np.ndarray
    maj_data: np.ndarray
    # (MAX_STACK, DDA_SIZE) float64 working rows of the majorant-grid walk. Kernels run one
    # path at a time per process, so one scratch serves them all; it lives here because the
    # kernels are compiled without reference counting and so cannot allocate.
    scratch: np.ndarray


def compile_media(media: list[Medium], use_majorant_grid: bool = True) -> MediaTable:
    """Validate `media` and flatten them into a MediaTable (an empty list gives M = 0).

    With use_majorant_grid False every grid medium gets a single majorant cell holding its
    global maximum density (the paper's single bound), which is correct but slower.
    """
    m = len(media)
    kind = np.zeros(m, np.int32)
    sigma_a = np.zeros((m, 3), np.float32)
    sigma_s = np.zeros((m, 3), np.float32)
    g = np.zeros(m, np.float32)
    emission = np.zeros((m, 3), np.float32)
    has_emission = np.zeros(m, np.int32)
    blackbody = np.zeros(m, np.float32)
    to_unit = np.zeros((m, 3, 4), np.float32)
    grid_offset = np.full((m, 3), -1, np.int64)
    grid_dims = np.zeros((m, 3, 3), np.int32)
    maj_offset = np.full(m, -1, np.int64)
    maj_dims = np.zeros((m, 3), np.int32)
    emission_rate = np.zeros(m, np.float32)
    grids: list[np.ndarray] = []
    majs: list[np.ndarray] = []
    grid_size = 0
    maj_size = 0
    # Instances of one volume share their arrays (the exporter passes the same objects):
    # store each array once, keyed by identity (the media list keeps them alive meanwhile).
    shared_grids: dict[tuple, tuple[int, tuple[int, int, int], np.ndarray]] = {}
    shared_majs: dict[tuple, tuple[int, tuple[int, int, int]]] = {}

    for i, med in enumerate(media):
        path = f"media[{i}]"
        _check_medium(med, path)
        kind[i] = MEDIUM_GRID if med.type == "grid" else MEDIUM_HOMOGENEOUS
        sigma_a[i] = np.asarray(med.sigma_a, np.float64) * med.scale
        sigma_s[i] = np.asarray(med.sigma_s, np.float64) * med.scale
        g[i] = med.g
        emission[i] = med.emission
        blackbody[i] = med.blackbody_intensity
        emits_constant = any(e > 0.0 for e in med.emission)
        emits_blackbody = med.temperature is not None and med.blackbody_intensity > 0.0
        has_emission[i] = int(emits_constant or (kind[i] == MEDIUM_GRID and emits_blackbody))
        if kind[i] == MEDIUM_HOMOGENEOUS:
            to_unit[i] = np.eye(3, 4)
            continue

        to_unit[i], axis_lengths = _world_to_unit(med, path)
        blackbody_grid = None
        for which, name in enumerate(GRID_NAMES):
            source = getattr(med, name)
            if source is None or (which == GRID_BLACKBODY and not emits_blackbody):
                continue
            key = (which, id(source), med.blackbody_intensity if which == GRID_BLACKBODY else 0.0)
            if key not in shared_grids:
                arr = _blackbody_grid(source, med.blackbody_intensity) if which == GRID_BLACKBODY else source
                arr = np.ascontiguousarray(arr, dtype=np.float32)
                shared_grids[key] = (grid_size, (arr.shape[2], arr.shape[1], arr.shape[0]), arr)
                grids.append(arr.ravel())
                grid_size += arr.size
            grid_offset[i, which], grid_dims[i, which], arr = shared_grids[key]
            if which == GRID_BLACKBODY:
                blackbody_grid = arr

        cells = _majorant_cells(med.density.shape, use_majorant_grid)
        maj_key = (id(med.density), cells, bool(has_emission[i]), emits_constant, id(med.flame),
                   id(med.temperature), med.blackbody_intensity)
        if maj_key not in shared_majs:
            maj = np.zeros((cells[2], cells[1], cells[0], 2), np.float32)
            maj[..., 0] = _cell_max(np.ascontiguousarray(med.density, np.float32), cells)
            if has_emission[i]:
                maj[..., 1] = _emitting_cells(med, cells, emits_constant, blackbody_grid)
            shared_majs[maj_key] = (maj_size, tuple(cells))
            majs.append(maj.reshape(-1, 2))
            maj_size += maj.shape[0] * maj.shape[1] * maj.shape[2]
        maj_offset[i], maj_dims[i] = shared_majs[maj_key]
        emission_rate[i] = EMISSION_COLLISIONS_PER_CELL * max(c / n for c, n in zip(cells, axis_lengths))

    grid_data = np.concatenate(grids) if grids else np.zeros(1, np.float32)
    maj_data = np.concatenate(majs) if majs else np.zeros((1, 2), np.float32)
    params = np.zeros((m, P_SIZE), np.float32)
    params[:, P_SIGMA_A : P_SIGMA_A + 3] = sigma_a
    params[:, P_SIGMA_S : P_SIGMA_S + 3] = sigma_s
    params[:, P_G] = g
    params[:, P_EMISSION : P_EMISSION + 3] = emission
    params[:, P_BLACKBODY] = blackbody
    params[:, P_EMISSION_RATE] = emission_rate
    params[:, P_TO_UNIT : P_TO_UNIT + 12] = to_unit.reshape(m, 12)
    index = np.zeros((m, I_SIZE), np.int64)
    index[:, I_KIND] = kind
    index[:, I_HAS_EMISSION] = has_emission
    index[:, I_GRID_OFFSET : I_GRID_OFFSET + 3] = grid_offset
    index[:, I_GRID_DIMS : I_GRID_DIMS + 9] = grid_dims.reshape(m, 9)
    index[:, I_MAJ_OFFSET] = maj_offset
    index[:, I_MAJ_DIMS : I_MAJ_DIMS + 3] = maj_dims
    return MediaTable(
        params,
        index,
        np.ascontiguousarray(grid_data, np.float32),
        np.ascontiguousarray(maj_data, np.float32),
        _dda_scratch(),
    )


def _dda_scratch() -> np.ndarray:
    # Imported here: the DDA module reads this module's column constants.
    from renderer.media.majorant import DDA_SIZE
    from renderer.media.stack import MAX_STACK

    return np.zeros((MAX_STACK, DDA_SIZE), np.float64)


# ------------------------------------------------------------------------------ validation


def _check_medium(med: Medium, path: str) -> None:
    """Last line of defence: the scene loader validates too, but kernels must never see these."""
    if med.type not in ("homogeneous", "grid"):
        raise SceneError(f"{path}.type", f"must be 'homogeneous' or 'grid', got {med.type!r}")
    for name in ("sigma_a", "sigma_s", "emission"):
        value = np.asarray(getattr(med, name), np.float64)
        if value.shape != (3,) or not np.all(np.isfinite(value)) or np.any(value < 0.0):
            raise SceneError(f"{path}.{name}", f"must be three finite values >= 0, got {getattr(med, name)}")
    for name in ("scale", "blackbody_intensity"):
        value = float(getattr(med, name))
        if not math.isfinite(value) or value < 0.0:
            raise SceneError(f"{path}.{name}", f"must be finite and >= 0, got {value}")
    if not (math.isfinite(med.g) and abs(med.g) < 1.0):
        raise SceneError(f"{path}.g", f"must satisfy |g| < 1, got {med.g}")
    if med.type == "homogeneous":
        for name in ("density", "flame", "temperature"):
            if getattr(med, name) is not None:
                raise SceneError(f"{path}.{name}", "only grid media take grid arrays (type is 'homogeneous')")
        return
    if med.density is None:
        raise SceneError(f"{path}.density", "required for grid media")
    for name in ("density", "flame", "temperature"):
        arr = getattr(med, name)
        if arr is None:
            continue
        arr = np.asarray(arr)
        if arr.ndim != 3 or arr.size == 0:
            raise SceneError(f"{path}.{name}", f"must be a non-empty 3-D (nz, ny, nx) array, got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise SceneError(f"{path}.{name}", "contains NaN or infinite values")
        if np.any(arr < 0.0):
            raise SceneError(f"{path}.{name}", f"must not be negative, got minimum {float(arr.min())}")


def _world_to_unit(med: Medium, path: str) -> tuple[np.ndarray, tuple[float, float, float]]:
    """D = (to_world * T(p0) * S(p1 - p0))^-1 as a 3x4 affine, and the world length of the
    unit cube's three edges (for the emission collision rate)."""
    w = np.asarray(med.to_world, np.float64)
    if w.shape != (4, 4) or not np.all(np.isfinite(w)):
        raise SceneError(f"{path}.to_world", "must be a finite 4x4 matrix")
    if not np.allclose(w[3], (0.0, 0.0, 0.0, 1.0), rtol=0.0, atol=1e-9):
        raise SceneError(f"{path}.to_world", f"last row must be (0, 0, 0, 1), got {tuple(w[3])}")
    p0 = np.asarray(med.p0, np.float64)
    extent = np.asarray(med.p1, np.float64) - p0
    if not np.all(np.isfinite(extent)) or not np.all(np.isfinite(p0)):
        raise SceneError(f"{path}.p1", "p0 and p1 must be finite")
    for axis in range(3):
        if extent[axis] == 0.0:
            raise SceneError(f"{path}.p1", f"equals p0 on the {'xyz'[axis]} axis: the grid box is flat")
    box = np.eye(4)
    box[:3, :3] = np.diag(extent)
    box[:3, 3] = p0
    unit_to_world = w @ box
    lin = unit_to_world[:3, :3]
    # Singular relative to the matrix's own scale: a tiny but well-shaped box is fine.
    if not np.all(np.isfinite(lin)) or np.linalg.cond(lin) > 1e12:
        raise SceneError(f"{path}.to_world", "singular matrix (combined with p0..p1)")
    inv = np.linalg.inv(unit_to_world)
    lengths = tuple(float(np.linalg.norm(lin[:, a])) for a in range(3))
    return inv[:3, :].astype(np.float32), lengths


# ------------------------------------------------------------------------------ majorants


def _majorant_cells(shape: tuple[int, int, int], use_majorant_grid: bool) -> tuple[int, int, int]:
    if not use_majorant_grid:
        return (1, 1, 1)
    nz, ny, nx = shape
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


def _cell_max(grid: np.ndarray, cells: tuple[int, int, int]) -> np.ndarray:
    """(cz, cy, cx) max of `grid` over each cell's voxel range: three separable 1-D max passes."""
    out = grid
    for axis, c in zip((2, 1, 0), cells):  # numpy axis 2 is x
        n = out.shape[axis]
        parts = []
        for k in range(c):
            lo, hi = _voxel_range(k, c, n)
            parts.append(np.take(out, np.arange(lo, hi + 1), axis=axis).max(axis=axis, keepdims=True))
        out = np.concatenate(parts, axis=axis)
    return out


def _blackbody_grid(temperature: np.ndarray, intensity: float) -> np.ndarray:
    """(nz, ny, nx, 3) float32 blackbody emission of every voxel (see GRID_BLACKBODY)."""
    from renderer.media.blackbody import blackbody_emission_voxels

    return blackbody_emission_voxels(np.asarray(temperature, np.float32), float(intensity)).astype(np.float32)


def _emitting_cells(med: Medium, cells: tuple[int, int, int], constant: bool,
                    blackbody: np.ndarray | None) -> np.ndarray:
    """1.0 where the emission term can be non-zero inside the cell (within the unit box);
    `blackbody` is the GRID_BLACKBODY array, if the medium has one."""
    if constant and med.flame is None:
        return np.ones((cells[2], cells[1], cells[0]), np.float32)
    emits = np.zeros((cells[2], cells[1], cells[0]), np.float32)
    if constant:
        emits = np.maximum(emits, _cell_max(np.asarray(med.flame, np.float32), cells) > 0.0)
    if blackbody is not None:
        # Voxels of any temperature emit when b < 1: Cycles' mix(1, T^4, b) is then positive at T = 0.
        emits = np.maximum(emits, _cell_max(np.abs(blackbody).max(axis=-1), cells) > 0.0)
    return emits.astype(np.float32)
