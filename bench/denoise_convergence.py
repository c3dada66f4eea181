"""relMSE against time, raw and denoised, for the issue's figure "time to relMSE 1e-3 with
and without denoising" (one process, so the times are for one core).

Renders a reference (1024 spp, another seed), then doubles the samples of one film
(1, 2, 4, ... spp) and after each doubling measures the relMSE of the raw image and of the
OIDN-denoised one (renderer.denoise with the film's albedo and normal passes), the time
counting the tracing so far plus that denoise.

    .venv/bin/python -m bench denoise_convergence [--size 64] [--max-spp 256] [--scene fog|box]
"""

from __future__ import annotations

import argparse
import time

from examples.scenes import cornell_box, cornell_fog
from renderer.compile import compile_scene
from renderer.denoise import denoise
from renderer.film import REL_EPS, Film
from renderer.integrator.wavefront import Tracer
from renderer.passes import film_passes

SCENES = {"fog": cornell_fog, "box": cornell_box}


def rel_mse(image, reference) -> float:
    return float(((image - reference) ** 2 / (reference ** 2 + REL_EPS)).mean())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench denoise_convergence", description=__doc__.split("\n")[0])
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--max-spp", type=int, default=256)
    parser.add_argument("--reference-spp", type=int, default=1024)
    parser.add_argument("--scene", choices=sorted(SCENES), default="fog")
    args = parser.parse_args(argv)
    make = SCENES[args.scene]
    scene = make(size=args.size, spp=args.max_spp)
    scene.film.aovs = True
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    reference = Film(cs.width, cs.height)
    tracer.trace(reference, 0, args.reference_spp, 99)
    ref = reference.image()
    film = Film(cs.width, cs.height)
    traced, spp = 0.0, 0
    print(f"{args.scene} {args.size}x{args.size}, reference {args.reference_spp} spp")
    print("spp | trace s | raw relMSE | denoised relMSE | denoise s")
    while spp < args.max_spp:
        k = max(spp, 1)
        t = time.perf_counter()
        tracer.trace(film, spp, k, scene.integrator.seed)
        traced += time.perf_counter() - t
        spp += k
        t = time.perf_counter()
        passes = film_passes(film, scene.camera, ("Denoising Albedo", "Denoising Normal"))
        clean = denoise(film.image(), passes["Denoising Albedo"], passes["Denoising Normal"])
        seconds = time.perf_counter() - t
        raw_error, clean_error = rel_mse(film.image(), ref), rel_mse(clean, ref)
        print(f"{spp} | {traced:.2f} | {raw_error:.3g} | {clean_error:.3g} | {seconds:.2f}", flush=True)
    return 0
