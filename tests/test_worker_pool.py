"""The worker pool of renderer.render: fixed units merged in unit order (the same bits
for any number of workers), persistent workers, and faults: a killed worker, a unit that
never ends (a lone voxel of density 1e8), a cancelled render.

Scenes are tiny (24x24) and seeded; nothing asserts on timing except the bounds the
issues set (a render with a 2 s time limit ends within 10 s, Ctrl-C within a few
seconds), which are generous against the work involved.
"""

from __future__ import annotations

import os
import signal
import threading
import time

import numpy as np
import pytest

from examples.media_scenes import grid_medium, with_grid_medium
from examples.scenes import cornell_box
from helpers.films import assert_same_bits
from renderer import render as render_module
from renderer import units as units_module
from renderer.compile import compile_scene
from renderer.film import Film
from renderer.integrator.wavefront import Tracer
from renderer.progress import UnitMerger
from renderer.render import Progress, render_progressive, worker_pids
from renderer.scene import Scene
from renderer.units import UNIT_PATHS, plan_units


def frames(scene: Scene, **options) -> list[Progress]:
    return list(render_progressive(scene, **options))


def lone_dense_voxel(size: int = 24, spp: int = 4) -> Scene:
    """Issue 17's render that never ends: a grid that is zero but for one voxel of 1e8. The
    voxel emits (flame), so the cells around it are not regular-tracked (issue 18,
    renderer/media/regular.py) and a ray through them still makes ~1e7 null collisions;
    the empty cells elsewhere cost nothing, as before."""
    density = np.zeros((8, 8, 8), np.float32)
    density[4, 4, 4] = 1e8
    medium = grid_medium("lone", density, (0.0, 0.0, 0.0), (0.5, 0.5, 0.5), sigma_a=(0.5, 0.5, 0.5),
                         sigma_s=(0.5, 0.5, 0.5), emission=(0.1, 0.1, 0.1), flame=density)
    return with_grid_medium(cornell_box(size=size, spp=spp), medium)


def warm_kernels(scene: Scene) -> None:
    """Compile (or load) the scene's kernels here, so a timed render does not time a compile."""
    Tracer(compile_scene(scene), scene.integrator)


@pytest.fixture(scope="module")
def reference() -> Film:
    """24x24 Cornell box, 64 spp, traced in this process."""
    return frames(cornell_box(size=24, spp=64), workers=1)[-1].film


# --- units ------------------------------------------------------------------------------


def test_units_cover_every_sample_once_and_depend_on_image_and_spp_only():
    """Images of at most UNIT_PATHS pixels: one tile, consecutive sample ranges (tiled
    images: tests/test_units.py)."""
    for width, height, spp in [(24, 24, 64), (128, 128, 1000), (1, 1, 1)]:
        units = plan_units(width, height, spp)
        assert [u.index for u in units] == list(range(len(units)))
        assert {(u.first_row, u.rows) for u in units} == {(0, height)}
        starts = [u.first_sample for u in units]
        assert starts == sorted(starts) and starts[0] == 0
        assert all(a.first_sample + a.samples == b.first_sample for a, b in zip(units, units[1:]))
        assert units[-1].first_sample + units[-1].samples == spp
        assert units == plan_units(width, height, spp)


def test_units_start_small_and_stay_near_unit_paths():
    units = plan_units(128, 128, 1000)
    assert [u.samples for u in units[:4]] == [1, 1, 2, 4]
    assert max(u.samples for u in units) == UNIT_PATHS // (128 * 128)
    assert {u.samples for u in plan_units(4096, 4096, 3)} == {1}  # one sample is the least


def test_units_are_merged_in_order_and_the_rest_on_a_stop():
    merged = Film(2, 1)
    merger = UnitMerger(merged)
    part = [Film(2, 1) for _ in range(4)]
    for i, p in enumerate(part):
        p.sum[:] = 10.0 ** i
        p.n[:] = i + 1  # unit i holds i + 1 samples per pixel
    assert not merger.add(1, part[1])  # waits for unit 0
    assert merger.add(0, part[0]) and merged.spp == 1 + 2
    assert not merger.add(3, part[3])  # unit 2 is not done
    assert merger.merge_the_rest() and merged.spp == 1 + 2 + 4
    assert merged.sum[0, 0] == 1.0 + 10.0 + 1000.0


def run_worker_loop(conn) -> None:
    """A worker's loop run here, until it is sent None; it ignores SIGINT, so restore ours."""
    from renderer import workers

    saved = signal.getsignal(signal.SIGINT)
    try:
        workers._worker_main(conn)
    finally:
        signal.signal(signal.SIGINT, saved)


def test_a_worker_builds_its_tracer_once_per_scene(tmp_path):
    """The worker loop, run here: two units of one scene, then one of another, then stop."""
    from multiprocessing import Pipe

    from renderer.shipment import shipped

    parent, child = Pipe()
    scenes = [cornell_box(size=8, spp=2), cornell_box(size=8, spp=2)]
    scenes[1].materials[0].lobes[0].color = (0.5, 0.5, 0.5)  # another scene: another key
    with shipped(compile_scene(scenes[0]), scenes[0].integrator) as first, \
            shipped(compile_scene(scenes[1]), scenes[1].integrator) as second:
        assert first.key != second.key
        units = plan_units(8, 8, 2)
        for shipment, unit in [(first, units[0]), (first, units[1]), (second, units[0])]:
            parent.send((shipment, unit, 0))
        parent.send(None)
        run_worker_loop(child)
    replies = []
    while parent.poll():
        replies.append(parent.recv())
    # ("compile" first when the kernels are not cached yet: that depends on earlier tests.)
    assert [r[0] for r in replies if r[0] != "compile"] == ["ready", "done", "done", "ready", "done"]
    assert all((r[2].n == 1).all() for r in replies if r[0] == "done")


def _smoke(value: float) -> Scene:
    density = np.full((16, 16, 16), 0.5, np.float32)
    density[3, 4, 5] = value
    smoke = grid_medium("smoke", density, (0.0, -0.5, 0.0), (0.4, 0.4, 0.4), (1, 1, 1), (1, 1, 1))
    return with_grid_medium(cornell_box(size=8, spp=1, boxes=False), smoke)


def test_a_shipment_maps_its_arrays_and_its_key_covers_them():
    """Workers get the scene's arrays as views of one copy-on-write map of the shipment file
    (one copy per machine, issue 18 item 3), writable and aligned as the parent's were (so the
    kernels' types, and cache entries, are the same); the key hashes the arrays too."""
    from renderer.shipment import load_shipment, shipped

    scene = _smoke(2.0)
    cs = compile_scene(scene)
    with shipped(cs, scene.integrator) as shipment, \
            shipped(compile_scene(_smoke(3.0)), scene.integrator) as other:
        assert shipment.key != other.key  # one voxel differs
        loaded, _ = load_shipment(shipment.path)
        for mine, theirs in [(cs.media.grid_data, loaded.media.grid_data), (cs.vertices, loaded.vertices)]:
            np.testing.assert_array_equal(theirs, mine)
            assert theirs.flags.writeable and theirs.flags.aligned and theirs.flags.c_contiguous
            base = theirs
            while isinstance(base, np.ndarray):
                base = base.base
            assert isinstance(base, memoryview)  # a view of the map, not a copy
        del loaded, theirs, base


def test_a_failing_worker_reports_the_error_and_goes_on():
    from multiprocessing import Pipe

    from renderer.shipment import Shipment

    parent, child = Pipe()
    parent.send((Shipment("no-such-scene", "/nonexistent/haze-scene.pkl"), plan_units(8, 8, 1)[0], 0))
    parent.send(None)
    run_worker_loop(child)
    kind, index, error, text = parent.recv()
    assert (kind, index) == ("error", 0) and isinstance(error, FileNotFoundError) and "Traceback" in text


class StubWorker:
    """What _PoolRender reads of a worker: its unit and whether it compiles."""

    def __init__(self) -> None:
        self.unit, self.compiling = None, False


def test_a_compile_in_workers_is_announced_once_in_the_parent_and_pauses_the_time_limit(monkeypatch):
    workers = [StubWorker(), StubWorker()]
    monkeypatch.setattr(render_module.pool, "workers", workers)
    scene = cornell_box(size=4, spp=1)
    scene.integrator.time_limit = 5.0
    announced: list[list[str]] = []
    run = render_module._PoolRender(None, scene.integrator, Film(4, 4), iter(plan_units(4, 4, 1)),
                                    time.perf_counter(), 0.0, 2, announced.append)
    run._handle([(workers[0], ("compile", ["shade_media"])), (workers[1], ("compile", ["shade_media"]))])
    assert announced == [["shade_media"]]
    assert run.clock.left() == float("inf")  # minutes of compiling do not count against 5 s
    run._handle([(workers[0], ("ready",))])
    assert run.clock.left() == float("inf")  # the other still compiles
    run._handle([(workers[1], ("ready",))])
    assert 0.0 < run.clock.left() <= 5.0


# --- determinism and persistence --------------------------------------------------------


@pytest.mark.slow
def test_two_workers_give_the_bits_of_one_process(reference: Film):
    scene = cornell_box(size=24, spp=64)
    assert_same_bits(frames(scene, workers=2)[-1].film, reference)
    assert_same_bits(frames(scene, workers=1, in_process=False)[-1].film, reference)


@pytest.mark.slow
def test_a_tiled_render_on_two_workers_gives_the_bits_of_one_process(monkeypatch):
    """Tiles without a large image: UNIT_PATHS lowered so a 24x24 box is 3 bands of 8 rows, 1
    spp per unit (planned in this process only; on a Dask cluster: tests/test_cluster.py)."""
    monkeypatch.setattr(units_module, "UNIT_PATHS", 200)
    assert [(u.first_row, u.rows) for u in plan_units(24, 24, 1)] == [(0, 8), (8, 8), (16, 8)]
    reference = frames(cornell_box(size=24, spp=6), workers=1, in_process=True)[-1].film
    last = frames(cornell_box(size=24, spp=6), workers=2)[-1]
    assert last.spp == 6 and (last.film.n == 6).all() and not last.note
    assert_same_bits(last.film, reference)


@pytest.mark.slow
def test_every_progress_counts_whole_units_in_order(reference: Film):
    seen = frames(cornell_box(size=24, spp=64), workers=2)
    sums = np.cumsum([u.samples for u in plan_units(24, 24, 64)])
    assert [p.spp for p in seen] == sorted(p.spp for p in seen)
    assert {p.spp for p in seen} <= set(sums.tolist()) and seen[-1].spp == 64
    assert (seen[-1].film.n == 64).all()


@pytest.mark.slow
def test_a_second_render_reuses_the_workers():
    scene = cornell_box(size=24, spp=8)
    frames(scene, workers=2)
    first = worker_pids()
    assert len(first) == 2
    scene.integrator.seed = 7  # another render of the same scene: same tracers, same processes
    frames(scene, workers=2)
    assert worker_pids() == first


@pytest.mark.slow
def test_two_renders_at_once_do_not_mix(reference: Film):
    """A second generator started while the first runs gets workers of its own."""
    first = render_progressive(cornell_box(size=24, spp=64), workers=2)
    second = render_progressive(cornell_box(size=24, spp=64), workers=1, in_process=False)
    a = b = None
    for a, b in zip(first, second):  # noqa: B007
        pass
    a = [a, *first][-1]
    b = [b, *second][-1]
    assert_same_bits(a.film, reference)
    assert_same_bits(b.film, reference)


# --- faults -----------------------------------------------------------------------------


@pytest.mark.slow
def test_a_killed_worker_costs_only_its_unit(reference: Film):
    frames(cornell_box(size=24, spp=8), workers=2)  # workers up and the tracer's kernels loaded
    killed: list[int] = []
    last = None
    for last in render_progressive(cornell_box(size=24, spp=64), workers=2):  # noqa: B007
        if not killed:  # after the first unit: 63 of 64 spp are still to come
            killed = worker_pids()
            for pid in killed:
                os.kill(pid, signal.SIGKILL)
    assert last is not None and not last.note
    assert (last.film.n == 64).all()  # every sample exactly once
    assert_same_bits(last.film, reference)
    assert not set(killed) & set(worker_pids())


@pytest.mark.slow
def test_a_cancelled_render_keeps_its_units_and_the_pool_recovers(reference: Film):
    scene = cornell_box(size=24, spp=64)
    run = render_progressive(scene, workers=2)
    first = next(run)
    run.close()  # as the add-on does on Esc
    assert first.spp >= 1 and (first.film.n == first.spp).all()
    assert np.isfinite(first.image).all()
    assert_same_bits(frames(scene, workers=2)[-1].film, reference)


@pytest.mark.slow
def test_a_lone_dense_voxel_stops_at_the_time_limit():
    scene = lone_dense_voxel()
    warm_kernels(scene)
    scene.integrator.time_limit = 2.0
    started = time.perf_counter()
    seen = frames(scene, workers=1)
    assert time.perf_counter() - started < 10.0
    last = seen[-1]
    assert np.isfinite(last.image).all() and last.image.shape == (24, 24, 3)
    assert (last.film.n == last.spp).all()
    if last.spp == 0:
        assert "time limit" in last.note


@pytest.mark.slow
def test_ctrl_c_stops_a_render_inside_a_kernel():
    scene = lone_dense_voxel()
    warm_kernels(scene)
    frames(cornell_box(size=24, spp=1), workers=1, in_process=False)  # a worker is up
    pids = worker_pids()
    sent: list[float] = []

    def ctrl_c() -> None:
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    interrupt = threading.Timer(2.0, ctrl_c)
    interrupt.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            frames(scene, workers=1, in_process=False)  # no time limit: only Ctrl-C ends it
        stopped = time.perf_counter()
    finally:
        interrupt.cancel()
    assert stopped - sent[0] < 2.0  # "within about a second"; the bound leaves room for a busy machine
    assert not set(pids) & set(worker_pids())  # the worker stuck in the kernel was terminated


USER_SCRIPT = """\
import sys
sys.path[:0] = {paths!r}
print("the user's script runs", flush=True)
from examples.scenes import cornell_box
from renderer.render import render_progressive

final = list(render_progressive(cornell_box(size=16, spp=2), workers=2))[-1]
print("rendered", int(final.film.n.sum()), flush=True)
"""


@pytest.mark.slow
def test_workers_never_run_the_users_script_again(tmp_path):
    """A script run by path (its __main__ has a __file__), without a __main__ guard, renders
    on two workers: spawn would have each worker run it again (here it would start workers
    of its own while bootstrapping, and a bpy script fails to import bpy there). It runs
    once and prints no traceback."""
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    script = tmp_path / "user_script.py"
    script.write_text(USER_SCRIPT.format(paths=[str(repo)]))
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    done = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=900)
    output = done.stdout + done.stderr
    assert done.returncode == 0, output
    assert output.count("the user's script runs") == 1, output
    assert "Traceback" not in output and "rendered 512" in output, output
