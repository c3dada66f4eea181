"""Whether a render fits in this machine's memory: an estimate per pixel, checked before
rendering (the command line and F12), so a film too large fails at once with the memory
it needs instead of with a MemoryError, or the system killing the process, partway through.
"""

from __future__ import annotations

import os
import sys

from renderer.cores import usable_cores
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


# What a render holds beside the film, per item of the scene (bytes per byte of the scene's
# arrays, or per triangle): a grid or image is held by the scene and again by its compiled
# table in this process (the workers map the shipment's copy, shared); an
# environment map adds its sampling tables (float64 pdf and cdfs per texel: about three
# times the float32 RGB map); a triangle costs its float64 corners and edges in the compiled
# geometry (9 * 8 * 2 bytes), its light-table row and Embree's BVH node share (about 100).
GRID_COPIES = 2
IMAGE_COPIES = 2
ENVIRONMENT_COPIES = 4
BYTES_PER_TRIANGLE = 250
# A worker process's own memory before its scene: Python, numba and LLVM, its kernels and
# Embree (`python -m bench worker_memory`: 98 MB of its own each), rounded up.
PROCESS_BYTES = 150_000_000


def _array_bytes(array) -> int:
    """Bytes of a dense array or a SparseGrid's bricks and index (renderer.media.bricks)."""
    if array is None:
        return 0
    if hasattr(array, "bricks"):
        return int(array.bricks.nbytes) + int(array.index.nbytes)
    return int(getattr(array, "nbytes", 0))


def scene_memory_items(scene) -> list[tuple[str, int]]:
    """(field, bytes a render holds for it) for the scene's grids, images, environment map
    and meshes, largest first."""
    items = []
    for i, medium in enumerate(scene.media):
        for name in ("density", "flame", "temperature"):
            items.append((f"media[{i}].{name}", GRID_COPIES * _array_bytes(getattr(medium, name))))
    for i, image in enumerate(scene.images):
        items.append((f"images[{i}] ({image.name})", IMAGE_COPIES * _array_bytes(image.pixels)))
    env_map = scene.environment.radiance_map
    items.append(("environment.radiance_map", ENVIRONMENT_COPIES * _array_bytes(env_map)))
    for i, mesh in enumerate(scene.meshes):
        arrays = [mesh.vertices, mesh.indices, mesh.normals, mesh.material_ids]
        arrays += [attribute.values for attribute in mesh.attributes]
        triangles = int(getattr(mesh.indices, "shape", (0,))[0])
        items.append((f"meshes[{i}] ({mesh.name})", 2 * sum(map(_array_bytes, arrays))
                      + BYTES_PER_TRIANGLE * triangles))
    return sorted((item for item in items if item[1] > 0), key=lambda item: -item[1])


def scene_memory_bytes(scene, workers: int) -> int:
    """The render's estimate: the film (render_memory_bytes), the scene's items and the
    worker processes' own memory."""
    return (render_memory_bytes(scene.film, workers) + sum(size for _, size in scene_memory_items(scene))
            + PROCESS_BYTES * workers)


def check_scene_memory(scene, workers: int, available: int | None = None) -> None:
    """Refuse a render of `scene` that needs more memory than the machine has, naming the
    largest item (the film, a grid, an image, the environment map, a mesh or the workers)."""
    available = available_memory_bytes() if available is None else available
    needed = scene_memory_bytes(scene, workers)
    if available is None or needed <= available:
        return
    film = ("film", render_memory_bytes(scene.film, workers))
    processes = (f"{workers} worker processes", PROCESS_BYTES * workers)
    name, size = max([film, processes, *scene_memory_items(scene)], key=lambda item: item[1])
    raise SceneError(name, f"the render needs about {needed / 1e9:.1f} GB of memory, {size / 1e9:.1f} GB of "
                     f"it for this; this machine has {available / 1e9:.1f} GB available")


def workers_allowed(scene, workers: int, available: int | None = None) -> int:
    """`workers`, capped at the cores this process may use and at the number whose memory fits
    (at least 1: check_scene_memory refuses a render even one cannot do)."""
    cores = usable_cores()
    available = available_memory_bytes() if available is None else available
    allowed = min(workers, cores)
    while allowed > 1 and available is not None and scene_memory_bytes(scene, allowed) > available:
        allowed -= 1
    return allowed


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
