"""The scene validator: everything any Scene can get wrong, in-memory or loaded from a file.

`validate_scene` conforms every field to its annotation (renderer.conform) and checks what
types cannot say: value ranges, the vocabulary of renderer.scene, unique names and the
references between objects, array shapes and index ranges, invertible transforms. The
compilers downstream rely on it; the medium and lobe checks are also called on their own
by the table builders (validate_medium, validate_material), the one copy of each rule. Every
problem is a SceneError whose message starts with the field path, e.g. `meshes[2].vertices`.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

import numpy as np

from renderer.conform import conform_object, require
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
    MEDIUM_TYPES,
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
    Medium,
    Mesh,
    Scene,
    SpotLight,
    SunLight,
)

MAX_FILM_SIDE = 16384
MIN_BATCH_SIZE, MAX_BATCH_SIZE = 1024, 1 << 22
GRID_ARRAYS = ("density", "flame", "temperature")
# Relative singularity threshold, see _is_singular.
_SINGULAR_TOLERANCE = 1e-12
# Limits that keep the float32 kernels finite. A float32 holds at most 3.4e38; a path value
# multiplies radiance by weights, coefficients and geometry terms (distances squared among
# them), so radiometric inputs and their products stay below MAX_MAGNITUDE and coordinates
# below MAX_COORDINATE, leaving about twenty orders of magnitude of headroom.
MAX_MAGNITUDE = 1e18
MAX_COORDINATE = 1e15
# A transform's columns scale by at most this factor either way; beyond it float32 loses all
# precision (or overflows) when the kernels apply it.
MAX_SCALE = 1e12
# Directions are normalised; below this length their square underflows float32.
MIN_DIRECTION_LENGTH = 1e-12
MAX_IOR = 1e6
# Stefan-Boltzmann radiance scaled as Cycles does (renderer/media/blackbody.py): times T^4.
_BLACKBODY_FACTOR = 5.670373e-8 / np.pi * 1e-6


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
    material_names = _check_unique_names(scene.materials, "materials")
    medium_names = _check_unique_names(scene.media, "media")
    _check_unique_names(scene.meshes, "meshes")
    for i, material in enumerate(scene.materials):
        _check_material(material, f"materials[{i}]")
    for i, mesh in enumerate(scene.meshes):
        _check_mesh(mesh, f"meshes[{i}]", material_names, medium_names)
    for i, light in enumerate(scene.lights):
        _check_light(light, f"lights[{i}]")
    for i, medium in enumerate(scene.media):
        _check_medium(medium, f"media[{i}]")
    _check_environment(scene.environment, "environment")
    _check_reference(scene.medium, medium_names, "medium", "medium")
    _check_path_growth(scene)


def validate_medium(medium: Medium, path: str) -> None:
    """Conform and check one medium as validate_scene does (names and references aside).

    renderer.media.compile calls it for every medium it flattens, so a scene compiled without
    validate_scene still never hands the kernels a bad grid or transform.
    """
    conform_object(medium, (Medium,), path)
    _check_medium(medium, path)


def validate_material(material: Material, path: str) -> None:
    """Conform and check one material as validate_scene does: renderer.bsdfs.table calls
    it, so the lobe table never holds a kind, side or Fresnel mode the kernels lack."""
    conform_object(material, (Material,), path)
    _check_material(material, path)


def check_choice(value: str, allowed: Collection[str], path: str, what: str) -> None:
    """`value` is one of `allowed` (a tuple of words or a dict keyed by them)."""
    expected = ", ".join(repr(a) for a in allowed)
    require(value in allowed, path, f"unknown {what} {value!r} (expected one of {expected})")


def _check_nonnegative_rgb(rgb: tuple[float, ...], path: str) -> None:
    """A colour, coefficient or radiometric quantity: >= 0 and small enough for float32 paths."""
    require(min(rgb) >= 0.0, path, f"must not be negative, got {rgb}")
    _check_magnitude(max(rgb), path)


def _check_magnitude(value: float, path: str, what: str = "") -> None:
    """`value` (or the product `what` describes) is at most MAX_MAGNITUDE."""
    shown = f"{what} = {value:.3g}" if what else f"got {value:.3g}"
    limit = f"must be at most {MAX_MAGNITUDE:g} (float32 kernels overflow)"
    require(value <= MAX_MAGNITUDE, path, f"{limit}, {shown}")


def _check_coordinates(values: np.ndarray | tuple[float, ...], path: str) -> None:
    largest = float(np.max(np.abs(values))) if np.size(values) else 0.0
    ok = largest <= MAX_COORDINATE
    require(ok, path, f"coordinates must be within +-{MAX_COORDINATE:g} (float32 kernels), got {largest:.3g}")


def _check_direction(vector: tuple[float, ...], path: str) -> None:
    """A direction the kernels normalise: neither (nearly) zero nor so long its square overflows."""
    require(any(x != 0.0 for x in vector), path, "must be a non-zero vector")
    largest = max(abs(x) for x in vector)
    long_enough = largest >= MIN_DIRECTION_LENGTH
    problem = f"too short to normalise: length {largest:.3g} (at least {MIN_DIRECTION_LENGTH:g})"
    require(long_enough, path, problem)
    _check_coordinates(vector, path)


def _check_reference(name: str | None, known: set[str], path: str, what: str) -> None:
    require(name is None or name in known, path, f"unknown {what} {name!r}")


def _check_unique_names(items: list, path: str) -> set[str]:
    """The names of `items`, which must be non-empty and unique."""
    first_index: dict[str, int] = {}
    for i, item in enumerate(items):
        require(item.name != "", f"{path}[{i}].name", "must not be empty")
        if item.name in first_index:
            also = f"{path}[{first_index[item.name]}]"
            raise SceneError(f"{path}[{i}].name", f"duplicate name {item.name!r} (also {also})")
        first_index[item.name] = i
    return set(first_index)


def _is_singular(linear: np.ndarray) -> bool:
    """Whether a 3x3 matrix is singular relative to its scale: |det| <= tol * prod(column norms).

    Columns are first divided by their largest entry, so huge or tiny scales neither
    overflow nor count as singular; a column that overflowed to inf does.
    """
    largest = np.abs(linear).max(axis=0)
    if not np.all(largest > 0.0) or not np.all(np.isfinite(largest)):
        return True
    scaled = linear / largest
    return abs(np.linalg.det(scaled)) <= _SINGULAR_TOLERANCE * np.prod(np.linalg.norm(scaled, axis=0))


def _check_transform(matrix: np.ndarray, path: str, check_range: bool = True) -> None:
    """An invertible affine 4x4 transform (the kernels use only its top three rows).

    `check_range=False` leaves the scale check to a caller that checks the transform's
    product with another scale (a grid medium's box).
    """
    affine = np.allclose(matrix[3], (0.0, 0.0, 0.0, 1.0), rtol=0.0, atol=1e-9)
    require(affine, path, f"last row must be (0, 0, 0, 1), got {tuple(matrix[3].tolist())}")
    require(not _is_singular(matrix[:3, :3]), path, "singular matrix")
    if check_range:
        _check_transform_range(matrix, path)


def _check_transform_range(matrix: np.ndarray, path: str) -> None:
    """Scale and translation the float32 kernels can apply without overflow or losing all precision."""
    scales = np.abs(matrix[:3, :3]).max(axis=0)  # the largest entry of each column
    for axis, scale in zip("xyz", scales):
        ok = 1.0 / MAX_SCALE <= scale <= MAX_SCALE
        bounds = f"[{1 / MAX_SCALE:g}, {MAX_SCALE:g}]"
        require(ok, path, f"scales the {axis} axis by {scale:.3g}; must be within {bounds}")
    _check_coordinates(matrix[:3, 3], path)


def _check_camera(camera: Camera, path: str) -> None:
    _check_transform(camera.to_world, f"{path}.to_world")
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
    require(settings.spp >= 1, f"{path}.spp", f"must be >= 1, got {settings.spp}")
    for name in ("max_bounces", "rr_depth"):
        value = getattr(settings, name)
        require(value >= 0, f"{path}.{name}", f"must be >= 0, got {value}")
    require(0 <= settings.seed < 2**64, f"{path}.seed", f"must be in [0, 2**64), got {settings.seed}")
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
    _check_nonnegative_rgb(material.emission, f"{path}.emission")
    check_choice(material.emission_sides, SIDES, f"{path}.emission_sides", "sides value")


def _check_lobe(lobe: Lobe, path: str) -> None:
    check_choice(lobe.kind, LOBE_KINDS, f"{path}.kind", "lobe kind")
    _check_nonnegative_rgb(lobe.weight, f"{path}.weight")
    _check_nonnegative_rgb(lobe.color, f"{path}.color")
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
    _check_coordinates(mesh.vertices, f"{path}.vertices")
    triangle_count = _check_rows_of_three(mesh.indices, f"{path}.indices", "T")
    _check_index_range(mesh.indices, vertex_count, f"{path}.indices", "vertices")
    if mesh.normals is not None:
        shape_ok = mesh.normals.shape == mesh.vertices.shape
        require(
            shape_ok, f"{path}.normals", f"must have shape ({vertex_count}, 3), got {mesh.normals.shape}"
        )
    for i, name in enumerate(mesh.materials):
        _check_reference(name, material_names, f"{path}.materials[{i}]", "material")
    _check_material_ids(mesh, triangle_count, path)
    _check_reference(mesh.medium, medium_names, f"{path}.medium", "medium")


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
            _check_nonnegative_rgb(getattr(light, name), f"{path}.{name}")
    if hasattr(light, "direction"):
        _check_direction(light.direction, f"{path}.direction")
    if hasattr(light, "position"):
        _check_coordinates(light.position, f"{path}.position")
    if isinstance(light, SpotLight):
        size_ok = 0.0 < light.spot_size <= 180.0
        require(size_ok, f"{path}.spot_size", f"must be in (0, 180] degrees, got {light.spot_size}")
        require(0.0 <= light.blend <= 1.0, f"{path}.blend", f"must be in [0, 1], got {light.blend}")
    if isinstance(light, SunLight):
        require(
            0.0 <= light.angle < 180.0, f"{path}.angle", f"must be in [0, 180) degrees, got {light.angle}"
        )


def _check_environment(env: Environment, path: str) -> None:
    _check_nonnegative_rgb(env.radiance, f"{path}.radiance")
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
    _check_magnitude(peak, where, "largest radiance x tint")


def _check_medium(medium: Medium, path: str) -> None:
    check_choice(medium.type, MEDIUM_TYPES, f"{path}.type", "medium type")
    for name in ("sigma_a", "sigma_s", "emission"):
        _check_nonnegative_rgb(getattr(medium, name), f"{path}.{name}")
    require(medium.scale >= 0.0, f"{path}.scale", f"must be >= 0, got {medium.scale}")
    _check_magnitude(medium.scale, f"{path}.scale")
    require(abs(medium.g) < 1.0, f"{path}.g", f"must satisfy |g| < 1, got {medium.g}")
    bb = medium.blackbody_intensity
    require(bb >= 0.0, f"{path}.blackbody_intensity", f"must be >= 0, got {bb}")
    _check_magnitude(bb, f"{path}.blackbody_intensity")
    if medium.type == "homogeneous":
        for name in GRID_ARRAYS:
            carries = getattr(medium, name) is not None
            require(
                not carries, f"{path}.{name}", "only grid media take grid arrays (type is 'homogeneous')"
            )
        require(medium.program is None, f"{path}.program",
                "only grid media take a program (type is 'homogeneous')")
        _check_medium_products(medium, path, 1.0, 1.0, 0.0)
        return
    procedural = medium.program is not None
    require(medium.density is not None or procedural, f"{path}.density",
            "required for grid media (or a program, for a procedural density)")
    require(not (procedural and medium.density is not None), f"{path}.program",
            "a grid medium takes a density grid or a program, not both")
    if procedural:
        require(medium.flame is None and medium.temperature is None, f"{path}.program",
                "a procedural medium takes no flame or temperature grid")
    for name in GRID_ARRAYS:
        if getattr(medium, name) is not None:
            _check_grid_array(getattr(medium, name), f"{path}.{name}")
    _check_coordinates(medium.p0, f"{path}.p0")
    _check_coordinates(medium.p1, f"{path}.p1")
    _check_grid_box(medium, path)
    flame = _grid_max(medium.flame, 1.0)
    hottest = _grid_max(medium.temperature, 0.0)
    # (a procedural density's bound is checked where it is built: renderer.media.procedural)
    _check_medium_products(medium, path, _grid_max(medium.density, 0.0), flame, hottest)


def _grid_max(grid: np.ndarray | None, default: float) -> float:
    return float(grid.max()) if grid is not None else default


def _check_medium_products(
    medium: Medium, path: str, density: float, flame: float, temperature: float
) -> None:
    """The products the kernels form from a medium's values stay below MAX_MAGNITUDE.

    Each factor may be fine alone while their product overflows float32, e.g. sigma_s 1e18
    times a density of 1e30. Python floats (float64) hold every product checked here.
    """
    extinction = max(a + s for a, s in zip(medium.sigma_a, medium.sigma_s)) * medium.scale * density
    _check_magnitude(extinction, f"{path}.scale", "(sigma_a + sigma_s) * scale * max density")
    emission = max(medium.emission) * max(density, 1.0) * flame
    _check_magnitude(emission, f"{path}.emission", "emission * max density * max flame")
    blackbody = _BLACKBODY_FACTOR * medium.blackbody_intensity * temperature**4 * max(density, 1.0)
    _check_magnitude(blackbody, f"{path}.temperature", "blackbody radiance * max density")


def _check_grid_array(grid, path: str) -> None:
    from renderer.media.bricks import SparseGrid  # lazily: renderer.media imports this module

    if isinstance(grid, SparseGrid):
        _check_sparse_grid(grid, path)
        return
    require(grid.ndim == 3, path, f"must be 3-D (nz, ny, nx), got shape {grid.shape}")
    require(grid.size > 0, path, f"must not be empty, got shape {grid.shape}")
    require(bool((grid >= 0.0).all()), path, f"must not be negative, got minimum {float(grid.min())}")


def _check_sparse_grid(grid, path: str) -> None:
    """A SparseGrid (renderer.media.bricks) whose index and bricks agree."""
    from renderer.media.bricks import SPAN, lattice_shape

    require(len(grid.shape) == 3 and min(grid.shape) > 0, path, f"must have a 3-D shape, got {grid.shape}")
    require(grid.index.shape == lattice_shape(grid.shape) and grid.index.dtype == np.int32, path,
            f"brick index must be int32 of shape {lattice_shape(grid.shape)}, got {grid.index.dtype} "
            f"{grid.index.shape}")
    require(grid.bricks.ndim == 4 and grid.bricks.shape[1:] == (SPAN, SPAN, SPAN), path,
            f"bricks must be (B, {SPAN}, {SPAN}, {SPAN}), got {grid.bricks.shape}")
    used = grid.index[grid.index >= 0]
    require(bool(used.size == 0 or used.max() < len(grid.bricks)) and bool((grid.index >= -1).all()), path,
            f"brick index refers to bricks outside 0..{len(grid.bricks) - 1}")
    require(bool(np.isfinite(grid.bricks).all()), path, "must be finite")
    require(grid.min() >= 0.0, path, f"must not be negative, got minimum {grid.min()}")


def _check_grid_box(medium: Medium, path: str) -> None:
    for axis, low, high in zip("xyz", medium.p0, medium.p1):
        require(low != high, f"{path}.p1", f"equals p0 on the {axis} axis ({high}): the grid box is flat")
    _check_transform(medium.to_world, f"{path}.to_world", check_range=False)
    with np.errstate(over="ignore"):  # an overflowing box is caught as singular just below
        box_to_world = medium.to_world[:3, :3] @ np.diag(np.subtract(medium.p1, medium.p0))
    require(not _is_singular(box_to_world), f"{path}.to_world", "singular matrix (combined with p0..p1)")
    # The kernels map the unit cube to the world by this product, so its scale is what must fit.
    combined = medium.to_world.copy()
    combined[:3, :3] = box_to_world
    _check_transform_range(combined, f"{path}.to_world")
