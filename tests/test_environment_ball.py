"""A mirror-ball environment sampled on its own image cells (renderer.lights.environment_ball):
the mapping's Jacobian, the pdf's normalisation over the sphere, and samples that follow
the pdf they report.

Tolerances: float rounding for the exact quantities, z-scores on the estimators' own
variance (Z, as tests/test_environment.py) for the Monte Carlo ones.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit
from test_environment import H, W, Z, rotation_z, sky_map

from renderer.lights.environment import environment_radiance, sample_environment
from renderer.lights.environment_ball import ball_direction
from renderer.lights.environment_lookup import INFO_RIM_PROB, mirror_ball_uv, to_map
from renderer.lights.environment_map import build_environment, mean_radiance
from renderer.scene import LUMINANCE, Environment

N_SAMPLES = 400_000
# The quadratures' grid over the ball image: a multiple of the distribution's cells (k x k
# per pixel for Linear, the pixels for Closest), 32 x 32 points per pixel.
ROWS, COLS = 32 * H, 32 * W
CASES = [(1.0, "linear"), (2.0e4, "linear"), (1.0, "closest"), (2.0e4, "closest")]


def ball_env(sun: float, interpolation: str = "linear"):
    return build_environment(Environment((1.0, 0.8, 1.2), sky_map(sun), projection="mirror_ball",
                                         interpolation=interpolation, to_world=rotation_z(40.0)))


@njit(cache=False)
def _ball_quadrature(env, rows, cols):
    """Midpoint rule over the ball's disk on a rows x cols grid of the image: per point the
    pdf and the radiance, times d omega = 16 du dv; points outside the
    disk count 0. Returns (integral of the pdf, integral of L (3,), pdf mass per point)."""
    d_omega = 16.0 / (rows * cols)
    mass = np.zeros((rows, cols))
    radiance = np.zeros(3)
    total = 0.0
    for i in range(rows):
        b = 2.0 * (i + 0.5) / rows - 1.0
        for j in range(cols):
            a = 2.0 * (j + 0.5) / cols - 1.0
            if a * a + b * b > 1.0:
                continue
            le, pdf = environment_radiance(env, ball_direction(env, a, b))
            mass[i, j] = pdf * d_omega
            total += mass[i, j]
            for c in range(3):
                radiance[c] += le[c] * d_omega
    return total, radiance, mass


@njit(cache=False)
def _draw(env, us):
    """Per sample: the ball point of its direction (u, v), the reported pdf, the pdf
    evaluated at its direction, its radiance."""
    out = np.empty((us.shape[0], 7))
    for k in range(us.shape[0]):
        d, le, pdf = sample_environment(env, us[k, 0], us[k, 1])
        m = to_map(env, d)
        out[k, 0], out[k, 1] = mirror_ball_uv(m)
        out[k, 2] = pdf
        out[k, 3] = environment_radiance(env, d)[1]
        out[k, 4], out[k, 5], out[k, 6] = le
    return out


def test_ball_is_an_equal_area_map_with_d_omega_16_du_dv():
    """The derivation in environment_ball: ball points go to unit directions that map back to
    them, and the area the directions sweep is 4 x the disk's (16 x the image's)."""
    env = ball_env(1.0)
    rng = np.random.default_rng(5)
    r, phi = np.sqrt(rng.random(200)) * 0.999, 2 * math.pi * rng.random(200)
    eps = 1e-6
    for a, b in zip(r * np.cos(phi), r * np.sin(phi)):
        m = np.array(to_map(env, ball_direction(env, a, b)))
        assert abs(np.linalg.norm(m) - 1.0) < 1e-12
        bu, bv = mirror_ball_uv(m)
        assert abs(2 * bu - 1 - a) < 1e-9 and abs(2 * bv - 1 - b) < 1e-9, (a, b)
        da = (np.array(ball_direction(env, a + eps, b)) - ball_direction(env, a - eps, b)) / (2 * eps)
        db = (np.array(ball_direction(env, a, b + eps)) - ball_direction(env, a, b - eps)) / (2 * eps)
        assert np.linalg.norm(np.cross(da, db)) == pytest.approx(4.0, rel=1e-5), (a, b)


@pytest.mark.parametrize("sun, interpolation", CASES)
def test_pdf_integrates_to_one_over_the_sphere(sun, interpolation):
    """The cells' part is constant on cells wholly inside the disk, which the sub-grid tiles
    exactly; only the rim's ring (uniform over s >= s_min) is cut by the grid, an error of
    about its probability x the ring's boundary cells / its cells (< 1e-2 x rim)."""
    env = ball_env(sun, interpolation)
    total, _, _ = _ball_quadrature(env, ROWS, COLS)
    rim = env[5][INFO_RIM_PROB]
    assert 0.0 < rim < 0.2, rim
    assert abs(total - 1.0) < 1e-2 * rim + 1e-9, (total, rim)


@pytest.mark.parametrize("sun, interpolation", CASES)
def test_samples_follow_the_pdf_they_report(sun, interpolation):
    env = ball_env(sun, interpolation)
    _, radiance, mass = _ball_quadrature(env, ROWS, COLS)
    out = _draw(env, np.random.default_rng(11).random((N_SAMPLES, 2)))
    assert np.isfinite(out).all() and (out[:, 2] > 0).all()
    # The pdf a sample reports is the pdf of its direction (what MIS weighs at escape).
    same = np.isclose(out[:, 2], out[:, 3], rtol=1e-9)
    assert same.mean() > 0.9999, same.mean()
    # E[1 / pdf] is the solid angle where the pdf is positive (everywhere: the map has no
    # black texel), and E[L / pdf] the integral of L, by the quadrature.
    for value, want in ((1.0 / out[:, 2], 4.0 * math.pi),
                        (out[:, 4:] @ np.asarray(LUMINANCE) / out[:, 2], radiance @ np.asarray(LUMINANCE))):
        se = value.std(ddof=1) / math.sqrt(N_SAMPLES)
        assert abs(value.mean() - want) < Z * se + 1e-4 * want, (value.mean(), want, se)
    # Chi-square of the samples' image pixels against the pdf's mass over each pixel.
    pixel = (np.clip((out[:, 1] * H).astype(int), 0, H - 1) * W
             + np.clip((out[:, 0] * W).astype(int), 0, W - 1))
    counts = np.bincount(pixel, minlength=H * W)
    expected = N_SAMPLES * mass.reshape(H, ROWS // H, W, COLS // W).sum(axis=(1, 3)).ravel()
    big = expected >= 10
    observed = np.append(counts[big], counts[~big].sum())
    wanted = np.append(expected[big], expected[~big].sum())
    chi2 = ((observed - wanted) ** 2 / wanted).sum()
    dof = observed.size - 1
    assert (chi2 - dof) / math.sqrt(2 * dof) < Z, (chi2, dof)


@pytest.mark.parametrize("sun, interpolation", CASES)
def test_mean_radiance_is_the_integral_over_the_ball(sun, interpolation):
    """The light's power (mean_radiance, from the pixels and the part of each in the disk)
    against the quadrature of what the kernels read; they differ only where Linear spreads
    a pixel across the rim."""
    environment = Environment((1.0, 0.8, 1.2), sky_map(sun), projection="mirror_ball",
                              interpolation=interpolation, to_world=rotation_z(40.0))
    _, radiance, _ = _ball_quadrature(build_environment(environment), ROWS, COLS)
    np.testing.assert_allclose(mean_radiance(environment), radiance / (4.0 * math.pi), rtol=2e-3)
