"""Render every example scene (and each estimator setting) with fixed seeds, and compare.

A refactoring of the kernels must not change an image: with the same seed a path draws the
same random numbers, so before and after agree to float rounding. This renders each case
at a small size in one process (one Tracer call, so the film's sums run in sample order)
and writes the images to an .npz; `--compare OLD.npz` renders again and reports, per case,
the largest difference relative to the image's own scale.

    .venv/bin/python -m bench golden -o /tmp/before.npz      # on the old commit
    .venv/bin/python -m bench golden --compare /tmp/before.npz  # on the new one
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from examples import media_scenes as ms
from examples import scenes as sc
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer
from renderer.scene import Medium, PointLight, Scene, SpotLight, SunLight

SIZE = 24
SPP = 8
SEED = 7


def _chromatic() -> Scene:
    scene = sc.cornell_box(SIZE, SPP)
    scene.materials.append(ms.interface_material())
    scene.media.append(Medium("chromatic", sigma_a=(3.0, 0.3, 0.03), sigma_s=(27.0, 2.7, 0.27)))
    scene.meshes.append(ms.grid_box_mesh("chromatic_box", "chromatic", (0.0, -0.55, 0.0), (0.45, 0.45, 0.45)))
    return scene


def _fog_point_lights() -> Scene:
    """The fog box lit by point, spot and sun lights too: the scalar medium path."""
    scene = sc.cornell_fog(SIZE, SPP, g=0.3)
    scene.lights += [PointLight((0.3, 0.5, 0.2), (2.0, 1.5, 1.0)),
                     SpotLight((-0.3, 0.8, 0.0), (0.0, -1.0, 0.0), (6.0, 6.0, 6.0)),
                     SunLight((0.2, 1.0, 0.1), (0.5, 0.5, 0.5))]
    return scene


def _overlapping_media() -> Scene:
    scene = ms.emitter_behind_box(
        [Medium("a", sigma_a=(0.5, 0.2, 0.1), sigma_s=(0.3, 0.6, 0.9), g=0.4),
         Medium("b", sigma_a=(0.1, 0.1, 0.1), sigma_s=(1.0, 0.5, 0.2), g=-0.3)],
        [("a", (0.0, 0.0, 0.0), (0.6, 0.6, 0.6)), ("b", (0.2, 0.1, 0.3), (0.5, 0.5, 0.5))],
        size=SIZE, spp=SPP)
    scene.camera = ms.camera_at((0.011, 0.017, 5.0), 30.0)
    return scene


def cases() -> dict[str, Callable[[], Scene]]:
    """Every example scene at SIZE x SIZE, SPP samples, and the estimator settings on the
    scenes they act on."""
    out: dict[str, Callable[[], Scene]] = {
        "cornell": lambda: sc.cornell_box(SIZE, SPP),
        "cornell_fog_g0": lambda: sc.cornell_fog(SIZE, SPP, 0.0),
        "cornell_fog_g0.9": lambda: sc.cornell_fog(SIZE, SPP, 0.9),
        "furnace_sphere": lambda: sc.furnace_sphere(0.8, SIZE, SPP),
        "point_light_plane": lambda: sc.point_light_plane(SIZE, SPP),
        "sunlit_slab": lambda: ms.add_slab(ms.sunlit_plane(SIZE, SPP),
                                           Medium("slab", sigma_a=(0.2, 0.4, 0.6), sigma_s=(0.5, 0.3, 0.1)),
                                           0.5, 1.0),
        "chromatic": _chromatic,
        "fog_point_lights": _fog_point_lights,
        "overlapping_media": _overlapping_media,
        "furnace_medium": lambda: ms.furnace_medium(
            Medium("white", sigma_a=(0.0,) * 3, sigma_s=(2.0, 1.0, 0.5)), size=SIZE, spp=SPP, max_bounces=64),
    }
    for name, build in ms.BUILDERS.items():
        out[name] = lambda build=build: build(SIZE, SPP)
    variants = {
        "nee": {"sampling": "nee"},
        "bsdf": {"sampling": "bsdf"},
        "delta": {"transmittance": "delta"},
        "uniform": {"distance_sampling": "uniform"},
        "no_equiangular": {"equiangular": False},
        "global_majorant": {"majorant_grid": False},
    }
    for base in ("cornell_fog_g0", "smoke_ball", "chromatic", "fire_ball"):
        for label, overrides in variants.items():
            def build(base=base, overrides=overrides) -> Scene:
                scene = out[base]()
                scene.integrator = replace(scene.integrator, **overrides)
                return scene
            out[f"{base}/{label}"] = build
    return out


def render_case(scene: Scene) -> np.ndarray:
    scene.integrator = replace(scene.integrator, seed=SEED, batch_size=4096)
    cs = compile_scene(scene)
    film = Film(cs.width, cs.height)
    Tracer(cs, scene.integrator).trace(film, 0, scene.integrator.spp, SEED)
    return film.image()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m bench golden", description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", type=Path, help="write the images to this .npz")
    ap.add_argument("--compare", type=Path, help="compare with the images of this .npz")
    ap.add_argument("--rtol", type=float, default=1e-5, help="largest difference / image scale allowed")
    ap.add_argument("--only", nargs="*", help="render only these cases")
    args = ap.parse_args(argv)
    old = dict(np.load(args.compare)) if args.compare else {}
    images: dict[str, np.ndarray] = {}
    worst = 0.0
    failed = []
    for name, build in cases().items():
        if args.only and name not in args.only:
            continue
        t = time.perf_counter()
        images[name] = img = render_case(build())
        line = f"{name:32s} mean {img.mean():.6g}  {time.perf_counter() - t:6.2f} s"
        if name in old:
            scale = max(float(np.abs(old[name]).max()), 1e-12)
            diff = float(np.abs(img.astype(np.float64) - old[name]).max()) / scale
            worst = max(worst, diff)
            line += f"  max |diff| / max {diff:.2e}"
            if not diff <= args.rtol:
                failed.append(name)
                line += "  DIFFERS"
        elif args.compare:
            line += "  (not in the old file)"
        print(line, flush=True)
    if args.out:
        np.savez_compressed(args.out, **images)
    if args.compare:
        passed = len(images) - len(failed)
        print(f"{passed} passed, {len(failed)} failed (rtol {args.rtol:g}, worst {worst:.2e})")
        return 1 if failed else 0
    return 0
