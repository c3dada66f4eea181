"""Where a benchmark scene's time goes, kernel by kernel: `.venv/bin/python -m bench kernel_profile
[scene] [--spp N] [--repeats N]`. Prints a table.

One core, in this process, after a warm-up pass. Every kernel call from the batch driver
and every Embree call is timed with the thread's CPU clock (time.thread_time), and each
part's figure is the best of --repeats runs (this VM's one-core speed swings by up to 25%
from run to run, so the minimum is the figure that repeats). Columns: ns per pixel sample
and the share of the best run's total. Scenes: those of `python -m bench speed` and of
`python -m bench convergence` (bench/scenes.py: smoke_ball_blender, fire_ball_blender, ...).
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

from bench.scenes import SCENES
from bench.speed import _scenes
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator import wavefront
from renderer.integrator.wavefront import Tracer


class _TimedKernels:
    """Stands in for the kernels module in the batch driver, timing every call."""

    def __init__(self, kernels, spent: Counter):
        self._kernels = kernels
        self._spent = spent

    def __getattr__(self, name):
        attr = getattr(self._kernels, name)
        if not callable(attr):
            return attr

        def timed(*args):
            t = time.thread_time()
            result = attr(*args)
            self._spent[name] += time.thread_time() - t
            return result

        return timed


def _time_embree(tracer: Tracer, spent: Counter) -> None:
    for method in ("intersect", "occluded"):
        call = getattr(tracer.isect, method)

        def timed(*args, call=call, method=method):
            t = time.thread_time()
            result = call(*args)
            spent["embree_" + method] += time.thread_time() - t
            return result

        setattr(tracer.isect, method, timed)


def profile(scene_name: str, size: int, spp: int, repeats: int) -> tuple[dict[str, float], float]:
    """(best seconds per part, best total seconds) over `repeats` renders of spp samples."""
    scene = _scenes(size)[scene_name] if scene_name in _scenes(8) else SCENES[scene_name].build(size)
    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    tracer.trace(Film(cs.width, cs.height), 0, 1, 0)  # compile / warm up
    _time_embree(tracer, spent := Counter())
    kernels = wavefront.K
    best: dict[str, float] = {}
    best_total = float("inf")
    try:
        wavefront.K = _TimedKernels(kernels, spent)
        for r in range(repeats):
            spent.clear()
            t = time.thread_time()
            tracer.trace(Film(cs.width, cs.height), 1 + r * spp, spp, 0)
            total = time.thread_time() - t
            spent["(driver, Python)"] = total - sum(spent.values())
            for part, seconds in spent.items():
                best[part] = min(best.get(part, float("inf")), seconds)
            best_total = min(best_total, total)
    finally:
        wavefront.K = kernels
    return best, best_total


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m bench kernel_profile", description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default="cornell_fog_g0", choices=[*_scenes(8), *SCENES])
    parser.add_argument("--size", type=int, default=128)
    parser.add_argument("--spp", type=int, default=16)
    parser.add_argument("--repeats", type=int, default=3)
    a = parser.parse_args(argv)
    best, total = profile(a.scene, a.size, a.spp, a.repeats)
    samples = a.size * a.size * a.spp
    print(f"{a.scene} {a.size}x{a.size}, {a.spp} spp, best of {a.repeats}: "
          f"{samples / total / 1e6:.3f} M samples/s, {total / samples * 1e9:.0f} ns per sample")
    print(f"{'part':<20}{'ns/sample':>10}{'share':>8}")
    for part, seconds in sorted(best.items(), key=lambda kv: -kv[1]):
        print(f"{part:<20}{seconds / samples * 1e9:>10.1f}{seconds / total:>8.1%}")
    return 0
