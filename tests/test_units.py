"""Units of work (renderer.units): fixed tiles of large images, every (pixel, sample) in
exactly one unit, and a tile's pixels traced with the numbers the whole image gives them,
Render Region or not.

Large images are planned, not rendered: the tile threshold is lowered through
iter_units' unit_paths so that a 24x24 box is cut into bands. Renders with workers and a
Dask cluster: tests/test_cluster.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from examples.scenes import cornell_box
from helpers.films import assert_same_bits
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer
from renderer.scene import Scene
from renderer.units import UNIT_PATHS, Unit, plan_units, tile_rows, trace_unit


def coverage(units: list[Unit], height: int, spp: int) -> np.ndarray:
    """(height, spp) how many units hold each row's sample (a unit spans whole rows)."""
    hits = np.zeros((height, spp), np.int64)
    for u in units:
        hits[u.first_row:u.first_row + u.rows, u.first_sample:u.first_sample + u.samples] += 1
    return hits


@pytest.mark.parametrize("width, height, spp, unit_paths", [
    (24, 24, 8, 100), (24, 24, 64, None), (3840, 2160, 3, None), (1920, 1080, 7, None), (7, 5, 3, 4),
    (1, 1, 1, None), (300000, 2, 2, None), (7680, 4320, 2, None), (401, 400, 1, None)])
def test_every_pixel_and_sample_is_in_exactly_one_unit(width, height, spp, unit_paths):
    units = plan_units(width, height, spp, unit_paths)
    assert units == plan_units(width, height, spp, unit_paths)  # the image and spp only
    assert [u.index for u in units] == list(range(len(units)))
    assert (coverage(units, height, spp) == 1).all()
    # Fixed tiles, the same in every pass; a pass's units before the next pass's.
    tiles = sorted({(u.first_row, u.rows) for u in units})
    passes = sorted({(u.first_sample, u.samples) for u in units})
    assert units == [Unit(i, s, n, y, r) for i, ((s, n), (y, r)) in enumerate(
        (p, t) for p in passes for t in tiles)]
    limit = UNIT_PATHS if unit_paths is None else unit_paths
    if width * height > limit:  # tiled: one sample per unit, at most `limit` paths unless a row is more
        assert all(u.samples == 1 and (u.rows * width <= limit or u.rows == 1) for u in units)
    else:
        assert tiles == [(0, height)]


def test_a_4k_frame_is_cut_into_64_bands_of_about_unit_paths_pixels():
    assert tile_rows(3840, 2160, UNIT_PATHS) == 34  # 130560 pixels, UNIT_PATHS = 131072
    units = plan_units(3840, 2160, 2)
    assert len(units) == 2 * 64 and units[63].rows == 2160 - 63 * 34
    assert tile_rows(362, 362, UNIT_PATHS) == 362  # 131044 pixels: one tile
    assert tile_rows(400, 400, UNIT_PATHS) == 200  # two even bands, not 327 + 73 rows
    assert units[65].describe() == "samples 1..1 of rows 34..67"  # in messages about a unit


def passes_and_tiles(scene: Scene, spp: int, unit_paths: int) -> tuple[Film, Film]:
    """The scene's window traced pass by pass over the whole window, and in tiles."""
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    whole, tiled = Film(cs.width, cs.height), Film(cs.width, cs.height)
    for first in range(spp):
        part = Film(cs.width, cs.height)
        tracer.trace(part, first, 1, scene.integrator.seed)
        whole.add(part)
    units = plan_units(cs.width, cs.height, spp, unit_paths)
    assert len({u.first_row for u in units}) > 1
    for unit in units:
        tiled.add(trace_unit(tracer, unit, scene.integrator.seed))
    return whole, tiled


def test_a_tile_traces_its_pixels_with_the_numbers_of_the_whole_image():
    """Same (seed, pixel, sample): the same path, bit for bit, whichever unit traces it;
    with the passes on, whose sample-0 columns depend on the tile's linear sample index."""
    scene = cornell_box(size=24, spp=3)
    scene.integrator.seed = 11
    scene.film.aovs = True
    whole, tiled = passes_and_tiles(scene, 3, unit_paths=100)  # bands of 4 rows
    assert (tiled.n == 3).all()
    assert_same_bits(tiled, whole)


def test_tiles_of_a_render_region_are_those_pixels_of_the_whole_frame():
    scene = cornell_box(size=24, spp=2)
    frame, _ = passes_and_tiles(scene, 2, unit_paths=100)
    scene.film.region = (3, 5, 17, 13)  # x, y, width, height
    window, tiled = passes_and_tiles(scene, 2, unit_paths=50)  # 5 bands of 3 rows (1 the last)
    assert_same_bits(tiled, window)
    rows = frame.sum.reshape(24, 24, 3)[5:18, 3:20]
    assert np.array_equal(tiled.sum.reshape(13, 17, 3), rows)
    assert np.array_equal(tiled.sq.reshape(13, 17, 3), frame.sq.reshape(24, 24, 3)[5:18, 3:20])


def test_the_memory_estimate_counts_a_tile_per_worker_and_plans_without_numba():
    import subprocess
    import sys

    from renderer.memory import WORKER_BYTES_PER_PIXEL, render_memory_bytes
    from renderer.scene import Film as FilmSize

    film = FilmSize(7680, 4320)  # 8K: 255 bands of 17 rows (2 the last)
    per_worker = 7680 * tile_rows(7680, 4320, UNIT_PATHS) * WORKER_BYTES_PER_PIXEL
    assert render_memory_bytes(film, 4) - render_memory_bytes(film, 1) == 4 * per_worker
    assert per_worker < UNIT_PATHS * WORKER_BYTES_PER_PIXEL
    code = "import sys, renderer.memory; print('numba' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.stdout.strip() == "False", out.stderr
