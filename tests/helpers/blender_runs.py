"""A test file's Blender run: its script run once (bench.blender.run_blender), required to
have finished with a result, as a module fixture.

    renders = blender_fixture(BODY, "cameras", timeout=3600)

runs BODY once per test module, in a fresh folder of its own, and gives the tests its JSON
result (or what `read` makes of it: the images it wrote, read on the host).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from bench.blender import BlenderRun, run_blender, shared_numba_cache


def blender_result(body: str, folder: Path, *, timeout: float, compiles: bool = True,
                   env: dict[str, str] | None = None) -> BlenderRun:
    """`body` run in Blender in `folder`, which must exit cleanly with a result. compiles:
    the run renders with Haze, so it gets the numba cache the tests share (a cold compile
    costs minutes); an export-only run gets a cache of its own."""
    run = run_blender(body, folder, timeout=timeout, env=env,
                      numba_cache=shared_numba_cache() if compiles else None)
    assert run.returncode == 0 and run.result, run.describe()
    return run


def result(run: BlenderRun, folder: Path) -> dict:
    return run.result


def with_arrays(run: BlenderRun, folder: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The run's result and the arrays its script saved (arrays.npz in its folder)."""
    return run.result, dict(np.load(folder / "arrays.npz"))


def blender_fixture(body: str | Callable[[], str], folder: str, *, timeout: float, compiles: bool = True,
                    env: dict[str, str] | None = None,
                    read: Callable[[BlenderRun, Path], object] = result):
    """A module-scoped fixture: `body` (or the script `body()` writes) run once in a fresh
    folder named after `folder`, and `read(run, folder)` given to the tests (by default the
    run's result)."""

    @pytest.fixture(scope="module")
    def blender_run(tmp_path_factory):
        where = tmp_path_factory.mktemp(folder)
        script = body() if callable(body) else body
        return read(blender_result(script, where, timeout=timeout, compiles=compiles, env=env), where)

    return blender_run
