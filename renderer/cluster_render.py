"""One progressive render on a Dask cluster: the same units, merged in the same order.

The units (renderer.units) are submitted as Dask tasks, earliest unit first and at most
IN_FLIGHT_PER_THREAD per worker thread at once (so a stop wastes little, and a worker
never idles between two units). Each finished task's future lands in a queue (a done
callback runs in the client's thread), and the main loop merges the films in unit order
(renderer.progress.UnitMerger): the image has the bits of a one-process render of the same
seed, whatever the workers and wherever they run.

The scene is scattered to every worker once per render (broadcast) and named by its hash;
a worker builds its tracer once per scene (renderer.cluster_tasks). Dask reruns the
tasks of a worker that is lost; a unit whose workers died on Dask's allowed-failures
attempts stops the render with the samples done. Stops (time limit, target error,
Ctrl-C, the caller closing the generator) cancel the units not finished and keep those
merged. A unit already running on a worker cannot be interrupted there (one numba kernel
call); its worker finishes it and drops the result.
"""

from __future__ import annotations

import heapq
import math
import queue
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING

from .cluster_tasks import remote_task
from .film import Film
from .progress import (
    STOP_GRACE,
    Clock,
    Pacer,
    Progress,
    UnitMerger,
    announce_compile,
    progress_now,
    target_reached,
)
from .units import Unit
from .workers import scene_payload

if TYPE_CHECKING:
    from distributed import Client, Future

    from .compile import CompiledScene
    from .scene import IntegratorSettings

IN_FLIGHT_PER_THREAD = 2  # one tracing, one queued beside it
THREADS_REFRESH = 1.0  # seconds between looks at the cluster's size


class ClusterRender:
    """Hand units to the cluster, merge their films in unit order, enforce the stops."""

    def __init__(self, client: Client, cs: CompiledScene, settings: IntegratorSettings, film: Film,
                 units: Iterator[Unit], t0: float, target_error: float, on_compile):
        self.client, self.cs, self.settings, self.film, self.t0 = client, cs, settings, film, t0
        self.fresh = units
        self.retry: list[Unit] = []  # a heap: units to submit again, before any fresh one
        self.target_error = target_error
        self.on_compile = on_compile or announce_compile
        self.announced = False
        self.compiling: set[str] = set()  # workers compiling kernels (the clock pauses)
        self.merger = UnitMerger(film)
        self.clock = Clock(settings, t0)
        self.pacer = Pacer()
        self.in_flight: dict[str, tuple[Future, Unit]] = {}  # by task key
        self.finished: queue.Queue = queue.Queue()  # ("done", key) or ("event", message)
        self.threads, self.threads_seen_at = 1, -math.inf
        self.stop_at = math.inf
        self.target_met = False
        self.task = remote_task()
        self.note = ""

    def frames(self) -> Iterator[Progress]:
        from .cluster_tasks import TOPIC

        key, payload = scene_payload(self.cs, self.settings)
        scene = self.client.scatter(payload, broadcast=True, hash=False)
        self.client.subscribe_topic(TOPIC, lambda event: self.finished.put(("event", event[1])))
        try:
            yield from self._run(key, scene)
        except KeyboardInterrupt:
            # Show the finished units before the interrupt goes on to the caller.
            self._cancel()
            if self._collect(0.0) | self.merger.merge_the_rest() or self.pacer.pending:
                yield self.progress_now()
            raise
        finally:
            self._cancel()  # closed by the caller (Esc in Blender), an error, or done
            self.client.unsubscribe_topic(TOPIC)
            scene.release()

    def _run(self, key: str, scene: Future) -> Iterator[Progress]:
        while True:
            if self._stopping():
                self.stop_at = min(self.stop_at, time.perf_counter() + STOP_GRACE)
            else:
                self._submit(key, scene)
            if not self.in_flight:
                break
            if time.perf_counter() >= self.stop_at:
                if self.film.spp == 0 and not self.merger.waiting and not self.note:
                    self.note = "the time limit passed before the first samples were done"
                break
            if self._collect(self._wait_time()) and self.pacer.merged():
                # Checked when shown: the estimate reads the whole image.
                self.target_met = target_reached(self.film, self.target_error)
                yield self.progress_now()
        merged = self._collect(0.0)  # units that finished in the grace period are kept
        self._cancel()
        if merged | self.merger.merge_the_rest() or self.pacer.pending or self.note or not self.pacer.shown:
            yield self.progress_now()

    def _stopping(self) -> bool:
        return bool(self.note) or self.target_met or self.clock.left() <= 0

    def _submit(self, key: str, scene: Future) -> None:
        while len(self.in_flight) < IN_FLIGHT_PER_THREAD * self._threads():
            unit = heapq.heappop(self.retry) if self.retry else next(self.fresh, None)
            if unit is None:
                return
            # Higher priority runs first: the earliest unit, so merges are never held up long.
            future = self.client.submit(self.task, key, scene, tuple(unit), self.settings.seed, pure=False,
                                        priority=-unit.index)
            self._track(future, unit)

    def _track(self, future: Future, unit: Unit) -> None:
        self.in_flight[future.key] = (future, unit)
        future.add_done_callback(lambda f: self.finished.put(("done", f.key)))  # called once

    def _threads(self) -> int:
        """Worker threads in the cluster, looked at once a second (a scheduler round trip)."""
        if time.perf_counter() - self.threads_seen_at >= THREADS_REFRESH:
            self.threads = max(1, sum(self.client.nthreads().values()))
            self.threads_seen_at = time.perf_counter()
        return self.threads

    def _wait_time(self) -> float:
        return max(0.0, min(self.clock.left(), self.stop_at - time.perf_counter(), THREADS_REFRESH))

    def _collect(self, timeout: float) -> bool:
        """Handle what has finished (waiting up to `timeout` for the first); True if merged."""
        merged = False
        try:
            item = self.finished.get(timeout=timeout) if timeout > 0 else self.finished.get_nowait()
            while True:
                merged |= self._handle(*item)
                item = self.finished.get_nowait()
        except queue.Empty:
            return merged

    def _handle(self, kind: str, what) -> bool:
        if kind == "event":
            self._worker_event(what)
            return False
        entry = self.in_flight.pop(what, None)
        if entry is None:
            return False  # cancelled by us
        future, unit = entry
        if future.status == "finished":
            return self.merger.add(unit.index, future.result())  # waits if its worker died since
        if future.status == "cancelled":  # e.g. the scene's data was lost with every holder
            heapq.heappush(self.retry, unit)
            return False
        if future.status != "error":  # its result was lost with its worker: Dask traces it again
            self._track(future, unit)
            return False
        error = future.exception()
        from distributed.scheduler import KilledWorker

        if isinstance(error, KilledWorker):
            self.note = f"cluster workers died tracing {unit.describe()}; stopped with the samples done"
            return False
        raise error

    def _worker_event(self, message: list) -> None:
        worker, what = message[0], message[1]
        if what == "compile":
            self.compiling.add(worker)
            if not self.announced:
                self.announced = True
                self.on_compile(message[2])
        else:
            self.compiling.discard(worker)
        self.clock.pause(bool(self.compiling))

    def _cancel(self) -> None:
        """Cancel the units not finished (their results are never merged); keep the rest."""
        pending = [future for future, _ in self.in_flight.values() if not future.done()]
        for key in [k for k, (f, _) in self.in_flight.items() if not f.done()]:
            del self.in_flight[key]
        if pending:
            self.client.cancel(pending)

    def progress_now(self) -> Progress:
        return progress_now(self.film, self.settings, self.t0, self.note)
