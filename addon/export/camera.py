"""The active camera and image size as Haze's Camera and Film."""

from __future__ import annotations

import math

import numpy as np

from renderer.scene import Camera, Film

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


def export_camera(camera_object, film: Film, render, scene_name: str, messages: Messages) -> Camera:
    if camera_object is None:
        raise ExportError(f"Scene '{scene_name}'",
                          "has no active camera; set one in Scene Properties > Camera")
    subject = object_subject(camera_object.name)
    if camera_object.type != "CAMERA":
        raise ExportError(subject, "is the scene camera but is not a camera object")
    data = camera_object.data
    if data.type != "PERSP":
        kind = {"ORTHO": "orthographic", "PANO": "panoramic"}.get(data.type, data.type.lower())
        raise ExportError(subject, f"{kind} cameras are not supported; use a perspective camera")
    if data.dof.use_dof:
        messages.warn(subject, "depth of field is not supported and is ignored (pinhole camera)")
    if render.pixel_aspect_x != render.pixel_aspect_y:
        messages.warn(f"Scene '{scene_name}'", "non-square pixel aspect is ignored")
    if getattr(render, "use_border", False):
        messages.warn(f"Scene '{scene_name}'", "Render Region is ignored; the whole frame is rendered")
    try:
        to_world = rigid_matrix(camera_object.matrix_world)
    except ValueError:
        raise ExportError(subject, "has a zero scale, so its orientation is undefined") from None
    fov, axis = field_of_view(data, film.width, film.height)
    return Camera(
        to_world=to_world,
        fov=fov,
        fov_axis=axis,
        shift=contract_shift(data, axis, film.width, film.height),
        clip_start=float(data.clip_start),
        clip_end=float(data.clip_end),
    )
