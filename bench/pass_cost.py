"""What the render passes cost: samples per second of one process with no pass, with the
data and denoising passes (film.aovs), and with the light passes too (film.light_aovs).

Each configuration traces the same scene in passes of `--spp` samples per pixel after a
warm-up pass (compiling what it needs), the three alternating so that the machine's load
drifts alike over all of them; prints the median of `--repeats` passes.

    .venv/bin/python -m bench pass_cost [--size 128] [--spp 2] [--repeats 5] [--scenes box fog]
"""

from __future__ import annotations

import argparse
import statistics
import time

from examples.scenes import cornell_box, cornell_fog
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer

SCENES = {"box": cornell_box, "fog": cornell_fog}
CONFIGS = {"no passes": (False, False), "data + denoising": (True, False), "+ light passes": (True, True)}


def tracer_for(make, size: int, aovs: bool, light: bool) -> tuple[Tracer, int, int]:
    scene = make(size=size, spp=1)
    scene.film.aovs, scene.film.light_aovs = aovs, light
    cs = compile_scene(scene)
    return Tracer(cs, scene.integrator), cs.width, cs.height


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench pass_cost", description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--spp", type=int, default=2)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--scenes", nargs="+", choices=sorted(SCENES), default=sorted(SCENES))
    args = parser.parse_args(argv)
    for name in args.scenes:
        tracers = {label: tracer_for(SCENES[name], args.size, *flags) for label, flags in CONFIGS.items()}
        rates: dict[str, list[float]] = {label: [] for label in CONFIGS}
        for repeat in range(args.repeats + 1):
            for label, (tracer, width, height) in tracers.items():
                film = Film(width, height)
                started = time.perf_counter()
                tracer.trace(film, repeat * args.spp, args.spp, 1)
                seconds = time.perf_counter() - started
                if repeat > 0:  # the first pass warms up
                    rates[label].append(width * height * args.spp / seconds / 1e6)
        base = statistics.median(rates["no passes"])
        cells = [f"{label} {statistics.median(r):.3f} ({statistics.median(r) / base - 1:+.1%})"
                 for label, r in rates.items()]
        print(f"{name} {args.size}x{args.size}, M samples/s, median of {args.repeats}: " + "; ".join(cells),
              flush=True)
    return 0
