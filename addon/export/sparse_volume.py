"""A volume's material over sparse grids (SparseGrid bricks) to a GridMedium, in bounded memory.

The dense path (grid_fields) stores the material's coefficients per voxel, then factors
them. On sparse grids the material is evaluated brick chunk by brick chunk as well, but
nothing per voxel is kept: the common materials give, in every chunk and with the same
constants, sigma_s = s x grid and sigma_a = a x grid (Principled Volume, Volume Scatter
and Absorption, ... scaling one grid), emission = e x grid (a fire's flame grid) and a
blackbody temperature. Haze then renders those grids unchanged as its density and flame
(no copy); the temperature, the one field Haze stores per voxel whatever the material
makes of it, is written into bricks of its own (the material evaluated on each stored
voxel, so the values are the dense path's). A chunk that does not fit (a colour grid, a
non-linear Math node on the density) makes build_sparse return None and the caller runs the
general factorisation on dense grids instead.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from renderer.media.bricks import BRICK, MAP_CHUNK, BrickStore, SparseGrid

from .grid_fields import CHUNK, EXACT, FieldAccumulator, GridMedium, VoxelFields, shape_text
from .volume_shader import Blackbody, VoxelCoefficients

Evaluate = Callable[[dict[str, np.ndarray]], VoxelCoefficients | None]
EXTINCTION = ("sigma_s", "sigma_a")


class _Multiple:
    """Which of the grids some coefficients are one constant multiple of, chunk after chunk."""

    def __init__(self, names: list[str], keys: tuple[str, ...]) -> None:
        self.candidates = list(names)
        self.keys = keys
        self.constants: dict[str, dict[str, np.ndarray]] = {}
        self.nonzero = False

    def add(self, c: VoxelCoefficients, chunk: dict[str, np.ndarray]) -> bool:
        """Keep the candidates this chunk fits; False when none is left."""
        self.nonzero |= any(np.any(getattr(c, key) != 0.0) for key in self.keys)
        self.candidates = [n for n in self.candidates
                           if _fits(c, self.keys, chunk[n], self.constants.setdefault(n, {}))]
        return bool(self.candidates)

    def result(self) -> tuple[str, list[np.ndarray]]:
        """(grid name, the keys' constants, each (3,) and at least 0)."""
        name = self.candidates[0]
        return name, [np.maximum(self.constants[name].get(k, np.zeros(3)), 0.0) for k in self.keys]


def build_sparse(grids: dict[str, SparseGrid], evaluate: Evaluate, start: np.ndarray,
                 index_to_object: np.ndarray) -> tuple[GridMedium, VoxelFields] | None:
    """(GridMedium, fields for the warnings) whose density is one of `grids` (SparseGrids
    sharing a brick index) times constant coefficients and whose emission another (or the
    same) times a constant colour, if the material is that everywhere; else None."""
    # Every non-zero voxel is in the core (8^3, apron left out) of the brick it belongs to,
    # which is stored; apron voxels repeat a core voxel or are 0, where the material gives 0.
    bricks = len(next(iter(grids.values())).bricks)
    if bricks == 0:
        return None
    extinction, emission = _Multiple(list(grids), EXTINCTION), _Multiple(list(grids), ("emission",))
    blackbody = _BlackbodyStats()
    # Only the anisotropy goes through the accumulator: its columns get constant zero rows.
    accumulator = FieldAccumulator(bricks * BRICK**3)
    step = max(1, CHUNK // BRICK**3)
    for first in range(0, bricks, step):
        last = min(first + step, bricks)
        chunk = {name: g.bricks[first:last, :BRICK, :BRICK, :BRICK].reshape(-1) for name, g in grids.items()}
        c = evaluate(chunk)
        if c is None or not extinction.add(c, chunk) or not emission.add(c, chunk):
            return None
        blackbody.add(c)
        zero = np.zeros((1, 3))
        accumulator.add(first * BRICK**3, last * BRICK**3, VoxelCoefficients(zero, zero, zero, c.anisotropy))
    density_name, (sigma_s, sigma_a) = extinction.result()
    flame, colour = None, np.zeros(3)
    if emission.nonzero:
        flame_name, (colour,) = emission.result()
        flame = grids[flame_name]
    temperature = _temperature_grid(grids, evaluate) if blackbody.active else None
    fields = blackbody.fields(accumulator.result())
    medium = GridMedium(grids[density_name], flame, temperature, sigma_a, sigma_s, colour, fields.anisotropy,
                        fields.blackbody_intensity, fields.blackbody_scale[1], np.asarray(start),
                        index_to_object)
    grid = grids[density_name]
    stored = sum(g.nbytes for g in {id(g): g for g in (grid, flame, temperature) if g is not None}.values())
    kinds = "density" + (" and flame" if flame is not None else "") + (
        " and temperature" if temperature is not None else "")
    medium.stats = [f"{kinds} grids {shape_text(grid.shape)} voxels, sparse: {len(grid.bricks)} of "
                    f"{grid.index.size} bricks of 8^3, {stored / 2**20:.3f} MB"]
    return medium, fields


class _BlackbodyStats:
    """What the dense path's accumulator learns of the blackbody terms, without per-voxel
    temperatures (those go into bricks: _temperature_grid)."""

    def __init__(self) -> None:
        self.active = False
        self.several = False
        self.intensity = [np.inf, -np.inf]
        self.scale = [np.inf, -np.inf]

    def add(self, c: VoxelCoefficients) -> None:
        active = _active_blackbodies(c)
        if not active:
            return
        self.active = True
        self.several |= len(active) > 1
        term = active[0]
        self.intensity = [min(self.intensity[0], float(term.intensity.min())),
                          max(self.intensity[1], float(term.intensity.max()))]
        scale = np.asarray(term.weight * term.tint, np.float64)
        self.scale = [min(self.scale[0], float(scale.min())), max(self.scale[1], float(scale.max()))]

    def fields(self, fields: VoxelFields) -> VoxelFields:
        if self.active:
            fields.temperature = np.zeros(0, np.float32)  # present (in bricks), for the warnings
            fields.blackbody_intensity = self.intensity[1]
            fields.blackbody_scale = (self.scale[0], self.scale[1])
            fields.several_blackbodies = self.several
        return fields


def _active_blackbodies(c: VoxelCoefficients) -> list[Blackbody]:
    return [t for t in c.blackbody if np.any((t.intensity > 0.0) & (t.weight != 0.0))]


def _temperature_grid(grids: dict[str, SparseGrid], evaluate: Evaluate) -> SparseGrid:
    """The blackbody temperature of every stored voxel (apron included: the material is a
    function of each voxel's own values) as bricks on the grids' index, computed as the
    dense path computes it (the first active blackbody term's temperature, in float32).
    The caller made sure it is 0 where every grid is 0, as in brick 0 and empty bricks."""
    sources = {name: g.zero_led() for name, g in grids.items()}
    count = len(next(iter(sources.values())))
    store = BrickStore(None)
    for first in range(0, count, MAP_CHUNK):
        blocks = {name: s[first:first + MAP_CHUNK] for name, s in sources.items()}
        shape = next(iter(blocks.values())).shape[:4]
        c = evaluate({name: b.reshape(-1) for name, b in blocks.items()})
        active = _active_blackbodies(c) if c is not None else []
        values = np.zeros(int(np.prod(shape)), np.float32)
        if active:
            values[:] = np.broadcast_to(active[0].temperature[:, 0], values.shape)
        store.add(values.reshape(shape))
    grid = next(iter(grids.values()))
    return store.grid(grid.shape, grid.index)


def _fits(c: VoxelCoefficients, keys: tuple[str, ...], grid: np.ndarray,
          found: dict[str, np.ndarray]) -> bool:
    """Whether this chunk's coefficients `keys` are grid x the constants found so far (or
    the first chunk that sets them), to float32 precision."""
    g = np.asarray(grid, np.float64)
    norm = float(g @ g)
    for key in keys:
        raw = np.asarray(getattr(c, key), np.float64)
        if not raw.any():  # zero everywhere in the chunk (often one row): fits constants 0 only
            if norm > 0.0 and np.any(found.setdefault(key, np.zeros(3)) != 0.0):
                return False
            continue
        values = np.broadcast_to(raw, (len(g), 3))
        scale = float(np.max(np.abs(values)))
        if norm == 0.0:
            return False  # non-zero coefficients where the grid is 0
        fit = (g @ values) / norm
        constants = found.setdefault(key, fit)
        if np.any(np.abs(constants - fit) > EXACT * np.maximum(np.abs(constants), 1e-30)):
            return False
        residual = np.multiply.outer(g, constants)
        np.subtract(values, residual, out=residual)
        if float(np.max(np.abs(residual, out=residual))) > EXACT * max(scale, 1e-30):
            return False
    return True
