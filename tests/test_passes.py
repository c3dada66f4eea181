"""Render passes and denoising in the renderer itself (no Blender).

The comparisons with Cycles' passes are in tests/test_addon_passes.py; these check the
renderer's own promises: a pass nobody asked for costs nothing (no config flag, no AOV
columns, no film sums), the sums merge across worker processes, and Open Image Denoise
guided by the albedo and normal passes cuts the error of a 16-spp fog Cornell box at
least 5-fold.
"""

from __future__ import annotations

import numpy as np
import pytest

from examples.scenes import cornell_box, cornell_fog
from helpers.films import render_film
from renderer.compile import compile_scene
from renderer.denoise import available, denoise
from renderer.film import REL_EPS
from renderer.integrator.config import CFG_AOVS, CFG_LIGHT_AOVS
from renderer.integrator.paths import (
    AOV_COUNT,
    L_COLUMNS,
    L_COLUMNS_AOV,
    L_COLUMNS_LIGHT_AOV,
    LIGHT_AOV_COUNT,
)
from renderer.integrator.wavefront import Tracer
from renderer.passes import MISS_DEPTH, film_passes


def rel_mse(image: np.ndarray, reference: np.ndarray) -> float:
    return float(np.mean((image - reference) ** 2 / (reference ** 2 + REL_EPS)))


def test_unrequested_passes_cost_nothing():
    scene = cornell_box(size=8, spp=1)
    tracer = Tracer(compile_scene(scene), scene.integrator)
    assert tracer.cfg[CFG_AOVS] == 0 and tracer.L.shape[1] == L_COLUMNS
    assert render_film(scene).aov is None
    scene.film.aovs = True
    tracer = Tracer(compile_scene(scene), scene.integrator)
    assert tracer.cfg[CFG_AOVS] == 1 and tracer.L.shape[1] == L_COLUMNS_AOV
    # The light and colour passes add their columns only when asked for.
    assert tracer.cfg[CFG_LIGHT_AOVS] == 0 and render_film(scene).aov.shape[1] == AOV_COUNT
    scene.film.light_aovs = True
    tracer = Tracer(compile_scene(scene), scene.integrator)
    assert tracer.cfg[CFG_LIGHT_AOVS] == 1 and tracer.L.shape[1] == L_COLUMNS_LIGHT_AOV
    assert render_film(scene).aov.shape[1] == AOV_COUNT + LIGHT_AOV_COUNT


@pytest.mark.slow
def test_passes_leave_the_image_unchanged():
    """Recording the passes draws no random numbers and adds no radiance: the same image."""
    for make in (cornell_box, cornell_fog):
        scene = make(size=16, spp=2)
        plain = render_film(scene).image()
        scene.film.aovs = True
        np.testing.assert_array_equal(render_film(scene).image(), plain)
        scene.film.light_aovs = True
        np.testing.assert_array_equal(render_film(scene).image(), plain)


@pytest.mark.slow
def test_light_passes_add_up_to_the_denoising_albedo():
    """In a box of diffuse walls with an emitter and no glossy lobes, every camera path's
    first hit is diffuse-like, so its Denoising Albedo is that hit's diffuse albedo (Diffuse
    Color) plus the emission seen there (Emission): the three agree to float precision, and
    Emission is the emitter's radiance where it fills a pixel, 0 where it is not seen."""
    scene = cornell_box(size=32, spp=4)
    scene.film.aovs = scene.film.light_aovs = True
    film = render_film(scene, workers=2)
    names = ("Denoising Albedo", "Diffuse Color", "Glossy Color", "Emission")
    passes = film_passes(film, scene.camera, names)
    np.testing.assert_allclose(passes["Diffuse Color"] + passes["Emission"], passes["Denoising Albedo"],
                               atol=1e-6)
    assert (passes["Glossy Color"] == 0.0).all()
    emission = passes["Emission"].max(axis=-1)
    lit = emission == emission.max()
    assert 0 < lit.sum() < emission.size // 4 and (emission[emission < emission.max()] < emission.max()).all()
    assert (emission == 0.0).mean() > 0.5
    assert passes["Diffuse Color"].max() <= 1.0 and passes["Diffuse Color"].min() >= 0.0


@pytest.mark.slow
def test_passes_merge_across_workers_and_read_back():
    scene = cornell_box(size=16, spp=4)
    scene.film.aovs = True
    one, two = render_film(scene), render_film(scene, workers=2)
    assert one.aov is not None and two.aov is not None
    np.testing.assert_allclose(two.aov, one.aov, rtol=1e-12, atol=1e-12)
    passes = film_passes(one, scene.camera)
    # The closed box: every camera ray hits a wall at a finite depth, normals are unit.
    depth = passes["Depth"]
    assert (depth > 0).all() and (depth < MISS_DEPTH).all()
    lengths = np.linalg.norm(passes["Denoising Normal"], axis=-1)
    assert np.median(lengths) == pytest.approx(1.0, abs=1e-5)
    # Diffuse walls of albedo <= 0.8, an emitter's radiance where the light is seen.
    assert passes["Denoising Albedo"].min() >= 0.0


@pytest.mark.slow
@pytest.mark.skipif(not available(), reason="Open Image Denoise not found")
def test_denoising_cuts_the_fog_box_error_fivefold():
    size = 64
    reference = cornell_fog(size=size, spp=1024)
    reference.integrator.seed = 99
    ref = render_film(reference, workers=2).image()
    scene = cornell_fog(size=size, spp=16)
    scene.film.aovs = True
    film = render_film(scene, workers=2)
    passes = film_passes(film, scene.camera)
    raw = film.image()
    clean = denoise(raw, passes["Denoising Albedo"], passes["Denoising Normal"])
    raw_error, clean_error = rel_mse(raw, ref), rel_mse(clean, ref)
    print(f"relMSE at 16 spp: raw {raw_error:.4g}, denoised {clean_error:.4g} "
          f"({raw_error / clean_error:.1f}x lower)")
    assert clean_error * 5.0 <= raw_error


@pytest.mark.slow
@pytest.mark.skipif(not available(), reason="Open Image Denoise not found")
def test_command_line_denoise(tmp_path):
    from renderer import cli
    from renderer.imageio import read_exr
    from renderer.scenefile import save_scene

    folder = tmp_path / "fog"
    save_scene(cornell_fog(size=32, spp=4), folder)
    raw, clean = tmp_path / "raw.exr", tmp_path / "clean.exr"
    common = ["--workers", "1", "--no-png", "--seed", "3"]
    assert cli.main(["render", str(folder), "-o", str(raw), *common]) == 0
    assert cli.main(["render", str(folder), "-o", str(clean), "--denoise", *common]) == 0
    raw_image, clean_image = read_exr(raw), read_exr(clean)
    # Smoother: the denoised image's pixel-to-pixel differences are far smaller.
    roughness = [float(np.abs(np.diff(im, axis=1)).mean()) for im in (raw_image, clean_image)]
    assert roughness[1] < 0.5 * roughness[0]


def test_memory_estimate_counts_the_pass_sums():
    from renderer.integrator.paths import AOV_COUNT
    from renderer.memory import AOV_BYTES_PER_PIXEL, render_memory_bytes

    assert AOV_BYTES_PER_PIXEL == AOV_COUNT * 8
    scene = cornell_box(size=100, spp=1)
    plain = render_memory_bytes(scene.film, 2)
    scene.film.aovs = True
    assert render_memory_bytes(scene.film, 2) == plain + 100 * 100 * AOV_BYTES_PER_PIXEL * (1 + 2 * 2)
    from renderer.memory import LIGHT_AOV_BYTES_PER_PIXEL

    assert LIGHT_AOV_BYTES_PER_PIXEL == LIGHT_AOV_COUNT * 8
    scene.film.light_aovs = True
    light = (AOV_BYTES_PER_PIXEL + LIGHT_AOV_BYTES_PER_PIXEL) * (1 + 2 * 2)
    assert render_memory_bytes(scene.film, 2) == plain + 100 * 100 * light
