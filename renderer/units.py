"""Units of work: ranges of sample indices over the whole image, traced anywhere, merged in order.

A path's random numbers depend only on (seed, pixel, sample index), so any unit can be
traced in any process (renderer.render, renderer.workers) and the film adds the units'
films in unit order: the image has the same bits whatever traced them.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, NamedTuple

from .film import Film

if TYPE_CHECKING:
    from .integrator.wavefront import Tracer

# Unit size rule: about UNIT_PATHS path samples per unit, i.e. max(1, UNIT_PATHS // pixels)
# samples per pixel: 0.1-0.2 s on one core for the Cornell box with or without fog (0.9-1.2
# M samples/s per core, README), up to about 1 s for dense grids (3.6-8.7 us per sample).
# Small enough that a time limit wastes little and a killed worker loses little; large
# enough that shipping a unit's film back (24 bytes per pixel and channel) stays small.
# The first units are smaller (1, 1, 2, 4, ... spp up to that size), so that the first
# image comes quickly and both of two workers start at once. One sample per pixel is the
# least: a unit spans the whole image (tiles would need the tracer to take a pixel range).
UNIT_PATHS = 1 << 17


class Unit(NamedTuple):
    index: int  # merge order
    first_sample: int
    samples: int  # samples per pixel in this unit


def iter_units(width: int, height: int, spp: int) -> Iterator[Unit]:
    """The render's units in order (see UNIT_PATHS): a function of the image size and spp
    only. A generator, since a benchmark's "render until stopped" asks for 2^20 spp."""
    full = max(1, UNIT_PATHS // max(1, width * height))
    index, start, size = 0, 0, 1
    while start < spp:
        count = min(size, full, spp - start)
        yield Unit(index, start, count)
        index += 1
        start += count
        if index >= 2:  # 1, 1, 2, 4, ...: two small units first, one per worker of two
            size *= 2


def plan_units(width: int, height: int, spp: int) -> list[Unit]:
    return list(iter_units(width, height, spp))


def trace_unit(tracer: Tracer, unit: Unit, seed: int) -> Film:
    """One unit into a film of its own: merged by addition, in unit order, wherever traced."""
    part = Film(tracer.cs.width, tracer.cs.height)
    tracer.trace(part, unit.first_sample, unit.samples, seed)
    return part
