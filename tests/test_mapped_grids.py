"""Large sparse grids live in one mapped file (renderer.mapped): built into it row by row,
shipped to the workers by name (not copied), unmapped from the builder after the export.

No kernels run here: the grids are compared voxel for voxel with the dense arrays they came
from (bricks.py's lookups are tested on the same storage in test_media_bricks)."""

from __future__ import annotations

import gc
import mmap
import os

import numpy as np
import pytest

from renderer import mapped
from renderer.media import bricks
from renderer.media.bricks import sparse_from_dense
from renderer.scene import IntegratorSettings
from renderer.shipment import load_shipment, shipped


@pytest.fixture
def small_files(monkeypatch):
    """Grids of 10 bricks or more go to files (the real threshold is MBs)."""
    monkeypatch.setattr(bricks, "MIN_BYTES", 10 * bricks.SPAN**3 * 4)


def _cloud(seed: int, shape=(40, 36, 44)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    values = rng.uniform(0.0, 2.0, shape).astype(np.float32)
    z, y, x = np.indices(shape)
    return np.where((z - 20) ** 2 + (y - 18) ** 2 + (x - 22) ** 2 < 15**2, values, np.float32(0.0))


def _file_of(values: np.ndarray) -> mmap.mmap | None:
    base = values
    while isinstance(base, np.ndarray):
        base = base.base
    return base if isinstance(base, mmap.mmap) else None


def test_a_large_grid_is_built_into_a_mapped_file_with_its_brick_bounds(small_files):
    dense = _cloud(1)
    grid = sparse_from_dense({"density": dense})["density"]
    assert _file_of(grid.bricks) is not None and grid.bricks.flags.writeable
    np.testing.assert_array_equal(grid.to_dense(), dense)
    assert not grid.zero_led()[0].any()
    axes = (1, 2, 3)
    np.testing.assert_array_equal(grid.bounds[0], grid.bricks.min(axis=axes))
    np.testing.assert_array_equal(grid.bounds[1], grid.bricks.max(axis=axes))
    assert grid.max() == dense.max() and grid.min() == 0.0
    doubled = grid.map(lambda v: 2.0 * v)
    np.testing.assert_array_equal(doubled.to_dense(), 2.0 * dense)
    np.testing.assert_array_equal(doubled.bounds[1], 2.0 * grid.bounds[1])
    path = mapped.reference(grid.zero_led().reshape(-1))[1]
    assert os.path.exists(path)
    del grid, doubled
    gc.collect()
    assert not os.path.exists(path)  # the file goes with its last array


def test_a_small_grid_stays_in_memory():
    grid = sparse_from_dense({"density": _cloud(1)})["density"]
    assert _file_of(grid.bricks) is None and mapped.reference(grid.zero_led().reshape(-1)) is None


def test_released_pages_read_back_the_same_values(small_files):
    dense = _cloud(2)
    grid = sparse_from_dense({"density": dense})["density"]
    mapped.release_pages()
    np.testing.assert_array_equal(grid.to_dense(), dense)


def test_a_shipment_names_the_mapped_file_and_its_key_follows_the_contents(small_files):
    """The bricks are not copied into the shipment; the worker maps the grid's own file,
    writable and aligned as the parent's array (the kernels' types). Two builds of the same
    values (two files) give one key, so workers keep their tracer across exports."""
    settings = IntegratorSettings()

    def scene(seed):
        grid = sparse_from_dense({"density": _cloud(seed)})["density"]
        return {"grid": grid.zero_led().reshape(-1), "other": np.arange(5.0)}

    first, again, other = scene(3), scene(3), scene(4)
    with shipped(first, settings) as a, shipped(again, settings) as b, \
            shipped(other, settings) as c:
        assert a.key == b.key != c.key
        assert os.path.getsize(a.path) < first["grid"].nbytes // 4
        loaded, _ = load_shipment(a.path)
        np.testing.assert_array_equal(loaded["grid"], first["grid"])
        np.testing.assert_array_equal(loaded["other"], first["other"])
        theirs = loaded["grid"]
        assert theirs.flags.writeable and theirs.flags.aligned and theirs.flags.c_contiguous
        assert _file_of(theirs) is not None



def test_a_fires_grids_are_joined_in_a_mapped_file(small_files, monkeypatch):
    """Several large grids (a fire's density and flame) compile into one grid_data array in
    a mapped file too, not in this process's memory; its values are the grids', in order."""
    from renderer.media.compile import build_media_data
    from renderer.scene import Medium

    monkeypatch.setattr(mapped, "MIN_BYTES", bricks.MIN_BYTES)
    dense = _cloud(5)
    grids = sparse_from_dense({"density": dense, "flame": np.where(dense > 1.5, dense, 0.0)})
    medium = Medium("fire", type="grid", sigma_a=(1, 1, 1), sigma_s=(1, 1, 1), emission=(1, 1, 1),
                    density=grids["density"], flame=grids["flame"])
    data = build_media_data([medium]).grid_data
    assert mapped.reference(data) is not None
    joined = np.concatenate([grids[n].zero_led().reshape(-1) for n in ("density", "flame")])
    np.testing.assert_array_equal(data, joined)


def test_a_writer_dropped_halfway_leaves_no_file():
    writer = mapped.FileWriter()
    writer.write(np.arange(10.0))
    path = writer.path
    assert os.path.exists(path)
    del writer
    gc.collect()
    assert not os.path.exists(path)
