"""Noise per sample of a benchmark scene, and what the film's error estimates make of it.

    .venv/bin/python -m bench noise_per_sample [scene] [--runs 16] [--spp 16,64] [--size 64]

Renders `runs` independent images (seeds --seed, --seed + 1, ...) per sample count in this process and
prints relMSE x spp, where relMSE is the variance across the runs per pixel over the runs'
mean squared (+ 1e-2), the measure tests/test_addon_hdri.py prints for Haze and Cycles; and
the ratio to it of: Film.rel_mse_estimate (what --target-error stops on), the per-pixel
variance from the two independent halves of the samples (Film.split_variance_of_mean) and
from their second moment (Film.variance_of_mean), both over the same level as the measure.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from bench.scenes import SCENES
from renderer.compile import compile_scene
from renderer.film import REL_EPS, Film
from renderer.integrator.wavefront import Tracer


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench noise_per_sample", description=__doc__.split("\n")[0])
    parser.add_argument("scene", nargs="?", default="hdri", choices=sorted(SCENES))
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--spp", default="16,64")
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--seed", type=int, default=100, help="of the first run")
    args = parser.parse_args(argv)
    scene = SCENES[args.scene].build(args.size)
    tracer = Tracer(compile_scene(scene), scene.integrator)
    for spp in (int(x) for x in args.spp.split(",")):
        start = time.perf_counter()
        films = []
        for run in range(args.runs):
            film = Film(args.size, args.size)
            tracer.trace(film, 0, spp, args.seed + run)
            films.append(film)
        seconds = (time.perf_counter() - start) / args.runs
        images = np.array([f.mean() for f in films])
        level = images.mean(axis=0) ** 2 + REL_EPS
        true = float((images.var(axis=0, ddof=1) / level).mean())
        estimate = np.mean([f.rel_mse_estimate() for f in films]) / true
        split = np.mean([np.mean(f.split_variance_of_mean() / level) for f in films]) / true
        moment = np.mean([np.mean(f.variance_of_mean() / level) for f in films]) / true
        print(f"{args.scene} {spp} spp x {args.runs}: relMSE x spp {true * spp:.4g}; against it, "
              f"rel_mse_estimate {estimate:.3f}, split variance {split:.3f}, second moment {moment:.3f}; "
              f"{seconds:.2f} s a run", flush=True)
    return 0
