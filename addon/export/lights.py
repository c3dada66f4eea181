"""Blender lights in Cycles' units.

Light power P (watts) times colour times 2^exposure (times the blackbody colour when
"temperature" is used) is converted as Cycles does (kernel/light/*.h):

* point/spot: radiant intensity P / (4 pi) W/sr, spot cone and blend as in Blender;
* sun: irradiance = strength (W/m^2) facing the sun, with its angular diameter;
* area: an emissive quad or disk facing the light's -Z, radiance P / (pi x area) with
  "normalize" on (P / pi per square metre without). A Cycles light is not a surface: rays
  pass through it (kernel/integrator/shade_light.h), so the emitter gets a clear transparent
  lobe; it emits only from its front and shows nothing from behind.
"""

from __future__ import annotations

import math

import numpy as np

from renderer.scene import Lobe, Material, Mesh, PointLight, SpotLight, SunLight

from .messages import Messages, object_subject
from .node_closures import rgb

DISK_SEGMENTS = 64


def light_power(light) -> np.ndarray:
    """Colour x power x 2^exposure, with the blackbody tint when temperature is enabled."""
    color = np.asarray(light.color[:3], dtype=np.float64)
    if getattr(light, "use_temperature", False):
        color = color * np.asarray(light.temperature_color[:3], dtype=np.float64)
    return color * float(light.energy) * 2.0 ** float(getattr(light, "exposure", 0.0))


def axis(matrix: np.ndarray, index: int) -> np.ndarray:
    column = matrix[:3, index]
    length = np.linalg.norm(column)
    return column / length if length > 0.0 else column


def warn_radius(light, subject: str, messages: Messages) -> None:
    if light.shadow_soft_size > 0.0:
        messages.warn(subject, f"radius {light.shadow_soft_size:g} m is ignored; Haze point and spot lights "
                      "are infinitely small (set Radius to 0 to match Cycles exactly)")


def point_light(light, matrix: np.ndarray, subject: str, messages: Messages) -> PointLight:
    warn_radius(light, subject, messages)
    return PointLight(position=rgb(matrix[:3, 3]), intensity=rgb(light_power(light) / (4.0 * math.pi)))


def spot_light(light, matrix: np.ndarray, subject: str, messages: Messages) -> SpotLight:
    warn_radius(light, subject, messages)
    scales = np.linalg.norm(matrix[:3, :2], axis=0)
    if not np.isclose(scales[0], scales[1], rtol=1e-4) or getattr(light, "use_square", False):
        messages.warn(subject, "square or non-uniformly scaled spot cones are rendered as round cones")
    return SpotLight(
        position=rgb(matrix[:3, 3]),
        direction=rgb(-axis(matrix, 2)),
        intensity=rgb(light_power(light) / (4.0 * math.pi)),
        spot_size=math.degrees(light.spot_size),
        blend=float(light.spot_blend),
    )


def sun_light(light, matrix: np.ndarray) -> SunLight:
    # A sun shines along its local -Z, so the direction toward it is +Z.
    return SunLight(direction=rgb(axis(matrix, 2)), irradiance=rgb(light_power(light)),
                    angle=math.degrees(light.angle))


def area_outline(light) -> tuple[np.ndarray, float]:
    """Local outline (N, 3) of an area light in its XY plane, counter-clockwise seen from -Z,
    and the area Cycles uses for it (pi/4 x a x b for disks and ellipses)."""
    size_x = float(light.size)
    size_y = float(light.size_y) if light.shape in {"RECTANGLE", "ELLIPSE"} else size_x
    if light.shape in {"DISK", "ELLIPSE"}:
        exact_area = math.pi / 4.0 * size_x * size_y
        angles = -np.arange(DISK_SEGMENTS) * (2.0 * math.pi / DISK_SEGMENTS)
        # Enlarge the polygon slightly so its area equals the ellipse's: same emitted power.
        polygon_area = 0.5 * DISK_SEGMENTS * math.sin(2.0 * math.pi / DISK_SEGMENTS) * 0.25 * size_x * size_y
        grow = math.sqrt(exact_area / polygon_area)
        points = np.stack([0.5 * size_x * grow * np.cos(angles), 0.5 * size_y * grow * np.sin(angles),
                           np.zeros(DISK_SEGMENTS)], axis=1)
        return points, exact_area
    half_x, half_y = 0.5 * size_x, 0.5 * size_y
    points = np.array([[-half_x, -half_y, 0.0], [-half_x, half_y, 0.0], [half_x, half_y, 0.0],
                       [half_x, -half_y, 0.0]])
    return points, size_x * size_y


def fan_triangles(count: int) -> np.ndarray:
    return np.array([[0, i, i + 1] for i in range(1, count - 1)], dtype=np.int32)


def area_light(light, matrix: np.ndarray, name: str, messages: Messages) -> tuple[Mesh, Material] | None:
    """The emitter geometry and material of an area light, or None if it emits nothing."""
    subject = object_subject(name)
    outline, local_area = area_outline(light)
    linear = matrix[:3, :3]
    world_area = local_area * float(np.linalg.norm(np.cross(linear[:, 0], linear[:, 1])))
    if world_area <= 0.0 or not math.isfinite(world_area):
        messages.warn(subject, "area light has zero size, so it emits nothing; it is skipped")
        return None
    if light.spread < math.pi - 1e-6:
        messages.warn(subject, f"spread {math.degrees(light.spread):g} degrees is rendered as 180 degrees")
    power = light_power(light)
    radiance = power / (math.pi * world_area) if light.normalize else power / math.pi
    vertices = (outline @ linear.T + matrix[:3, 3]).astype(np.float32)
    triangles = fan_triangles(len(outline))
    if np.linalg.det(linear) < 0.0:
        triangles = triangles[:, ::-1].copy()
    see_through = [Lobe("transparent", color=(1.0, 1.0, 1.0), sides="both")]
    material = Material(f"{name} (area light)", lobes=see_through, emission=rgb(radiance),
                        emission_sides="front")
    mesh = Mesh(f"{name} (area light)", vertices, triangles, [material.name])
    return mesh, material
