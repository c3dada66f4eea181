"""Whether a render fits in this machine's memory: an estimate per pixel, checked before
rendering (the command line and F12), so a film too large fails at once with the memory
it needs instead of with a MemoryError, or the system killing the process, partway through.
"""

from __future__ import annotations

import os
import sys

from renderer.errors import SceneError
from renderer.scene import Film
from renderer.units import UNIT_PATHS, tile_rows

# Bytes per pixel a render holds: the film's sums, squares, counts, alpha and odd samples'
# sum and count (2 * 24 + 8 + 8 + 32), and per progress update the float32 image with the float64 mean
# and variance behind it.
FILM_BYTES_PER_PIXEL = 96
PROGRESS_BYTES_PER_PIXEL = 12 + 24 + 24
# Each worker process fills its own film, and the parent holds it again while merging: one
# unit's film, the size of a tile (the whole image unless it is larger than UNIT_PATHS pixels).
WORKER_BYTES_PER_PIXEL = 2 * FILM_BYTES_PER_PIXEL
# The render passes' sums when the film has them (film.aovs): integrator.paths.AOV_COUNT
# float64 columns (a constant here: importing the integrator would load numba).
AOV_BYTES_PER_PIXEL = 15 * 8
LIGHT_AOV_BYTES_PER_PIXEL = 18 * 8  # and integrator.paths.LIGHT_AOV_COUNT with film.light_aovs


def render_memory_bytes(film: Film, workers: int) -> int:
    """An estimate of the memory a render of `film` with `workers` processes needs."""
    pixels = film.width * film.height
    extra_workers = workers if workers > 1 else 0  # one worker renders in the calling process
    light = getattr(film, "light_aovs", False)
    aovs = AOV_BYTES_PER_PIXEL if getattr(film, "aovs", False) or light else 0
    aovs += LIGHT_AOV_BYTES_PER_PIXEL if light else 0
    worker_bytes = WORKER_BYTES_PER_PIXEL + 2 * aovs  # as WORKER_BYTES_PER_PIXEL: two films in flight
    tile_pixels = film.width * tile_rows(film.width, film.height, UNIT_PATHS)
    return (pixels * (FILM_BYTES_PER_PIXEL + aovs + PROGRESS_BYTES_PER_PIXEL)
            + tile_pixels * extra_workers * worker_bytes)


def available_memory_bytes() -> int | None:
    """Memory the machine can give a new render now (Linux MemAvailable), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


def check_render_memory(film: Film, workers: int, available: int | None = None) -> None:
    """Refuse a film whose render would need more memory than the machine has.

    The validator allows films up to MAX_FILM_SIDE on a side; whether one fits depends on
    the machine.
    """
    available = available_memory_bytes() if available is None else available
    needed = render_memory_bytes(film, workers)
    if available is not None and needed > available:
        size = f"{film.width}x{film.height}"
        raise SceneError(
            "film",
            f"a {size} render with {workers} worker(s) needs about {needed / 1e9:.1f} GB of memory; "
            f"this machine has {available / 1e9:.1f} GB available",
        )


def release_free_memory() -> None:
    """Hand the C heap's free pages back to the system (glibc only; elsewhere nothing).

    A scene export frees 100s of MB of row-sized temporaries (a .vdb read slab by slab);
    glibc keeps such freed heap pages mapped, so Blender's process would hold them for the
    whole render (measured: 94 MB of the 512^3 cloud's export). malloc_trim returns them.
    The pages of mapped files (a large grid's bricks, renderer.mapped) that the export and
    compile read are unmapped too: the workers map the file themselves.
    """
    from renderer.mapped import release_pages

    release_pages()
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    try:
        trim = ctypes.CDLL("libc.so.6").malloc_trim
    except (OSError, AttributeError):  # musl and other C libraries have no malloc_trim
        return
    trim(0)
