"""Shader programs in the renderer, without bpy: a checker-textured diffuse plane under a
constant sky renders its albedo per cell (an analytic answer), a scene without programs
compiles no program stage, and programs survive the scene folder (the CLI's input)."""

from __future__ import annotations

import numpy as np

from renderer.compile import compile_scene
from renderer.render import render
from renderer.scene import (
    Camera,
    CornerAttribute,
    Environment,
    Film,
    IntegratorSettings,
    Lobe,
    Material,
    Mesh,
    Scene,
)
from renderer.scenefile import load_scene, save_scene
from renderer.shading.program import BIND_FIELDS, BIND_SET, OP, ShaderProgram

COLOR1, COLOR2, SCALE = (0.8, 0.2, 0.1), (0.1, 0.3, 0.9), 4.0
SIZE = 32


def instr(op, dst, a=0, b=0, c=0, d=0, e=0, i0=0, i1=0, i2=0):
    return [OP[op], dst, a, b, c, d, e, i0, i1, i2]


def checker_program() -> ShaderProgram:
    """Diffuse colour = Checker(UV, COLOR1, COLOR2, SCALE). Registers: 0-2 UV, 3-5 and 6-8
    the colours, 9 the scale, 10-12 the result, 13 its factor."""
    regs = np.zeros(14, np.float32)
    regs[3:6], regs[6:9], regs[9] = COLOR1, COLOR2, SCALE
    code = np.array([instr("attribute", 0, i0=0, i1=2), instr("checker", 10, a=0, b=3, c=6, d=9)], np.int32)
    binds = np.array([[0, BIND_FIELDS.index("color"), 3, 10, BIND_SET]], np.int32)
    return ShaderProgram(code, regs, binds, attributes=["uv:UVMap"])


def plane_scene(program: ShaderProgram | None, spp: int = 64) -> Scene:
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    idx = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    uv = ((v[:, :2] + 1) / 2)[idx].astype(np.float32)  # (T, 3, 2)
    mesh = Mesh("plane", v, idx, ["m"], attributes=[CornerAttribute("uv:UVMap", uv)])
    material = Material("m", lobes=[Lobe("diffuse", color=(0.5, 0.5, 0.5))], program=program)
    camera = Camera(to_world=np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 5], [0, 0, 0, 1]], float),
                    projection="orthographic", ortho_scale=2.0)
    return Scene(camera=camera, film=Film(width=SIZE, height=SIZE),
                 integrator=IntegratorSettings(spp=spp, max_bounces=2, seed=3),
                 materials=[material], meshes=[mesh], environment=Environment((1.0, 1.0, 1.0)))


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
