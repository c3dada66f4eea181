"""One volume's grids read and turned into a GridMedium: sparsely from its .vdb file, or densely.

The choice (GridReader.read): a Volume object that loads a .vdb file (no modifiers), or a
smoke domain (its frame's cache file), whose index box holds SPARSE_MIN_VOXELS or more is
read sparsely, when its grids are float grids with background 0 and its material is
constant coefficients times one grid (density), another (flame) for the emission, and a
blackbody temperature (vdb_reader reads the file into 8^3 bricks of the occupied voxels,
sparse_volume fits the material on them). Anything else (volumes made by modifiers or
geometry nodes, smaller boxes, other materials) goes through the geometry-node sampler into
dense grids: cleaned (clean_grid), evaluated per voxel and factored (grid_fields), cropped
to the non-zero voxels.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .grid_fields import FieldBuilder, GridMedium, clean_grid, crop_to_voxels, evaluate_fields, shape_text
from .grid_sampler import GridInfo, GridSampler, VolumeInfo, index_box
from .messages import Messages, material_subject
from .sampled_bricks import sample_bricks
from .smoke import SmokeCache
from .sparse_volume import build_sparse
from .vdb_reader import VdbFile
from .volume_shader import VoxelCoefficients, evaluate_volume_material, grids_a_material_reads

CROP_GRIDS = True  # tests switch it off to measure what cropping saves
MAX_VOXELS = 1 << 28  # dense grids beyond this (1 GB per float32 grid) are refused
# Volume objects loading a .vdb file whose index box holds at least this many voxels are
# read sparsely (vdb_reader: 8^3 bricks of the occupied voxels only); smaller ones through
# the sampler into dense grids, which look up a little faster. Tests set it to 0.
SPARSE_MIN_VOXELS = 1 << 18


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


class GridReader:
    """Reads volumes' grids into GridMedia, reporting problems to `messages`."""

    def __init__(self, messages: Messages) -> None:
        self.messages = messages

    def read(self, sampler: GridSampler, source: VolumeSource) -> GridMedium | None:
        if source.filepath or source.smoke is not None:
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
        is not constant coefficients times one grid (and another for the emission). A smoke
        domain's cache file is read so too, its grids converted as the dense path does."""
        vdb = VdbFile(source.smoke.path if source.smoke is not None else source.filepath)
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
        zero = {name: np.zeros(1, np.float32) for name in wanted}
        if not self._empty_without_grids(source, zero):
            return None  # the material gives something where every grid is 0: dense path
        convert = source.smoke.attributes if source.smoke is not None else None
        grids = vdb.read_bricks(wanted, start, shape, source.clipping, source.subject, self.messages, convert)
        if grids is None or not any(len(g.bricks) and g.max() > 0.0 for g in grids.values()):
            return None
        index_to_object = primary.index_to_object if source.smoke is None else source.smoke.index_to_object()
        built = build_sparse(grids, lambda values: self._coefficients(source, values), np.asarray(start),
                             index_to_object)
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


def default_volume_coefficients(grids: dict[str, np.ndarray]) -> VoxelCoefficients:
    """Cycles' default volume shader (a Principled Volume with its default inputs: Color 0.5,
    Density 1 times the "density" grid), used for volume objects without a material."""
    density = grids.get("density")
    values = density[:, None].astype(np.float64) if density is not None else np.ones((1, 1))
    half = np.full((1, 3), 0.5)
    scattering = half * values
    return VoxelCoefficients(scattering, half * values, np.zeros((1, 3)), [(np.zeros((1, 1)), scattering)])
