"""Volume objects and smoke domains to Haze grid media inside interface boxes.

Each rendered volume becomes a grid Medium plus a closed box Mesh around the grid whose
material has no lobes (an invisible boundary that carries the medium). The steps, per volume
data and material (instances share the result, only the transform differs):

1. read the grids the material looks up (grid_sampler: a temporary geometry-node tree) over
   the volume's bounds plus one voxel of background on every side;
2. clean them as Cycles sees them: voxels below the volume's clipping value are empty (0),
   NaN and infinite voxels are dropped with a warning;
3. evaluate the material at every voxel (volume_shader) and write the coefficients as Haze's
   model: sigma_s = s x density(x), sigma_a = a x density(x), emission = e x flame(x) plus
   blackbody(temperature(x)), using the volume's own grid as density/flame where the
   material scales it by constants (so what Haze renders is that grid, unchanged);
4. crop every grid to the voxels that matter plus one empty voxel on each side.

Placement: voxel (i, j, k) is centred at index coordinates (i, j, k) of the grid, so a box of
voxels lo..hi spans index coordinates lo - 0.5 .. hi + 0.5; Haze's grid box p0..p1 is that
range, and to_world = object matrix x grid index-to-object matrix. The empty border voxels
make the density fall to 0 over the last half voxel, as in Cycles (which reads the grid's
background, 0, beyond its voxels), and the interface box may coincide with the grid box.

Cycles details followed here: a volume object's densities are multiplied by
object_volume_density, 1 / |M (1, 1, 1) / sqrt 3| for render space "Object" (the default),
1 for "World" and for smoke domains; a volume object without material renders with Cycles'
default volume shader (Principled Volume, Color 0.5, Density 1, reading "density").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from renderer.scene import Material, Medium, Mesh

from .grid_sampler import GridInfo, GridSampler, VolumeInfo, index_box
from .materials import MAX_ANISOTROPY, MaterialLibrary
from .messages import Messages, material_subject, object_subject
from .volume_shader import Blackbody, VoxelCoefficients, evaluate_volume_material, grids_a_material_reads

INTERFACE_MATERIAL = "Haze Volume Boundary"
CROP_GRIDS = True  # tests switch it off to measure what cropping saves
MAX_VOXELS = 1 << 28  # dense grids beyond this (1 GB per float32 grid) are refused
EXACT = 1e-5  # relative residual under which a factorisation counts as exact (float32 data)
BOX_TRIANGLES = np.array([
    (0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6),  # z = p0, z = p1
    (0, 1, 4), (1, 5, 4), (2, 6, 3), (3, 6, 7),  # y = p0, y = p1
    (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5),  # x = p0, x = p1
], np.int32)


# ---------------------------------------------------------------------------- pure helpers


def box_mesh(name: str, medium: str, p0, p1, to_world: np.ndarray) -> Mesh:
    """A closed box (12 triangles, outward normals) over the local box p0..p1, in world space."""
    corners = np.array([[(p1 if x else p0)[0], (p1 if y else p0)[1], (p1 if z else p0)[2], 1.0]
                        for z in (0, 1) for y in (0, 1) for x in (0, 1)])
    world = (corners @ to_world.T)[:, :3].astype(np.float32)
    mirrored = np.linalg.det(to_world[:3, :3]) < 0.0
    triangles = BOX_TRIANGLES[:, ::-1].copy() if mirrored else BOX_TRIANGLES.copy()
    return Mesh(name, world, triangles, [INTERFACE_MATERIAL], medium=medium)


def object_density_factor(matrix: np.ndarray, space: str) -> float:
    """Cycles' object_volume_density: densities of object-space volumes follow the scale."""
    if space != "OBJECT":
        return 1.0
    length = float(np.linalg.norm(matrix[:3, :3] @ (np.ones(3) / math.sqrt(3.0))))
    return 1.0 / length if length > 0.0 else 0.0


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


def factor_rank_one(values: np.ndarray, candidates: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray, bool]:
    """Write (n, c) per-voxel values as field (n,) x constants (c,).

    A candidate grid the values are a constant multiple of is preferred (then Haze renders the
    volume's own grid); otherwise the field is the values' mean over c. Returns (field,
    constants, exact) where exact says the product reproduces the values to float precision."""
    scale = float(np.max(np.abs(values))) if values.size else 0.0
    for grid in candidates:
        grid = np.asarray(grid, np.float64)
        norm = float(np.dot(grid, grid))
        if norm == 0.0:
            continue
        constants = grid @ values / norm
        if np.max(np.abs(values - np.outer(grid, constants))) <= EXACT * scale:
            return grid, constants, True
    field = values.mean(axis=1)
    norm = float(np.dot(field, field))
    constants = field @ values / norm if norm > 0.0 else np.zeros(values.shape[1])
    exact = np.max(np.abs(values - np.outer(field, constants))) <= EXACT * scale
    return field, constants, bool(exact)


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
    padded = np.pad(values, pad) if any(p != (0, 0) for p in pad) else values
    start = [int(lo[a]) - 1 + pad[a][0] for a in range(3)]
    stop = [int(hi[a]) + 2 + pad[a][0] for a in range(3)]
    return np.ascontiguousarray(padded[start[0]:stop[0], start[1]:stop[1], start[2]:stop[2]], np.float32)


def megabytes(values: np.ndarray | None) -> float:
    return 0.0 if values is None else values.nbytes / 2**20


def shape_text(shape) -> str:
    return "x".join(str(int(s)) for s in reversed(shape))  # x by y by z


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
    blackbody_scale: float  # Cycles' blackbody weight (mix weight x tint), Haze renders 1
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


def mean_anisotropy(terms: list[tuple[np.ndarray, np.ndarray]], subject: str, messages: Messages) -> float:
    """One Henyey-Greenstein g for the volume: the closures' g weighted by their scattering."""
    if not terms:
        return 0.0
    pairs = [np.broadcast_arrays(g[:, 0], w.mean(axis=1)) for g, w in terms]
    total = sum(float(w.sum()) for _, w in pairs)
    if total <= 0.0:
        return float(np.clip(pairs[0][0].mean(), -MAX_ANISOTROPY, MAX_ANISOTROPY))
    g = sum(float((v * w).sum()) for v, w in pairs) / total
    spread = max(float(np.max(np.abs(v - g)[w > 0], initial=0.0)) for v, w in pairs)
    if spread > 1e-6:
        messages.warn(subject, "the volume's Anisotropy varies; Haze uses its scattering-weighted mean "
                               f"{g:.3g}")
    return float(np.clip(g, -MAX_ANISOTROPY, MAX_ANISOTROPY))


def blackbody_terms(terms: list[Blackbody], count: int, subject: str, messages: Messages):
    """(temperature (n,) or None, intensity, scale) of the material's blackbody emission."""
    active = [t for t in terms if np.any((t.intensity > 0.0) & (t.weight != 0.0))]
    if not active:
        return None, 0.0, 1.0
    if len(active) > 1:
        messages.warn(subject, "several Principled Volume blackbody emissions; Haze renders the first")
    term = active[0]
    intensity = float(np.max(term.intensity))
    if np.ptp(term.intensity) > 1e-6:
        messages.warn(subject, f"Blackbody Intensity varies between voxels; Haze uses its maximum "
                               f"{intensity:g}")
    weights = np.unique(np.round(np.asarray(term.weight * term.tint, np.float64), 6))
    scale = float(weights.max()) if weights.size else 1.0
    if weights.size != 1 or abs(scale - 1.0) > 1e-6:
        messages.warn(subject, "Haze's blackbody emission has no tint or weight: Blackbody Tint and Mix "
                               "Shader factors on the blackbody are rendered as 1")
    temperature = np.broadcast_to(term.temperature[:, 0], (count,)).astype(np.float32)
    return temperature, intensity, scale


class FieldBuilder:
    """Turns one volume's per-voxel coefficients into a GridMedium on its voxel lattice."""

    def __init__(self, subject: str, messages: Messages, shape: tuple[int, int, int],
                 raw: dict[str, np.ndarray]) -> None:
        self.subject, self.messages, self.shape = subject, messages, shape
        self.count = int(np.prod(shape))
        # Scalar grids the material may scale: preferred as Haze's density and flame.
        self.candidates = [v.reshape(-1) for v in raw.values() if v.ndim == 3]

    def per_voxel(self, values: np.ndarray) -> np.ndarray:
        return np.broadcast_to(np.maximum(values, 0.0), (self.count, values.shape[1]))

    def extinction(self, coefficients: VoxelCoefficients):
        both = np.concatenate([self.per_voxel(coefficients.sigma_s), self.per_voxel(coefficients.sigma_a)], 1)
        if not np.any(both):
            return np.zeros(self.shape, np.float32), np.zeros(3), np.zeros(3)
        density, constants, exact = factor_rank_one(both, self.candidates)
        if not exact:
            self.messages.warn(self.subject, "the volume's colour varies between voxels (e.g. a colour grid "
                                             "or different Math on scattering and absorption); Haze "
                                             "renders one colour per volume, their average")
        return density.reshape(self.shape).astype(np.float32), np.maximum(constants[:3], 0.0), \
            np.maximum(constants[3:], 0.0)

    def emission(self, coefficients: VoxelCoefficients):
        values = np.maximum(coefficients.emission, 0.0)
        if not np.any(values):
            return None, np.zeros(3)
        if values.shape[0] == 1:
            return None, values[0]  # constant: Haze emits it throughout the grid box
        flame, constants, exact = factor_rank_one(values, self.candidates)
        if not exact:
            self.messages.warn(self.subject, "the emission colour varies between voxels; Haze renders one "
                                             "colour per volume, the average")
        return flame.reshape(self.shape).astype(np.float32), np.maximum(constants, 0.0)

    def build(self, coefficients: VoxelCoefficients, start: np.ndarray, index_to_object: np.ndarray,
              read_shape: tuple[int, int, int]) -> GridMedium | None:
        density, sigma_s, sigma_a = self.extinction(coefficients)
        flame, emission = self.emission(coefficients)
        temperature, intensity, bb_scale = blackbody_terms(coefficients.blackbody, self.count, self.subject,
                                                           self.messages)
        if temperature is not None:
            temperature = temperature.reshape(self.shape)
        g = mean_anisotropy(coefficients.anisotropy, self.subject, self.messages)
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
        lo, hi = box if CROP_GRIDS else (np.ones(3, int), np.array(self.shape) - 2)
        grids = [crop(a, lo, hi) if a is not None else None for a in (density, flame, temperature)]
        medium = GridMedium(grids[0], grids[1], grids[2], sigma_a, sigma_s, emission, g, intensity, bb_scale,
                            start + lo[::-1] - 1, index_to_object)
        medium.stats = self.stats(read_shape, medium)
        return medium

    @staticmethod
    def stats(read_shape, medium: GridMedium) -> list[str]:
        before = int(np.prod(read_shape)) * 4 / 2**20
        lines = []
        for name in ("density", "flame", "temperature"):
            values = getattr(medium, name)
            if values is not None:
                lines.append(f"{name} grid {shape_text(values.shape)} voxels, {megabytes(values):.3f} MB "
                             f"(read {shape_text(read_shape)}, {before:.3f} MB before cropping)")
        return lines


# ---------------------------------------------------------------------------- Blender side


@dataclass
class VolumeSource:
    """Where a rendered volume's grids come from and how its material reads them."""

    key: tuple  # instances with equal keys share one GridMedium
    subject: str  # the Blender object, for messages
    target: object | None  # original volume object to sample, or None (read from `cache_file`)
    cache_file: str | None  # smoke domains: the frame's OpenVDB cache file
    material: object | None
    clipping: float
    grid_names: dict[str, str] = field(default_factory=dict)  # material attribute -> grid in the volume
    domain_box: tuple[np.ndarray, np.ndarray] | None = None  # smoke: object-space box of the grid
    domain_res: np.ndarray | None = None  # smoke: cells along x, y, z filling domain_box
    flame_range: tuple[float, float] = (1.5, 3.0)  # smoke: flame ignition and maximum temperature


@dataclass
class VolumeInstance:
    source: VolumeSource
    name: str
    matrix_world: np.ndarray
    density_factor: float


def is_smoke_domain(obj) -> bool:
    """A gas fluid domain (smoke or fire): rendered from its grids, not as a mesh."""
    for modifier in getattr(obj, "modifiers", ()):
        if modifier.type == "FLUID" and modifier.fluid_type == "DOMAIN" and modifier.show_render:
            return modifier.domain_settings.domain_type == "GAS"
    return False


def first_material(obj):
    for slot in obj.material_slots:
        if slot.material is not None:
            return slot.material
    materials = getattr(obj.data, "materials", None) or []
    return next((m for m in materials if m is not None), None)


class VolumeExporter:
    """Collects the rendered volumes of an export, then reads and converts them all at once."""

    def __init__(self, library: MaterialLibrary, messages: Messages, frame: int = 1,
                 subframe: float = 0.0) -> None:
        self.library = library
        self.messages = messages
        self.frame, self.subframe = frame, subframe
        self.instances: list[VolumeInstance] = []
        self.stats: list[str] = []
        self._names: set[str] = set()

    # ------------------------------------------------------------------ collecting
    def add(self, instance, group_name: str) -> None:
        """Record one depsgraph instance of a volume object or smoke domain (during iteration:
        depsgraph instances are only valid then)."""
        obj = instance.object
        matrix = np.array(instance.matrix_world, np.float64)
        if obj.type == "VOLUME":
            source = self._volume_source(obj)
            factor = object_density_factor(matrix, obj.data.render.space)
        else:
            source = self._smoke_source(obj)
            factor = 1.0
        if source is not None:
            self.instances.append(VolumeInstance(source, self._unique(group_name), matrix, factor))

    def _unique(self, name: str) -> str:
        candidate, index = name, 2
        while candidate in self._names:
            candidate, index = f"{name} [{index}]", index + 1
        self._names.add(candidate)
        return candidate

    def _volume_source(self, obj) -> VolumeSource | None:
        original = obj.original
        subject = object_subject(original.name)
        material = first_material(obj)
        if material is not None and getattr(material, "cycles", None) is not None:
            if getattr(material.cycles, "volume_interpolation", "LINEAR") != "LINEAR":
                self.messages.warn(material_subject(material.name_full), "cubic volume interpolation is "
                                   "rendered as linear")
        data_key = original.name_full if len(original.modifiers) else "data:" + original.data.name_full
        key = ("volume", data_key, material.name_full if material is not None else "")
        return VolumeSource(key, subject, original, None, material, float(obj.data.render.clipping))

    def _smoke_source(self, obj) -> VolumeSource | None:
        from .smoke import smoke_cache_source

        return smoke_cache_source(obj, self.frame, self.messages, first_material(obj))

    # ------------------------------------------------------------------ converting
    def export(self) -> tuple[list[Mesh], list[Medium]]:
        """Read every recorded volume: their boundary meshes and media (the boundaries'
        material goes into the material library)."""
        if not self.instances:
            return [], []
        converted: dict[tuple, GridMedium | None] = {}
        with GridSampler(self.frame, self.subframe) as sampler:
            for item in self.instances:
                if item.source.key not in converted:
                    converted[item.source.key] = self._convert(sampler, item.source)
        meshes, media = [], []
        for item in self.instances:
            grid = converted[item.source.key]
            if grid is None:
                continue
            medium = grid.medium(f"{item.name} (volume)", item.matrix_world, item.density_factor)
            if grid.temperature is not None and abs(item.density_factor * grid.blackbody_scale - 1.0) > 1e-6:
                self.messages.warn(item.source.subject, "blackbody emission is rendered without the object's "
                                   "volume density factor (object scale with render space 'Object')")
            media.append(medium)
            meshes.append(box_mesh(f"{item.name} (volume boundary)", medium.name, medium.p0, medium.p1,
                                   medium.to_world))
        for key, grid in converted.items():
            if grid is not None:
                self.stats.extend(f"{self._subject_of(key)}: {line}" for line in grid.stats)
        for line in self.stats:
            print(f"Haze: {line}")  # the console, next to Blender's own render log
        if media:
            self.library.add(Material(INTERFACE_MATERIAL))
        return meshes, media

    def _subject_of(self, key: tuple) -> str:
        return next(i.source.subject for i in self.instances if i.source.key == key)

    def _convert(self, sampler: GridSampler, source: VolumeSource) -> GridMedium | None:
        try:
            return self._read_and_build(sampler, source)
        except (RuntimeError, ValueError, MemoryError) as error:
            self.messages.warn(source.subject, f"its grids could not be read ({error}); it is not rendered")
            return None

    def _read_and_build(self, sampler: GridSampler, source: VolumeSource) -> GridMedium | None:
        target = source.target if source.target is not None else sampler.file_volume(source.cache_file)
        info = sampler.inspect(target)
        if not info.grids:
            self.messages.warn(source.subject, "has no grids (an empty volume or a file that did not load); "
                                               "it is not rendered")
            return None
        wanted = self._wanted_grids(source, info)
        if not wanted:
            return None
        primary = info.grids[wanted.get("density") or next(iter(wanted.values()))]
        start, shape = self._read_box(source, primary, info)
        raw = self._read_grids(sampler, target, source, info, wanted, primary, start, shape)
        if raw is None:
            return None
        read_shape = (int(shape[2]), int(shape[1]), int(shape[0]))
        if self._empty_without_grids(source, raw):
            raw, start = crop_to_voxels(raw, np.asarray(start))
        return self._build(source, raw, start, read_shape, primary)

    def _empty_without_grids(self, source: VolumeSource, raw: dict[str, np.ndarray]) -> bool:
        """Whether the material gives nothing where every grid it reads is 0: then the grids
        can be cropped before the (per-voxel, float64) material evaluation."""
        zero = {name: np.zeros((1,) + v.shape[3:], np.float32) for name, v in raw.items()}
        coefficients = self._coefficients(source, zero)
        if coefficients is None:
            return True
        c = coefficients
        blackbody = any(np.any((t.temperature > 0.0) & (t.intensity > 0.0)) for t in c.blackbody)
        return not (np.any(c.sigma_s) or np.any(c.sigma_a) or np.any(c.emission) or blackbody)

    def _wanted_grids(self, source: VolumeSource, info: VolumeInfo) -> dict[str, str]:
        """Material attribute name -> grid name, for the grids the material reads that exist."""
        names = grids_a_material_reads(source.material) if source.material is not None else {"density"}
        mapping = source.grid_names or {name: name for name in info.grids}
        wanted = {name: mapping[name] for name in sorted(names) if mapping.get(name) in info.grids}
        unreadable = [n for n, g in wanted.items() if info.grids[g].node_type is None]
        for name in unreadable:
            grid = info.grids[wanted.pop(name)]
            self.messages.warn(source.subject, f"grid '{grid.name}' of type {grid.data_type} cannot be read "
                                               "by Haze; it reads as 0")
        if not wanted:
            self.messages.warn(source.subject, "its material reads none of its grids "
                               f"({', '.join(sorted(info.grids))}); it is not rendered")
        return wanted

    def _read_box(self, source: VolumeSource, primary: GridInfo, info: VolumeInfo):
        start, shape = index_box(primary, info.bounds)
        if int(np.prod(shape)) > MAX_VOXELS:
            raise ValueError(f"grid '{primary.name}' spans {shape_text(shape[::-1])} voxels, more than "
                             f"Haze's dense grids hold ({MAX_VOXELS} voxels); lower its resolution")
        return start, shape

    def _read_grids(self, sampler, target, source: VolumeSource, info: VolumeInfo, wanted: dict[str, str],
                    primary: GridInfo, start, shape) -> dict[str, np.ndarray] | None:
        raw: dict[str, np.ndarray] = {}
        for attribute, grid_name in wanted.items():
            grid = info.grids[grid_name]
            if not np.allclose(grid.index_to_object, primary.index_to_object, rtol=1e-6, atol=1e-9):
                self.messages.warn(source.subject, f"grid '{grid_name}' has another voxel size or placement "
                                   f"than grid '{primary.name}'; Haze needs them aligned and leaves it out")
                continue
            values = sampler.read(target, grid, start, shape)
            raw[attribute] = clean_grid(values, source.clipping, source.subject, grid_name, self.messages)
        if source.cache_file is not None:
            from .smoke import smoke_attributes

            raw = smoke_attributes(raw, source)
        if not any(np.any(v) for v in raw.values()):
            names = ", ".join(f"'{wanted[a]}'" for a in raw)
            self.messages.warn(source.subject, f"grids {names} have no voxels above the clipping value "
                               f"{source.clipping:g}; the volume is not rendered")
            return None
        return raw

    def _build(self, source: VolumeSource, raw: dict[str, np.ndarray], start, read_shape,
               primary: GridInfo) -> GridMedium | None:
        grid_shape = next(iter(raw.values())).shape[:3]
        flat = {name: v.reshape(-1) if v.ndim == 3 else v.reshape(-1, 3) for name, v in raw.items()}
        coefficients = self._coefficients(source, flat)
        if coefficients is None:
            return None
        builder = FieldBuilder(source.subject, self.messages, grid_shape, raw)
        index_to_object = primary.index_to_object
        if source.domain_box is not None:
            index_to_object = smoke_index_to_object(source.domain_box, source.domain_res)
        medium = builder.build(coefficients, np.asarray(start), index_to_object, read_shape)
        if medium is None:
            self.messages.warn(source.subject, "its material gives no extinction or emission anywhere; it is "
                                               "not rendered")
        return medium

    def _coefficients(self, source: VolumeSource, flat: dict[str, np.ndarray]) -> VoxelCoefficients | None:
        if source.material is None:
            return default_volume_coefficients(flat)
        owner = material_subject(source.material.name_full)
        coefficients = evaluate_volume_material(source.material, owner, self.messages, flat)
        if coefficients is None:
            self.messages.warn(source.subject, f"material '{source.material.name_full}' has no Volume "
                                               "shader; the volume is not rendered (as in Cycles)")
        return coefficients


def crop_to_voxels(raw: dict[str, np.ndarray], start: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The grids cut to their non-zero voxels plus one empty voxel around them, and the (x, y, z)
    index of the new voxel [0, 0, 0]."""
    masks = [(v != 0.0) if v.ndim == 3 else np.any(v != 0.0, axis=-1) for v in raw.values()]
    box = crop_box(masks)
    if box is None or not CROP_GRIDS:
        return raw, start
    lo, hi = box
    cropped = {}
    for name, values in raw.items():
        if values.ndim == 3:
            cropped[name] = crop(values, lo, hi)
        else:
            cropped[name] = np.stack([crop(values[..., c], lo, hi) for c in range(values.shape[-1])], axis=-1)
    return cropped, start + lo[::-1] - 1


def default_volume_coefficients(grids: dict[str, np.ndarray]) -> VoxelCoefficients:
    """Cycles' default volume shader (a Principled Volume with its default inputs: Color 0.5,
    Density 1 times the "density" grid), used for volume objects without a material."""
    density = grids.get("density")
    values = density[:, None].astype(np.float64) if density is not None else np.ones((1, 1))
    half = np.full((1, 3), 0.5)
    scattering = half * values
    return VoxelCoefficients(scattering, half * values, np.zeros((1, 3)), [(np.zeros((1, 1)), scattering)])


def smoke_index_to_object(box: tuple[np.ndarray, np.ndarray], resolution) -> np.ndarray:
    """Index-to-object matrix of a smoke domain's grid: `resolution` (x, y, z) cells fill the
    domain's box, cell i centred at (i + 0.5) / res of it."""
    low, high = (np.asarray(v, np.float64) for v in box)
    size = (high - low) / np.asarray(resolution, np.float64)
    matrix = np.eye(4)
    matrix[:3, :3] = np.diag(size)
    matrix[:3, 3] = low + 0.5 * size
    return matrix

