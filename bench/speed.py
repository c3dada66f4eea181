"""Speed benchmark: `python -m bench speed` (or `make bench`). Prints figures; asserts nothing.

For each example at 128x128 and 256x256: M samples/s on one core (CPU time), path
vertices/s, the share of time spent inside Embree, and samples/s with two worker processes
(wall clock: needs an otherwise idle machine) with the speed-up. Also the cold (compiling)
and warm (cached) start-up of the numba kernels, each in a fresh process, and the cost of
media support on a scene without media.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

from renderer.film import Film


def _scenes(size: int):
    from examples.scenes import cornell_box, cornell_fog

    return {
        "cornell": cornell_box(size, 1, max_bounces=3),
        "cornell_fog_g0": cornell_fog(size, 1, g=0.0, max_bounces=3),
        "cornell_fog_g0.9": cornell_fog(size, 1, g=0.9, max_bounces=3),
    }


class _EmbreeTimer:
    """Wraps an Intersector to add up the seconds spent inside Embree."""

    def __init__(self, isect):
        self.seconds = 0.0
        self._intersect, self._occluded = isect.intersect, isect.occluded
        isect.intersect, isect.occluded = self.intersect, self.occluded

    def intersect(self, *a):
        t = time.thread_time()
        r = self._intersect(*a)
        self.seconds += time.thread_time() - t
        return r

    def occluded(self, *a):
        t = time.thread_time()
        r = self._occluded(*a)
        self.seconds += time.thread_time() - t
        return r


def one_core(scene, spp: int) -> dict:
    from renderer.compile import compile_scene
    from renderer.integrator.wavefront import Tracer

    cs = compile_scene(scene)
    tracer = Tracer(cs, scene.integrator)
    tracer.trace(Film(cs.width, cs.height), 0, 1, 0)  # compile / warm caches
    timer = _EmbreeTimer(tracer.isect)
    rays0 = tracer.stats["rays"]
    film = Film(cs.width, cs.height)
    # CPU time of this thread: "per core" even when other processes share the machine.
    t = time.thread_time()
    tracer.trace(film, 1, spp, 0)
    seconds = time.thread_time() - t
    samples = cs.width * cs.height * spp
    return {"msps": samples / seconds / 1e6, "vertices_per_s": (tracer.stats["rays"] - rays0) / seconds / 1e6,
            "embree_share": timer.seconds / seconds, "seconds": seconds}


def _surface_only_kernels():
    """The integrator's stage kernels with the surface stage recompiled from its own source
    with every trace of media deleted: the stack updates of interface crossings become
    no-ops (the medium stage never runs on a scene without media). Uncached: the baseline
    of media_overhead."""
    import importlib.util
    import inspect
    import types

    from numba import njit

    from renderer.integrator import stages, surface_stage
    from renderer.kernels import JIT_OPTIONS

    uncached = {**JIT_OPTIONS, "cache": False}  # a module built from a string has no cache file
    src = inspect.getsource(surface_stage).replace("@inline_kernel\n", "@_uncached_inline\n")
    src = src.replace("@kernel\n", "@_uncached\n")
    src = src.replace("    med = geo.medium[p]\n    if med >= 0:", "    med = -1\n    if med >= 0:")
    spec = importlib.util.spec_from_loader("renderer.integrator._surface_only", loader=None)
    module = importlib.util.module_from_spec(spec)
    module.__package__ = "renderer.integrator"
    module.__dict__.update(_uncached=njit(**uncached), _uncached_inline=njit(**uncached, forceinline=True))
    exec(compile(src, "<surface-only surface stage>", "exec"), module.__dict__)
    kernels = {name: getattr(stages, name) for name in stages.__all__}
    kernels["shade_surface"] = module.shade_surface
    return types.SimpleNamespace(**kernels)


def media_overhead(scene, spp: int, repeats: int = 3) -> float:
    """Relative slow-down of the media-capable kernels against the same kernels with media
    compiled out, on a scene without media (best of `repeats`, CPU time)."""
    from renderer.compile import compile_scene
    from renderer.integrator import wavefront
    from renderer.integrator.wavefront import Tracer

    cs = compile_scene(scene)
    times = {}
    for label, module in (("with media", wavefront.K), ("surface only", _surface_only_kernels())):
        original = wavefront.K
        wavefront.K = module
        try:
            tracer = Tracer(cs, scene.integrator)
            tracer.trace(Film(cs.width, cs.height), 0, 1, 0)
            best = float("inf")
            for _ in range(repeats):
                t = time.thread_time()
                tracer.trace(Film(cs.width, cs.height), 1, spp, 0)
                best = min(best, time.thread_time() - t)
            times[label] = best
        finally:
            wavefront.K = original
    return times["with media"] / times["surface only"] - 1.0


def two_processes(scene, seconds: float = 6.0) -> float:
    """Samples/s with 2 worker processes over about `seconds` of wall time, counted from the
    first finished pass (so the workers' start-up is left out), in M/s."""
    from renderer.render import render_progressive

    scene.integrator.spp = 1 << 20
    scene.integrator.time_limit = seconds
    t_first = None
    spp_first = 0
    last = None
    for last in render_progressive(scene, workers=2):
        if t_first is None:
            t_first, spp_first = last.elapsed, last.spp
    assert last is not None and t_first is not None
    samples = scene.film.width * scene.film.height * (last.spp - spp_first)
    return samples / max(last.elapsed - t_first, 1e-9) / 1e6


def startup(cold: bool) -> float:
    """Seconds to import and render one 16x16 sample in a fresh process (cold: empty cache)."""
    env = dict(os.environ)
    if cold:
        import tempfile

        env["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="haze-numba-")
    code = ("import time; t=time.perf_counter(); from examples.scenes import cornell_fog; "
            "from renderer.render import render; render(cornell_fog(16, 1)); print(time.perf_counter()-t)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    return float(r.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m bench speed")
    p.add_argument("--spp", type=int, default=16, help="samples per pixel per measurement")
    p.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    p.add_argument("--no-startup", action="store_true")
    p.add_argument("--two-seconds", type=float, default=6.0, help="wall seconds per 2-process measurement")
    args = p.parse_args(argv)
    p_overhead = _scenes(128)["cornell"]
    print(f"media support on a surface-only scene (cornell 128x128): "
          f"{media_overhead(p_overhead, args.spp):+.1%} CPU time against kernels with media compiled out")
    if not args.no_startup:
        print(f"start-up: cold (compiling) {startup(True):.1f} s, warm (cached) {startup(False):.1f} s")
    print(f"{'scene':<18}{'size':>6}{'M samples/s':>13}{'M vertices/s':>14}{'Embree':>8}{'2 procs':>10}"
          f"{'speed-up':>10}")
    for size in args.sizes:
        for name, scene in _scenes(size).items():
            r = one_core(scene, args.spp)
            two = two_processes(_scenes(size)[name], args.two_seconds)
            print(f"{name:<18}{size:>6}{r['msps']:>13.3f}{r['vertices_per_s']:>14.3f}"
                  f"{r['embree_share']:>7.0%}{two:>10.3f}{two / r['msps']:>9.2f}x", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
