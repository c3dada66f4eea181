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
background, 0, beyond its voxels); the interface box stops at the empty border voxels' centres
(boundary_box), half a voxel inside the grid box.

Cycles details followed here: a volume object's densities are multiplied by
object_volume_density, 1 / |M (1, 1, 1) / sqrt 3| for render space "Object" (the default),
1 for "World" and for smoke domains; a volume object without material renders with Cycles'
default volume shader (Principled Volume, Color 0.5, Density 1, reading "density").
"""

from __future__ import annotations

import math
import traceback
from dataclasses import dataclass, field

import numpy as np

from renderer.media.bricks import SparseGrid
from renderer.scene import Material, Medium, Mesh

from .grid_fields import FieldBuilder, GridMedium, clean_grid, crop_to_voxels, evaluate_fields, shape_text
from .grid_sampler import GridInfo, GridSampler, VolumeInfo, index_box, volume_info
from .materials import MaterialLibrary
from .messages import Messages, material_subject, object_subject
from .sampled_bricks import sample_bricks
from .smoke import CACHE_GRIDS, SmokeCache, smoke_cache
from .sparse_volume import build_sparse
from .vdb_reader import VdbFile
from .volume_shader import VoxelCoefficients, evaluate_volume_material, grids_a_material_reads

INTERFACE_MATERIAL = "Haze Volume Boundary"
CROP_GRIDS = True  # tests switch it off to measure what cropping saves
MAX_VOXELS = 1 << 28  # dense grids beyond this (1 GB per float32 grid) are refused
# Volume objects loading a .vdb file whose index box holds at least this many voxels are
# read sparsely (vdb_reader: 8^3 bricks of the occupied voxels only); smaller ones through
# the sampler into dense grids, which look up a little faster. Tests set it to 0.
SPARSE_MIN_VOXELS = 1 << 18
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


def boundary_box(grid: GridMedium) -> tuple[np.ndarray, np.ndarray]:
    """Index-space corners of the invisible boundary box around a grid medium.

    The grid box spans start - 0.5 .. start + shape - 0.5 (voxel centres at integers). When
    every grid's outer voxel layer is empty (cropping leaves one empty voxel on each side, an
    uncropped read its background border) and no emission fills the box without a flame grid,
    the medium is exactly 0 beyond those voxels' centres (lookups clamp to them), so the
    boundary stops there, half a voxel inside the grid box: the same medium, but a grid box
    resting on a surface (a fire on a floor, cropped to its voxels) does not put the boundary
    in the surface's plane, where the two tie and a path that crosses the boundary first
    leaves the medium on the far side of the surface and is lost. Cycles has no such face.
    """
    start = np.asarray(grid.start, np.float64)
    shape = np.array(grid.density.shape[::-1])
    full = (start - 0.5, start + shape - 0.5)
    if isinstance(grid.density, SparseGrid):  # sparse_volume: a density grid alone
        empty = grid.density.shell_max() == 0.0 and not np.any(np.asarray(grid.emission) != 0.0)
        return (start, start + shape - 1.0) if empty and np.all(shape >= 3) else full
    if np.any(shape < 3) or (grid.flame is None and np.any(np.asarray(grid.emission) != 0.0)):
        return full
    from renderer.media.blackbody import blackbody_emission_voxels

    shell = np.ones(grid.density.shape[:3], bool)
    shell[1:-1, 1:-1, 1:-1] = False
    layers = [grid.density[shell]] + ([] if grid.flame is None else [grid.flame[shell]])
    if grid.temperature is not None:  # its emission, as the renderer compiles it (0 K may emit)
        layers.append(blackbody_emission_voxels(grid.temperature[shell], grid.blackbody_intensity))
    if any(np.any(layer != 0.0) for layer in layers):
        return full
    return start, start + shape - 1.0


def object_density_factor(matrix: np.ndarray, space: str) -> float:
    """Cycles' object_volume_density: densities of object-space volumes follow the scale."""
    if space != "OBJECT":
        return 1.0
    length = float(np.linalg.norm(matrix[:3, :3] @ (np.ones(3) / math.sqrt(3.0))))
    return 1.0 / length if length > 0.0 else 0.0


# ---------------------------------------------------------------------------- Blender side


@dataclass(frozen=True)
class VolumeSource:
    """Where a rendered volume's grids come from and how its material reads them: a volume
    object to sample (`target`) or a smoke domain's cache file (`smoke`)."""

    key: tuple  # instances with equal keys share one GridMedium
    subject: str  # the Blender object, for messages
    material: object | None
    clipping: float
    target: object | None = None  # the original volume object
    filepath: str = ""  # the .vdb file (this frame's, for a sequence) a modifier-free volume loads
    smoke: SmokeCache | None = None
    grid_names: dict[str, str] = field(default_factory=dict)  # material attribute -> grid in the volume
    # Grids of a volume that a non-volume object's geometry nodes output (Volume Cube, Mesh
    # to Volume...), read from the depsgraph instance: the sampler evaluates the original
    # object, whose own type is not VOLUME, and reads these grids from its geometry.
    info: VolumeInfo | None = field(default=None, compare=False)


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
        filepath = "" if len(original.modifiers) else volume_file(obj.data)
        key = ("volume", data_key, material.name_full if material is not None else "", filepath)
        info = volume_info(obj) if original.type != "VOLUME" else None
        return VolumeSource(key, subject, material, float(obj.data.render.clipping), target=original,
                            filepath=filepath, info=info)

    def _smoke_source(self, obj) -> VolumeSource | None:
        cache = smoke_cache(obj, self.frame, self.messages)
        if cache is None:
            return None
        original, material = obj.original, first_material(obj)
        key = ("smoke", original.name_full, cache.path, material.name_full if material else "")
        return VolumeSource(key, object_subject(original.name), material, cache.clipping, smoke=cache,
                            grid_names=dict(CACHE_GRIDS))

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
            if grid.temperature is not None and abs(item.density_factor - 1.0) > 1e-6:
                self.messages.warn(item.source.subject, "blackbody emission is rendered without the object's "
                                   "volume density factor (object scale with render space 'Object')")
            media.append(medium)
            low, high = boundary_box(grid)
            meshes.append(box_mesh(f"{item.name} (volume boundary)", medium.name, low, high, medium.to_world))
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
        except Exception as error:  # one unreadable volume must not stop the render of the others
            traceback.print_exc()
            self.messages.warn(source.subject, f"reading its grids failed ({type(error).__name__}: {error}); "
                                               "it is not rendered")
        return None

    def _read_and_build(self, sampler: GridSampler, source: VolumeSource) -> GridMedium | None:
        if source.filepath:
            try:
                medium = self._read_sparse(source)
            except (OSError, RuntimeError, KeyError, ValueError):  # the sampler reads it, or says why not
                medium = None
            if medium is not None:
                return medium
        target = source.target if source.smoke is None else sampler.file_volume(source.smoke.path)
        info = source.info or sampler.inspect(target)
        if not info.grids:
            self.messages.warn(source.subject, "has no grids (an empty volume or a file that did not load); "
                                               "it is not rendered")
            return None
        wanted = self._wanted_grids(source, info)
        if not wanted:
            return None
        primary = info.grids[wanted.get("density") or next(iter(wanted.values()))]
        start, shape = index_box(primary, info.bounds)
        if self._samples_sparsely(source, info, wanted, primary, shape):
            return self._sample_sparse(sampler, target, source, info, wanted, primary, start, shape)
        self._check_dense_box(primary, shape)
        raw = self._read_grids(sampler, target, source, info, wanted, primary, start, shape)
        if raw is None:
            return None
        return self._crop_and_build(source, raw, start, shape, primary)

    def _crop_and_build(self, source: VolumeSource, raw: dict[str, np.ndarray], start, shape,
                        primary: GridInfo) -> GridMedium | None:
        read_shape = (int(shape[2]), int(shape[1]), int(shape[0]))
        if CROP_GRIDS and self._empty_without_grids(source, raw):
            raw, start = crop_to_voxels(raw, np.asarray(start))
        return self._build(source, raw, start, read_shape, primary)

    def _read_sparse(self, source: VolumeSource) -> GridMedium | None:
        """The volume's file read into bricks (vdb_reader, sparse_volume), or None when the
        sampler path should read it: a small box, grids that are not float, a material that
        is not constant coefficients times one grid."""
        vdb = VdbFile(source.filepath)
        info = vdb.info()
        if not info.grids:
            return None
        wanted = self._wanted_grids(source, info)
        if not wanted or not all(vdb.sparse_readable(name) for name in wanted.values()):
            return None
        primary = info.grids[wanted.get("density") or next(iter(wanted.values()))]
        if any(not np.allclose(info.grids[g].index_to_object, primary.index_to_object, rtol=1e-6, atol=1e-9)
               for g in wanted.values()):
            return None  # the sampler path leaves misaligned grids out, with a warning
        start, shape = index_box(primary, info.bounds)
        if int(np.prod(shape)) < SPARSE_MIN_VOXELS:
            return None
        grids = vdb.read_bricks(wanted, start, shape, source.clipping, source.subject, self.messages)
        if grids is None or not any(len(g.bricks) and g.max() > 0.0 for g in grids.values()):
            return None
        zero = {name: np.zeros(1, np.float32) for name in grids}
        if not self._empty_without_grids(source, zero):
            return None  # the material gives something where every grid is 0: dense path
        built = build_sparse(grids, lambda values: self._coefficients(source, values), np.asarray(start),
                             primary.index_to_object)
        if built is None:
            return None
        medium, fields = built
        FieldBuilder(source.subject, self.messages, (1, 1, 1), {}).warn_blackbody(fields)
        return medium

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

    @staticmethod
    def _check_dense_box(primary: GridInfo, shape) -> None:
        if int(np.prod(shape)) > MAX_VOXELS:
            raise ValueError(f"grid '{primary.name}' spans {shape_text(shape[::-1])} voxels, more than "
                             f"Haze's dense grids hold ({MAX_VOXELS} voxels); lower its resolution")

    def _samples_sparsely(self, source: VolumeSource, info: VolumeInfo, wanted: dict[str, str],
                          primary: GridInfo, shape) -> bool:
        """Whether the sampler reads this volume into bricks (sampled_bricks): a large box of
        scalar, aligned grids of a volume that is not a smoke cache, under a material that
        gives nothing where its grids are 0 (so empty bricks are exact)."""
        if source.smoke is not None or int(np.prod(shape)) < SPARSE_MIN_VOXELS:
            return False
        grids = [info.grids[g] for g in wanted.values()]
        aligned = all(np.allclose(g.index_to_object, primary.index_to_object, rtol=1e-6, atol=1e-9)
                      for g in grids)
        if not aligned or any(g.node_type != "FLOAT" for g in grids):
            return False
        return self._empty_without_grids(source, {name: np.zeros(1, np.float32) for name in wanted})

    def _sample_sparse(self, sampler, target, source: VolumeSource, info: VolumeInfo, wanted: dict[str, str],
                       primary: GridInfo, start, shape) -> GridMedium | None:
        """The volume's grids sampled into bricks, rendered as they are when the material is
        constant coefficients times one grid (sparse_volume); otherwise made dense for the
        general path, if the box is small enough to hold densely."""
        grids = sample_bricks(sampler, target, {a: info.grids[g] for a, g in wanted.items()}, start, shape,
                              source.clipping, source.subject, self.messages)
        if not any(len(g.bricks) and g.max() > 0.0 for g in grids.values()):
            names = ", ".join(f"'{g}'" for g in wanted.values())
            self.messages.warn(source.subject, f"grids {names} have no voxels above the clipping value "
                               f"{source.clipping:g}; the volume is not rendered")
            return None
        built = build_sparse(grids, lambda values: self._coefficients(source, values), np.asarray(start),
                             primary.index_to_object)
        if built is not None:
            medium, fields = built
            FieldBuilder(source.subject, self.messages, (1, 1, 1), {}).warn_blackbody(fields)
            return medium
        self._check_dense_box(primary, shape)
        raw = {name: grids.pop(name).to_dense() for name in list(grids)}
        return self._crop_and_build(source, raw, start, shape, primary)

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
        if source.smoke is not None:
            raw = source.smoke.attributes(raw)
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
        count = int(np.prod(grid_shape))
        fields = evaluate_fields(lambda grids: self._coefficients(source, grids), flat, count)
        if fields is None:
            return None
        builder = FieldBuilder(source.subject, self.messages, grid_shape, raw, CROP_GRIDS)
        index_to_object = primary.index_to_object
        if source.smoke is not None:
            index_to_object = source.smoke.index_to_object()
        medium = builder.build(fields, np.asarray(start), index_to_object, read_shape)
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


def volume_file(volume) -> str:
    """The absolute path of the .vdb file a Volume datablock renders at the evaluated frame
    (a sequence's frame file), or "" for none or a packed file (read by the sampler)."""
    import bpy

    if not volume.filepath or volume.packed_file is not None:
        return ""
    path = volume.grids.frame_filepath if volume.is_sequence else volume.filepath
    return bpy.path.abspath(path, library=volume.library) if path else ""


def default_volume_coefficients(grids: dict[str, np.ndarray]) -> VoxelCoefficients:
    """Cycles' default volume shader (a Principled Volume with its default inputs: Color 0.5,
    Density 1 times the "density" grid), used for volume objects without a material."""
    density = grids.get("density")
    values = density[:, None].astype(np.float64) if density is not None else np.ones((1, 1))
    half = np.full((1, 3), 0.5)
    scattering = half * values
    return VoxelCoefficients(scattering, half * values, np.zeros((1, 3)), [(np.zeros((1, 1)), scattering)])
