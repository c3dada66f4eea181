"""One-core samples per second of a plane whose diffuse colour is a Checker program, against
the same plane with a constant colour: what running shader programs costs per hit.

    .venv/bin/python tools/program_cost.py [repeats]

128x128, 16 spp, CPU time of this thread, best of `repeats` after a warm-up pass (as
tools/speed_ab.py). Only the camera ray's hit runs the program: the plane is lit by a
constant sky, so every path has one hit.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path.cwd()))
sys.path.insert(0, str(Path.cwd() / "tests"))

from test_shading_render import checker_program, plane_scene  # noqa: E402

from renderer.compile import compile_scene  # noqa: E402
from renderer.film import Film  # noqa: E402
from renderer.integrator.wavefront import Tracer  # noqa: E402

SIZE, SPP = 128, 16


def samples_per_second(scene, repeats: int) -> float:
    scene.film.width = scene.film.height = SIZE
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    tracer.trace(Film(cs.width, cs.height), 0, 1, 0)
    best = float("inf")
    for _ in range(repeats):
        t = time.thread_time()
        tracer.trace(Film(cs.width, cs.height), 1, SPP, 0)
        best = min(best, time.thread_time() - t)
    return cs.width * cs.height * SPP / best


def main() -> int:
    repeats = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    constant = samples_per_second(plane_scene(None), repeats)
    program = samples_per_second(plane_scene(checker_program()), repeats)
    print(f"constant {constant / 1e6:.3f} | checker program {program / 1e6:.3f} M samples/s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
