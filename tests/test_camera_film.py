"""Render Region and Film > Transparent in the renderer itself (no Blender).

The comparisons with Cycles are in tests/test_addon_cameras.py; these check the renderer's
own promises: a region renders exactly the full frame's pixels (paths are keyed by their
pixel in the full frame), and alpha is 1 - the mean throughput with which camera paths
reach the world directly.
"""

from __future__ import annotations

import math

import numpy as np

from examples.scenes import box, cornell_box, furnace_sphere, quad
from helpers.films import render_film
from renderer.film import Film
from renderer.scene import Lobe, Material, Medium, Mesh, Scene

Z = 5.0  # z-score bound on the estimator's own variance


def test_region_renders_exactly_the_full_frames_window():
    scene = cornell_box(size=16, spp=2)
    full = render_film(scene).image()
    scene.film.region = (3, 5, 7, 4)
    window = render_film(scene)
    assert (window.width, window.height) == (7, 4)
    np.testing.assert_array_equal(window.image(), full[5:9, 3:10])


def transparent_stage(spp: int = 256) -> Scene:
    """The furnace sphere (opaque, centre) seen from z = 4 through a transparent sheet of
    colour (0.2, 0.5, 0.8) over the left half of the view and a slab of absorbing medium
    (sigma_a 1, 0.4 thick) over the right half."""
    scene = furnace_sphere(size=16, spp=spp, max_bounces=2)
    scene.film.transparent = True
    sheet_v, sheet_i = quad((-1.5, 0.0, 2.0), (1.5, 0.0, 0.0), (0.0, 3.0, 0.0))
    scene.materials.append(Material("sheet", lobes=[Lobe("transparent", color=(0.2, 0.5, 0.8))]))
    scene.meshes.append(Mesh("sheet", sheet_v, sheet_i, ["sheet"]))
    scene.materials.append(Material("boundary"))  # no lobes: an invisible medium boundary
    scene.media.append(Medium("smoke", sigma_a=(1.0, 1.0, 1.0), sigma_s=(0.0, 0.0, 0.0)))
    slab_v, slab_i = box((1.6, 0.0, 2.2), (1.5, 3.0, 0.2))
    scene.meshes.append(Mesh("slab", slab_v, slab_i, ["boundary"], medium="smoke"))
    return scene


def slab_transmittance(film: Film, rows: slice, cols: slice) -> float:
    """Mean over the pixels of exp(-0.4 / cos) along each pixel centre's camera ray."""
    y, x = np.mgrid[rows, cols]
    t = math.tan(math.radians(15.0))
    dx = (2.0 * (x + 0.5) / film.width - 1.0) * t
    dy = (1.0 - 2.0 * (y + 0.5) / film.height) * t
    return float(np.mean(np.exp(-0.4 * np.sqrt(1.0 + dx * dx + dy * dy))))


def test_transparent_film_gives_alpha_of_the_world_seen_directly():
    film = render_film(transparent_stage())
    alpha = film.alpha_image()
    colour = film.image()
    # The 2 x 2 pixels at the top corners: their rays pass the sphere (1.09 from its centre).
    corner = slice(0, 2)
    right = slice(film.width - 2, film.width)
    # Through the sheet: alpha = 1 - mean(colour), the same for every sample.
    np.testing.assert_allclose(alpha[corner, corner], 0.5, atol=1e-6)
    # Through the slab: 1 - transmittance. A path gets through or not (at worst), so the
    # 4 pixels x 256 samples have a standard error <= 0.5 / 32: 0.05 is over 3 of them.
    assert abs(alpha[corner, right].mean() - (1.0 - slab_transmittance(film, corner, right))) < 0.05
    # The world seen through them is left out of the colour.
    assert colour[corner, corner].max() == 0.0 and colour[corner, right].max() == 0.0
    # The sphere's centre is opaque and lit by the world.
    centre = film.height // 2, film.width // 2
    assert alpha[centre] == 1.0 and colour[centre].min() > 0.1


def test_without_transparent_film_alpha_is_one():
    scene = transparent_stage(spp=4)
    scene.film.transparent = False
    film = render_film(scene)
    assert (film.alpha_image() == 1.0).all()
    assert film.image()[0, 0].min() > 0.1  # the world through the sheet


def test_alpha_and_region_merge_across_workers():
    """Workers' films add their alpha sums too (Film.add): two workers give one's image."""
    scene = transparent_stage(spp=8)
    scene.film.region = (2, 1, 12, 9)
    alone, pair = render_film(scene), render_film(scene, workers=2)
    assert (pair.width, pair.height) == (12, 9)
    np.testing.assert_allclose(pair.alpha_image(), alone.alpha_image(), rtol=1e-6, atol=1e-7)
    np.testing.assert_allclose(pair.image(), alone.image(), rtol=1e-5, atol=1e-7)
