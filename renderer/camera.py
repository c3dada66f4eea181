"""Camera rays with Cycles' projections (kernel/camera/camera.h and projection.h in the
Cycles source): perspective with an optional thin lens, orthographic, and the panoramic
types. Box filter of width 1: the sample is a uniform jitter in its pixel.

Cycles' camera space looks down +Z; Haze's (Blender's) looks down -Z with +Y up, so a
direction (x, y, z) of Cycles' perspective space is (x, y, -z) here. Cycles' panoramic
space looks down +X with +Z up (the centre of an environment map); its (x, y, z) is
(-y, z, -x) here. The mirror ball's looks down -Y with +Z up (as a mirror ball texture
does); its (x, y, z) is (x, z, y) here (blender/camera.cpp, blender_camera_matrix).

The pinhole perspective camera takes the first branch and costs what it did before the
other projections existed.
"""

import math

from renderer.kernels import inline_kernel, kernel

# Projection codes: the same numbers as renderer.scene.PROJECTIONS.
PERSPECTIVE = 0
ORTHOGRAPHIC = 1
EQUIRECTANGULAR = 2
FISHEYE_EQUIDISTANT = 3
FISHEYE_EQUISOLID = 4
MIRRORBALL = 5

# CameraParams.lens: the thin lens (radius 0 = pinhole).
LENS_RADIUS, LENS_FOCUS, LENS_BLADES, LENS_ROTATION, LENS_INV_RATIO = 0, 1, 2, 3, 4
LENS_SIZE = 5
# CameraParams.projection: the code, then the panoramic types' parameters.
PROJ_KIND, PROJ_LON_MIN, PROJ_LON_MAX, PROJ_LAT_MIN, PROJ_LAT_MAX = 0, 1, 2, 3, 4
PROJ_FISHEYE_FOV, PROJ_FISHEYE_LENS, PROJ_SENSOR_W, PROJ_SENSOR_H = 5, 6, 7, 8
PROJ_SIZE = 9
# CameraParams.raster: the full frame's size and the rendered window's top-left pixel.
RASTER_WIDTH, RASTER_HEIGHT, RASTER_X0, RASTER_Y0 = 0, 1, 2, 3


@kernel
def camera_ray(cam, px, py, u1, u2, u3, u4):
    """Ray through pixel (px, py) of the full frame, row 0 at the top; (u1, u2) jitter the
    point in the pixel, (u3, u4) pick the point on the lens. Returns (origin, unit
    direction, distance to the near clip along the ray, length from there to the far clip,
    ok); ok is False where the projection has no ray (outside a fisheye's circle): such a
    sample is black, as in Cycles."""
    to_world, tan_half, shift, clip, raster, lens, proj = cam
    width = raster[RASTER_WIDTH]
    height = raster[RASTER_HEIGHT]
    kind = int(proj[PROJ_KIND])
    # Image plane coordinates in [-1, 1], y up.
    sx = 2.0 * (px + u1) / width - 1.0
    sy = 1.0 - 2.0 * (py + u2) / height
    if kind == PERSPECTIVE and lens[LENS_RADIUS] <= 0.0:
        # Pinhole: the image plane at distance 1 spans [-tan_half, tan_half] plus the shift.
        d = (sx * tan_half[0] + shift[0], sy * tan_half[1] + shift[1], -1.0)
        return _origin(to_world), _direction(to_world, d), clip[0], clip[1] - clip[0], True
    if kind == PERSPECTIVE:
        x = sx * tan_half[0] + shift[0]
        y = sy * tan_half[1] + shift[1]
        o, d = _thin_lens_perspective(x, y, lens, u3, u4)
        # Cycles clips along the pinhole ray's depth: near / cos, cos from (x, y, 1).
        inv_cos = math.sqrt(x * x + y * y + 1.0)
        return (_point(to_world, o), _direction(to_world, d), clip[0] * inv_cos,
                (clip[1] - clip[0]) * inv_cos, True)
    if kind == ORTHOGRAPHIC:
        # tan_half holds the half extents of the view in world units.
        x = sx * tan_half[0] + shift[0]
        y = sy * tan_half[1] + shift[1]
        o, d, near = _orthographic(x, y, lens, u3, u4, clip[0])
        return _point(to_world, o), _direction(to_world, d), near, clip[1] - clip[0], True
    # Panoramic: Cycles' (u, v) in [0, 1]^2 over the image, v up.
    u = 0.5 * (sx + 1.0)
    v = 0.5 * (sy + 1.0)
    d, ok = panorama_direction(proj, u, v)
    if not ok:
        return _origin(to_world), _direction(to_world, (0.0, 0.0, -1.0)), clip[0], 0.0, False
    o = (0.0, 0.0, 0.0)
    if lens[LENS_RADIUS] > 0.0:
        # The lens' first axis follows the panoramic space's x, wherever that is here.
        axis = (1.0, 0.0, 0.0) if kind == MIRRORBALL else (0.0, 0.0, -1.0)
        o, d = _thin_lens_panorama(d, axis, lens, u3, u4)
    return _point(to_world, o), _direction(to_world, d), clip[0], clip[1] - clip[0], True


@inline_kernel
def _thin_lens_perspective(x, y, lens, u3, u4):
    """Cycles' perspective depth of field: from a point on the lens to where the pinhole
    ray (x, y, -1) meets the plane of focus at depth f. Camera space."""
    lx, ly = aperture_point(lens, u3, u4)
    f = lens[LENS_FOCUS]
    return (lx, ly, 0.0), _normalized((x * f - lx, y * f - ly, -f))


@inline_kernel
def _orthographic(x, y, lens, u3, u4, near):
    """Cycles' orthographic ray from (x, y) on the view plane, with its depth of field: from
    (x, y) + the lens point toward (x, y) at depth f. Returns (origin, direction, distance
    from the origin to the near clip along the ray)."""
    if lens[LENS_RADIUS] <= 0.0:
        return (x, y, 0.0), (0.0, 0.0, -1.0), near
    lx, ly = aperture_point(lens, u3, u4)
    f = lens[LENS_FOCUS]
    d = _normalized((-lx, -ly, -f))
    # Cycles starts the ray where it crosses the near clip plane: near / cos along it.
    return (x + lx, y + ly, 0.0), d, near / -d[2]


@inline_kernel
def _thin_lens_panorama(d, a, lens, u3, u4):
    """Cycles' panoramic depth of field: the lens is the disk across direction d, its first
    axis U from the panoramic space's x axis a, focused at distance f along d."""
    lx, ly = aperture_point(lens, u3, u4)
    f = lens[LENS_FOCUS]
    # U = normalize(a - (a . d) d); V = d x U (the spaces differ by rotations: same sense).
    a_dot_d = a[0] * d[0] + a[1] * d[1] + a[2] * d[2]
    ux, uy, uz = a[0] - a_dot_d * d[0], a[1] - a_dot_d * d[1], a[2] - a_dot_d * d[2]
    norm = math.sqrt(ux * ux + uy * uy + uz * uz)
    if norm <= 0.0:  # d along the axis: any perpendicular will do
        ux, uy, uz, norm = d[1], d[2], d[0], 1.0
    ux, uy, uz = ux / norm, uy / norm, uz / norm
    vx = d[1] * uz - d[2] * uy
    vy = d[2] * ux - d[0] * uz
    vz = d[0] * uy - d[1] * ux
    o = (ux * lx + vx * ly, uy * lx + vy * ly, uz * lx + vz * ly)
    return o, _normalized((d[0] * f - o[0], d[1] * f - o[1], d[2] * f - o[2]))


@inline_kernel
def aperture_point(lens, u, v):
    """Cycles' camera_sample_aperture: a point on the unit disk (concentric map) or the unit
    regular polygon of `blades` corners, x divided by the aperture ratio, times the radius."""
    blades = lens[LENS_BLADES]
    if blades < 3.0:
        x, y = concentric_disk(u, v)
    else:
        x, y = regular_polygon(blades, lens[LENS_ROTATION], u, v)
    radius = lens[LENS_RADIUS]
    return x * lens[LENS_INV_RATIO] * radius, y * radius


@inline_kernel
def concentric_disk(u, v):
    """Cycles' sample_uniform_disk (Shirley-Chiu concentric mapping)."""
    a = 2.0 * u - 1.0
    b = 2.0 * v - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if a * a > b * b:
        r = a
        phi = 0.25 * math.pi * (b / a)
    else:
        r = b
        phi = 0.5 * math.pi - 0.25 * math.pi * (a / b)
    return r * math.cos(phi), r * math.sin(phi)


@inline_kernel
def regular_polygon(corners, rotation, u, v):
    """Cycles' regular_polygon_sample: pick a corner's triangle with u, a uniform point in
    it, rotated to the corner; corners lie on the unit circle."""
    corner = math.floor(u * corners)
    u = u * corners - corner
    u = math.sqrt(u)
    v = v * u
    u = 1.0 - u
    angle = math.pi / corners
    px = (u + v) * math.cos(angle)
    py = (u - v) * math.sin(angle)
    rotation += corner * 2.0 * angle
    cr = math.cos(rotation)
    sr = math.sin(rotation)
    return cr * px - sr * py, sr * px + cr * py


@kernel
def panorama_direction(proj, u, v):
    """Camera-space direction of image point (u, v) in [0, 1]^2 (v up) for the panoramic
    types (Cycles' panorama_to_direction), and whether there is one."""
    kind = int(proj[PROJ_KIND])
    if kind == EQUIRECTANGULAR:
        # Cycles' equirectangular range: phi falls from -lon_min at the left edge to
        # -lon_max at the right, theta (from the zenith) from pi/2 - lat_min at the bottom.
        lon_min, lon_max = proj[PROJ_LON_MIN], proj[PROJ_LON_MAX]
        lat_min, lat_max = proj[PROJ_LAT_MIN], proj[PROJ_LAT_MAX]
        phi = -lon_min - u * (lon_max - lon_min)
        theta = 0.5 * math.pi - lat_min - v * (lat_max - lat_min)
        st = math.sin(theta)
        # Panoramic (sin t cos p, sin t sin p, cos t) is (-y, z, -x) here.
        return (-st * math.sin(phi), math.cos(theta), -st * math.cos(phi)), True
    if kind == MIRRORBALL:
        # The ball's point (x, y, z) seen from -y, and the reflection of the view about it.
        bx = 2.0 * u - 1.0
        bz = 2.0 * v - 1.0
        if bx * bx + bz * bz > 1.0:
            return (0.0, 0.0, -1.0), False
        by = -math.sqrt(max(1.0 - bx * bx - bz * bz, 0.0))
        rx, ry, rz = -2.0 * by * bx, 1.0 - 2.0 * by * by, -2.0 * by * bz
        # The centre reflects -Y: the mirror ball space's forward, our -Z.
        return (rx, rz, ry), True
    if kind == FISHEYE_EQUIDISTANT:
        a = 2.0 * (u - 0.5)
        b = 2.0 * (v - 0.5)
        r = math.sqrt(a * a + b * b)
        if r > 1.0:
            return (0.0, 0.0, -1.0), False
        return _fisheye(r * proj[PROJ_FISHEYE_FOV] * 0.5, a, b, r), True
    # FISHEYE_EQUISOLID: r = 2 lens sin(theta / 2) on a sensor in mm.
    a = (u - 0.5) * proj[PROJ_SENSOR_W]
    b = (v - 0.5) * proj[PROJ_SENSOR_H]
    focal = proj[PROJ_FISHEYE_LENS]
    r = math.sqrt(a * a + b * b)
    if r > 2.0 * focal * math.sin(proj[PROJ_FISHEYE_FOV] * 0.25):
        return (0.0, 0.0, -1.0), False
    return _fisheye(2.0 * math.asin(min(r / (2.0 * focal), 1.0)), a, b, r), True


@inline_kernel
def _fisheye(theta, a, b, r):
    """Direction at angle theta from the view axis, toward (a, b) on the image."""
    if r <= 0.0:
        return (0.0, 0.0, -1.0)
    s = math.sin(theta) / r
    return (a * s, b * s, -math.cos(theta))


@inline_kernel
def _normalized(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n)


@inline_kernel
def _origin(m):
    return (m[0, 3], m[1, 3], m[2, 3])


@inline_kernel
def _point(m, p):
    return (m[0, 0] * p[0] + m[0, 1] * p[1] + m[0, 2] * p[2] + m[0, 3],
            m[1, 0] * p[0] + m[1, 1] * p[1] + m[1, 2] * p[2] + m[1, 3],
            m[2, 0] * p[0] + m[2, 1] * p[1] + m[2, 2] * p[2] + m[2, 3])


@inline_kernel
def _direction(m, d):
    return _normalized((m[0, 0] * d[0] + m[0, 1] * d[1] + m[0, 2] * d[2],
                        m[1, 0] * d[0] + m[1, 1] * d[1] + m[1, 2] * d[2],
                        m[2, 0] * d[0] + m[2, 1] * d[1] + m[2, 2] * d[2]))
