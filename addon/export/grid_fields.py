"""Per-voxel volume coefficients to Haze's grid model, in bounded memory (no bpy here).

Haze's grid medium is sigma_s = s x density(x), sigma_a = a x density(x), emission =
e x flame(x) + blackbody(temperature(x)), with constant colours s, a, e and scalar grids.
A material evaluated at every voxel (volume_shader) gives sigma_s, sigma_a and emission per
voxel; they are written in that form by a rank-one factorisation that prefers the volume's
own grid as density or flame (then Haze renders that grid unchanged) and reports when no
single colour fits (e.g. a colour grid).

Materials are evaluated chunk by chunk (CHUNK voxels at a time, float64 inside a chunk) into
float32 arrays, and values that are the same in every voxel stay one row, so a 256^3 volume
needs a few hundred MB at most, not several GB.

Grids are (nz, ny, nx) arrays; `start` is the (x, y, z) index of voxel [0, 0, 0] in the
grid's index space, where voxel (i, j, k) is centred at (i, j, k).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from renderer.scene import Medium

from .materials import MAX_ANISOTROPY
from .messages import Messages
from .volume_shader import VoxelCoefficients

CHUNK = 1 << 19  # voxels per material evaluation
EXACT = 1e-5  # relative residual under which a factorisation counts as exact (float32 data)


def chunks(count: int, size: int | None = None) -> Iterator[tuple[int, int]]:
    size = size or CHUNK
    for begin in range(0, count, size):
        yield begin, min(begin + size, count)


# ---------------------------------------------------------------------------- grid cleaning, cropping


def clean_grid(values: np.ndarray, clipping: float, subject: str, name: str,
               messages: Messages) -> np.ndarray:
    """The grid as Cycles renders it: voxels below `clipping` (and negative ones) are empty;
    NaN and infinite voxels, which Cycles would render as garbage, are dropped with a warning."""
    values = np.asarray(values, np.float32)
    finite = np.isfinite(values)
    if not finite.all():
        bad = values.size - int(np.count_nonzero(finite))
        messages.warn(subject, f"grid '{name}' has {bad} NaN or infinite voxel values; they are treated as 0")
        values = np.where(finite, values, np.float32(0.0))
    negative = int(np.count_nonzero(values < 0.0))
    if negative:
        messages.warn(subject, f"grid '{name}' has {negative} negative voxel values; they are treated as 0 "
                               "(empty, as Cycles' clipping makes them)")
    scalar = values if values.ndim == 3 else values.max(axis=-1)
    keep = scalar >= max(float(clipping), 0.0) if clipping > 0.0 else scalar > 0.0
    keep = keep[..., None] if values.ndim == 4 else keep
    return np.where(keep & (values >= 0.0), values, np.float32(0.0))


def crop_box(masks: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray] | None:
    """(lo, hi) inclusive (z, y, x) bounds of the voxels set in any mask, or None if none is."""
    union = np.zeros(masks[0].shape, bool)
    for mask in masks:
        union |= mask
    if not union.any():
        return None
    where = [np.flatnonzero(union.any(axis=tuple(a for a in range(3) if a != axis))) for axis in range(3)]
    return np.array([w[0] for w in where]), np.array([w[-1] for w in where])


def crop(values: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """values[lo - 1 .. hi + 1] (z, y, x), zero-padded where that leaves the array: one empty
    voxel around the kept ones, so the density falls to 0 inside the grid box."""
    pad = [(max(0, 1 - int(lo[a])), max(0, int(hi[a]) + 2 - values.shape[a])) for a in range(3)]
    pad += [(0, 0)] * (values.ndim - 3)
    padded = np.pad(values, pad) if any(p != (0, 0) for p in pad) else values
    start = [int(lo[a]) - 1 + pad[a][0] for a in range(3)]
    stop = [int(hi[a]) + 2 + pad[a][0] for a in range(3)]
    return np.ascontiguousarray(padded[start[0]:stop[0], start[1]:stop[1], start[2]:stop[2]], np.float32)


def crop_to_voxels(raw: dict[str, np.ndarray], start: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The grids cut to their non-zero voxels plus one empty voxel around them, and the (x, y, z)
    index of the new voxel [0, 0, 0]."""
    masks = [(v != 0.0) if v.ndim == 3 else np.any(v != 0.0, axis=-1) for v in raw.values()]
    box = crop_box(masks)
    if box is None:
        return raw, start
    lo, hi = box
    return {name: crop(values, lo, hi) for name, values in raw.items()}, start + lo[::-1] - 1


# ---------------------------------------------------------------------------- factorisation


def block_rows(blocks: list[np.ndarray], begin: int, end: int) -> np.ndarray:
    """Rows begin..end of the column blocks side by side, float64 (one-row blocks repeat)."""
    parts = [np.broadcast_to(b if b.shape[0] == 1 else b[begin:end], (end - begin, b.shape[1]))
             for b in blocks]
    return np.concatenate(parts, axis=1).astype(np.float64)


def factor_rank_one(values, candidates: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, bool]:
    """Write per-voxel values ((n, c) array, or a list of (n, k) / (1, k) column blocks) as
    field (n,) x constants (c,).

    A candidate grid (n,) the values are a constant multiple of is preferred, and returned
    as it is; otherwise the field is the values' mean over their columns. Returns (field,
    constants, exact); exact says the product reproduces the values to float32 precision."""
    blocks = [np.atleast_2d(values)] if isinstance(values, np.ndarray) else list(values)
    count = max(b.shape[0] for b in blocks)
    scale = max(float(np.max(np.abs(b))) if b.size else 0.0 for b in blocks)
    for grid in candidates:
        if len(grid) != count:
            continue
        constants = _fit(blocks, grid, count)
        if constants is not None and _residual(blocks, grid, constants, count) <= EXACT * scale:
            return grid, constants, True
    field_values = np.empty(count, np.float32)
    for begin, end in chunks(count):
        field_values[begin:end] = block_rows(blocks, begin, end).mean(axis=1)
    constants = _fit(blocks, field_values, count)
    if constants is None:
        return field_values, np.zeros(sum(b.shape[1] for b in blocks)), True
    return field_values, constants, _residual(blocks, field_values, constants, count) <= EXACT * scale


def _fit(blocks: list[np.ndarray], grid: np.ndarray, count: int) -> np.ndarray | None:
    """Least-squares constants c of values ~ grid x c, or None for an all-zero grid."""
    norm, product = 0.0, 0.0
    for begin, end in chunks(count):
        part = np.asarray(grid[begin:end], np.float64)
        norm += float(part @ part)
        product = product + part @ block_rows(blocks, begin, end)
    return product / norm if norm > 0.0 else None


def _residual(blocks: list[np.ndarray], grid: np.ndarray, constants: np.ndarray, count: int) -> float:
    worst = 0.0
    for begin, end in chunks(count):
        rows = block_rows(blocks, begin, end)
        worst = max(worst, float(np.max(np.abs(rows - np.outer(np.asarray(grid[begin:end], np.float64),
                                                                     constants)))))
    return worst


# ---------------------------------------------------------------------------- per-voxel fields


class Column:
    """Per-voxel values filled chunk by chunk: one row while every chunk gives the same
    constant, else a float32 (n, width) array."""

    def __init__(self, count: int, width: int) -> None:
        self.count, self.width = count, width
        self.constant: np.ndarray | None = None
        self.array: np.ndarray | None = None

    def put(self, begin: int, end: int, values: np.ndarray) -> None:
        values = np.asarray(values, np.float64)
        if self.array is None:
            if values.shape[0] == 1 and (self.constant is None or np.array_equal(self.constant, values)):
                self.constant = values.copy()
                return
            self.array = np.empty((self.count, self.width), np.float32)
            if self.constant is not None:
                self.array[:begin] = self.constant
        self.array[begin:end] = np.broadcast_to(values, (end - begin, self.width))

    def result(self) -> np.ndarray:
        if self.array is not None:
            return self.array
        return self.constant if self.constant is not None else np.zeros((1, self.width))


@dataclass
class VoxelFields:
    """A material's coefficients at every voxel of a grid lattice, ready to factor."""

    sigma_s: np.ndarray  # (n, 3) float32 or (1, 3)
    sigma_a: np.ndarray
    emission: np.ndarray
    temperature: np.ndarray | None  # (n,) float32 kelvin, where blackbody emission is on
    blackbody_intensity: float
    blackbody_scale: tuple[float, float]  # min and max of Cycles' blackbody weight x tint
    anisotropy: float
    anisotropy_spread: float  # largest |g - mean g| where the volume scatters
    several_blackbodies: bool = False


class FieldAccumulator:
    """Collects VoxelCoefficients chunk by chunk into VoxelFields."""

    def __init__(self, count: int) -> None:
        self.count = count
        self.columns = {name: Column(count, 3) for name in ("sigma_s", "sigma_a", "emission")}
        self.temperature: np.ndarray | None = None
        self.intensity = [np.inf, -np.inf]
        self.scale = [np.inf, -np.inf]
        self.g_weighted, self.weight = 0.0, 0.0
        self.g_values: list[tuple[float, float]] = []  # (min, max) of g where there is scattering
        self.several_blackbodies = False

    def add(self, begin: int, end: int, coefficients: VoxelCoefficients) -> None:
        for name, column in self.columns.items():
            column.put(begin, end, np.maximum(getattr(coefficients, name), 0.0))
        for g, weight in coefficients.anisotropy:
            w = np.maximum(weight, 0.0)
            # The mean of three columns, added as mean() adds them (bit for bit), but faster.
            w_mean = (w[:, 0] + w[:, 1] + w[:, 2]) / 3.0 if w.shape[1] == 3 else w.mean(axis=1)
            g_rows, w_rows = np.broadcast_arrays(g[:, 0], w_mean)
            self.g_weighted += float((g_rows * w_rows).sum())
            self.weight += float(w_rows.sum())
            scattering = g_rows[w_rows > 0.0]
            if scattering.size:
                self.g_values.append((float(scattering.min()), float(scattering.max())))
        self._add_blackbody(begin, end, coefficients)

    def _add_blackbody(self, begin: int, end: int, coefficients: VoxelCoefficients) -> None:
        active = [t for t in coefficients.blackbody if np.any((t.intensity > 0.0) & (t.weight != 0.0))]
        if not active:
            return
        self.several_blackbodies |= len(active) > 1
        term = active[0]
        if self.temperature is None:
            self.temperature = np.zeros(self.count, np.float32)
        self.temperature[begin:end] = np.broadcast_to(term.temperature[:, 0], (end - begin,))
        self.intensity = [min(self.intensity[0], float(term.intensity.min())),
                          max(self.intensity[1], float(term.intensity.max()))]
        scale = np.asarray(term.weight * term.tint, np.float64)
        self.scale = [min(self.scale[0], float(scale.min())), max(self.scale[1], float(scale.max()))]

    def result(self) -> VoxelFields:
        g = self.g_weighted / self.weight if self.weight > 0.0 else 0.0
        spread = max((max(abs(low - g), abs(high - g)) for low, high in self.g_values), default=0.0)
        has_blackbody = self.temperature is not None
        columns = self.columns
        return VoxelFields(
            columns["sigma_s"].result(), columns["sigma_a"].result(), columns["emission"].result(),
            self.temperature, self.intensity[1] if has_blackbody else 0.0,
            (self.scale[0], self.scale[1]) if has_blackbody else (1.0, 1.0),
            float(np.clip(g, -MAX_ANISOTROPY, MAX_ANISOTROPY)), spread, self.several_blackbodies)


def evaluate_fields(evaluate: Callable[[dict[str, np.ndarray]], VoxelCoefficients | None],
                    grids: dict[str, np.ndarray], count: int) -> VoxelFields | None:
    """`evaluate` (a material over voxel values) applied chunk by chunk to flattened grids."""
    accumulator = FieldAccumulator(count)
    for begin, end in chunks(count):
        coefficients = evaluate({name: values[begin:end] for name, values in grids.items()})
        if coefficients is None:
            return None
        accumulator.add(begin, end, coefficients)
    return accumulator.result()


# ---------------------------------------------------------------------------- grid media


@dataclass
class GridMedium:
    """A volume's grids and constants as Haze renders them, shared by all its instances."""

    density: np.ndarray  # (nz, ny, nx) float32
    flame: np.ndarray | None
    temperature: np.ndarray | None
    sigma_a: np.ndarray  # (3,)
    sigma_s: np.ndarray
    emission: np.ndarray
    g: float
    blackbody_intensity: float
    blackbody_scale: float  # Cycles' blackbody weight (mix weight x tint); Haze renders 1
    start: np.ndarray  # (3,) x, y, z index of the grid's voxel [0, 0, 0]
    index_to_object: np.ndarray  # (4, 4)
    stats: list[str] = field(default_factory=list)

    def medium(self, name: str, matrix_world: np.ndarray, density_factor: float) -> Medium:
        shape = np.array(self.density.shape[::-1])
        p0 = self.start - 0.5
        return Medium(
            name, "grid", sigma_a=tuple(float(v) for v in self.sigma_a),
            sigma_s=tuple(float(v) for v in self.sigma_s), scale=float(density_factor), g=self.g,
            emission=tuple(float(v) * density_factor for v in self.emission), density=self.density,
            p0=tuple(float(v) for v in p0), p1=tuple(float(v) for v in p0 + shape),
            to_world=matrix_world @ self.index_to_object, flame=self.flame, temperature=self.temperature,
            blackbody_intensity=self.blackbody_intensity)


def megabytes(values: np.ndarray | None) -> float:
    return 0.0 if values is None else values.nbytes / 2**20


def shape_text(shape) -> str:
    return "x".join(str(int(s)) for s in reversed(shape))  # x by y by z


class FieldBuilder:
    """Turns one volume's VoxelFields into a GridMedium on its voxel lattice."""

    def __init__(self, subject: str, messages: Messages, shape: tuple[int, int, int],
                 raw: dict[str, np.ndarray], crop_grids: bool = True) -> None:
        self.subject, self.messages, self.shape = subject, messages, tuple(shape)
        self.count = int(np.prod(shape))
        self.crop_grids = crop_grids
        # Scalar grids the material may scale: preferred as Haze's density and flame.
        self.candidates = [v.reshape(-1) for v in raw.values() if v.ndim == 3]

    def extinction(self, fields: VoxelFields):
        if not (np.any(fields.sigma_s) or np.any(fields.sigma_a)):
            return np.zeros(self.shape, np.float32), np.zeros(3), np.zeros(3)
        density, constants, exact = factor_rank_one([fields.sigma_s, fields.sigma_a], self.candidates)
        if not exact:
            self.messages.warn(self.subject, "the volume's colour varies between voxels (e.g. a colour grid "
                                             "or different Math on scattering and absorption); Haze "
                                             "renders one colour per volume, their average")
        density = np.broadcast_to(density, (self.count,)).reshape(self.shape).astype(np.float32)
        return density, np.maximum(constants[:3], 0.0), np.maximum(constants[3:], 0.0)

    def emission(self, fields: VoxelFields):
        values = fields.emission
        if not np.any(values):
            return None, np.zeros(3)
        if values.shape[0] == 1:
            return None, values[0]  # constant: Haze emits it throughout the grid box
        flame, constants, exact = factor_rank_one([values], self.candidates)
        if not exact:
            self.messages.warn(self.subject, "the emission colour varies between voxels; Haze renders one "
                                             "colour per volume, the average")
        return flame.reshape(self.shape).astype(np.float32), np.maximum(constants, 0.0)

    def warn_blackbody(self, fields: VoxelFields) -> None:
        if fields.several_blackbodies:
            self.messages.warn(self.subject, "several Principled Volume blackbody emissions; Haze renders "
                                             "the first")
        if fields.temperature is not None and max(abs(v - 1.0) for v in fields.blackbody_scale) > 1e-6:
            self.messages.warn(self.subject, "Haze's blackbody emission has no tint or weight: Blackbody "
                                             "Tint and Mix Shader factors on the blackbody are rendered as 1")
        if fields.anisotropy_spread > 1e-6:
            self.messages.warn(self.subject, "the volume's Anisotropy varies; Haze uses its scattering-"
                                             f"weighted mean {fields.anisotropy:.3g}")

    def build(self, fields: VoxelFields, start: np.ndarray, index_to_object: np.ndarray,
              read_shape: tuple[int, int, int]) -> GridMedium | None:
        density, sigma_s, sigma_a = self.extinction(fields)
        flame, emission = self.emission(fields)
        temperature = None if fields.temperature is None else fields.temperature.reshape(self.shape)
        self.warn_blackbody(fields)
        masks = [density > 0.0]
        if flame is not None:
            masks.append(flame > 0.0)
        if temperature is not None:
            masks.append(temperature > 0.0)
        if flame is None and np.any(emission):
            masks.append(np.ones(self.shape, bool))
        box = crop_box(masks)
        if box is None:
            return None
        lo, hi = box if self.crop_grids else (np.ones(3, int), np.array(self.shape) - 2)
        grids = [crop(a, lo, hi) if a is not None else None for a in (density, flame, temperature)]
        bb_scale = fields.blackbody_scale[1]
        medium = GridMedium(grids[0], grids[1], grids[2], sigma_a, sigma_s, emission, fields.anisotropy,
                            fields.blackbody_intensity, bb_scale, start + lo[::-1] - 1, index_to_object)
        medium.stats = grid_stats(read_shape, medium)
        return medium


def grid_stats(read_shape, medium: GridMedium) -> list[str]:
    before = int(np.prod(read_shape)) * 4 / 2**20
    lines = []
    for name in ("density", "flame", "temperature"):
        values = getattr(medium, name)
        if values is not None:
            lines.append(f"{name} grid {shape_text(values.shape)} voxels, {megabytes(values):.3f} MB "
                         f"(read {shape_text(read_shape)}, {before:.3f} MB before cropping)")
    return lines
