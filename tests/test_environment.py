"""The environment map light (renderer/lights/environment.py): Cycles' direction mapping,
the texture read, the importance-sampling distribution, and renders against quadrature.

Tolerances are z-scores on the estimators' own variance, or float rounding for exact maps.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from examples.scenes import quad
from helpers.films import render_film
from renderer.compile import compile_scene
from renderer.errors import SceneError
from renderer.lights.environment import environment_radiance, sample_environment
from renderer.lights.environment_lookup import lookup, mirror_ball_uv, uv_to_direction
from renderer.lights.environment_map import MAP_COLUMNS, _pixel_density, build_environment
from renderer.scene import (
    ENV_INTERPOLATIONS,
    LUMINANCE,
    Camera,
    Environment,
    IntegratorSettings,
    Lobe,
    Material,
    Mesh,
    Scene,
)
from renderer.scene import Film as FilmSettings
from renderer.scenefile import load_scene, save_scene
from renderer.validate import validate_scene

Z = 5.0  # z-score bound, as tests/test_render_core.py
H, W = 32, 64
SUN = (24, 10)  # the sun's pixel (row from the bottom, column): 45 degrees up
SUN_RADIANCE = 2.0e4
ALBEDO = 0.5


def sky_map(sun: float = SUN_RADIANCE) -> np.ndarray:
    """A coloured sky brightening toward the zenith, a dim ground, and a one-pixel sun."""
    v = (np.arange(H) + 0.5) / H
    u = (np.arange(W) + 0.5) / W
    z = -np.cos(math.pi * v)  # v = 1 - theta / pi
    sky = np.clip(z, 0.0, None)[:, None] * (1.0 + 0.5 * np.sin(2 * math.pi * u))[None, :]
    image = np.empty((H, W, 3), np.float32)
    image[..., 0] = 0.05 + 0.3 * sky
    image[..., 1] = 0.05 + 0.5 * sky
    image[..., 2] = 0.08 + 0.9 * sky
    image[SUN] = (sun, 0.9 * sun, 0.7 * sun)
    return image


def rotation_z(degrees: float) -> np.ndarray:
    a = math.radians(degrees)
    m = np.eye(4)
    m[:2, :2] = [[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]]
    return m


@njit(cache=False)
def _samples(env, us):
    out = np.empty((us.shape[0], 5))
    for k in range(us.shape[0]):
        d, le, pdf = sample_environment(env, us[k, 0], us[k, 1])
        _, pdf_eval = environment_radiance(env, d)
        out[k, 0], out[k, 1], out[k, 2] = d
        out[k, 3] = pdf
        out[k, 4] = pdf_eval
    return out


@njit(cache=False)
def _radiance_grid(env, n_v, n_u):
    """Radiance and pdf at the centres of an n_v x n_u grid over (u, v), and sin theta."""
    rad = np.empty((n_v, n_u, 3))
    pdf = np.empty((n_v, n_u))
    sin_t = np.empty((n_v, n_u))
    z = np.empty((n_v, n_u))
    for i in range(n_v):
        for j in range(n_u):
            d, s = uv_to_direction(env, (j + 0.5) / n_u, (i + 0.5) / n_v)
            le, p = environment_radiance(env, d)
            rad[i, j, 0], rad[i, j, 1], rad[i, j, 2] = le
            pdf[i, j] = p
            sin_t[i, j] = s
            z[i, j] = d[2]
    return rad, pdf, sin_t, z


def test_direction_mapping_is_cycles_equirectangular():
    """u = 1/2 looks down +X, u = 1/4 down +Y (atan2 grows toward -u), v = 1 is the zenith;
    a rotation in to_world turns the map."""
    image = np.zeros((H, W, 3), np.float32)
    env = build_environment(Environment((1.0, 1.0, 1.0), image))
    cases = [((0.5, 0.5), (1.0, 0.0, 0.0)), ((0.25, 0.5), (0.0, 1.0, 0.0)),
             ((0.5, 0.999999), (0.0, 0.0, 1.0))]
    for (u, v), want in cases:
        d, _ = uv_to_direction(env, u, v)
        assert np.allclose(d, want, atol=1e-5), (u, v, d)
    turned = build_environment(Environment((1.0, 1.0, 1.0), image, to_world=rotation_z(90.0)))
    d, _ = uv_to_direction(turned, 0.5, 0.5)  # the map's +X is the world's +Y
    assert np.allclose(d, (0.0, 1.0, 0.0), atol=1e-6)


def test_mirror_ball_mapping_is_cycles():
    """The ball's centre looks down -Y; straight up (+Z) is at radius sin 45 degrees above the
    centre; the read is clamped at the rim."""
    assert mirror_ball_uv((0.0, -1.0, 0.0)) == pytest.approx((0.5, 0.5))
    assert mirror_ball_uv((0.0, 0.0, 1.0)) == pytest.approx((0.5, 0.5 + 0.5 * math.sqrt(0.5)))
    assert mirror_ball_uv((1.0, 0.0, 0.0)) == pytest.approx((0.5 + 0.5 * math.sqrt(0.5), 0.5))
    image = sky_map()
    env = build_environment(Environment((1.0, 1.0, 1.0), image, projection="mirror_ball"))
    d, _ = uv_to_direction(env, 0.75, 0.5)  # equirectangular (u, v) of -Y: the ball's centre
    assert np.allclose(d, (0.0, -1.0, 0.0), atol=1e-9)
    centre = 0.25 * (image[15, 31] + image[15, 32] + image[16, 31] + image[16, 32])
    assert np.allclose(lookup(env, 0.75, 0.5), centre, rtol=1e-6)


def test_linear_and_closest_reads_hit_pixel_values_at_centres():
    image = sky_map()
    for interpolation in ("linear", "closest"):
        env = build_environment(Environment((2.0, 1.0, 0.5), image, interpolation=interpolation))
        for i, j in [(0, 0), (5, 63), SUN, (31, 17)]:
            got = lookup(env, (j + 0.5) / W, (i + 0.5) / H)
            assert np.allclose(got, image[i, j] * (2.0, 1.0, 0.5), rtol=1e-6), (interpolation, i, j)
    # Linear halfway between two columns is their mean, also across the seam at u = 0.
    env = build_environment(Environment((1.0, 1.0, 1.0), image))
    assert np.allclose(lookup(env, 0.0, 5.5 / H), 0.5 * (image[5, 0] + image[5, W - 1]), rtol=1e-6)


def test_pdf_integrates_to_one_and_samples_follow_it():
    env = build_environment(Environment((1.0, 1.0, 1.0), sky_map(), to_world=rotation_z(30.0)))
    # The pdf times sin theta is constant on each cell of the distribution (k x k per pixel
    # of this small map): the midpoint rule on the cells is exact.
    rows, cols = env[1].shape
    assert (rows, cols) == (H * MAP_COLUMNS // W, MAP_COLUMNS)
    _, pdf, sin_t, _ = _radiance_grid(env, rows, cols)
    integral = (pdf * sin_t).sum() * (2 * math.pi / cols) * (math.pi / rows)
    assert abs(integral - 1.0) < 1e-6, integral

    n = 400_000
    us = np.random.default_rng(1).random((n, 2))
    out = _samples(env, us)
    assert np.isfinite(out).all()
    # The pdf a sample reports is the pdf of its direction (what MIS weighs at escape).
    same = np.isclose(out[:, 3], out[:, 4], rtol=1e-4)
    assert same.mean() > 0.999, same.mean()
    # Chi-square of the samples' pixels against the distribution's probabilities.
    local = out[:, :3] @ env[4].T  # world -> map
    u = 0.5 - np.arctan2(local[:, 1], local[:, 0]) / (2 * math.pi)
    v = 1.0 - np.arccos(np.clip(local[:, 2], -1, 1)) / math.pi
    cell = np.clip((v * H).astype(int), 0, H - 1) * W + np.clip((u * W).astype(int), 0, W - 1) % W
    counts = np.bincount(cell, minlength=H * W)
    per_pixel = env[1].reshape(H, rows // H, W, cols // W).sum(axis=(1, 3))
    expected = n * per_pixel.ravel() / per_pixel.sum()
    big = expected >= 10
    observed = np.append(counts[big], counts[~big].sum())
    wanted = np.append(expected[big], expected[~big].sum())
    chi2 = ((observed - wanted) ** 2 / wanted).sum()
    dof = observed.size - 1
    z = (chi2 - dof) / math.sqrt(2 * dof)
    assert z < Z, (chi2, dof)
    # The one-pixel sun holds most of the power and gets most of the samples.
    assert counts[SUN[0] * W + SUN[1]] > 0.3 * n


def test_small_maps_are_sampled_on_cells_that_follow_linear_interpolation():
    """A map narrower than MAP_COLUMNS / 2 gets k x k cells per pixel (Cycles samples its
    background on a 1024-column map): each cell's density is the mean of the bilinear
    luminance over it (checked by a 40 x 40 midpoint rule, x sin theta at the cell's row),
    and the cells of a pixel average to the pixel's own mean as a map of wide images has it
    (weights 3/4 and 1/8 of it and its neighbours along each axis)."""
    image = sky_map()
    lum = image.astype(np.float64) @ np.asarray(LUMINANCE)
    fine = _pixel_density(image, ENV_INTERPOLATIONS["linear"])
    k = MAP_COLUMNS // W
    assert fine.shape == (k * H, k * W)
    sin_rows = np.sin(math.pi * (np.arange(k * H) + 0.5) / (k * H))
    cells = fine / sin_rows[:, None]

    def bilinear(u, v):
        x, y = u * W - 0.5, v * H - 0.5
        j0, i0 = np.floor(x).astype(int), np.floor(y).astype(int)
        tx, ty = x - j0, y - i0
        i1, i0 = np.clip(i0 + 1, 0, H - 1), np.clip(i0, 0, H - 1)
        j1, j0 = (j0 + 1) % W, j0 % W
        return ((1 - tx) * (1 - ty) * lum[i0, j0] + tx * (1 - ty) * lum[i0, j1]
                + (1 - tx) * ty * lum[i1, j0] + tx * ty * lum[i1, j1])

    t = (np.arange(40) + 0.5) / 40
    for i, j in ((SUN[0] * k + 3, SUN[1] * k + 11), (0, 5), (k * H - 1, k * W - 1), (100, 400)):
        u, v = np.meshgrid((j + t) / (k * W), (i + t) / (k * H))
        assert abs(bilinear(u, v).mean() - cells[i, j]) <= 1e-9 * max(1.0, cells[i, j]), (i, j)
    pixel = 0.75 * lum + 0.125 * (np.roll(lum, 1, axis=1) + np.roll(lum, -1, axis=1))
    below, above = np.concatenate([pixel[:1], pixel[:-1]]), np.concatenate([pixel[1:], pixel[-1:]])
    pixel = 0.75 * pixel + 0.125 * (below + above)
    np.testing.assert_allclose(cells.reshape(H, k, W, k).mean(axis=(1, 3)), pixel, rtol=1e-12)


def _plane_scene(env: Environment, sampling: str, spp: int = 64) -> Scene:
    v, i = quad((0, 0, 0), (50, 0, 0), (0, 50, 0))  # faces +Z, large enough to see the whole sky
    to_world = np.eye(4)
    to_world[2, 3] = 1.0  # one unit up, looking down -Z
    return Scene(camera=Camera(to_world, projection="orthographic", ortho_scale=2.0),
                 film=FilmSettings(16, 16),
                 integrator=IntegratorSettings(spp=spp, max_bounces=0, sampling=sampling, seed=3),
                 materials=[Material("floor", [Lobe("diffuse", color=(ALBEDO,) * 3)])],
                 meshes=[Mesh("floor", v, i, ["floor"])], environment=env)


def _plane_radiance(env: Environment) -> np.ndarray:
    """albedo / pi x the irradiance on an upward plane: the integral of L cos over the upper
    hemisphere, by the midpoint rule on a grid 32x finer than the map (L is bilinear in
    the map's pixels, which a mirror ball shrinks toward its rim)."""
    tables = build_environment(env)
    rad, _, sin_t, z = _radiance_grid(tables, 32 * H, 32 * W)
    weight = np.clip(z, 0.0, None) * sin_t * (2 * math.pi / (32 * W)) * (math.pi / (32 * H))
    return ALBEDO / math.pi * np.einsum("ijc,ij->c", rad, weight)


def _check_against(film, want) -> float:
    m, var = film.mean(), film.variance_of_mean()
    k = m.shape[0]
    for c in range(3):
        se = math.sqrt(var[:, c].sum()) / k
        assert abs(m[:, c].mean() - want[c]) <= Z * se + 1e-5 * want[c], (c, m[:, c].mean(), want[c], se)
    return float(var.sum() / k**2)


@pytest.mark.parametrize("projection", ["equirectangular", "mirror_ball"])
def test_plane_under_an_hdri_matches_quadrature_for_every_sampling(projection):
    """Direct light from a map with a small, very bright sun on a diffuse plane: light
    sampling, BSDF sampling and their MIS all give the quadrature's value, and MIS has far
    less variance than BSDF sampling alone (the sun found by importance, not by chance).
    The same image read as a mirror ball puts the sun elsewhere, and its distribution comes
    from the ball's own image cells (renderer.lights.environment_ball)."""
    env = Environment((1.0, 0.8, 1.2), sky_map(), projection=projection, to_world=rotation_z(40.0))
    want = _plane_radiance(env)
    variance = {s: _check_against(render_film(_plane_scene(env, s)), want) for s in ("mis", "nee", "bsdf")}
    assert variance["mis"] < 0.05 * variance["bsdf"], variance


def test_constant_world_compiles_no_map_and_scene_files_keep_the_map(tmp_path):
    scene = _plane_scene(Environment((0.5, 0.5, 0.5)), "mis")
    assert compile_scene(scene).environment is None
    scene.environment = Environment((1.0, 2.0, 3.0), sky_map(), interpolation="closest",
                                    to_world=rotation_z(15.0))
    save_scene(scene, tmp_path)
    back = load_scene(tmp_path).environment
    assert np.array_equal(back.radiance_map, scene.environment.radiance_map)
    assert back.interpolation == "closest" and np.allclose(back.to_world, rotation_z(15.0))
    assert compile_scene(load_scene(tmp_path)).environment is not None


@pytest.mark.parametrize("change, needle", [
    (dict(radiance_map=-sky_map()), "must not be negative"),
    (dict(radiance_map=np.zeros((4, 4), np.float32)), "(height, width, 3)"),
    (dict(radiance_map=sky_map(), interpolation="cubic"), "unknown interpolation"),
    (dict(radiance_map=sky_map(), projection="cube"), "unknown projection"),
    (dict(radiance_map=sky_map(), to_world=np.diag([2.0, 1.0, 1.0, 1.0])), "not orthogonal"),
    (dict(radiance_map=sky_map(1e30)), "at most"),
])
def test_bad_maps_are_named_errors(change, needle):
    scene = _plane_scene(Environment((1.0, 1.0, 1.0), **change), "mis")
    with pytest.raises(SceneError, match="environment") as error:
        validate_scene(scene)
    assert needle in str(error.value)
