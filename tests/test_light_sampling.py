"""Triangle lights sampled by solid angle (renderer/lights/spherical_triangle.py).

The sampler must put every direction on the triangle and be uniform in solid angle: the
integral of a smooth function over the spherical triangle, estimated with pdf 1 / Omega,
must agree with the area-sampling estimate of the same integral within their combined
standard error (z-score), also for grazing and near views.
"""

import math

import numpy as np
import pytest
from numba import njit

from renderer.lights.spherical_triangle import MIN_SOLID_ANGLE, sample_direction, solid_angle, use_solid_angle

Z_MAX = 4.5  # two-sided p ~ 7e-6 per check
P0, P1, P2 = (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.2, 0.9, 0.0)
VIEWS = [(0.3, 0.3, 0.5), (0.3, 0.3, 0.001), (2.0, 0.3, 0.01), (-0.5, -0.5, 0.02), (3.0, 3.0, -0.05),
         (0.2, -1.0, 0.003), (0.4, 0.2, -2.0)]


@njit(cache=False)
def _sample_many(x, us):
    omega = solid_angle(x, P0, P1, P2)
    out = np.empty((us.shape[0], 3))
    for i in range(us.shape[0]):
        w = sample_direction(x, P0, P1, P2, omega, us[i, 0], us[i, 1])
        out[i, 0] = w[0]
        out[i, 1] = w[1]
        out[i, 2] = w[2]
    return omega, out


def _hit_points(x: np.ndarray, dirs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t = -x[2] / dirs[:, 2]  # the triangle lies in z = 0
    return x + dirs * t[:, None], t


def _barycentric(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a, b, c = map(np.array, (P0, P1, P2))
    m = np.stack([b - a, c - a], axis=1)[:2]
    b12 = np.linalg.solve(m, (points - a)[:, :2].T)
    return b12[0], b12[1]


def _g(points: np.ndarray) -> np.ndarray:
    """A smooth positive function on the light (varying emission)."""
    return 1.0 + points[:, 0] + 0.5 * np.sin(3.0 * points[:, 1])


@pytest.mark.parametrize("view", VIEWS)
def test_directions_land_on_the_triangle(view):
    x = np.array(view)
    _, dirs = _sample_many(view, np.random.default_rng(1).random((20000, 2)))
    points, t = _hit_points(x, dirs)
    b1, b2 = _barycentric(points)
    assert np.all(t > 0)
    assert np.all((b1 > -1e-6) & (b2 > -1e-6) & (b1 + b2 < 1 + 1e-6))
    assert np.allclose(np.linalg.norm(dirs, axis=1), 1.0, atol=1e-9)


@pytest.mark.parametrize("view", VIEWS)
def test_uniform_in_solid_angle(view):
    """E[g(hit) |cos_l| / r^2 ... ] the same integral two ways: the irradiance-like
    integral of g over the triangle, int g(y) cos_x cos_l / r^2 dA = int g cos_x dOmega."""
    rng = np.random.default_rng(7)
    x = np.array(view)
    n = 200_000
    omega, dirs = _sample_many(view, rng.random((n, 2)))
    points, _ = _hit_points(x, dirs)
    f_solid = omega * _g(points) * np.abs(dirs[:, 2])
    su = np.sqrt(rng.random(n))
    r2 = rng.random(n)
    a, b, c = map(np.array, (P0, P1, P2))
    ys = a + np.outer(1 - su, b - a) + np.outer(r2 * su, c - a)
    d = ys - x
    dist2 = np.einsum("ij,ij->i", d, d)
    cos = np.abs(d[:, 2]) / np.sqrt(dist2)
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a))
    f_area = area * _g(ys) * cos * cos / dist2
    se = math.hypot(f_solid.std() / math.sqrt(n), f_area.std() / math.sqrt(n))
    z = (f_solid.mean() - f_area.mean()) / se
    assert abs(z) < Z_MAX, f"solid {f_solid.mean():.6g} area {f_area.mean():.6g} z {z:.2f}"
    # and the solid angle itself: the area estimate of int cos_l / r^2 dA
    omega_area = area * cos / dist2
    z = (omega - omega_area.mean()) / (omega_area.std() / math.sqrt(n))
    assert abs(z) < Z_MAX


def test_solid_angle_of_a_face_seen_from_a_cube_centre():
    """Two triangles making one face of a cube subtend 4 pi / 6 from its centre."""
    x = (0.5, 0.5, 0.5)
    total = solid_angle(x, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (1.0, 1.0, 0.0)) + solid_angle(
        x, (0.0, 0.0, 0.0), (1.0, 1.0, 0.0), (0.0, 1.0, 0.0))
    assert total == pytest.approx(4.0 * math.pi / 6.0, rel=1e-12)


def test_tiny_and_degenerate_views_fall_back_to_area_sampling():
    assert not use_solid_angle(solid_angle((1e4, 2e4, 3e3), P0, P1, P2))  # far away
    assert not use_solid_angle(solid_angle((2.0, 2.0, 0.0), P0, P1, P2))  # in its plane: 0
    assert not use_solid_angle(float("nan"))
    assert use_solid_angle(MIN_SOLID_ANGLE)
