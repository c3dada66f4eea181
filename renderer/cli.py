"""Command line: `python -m renderer render SCENE_DIR -o OUT.exr [options]`."""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from pathlib import Path

from .errors import SceneError


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m renderer", description="Haze volumetric path tracer")
    sub = p.add_subparsers(dest="command", required=True)
    r = sub.add_parser("render", help="render a scene folder to an EXR (and a PNG preview)")
    r.add_argument("scene", type=Path, help="scene folder holding scene.json")
    r.add_argument("-o", "--output", type=Path, required=True, help="output .exr path")
    r.add_argument("--spp", type=int, help="samples per pixel (default: the scene's)")
    r.add_argument("--time-limit", type=float, help="stop after this many seconds")
    r.add_argument("--seed", type=int, help="random seed (default: the scene's)")
    r.add_argument("--max-bounces", type=int, help="Cycles' max_bounces: 0 = direct light only")
    r.add_argument("--target-error", type=float, default=0.0, help="stop once estimated relMSE <= this")
    r.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes (default: all cores)")
    r.add_argument("--no-png", action="store_true", help="do not write the PNG preview")
    return p


def _bar(done: int, total: int, elapsed: float, err: float) -> str:
    frac = min(1.0, done / max(total, 1))
    width = 30
    filled = int(frac * width)
    eta = elapsed / frac - elapsed if frac > 0 else float("nan")
    err_s = f"  relMSE~{err:.2e}" if err == err else ""
    return (f"\r[{'#' * filled}{'.' * (width - filled)}] {done}/{total} spp  {elapsed:6.1f}s elapsed"
            f"  ETA {eta:5.1f}s{err_s}")


def _check(args) -> str | None:
    if args.spp is not None and args.spp < 1:
        return "--spp must be at least 1"
    if args.time_limit is not None and args.time_limit <= 0:
        return "--time-limit must be positive"
    if args.max_bounces is not None and args.max_bounces < 0:
        return "--max-bounces must be 0 or more"
    if args.workers < 1:
        return "--workers must be at least 1"
    if args.output.suffix.lower() != ".exr":
        return f"output {args.output}: must end in .exr"
    return None


class CompileTicker:
    """'compiling kernels (first run only): N s' on stderr, once a second, until stopped."""

    def __init__(self, interval: float = 1.0):
        self.interval = interval
        self._done = threading.Event()
        self._thread: threading.Thread | None = None

    def start(self, names: list[str]) -> None:
        t0 = time.perf_counter()

        def tick() -> None:
            while True:
                print(f"\rcompiling kernels (first run only): {time.perf_counter() - t0:.0f} s", end="",
                      file=sys.stderr, flush=True)
                if self._done.wait(self.interval):
                    break
            print(f"\rcompiled kernels in {time.perf_counter() - t0:.1f} s", file=sys.stderr, flush=True)

        self._thread = threading.Thread(target=tick, daemon=True)
        self._thread.start()

    def stop(self) -> None:
        if self._thread is not None:
            self._done.set()
            self._thread.join()
            self._thread = None


def render_command(args) -> int:
    from .workers import start_workers

    problem = _check(args)
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    # Before numba loads here: the workers' start overlaps this process's imports and loading.
    start_workers(args.workers)
    from .imageio import write_exr, write_png
    from .render import render_progressive
    from .scenefile import load_scene

    scene = load_scene(args.scene)
    s = scene.integrator
    if args.spp is not None:
        s.spp = args.spp
    if args.time_limit is not None:
        s.time_limit = args.time_limit
    if args.seed is not None:
        s.seed = args.seed
    if args.max_bounces is not None:
        s.max_bounces = args.max_bounces
    t0 = time.perf_counter()
    last = None
    ticker = CompileTicker()
    try:
        for last in render_progressive(scene, workers=args.workers, target_error=args.target_error,
                                       on_compile=ticker.start, in_process=False):
            ticker.stop()
            line = _bar(last.spp, s.spp, last.elapsed, last.error_estimate)
            print(line, end="", file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        print("\ninterrupted: writing the samples so far", file=sys.stderr)
    finally:
        ticker.stop()
    print(file=sys.stderr)
    if last is None:
        print("error: no samples were rendered", file=sys.stderr)
        return 1
    write_exr(args.output, last.image)
    msg = f"wrote {args.output}"
    if not args.no_png:
        png = args.output.with_suffix(".png")
        write_png(png, last.image)
        msg += f" and {png}"
    seconds = time.perf_counter() - t0
    samples = last.spp * scene.film.width * scene.film.height
    print(msg, file=sys.stderr)
    if last.note:
        print(f"warning: {last.note}", file=sys.stderr)
    if last.film.nonfinite[0]:
        bad = int(last.film.nonfinite[0])
        print(f"warning: {bad} path values were NaN or infinite and were counted as 0", file=sys.stderr)
    print(f"{last.spp} spp, {seconds:.2f} s, {samples / seconds / 1e6:.3f} M samples/s", file=sys.stderr)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        if args.command == "render":
            return render_command(args)
    except SceneError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except FileNotFoundError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 1
