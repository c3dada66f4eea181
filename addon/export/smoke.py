"""Smoke and fire domains (gas fluid simulations) from their OpenVDB cache files.

A gas domain's grids for the current frame are in <cache directory>/data/fluid_data_NNNN.vdb
(Mantaflow's OpenVDB cache; NNNN = scene frame - the domain's cache frame offset, 4 digits).
The file is loaded into a temporary volume object so the same geometry-node sampler reads it
(never the simulation itself: nothing is baked). Cell (i, j, k) of the simulation is voxel
(i, j, k) of the file's index space; the base resolution fills the domain mesh's bounding box
(the texture space Cycles places smoke in), cell i centred at (i + 0.5) / res of it.

Attributes as Cycles reads them from a domain (rna_fluid: *_grid_get):
  density      the "density" grid
  flame        the "flame" grid
  heat         the simulation's heat (stored as "temperature") times 0.5
  temperature  flame mapped to kelvin-ish units: ignition + flame x (max temp - ignition)
               where flame > 0.01, else 0 (Principled Volume multiplies it by its Temperature)
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .messages import Messages, object_subject

CACHE_GRIDS = {"density": "density", "flame": "flame", "heat": "temperature", "temperature": "flame"}
FLAME_THRESHOLD = 0.01  # flame at or below this has temperature 0 (rna_FluidModifier_temperature_grid_get)


def fluid_domain(obj):
    for modifier in obj.modifiers:
        if modifier.type == "FLUID" and modifier.fluid_type == "DOMAIN":
            return modifier.domain_settings
    return None


def base_resolution(size: np.ndarray, resolution_max: int) -> np.ndarray:
    """Blender's base resolution of a domain of (object-scaled) size: the longest side gets
    `resolution_max` cells, the others as many cells of that size as fit (rounded, >= 4)."""
    longest = int(np.argmax(size))
    cell = size[longest] / resolution_max
    res = np.maximum(np.floor(size / cell + 0.5).astype(np.int64), 4)
    res[longest] = resolution_max
    return res


def mesh_bounds(mesh) -> tuple[np.ndarray, np.ndarray]:
    positions = np.empty(len(mesh.vertices) * 3, np.float64)
    mesh.vertices.foreach_get("co", positions)
    positions = positions.reshape(-1, 3)
    return positions.min(axis=0), positions.max(axis=0)


def cache_file(directory: str, frame: int) -> Path:
    return Path(directory) / "data" / f"fluid_data_{frame:04d}.vdb"


@dataclass(frozen=True)
class SmokeCache:
    """One frame of a gas domain's simulation: the cache file and where its grid sits."""

    path: str  # the frame's OpenVDB cache file
    box: tuple[np.ndarray, np.ndarray]  # object-space bounds of the domain mesh, which the grid fills
    resolution: np.ndarray  # base resolution: cells along x, y, z filling `box`
    flame_range: tuple[float, float]  # flame ignition and maximum temperature
    clipping: float  # voxels below this are empty

    def index_to_object(self) -> np.ndarray:
        """Index-to-object matrix of the grid: cell i centred at (i + 0.5) / res of the box."""
        low, high = (np.asarray(v, np.float64) for v in self.box)
        size = (high - low) / np.asarray(self.resolution, np.float64)
        matrix = np.eye(4)
        matrix[:3, :3] = np.diag(size)
        matrix[:3, 3] = low + 0.5 * size
        return matrix

    def attributes(self, raw: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Cache grids (keyed by the attribute they serve) converted to Cycles' attribute values."""
        converted = dict(raw)
        if "heat" in converted:
            converted["heat"] = converted["heat"] * np.float32(0.5)
        if "temperature" in converted:
            ignition, maximum = self.flame_range
            flame = converted["temperature"]
            kelvin = ignition + flame * (maximum - ignition)
            converted["temperature"] = np.where(flame > FLAME_THRESHOLD, kelvin, 0.0).astype(np.float32)
        return converted


def smoke_cache(obj, frame: int, messages: Messages) -> SmokeCache | None:
    """The cache of a gas domain at `frame`, or None (with a warning) if it holds nothing
    readable for that frame."""
    import bpy

    original = obj.original
    subject = object_subject(original.name)
    settings = fluid_domain(original)
    if settings is None or original.type != "MESH" or len(original.data.vertices) == 0:
        messages.warn(subject, "is a fluid domain without a mesh box; it is not rendered")
        return None
    if settings.cache_data_format != "OPENVDB":
        messages.warn(subject, f"its fluid cache format is {settings.cache_data_format}; Haze reads only "
                               "OpenVDB caches, the domain is not rendered")
        return None
    cache_frame = frame - int(settings.cache_frame_offset)  # the cache's frame shown at scene `frame`
    path = cache_file(bpy.path.abspath(settings.cache_directory), cache_frame)
    if not path.is_file():
        messages.warn(subject, f"no cached smoke for frame {cache_frame} ({path}); bake the simulation (or "
                               "set the frame) to render it")
        return None
    if settings.use_noise:
        messages.warn(subject, "noise (high-resolution) grids are not read; Haze renders the base resolution")
    if settings.use_adaptive_domain:
        messages.warn(subject, "adaptive domains are rendered as if the grid filled the whole domain box")
    low, high = mesh_bounds(original.data)
    size = np.abs((high - low) * np.array(original.scale, np.float64))
    if np.any(size <= 0.0):
        messages.warn(subject, "is a flat fluid domain; it is not rendered")
        return None
    resolution = base_resolution(size, int(settings.resolution_max))
    flame_range = (float(settings.flame_ignition), float(settings.flame_max_temp))
    return SmokeCache(str(path), (low, high), resolution, flame_range, float(settings.clipping))
