"""Volume objects and smoke domains to Haze grid media inside interface boxes.

Each rendered volume becomes a grid Medium plus a closed box Mesh around the grid whose
material has no lobes (an invisible boundary that carries the medium). The steps, per volume
data and material (instances share the result, only the transform differs):

1. read the grids the material looks up over the volume's bounds plus one voxel of
   background on every side (volume_read: sparsely from a .vdb file into bricks, or densely
   through grid_sampler, a temporary geometry-node tree; steps 2-4 are the dense path's);
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
from dataclasses import dataclass

import numpy as np

from renderer.media.bricks import SparseGrid
from renderer.scene import Material, Medium, Mesh

from .grid_fields import GridMedium
from .grid_sampler import GridSampler, volume_info
from .materials import MaterialLibrary
from .messages import Messages, material_subject, object_subject
from .smoke import CACHE_GRIDS, smoke_cache
from .volume_read import GridReader, VolumeSource

INTERFACE_MATERIAL = "Haze Volume Boundary"
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
    if isinstance(grid.density, SparseGrid):  # sparse_volume: emission only with a flame grid
        return _sparse_boundary(grid, start, shape, full)
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


def _sparse_boundary(grid: GridMedium, start: np.ndarray, shape: np.ndarray, full):
    """boundary_box for sparse grids: the same test on their outer voxel layers."""
    from renderer.media.blackbody import blackbody_emission_voxels

    grids = [g for g in (grid.density, grid.flame, grid.temperature) if g is not None]
    layers = [g.shell_max() for g in grids]
    if grid.temperature is not None:  # 0 K emits too when the intensity is below 1
        cold = blackbody_emission_voxels(np.zeros(1, np.float32), grid.blackbody_intensity)
        layers.append(float(np.max(cold)))
    if np.any(shape < 3) or any(layer != 0.0 for layer in layers) or (
            grid.flame is None and np.any(np.asarray(grid.emission) != 0.0)):
        return full
    return start, start + shape - 1.0


def object_density_factor(matrix: np.ndarray, space: str) -> float:
    """Cycles' object_volume_density: densities of object-space volumes follow the scale."""
    if space != "OBJECT":
        return 1.0
    length = float(np.linalg.norm(matrix[:3, :3] @ (np.ones(3) / math.sqrt(3.0))))
    return 1.0 / length if length > 0.0 else 0.0


# ---------------------------------------------------------------------------- Blender side


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
        self.reader = GridReader(messages)
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
            return self.reader.read(sampler, source)
        except (RuntimeError, ValueError, MemoryError) as error:
            self.messages.warn(source.subject, f"its grids could not be read ({error}); it is not rendered")
        except Exception as error:  # one unreadable volume must not stop the render of the others
            traceback.print_exc()
            self.messages.warn(source.subject, f"reading its grids failed ({type(error).__name__}: {error}); "
                                               "it is not rendered")
        return None

def volume_file(volume) -> str:
    """The absolute path of the .vdb file a Volume datablock renders at the evaluated frame
    (a sequence's frame file), or "" for none or a packed file (read by the sampler)."""
    import bpy

    if not volume.filepath or volume.packed_file is not None:
        return ""
    path = volume.grids.frame_filepath if volume.is_sequence else volume.filepath
    return bpy.path.abspath(path, library=volume.library) if path else ""
