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

import math
import queue
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING

from .cluster_tasks import remote_task
from .film import Film
from .schedule import Schedule
from .shipment import scene_payload
from .units import Unit

if TYPE_CHECKING:
    from distributed import Client, Future

    from .compile import CompiledScene
    from .scene import IntegratorSettings

IN_FLIGHT_PER_THREAD = 2  # one tracing, one queued beside it
THREADS_REFRESH = 1.0  # seconds between looks at the cluster's size


class ClusterRender(Schedule):
    """Hand units to the cluster, merge their films in unit order, enforce the stops: the
    cluster back-end of the scheduler loop (renderer.schedule)."""

    MAX_WAIT = THREADS_REFRESH  # the loop looks at the cluster's size between waits

    def __init__(self, client: Client, cs: CompiledScene, settings: IntegratorSettings, film: Film,
                 units: Iterator[Unit], t0: float, target_error: float, on_compile):
        super().__init__(settings, film, units, t0, target_error, on_compile)
        self.client, self.cs = client, cs
        self.compiling: set[str] = set()  # workers compiling kernels (the clock pauses)
        self.in_flight: dict[str, tuple[Future, Unit]] = {}  # by task key
        self.finished: queue.Queue = queue.Queue()  # ("done", key) or ("event", message)
        self.threads, self.threads_seen_at = 1, -math.inf
        self.task = remote_task()
        self.key, self.scene = "", None

    @contextmanager
    def _opened(self) -> Iterator[None]:
        from .cluster_tasks import TOPIC

        self.key, payload = scene_payload(self.cs, self.settings)
        self.scene = self.client.scatter(payload, broadcast=True, hash=False)
        self.client.subscribe_topic(TOPIC, lambda event: self.finished.put(("event", event[1])))
        try:
            yield
        finally:  # after Schedule.frames cancelled the units not finished
            self.client.unsubscribe_topic(TOPIC)
            self.scene.release()

    def _busy(self) -> bool:
        return bool(self.in_flight)

    def _finish(self) -> bool:
        merged = self._collect(0.0)  # units that finished in the grace period are kept
        self._cancel()
        return merged

    def _submit(self) -> None:
        while len(self.in_flight) < IN_FLIGHT_PER_THREAD * self._threads():
            unit = self._next_unit()
            if unit is None:
                return
            # Higher priority runs first: the earliest unit, so merges are never held up long.
            future = self.client.submit(self.task, self.key, self.scene, tuple(unit), self.settings.seed,
                                        pure=False, priority=-unit.index)
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
            self._retry(unit)
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
            self._announce(message[2])
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
