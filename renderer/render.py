"""Progressive rendering: fixed units of work, traced anywhere, merged in unit order.

A path's random numbers depend only on (seed, pixel, sample index), so a render is cut
into units, each a range of sample indices for every pixel of a tile (`plan_units`: the
whole image, or bands of rows in a large one). Their sizes depend only on the image size
and the sample count, never on timing, and the film adds them into place in unit order
(this process traces the same units), so the image is bit-identical whatever the number
of workers and equal to the single-process render of the same seed. A unit that finishes
before its predecessors waits in a small buffer.

While a pass (a sample range) is cut into tiles, the pixels of tiles already merged hold
one unit's samples more than the others. Every image shown is each pixel's own mean and
the error estimate weighs each pixel by its own count (renderer.film), so a progress
image in mid-pass is as right as one at a pass's end, only less even; waiting for whole
passes would hide finished work (a 4K pass is 64 units) and lose it on a stop. The
samples reported (Progress.spp, film.spp) are those every pixel has.

The caller sees the image after merges (the first at once, then at most every
YIELD_INTERVAL) and may stop at any time. A render that stops early (time limit, target
error, or a KeyboardInterrupt while it waits) merges every finished unit before it
returns, so no finished sample is lost (closing the generator keeps what was yielded),
and the film counts exactly the samples it holds.

Embree holds Python's lock while it traces, so the second core needs a second process.
The worker processes (renderer.workers) persist across renders in this process and get
each scene once. The parent watches the clock: a worker still inside a unit when the time
limit passes (one numba kernel call cannot be interrupted, and a pathological scene may
stay in one for hours), or half a second after the render is cancelled, is terminated,
and the next render starts a new one. A worker that dies costs only its unit, which
another traces again. One worker without a time limit traces in this process by default
(see render_progressive's in_process): it starts fastest, but cannot be stopped inside a
kernel; the command line always uses the pool.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import numpy as np

from .compile import CompiledScene, compile_scene
from .cores import usable_cores
from .film import Film
from .integrator.wavefront import Tracer
from .memory import release_free_memory
from .progress import STOP_GRACE, Pacer, Progress, progress_now, target_reached
from .scene import IntegratorSettings, Scene
from .schedule import Schedule
from .shipment import Shipment, shipped
from .units import Unit, iter_units, plan_units, trace_unit
from .workers import Worker, borrowed_pool, pool, shutdown_workers, start_workers, worker_pids

__all__ = ["Progress", "Unit", "default_workers", "iter_units", "plan_units", "render", "render_progressive",
           "shutdown_workers", "start_workers", "worker_pids"]

MAX_ATTEMPTS = 3  # a unit whose worker died this many times is given up (the render stops)


def _validate(scene: Scene) -> None:
    from .validate import validate_scene

    validate_scene(scene)


def render_progressive(scene: Scene, workers: int = 1, target_error: float = 0.0,
                       validate: bool = True, on_compile: Callable[[list[str]], None] | None = None,
                       in_process: bool | None = None, cluster: str = "") -> Iterator[Progress]:
    """Render `scene`, yielding the image as units are merged (see YIELD_INTERVAL). Stops
    at scene.integrator.spp samples, at scene.integrator.time_limit seconds (if > 0) or
    once the estimated relMSE falls below target_error (if > 0). on_compile(kernel names)
    is called (in this process, while the generator runs) when kernels must be compiled.

    in_process: trace in this process (True) or in the worker pool (False). By default
    (None) one worker without a time limit runs in this process, which starts fastest and
    lets tests observe the kernels; but a numba kernel cannot be interrupted there, so
    neither Ctrl-C nor a time limit can stop a pathological scene. The pool enforces both.

    cluster: a Dask scheduler's address (tcp://HOST:8786) or "local" (a LocalCluster of
    `workers` processes) renders there instead (renderer.cluster_render), to the same bits."""
    t0 = time.perf_counter()
    if validate:
        _validate(scene)
    cs = compile_scene(scene)
    release_free_memory()  # the export's and compile's temporaries, before the render's peak
    settings = scene.integrator
    film = Film(cs.width, cs.height)
    units = iter_units(cs.width, cs.height, settings.spp)
    if cluster:
        yield from _render_on_cluster(cluster, cs, settings, film, units, t0, target_error, workers,
                                      on_compile)
        return
    if in_process is None:
        in_process = workers <= 1 and settings.time_limit <= 0
    if in_process:
        yield from _render_here(cs, settings, film, units, t0, target_error, on_compile)
    else:
        run = _PoolRender(cs, settings, film, units, t0, target_error, max(1, workers), on_compile)
        yield from run.frames()


def _render_on_cluster(address: str, cs: CompiledScene, settings: IntegratorSettings, film: Film,
                       units: Iterator[Unit], t0: float, target_error: float, workers: int,
                       on_compile) -> Iterator[Progress]:
    """Dask is imported only here: a render on this machine's pool never loads it."""
    from .cluster import connect, wait_for_a_worker
    from .cluster_render import ClusterRender

    client = connect(address, max(1, workers))
    wait_for_a_worker(client, address)
    yield from ClusterRender(client, cs, settings, film, units, t0, target_error, on_compile).frames()


def _render_here(cs: CompiledScene, settings: IntegratorSettings, film: Film, units: Iterator[Unit],
                 t0: float, target_error: float, on_compile) -> Iterator[Progress]:
    tracer = Tracer(cs, settings, on_compile)
    pacer = Pacer()
    for unit in units:
        film.add(trace_unit(tracer, unit, settings.seed))
        if pacer.merged():
            yield progress_now(film, settings, t0)
            if target_reached(film, target_error):  # checked when shown: it reads the whole image
                return
        if settings.time_limit > 0 and time.perf_counter() - t0 >= settings.time_limit:
            break
    if pacer.pending:
        yield progress_now(film, settings, t0)


class _PoolRender(Schedule):
    """One render on the persistent pool (renderer.workers): the local back-end of the
    scheduler loop (renderer.schedule)."""

    def __init__(self, cs: CompiledScene, settings: IntegratorSettings, film: Film, units: Iterator[Unit],
                 t0: float, target_error: float, workers: int, on_compile):
        super().__init__(settings, film, units, t0, target_error, on_compile)
        self.cs = cs
        self.workers = workers
        self.heard_from_a_worker = False  # see _pool_size
        self.attempts: dict[int, int] = {}
        self.pool = pool  # the shared workers; _opened borrows them
        self.shipment: Shipment | None = None

    @contextmanager
    def _opened(self) -> Iterator[None]:
        with borrowed_pool() as self.pool, shipped(self.cs, self.settings) as self.shipment:
            yield

    def _start(self) -> None:
        self.pool.resize(self._pool_size())

    def _pool_size(self) -> int:
        """Workers wanted now. A pool that must start processes starts one, and the others
        once it has said "ready" or "compile": processes starting together share two cores
        with this one's imports, so the first of several was ready about a second later than
        a lone one (warm cache); a compile still starts them all at once, to share it."""
        if self.heard_from_a_worker or len(self.pool.workers) >= self.workers:
            return self.workers
        return max(1, len(self.pool.workers))

    def _busy(self) -> bool:
        return bool(self.pool.busy())

    def _cancel(self) -> None:
        self.pool.terminate_busy()

    def _drain(self) -> None:
        self.pool.drain(STOP_GRACE)

    # The pool is refilled by the next render (lazily: an exiting CLI must not wait for new
    # processes to start), so _finish only stops the units given up (Schedule._finish).

    def _submit(self) -> None:
        self.pool.resize(self._pool_size())  # also replaces idle workers that died (killed, out of memory)
        for worker in self.pool.idle():
            unit = self._next_unit()
            if unit is None:
                self._warm_idle(self.shipment)
                return
            worker.send(self.shipment, unit, self.settings.seed)

    def _warm_idle(self, shipment: Shipment) -> None:
        """Workers left without a unit while another compiles load the scene's tracer all the
        same: on a cold cache they take kernels off the compiling one (a 1-sample render or a
        preview has one unit; F12 of the surface box at 1 spp: one worker compiled all 179
        functions)."""
        if not any(w.compiling for w in self.pool.workers):
            return
        for worker in self.pool.idle():
            if worker.scene_key != shipment.key:
                worker.warm(shipment)

    def _collect(self, timeout: float) -> bool:
        if not self.pool.busy():  # nothing in flight (e.g. after a Ctrl-C terminated them)
            return False
        return self._handle(self.pool.events(timeout))

    def _handle(self, events: list[tuple[Worker, tuple | None]]) -> bool:
        """Act on the workers' messages; True if the film changed."""
        merged = False
        for worker, message in events:
            if message is None:
                self._lost(worker)
                continue
            self.heard_from_a_worker = True
            if message[0] == "compile":
                self._compiling(worker, True, message[1])
            elif message[0] == "ready":
                self._compiling(worker, False)
            elif message[0] == "done":
                worker.unit = None
                merged |= self.merger.add(message[1], message[2])
            elif message[0] == "error":
                worker.unit = None
                raise message[2] from RuntimeError(f"in a worker process:\n{message[3]}")
        return merged

    def _compiling(self, worker: Worker, compiling: bool, names: list[str] | None = None) -> None:
        worker.compiling = compiling
        if names:
            self._announce(names)
        self.clock.pause(any(w.compiling for w in self.pool.workers))

    def _lost(self, worker: Worker) -> None:
        """A worker died: its unit goes back to the queue and a new process takes its place."""
        unit = worker.unit
        code = worker.process.exitcode
        worker.unit, worker.compiling = None, False
        self.pool.replace(worker)
        self.clock.pause(any(w.compiling for w in self.pool.workers))
        if unit is None:
            return
        self.attempts[unit.index] = self.attempts.get(unit.index, 0) + 1
        if self.attempts[unit.index] >= MAX_ATTEMPTS:
            self.note = (f"worker processes died {MAX_ATTEMPTS} times tracing {unit.describe()} (last exit"
                         f" code {code}); stopped with the samples done")
            self.failed = True
            return
        self._retry(unit)


def render(scene: Scene, workers: int = 1) -> np.ndarray:
    """Render to completion and return the (H, W, 3) float32 image."""
    image = np.zeros((scene.film.height, scene.film.width, 3), np.float32)
    for progress in render_progressive(scene, workers=workers):
        image = progress.image
    return image


def default_workers() -> int:
    """One worker per core this process may use (renderer.cores)."""
    return usable_cores()
