"""The validator's checks of a whole Scene: camera, film, integrator, materials and lobes,
meshes, lights, environment, names and references, and how far a path can grow.

`validate_scene` (exported by renderer.validate) conforms every field to its annotation
(renderer.validate.conform) and checks what types cannot say; a medium's checks are in
renderer.validate.media, the checks every part shares in renderer.validate.checks.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from renderer.errors import SceneError
from renderer.scene import (
    CONDUCTOR_KINDS,
    DISTANCE_SAMPLING_MODES,
    ENV_INTERPOLATIONS,
    ENV_PROJECTIONS,
    FOV_AXES,
    FRESNEL_MODES,
    LIGHT_TYPES,
    LOBE_KINDS,
    PROJECTIONS,
    SAMPLING_MODES,
    SIDES,
    TRANSMITTANCE_MODES,
    Camera,
    Environment,
    Film,
    IntegratorSettings,
    Lobe,
    Material,
    Mesh,
    Scene,
    SpotLight,
    SunLight,
)
from renderer.validate.checks import (
    MAX_MAGNITUDE,
    check_choice,
    check_coordinates,
    check_direction,
    check_magnitude,
    check_nonnegative_rgb,
    check_reference,
    check_transform,
    check_unique_names,
)
from renderer.validate.conform import conform_object, require
from renderer.validate.media import check_medium
from renderer.validate.program import check_shading

MAX_FILM_SIDE = 16384
MIN_BATCH_SIZE, MAX_BATCH_SIZE = 1024, 1 << 22
MAX_IOR = 1e6
# Cycles' own limits (its max_bounces and samples properties): a path ends after at most
# MAX_BOUNCES scattering events whatever the scene asks, so no valid scene traces forever
# (interfaces are capped by the surface stage's MAX_CROSSINGS; null collisions end in finite
# expected time). Seeds are 64-bit (renderer.units.kernel_seed).
MAX_BOUNCES = 1024
MAX_SPP = 1 << 24
MAX_SEED = 2**64


def validate_scene(scene: Scene) -> None:
    """Raise SceneError for the first problem in `scene`.

    Normalises in place on the way: arrays become contiguous float32/int32 (float64 and
    int64 are converted when the values fit), number tuples become tuples of floats and
    matrices float64 arrays, so the compiler can trust the types afterwards.
    """
    if not isinstance(scene, Scene):
        raise SceneError("scene", f"must be a Scene, got {type(scene).__name__}")
    conform_object(scene, (Scene,), "")
    _check_camera(scene.camera, "camera")
    _check_film(scene.film, "film")
    _check_integrator(scene.integrator, "integrator")
    material_names = check_unique_names(scene.materials, "materials")
    medium_names = check_unique_names(scene.media, "media")
    check_unique_names(scene.meshes, "meshes")
    for i, material in enumerate(scene.materials):
        _check_material(material, f"materials[{i}]")
    for i, mesh in enumerate(scene.meshes):
        _check_mesh(mesh, f"meshes[{i}]", material_names, medium_names)
    check_shading(scene)
    for i, light in enumerate(scene.lights):
        _check_light(light, f"lights[{i}]")
    for i, medium in enumerate(scene.media):
        check_medium(medium, f"media[{i}]")
    _check_environment(scene.environment, "environment")
    check_reference(scene.medium, medium_names, "medium", "medium")
    _check_path_growth(scene)


def validate_material(material: Material, path: str) -> None:
    """Conform and check one material as validate_scene does: renderer.bsdfs.table calls
    it, so the lobe table never holds a kind, side or Fresnel mode the kernels lack."""
    conform_object(material, (Material,), path)
    _check_material(material, path)


def _check_camera(camera: Camera, path: str) -> None:
    check_transform(camera.to_world, f"{path}.to_world")
    require(0.0 < camera.fov < 180.0, f"{path}.fov", f"must be in (0, 180) degrees, got {camera.fov}")
    check_choice(camera.fov_axis, FOV_AXES, f"{path}.fov_axis", "fov axis")
    require(camera.clip_start > 0.0, f"{path}.clip_start", f"must be > 0, got {camera.clip_start}")
    require(
        camera.clip_end > camera.clip_start,
        f"{path}.clip_end",
        f"must be > clip_start ({camera.clip_start}), got {camera.clip_end}",
    )
    check_choice(camera.projection, PROJECTIONS, f"{path}.projection", "projection")
    _check_lens(camera, path)
    _check_panorama(camera, path)


def _check_lens(camera: Camera, path: str) -> None:
    require(camera.ortho_scale > 0.0, f"{path}.ortho_scale", f"must be > 0, got {camera.ortho_scale}")
    require(camera.aperture_radius >= 0.0, f"{path}.aperture_radius",
            f"must be >= 0, got {camera.aperture_radius}")
    require(camera.focus_distance > 0.0, f"{path}.focus_distance",
            f"must be > 0, got {camera.focus_distance}")
    require(0 <= camera.aperture_blades <= 256, f"{path}.aperture_blades",
            f"must be in [0, 256], got {camera.aperture_blades}")
    require(camera.aperture_ratio > 0.0, f"{path}.aperture_ratio",
            f"must be > 0, got {camera.aperture_ratio}")


def _check_panorama(camera: Camera, path: str) -> None:
    require(camera.longitude_min < camera.longitude_max, f"{path}.longitude_max",
            f"must be > longitude_min ({camera.longitude_min}), got {camera.longitude_max}")
    require(camera.latitude_min < camera.latitude_max, f"{path}.latitude_max",
            f"must be > latitude_min ({camera.latitude_min}), got {camera.latitude_max}")
    require(0.0 < camera.fisheye_fov <= 2.0 * np.pi, f"{path}.fisheye_fov",
            f"must be in (0, 2 pi] radians, got {camera.fisheye_fov}")
    require(camera.fisheye_lens > 0.0, f"{path}.fisheye_lens", f"must be > 0, got {camera.fisheye_lens}")
    require(camera.sensor > 0.0, f"{path}.sensor", f"must be > 0, got {camera.sensor}")


def _check_film(film: Film, path: str) -> None:
    for name in ("width", "height"):
        size = getattr(film, name)
        require(1 <= size <= MAX_FILM_SIDE, f"{path}.{name}", f"must be in [1, {MAX_FILM_SIDE}], got {size}")
    if film.region is not None:
        require(all(float(v).is_integer() for v in film.region), f"{path}.region",
                f"must be whole pixels, got {tuple(film.region)}")
        x, y, w, h = film.region
        inside = 0 <= x and 0 <= y and w >= 1 and h >= 1 and x + w <= film.width and y + h <= film.height
        require(inside, f"{path}.region", f"must be a non-empty window of the {film.width}x{film.height} "
                f"frame, got {tuple(film.region)}")


def _check_integrator(settings: IntegratorSettings, path: str) -> None:
    spp_ok = 1 <= settings.spp <= MAX_SPP
    require(spp_ok, f"{path}.spp", f"must be in [1, {MAX_SPP}], got {settings.spp}")
    bounces_ok = 0 <= settings.max_bounces <= MAX_BOUNCES
    require(bounces_ok, f"{path}.max_bounces", f"must be in [0, {MAX_BOUNCES}], got {settings.max_bounces}")
    rr_ok = 0 <= settings.rr_depth < 2**31
    require(rr_ok, f"{path}.rr_depth", f"must be in [0, 2**31), got {settings.rr_depth}")
    require(0 <= settings.seed < MAX_SEED, f"{path}.seed", f"must be in [0, 2**64), got {settings.seed}")
    batch = settings.batch_size
    batch_ok = MIN_BATCH_SIZE <= batch <= MAX_BATCH_SIZE
    require(batch_ok, f"{path}.batch_size", f"must be in [{MIN_BATCH_SIZE}, {MAX_BATCH_SIZE}], got {batch}")
    check_choice(settings.sampling, SAMPLING_MODES, f"{path}.sampling", "sampling mode")
    check_choice(settings.transmittance, TRANSMITTANCE_MODES, f"{path}.transmittance", "transmittance mode")
    check_choice(
        settings.distance_sampling, DISTANCE_SAMPLING_MODES, f"{path}.distance_sampling", "distance sampling"
    )
    limit = settings.time_limit
    require(limit >= 0.0, f"{path}.time_limit", f"must be >= 0, got {limit}")


def _check_material(material: Material, path: str) -> None:
    for i, lobe in enumerate(material.lobes):
        _check_lobe(lobe, f"{path}.lobes[{i}]")
    check_nonnegative_rgb(material.emission, f"{path}.emission")
    check_choice(material.emission_sides, SIDES, f"{path}.emission_sides", "sides value")


def _check_lobe(lobe: Lobe, path: str) -> None:
    check_choice(lobe.kind, LOBE_KINDS, f"{path}.kind", "lobe kind")
    check_nonnegative_rgb(lobe.weight, f"{path}.weight")
    check_nonnegative_rgb(lobe.color, f"{path}.color")
    roughness_ok = 0.0 <= lobe.roughness <= 1.0
    require(roughness_ok, f"{path}.roughness", f"must be in [0, 1], got {lobe.roughness}")
    require(lobe.ior > 0.0, f"{path}.ior", f"must be > 0, got {lobe.ior}")
    require(lobe.ior <= MAX_IOR, f"{path}.ior", f"must be at most {MAX_IOR:g}, got {lobe.ior}")
    check_choice(lobe.sides, SIDES, f"{path}.sides", "sides value")
    check_choice(lobe.fresnel, FRESNEL_MODES, f"{path}.fresnel", "Fresnel mode")
    fresnel_ok = lobe.fresnel == "constant" or lobe.kind in CONDUCTOR_KINDS
    require(fresnel_ok, f"{path}.fresnel", f"{lobe.fresnel!r} applies to conductors only, not {lobe.kind!r}")
    tint_ok = len(lobe.tint) == 3 and 0.0 <= min(lobe.tint) and max(lobe.tint) <= 1.0
    require(tint_ok, f"{path}.tint", f"must be three numbers in [0, 1], got {lobe.tint}")


def _material_albedo(material: Material) -> float:
    """The most a bounce off `material` can multiply a path's value by: its lobes' weight x color."""
    return sum(max(w * c for w, c in zip(lobe.weight, lobe.color)) for lobe in material.lobes)


def _check_path_growth(scene: Scene) -> None:
    """Paths that gain energy at every bounce must not overflow float32 by the last bounce.

    Each value is bounded on its own, but a material whose weight x color exceeds 1 makes a
    path's throughput grow geometrically: albedo ** (max_bounces + 1) times a radiance of up
    to MAX_MAGNITUDE must stay finite, so the growth itself is held below MAX_MAGNITUDE.
    Logarithms, because the power itself may overflow even a Python float.
    """
    albedos = [_material_albedo(material) for material in scene.materials]
    if not albedos or max(albedos) <= 1.0:
        return
    worst = int(np.argmax(albedos))
    bounces = scene.integrator.max_bounces + 1
    if bounces * np.log10(albedos[worst]) > np.log10(MAX_MAGNITUDE):
        raise SceneError(
            f"materials[{worst}].lobes",
            f"weight x color up to {albedos[worst]:.3g} grows a path {albedos[worst]:.3g}^{bounces} times "
            f"over integrator.max_bounces = {bounces - 1}; must stay below {MAX_MAGNITUDE:g}",
        )


def _check_mesh(mesh: Mesh, path: str, material_names: set[str], medium_names: set[str]) -> None:
    vertex_count = _check_rows_of_three(mesh.vertices, f"{path}.vertices", "V")
    check_coordinates(mesh.vertices, f"{path}.vertices")
    triangle_count = _check_rows_of_three(mesh.indices, f"{path}.indices", "T")
    _check_index_range(mesh.indices, vertex_count, f"{path}.indices", "vertices")
    if mesh.normals is not None:
        shape_ok = mesh.normals.shape == mesh.vertices.shape
        require(
            shape_ok, f"{path}.normals", f"must have shape ({vertex_count}, 3), got {mesh.normals.shape}"
        )
    for i, name in enumerate(mesh.materials):
        check_reference(name, material_names, f"{path}.materials[{i}]", "material")
    _check_material_ids(mesh, triangle_count, path)
    check_reference(mesh.medium, medium_names, f"{path}.medium", "medium")


def _check_rows_of_three(array: np.ndarray, path: str, rows: str) -> int:
    shape_ok = array.ndim == 2 and array.shape[1] == 3
    require(shape_ok, path, f"must have shape ({rows}, 3), got {array.shape}")
    return array.shape[0]


def _check_index_range(indices: np.ndarray, count: int, path: str, what: str) -> None:
    """Every index in [0, count); `what` names the indexed list in the message."""
    if indices.size == 0:
        return
    low, high = int(indices.min()), int(indices.max())
    require(low >= 0, path, f"contains negative index {low}")
    require(high < count, path, f"index {high} out of range for {count} {what}")


def _check_material_ids(mesh: Mesh, triangle_count: int, path: str) -> None:
    material_count = len(mesh.materials)
    if mesh.material_ids is None:
        has_material = material_count > 0 or triangle_count == 0
        require(
            has_material, f"{path}.materials", "must name at least one material (the mesh has triangles)"
        )
        return
    ids = mesh.material_ids
    ids_path = f"{path}.material_ids"
    require(
        ids.shape == (triangle_count,), ids_path, f"must have shape ({triangle_count},), got {ids.shape}"
    )
    _check_index_range(ids, material_count, ids_path, "materials")


def _check_light(light: Any, path: str) -> None:
    check_choice(light.type, LIGHT_TYPES, f"{path}.type", "light type")
    matches = LIGHT_TYPES[light.type] is type(light)
    require(matches, f"{path}.type", f"{light.type!r} does not match a {type(light).__name__}")
    for name in ("intensity", "irradiance"):
        if hasattr(light, name):
            check_nonnegative_rgb(getattr(light, name), f"{path}.{name}")
    if hasattr(light, "direction"):
        check_direction(light.direction, f"{path}.direction")
    if hasattr(light, "position"):
        check_coordinates(light.position, f"{path}.position")
    if isinstance(light, SpotLight):
        size_ok = 0.0 < light.spot_size <= 180.0
        require(size_ok, f"{path}.spot_size", f"must be in (0, 180] degrees, got {light.spot_size}")
        require(0.0 <= light.blend <= 1.0, f"{path}.blend", f"must be in [0, 1], got {light.blend}")
    if isinstance(light, SunLight):
        require(
            0.0 <= light.angle < 180.0, f"{path}.angle", f"must be in [0, 180) degrees, got {light.angle}"
        )


def _check_environment(env: Environment, path: str) -> None:
    check_nonnegative_rgb(env.radiance, f"{path}.radiance")
    check_choice(env.interpolation, ENV_INTERPOLATIONS, f"{path}.interpolation", "interpolation")
    check_choice(env.projection, ENV_PROJECTIONS, f"{path}.projection", "projection")
    rotation = env.to_world[:3, :3]
    # An orthogonal matrix has no entry beyond +-1 (checked first, so the product cannot overflow).
    bounded = bool(np.abs(rotation).max() <= 1.0 + 1e-5)
    orthogonal = bounded and np.allclose(rotation @ rotation.T, np.eye(3), rtol=0.0, atol=1e-5)
    require(orthogonal, f"{path}.to_world", "must rotate (or reflect) only: its 3x3 part is not orthogonal")
    image = env.radiance_map
    if image is None:
        return
    where = f"{path}.radiance_map"
    ok = image.ndim == 3 and image.shape[2] == 3 and image.shape[0] >= 1 and image.shape[1] >= 1
    require(ok, where, f"must have shape (height, width, 3), got {image.shape}")
    require(float(image.min()) >= 0.0, where, "must not be negative")
    peak = float(image.max()) * max(env.radiance)
    check_magnitude(peak, where, "largest radiance x tint")


