"""Progressive rendering: a generator of passes over disjoint sample ranges.

Each pass adds a chunk of samples per pixel to the film; the caller sees the image after
every pass and may stop at any time (closing the generator stops the workers). Because a
path's random numbers depend only on (seed, pixel, sample index), chunks can be traced in
any process and merged: the image does not depend on the number of workers or the batch
size (up to the order of floating-point sums).

Embree holds Python's lock while it traces, so the second core needs a second process.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Iterator
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import dataclass

import numpy as np

from .compile import CompiledScene, compile_scene
from .film import Film
from .integrator.wavefront import Tracer
from .scene import IntegratorSettings, Scene

PASS_SECONDS = 0.5  # aim for a pass about this long: responsive progress, small overhead


@dataclass
class Progress:
    image: np.ndarray  # (H, W, 3) float32 linear RGB, row 0 at the top
    spp: int  # samples per pixel so far
    spp_target: int
    elapsed: float  # seconds since the render started (scene compile included)
    error_estimate: float  # estimated relMSE of `image` (nan before 2 spp)
    film: Film


def _validate(scene: Scene) -> None:
    from .validate import validate_scene

    validate_scene(scene)


class _Chunker:
    """Sizes passes from the measured time per sample so each lasts about PASS_SECONDS."""

    def __init__(self, target: int, workers: int = 1):
        self.target = target
        self.workers = workers
        self.next = 0  # first sample index not yet handed out
        self.seconds_per_spp = math.nan

    def take(self, time_left: float) -> tuple[int, int] | None:
        if self.next >= self.target:
            return None
        if math.isnan(self.seconds_per_spp):
            k = 1
        else:
            budget = min(PASS_SECONDS, time_left) if time_left > 0 else PASS_SECONDS
            k = max(1, int(budget / max(self.seconds_per_spp, 1e-9)))
        remaining = self.target - self.next
        # Near the end, split what is left evenly so no worker idles while another finishes.
        k = min(k, max(1, -(-remaining // self.workers)))
        start = self.next
        self.next += k
        return start, k

    def measured(self, spp: int, seconds: float) -> None:
        if spp > 0:
            s = seconds / spp
            self.seconds_per_spp = s if math.isnan(self.seconds_per_spp) else 0.5 * (self.seconds_per_spp + s)


def render_progressive(scene: Scene, workers: int = 1, target_error: float = 0.0,
                       validate: bool = True, on_compile: Callable[[list[str]], None] | None = None
                       ) -> Iterator[Progress]:
    """Render `scene`, yielding after every pass. Stops at scene.integrator.spp samples,
    at scene.integrator.time_limit seconds (if > 0) or once the estimated relMSE falls
    below target_error (if > 0). on_compile(kernel names) is called when this process must
    compile the scene's kernels first (worker processes announce it on stderr instead)."""
    t0 = time.perf_counter()
    if validate:
        _validate(scene)
    cs = compile_scene(scene)
    settings = scene.integrator
    film = Film(cs.width, cs.height)
    chunker = _Chunker(settings.spp, max(1, workers))
    if workers <= 1:
        yield from _render_here(cs, settings, film, chunker, t0, target_error, on_compile)
    else:
        yield from _render_in_workers(cs, settings, film, chunker, t0, target_error, workers)


def _should_stop(settings: IntegratorSettings, film: Film, t0: float, target_error: float) -> bool:
    if settings.time_limit > 0 and time.perf_counter() - t0 >= settings.time_limit:
        return True
    if target_error > 0 and film.spp >= 4:
        err = film.rel_mse_estimate()
        if not math.isnan(err) and err <= target_error:
            return True
    return False


def _time_left(settings: IntegratorSettings, t0: float) -> float:
    return settings.time_limit - (time.perf_counter() - t0) if settings.time_limit > 0 else 0.0


def _progress(film: Film, settings: IntegratorSettings, t0: float) -> Progress:
    return Progress(film.image(), film.spp, settings.spp, time.perf_counter() - t0, film.rel_mse_estimate(),
                    film)


def _render_here(cs, settings, film, chunker, t0, target_error, on_compile) -> Iterator[Progress]:
    tracer = Tracer(cs, settings, on_compile)
    while True:
        chunk = chunker.take(_time_left(settings, t0))
        if chunk is None:
            return
        start, k = chunk
        t = time.perf_counter()
        tracer.trace(film, start, k, settings.seed)
        chunker.measured(k, time.perf_counter() - t)
        yield _progress(film, settings, t0)
        if _should_stop(settings, film, t0, target_error):
            return


# --- worker processes -------------------------------------------------------------------

_worker_tracer: Tracer | None = None


def _worker_init(cs: CompiledScene, settings: IntegratorSettings) -> None:
    global _worker_tracer
    _worker_tracer = Tracer(cs, settings, announce_compile)


def announce_compile(names: list[str]) -> None:
    """What a process says before it compiles kernels (once per machine and Haze build)."""
    print(f"haze: compiling kernels (first run only): {', '.join(names)}", file=sys.stderr, flush=True)


def _worker_trace(start: int, k: int, seed: int):
    assert _worker_tracer is not None
    cs = _worker_tracer.cs
    film = Film(cs.width, cs.height)
    t = time.perf_counter()
    _worker_tracer.trace(film, start, k, seed)
    return film, k, time.perf_counter() - t


def _render_in_workers(cs, settings, film, chunker, t0, target_error, workers) -> Iterator[Progress]:
    ctx = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init,
                               initargs=(cs, settings))
    pending = set()
    stopping = False
    try:
        while True:
            while not stopping and len(pending) < workers:
                chunk = chunker.take(_time_left(settings, t0) / 1.0)
                if chunk is None:
                    break
                pending.add(pool.submit(_worker_trace, chunk[0], chunk[1], settings.seed))
            if not pending:
                return
            done, pending = wait(pending, return_when=FIRST_COMPLETED)
            for fut in done:
                part, k, seconds = fut.result()
                film.add(part)
                chunker.measured(k, seconds)
            yield _progress(film, settings, t0)
            if _should_stop(settings, film, t0, target_error):
                stopping = True
                if not pending:
                    return
    finally:
        _shutdown(pool)


def _shutdown(pool: ProcessPoolExecutor) -> None:
    """Stop workers at once (a cancelled render must not wait for passes in flight)."""
    processes = list(getattr(pool, "_processes", {}).values())
    pool.shutdown(wait=False, cancel_futures=True)
    for p in processes:
        if p.is_alive():
            p.terminate()
    for p in processes:
        p.join(timeout=5)


def render(scene: Scene, workers: int = 1) -> np.ndarray:
    """Render to completion and return the (H, W, 3) float32 image."""
    image = np.zeros((scene.film.height, scene.film.width, 3), np.float32)
    for progress in render_progressive(scene, workers=workers):
        image = progress.image
    return image


def default_workers() -> int:
    return max(1, os.cpu_count() or 1)
