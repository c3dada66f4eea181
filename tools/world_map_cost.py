"""What baking a world program at an HDRI's own resolution costs at export: time and peak
memory of world_program.evaluate_on_grid for an Environment Texture (equirectangular,
Linear) of a W x W/2 float image, at the old fixed 1024 x 512 grid and at the image's size.

    .venv/bin/python tools/world_map_cost.py [width ...]

No Blender: the program is assembled with the exporter's own builder and handler maths
(world_program.equirectangular_uv). Peak memory is tracemalloc's (numpy's arrays).
"""

from __future__ import annotations

import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path.cwd()))

from addon.export.program_builder import ProgramBuilder  # noqa: E402
from addon.export.world_program import equirectangular_uv, evaluate_on_grid  # noqa: E402
from renderer.shading.names import VECTOR_OPS  # noqa: E402
from renderer.shading.program import ImageTexture  # noqa: E402


class Images:
    def __init__(self, textures):
        self.textures = textures

    def list(self):
        return self.textures


def hdri_program(name: str):
    p = ProgramBuilder()
    zero = p.const(0.0)
    d = p.emit("vector_math", 3, p.emit("position", 3), zero, zero, p.const(1.0),
               i0=VECTOR_OPS.index("NORMALIZE"))
    u, v = equirectangular_uv(p, d)
    out = p.emit("image", 4, p.emit("combine", 3, u, v, zero), i0=p.image(name), i1=1, i2=0)
    return p.build([]), out.index


def measure(image_width: int, grid_width: int) -> tuple[float, float]:
    rng = np.random.default_rng(1)
    pixels = rng.random((image_width // 2, image_width, 4), dtype=np.float32)
    images = Images([ImageTexture("hdri", pixels)])
    program, register = hdri_program("hdri")
    tracemalloc.start()
    start = time.perf_counter()
    evaluate_on_grid(program, register, images, grid_width, grid_width // 2)
    seconds = time.perf_counter() - start
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    tracemalloc.stop()
    return seconds, peak


def main() -> None:
    widths = [int(a) for a in sys.argv[1:]] or [2048, 4096]
    measure(64, 64)  # compile (or load) the evaluator first
    for width in widths:
        for grid in (1024, width):
            seconds, peak = measure(width, grid)
            print(f"image {width}x{width // 2}, grid {grid}x{grid // 2}: {seconds:.2f} s, "
                  f"peak {peak:.0f} MiB")


if __name__ == "__main__":
    main()
