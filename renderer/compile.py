"""Flatten a Scene into the arrays the kernels read.

Every mesh is merged into one triangle soup (a global triangle index per hit); materials
become the lobe table of `renderer.bsdfs`; lights become a LightTable; media become the
MediaData of `renderer.media`. Nothing here runs per ray, and nothing here is written
after compiling: buffers the kernels write (path state, the majorant walk's scratch) belong
to the tracer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .bsdfs.table import build_material_table
from .camera import (
    LENS_BLADES,
    LENS_FOCUS,
    LENS_INV_RATIO,
    LENS_RADIUS,
    LENS_ROTATION,
    LENS_SIZE,
    PROJ_FISHEYE_FOV,
    PROJ_FISHEYE_LENS,
    PROJ_KIND,
    PROJ_LAT_MAX,
    PROJ_LAT_MIN,
    PROJ_LON_MAX,
    PROJ_LON_MIN,
    PROJ_SENSOR_H,
    PROJ_SENSOR_W,
    PROJ_SIZE,
)
from .lights.environment_map import build_environment
from .lights.table import LightTable, build_light_table
from .media.compile import build_media_data
from .media.layout import MediaData
from .scene import MAX_STACK as MAX_STACK  # re-exported: the integrator sizes its stacks with it
from .scene import PROJECTIONS, SIDES, Scene
from .shading.table import ShadingTables, build_shading_tables
from .validate.program import check_shading


class Geometry(NamedTuple):
    """Per-triangle tables, T triangles (float32 unless noted).

    v0, e1, e2 (T, 3): vertex 0 and the edges v1 - v0, v2 - v0.
    ng (T, 3): unit geometric normal, the front side (counter-clockwise winding).
    sn (T, 3, 3): shading normals at the three vertices (copies of ng when the mesh has none).
    material (T,) int32: global material index.
    medium (T,) int32: medium enclosed by the triangle's mesh, -1 for none.
    light (T,) int32: row in the light table, -1 when the triangle does not emit.
    """

    v0: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    ng: np.ndarray
    sn: np.ndarray
    material: np.ndarray
    medium: np.ndarray
    light: np.ndarray


class CameraParams(NamedTuple):
    """What renderer.camera.camera_ray reads (float64 arrays).

    to_world (4, 4); tan_half (x, y): the image plane's half extent, at distance 1 for a
    perspective camera, in world units for an orthographic one; shift (x, y) in the same
    units; clip (start, end); raster: the full frame's width and height and the rendered
    window's top-left pixel (RASTER_*); lens: the thin lens (LENS_*); projection: the
    projection's code and the panoramic parameters (PROJ_*).
    """

    to_world: np.ndarray
    tan_half: np.ndarray
    shift: np.ndarray
    clip: np.ndarray
    raster: np.ndarray
    lens: np.ndarray
    projection: np.ndarray


@dataclass
class CompiledScene:
    vertices: np.ndarray  # (V, 3) float32, merged
    indices: np.ndarray  # (T, 3) int32, merged
    geometry: Geometry
    materials: tuple  # renderer.bsdfs material table
    lights: LightTable
    media: MediaData  # immutable; the tracer adds its scratch for the kernels
    camera: CameraParams
    width: int
    height: int
    world_medium: int  # -1 for none
    has_media: bool  # any medium at all: the integrator skips every medium step without
    needs_shadow_walk: bool  # shadow rays must walk through interfaces / transparent surfaces
    scene_radius: float
    transparent: bool = False  # Film > Transparent: the world seen directly gives alpha 0
    aovs: bool = False  # the surface stage writes the passes' columns (renderer.passes)
    mist: tuple[float, float, float] = (5.0, 1.0 / 25.0, 2.0)  # start, 1 / depth, falloff exponent
    shading: ShadingTables | None = None  # shader programs (renderer.shading.table); None = none
    # The environment map's tables (renderer.lights.environment_map); None for a constant
    # world, which then compiles and runs no map code.
    environment: tuple | None = None
    light_aovs: bool = False  # and the light passes' (Emission, Diffuse/Glossy Color, Volume)


def _merge_meshes(scene: Scene, material_index: dict[str, int], medium_index: dict[str, int]):
    verts, idx, mats, meds = [], [], [], []
    offset = 0
    for mesh in scene.meshes:
        v = np.asarray(mesh.vertices, np.float32).reshape(-1, 3)
        i = np.asarray(mesh.indices, np.int32).reshape(-1, 3)
        local_ids = (np.zeros(i.shape[0], np.int32) if mesh.material_ids is None
                     else np.asarray(mesh.material_ids, np.int32))
        lut = np.array([material_index[name] for name in mesh.materials] or [0], np.int32)
        verts.append(v)
        idx.append(i + offset)
        mats.append(lut[local_ids])
        meds.append(np.full(i.shape[0], -1 if mesh.medium is None else medium_index[mesh.medium], np.int32))
        offset += v.shape[0]
    if not verts:
        return (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), np.zeros(0, np.int32),
                np.zeros(0, np.int32))
    return np.concatenate(verts), np.concatenate(idx), np.concatenate(mats), np.concatenate(meds)


def _camera(scene: Scene) -> CameraParams:
    cam, film = scene.camera, scene.film
    aspect = film.width / film.height
    if cam.projection == "orthographic":
        # The fitted side spans ortho_scale world units (Cycles' viewplane).
        t = 0.5 * cam.ortho_scale
    else:
        t = math.tan(math.radians(cam.fov) * 0.5)
    half = np.array([t, t / aspect] if cam.fov_axis == "x" else [t * aspect, t], np.float64)
    # Blender shifts by a fraction of the larger image side; the image plane spans 2 * half.
    shift = np.array(cam.shift, np.float64) * 2.0 * max(half)
    x0, y0, _, _ = film.window()
    raster = np.array([film.width, film.height, x0, y0], np.float64)
    # C order whatever the scene gave (Blender's matrix_world arrives in Fortran order):
    # numba compiles the camera kernels once per array layout.
    to_world = np.ascontiguousarray(cam.to_world, np.float64)
    return CameraParams(to_world, half, shift,
                        np.array([cam.clip_start, cam.clip_end], np.float64), raster, _lens(cam),
                        _projection(cam, aspect))


def _lens(cam) -> np.ndarray:
    lens = np.zeros(LENS_SIZE, np.float64)
    lens[LENS_RADIUS] = cam.aperture_radius
    lens[LENS_FOCUS] = max(cam.focus_distance, 1e-5)  # Cycles' floor
    lens[LENS_BLADES] = cam.aperture_blades if cam.aperture_blades >= 3 else 0
    lens[LENS_ROTATION] = cam.aperture_rotation
    lens[LENS_INV_RATIO] = 1.0 / cam.aperture_ratio
    return lens


def _projection(cam, aspect: float) -> np.ndarray:
    proj = np.zeros(PROJ_SIZE, np.float64)
    proj[PROJ_KIND] = PROJECTIONS[cam.projection]
    proj[[PROJ_LON_MIN, PROJ_LON_MAX, PROJ_LAT_MIN, PROJ_LAT_MAX]] = (
        cam.longitude_min, cam.longitude_max, cam.latitude_min, cam.latitude_max)
    proj[PROJ_FISHEYE_FOV] = cam.fisheye_fov
    proj[PROJ_FISHEYE_LENS] = cam.fisheye_lens
    # Cycles' panoramic sensor: `sensor` along the fitted side, the other side in proportion.
    if cam.fov_axis == "x":
        proj[PROJ_SENSOR_W], proj[PROJ_SENSOR_H] = cam.sensor, cam.sensor / aspect
    else:
        proj[PROJ_SENSOR_W], proj[PROJ_SENSOR_H] = cam.sensor * aspect, cam.sensor
    return proj


def compile_scene(scene: Scene) -> CompiledScene:
    # The indices the kernels read programs with, checked even for a scene compiled without
    # validate_scene (cheap: Python over the programs' rows).
    check_shading(scene)
    material_index = {m.name: i for i, m in enumerate(scene.materials)}
    medium_index = {m.name: i for i, m in enumerate(scene.media)}
    vertices, indices, tri_mat, tri_med = _merge_meshes(scene, material_index, medium_index)
    emission = np.array([m.emission for m in scene.materials] or np.zeros((0, 3)), np.float64)
    sides = np.array([SIDES[m.emission_sides] for m in scene.materials] or np.zeros(0), np.int32)
    if vertices.shape[0]:
        lo, hi = vertices.min(axis=0), vertices.max(axis=0)
        radius = float(0.5 * np.linalg.norm(hi - lo)) or 1.0
    else:
        radius = 1.0
    v0 = vertices[indices[:, 0]].astype(np.float64)
    v1 = vertices[indices[:, 1]].astype(np.float64)
    v2 = vertices[indices[:, 2]].astype(np.float64)
    lights = build_light_table((v0, v1, v2, tri_mat), emission, sides, scene.lights, scene.environment,
                               radius)
    geometry = _geometry_from_meshes(scene, vertices, indices, tri_mat, tri_med, lights.tri_light)
    materials = build_material_table(scene.materials)
    media = build_media_data(scene.media, scene.integrator.majorant_grid)
    world_medium = -1 if scene.medium is None else medium_index[scene.medium]
    has_media = bool(len(scene.media)) and (world_medium >= 0 or bool((tri_med >= 0).any()))
    # Shadow rays need an interface walk when a surface can let them through: a medium
    # boundary (meshes with media) or a material without opaque lobes on some side.
    see_through = [_lets_light_through(m) for m in scene.materials]
    used = np.unique(tri_mat)
    needs_walk = bool((tri_med >= 0).any()) or any(see_through[i] for i in used)
    # The film holds the rendered window only (the whole frame without a Render Region).
    _, _, width, height = scene.film.window()
    return CompiledScene(vertices, indices, geometry, materials, lights, media, _camera(scene),
                         width, height, world_medium, has_media, needs_walk, radius,
                         bool(scene.film.transparent), bool(scene.film.aovs), _mist(scene.film),
                         build_shading_tables(scene.materials, scene.meshes, scene.images, indices.shape[0]),
                         build_environment(scene.environment), bool(scene.film.light_aovs))


def _mist(film) -> tuple[float, float, float]:
    """Cycles' mist parameters (start, 1 / depth, falloff), as film.cpp sets them."""
    return (float(film.mist_start), 1.0 / max(float(film.mist_depth), 1e-30), float(film.mist_falloff))


def _lets_light_through(material) -> bool:
    kinds = {lobe.kind for lobe in material.lobes}
    return not material.lobes or "transparent" in kinds


def _geometry_from_meshes(scene, vertices, indices, tri_mat, tri_med, tri_light) -> Geometry:
    per_mesh = []
    for mesh in scene.meshes:
        t = np.asarray(mesh.indices).reshape(-1, 3)
        if mesh.normals is None:
            per_mesh.append((t.shape[0], None))
        else:
            n = np.asarray(mesh.normals, np.float32).reshape(-1, 3)
            per_mesh.append((t.shape[0], n[t]))
    v0 = vertices[indices[:, 0]]
    e1 = vertices[indices[:, 1]] - v0
    e2 = vertices[indices[:, 2]] - v0
    cr = np.cross(e1.astype(np.float64), e2.astype(np.float64))
    norm = np.linalg.norm(cr, axis=1, keepdims=True)
    ng = np.where(norm > 0, cr / np.maximum(norm, 1e-300), np.array([0.0, 0.0, 1.0])).astype(np.float32)
    sn = np.repeat(ng[:, None, :], 3, axis=1)
    start = 0
    for count, n in per_mesh:
        if n is not None:
            ln = np.linalg.norm(n, axis=2, keepdims=True)
            good = (ln > 0).all(axis=(1, 2))
            block = sn[start:start + count]
            block[good] = (n / np.maximum(ln, 1e-30))[good]
        start += count
    return Geometry(np.ascontiguousarray(v0, np.float32), np.ascontiguousarray(e1, np.float32),
                    np.ascontiguousarray(e2, np.float32), np.ascontiguousarray(ng),
                    np.ascontiguousarray(sn, np.float32), np.ascontiguousarray(tri_mat, np.int32),
                    np.ascontiguousarray(tri_med, np.int32), np.ascontiguousarray(tri_light, np.int32))
