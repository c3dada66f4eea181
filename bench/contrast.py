"""Cost of density contrast: `python -m bench contrast`. Prints figures; asserts nothing.

Three 64^3 grids in the same view (a unit box, sigma_t 10 per unit density, albedo 0.8,
lit by a uniform environment), rendered on one core: a smooth gaussian blob (peak 1), a
lone voxel of density 1e8 among zeros, voxels of 10^U(-6, 0) (contrast 1e6), and the blob
with one voxel in a thousand set to 1e6. Reports
CPU seconds per sample (pixel sample, all bounces) and the ratio to the smooth grid: the
cost of a ray must not grow with one voxel's density (issue 18, item 5).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from examples.media_scenes import camera_at, interface_material
from examples.scenes import box
from renderer.film import Film
from renderer.scene import Environment, IntegratorSettings, Medium, Mesh, Scene
from renderer.scene import Film as FilmSettings

N = 64
SIGMA_A, SIGMA_S = (2.0, 2.0, 2.0), (8.0, 8.0, 8.0)


def grids(n: int = N) -> dict[str, np.ndarray]:
    """(nz, ny, nx) float32 density grids of the study, by name."""
    c = (np.arange(n) + 0.5) / n - 0.5
    z, y, x = np.meshgrid(c, c, c, indexing="ij")
    smooth = np.exp(-(x * x + y * y + z * z) / (2 * 0.2**2))
    lone = np.zeros((n, n, n))
    lone[n // 2, n // 2, n // 2] = 1e8
    rng = np.random.default_rng(1)
    contrast = 10.0 ** rng.uniform(-6.0, 0.0, (n, n, n))
    spikes = smooth + 1e6 * (rng.uniform(size=(n, n, n)) < 1e-3)
    return {name: g.astype(np.float32) for name, g in
            (("smooth", smooth), ("lone_1e8_voxel", lone), ("contrast_1e6", contrast),
             ("spikes_1e6", spikes))}


def scene(density: np.ndarray, size: int, spp: int) -> Scene:
    medium = Medium("grid", "grid", sigma_a=SIGMA_A, sigma_s=SIGMA_S, density=density,
                    p0=(-0.5,) * 3, p1=(0.5,) * 3)
    v, i = box((0.0, 0.0, 0.0), (0.51, 0.51, 0.51))
    return Scene(camera=camera_at((0.003, 0.002, 2.5), 30.0), film=FilmSettings(size, size),
                 integrator=IntegratorSettings(spp=spp, max_bounces=4),
                 materials=[interface_material()],
                 meshes=[Mesh("bounds", v, i, ["interface"], medium="grid")],
                 media=[medium], environment=Environment((1.0, 1.0, 1.0)))


def seconds_per_sample(s: Scene) -> float:
    """CPU seconds of this thread per pixel sample, after one warm-up pass."""
    from renderer.compile import compile_scene
    from renderer.integrator.wavefront import Tracer

    cs = compile_scene(s)
    tracer = Tracer(cs, s.integrator)
    tracer.trace(Film(cs.width, cs.height), 0, 1, 0)  # compile / warm caches
    spp = s.integrator.spp
    t = time.thread_time()
    tracer.trace(Film(cs.width, cs.height), 1, spp, 0)
    return (time.thread_time() - t) / (cs.width * cs.height * spp)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench contrast", description=__doc__)
    ap.add_argument("--size", type=int, default=32, help="image width and height")
    ap.add_argument("--spp", type=int, default=4)
    args = ap.parse_args(argv)
    base = None
    for name, density in grids().items():
        sps = seconds_per_sample(scene(density, args.size, args.spp))
        base = base or sps
        print(f"{name:16s} {sps * 1e6:10.2f} us/sample  {sps / base:8.2f}x smooth", flush=True)
    return 0
