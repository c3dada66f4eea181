"""Issue 37, item 6: the memory estimate counts grids, images, environment maps, meshes and
worker processes, refuses a render over the available memory naming its largest item, and
caps the workers at the cores and the memory. In-process; the large arrays are broadcast
views (their nbytes is the size a real one would have, without the memory)."""

from __future__ import annotations

import numpy as np
import pytest

from examples.scenes import cornell_box, cornell_fog
from renderer.cores import usable_cores
from renderer.errors import SceneError
from renderer.memory import (
    PROCESS_BYTES,
    check_scene_memory,
    render_memory_bytes,
    scene_memory_bytes,
    workers_allowed,
)
from renderer.shading.program import ImageTexture

GB = 1_000_000_000


def _huge(shape: tuple[int, ...]) -> np.ndarray:
    return np.broadcast_to(np.float32(0.5), shape)


def test_a_dense_grid_is_counted_and_named() -> None:
    scene = cornell_fog(size=8, spp=1)
    scene.media[0].density = _huge((1400, 1400, 1400))  # 11 GB of float32
    assert scene_memory_bytes(scene, 1) > 2 * 1400**3 * 4
    with pytest.raises(SceneError, match=r"^media\[0\]\.density: the render needs about \d+\.\d GB"):
        check_scene_memory(scene, 1, available=8 * GB)


def test_an_image_and_an_environment_map_are_counted_and_named() -> None:
    scene = cornell_box(size=8, spp=1)
    scene.images = [ImageTexture("big", _huge((32768, 32768, 4)))]  # 17 GB
    with pytest.raises(SceneError, match=r"^images\[0\] \(big\): .*8\.0 GB available"):
        check_scene_memory(scene, 1, available=8 * GB)
    scene.images = []
    scene.environment.radiance_map = _huge((8165, 16330, 3))  # 1.6 GB of radiance, and its tables
    with pytest.raises(SceneError, match=r"^environment\.radiance_map: "):
        check_scene_memory(scene, 1, available=4 * GB)


def test_small_scenes_pass_and_each_worker_costs_its_process() -> None:
    scene = cornell_box(size=64, spp=1)
    check_scene_memory(scene, 2, available=8 * GB)
    extra = scene_memory_bytes(scene, 3) - scene_memory_bytes(scene, 2)
    assert extra == PROCESS_BYTES + render_memory_bytes(scene.film, 3) - render_memory_bytes(scene.film, 2)


def test_workers_are_capped_at_cores_and_memory() -> None:
    scene = cornell_box(size=64, spp=1)
    cores = usable_cores()
    assert workers_allowed(scene, 400, available=1000 * GB) == cores
    assert workers_allowed(scene, 1, available=1000 * GB) == 1
    fits_two = scene_memory_bytes(scene, 2) + 1
    assert workers_allowed(scene, 400, available=fits_two) == min(2, cores)
