"""One-core samples per second of the speed benchmark's scenes, for A/B runs of two builds.

    cd TREE && .venv/bin/python -m bench speed_ab [repeats] [--grids]

Prints one line: M samples/s (CPU time of this thread, best of `repeats` after a warm-up
pass) for the surface Cornell box and the fog box at g 0 and 0.9, 128x128, 16 spp, the
scenes and settings of `python -m bench speed`; with --grids, for the smoke ball and the
fire ball (grid media) instead. Alternate the two trees' runs (A B A B ...)
and compare the best of each: this VM's one-core speed swings by 10% from run to run.
"""

from __future__ import annotations

import argparse
import time

from examples.media_scenes import fire_ball, smoke_ball
from examples.scenes import cornell_box, cornell_fog
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer

SIZE, SPP = 128, 16


def samples_per_second(scene, repeats: int) -> float:
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    tracer.trace(Film(cs.width, cs.height), 0, 1, 0)  # compile or load, warm up
    best = float("inf")
    for _ in range(repeats):
        t = time.thread_time()
        tracer.trace(Film(cs.width, cs.height), 1, SPP, 0)
        best = min(best, time.thread_time() - t)
    return cs.width * cs.height * SPP / best


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m bench speed_ab", description=__doc__.splitlines()[0])
    parser.add_argument("repeats", type=int, nargs="?", default=3, help="timed runs per scene (best kept)")
    parser.add_argument("--grids", action="store_true", help="the smoke ball and the fire ball instead")
    args = parser.parse_args(argv)
    repeats = args.repeats
    if args.grids:
        scenes = {"smoke ball": smoke_ball(SIZE, SPP), "fire ball": fire_ball(SIZE, SPP)}
    else:
        scenes = {"surface": cornell_box(SIZE, SPP), "fog g0": cornell_fog(SIZE, SPP, 0.0),
                  "fog g0.9": cornell_fog(SIZE, SPP, 0.9)}
    print(" | ".join(f"{name} {samples_per_second(s, repeats) / 1e6:.3f}" for name, s in scenes.items()),
          flush=True)
    return 0
