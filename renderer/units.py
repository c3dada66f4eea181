"""Units of work: a range of sample indices over a band of the image's rows, traced
anywhere, merged in order.

A path's random numbers depend only on (seed, pixel of the full frame, sample index), so
any unit can be traced in any process (renderer.render, renderer.workers,
renderer.cluster_tasks), and the film adds the units' films in unit order: the image has
the same bits whatever traced them, and a tile's pixels get the numbers they get in a
unit over the whole image (renderer.integrator.camera_rays).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING, NamedTuple

if TYPE_CHECKING:  # the film and the tracer load numba: planning units (renderer.memory) does not
    from .film import Film
    from .integrator.wavefront import Tracer

# Unit size rule: about UNIT_PATHS path samples per unit: 0.1-0.2 s on one core for the
# Cornell box with or without fog (0.9-1.2 M samples/s per core, docs/benchmarks.md), up to about 1 s
# for dense grids (3.6-8.7 us per sample). Small enough that a time limit wastes little
# and a killed worker loses little; large enough that the per-unit overhead (a task and a
# film sent back) stays small against the tracing.
#
# An image of at most UNIT_PATHS pixels is one tile: a unit is every pixel for
# max(1, UNIT_PATHS // pixels) samples, the first units smaller (1, 1, 2, 4, ... spp) so
# that the first image comes quickly and both of two workers start at once.
#
# A larger image is cut into tiles of whole rows (bands), as few as keep a tile at most
# UNIT_PATHS pixels where a row allows (a 3840x2160 frame: 64 bands of 34 rows, 130560
# pixels; a row is the least), of one height but for a shorter last; a unit is one tile
# for 1 sample per pixel (more only while a tile stays under UNIT_PATHS paths). A tile's
# film (96 bytes a pixel) is what a worker sends back: 12.5 MB for a 4K band, against 800
# MB for a whole-frame unit. Whole rows, not squares: a band is a contiguous range of the
# window's pixels, so the tracer's linear sample index needs only an offset and a tile's
# film merges as one slice (squares might trace camera rays a little more coherently; not
# measured). Units go pass by pass (a sample range), tile by tile within a pass.
UNIT_PATHS = 1 << 17


class Unit(NamedTuple):
    index: int  # merge order
    first_sample: int
    samples: int  # samples per pixel in this unit
    first_row: int  # the tile: rows first_row .. first_row + rows - 1 of the rendered window,
    rows: int  # every column (the whole window for an image that is one tile)

    def describe(self) -> str:
        """What the unit traces, for messages: "samples 4..7 of rows 34..67"."""
        return (f"samples {self.first_sample}..{self.first_sample + self.samples - 1} of rows "
                f"{self.first_row}..{self.first_row + self.rows - 1}")


def tile_rows(width: int, height: int, unit_paths: int) -> int:
    """Rows per tile: the height for an image of at most unit_paths pixels, else the band
    height that cuts it into the fewest tiles of at most unit_paths pixels (one row the
    least), spread evenly."""
    if width * height <= unit_paths:
        return max(1, height)
    tiles = -(-height // max(1, unit_paths // max(1, width)))  # of the most rows that fit
    return -(-height // tiles)  # no more than those


def iter_units(width: int, height: int, spp: int, unit_paths: int | None = None) -> Iterator[Unit]:
    """The render's units in order (see UNIT_PATHS): a function of the image size and spp
    only (unit_paths: UNIT_PATHS unless given, read at the call). A generator, since a
    benchmark's "render until stopped" asks for 2^20 spp."""
    unit_paths = UNIT_PATHS if unit_paths is None else unit_paths
    rows = tile_rows(width, height, unit_paths)
    bands = [(y, min(rows, height - y)) for y in range(0, max(1, height), rows)]
    full = max(1, unit_paths // max(1, width * rows))
    index, start, size = 0, 0, 1
    while start < spp:
        count = min(size, full, spp - start)
        for first_row, band in bands:
            yield Unit(index, start, count, first_row, band)
            index += 1
        start += count
        if index >= 2:  # 1, 1, 2, 4, ...: two small units first, one per worker of two
            size *= 2


def plan_units(width: int, height: int, spp: int, unit_paths: int | None = None) -> list[Unit]:
    return list(iter_units(width, height, spp, unit_paths))


def trace_unit(tracer: Tracer, unit: Unit, seed: int) -> Film:
    """One unit into a film of its own, of its tile's size: merged into place by addition,
    in unit order, wherever traced."""
    from .film import Film

    part = Film(tracer.cs.width, unit.rows, unit.first_row)
    tracer.trace(part, unit.first_sample, unit.samples, kernel_seed(seed))
    return part


def kernel_seed(seed: int) -> int:
    """A seed in [0, 2**64) as the int64 with the same bits: the kernels take an int64 and
    hash it as uint64 (kernels.rng.path_key), so seeds from 2**63 on give the keys of their
    unsigned value instead of a typing error (numba would type such an int as uint64)."""
    return seed - (1 << 64) if seed >= 1 << 63 else seed
