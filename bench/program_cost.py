"""One-core samples per second of a plane whose diffuse colour is a Checker program, against
the same plane with a constant colour: what running shader programs costs per hit.

    .venv/bin/python -m bench program_cost [repeats]

128x128, 16 spp, CPU time of this thread, best of `repeats` after a warm-up pass (as
`python -m bench speed_ab`). Only the camera ray's hit runs the program: the plane is lit by
a constant sky, so every path has one hit. The plane and its program are those of
tests/test_shading_render.py, which imports them from here.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer
from renderer.scene import (
    Camera,
    CornerAttribute,
    Environment,
    IntegratorSettings,
    Lobe,
    Material,
    Mesh,
    Scene,
)
from renderer.scene import Film as FilmSettings
from renderer.shading.program import BIND_FIELDS, BIND_SET, OP, ShaderProgram

BENCH_SIZE, SPP = 128, 16

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
    return Scene(camera=camera, film=FilmSettings(width=SIZE, height=SIZE),
                 integrator=IntegratorSettings(spp=spp, max_bounces=2, seed=3),
                 materials=[material], meshes=[mesh], environment=Environment((1.0, 1.0, 1.0)))


def samples_per_second(scene, repeats: int) -> float:
    scene.film.width = scene.film.height = BENCH_SIZE
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    tracer.trace(Film(cs.width, cs.height), 0, 1, 0)
    best = float("inf")
    for _ in range(repeats):
        t = time.thread_time()
        tracer.trace(Film(cs.width, cs.height), 1, SPP, 0)
        best = min(best, time.thread_time() - t)
    return cs.width * cs.height * SPP / best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench program_cost", description=__doc__.splitlines()[0])
    parser.add_argument("repeats", type=int, nargs="?", default=3, help="timed runs (best kept, default 3)")
    repeats = parser.parse_args(argv).repeats
    constant = samples_per_second(plane_scene(None), repeats)
    program = samples_per_second(plane_scene(checker_program()), repeats)
    print(f"constant {constant / 1e6:.3f} | checker program {program / 1e6:.3f} M samples/s", flush=True)
    return 0
