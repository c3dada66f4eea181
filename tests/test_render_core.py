"""End-to-end checks of the surface path tracer against closed forms.

Every tolerance is a z-score on the estimator's own variance, measured from the film's
per-pixel second moments (Film.variance_of_mean), never a hand-widened margin.
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from examples.scenes import cornell_box, furnace_sphere, icosphere, point_light_plane, quad
from helpers.films import render_film
from renderer.film import Film
from renderer.imageio import read_exr
from renderer.scene import Camera, IntegratorSettings, Lobe, Material, Mesh, PointLight, Scene
from renderer.scene import Film as FilmSettings
from renderer.scenefile import save_scene

Z = 5.0  # z-score bound: a false alarm about once in 3.5 million checks


def assert_mean_close(film: Film, expected: np.ndarray, mask: np.ndarray | None = None) -> None:
    """Mean over the masked pixels agrees with the mean of `expected` within Z standard errors."""
    m = film.mean()
    var = film.variance_of_mean()
    if mask is None:
        mask = np.ones(m.shape[0], bool)
    k = mask.sum()
    for c in range(3):
        got = m[mask, c].mean()
        want = np.asarray(expected)[..., c][mask].mean() if np.ndim(expected) > 1 else expected[c]
        se = math.sqrt(var[mask, c].sum()) / k
        assert abs(got - want) <= Z * se + 1e-6 * abs(want), (c, got, want, se)


def test_white_furnace_sphere_under_uniform_environment():
    film = render_film(furnace_sphere(albedo=1.0, size=32, spp=64))
    assert np.isfinite(film.mean()).all()
    assert_mean_close(film, np.ones(3))


def test_emissive_furnace_inside_sphere_gives_le_over_one_minus_albedo():
    """Inside a closed sphere that emits Le and reflects albedo a: L = Le / (1 - a)."""
    v, i = icosphere(2, radius=2.0)
    a = 0.5
    scene = Scene(camera=Camera(np.eye(4), fov=60.0), film=FilmSettings(16, 16),
                  integrator=IntegratorSettings(spp=256, max_bounces=1000, rr_depth=0),
                  materials=[Material("wall", [Lobe("diffuse", color=(a, a, a))], emission=(1.0, 1.0, 1.0),
                                      emission_sides="both")],
                  meshes=[Mesh("sphere", v, i, ["wall"])])
    film = render_film(scene)
    assert_mean_close(film, np.full(3, 1.0 / (1.0 - a)))


def test_emitter_seen_directly_is_exactly_its_radiance():
    le = (3.0, 0.25, 7.5)
    v, i = quad((0, 0, -1), (5, 0, 0), (0, 5, 0))
    scene = Scene(camera=Camera(np.eye(4), fov=40.0), film=FilmSettings(8, 8),
                  integrator=IntegratorSettings(spp=4, max_bounces=0),
                  materials=[Material("light", [], emission=le)], meshes=[Mesh("light", v, i, ["light"])])
    film = render_film(scene)
    assert np.array_equal(film.mean().astype(np.float32), np.tile(np.float32(le), (64, 1)))


def test_diffuse_plane_under_point_light_matches_closed_form():
    """Pixel = albedo / pi * I * cos / d^2 averaged over the pixel's footprint."""
    size, h, intensity, albedo = 16, 1.0, 10.0, 0.5
    scene = point_light_plane(size=size, spp=64, height=h, intensity=intensity, albedo=albedo)
    film = render_film(scene)
    # The closed form averaged over each pixel by a fine deterministic grid of sub-pixel rays.
    n = 16
    sub = (np.arange(n) + 0.5) / n
    tan_half = math.tan(math.radians(30.0))
    px = (np.arange(size)[:, None] + sub[None, :]).ravel()
    xs = (2 * px / size - 1) * tan_half
    ys = (1 - 2 * px / size) * tan_half
    x, y = np.meshgrid(xs, ys)  # camera at z = 3 looking down -z: hits the plane at (3x, 3y, 0)
    hx, hy = 3 * x, 3 * y
    d2 = hx**2 + hy**2 + h**2
    e = albedo / math.pi * intensity * (h / np.sqrt(d2)) / d2
    e[(np.abs(hx) > 2) | (np.abs(hy) > 2)] = 0.0
    expected = e.reshape(size, n, size, n).mean(axis=(1, 3)).reshape(-1)
    m = film.mean()[:, 0]
    se = np.sqrt(film.variance_of_mean()[:, 0])
    inside = (expected > 0) & (se > 0)
    z = (m[inside] - expected[inside]) / se[inside]
    assert np.abs(z).max() < Z + 1.0, np.abs(z).max()  # many pixels: allow the max of ~200 normals
    # and pixels with no sub-pixel variance (all on the plane) agree to float precision
    exact = (expected > 0) & (se == 0)
    assert np.allclose(m[exact], expected[exact], rtol=1e-4)


def _two_lights_scene(sampling: str) -> Scene:
    """A small bright and a large dim light over smooth and rough surfaces."""
    floor_v, floor_i = quad((0, -1, 0), (0, 0, 2), (2, 0, 0))
    small_v, small_i = quad((-0.5, 0.9, 0), (0.05, 0, 0), (0, 0, 0.05))
    big_v, big_i = quad((0.6, 0.9, 0), (0.5, 0, 0), (0, 0, 0.5))
    ball_v, ball_i = icosphere(2, 0.35)
    cam = np.eye(4)
    cam[:3, 3] = (0, 0, 3.5)
    return Scene(
        camera=Camera(cam, fov=45.0), film=FilmSettings(24, 24),
        integrator=IntegratorSettings(spp=128, max_bounces=2, sampling=sampling, seed=7),
        materials=[
            Material("floor", [
                Lobe("diffuse", color=(0.6, 0.6, 0.6)),
                Lobe("rough_conductor", color=(0.9, 0.9, 0.9), roughness=0.3, weight=(0.3,) * 3),
            ]),
            Material("ball", [Lobe("rough_conductor", color=(0.9, 0.7, 0.5), roughness=0.05)]),
            Material("small", [], emission=(200.0, 200.0, 200.0)),
            Material("big", [], emission=(2.0, 2.0, 2.0)),
        ],
        meshes=[
            Mesh("floor", floor_v, floor_i, ["floor"]),
            Mesh("ball", ball_v + np.float32([0, -0.6, 0]), ball_i, ["ball"]),
            Mesh("small", small_v, small_i, ["small"]),
            Mesh("big", big_v, big_i, ["big"]),
        ],
    )


def test_nee_bsdf_and_mis_agree():
    films = {s: render_film(_two_lights_scene(s)) for s in ("mis", "nee", "bsdf")}
    means = {s: f.mean().mean(axis=0) for s, f in films.items()}
    ses = {s: np.sqrt(f.variance_of_mean().sum(axis=0)) / f.mean().shape[0] for s, f in films.items()}
    for a, b in (("mis", "nee"), ("mis", "bsdf"), ("nee", "bsdf")):
        se = np.sqrt(ses[a] ** 2 + ses[b] ** 2)
        assert (np.abs(means[a] - means[b]) <= Z * se).all(), (a, b, means[a], means[b], se)
    # MIS should not be noisier than the worse of the two strategies
    assert (ses["mis"] <= np.maximum(ses["nee"], ses["bsdf"])).all()


@pytest.mark.parametrize("lobes", [[], [Lobe("transparent", color=(1.0, 1.0, 1.0))]],
                         ids=["emitter", "transparent"])
def test_light_sampling_agrees_with_bsdf_sampling_for_a_low_wide_light(lobes):
    """A 1 x 0.5 one-sided emitter 0.5 above a diffuse floor, direct light only: shadow rays
    at grazing angles once hit the light itself (origin offset, direction from the surface
    point) and lost 80% of the light."""
    fv, fi = quad((0, 0, 0), (2, 0, 0), (0, 2, 0))
    lv, li = quad((0, 0, 0.5), (0, 0.25, 0), (0.5, 0, 0))
    cam = np.eye(4)
    cam[:3, 3] = (0, 0, 3)

    def film(sampling: str) -> Film:
        return render_film(Scene(
            camera=Camera(cam, fov=30.0), film=FilmSettings(16, 16),
            integrator=IntegratorSettings(spp=64, max_bounces=0, sampling=sampling, seed=3),
            materials=[Material("floor", [Lobe("diffuse", color=(0.8, 0.8, 0.8))]),
                       Material("light", lobes, emission=(5.0, 5.0, 5.0))],
            meshes=[Mesh("floor", fv, fi, ["floor"]), Mesh("light", lv, li, ["light"])]))

    nee, bsdf = film("nee"), film("bsdf")
    k = nee.mean().shape[0]
    se = np.sqrt(nee.variance_of_mean().sum(axis=0) + bsdf.variance_of_mean().sum(axis=0)) / k
    diff = nee.mean().mean(axis=0) - bsdf.mean().mean(axis=0)
    assert (np.abs(diff) <= Z * se).all(), (diff, se)


def test_same_image_for_any_batch_size_and_worker_count():
    scene = cornell_box(size=32, spp=4)
    scene.integrator.batch_size = 4096
    a = render_film(scene).mean()
    scene.integrator.batch_size = 1 << 16
    b = render_film(scene).mean()
    c = render_film(scene, workers=2).mean()
    assert np.allclose(a, b, rtol=1e-9, atol=1e-12)
    assert np.allclose(a, c, rtol=1e-9, atol=1e-12)


def test_point_light_scene_without_environment_is_black_where_unlit():
    scene = point_light_plane(size=8, spp=2)
    scene.lights = [PointLight((0.0, 0.0, -5.0), (10.0, 10.0, 10.0))]  # behind the plane
    film = render_film(scene)
    # The camera sees the front face; a reflection lobe gets nothing from the other side.
    assert np.all(film.mean() == 0.0)


def test_cli_renders_a_scene_folder_to_exr(tmp_path: Path):
    scene = cornell_box(size=16, spp=2)
    save_scene(scene, tmp_path / "scene")
    out = tmp_path / "out.exr"
    r = subprocess.run([sys.executable, "-m", "renderer", "render", str(tmp_path / "scene"), "-o", str(out),
                        "--spp", "2", "--workers", "1"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    img = read_exr(out)
    assert img.shape == (16, 16, 3) and np.isfinite(img).all() and img.mean() > 0
    assert out.with_suffix(".png").exists()
    assert "M samples/s" in r.stderr


@pytest.mark.parametrize("args, needle", [
    (["--spp", "0"], "--spp"),
    (["--max-bounces", "-1"], "--max-bounces"),
])
def test_cli_rejects_bad_options_in_one_line(tmp_path: Path, args, needle):
    save_scene(cornell_box(size=8, spp=1), tmp_path / "s")
    r = subprocess.run([sys.executable, "-m", "renderer", "render", str(tmp_path / "s"), "-o",
                        str(tmp_path / "o.exr"), *args], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and needle in r.stderr and "Traceback" not in r.stderr


def test_cli_reports_missing_scene_without_traceback(tmp_path: Path):
    r = subprocess.run([sys.executable, "-m", "renderer", "render", str(tmp_path / "nope"), "-o",
                        str(tmp_path / "o.exr")], capture_output=True, text=True, timeout=120)
    assert r.returncode != 0 and "Traceback" not in r.stderr and r.stderr.strip().count("\n") == 0
