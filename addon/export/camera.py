"""The active camera and image size as Haze's Camera and Film."""

from __future__ import annotations

import math

import numpy as np

from renderer.scene import Camera, Film

from ..display import render_region as render_region  # the exporter's and the session's window
from .messages import ExportError, Messages, object_subject


def film_size(render) -> tuple[int, int]:
    """Output resolution in pixels: resolution x percentage, as Blender renders it."""
    scale = render.resolution_percentage / 100.0
    return max(1, int(render.resolution_x * scale)), max(1, int(render.resolution_y * scale))


def fit_axis(sensor_fit: str, width: float, height: float) -> str:
    """Blender's sensor fit: AUTO fits the sensor width along the larger image side."""
    if sensor_fit == "HORIZONTAL":
        return "x"
    if sensor_fit == "VERTICAL":
        return "y"
    return "x" if width >= height else "y"


def field_of_view(camera_data, width: float, height: float) -> tuple[float, str]:
    """(full angle in degrees, axis) of a perspective camera for an image of width x height."""
    axis = fit_axis(camera_data.sensor_fit, width, height)
    # Blender uses the sensor height only for VERTICAL fit; AUTO always uses the width.
    sensor = camera_data.sensor_height if camera_data.sensor_fit == "VERTICAL" else camera_data.sensor_width
    return math.degrees(2.0 * math.atan(sensor / (2.0 * camera_data.lens))), axis


def contract_shift(camera_data, axis: str, width: float, height: float) -> tuple[float, float]:
    """Blender's shift is in units of the fitted image side; Haze's in units of the larger side."""
    fitted = width if axis == "x" else height
    factor = fitted / max(width, height)
    return (camera_data.shift_x * factor, camera_data.shift_y * factor)


def rigid_matrix(matrix_world) -> np.ndarray:
    """Camera-to-world without scale (Cycles ignores camera object scale)."""
    matrix = np.array(matrix_world, dtype=np.float64)
    lengths = np.linalg.norm(matrix[:3, :3], axis=0)
    if np.any(lengths <= 0.0):
        raise ValueError("degenerate")
    matrix[:3, :3] /= lengths
    return matrix


# Blender's panorama types Haze renders, by its projection names.
PANORAMA_TYPES = {
    "EQUIRECTANGULAR": "equirectangular",
    "FISHEYE_EQUIDISTANT": "fisheye_equidistant",
    "FISHEYE_EQUISOLID": "fisheye_equisolid",
    "MIRRORBALL": "mirrorball",
}


def projection_of(data, subject: str) -> str:
    """Haze's projection for a Blender camera, or an ExportError for one Haze lacks."""
    if data.type == "PERSP":
        return "perspective"
    if data.type == "ORTHO":
        return "orthographic"
    if data.type == "PANO" and data.panorama_type in PANORAMA_TYPES:
        return PANORAMA_TYPES[data.panorama_type]
    kind = data.panorama_type.lower().replace("_", " ") if data.type == "PANO" else data.type.lower()
    raise ExportError(subject, f"{kind} cameras are not supported; use a perspective, orthographic, "
                      "equirectangular, fisheye (equidistant or equisolid) or mirror ball camera")


def aperture_radius(data, projection: str) -> float:
    """Cycles' aperture size from the f-stop: focal length / (2 f-stop), the focal length in
    mm taken as metres x 1e-3; an orthographic camera has no focal length and uses 1 / (2
    f-stop) scene units (blender/camera.cpp)."""
    if not data.dof.use_dof:
        return 0.0
    fstop = max(float(data.dof.aperture_fstop), 1e-5)
    if projection == "orthographic":
        return 1.0 / (2.0 * fstop)
    return float(data.lens) * 1e-3 / (2.0 * fstop)


def focus_distance(camera_object, to_world: np.ndarray, messages: Messages) -> float:
    """Cycles' focal distance: the focus object's distance along the camera's view axis, or
    the Focus Distance without one."""
    dof = camera_object.data.dof
    target = dof.focus_object
    if target is None:
        return float(dof.focus_distance)
    if getattr(dof, "focus_subtarget", ""):
        messages.warn(object_subject(camera_object.name),
                      "a bone as focus target is not supported; the focus object's origin is used")
    axis = to_world[:3, 2]
    offset = to_world[:3, 3] - np.array(target.matrix_world.translation, np.float64)
    return abs(float(np.dot(axis, offset)))


def panorama_sensor(data) -> float:
    """The sensor side Cycles fits a fisheye to: the height for VERTICAL fit, else the width."""
    return float(data.sensor_height if data.sensor_fit == "VERTICAL" else data.sensor_width)


def render_warnings(render, scene_name: str, messages: Messages) -> None:
    """Output settings Haze renders without: said once, the render goes on."""
    if render.pixel_aspect_x != render.pixel_aspect_y:
        messages.warn(f"Scene '{scene_name}'", "non-square pixel aspect is ignored")
    if getattr(render, "use_motion_blur", False):
        messages.warn(f"Scene '{scene_name}'",
                      "motion blur is not supported: the scene renders as it is at the current frame")


def export_camera(camera_object, film: Film, render, scene_name: str, messages: Messages) -> Camera:
    if camera_object is None:
        raise ExportError(f"Scene '{scene_name}'",
                          "has no active camera; set one in Scene Properties > Camera")
    subject = object_subject(camera_object.name)
    if camera_object.type != "CAMERA":
        raise ExportError(subject, "is the scene camera but is not a camera object")
    data = camera_object.data
    projection = projection_of(data, subject)
    render_warnings(render, scene_name, messages)
    try:
        to_world = rigid_matrix(camera_object.matrix_world)
    except ValueError:
        raise ExportError(subject, "has a zero scale, so its orientation is undefined") from None
    fov, axis = field_of_view(data, film.width, film.height)
    shift = contract_shift(data, axis, film.width, film.height)
    if projection not in ("perspective", "orthographic") and shift != (0.0, 0.0):
        messages.warn(subject, "lens shift of a panoramic camera is not supported and is ignored")
        shift = (0.0, 0.0)
    radius = aperture_radius(data, projection)
    return Camera(
        to_world=to_world,
        fov=fov,
        fov_axis=axis,
        shift=shift,
        clip_start=float(data.clip_start),
        clip_end=float(data.clip_end),
        projection=projection,
        ortho_scale=float(data.ortho_scale),
        aperture_radius=radius,
        focus_distance=max(focus_distance(camera_object, to_world, messages), 1e-5) if radius > 0 else 10.0,
        aperture_blades=int(data.dof.aperture_blades),
        aperture_rotation=float(data.dof.aperture_rotation),
        aperture_ratio=float(data.dof.aperture_ratio),
        longitude_min=float(data.longitude_min),
        longitude_max=float(data.longitude_max),
        latitude_min=float(data.latitude_min),
        latitude_max=float(data.latitude_max),
        fisheye_fov=float(data.fisheye_fov),
        fisheye_lens=float(data.fisheye_lens),
        sensor=panorama_sensor(data),
    )
