"""F12 with the real engine in Blender: progress, cancelling, bad scenes, and the CLI path.

One Blender subprocess renders several small scenes headless (bpy.ops.render.render with
write_still, exactly what a background script does) with the engine's RenderEngine methods
wrapped to record what Blender is told; the tests check the recordings and the images.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from bench.blender import REPO, shared_numba_cache
from helpers.blender_runs import blender_fixture
from renderer.imageio import read_exr

pytestmark = [pytest.mark.bpy, pytest.mark.slow]

BODY = r'''
import bpy
import bpy_helpers as H
import blender_cornell as C

OUT = os.getcwd()
log = {"progress": [], "stats": [], "reports": []}
state = {"breaks_after": None, "interrupt_at": None}


class Recorder:
    """Stands between the session and Blender's engine: records, may cancel, forwards."""

    def __init__(self, engine):
        self._engine = engine

    def __getattr__(self, name):
        return getattr(self._engine, name)

    def update_progress(self, value):
        log["progress"].append(value)
        if state["interrupt_at"] is not None and len(log["progress"]) >= state["interrupt_at"]:
            raise KeyboardInterrupt  # as if Ctrl-C arrived during the render
        self._engine.update_progress(value)

    def update_stats(self, stats, info):
        log["stats"].append(info)
        self._engine.update_stats(stats, info)

    def report(self, kind, text):
        log["reports"].append([sorted(kind)[0], text])
        self._engine.report(kind, text)

    def test_break(self):
        if state["breaks_after"] is not None and len(log["progress"]) >= state["breaks_after"]:
            return True
        return self._engine.test_break()


def instrument():
    """Every render session talks to Blender's engine through a Recorder."""
    session = H.addon_module("session")
    original_init = session.RenderSession.__init__

    def init(self, engine, depsgraph, *args, **kwargs):
        original_init(self, Recorder(engine), depsgraph, *args, **kwargs)
    session.RenderSession.__init__ = init


def render(scene, name, **state_values):
    """F12 headless; returns what was recorded during this render."""
    for key in log:
        log[key] = []
    state.update(breaks_after=None, interrupt_at=None)
    state.update(state_values)
    path = os.path.join(OUT, f"{name}.exr")
    error = ""
    try:
        H.render_exr(scene, path)
    except RuntimeError as exc:
        error = str(exc)
    return {"exr": path if os.path.exists(path) else None, "error": error,
            "progress": list(log["progress"]), "stats": list(log["stats"]), "reports": list(log["reports"])}


def cornell(samples, seed=0):
    scene = C.build_fog_cornell(16, 16, max_bounces=3)
    H.configure_haze(scene, samples, 3, seed=seed, workers=1)
    return scene


def hdri_stage():
    """A ball on a floor under an in-memory float HDRI (a sky and a small bright sun),
    through a rotating Mapping node."""
    import numpy as np

    scene = C.clear_scene()
    C.add_camera(scene, (0.0, -3.0, 1.0), (80.0, 0.0, 0.0))
    H.floor_plane("Floor", 2.0, C.diffuse_material("Floor", (0.6, 0.6, 0.6)))
    H.uv_sphere("Ball", (0.0, 0.0, 0.5), 0.5, C.diffuse_material("Ball", (0.7, 0.4, 0.3)))
    image = bpy.data.images.new("Sky", 64, 32, alpha=False, float_buffer=True)
    rgba = np.ones((32, 64, 4), np.float32)
    rgba[..., :3] = np.linspace(0.05, 1.0, 32)[:, None, None]
    rgba[24, 10, :3] = 500.0
    image.pixels.foreach_set(rgba.ravel())
    world = bpy.data.worlds.new("HDRI"); H.ensure_nodes(world)
    nodes, links = world.node_tree.nodes, world.node_tree.links
    texture = nodes.new("ShaderNodeTexEnvironment"); texture.image = image
    mapping = nodes.new("ShaderNodeMapping"); mapping.inputs["Rotation"].default_value = (0.0, 0.0, 0.7)
    links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
    links.new(texture.outputs["Color"], nodes["Background"].inputs["Color"])
    scene.world = world
    scene.render.resolution_x, scene.render.resolution_y = 24, 16
    H.configure_haze(scene, 4, 3, seed=5, workers=1)
    return scene


def main():
    H.enable_addon()
    instrument()
    results = {}
    scene = cornell(8, seed=3)
    results["complete"] = render(scene, "complete")
    folder = os.path.join(OUT, "exported_scene")
    results["export"] = sorted(bpy.ops.export_scene.haze(filepath=folder))
    results["export_folder"] = folder
    user_folder = os.path.join(OUT, "user_folder")
    os.makedirs(user_folder)
    with open(os.path.join(user_folder, "notes.txt"), "w") as file:
        file.write("mine")
    try:
        results["refused"] = sorted(bpy.ops.export_scene.haze(filepath=user_folder))
    except RuntimeError as error:
        results["refused"] = str(error)
    results["user_file"] = open(os.path.join(user_folder, "notes.txt")).read()

    scene = cornell(100000)
    results["break"] = render(scene, "break", breaks_after=1)
    results["interrupt"] = render(scene, "interrupt", interrupt_at=2)

    scene = cornell(2)
    wall = bpy.data.objects["Back"].active_material  # a fresh copy: "Back Wall.00N"
    tree = wall.node_tree
    texture = tree.nodes.new("ShaderNodeTexGabor")  # a texture Haze does not compile yet
    texture.name = "Stucco"
    tree.links.new(texture.outputs["Value"], tree.nodes["Diffuse BSDF"].inputs["Color"])
    fog = bpy.data.objects["Fog"]
    results["names"] = {"wall": wall.name, "fog": fog.active_material.name}
    import bmesh
    bm = bmesh.new(); bm.from_mesh(fog.data); bm.faces.ensure_lookup_table()
    bmesh.ops.delete(bm, geom=[bm.faces[0]], context="FACES_ONLY"); bm.to_mesh(fog.data); bm.free()
    H.add_light("AREA", "Flat Light", (0, 0, 1), size=0.0, energy=10.0)
    results["warned"] = render(scene, "warned")

    scene = hdri_stage()
    results["hdri"] = render(scene, "hdri")
    folder = os.path.join(OUT, "exported_hdri")
    results["hdri_export"] = sorted(bpy.ops.export_scene.haze(filepath=folder))
    results["hdri_folder"] = folder

    scene = C.clear_scene()
    C.add_camera(scene, (0, -3, 1), (90, 0, 0))
    C.black_world(scene)
    H.configure_haze(scene, 2, 3, seed=0, workers=1)
    results["empty"] = render(scene, "empty")
    scene.camera = None
    results["no_camera"] = render(scene, "no_camera")
    return results
'''


@pytest.fixture(scope="module")
def numba_cache_dir():
    return shared_numba_cache()


renders = blender_fixture(BODY, "render", timeout=900)


def errors(record):
    return [text for kind, text in record["reports"] if kind == "ERROR"]


def warnings(record):
    return [text for kind, text in record["reports"] if kind == "WARNING"]


def test_f12_reports_progress_and_stats(renders):
    record = renders["complete"]
    assert record["error"] == "" and errors(record) == []
    assert record["progress"] == sorted(record["progress"]) and record["progress"][-1] == pytest.approx(1.0)
    samples = [line for line in record["stats"] if "Sample" in line]
    assert samples[-1].startswith("Haze | Sample 8/8 | Elapsed ")
    assert "Remaining" in samples[-1] and "Noise" in samples[-1]
    image = read_exr(record["exr"])
    assert image.shape == (16, 16, 3) and np.isfinite(image).all() and image.mean() > 0.01


def test_test_break_after_the_first_pass_keeps_a_partial_image(renders):
    record = renders["break"]
    assert record["error"] == ""
    stopped = [w for w in warnings(record) if w.startswith("Haze: render stopped after ")]
    assert len(stopped) == 1 and int(stopped[0].split()[4]) < 100000
    assert read_exr(record["exr"]).mean() > 0.0


def test_keyboard_interrupt_keeps_a_partial_image(renders):
    record = renders["interrupt"]
    assert record["error"] == "" and len(record["progress"]) == 2
    assert any(w.startswith("Haze: render stopped after ") for w in warnings(record))
    assert read_exr(record["exr"]).mean() > 0.0


def test_unsupported_node_open_volume_and_flat_light_warn_but_render(renders):
    record = renders["warned"]
    assert record["error"] == "" and errors(record) == []
    texts = warnings(record)
    names = renders["names"]
    assert f"Material '{names['wall']}', node 'Stucco': Gabor Texture nodes are not supported by Haze; " \
           "the inputs it feeds use their own values" in texts
    open_fog = f"Object 'Fog': encloses the volume '{names['fog']} (volume)' but is not closed"
    assert any(t.startswith(open_fog) for t in texts)
    assert "Object 'Flat Light': area light has zero size, so it emits nothing; it is skipped" in texts
    assert np.isfinite(read_exr(record["exr"])).all()


def test_empty_scene_renders_black(renders):
    record = renders["empty"]
    assert record["error"] == "" and errors(record) == []
    assert np.all(read_exr(record["exr"]) == 0.0)


def test_missing_camera_is_an_error_not_a_crash(renders):
    assert "no camera" in renders["no_camera"]["error"].lower()
    assert renders["no_camera"]["exr"] is None


def test_export_refuses_a_folder_of_user_files(renders):
    assert renders["export"] == ["FINISHED"]
    assert "already holds other files" in str(renders["refused"])
    assert renders["user_file"] == "mine"


def test_exported_scene_rendered_by_the_cli_equals_the_blender_render(renders, tmp_path, numba_cache_dir):
    output = tmp_path / "cli.exr"
    command = [sys.executable, "-m", "renderer", "render", renders["export_folder"], "-o", str(output),
               "--workers", "1", "--no-png"]
    env = {"NUMBA_CACHE_DIR": str(numba_cache_dir), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    process = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert process.returncode == 0, process.stderr
    blender = read_exr(renders["complete"]["exr"])
    cli = read_exr(output)
    assert blender.mean() > 0.01
    np.testing.assert_array_equal(cli, blender)


def test_hdri_world_renders_the_same_through_the_cli(renders, tmp_path, numba_cache_dir):
    """An HDRI world (an in-memory float image) exported and rendered by the command line
    gives F12's image, same seed, bit for bit."""
    assert renders["hdri_export"] == ["FINISHED"] and not errors(renders["hdri"])
    output = tmp_path / "hdri.exr"
    command = [sys.executable, "-m", "renderer", "render", renders["hdri_folder"], "-o", str(output),
               "--workers", "1", "--no-png"]
    env = {"NUMBA_CACHE_DIR": str(numba_cache_dir), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path)}
    process = subprocess.run(command, cwd=REPO, env=env, capture_output=True, text=True, timeout=600)
    assert process.returncode == 0, process.stderr
    blender = read_exr(renders["hdri"]["exr"])
    assert blender.mean() > 0.05 and blender.std() > 0.01  # lit, and not a constant sky
    np.testing.assert_array_equal(read_exr(output), blender)
