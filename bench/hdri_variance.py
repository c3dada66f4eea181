"""Noise per sample of Haze and Cycles on the HDRI scene of tests/test_addon_hdri.py.

    .venv/bin/python -m bench hdri_variance [--runs 12] [--spp 32] [--size 64]
                                  [--projections EQUIRECTANGULAR,MIRROR_BALL]
                                  [--engines haze,cycles] [--out build/hdri_variance]

One Blender subprocess builds examples/blender_materials.hdri_scene (the same EXR read as an
equirectangular map and as a mirror ball) and renders `runs` independent images per engine
(seeds 1..runs, the same samples per pixel for both engines) into --out/<projection>/. Then,
per projection and engine, it prints relMSE x spp with its standard error:

    relMSE = mean over pixels and channels of s^2 / (ref^2 + 1e-2)

where s^2 is the unbiased variance of one render across the K runs (divided by K - 1) and
ref the mean of all runs of both engines (both converge to the same image: the test checks
it). The standard error is the delete-one jackknife over runs (the noise is heavy-tailed
around a small sun, so a formula for Gaussian noise would understate it).

--engines renders only those engines; the statistics read every EXR in --out, so after a
change to Haze, `--engines haze` reuses the Cycles renders of an earlier call (same --runs,
--spp, --size).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from bench.blender import run_blender
from renderer.imageio import read_exr

REPO = Path(__file__).resolve().parents[1]

REL_EPS = 1e-2
MAX_BOUNCES = 3  # as tests/test_addon_hdri.py

BODY = r'''
import time
import bpy_helpers as H
import blender_materials as M

CONFIGURE = {"cycles": H.configure_cycles, "haze": H.configure_haze}


def main():
    H.enable_addon()
    seconds = {}
    for projection in PROJECTIONS:
        folder = f"{OUT}/{projection}"
        scene = M.hdri_scene(SIZE, folder, projection)
        for engine in ENGINES:
            start = time.perf_counter()
            for run in range(RUNS):
                CONFIGURE[engine](scene, SPP, MAX_BOUNCES, seed=run + 1)
                H.render_exr(scene, f"{folder}/{engine}_{run}.exr")
            seconds[f"{projection} {engine}"] = time.perf_counter() - start
            print(projection, engine, "done", flush=True)
    return seconds
'''


def rel_mse(images: np.ndarray, reference: np.ndarray) -> float:
    """Mean over pixels of the unbiased per-pixel variance of one render over ref^2 + eps."""
    return float((images.var(axis=0, ddof=1) / (reference**2 + REL_EPS)).mean())


def jackknife(images: np.ndarray, reference: np.ndarray) -> tuple[float, float]:
    """(relMSE of all K runs, its delete-one jackknife standard error)."""
    k = images.shape[0]
    full = rel_mse(images, reference)
    leave_one = np.array([rel_mse(np.delete(images, i, axis=0), reference) for i in range(k)])
    return full, float(np.sqrt((k - 1) / k * ((leave_one - leave_one.mean()) ** 2).sum()))


def load(folder: Path, engine: str, runs: int) -> np.ndarray | None:
    paths = [folder / f"{engine}_{run}.exr" for run in range(runs)]
    if not all(p.is_file() for p in paths):
        return None
    return np.stack([read_exr(str(p))[..., :3] for p in paths]).astype(np.float64)


def report(out: Path, projections: list[str], runs: int, spp: int) -> None:
    for projection in projections:
        folder = out / projection
        images = {e: load(folder, e, runs) for e in ("haze", "cycles")}
        present = [im for im in images.values() if im is not None]
        if not present:
            continue
        reference = np.concatenate(present).mean(axis=0)
        for engine, stack in images.items():
            if stack is None:
                print(f"{projection:16s} {engine:6s} (no renders in {folder})")
                continue
            value, error = jackknife(stack, reference)
            print(f"{projection:16s} {engine:6s} relMSE x spp {value * spp:.4f} +- {error * spp:.4f} "
                  f"({runs} runs x {spp} spp)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench hdri_variance", description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=12)
    parser.add_argument("--spp", type=int, default=32)
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--projections", default="EQUIRECTANGULAR,MIRROR_BALL")
    parser.add_argument("--engines", default="haze,cycles", help="engines to render ('' only reports)")
    parser.add_argument("--out", type=Path, default=REPO / "build" / "hdri_variance")
    args = parser.parse_args(argv)
    if args.runs < 3:
        parser.error("--runs must be at least 3 (a variance and its jackknife)")
    projections = [p for p in args.projections.split(",") if p]
    engines = [e for e in args.engines.split(",") if e]
    out = args.out.resolve()
    if engines:
        constants = dict(OUT=str(out), SIZE=args.size, RUNS=args.runs, SPP=args.spp,
                         MAX_BOUNCES=MAX_BOUNCES, PROJECTIONS=projections, ENGINES=engines)
        body = "".join(f"{k} = {v!r}\n" for k, v in constants.items()) + BODY
        start = time.perf_counter()
        # The per-user kernel cache: keyed by the renderer's sources, so any checkout may share it.
        run = run_blender(body, out / "blender", timeout=7200, numba_cache=Path.home() / ".cache" / "haze")
        if run.returncode != 0:
            sys.exit(run.describe())
        print(f"rendered in {time.perf_counter() - start:.0f} s: {json.dumps(run.result)}")
    report(out, projections, args.runs, args.spp)
    return 0
