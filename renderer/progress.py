"""What a progressive render shares wherever its units are traced (renderer.render's pool
or this process, renderer.cluster_render's Dask cluster): the Progress it yields, when to
yield it, the in-order merge of finished units, and the time limit's clock.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from .film import Film
from .scene import IntegratorSettings

# Progress is yielded at most this often (and always for the first and the last merge):
# the image and its error estimate cost about a tenth of a unit's tracing at 256x256.
YIELD_INTERVAL = 0.5
# After a stop (time limit, target error), units in flight get this long to finish before
# their workers are terminated: long enough for a normal unit, short enough for "about a second".
STOP_GRACE = 0.5


@dataclass
class Progress:
    image: np.ndarray  # (H, W, 3) float32 linear RGB, row 0 at the top
    spp: int  # samples per pixel so far
    spp_target: int
    elapsed: float  # seconds since the render started (scene compile included)
    error_estimate: float  # estimated relMSE of `image` (nan before 2 spp)
    film: Film
    note: str = ""  # what went wrong, when the render stopped short for another reason than asked
    # The render could not go on (its worker processes kept dying): `note` says why, and a
    # caller reports an error (the command line exits non-zero) instead of a warning.
    failed: bool = False


def target_reached(film: Film, target_error: float) -> bool:
    if target_error > 0 and film.spp >= 4:
        err = film.rel_mse_estimate()
        return not math.isnan(err) and err <= target_error
    return False


def progress_now(film: Film, settings: IntegratorSettings, t0: float, note: str = "",
                 failed: bool = False) -> Progress:
    return Progress(film.image(), film.spp, settings.spp, time.perf_counter() - t0, film.rel_mse_estimate(),
                    film, note, failed)


class Pacer:
    """When to show progress: at the first merge, then at most every YIELD_INTERVAL."""

    def __init__(self) -> None:
        self.last = -math.inf
        self.pending = False  # merged since the last progress shown
        self.shown = False  # whether the caller has had an image

    def merged(self) -> bool:
        """Record a merge; True if progress is due now."""
        self.pending = True
        if time.perf_counter() - self.last < YIELD_INTERVAL:
            return False
        self.last = time.perf_counter()
        self.pending = False
        self.shown = True
        return True


class UnitMerger:
    """Adds finished units to the film in unit order; later ones wait in a buffer."""

    def __init__(self, film: Film):
        self.film = film
        self.next = 0  # index of the next unit to merge
        self.waiting: dict[int, Film] = {}

    def add(self, index: int, part: Film) -> bool:
        """Buffer a finished unit; True if the film changed (its predecessors were all in)."""
        self.waiting[index] = part
        merged = False
        while self.next in self.waiting:
            self.film.add(self.waiting.pop(self.next))
            self.next += 1
            merged = True
        return merged

    def merge_the_rest(self) -> bool:
        """On an early stop: merge every finished unit, in unit order, gaps and all."""
        merged = bool(self.waiting)
        for index in sorted(self.waiting):
            self.film.add(self.waiting.pop(index))
        return merged


def announce_compile(names: list[str]) -> None:
    """What a process says before it compiles kernels (once per machine and Haze build)."""
    try:
        print(f"haze: compiling kernels (first run only): {', '.join(names)}", file=sys.stderr, flush=True)
    except (OSError, ValueError):  # a broken stderr (closed pipe, full disk) must not stop a render
        pass


class Clock:
    """The time limit, paused while a worker compiles kernels (first run only): a limit of
    seconds must not stop a render before its first sample, or the compile forever."""

    def __init__(self, settings: IntegratorSettings, t0: float):
        self.deadline = t0 + settings.time_limit if settings.time_limit > 0 else math.inf
        self.paused_at: float | None = None

    def pause(self, compiling: bool) -> None:
        now = time.perf_counter()
        if compiling and self.paused_at is None:
            self.paused_at = now
        elif not compiling and self.paused_at is not None:
            self.deadline += now - self.paused_at
            self.paused_at = None

    def left(self) -> float:
        return math.inf if self.paused_at is not None else self.deadline - time.perf_counter()
