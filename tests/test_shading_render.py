"""Shader programs in the renderer, without bpy: a checker-textured diffuse plane under a
constant sky renders its albedo per cell (an analytic answer), a scene without programs
compiles no program stage, and programs survive the scene folder (the CLI's input)."""

from __future__ import annotations

import numpy as np

from bench.program_cost import COLOR1, COLOR2, SCALE, SIZE, checker_program, plane_scene
from renderer.compile import compile_scene
from renderer.render import render
from renderer.scenefile import load_scene, save_scene


def expected_albedo() -> np.ndarray:
    """(SIZE, SIZE, 3) albedo at pixel centres, NaN for pixels crossing a cell edge."""
    centres = (np.arange(SIZE) + 0.5) / SIZE
    u, v = np.meshgrid(centres, centres[::-1])  # image row 0 is the top (v = 1)
    half = 0.5 / SIZE
    out = np.full((SIZE, SIZE, 3), np.nan)
    cell = lambda x: np.floor(x * SCALE)  # noqa: E731
    inside = (cell(u - half) == cell(u + half)) & (cell(v - half) == cell(v + half))
    first = (cell(u).astype(int) % 2) == (cell(v).astype(int) % 2)
    # Cycles' checker: colour 1 where (x, y, z) cells have x parity == y parity, compared with z parity 0.
    color1 = ~first
    out[inside & color1] = COLOR1
    out[inside & ~color1] = COLOR2
    return out


def test_checker_plane_renders_its_albedo():
    image = render(plane_scene(checker_program()))
    expected = expected_albedo()
    for color in (COLOR1, COLOR2):
        mask = np.all(expected == color, axis=2)
        values = image[mask]
        assert len(values) > 50
        mean = values.mean(axis=0)
        sigma = values.std(axis=0, ddof=1) / np.sqrt(len(values))
        z = (mean - np.array(color)) / np.maximum(sigma, 1e-6)
        assert np.all(np.abs(z) < 4.5), (color, mean, z)


def test_scene_without_programs_has_no_program_stage():
    cs = compile_scene(plane_scene(None))
    assert cs.shading is None


def test_programs_and_attributes_survive_the_scene_folder(tmp_path):
    scene = plane_scene(checker_program())
    save_scene(scene, tmp_path / "s")
    loaded = load_scene(tmp_path / "s")
    a, b = scene.materials[0].program, loaded.materials[0].program
    assert np.array_equal(a.code, b.code) and np.array_equal(a.registers, b.registers)
    assert np.array_equal(a.bindings, b.bindings) and a.attributes == b.attributes
    assert np.array_equal(scene.meshes[0].attributes[0].values, loaded.meshes[0].attributes[0].values)
