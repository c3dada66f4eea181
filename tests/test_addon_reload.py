"""Disable and enable the add-on, then F12: it starts warm (issue 19).

Blender enables the installed extension the way a user does (addon_utils.enable; with
HAZE_TEST_ADDON=clone the checkout's add-on linked into the user's add-on folder), renders
the fog box, disables and enables it, renders again, then loads factory settings, enables it
and renders a third time, and once more after importing the add-on and the renderer afresh
(new named-tuple classes). Numba's event API records every compile. The kernel cache is a
copy of the shared warm test cache with one small kernel (integrator.splat) taken out, so the
first F12 really compiles something and must say so in the render stats; the later ones
must compile nothing and say nothing.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from bench.blender import REPO, addon_mode, isolated_site, run_blender, shared_numba_cache
from bench.installed import built_zip as built_zip_once

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

BODY = r'''
import time
import bpy  # first: it puts Blender's own modules (addon_utils) on sys.path
import addon_utils
import numba.core.event as numba_event
import bpy_helpers as H
import blender_cornell as C

# The installed extension's package, or (HAZE_TEST_ADDON=clone) the checkout's add-on folder
# linked into BLENDER_USER_RESOURCES/scripts/addons.
ADDON = "haze" if os.environ[H.ADDON_MODE_ENV] == "clone" else H.EXTENSION_PACKAGE
stats = []


class CompileLog(numba_event.Listener):
    def __init__(self):
        self.names = []

    def on_start(self, event):
        self.names.append(event.data["dispatcher"].py_func.__name__)

    def on_end(self, event):
        pass


class Recorder:
    def __init__(self, engine):
        self._engine = engine

    def __getattr__(self, name):
        return getattr(self._engine, name)

    def update_stats(self, stats_text, info):
        stats.append(info)
        self._engine.update_stats(stats_text, info)


def record_stats():
    session = sys.modules[ADDON + ".session"].RenderSession
    if getattr(session, "recorded", False):
        return
    original = session.__init__

    def init(self, engine, depsgraph, *args, **kwargs):
        original(self, Recorder(engine), depsgraph, *args, **kwargs)
    session.__init__ = init
    session.recorded = True


def f12(name):
    record_stats()
    scene = C.build_fog_cornell(16, 16, max_bounces=3)
    H.configure_haze(scene, 2, 3, seed=0, workers=1)
    stats.clear()
    log = CompileLog()
    started = time.perf_counter()
    with numba_event.install_listener("numba:compile", log):
        H.render_exr(scene, os.path.join(os.getcwd(), name + ".exr"))
    return {"seconds": time.perf_counter() - started, "compiled": log.names, "stats": list(stats)}


def main():
    global PATHS
    out = {}
    assert addon_utils.enable(ADDON, default_set=True) is not None
    out["first"] = f12("first")
    PATHS = sys.modules["renderer.integrator.state"].Paths
    addon_utils.disable(ADDON, default_set=True)
    addon_utils.enable(ADDON, default_set=True)
    out["re_enabled"] = f12("re_enabled")
    bpy.ops.wm.read_factory_settings()
    addon_utils.enable(ADDON, default_set=True)
    out["factory_settings"] = f12("factory_settings")
    # The issue's suspect: a reload recreating the renderer's named-tuple classes. Forget
    # every module of the add-on and the renderer, so both are imported afresh.
    addon_utils.disable(ADDON, default_set=True)
    ours = (ADDON, "renderer")
    for name in [m for m in sys.modules if m in ours or m.startswith(tuple(o + "." for o in ours))]:
        del sys.modules[name]
    addon_utils.enable(ADDON, default_set=True)
    out["reimported"] = f12("reimported")
    out["named_tuples_recreated"] = sys.modules["renderer.integrator.state"].Paths is not PATHS
    out["cache_root"] = os.environ["HAZE_CACHE_DIR"]
    return out
'''

COMPILING = "Haze | Compiling kernels (first run only)…"


def partly_cold_cache(root: Path) -> Path:
    """A copy of the shared warm cache without integrator.splat: the first F12 compiles a little."""
    shutil.copytree(shared_numba_cache(), root, symlinks=True)
    for index in root.glob("kernels-*/integrator/splat.splat-*"):
        index.unlink()
    return root


@pytest.fixture(scope="module")
def reload_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("reload")
    root = partly_cold_cache(tmp / "cache")
    if addon_mode() == "clone":
        addons = tmp / "run" / "blender_user" / "scripts" / "addons"
        addons.mkdir(parents=True)
        (addons / "haze").symlink_to(REPO / "addon", target_is_directory=True)
    run = run_blender(BODY, tmp / "run", timeout=900, env={"HAZE_CACHE_DIR": str(root)})
    assert run.returncode == 0 and run.result, run.describe()
    return run.result


def test_first_f12_on_a_cold_cache_says_it_compiles(reload_run):
    # F12 renders in a worker process (one here), which compiles splat; the stats say so.
    first = reload_run["first"]
    assert COMPILING in first["stats"]
    assert first["stats"].index(COMPILING) < next(i for i, s in enumerate(first["stats"]) if "Sample" in s)


@pytest.mark.parametrize("render", ["re_enabled", "factory_settings", "reimported"])
def test_disable_and_enable_then_f12_starts_warm(reload_run, render):
    again = reload_run[render]
    assert again["compiled"] == [], f"compiled again after {render}: {again['compiled']}"  # in Blender
    assert COMPILING not in again["stats"]  # nor in the worker: it would have said so
    assert any("Sample 2/2" in s for s in again["stats"])


def test_recreated_named_tuple_classes_still_match_the_cache(reload_run):
    assert reload_run["named_tuples_recreated"]  # so "reimported" above really tested that


# The issue's own scenario: the built zip installed, two render workers. Disabling an
# extension deletes its bundled wheels (the renderer's sources included) and enabling it
# extracts them again with new file times; numba's own cache, keyed by source file times,
# then took every kernel for stale. Workers say on stderr when they compile.
EXTENSION_BODY = r'''
import bpy
import addon_utils
import bpy_helpers as H


def f12(name):
    scene = bpy.context.scene
    for obj in list(scene.collection.all_objects):
        if obj.type == "MESH":
            obj.data.materials.clear()  # the default cube, grey diffuse
    H.configure_haze(scene, 4, 2, seed=1, workers=2)
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100
    print(f"=== F12 {name}", file=sys.stderr, flush=True)
    H.render_exr(scene, os.path.join(os.getcwd(), name + ".exr"))


def main():
    bpy.ops.extensions.package_install_files(filepath=ZIP, repo="user_default", enable_on_install=True)
    name = next(m.__name__ for m in addon_utils.modules() if m.__name__.endswith(".haze"))
    import renderer.scene
    source = renderer.scene.__file__
    f12("first")
    first_pids = workers()
    addon_utils.disable(name, default_set=True)
    deleted = not os.path.exists(source)
    stopped = [pid for pid in first_pids if not alive(pid)]
    addon_utils.enable(name, default_set=True)
    f12("re_enabled")
    re_enabled_pids = workers()
    f12("again")
    return {"sources_deleted_on_disable": deleted, "first_pids": first_pids, "stopped_on_disable": stopped,
            "re_enabled_pids": re_enabled_pids, "again_pids": workers()}


def workers():
    return sorted(sys.modules["renderer.render"].worker_pids())


def alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True
'''


@pytest.fixture(scope="module")
def extension_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("extension_reload")
    built_zip = built_zip_once()
    root = partly_cold_cache(tmp / "cache")
    body = EXTENSION_BODY.replace("ZIP,", f"{str(built_zip)!r},")
    run = run_blender(body, tmp / "run", timeout=900, dev_paths=False, site=isolated_site(tmp),
                      env={"HAZE_CACHE_DIR": str(root)})
    assert run.returncode == 0 and run.result, run.describe()
    renders = run.stderr.split("=== F12 ")[1:]
    return run.result, {text.split()[0]: text for text in renders}


def test_installed_extension_disabled_and_enabled_starts_warm_in_its_workers(extension_run):
    result, stderr = extension_run
    assert result["sources_deleted_on_disable"]  # the scenario really re-extracts the renderer
    said = [line for line in stderr["first"].splitlines() if "compiling kernels (first run only): " in line]
    assert said and "splat" in said[0], stderr["first"]  # at least splat was cold
    assert "compiling kernels" not in stderr["re_enabled"], stderr["re_enabled"]
    assert "compiling kernels" not in stderr["again"], stderr["again"]


def test_workers_persist_across_f12_and_stop_when_the_add_on_is_disabled(extension_run):
    result, _ = extension_run
    assert len(result["first_pids"]) == 2
    assert result["stopped_on_disable"] == result["first_pids"]
    assert len(result["re_enabled_pids"]) == 2
    assert result["again_pids"] == result["re_enabled_pids"]  # the second F12 reused them
