"""Perspective pinhole camera rays (box filter of width 1: uniform jitter in the pixel)."""

import math

from renderer.kernels import kernel


@kernel
def camera_ray(to_world, tan_half, shift, px, py, width, height, u1, u2):
    """Ray through pixel (px, py), row 0 at the top. Returns (origin, unit direction).

    The camera looks down its local -Z with +Y up; the image plane at distance 1 spans
    [-tan_half, tan_half] plus the lens shift.
    """
    x = (2.0 * (px + u1) / width - 1.0) * tan_half[0] + shift[0]
    y = (1.0 - 2.0 * (py + u2) / height) * tan_half[1] + shift[1]
    dx = to_world[0, 0] * x + to_world[0, 1] * y - to_world[0, 2]
    dy = to_world[1, 0] * x + to_world[1, 1] * y - to_world[1, 2]
    dz = to_world[2, 0] * x + to_world[2, 1] * y - to_world[2, 2]
    n = math.sqrt(dx * dx + dy * dy + dz * dz)
    return (to_world[0, 3], to_world[1, 3], to_world[2, 3]), (dx / n, dy / n, dz / n)
