"""The background compile at enable, its state in the preferences, and Clear Kernel Cache.

Blender runs in a subprocess with private HOME / BLENDER_USER_RESOURCES and a private
HAZE_CACHE_DIR holding fake kernel folders. The background compile's command is replaced
by small stand-ins (one that keeps "compiling", one that succeeds, one that fails), so no
kernel is compiled: these tests are about the add-on's bookkeeping, not numba.
"""

from __future__ import annotations

import pytest

from bench.blender import isolated_site, run_blender, shared_numba_cache
from bench.installed import built_zip as built_zip_once

pytestmark = [pytest.mark.bpy]  # the real-compile test is also marked slow

BODY = r'''
import subprocess, time
import bpy
import bpy_helpers as H

B = H.addon_module("background")
kernel_cache = H.addon_module("kernel_cache")

ROOT = os.environ["HAZE_CACHE_DIR"]


def stand_in(code):
    B.command = lambda: [sys.executable, "-c", code]


def wait_for(kind, seconds=30.0):
    end = time.monotonic() + seconds
    while time.monotonic() < end and B.state().kind != kind:
        time.sleep(0.1)
    return B.state().kind


def clear():
    try:
        return sorted(bpy.ops.haze.clear_kernel_cache())
    except RuntimeError as error:  # the operator's ERROR report
        return str(error)


def listing():
    return sorted(os.listdir(ROOT))


class Layout:
    """Records what the panel draws (headless Blender draws no UI)."""

    def __init__(self, lines):
        self.lines, self.enabled = lines, True

    def box(self):
        return self

    def column(self, **kwargs):
        return self

    def row(self, **kwargs):
        return self

    def label(self, text="", icon="NONE"):
        self.lines.append(text)

    def operator(self, idname, **kwargs):
        self.lines.append(f"[{idname}{'' if self.enabled else ' disabled'}]")


def panel():
    HazePreferences = H.addon_module("preferences").HazePreferences
    lines = []
    HazePreferences.draw(type("Panel", (), {"layout": Layout(lines)})(), bpy.context)
    return lines


def main():
    out = {}
    stand_in("import time; print('compiling kernels (first run only): shade_media', flush=True); "
             "time.sleep(120)")
    addon = H.addon_package()
    addon.register()  # starts the stand-in compile
    job = B._job
    out["registered_kind"] = B.state().kind
    out["compiling_kind"] = wait_for("compiling")
    out["compiling_text"] = kernel_cache.state_text(B.state())
    out["second_start_same_job"] = B.start() is job
    out["panel_compiling"] = panel()
    out["refused"] = clear()
    out["after_refusal"] = listing()
    out["cache_text"] = kernel_cache.cache_text(__import__("pathlib").Path(ROOT))

    addon.unregister()  # stops the background compile
    out["stopped_returncode"] = job.process.poll()
    out["stopped_kind"] = B.state().kind

    stand_in("print('kernels ready (0.1 s)')")
    addon.register()
    out["numba_imported_by_register"] = "numba" in sys.modules
    out["ready_kind"] = wait_for("ready")
    out["ready_text"] = kernel_cache.state_text(B.state())
    out["panel_ready"] = panel()
    out["cleared"] = clear()
    out["after_clear"] = listing()
    out["other_files_kept"] = open(os.path.join(ROOT, "notes.txt")).read()
    out["linked_target_kept"] = sorted(os.listdir(os.environ["HAZE_OUTSIDE"]))
    out["after_clear_kind"] = B.state().kind
    stand_in("print('kernels ready (0.2 s)')")
    out["compile_button"] = sorted(bpy.ops.haze.compile_kernels())
    out["compile_button_kind"] = wait_for("ready")

    stand_in("import sys; print('numba exploded'); sys.exit(1)")
    B.start()
    out["failed_kind"] = wait_for("failed")
    out["failed_log"] = [str(B.state().log), open(B.state().log).read()]
    addon.unregister()

    precompile = H.addon_module("precompile")
    rigid_matrix = H.addon_module("export.camera").rigid_matrix
    from dataclasses import replace

    from renderer.compile import compile_scene
    exported = rigid_matrix(bpy.data.objects["Camera"].matrix_world)
    box = precompile.surface_box()
    as_exported = replace(box, camera=replace(box.camera, to_world=exported))
    out["camera_layouts"] = [layout(compile_scene(as_exported).camera.to_world),
                             layout(compile_scene(box).camera.to_world)]
    return out


def layout(array):
    return "C" if array.flags["C_CONTIGUOUS"] else "F" if array.flags["F_CONTIGUOUS"] else "A"
'''


@pytest.fixture(scope="module")
def prefs_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("prefs")
    root = tmp / "cache"
    outside = tmp / "outside"
    for folder in (root / "kernels-aaaa" / "media", root / "kernels-bbbb", root / "not-haze", outside):
        folder.mkdir(parents=True)
    (root / "kernels-aaaa" / "media" / "shade_media.nbc").write_bytes(b"x" * 3_000_000)
    (root / "kernels-bbbb" / "index.nbi").write_bytes(b"x" * 1000)
    (root / "notes.txt").write_text("mine")
    (outside / "precious.txt").write_text("not Haze's")
    (root / "kernels-link").symlink_to(outside, target_is_directory=True)
    run = run_blender(BODY, tmp / "run", timeout=300,
                      env={"HAZE_CACHE_DIR": str(root), "HAZE_BACKGROUND_COMPILE": "1",
                           "HAZE_OUTSIDE": str(outside)})
    assert run.returncode == 0 and run.result, run.describe()
    return run.result, root


def test_enable_starts_one_background_compile_and_shows_its_state(prefs_run):
    result, _ = prefs_run
    assert result["registered_kind"] in {"checking", "compiling"}
    assert result["compiling_kind"] == "compiling"
    assert result["compiling_text"].startswith("Compiling kernels in the background")
    assert result["second_start_same_job"]  # never a second process while one runs


def test_preferences_panel_shows_state_log_folder_size_and_button(prefs_run):
    result, root = prefs_run
    state, log, folder, size, compile_button, clear_button = result["panel_compiling"]
    assert state.startswith("Compiling kernels in the background") and log == f"Log: {root / 'warmup.log'}"
    assert folder == f"Kernel cache: {root}" and size == "Size: 3.0 MB in 2 builds"
    # Both buttons greyed out while compiling.
    assert compile_button == "[haze.compile_kernels disabled]"
    assert clear_button == "[haze.clear_kernel_cache disabled]"
    assert result["panel_ready"][0].startswith("Kernels ready")
    assert result["panel_ready"][-2:] == ["[haze.compile_kernels]", "[haze.clear_kernel_cache]"]


def test_clear_refuses_while_compiling(prefs_run):
    result, _ = prefs_run
    assert "being compiled" in result["refused"]
    assert {"kernels-aaaa", "kernels-bbbb"} <= set(result["after_refusal"])
    assert result["cache_text"] == "3.0 MB in 2 builds"  # the link to a foreign folder is not counted


def test_disabling_the_addon_stops_the_background_compile(prefs_run):
    result, _ = prefs_run
    assert result["stopped_returncode"] is not None
    assert result["stopped_kind"] == "stopped"


def test_clear_deletes_only_hazes_kernel_folders(prefs_run):
    result, root = prefs_run
    assert result["cleared"] == ["FINISHED"]
    assert result["after_clear"] == ["kernels-link", "not-haze", "notes.txt", "warmup.log"]
    assert result["other_files_kept"] == "mine"
    assert result["linked_target_kept"] == ["precious.txt"]


def test_kernels_see_one_camera_array_layout(prefs_run):
    """Numba compiles the camera kernels once per array layout: whatever layout F12's export
    gives (Blender's matrix_world arrives in Fortran order), the compiled scene's camera is in
    the background compile's C order, or the first F12 compiles them again."""
    result, _ = prefs_run
    exported, precompiled = result["camera_layouts"]
    assert exported == precompiled == "C"


def test_registering_imports_no_numba(prefs_run):
    result, _ = prefs_run
    assert result["numba_imported_by_register"] is False


def test_compile_kernels_button_starts_the_background_compile_again(prefs_run):
    result, _ = prefs_run
    assert result["after_clear_kind"] == "idle"  # "ready" would no longer be true
    assert result["compile_button"] == ["FINISHED"] and result["compile_button_kind"] == "ready"


def test_ready_and_failed_states(prefs_run):
    result, root = prefs_run
    assert result["ready_kind"] == "ready" and result["ready_text"].startswith("Kernels ready")
    assert result["failed_kind"] == "failed"
    log, text = result["failed_log"]
    assert log == str(root / "warmup.log") and "numba exploded" in text


REAL_BODY = r'''
import time
import bpy
import bpy_helpers as H

B = H.addon_module("background")


def main():
    H.enable_addon()
    end = time.monotonic() + 900
    while B.running() and time.monotonic() < end:
        time.sleep(0.2)
    state = B.state()
    return {"kind": state.kind, "seconds": state.seconds, "log": open(state.log).read(),
            "log_path": str(state.log)}
'''


@pytest.mark.slow
def test_real_background_compile_checks_a_warm_cache_and_is_ready(tmp_path):
    """addon/precompile.py in a child of the bpy module: found its interpreter and renderer."""
    cache = shared_numba_cache()  # warm after the other add-on tests (else this compiles it)
    run = run_blender(REAL_BODY, tmp_path, timeout=1000, numba_cache=cache,
                      env={"HAZE_BACKGROUND_COMPILE": "1"})
    assert run.returncode == 0 and run.result, run.describe()
    assert run.result["kind"] == "ready", run.result["log"]
    assert run.result["log_path"] == str(cache / "warmup.log")
    log = run.result["log"]
    for scene in ("surface box", "fog cube", "fog-filled box", "smoke ball"):
        assert f"\n{scene}: " in log
    assert "kernels ready" in log


EXTENSION_BODY = r'''
import time
import bpy
import addon_utils


def main():
    bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default", enable_on_install=True)
    name = next(m.__name__ for m in addon_utils.modules() if m.__name__.endswith(".haze"))
    background = sys.modules[name + ".background"]
    end = time.monotonic() + 900
    while background.running() and time.monotonic() < end:
        time.sleep(0.2)
    state = background.state()
    return {"kind": state.kind, "log": open(state.log).read()}
'''


@pytest.mark.slow
def test_installed_extensions_background_compile_uses_its_bundled_renderer(tmp_path):
    """In Blender the child runs Blender's Python (here python -S, like the isolated install
    test) and must find the renderer and numba in the extension's wheels."""
    built_zip = built_zip_once()
    run = run_blender(EXTENSION_BODY.replace("ZIP,", f"{str(built_zip)!r},"), tmp_path / "run", timeout=1000,
                      numba_cache=shared_numba_cache(), dev_paths=False, site=isolated_site(tmp_path),
                      env={"HAZE_BACKGROUND_COMPILE": "1"})
    assert run.returncode == 0 and run.result, run.describe()
    assert run.result["kind"] == "ready", run.result["log"]
    extensions = tmp_path / "run" / "blender_user" / "extensions"
    bundled = extensions / ".local" / "lib" / "python3.11" / "site-packages"
    assert f"renderer: {bundled / 'renderer'}" in run.result["log"]
