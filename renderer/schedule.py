"""The one scheduler loop of a progressive render: hand out units, merge them, enforce the stops.

A render's units (renderer.units) run on a back-end: this machine's persistent worker
processes (renderer.render's _PoolRender) or a Dask cluster (renderer.cluster_render's
ClusterRender). They differ only in how a unit is submitted, how what finished is
collected and how the units in flight are cancelled; the loop is this one. It hands out
retried units (a heap, earliest first) before fresh ones, merges films in unit order
(renderer.progress.UnitMerger, so the image has the bits of a one-process render of the
same seed), shows the image after merges (renderer.progress.Pacer), pauses the time limit
while kernels compile, and stops at the time limit, the target error, a note (units given
up) or a Ctrl-C, keeping every unit that finished. Units still in flight STOP_GRACE
seconds after a stop are given up.

A back-end implements:
- `_opened()`: a context manager around the render (the scene shipped, workers borrowed);
- `_submit()`: hand out units (`_next_unit()`) while it has room;
- `_busy()`: whether units are in flight;
- `_collect(timeout)`: act on what finished (waiting up to `timeout` for the first), True if
  the film changed; `_retry(unit)` queues a unit again, `_announce(names)` a compile;
- `_cancel()`: stop the units in flight (their results are never merged);
and may override `_start()` (before the first unit), `_finish()` (after the last; True if
it merged) and `_drain()` (the caller closed the generator).
"""

from __future__ import annotations

import heapq
import math
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager

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
from .scene import IntegratorSettings
from .units import Unit


class Schedule:
    """One render's loop; a subclass is the back-end that runs the units."""

    MAX_WAIT = 3600.0  # seconds the loop waits at most for a unit before it looks again

    def __init__(self, settings: IntegratorSettings, film: Film, units: Iterator[Unit], t0: float,
                 target_error: float, on_compile: Callable[[list[str]], None] | None):
        self.settings, self.film, self.t0 = settings, film, t0
        self.fresh = units
        self.retry: list[Unit] = []  # a heap: units to run again, before any fresh one
        self.target_error = target_error
        self.on_compile = on_compile or announce_compile
        self.announced = False
        self.merger = UnitMerger(film)
        self.clock = Clock(settings, t0)
        self.stop_at = math.inf  # when units still in flight are given up
        self.note = ""
        self.failed = False  # the note is a failure (units given up): see Progress.failed
        self.pacer = Pacer()
        self.target_met = False

    # --- the back-end -------------------------------------------------------------------

    def _opened(self) -> AbstractContextManager:
        raise NotImplementedError

    def _start(self) -> None:
        pass

    def _submit(self) -> None:
        raise NotImplementedError

    def _busy(self) -> bool:
        raise NotImplementedError

    def _collect(self, timeout: float) -> bool:
        raise NotImplementedError

    def _cancel(self) -> None:
        raise NotImplementedError

    def _finish(self) -> bool:
        """After the loop: units still in flight are given up; True if something merged."""
        self._cancel()
        return False

    def _drain(self) -> None:
        pass

    # --- the loop -----------------------------------------------------------------------

    def frames(self) -> Iterator[Progress]:
        with self._opened():
            try:
                yield from self._run()
            except KeyboardInterrupt:
                # Show the finished units before the interrupt goes on to the caller.
                self._cancel()
                if self._collect(0.0) | self.merger.merge_the_rest() or self.pacer.pending:
                    yield self.progress_now()
                raise
            except GeneratorExit:  # closed by the caller (Esc in Blender): no more images
                self._drain()
                raise
            finally:
                self._cancel()  # a cancelled render leaves no unit in flight

    def _run(self) -> Iterator[Progress]:
        self._start()
        while True:
            if self._stopping():
                self.stop_at = min(self.stop_at, time.perf_counter() + STOP_GRACE)
            else:
                self._submit()
            if not self._busy():
                break
            if time.perf_counter() >= self.stop_at:
                break
            if self._collect(self._wait_time()) and self.pacer.merged():
                # Checked when shown: the estimate reads the whole image.
                self.target_met = target_reached(self.film, self.target_error)
                yield self.progress_now()
        merged = self._finish()
        merged |= self.merger.merge_the_rest()
        # After the last merge, whichever way the loop ended: a unit stopped at the limit
        # can leave nothing busy before the grace period is over.
        if self.film.spp == 0 and not self.note and self.clock.left() <= 0:
            self.note = "the time limit passed before the first samples were done"
        if merged or self.pacer.pending or self.note or not self.pacer.shown:
            yield self.progress_now()

    def _stopping(self) -> bool:
        return bool(self.note) or self.target_met or self.clock.left() <= 0

    def _wait_time(self) -> float:
        return max(0.0, min(self.clock.left(), self.stop_at - time.perf_counter(), self.MAX_WAIT))

    # --- for the back-ends --------------------------------------------------------------

    def _next_unit(self) -> Unit | None:
        """A unit to run next: a retried one first (the earliest), else a fresh one; None at the end."""
        return heapq.heappop(self.retry) if self.retry else next(self.fresh, None)

    def _retry(self, unit: Unit) -> None:
        heapq.heappush(self.retry, unit)

    def _announce(self, names: list[str]) -> None:
        """A worker compiles kernels: announced once per render (the clock is the back-end's)."""
        if not self.announced:
            self.announced = True
            self.on_compile(names)

    def progress_now(self) -> Progress:
        return progress_now(self.film, self.settings, self.t0, self.note, self.failed)
