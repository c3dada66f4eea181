"""A mirror-ball environment image sampled on its own cells (renderer.lights.environment
picks the cell; this module maps ball points to directions and gives their pdf).

The mapping (Cycles' direction_to_mirrorball, environment_lookup.mirror_ball_uv). A unit
direction m in the map's frame lands on the ball image at (u, v), or in ball coordinates
(a, b) = 2 (u, v) - 1 in the unit disk:
    (a, b) = (m_x, m_z) / sqrt(2 (1 - m_y)),
so s = a^2 + b^2 = (1 - m_y^2) / (2 (1 - m_y)) = (1 + m_y) / 2, and back
    m = (2 sqrt(1 - s) a, 2 s - 1, 2 sqrt(1 - s) b)     (|m|^2 = 4 (1 - s) s + (2 s - 1)^2 = 1).
Jacobian. With psi the angle of m from -Y (the image's centre) and phi its angle about Y,
m_y = -cos psi, so s = (1 - cos psi) / 2 = sin^2(psi / 2): the disk's radius is
r = sin(psi / 2) and its polar angle is phi ((a, b) is along (m_x, m_z)). Its area element
    dA = r dr dphi = sin(psi / 2) cos(psi / 2) / 2 dpsi dphi = sin(psi) dpsi dphi / 4 = d omega / 4:
the ball is an equal-area map of the sphere (Lambert's azimuthal projection from -Y), the
disk's area pi holding the sphere's 4 pi. As dA = da db = 4 du dv, d omega = 16 du dv: a
density p(u, v) over the image is p(u, v) / 16 per steradian, with no factor that varies
(unlike the equirectangular map's sin theta).

The density is a mixture of two techniques, each normalised over the sphere:
  cells  (probability 1 - rim): piecewise constant over the image's cells wholly inside the
         disk, in proportion to f (the cells' mean luminance; environment_map._ball_density);
  rim    (probability rim): uniform over the ring s in [s_min, 1], which holds every part of
         the disk the cells miss: uniform in s and in the polar angle is uniform in area, so
         in solid angle (a spherical cap of 4 pi (1 - s_min) steradians about +Y).
A direction's pdf is the sum of the two: INFO_NORM (which carries 1 - rim) x f / 16, plus
rim / (4 pi (1 - s_min)) if s >= s_min.
"""

from __future__ import annotations

import math

from ..kernels import inline_kernel
from .environment_lookup import ENV_FUNC, ENV_INFO, INFO_NORM, INFO_RIM_PROB, INFO_RIM_S, from_map

INV_16 = 1.0 / 16.0  # d omega = 16 du dv


@inline_kernel
def ball_pdf(env, a, b):
    """Solid-angle pdf, both techniques, of the direction at ball point (a, b)."""
    info = env[ENV_INFO]
    func = env[ENV_FUNC]
    h, w = func.shape[0], func.shape[1]
    j = min(max(int((a + 1.0) * 0.5 * w), 0), w - 1)
    i = min(max(int((b + 1.0) * 0.5 * h), 0), h - 1)
    pdf = func[i, j] * info[INFO_NORM] * INV_16
    rim, s_min = info[INFO_RIM_PROB], info[INFO_RIM_S]
    if rim > 0.0 and a * a + b * b >= s_min:
        pdf += rim / (4.0 * math.pi * (1.0 - s_min))
    return pdf


@inline_kernel
def rim_point(env, u1, t):
    """Ball point (a, b) uniform over the ring s in [s_min, 1]; t uniform in [0, 1)."""
    s_min = env[ENV_INFO][INFO_RIM_S]
    r = math.sqrt(s_min + (1.0 - s_min) * t)
    phi = 2.0 * math.pi * u1
    return r * math.cos(phi), r * math.sin(phi)


@inline_kernel
def ball_direction(env, a, b):
    """World direction (unit) of ball point (a, b) in the disk."""
    s = min(a * a + b * b, 1.0)
    c = 2.0 * math.sqrt(1.0 - s)
    return from_map(env, (c * a, 2.0 * s - 1.0, c * b))
