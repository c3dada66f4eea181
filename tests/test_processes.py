"""Issue 37, items 2, 3, 4 and 7: processes die cleanly, waits are bounded, output survives.

- A parent killed (SIGKILL) while its workers are inside a long kernel call takes them
  with it (the parent-death signal), and its scene file is removed by the next render;
  SIGTERM unwinds the render: one error line, workers and scene file gone.
- A render whose workers are all killed as they start exits non-zero with one error line.
- Progress into a closed pipe or a full disk (/dev/full) still writes the image, exit 0.
- A compile lock held by a stopped process is waited for only until the wait sees it is
  stopped; an unusable lock folder compiles without locks; both say so once.

The long kernel call is a closed white sphere seen from inside (paths never escape) at the
path-length cap: units take tens of seconds, while a worker whose parent died without the
death signal would only notice at its unit's end.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from examples.scenes import cornell_box, icosphere
from renderer.imageio import read_exr
from renderer.kernels import cache
from renderer.scene import Camera, Environment, Film, IntegratorSettings, Lobe, Material, Mesh, Scene
from renderer.scenefile import save_scene
from renderer.shipment import PREFIX, remove_orphans
from renderer.validate.scene import MAX_BOUNCES

ROOT = Path(__file__).resolve().parents[1]
pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc; Linux signals")


def _closed_sphere() -> Scene:
    """A white sphere around the camera, lit by its own emission: every path runs MAX_BOUNCES."""
    v, i = icosphere(2, radius=2.0)
    wall = Material("wall", [Lobe("diffuse", color=(1.0, 1.0, 1.0))], emission=(0.1, 0.1, 0.1),
                    emission_sides="both")
    settings = IntegratorSettings(spp=1000, max_bounces=MAX_BOUNCES, rr_depth=MAX_BOUNCES)
    return Scene(camera=Camera(np.eye(4), fov=60.0), film=Film(64, 64), integrator=settings,
                 materials=[wall], meshes=[Mesh("sphere", v, i, ["wall"])], environment=Environment())


def _children(pid: int) -> list[int]:
    """Processes whose parent is `pid` (a scan of /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            if int(stat[stat.rfind(")") + 2:].split()[1]) == pid:
                found.append(int(entry.name))
    return found


def _is_worker(pid: int) -> bool:
    try:
        return b"spawn_main" in Path(f"/proc/{pid}/cmdline").read_bytes()
    except OSError:
        return False


def _cpu_seconds(pid: int) -> float:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return 0.0
    fields = stat[stat.rfind(")") + 2:].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _alive(pid: int) -> bool:
    """Running, and not a zombie waiting for its parent to reap it."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat[stat.rfind(")") + 2] != "Z"


def _start_render(tmp_path: Path, scene: Scene, *extra: str, **popen) -> tuple[subprocess.Popen, Path]:
    save_scene(scene, tmp_path / "scene")
    out = tmp_path / "out.exr"
    env = dict(os.environ, TMPDIR=str(tmp_path / "tmp"))
    (tmp_path / "tmp").mkdir()
    command = [sys.executable, "-m", "renderer", "render", str(tmp_path / "scene"), "-o", str(out), *extra]
    popen.setdefault("stderr", subprocess.PIPE)
    return subprocess.Popen(command, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, **popen), out


def _busy_workers(process: subprocess.Popen, count: int, timeout: float = 900.0) -> list[int]:
    """The render's worker processes once `count` of them have each run 10 CPU seconds (past
    their imports, inside the sphere's long first units)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert process.poll() is None, process.stderr.read() if process.stderr else ""
        workers = [p for p in _children(process.pid) if _is_worker(p)]
        if len(workers) >= count and all(_cpu_seconds(p) >= 10.0 for p in workers):
            return workers
        time.sleep(0.5)
    pytest.fail("the workers never got busy")


def _gone_within(pids: list[int], seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while any(_alive(p) for p in pids):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.1)
    return True


def test_workers_inside_a_kernel_die_with_a_killed_parent(tmp_path: Path) -> None:
    process, _ = _start_render(tmp_path, _closed_sphere(), "--workers", "2", stderr=subprocess.DEVNULL)
    workers: list[int] = []
    try:
        workers = _busy_workers(process, 2)
        process.kill()
        process.wait(timeout=30)
        assert _gone_within(workers, 5.0), [p for p in workers if _alive(p)]
    finally:
        for pid in workers:  # the test's own clean-up if they outlived their parent
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)
        if process.poll() is None:
            process.kill()
    left = list((tmp_path / "tmp").glob(f"{PREFIX}{process.pid}-*"))
    assert left, "a SIGKILLed parent cannot remove its own scene file"
    remove_orphans(str(tmp_path / "tmp"))  # what the next render does first
    assert not list((tmp_path / "tmp").glob(f"{PREFIX}*"))


def test_sigterm_ends_the_render_with_one_error_line_and_no_leftovers(tmp_path: Path) -> None:
    process, _ = _start_render(tmp_path, _closed_sphere(), "--workers", "2")
    workers = _busy_workers(process, 2)
    process.send_signal(signal.SIGTERM)
    _, stderr = process.communicate(timeout=60)
    text = stderr.decode()
    errors = [line for line in text.splitlines() if line.strip().startswith("error:")]
    assert process.returncode == 128 + signal.SIGTERM, text
    assert errors == ["error: stopped by SIGTERM"] and "Traceback" not in text, text
    assert _gone_within(workers, 5.0)
    assert not list((tmp_path / "tmp").glob(f"{PREFIX}*"))


def test_a_render_whose_workers_all_die_exits_non_zero_with_one_error_line(tmp_path: Path) -> None:
    process, out = _start_render(tmp_path, cornell_box(size=8, spp=4), "--workers", "2")
    stop = threading.Event()

    def kill_workers() -> None:  # every worker, as soon as it appears
        while not stop.is_set():
            for pid in _children(process.pid):
                if _is_worker(pid):
                    try:
                        os.kill(pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
            time.sleep(0.01)

    killer = threading.Thread(target=kill_workers, daemon=True)
    killer.start()
    try:
        _, stderr = process.communicate(timeout=600)
    finally:
        stop.set()
        killer.join()
    text = stderr.decode()
    errors = [line for line in text.splitlines() if line.strip().startswith("error:")]
    assert process.returncode == 1, text
    assert len(errors) == 1 and "worker processes died" in errors[0] and "Traceback" not in text, text
    assert not out.exists()  # no samples: nothing to write


@pytest.mark.parametrize("target", ["closed pipe", "/dev/full"])
def test_a_broken_stderr_still_writes_the_image(tmp_path: Path, target: str) -> None:
    if target == "closed pipe":
        process, out = _start_render(tmp_path, cornell_box(size=8, spp=4), "--workers", "1")
        process.stderr.close()  # as `| head -c 0`: every write to stderr now fails with EPIPE
        code = process.wait(timeout=600)
    else:
        with open("/dev/full", "w") as full:
            process, out = _start_render(tmp_path, cornell_box(size=8, spp=4), "--workers", "1", stderr=full)
            code = process.wait(timeout=600)
    assert code == 0
    assert np.isfinite(read_exr(out)).all() and out.with_suffix(".png").exists()


HOLD_LOCK = """
import os, signal, sys
from renderer.kernels import cache
with cache.function_lock("held_by_a_stopped_process"):
    print("held", flush=True)
    os.kill(os.getpid(), signal.SIGSTOP)
"""


def test_a_lock_held_by_a_stopped_process_is_not_waited_for(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("HAZE_CACHE_DIR", str(tmp_path))
    holder = subprocess.Popen([sys.executable, "-c", HOLD_LOCK], cwd=ROOT, stdout=subprocess.PIPE,
                              env=dict(os.environ, HAZE_CACHE_DIR=str(tmp_path)))
    try:
        assert holder.stdout.readline() == b"held\n"
        t0 = time.monotonic()
        with cache.function_lock("held_by_a_stopped_process") as held:
            assert held
        assert time.monotonic() - t0 < 30.0
    finally:
        holder.kill()
        holder.wait()
    err = capsys.readouterr().err
    assert f"process {holder.pid} holds the compile lock" in err and "stopped" in err, err


def test_an_unusable_lock_folder_compiles_without_locks(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.setenv("HAZE_CACHE_DIR", str(tmp_path))
    locks = cache.kernel_cache_dir() / cache.LOCK_FOLDER
    locks.parent.mkdir(parents=True)
    locks.write_text("a file where the folder should be")
    with cache.function_lock("any") as held:
        assert held
    with cache.function_lock("other", blocking=False) as held:
        assert not held  # a warm-up leaves it to the real compile
    assert capsys.readouterr().err.count("compile locks unusable") == 1


def test_orphan_scene_files_of_live_processes_and_other_names_are_kept(tmp_path: Path) -> None:
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    files = {name: tmp_path / name for name in (
        f"{PREFIX}{dead.pid}-abcd-x.pkl", f"{PREFIX}{os.getppid()}-abcd-y.pkl",
        f"{PREFIX}{os.getpid()}-ab-z.pkl", "haze-scene-notapid-q.pkl", "other.pkl")}
    for file in files.values():
        file.write_bytes(b"")
    remove_orphans(str(tmp_path))
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(list(files)[1:])


def test_a_worker_started_by_a_thread_that_ends_lives_on() -> None:
    """The parent-death signal follows the thread that started a process: workers a render
    thread asks for (Blender's F12) must outlive it, to serve the next render."""
    from renderer.workers import Pool

    pool = Pool()
    thread = threading.Thread(target=pool.resize, args=(1,))
    thread.start()
    thread.join()
    try:
        time.sleep(2.0)
        assert len(pool.workers) == 1 and pool.workers[0].alive()
    finally:
        pool.shutdown()
