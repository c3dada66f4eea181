"""Issue 17: bad inputs and faults end in one-line errors, and never cost anyone's files.

One test (or a few) per class of fault the issue found: outputs that destroyed inputs,
array paths leaving the scene folder, an exporter that trusted any scene.json and wrote
through planted links, values the float32 kernels cannot hold, pathological JSON and huge
images, and an interrupted render that exited 0. Most stop before rendering (in-process);
the interrupt test renders in a subprocess.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from examples.scenes import cornell_box, cornell_fog
from renderer import cli
from renderer.errors import SceneError
from renderer.imageio import is_haze_png, read_exr, write_exr, write_png
from renderer.memory import check_render_memory, render_memory_bytes
from renderer.scene import Film, Medium, SunLight
from renderer.scenefile import EXPORT_GENERATOR, load_scene, save_scene
from renderer.validate import validate_scene

ROOT = Path(__file__).resolve().parents[1]


def _scene_folder(tmp_path: Path, name: str = "scene") -> Path:
    folder = tmp_path / name
    save_scene(cornell_box(size=8, spp=1), folder)
    return folder


def _first_array(folder: Path) -> Path:
    return sorted((folder / "arrays").iterdir())[0]


def _run_cli(capsys, *args: str) -> tuple[int, str]:
    """Run the CLI in-process (for checks that stop before rendering): (exit code, stderr)."""
    code = cli.main(["render", *args])
    return code, capsys.readouterr().err


def _one_line_error(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), stderr
    assert "Traceback" not in stderr
    return lines[0]


# ------------------------------------------------------------ 3: outputs never destroy inputs


def test_an_output_linked_to_an_input_array_is_refused_before_rendering(tmp_path: Path, capsys) -> None:
    folder = _scene_folder(tmp_path)
    array = _first_array(folder)
    before = array.read_bytes()
    link = tmp_path / "out.exr"
    link.symlink_to(array)
    code, err = _run_cli(capsys, str(folder), "-o", str(link), "--workers", "1")
    assert code == 2 and "input file" in _one_line_error(err)
    assert array.read_bytes() == before and link.is_symlink()
    load_scene(folder)  # the scene still loads


def test_an_output_that_is_an_input_array_is_refused(tmp_path: Path, capsys) -> None:
    # An array may have any name, even one ending in .exr.
    folder = _scene_folder(tmp_path)
    data = json.loads((folder / "scene.json").read_text())
    old = data["meshes"][0]["vertices"]
    os.rename(folder / old, folder / "arrays/v.exr")
    data["meshes"][0]["vertices"] = "arrays/v.exr"
    (folder / "scene.json").write_text(json.dumps(data))
    before = (folder / "arrays/v.exr").read_bytes()
    code, err = _run_cli(capsys, str(folder), "-o", str(folder / "arrays/v.exr"))
    assert code == 2 and "input file" in _one_line_error(err)
    assert (folder / "arrays/v.exr").read_bytes() == before


@pytest.mark.parametrize("place", ["folder", "under a file"])
def test_unusable_output_places_are_refused_before_rendering(tmp_path: Path, capsys, place: str) -> None:
    folder = _scene_folder(tmp_path)
    if place == "folder":
        output = tmp_path / "out.exr"
        output.mkdir()
        expected = "is a folder"
    else:
        (tmp_path / "plain").write_text("mine")
        output = tmp_path / "plain" / "deeper" / "out.exr"
        expected = "is not a folder"
    code, err = _run_cli(capsys, str(folder), "-o", str(output))
    assert code == 2 and expected in _one_line_error(err)
    assert (tmp_path / "out.exr").is_dir() or (tmp_path / "plain").read_text() == "mine"


def test_a_png_haze_did_not_write_is_not_replaced_unless_asked(tmp_path: Path, capsys) -> None:
    folder = _scene_folder(tmp_path)
    (tmp_path / "out.png").write_bytes(b"someone's picture")
    code, err = _run_cli(capsys, str(folder), "-o", str(tmp_path / "out.exr"))
    line = _one_line_error(err)
    assert code == 2 and "not written by Haze" in line and "--overwrite" in line
    assert (tmp_path / "out.png").read_bytes() == b"someone's picture"
    assert not (tmp_path / "out.exr").exists()


def test_an_output_hard_linked_to_an_input_is_refused(tmp_path: Path, capsys) -> None:
    folder = _scene_folder(tmp_path)
    array = _first_array(folder)
    os.link(array, tmp_path / "out.exr")
    code, err = _run_cli(capsys, str(folder), "-o", str(tmp_path / "out.exr"))
    assert code == 2 and "input file" in _one_line_error(err)


def _render_cli(folder: Path, output: Path, *extra: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "renderer", "render", str(folder), "-o", str(output), "--workers", "1",
               "--spp", "1", *extra]
    return subprocess.run(command, cwd=ROOT, capture_output=True, text=True, timeout=900)


def test_the_png_preview_replaces_haze_pngs_and_others_only_with_overwrite(tmp_path: Path) -> None:
    folder = _scene_folder(tmp_path)
    output = tmp_path / "out.exr"
    first = _render_cli(folder, output)
    assert first.returncode == 0 and is_haze_png(output.with_suffix(".png")), first.stderr
    again = _render_cli(folder, output)  # Haze's own preview: replaced without asking
    assert again.returncode == 0, again.stderr
    output.with_suffix(".png").write_bytes(b"someone's picture")
    asked = _render_cli(folder, output, "--overwrite")
    assert asked.returncode == 0 and is_haze_png(output.with_suffix(".png")), asked.stderr


def test_haze_recognises_its_own_png_only(tmp_path: Path) -> None:
    image = np.full((2, 3, 3), 0.5, np.float32)
    write_png(tmp_path / "ours.png", image)
    (tmp_path / "theirs.png").write_bytes((tmp_path / "ours.png").read_bytes().replace(b"Haze", b"Gimp"))
    (tmp_path / "link.png").symlink_to(tmp_path / "ours.png")
    assert is_haze_png(tmp_path / "ours.png")
    assert not is_haze_png(tmp_path / "theirs.png")
    assert not is_haze_png(tmp_path / "link.png")  # replacing a link is never assumed to be fine
    assert not is_haze_png(tmp_path / "missing.png")


@pytest.mark.parametrize("writer", ["exr", "png"])
def test_images_replace_a_symbolic_link_instead_of_writing_through_it(tmp_path: Path, writer: str) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    link = tmp_path / f"out.{writer}"
    link.symlink_to(victim)
    image = np.full((2, 2, 3), 0.25, np.float32)
    (write_exr if writer == "exr" else write_png)(link, image)
    assert victim.read_text() == "precious"
    assert not link.is_symlink() and link.stat().st_size > 0
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([victim.name, link.name])  # no temp left
    if writer == "exr":
        assert np.array_equal(read_exr(link), image)


def test_cli_help_states_the_output_rules(capsys) -> None:
    with pytest.raises(SystemExit):
        cli.main(["render", "--help"])
    text = capsys.readouterr().out
    assert "--overwrite" in text and "symbolic link" in text and "130" in text


# ----------------------------------------------------- 4: the scene folder is a sandbox


def _point_array_at(folder: Path, value: str) -> None:
    data = json.loads((folder / "scene.json").read_text())
    data["meshes"][0]["vertices"] = value
    (folder / "scene.json").write_text(json.dumps(data))


def _load_error(folder: Path) -> SceneError:
    with pytest.raises(SceneError) as caught:
        load_scene(folder)
    return caught.value


def test_dot_dot_array_paths_are_refused_alike_whether_or_not_the_target_exists(tmp_path: Path) -> None:
    folder = _scene_folder(tmp_path)
    np.save(tmp_path / "outside.npy", np.zeros((3, 3), np.float32))
    _point_array_at(folder, "../outside.npy")
    existing = _load_error(folder)
    _point_array_at(folder, "../missing.npy")
    missing = _load_error(folder)
    _point_array_at(folder, "arrays/../../outside.npy")
    nested = _load_error(folder)
    assert existing.path == "meshes[0].vertices" and "stay in it" in existing.problem
    problems = {error.problem.split(", got")[0] for error in (existing, missing, nested)}
    assert len(problems) == 1


def test_symbolic_links_out_of_the_scene_folder_are_refused(tmp_path: Path) -> None:
    folder = _scene_folder(tmp_path)
    np.save(tmp_path / "outside.npy", np.zeros((3, 3), np.float32))
    (folder / "arrays/out.npy").symlink_to(tmp_path / "outside.npy")
    (folder / "arrays/gone.npy").symlink_to(tmp_path / "missing.npy")
    (tmp_path / "elsewhere").mkdir()
    (folder / "linkdir").symlink_to(tmp_path / "elsewhere")
    np.save(tmp_path / "elsewhere" / "v.npy", np.zeros((3, 3), np.float32))
    problems = []
    for value in ("arrays/out.npy", "arrays/gone.npy", "linkdir/v.npy"):
        _point_array_at(folder, value)
        problems.append(_load_error(folder).problem.split(", got")[0])
    assert len(set(problems)) == 1 and "stay in it" in problems[0]


def test_a_link_that_stays_inside_the_folder_is_fine(tmp_path: Path) -> None:
    folder = _scene_folder(tmp_path)
    data = json.loads((folder / "scene.json").read_text())
    (folder / "arrays/alias.npy").symlink_to(folder / data["meshes"][0]["vertices"])
    _point_array_at(folder, "arrays/alias.npy")
    load_scene(folder)


# ---------------------------------------------------------------- 5: the exporter's folder


@pytest.fixture()
def export_folder():
    import addon  # noqa: F401  (puts the renderer on the path as Blender would)
    from addon.export import folder

    return folder


def test_a_folder_with_a_foreign_scene_json_is_refused(tmp_path: Path, export_folder) -> None:
    web = tmp_path / "website"
    web.mkdir()
    (web / "scene.json").write_text('{"title": "my 3D page"}')
    assert "did not write" in export_folder.target_problem(web)
    with pytest.raises(export_folder.ExportFolderError):
        export_folder.write_export(cornell_box(size=8, spp=1), web)
    assert (web / "scene.json").read_text() == '{"title": "my 3D page"}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["website"]


def test_exports_are_marked_and_replace_only_previous_exports(tmp_path: Path, export_folder) -> None:
    target = tmp_path / "new" / "export"
    export_folder.write_export(cornell_box(size=8, spp=1), target)
    assert json.loads((target / "scene.json").read_text())["generator"] == EXPORT_GENERATOR
    load_scene(target)  # the loader accepts the marker
    (target / "render.exr").write_text("the user's render")
    export_folder.write_export(cornell_fog(size=8, spp=1), target)
    assert (target / "render.exr").read_text() == "the user's render"
    assert load_scene(target).media  # the new scene replaced the old one
    assert sorted(p.name for p in target.parent.iterdir()) == ["export"]  # no staging left


def test_links_planted_in_a_previous_export_are_never_followed(tmp_path: Path, export_folder) -> None:
    target = tmp_path / "export"
    export_folder.write_export(cornell_box(size=8, spp=1), target)
    victim = tmp_path / "victim.npy"
    victim.write_bytes(b"precious")
    for array in (target / "arrays").iterdir():  # every array file becomes a link out
        array.unlink()
        array.symlink_to(victim)
    export_folder.write_export(cornell_box(size=8, spp=1), target)
    assert victim.read_bytes() == b"precious"
    # And an `arrays` that is itself a link to another folder:
    other = tmp_path / "other"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    os.rename(target / "arrays", tmp_path / "old_arrays")
    (target / "arrays").symlink_to(other)
    export_folder.write_export(cornell_box(size=8, spp=1), target)
    assert sorted(p.name for p in other.iterdir()) == ["keep.txt"]
    assert not (target / "arrays").is_symlink()
    load_scene(target)


def test_an_export_that_fails_halfway_leaves_the_previous_one(tmp_path: Path, export_folder,
                                                              monkeypatch) -> None:
    target = tmp_path / "export"
    export_folder.write_export(cornell_box(size=8, spp=1), target)
    before = {p.relative_to(target): p.read_bytes() for p in target.rglob("*") if p.is_file()}

    def fail_halfway(scene, folder, generator=None):
        (Path(folder) / "arrays").mkdir()
        (Path(folder) / "arrays" / "half.npy").write_bytes(b"half")
        raise OSError("disk full")

    monkeypatch.setattr(export_folder, "save_scene", fail_halfway)
    with pytest.raises(OSError, match="disk full"):
        export_folder.write_export(cornell_fog(size=8, spp=1), target)
    after = {p.relative_to(target): p.read_bytes() for p in target.rglob("*") if p.is_file()}
    assert after == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["export"]


# ------------------------------------------------------- 6: values float32 kernels overflow


def _with(edit) -> SceneError:
    scene = cornell_fog(size=8, spp=1)
    edit(scene)
    with pytest.raises(SceneError) as caught:
        validate_scene(scene)
    return caught.value


def _set_emission(scene) -> None:
    next(m for m in scene.materials if max(m.emission) > 0).emission = (4e38, 1.0, 1.0)


def _scale_camera(scene) -> None:
    scene.camera.to_world = scene.camera.to_world @ np.diag([1e200, 1e200, 1e200, 1.0])


def _overflowing_medium(scene) -> None:
    scene.media[0].sigma_s = (1e17, 1e17, 1e17)
    scene.media[0].scale = 1e10  # each fine alone; the product is not


def _far_vertices(scene) -> None:
    scene.meshes[0].vertices = scene.meshes[0].vertices * np.float32(1e20)


@pytest.mark.parametrize(("edit", "field"), [
    (_set_emission, "emission"),
    (lambda s: setattr(s.environment, "radiance", (1e30, 0.0, 0.0)), "environment.radiance"),
    (lambda s: s.lights.append(SunLight((0.0, 1e-320, 0.0), (1.0, 1.0, 1.0))), "lights[0].direction"),
    (lambda s: s.lights.append(SunLight((0.0, 1e300, 0.0), (1.0, 1.0, 1.0))), "lights[0].direction"),
    (lambda s: s.lights.append(SunLight((0.0, 1.0, 0.0), (1e38, 1.0, 1.0))), "lights[0].irradiance"),
    (_scale_camera, "camera.to_world"),
    (_overflowing_medium, "media[0].scale"),
    (_far_vertices, "meshes[0].vertices"),
])
def test_values_the_float32_kernels_cannot_hold_are_refused_by_name(edit, field: str) -> None:
    error = _with(edit)
    assert field in error.path and "\n" not in str(error)


def test_materials_that_gain_energy_every_bounce_are_refused_when_paths_would_overflow() -> None:
    # weight and color of 1e18 each are fine alone; a path multiplies them at every bounce.
    scene = cornell_fog(size=8, spp=1, max_bounces=3)
    scene.materials[0].lobes[0].weight = (1e9, 1e9, 1e9)
    scene.materials[0].lobes[0].color = (1e9, 1e9, 1e9)
    with pytest.raises(SceneError, match=r"^materials\[0\]\.lobes: weight x color"):
        validate_scene(scene)
    scene.materials[0].lobes[0].weight = scene.materials[0].lobes[0].color = (2.0, 2.0, 2.0)
    validate_scene(scene)  # 4 ** 4: fine
    scene.integrator.max_bounces = 64
    with pytest.raises(SceneError, match=r"max_bounces = 64"):
        validate_scene(scene)


def test_a_grid_whose_emission_product_overflows_is_refused() -> None:
    scene = cornell_fog(size=8, spp=1)
    dense = np.full((2, 2, 2), 1e30, np.float32)
    scene.media[0] = Medium("fog", "grid", emission=(1e10, 1.0, 1.0), density=dense)
    with pytest.raises(SceneError, match=r"media\[0\]\.emission"):
        validate_scene(scene)


# ----------------------------------------------------- 7: pathological JSON, huge images


def test_very_deep_json_is_one_error(tmp_path: Path) -> None:
    folder = _scene_folder(tmp_path)
    (folder / "scene.json").write_text("[" * 100000 + "]" * 100000)
    error = _load_error(folder)
    assert error.path == "scene.json" and "nested" in error.problem
    # Shallow enough for the parser, far deeper than any scene: refused before decoding.
    text = json.dumps({"version": 1, "film": {"width": json.loads("[" * 40 + "]" * 40)}})
    (folder / "scene.json").write_text(text)
    assert "nested" in _load_error(folder).problem


def test_a_scene_json_too_large_to_be_a_scene_is_refused_unread(tmp_path: Path, monkeypatch) -> None:
    from renderer import scenefile

    folder = _scene_folder(tmp_path)
    monkeypatch.setattr(scenefile, "MAX_SCENE_JSON_BYTES", 100)
    error = _load_error(folder)
    assert error.path == "scene.json" and "a scene.json may have" in error.problem


@pytest.mark.parametrize("digits", [500, 5000, 100000])
@pytest.mark.parametrize(("section", "key", "field"), [
    ("integrator", "seed", "integrator.seed"),  # an integer field
    ("camera", "fov", "camera.fov"),  # a float field
])
def test_integers_of_thousands_of_digits_name_their_field(
    tmp_path: Path, digits: int, section: str, key: str, field: str
) -> None:
    folder = _scene_folder(tmp_path)
    data = json.loads((folder / "scene.json").read_text())
    data[section][key] = 123456789
    text = json.dumps(data).replace(f'"{key}": 123456789', f'"{key}": {"9" * digits}')
    (folder / "scene.json").write_text(text)
    error = _load_error(folder)
    assert error.path == field and len(str(error)) < 200


def _write_npy_with_header(file: Path, header: str, data: bytes) -> None:
    header_bytes = header.encode("latin1")
    padding = 64 - (10 + len(header_bytes) + 1) % 64
    header_bytes += b" " * padding + b"\n"
    file.write_bytes(b"\x93NUMPY\x01\x00" + len(header_bytes).to_bytes(2, "little") + header_bytes + data)


@pytest.mark.parametrize(("shape", "fragment"), [
    ("(-1, 3)", "negative dimension"),
    ("(1000000000000, 3)", "needs"),  # a 12 TB claim from a tiny file: refused, not allocated
    ("(5, 3)", "needs"),  # truncated
])
def test_npy_headers_that_lie_are_refused(tmp_path: Path, shape: str, fragment: str) -> None:
    folder = _scene_folder(tmp_path)
    data = json.loads((folder / "scene.json").read_text())
    file = folder / data["meshes"][0]["vertices"]
    header = f"{{'descr': '<f4', 'fortran_order': False, 'shape': {shape}, }}"
    _write_npy_with_header(file, header, np.zeros((4, 3), np.float32).tobytes())
    error = _load_error(folder)
    assert error.path == "meshes[0].vertices" and fragment in error.problem


def test_a_film_too_large_for_memory_is_refused_with_the_memory_needed() -> None:
    film = Film(16384, 16384)
    needed = render_memory_bytes(film, 1)
    assert needed > 14e9
    with pytest.raises(SceneError, match=r"^film: .*needs about \d+\.\d GB.*8\.0 GB available"):
        check_render_memory(film, 1, available=8_000_000_000)
    check_render_memory(Film(64, 64), 4, available=8_000_000_000)


def test_the_cli_refuses_a_huge_film_in_one_line(tmp_path: Path, capsys) -> None:
    from renderer.memory import available_memory_bytes

    scene = cornell_box(size=8, spp=1)
    scene.film = Film(16384, 16384)
    available = available_memory_bytes()
    if available is None or available > render_memory_bytes(scene.film, 1):
        pytest.skip("this machine has the memory for a 16384x16384 render")
    save_scene(scene, tmp_path / "big")
    code, err = _run_cli(capsys, str(tmp_path / "big"), "-o", str(tmp_path / "big.exr"), "--workers", "1")
    assert code == 2 and "GB of memory" in _one_line_error(err)


# ------------------------------------------------------------- 8: interrupts, bad options


@pytest.mark.parametrize("value", ["nan", "-1", "inf", "-inf", "abc"])
def test_bad_target_errors_are_refused_by_argument_parsing(tmp_path: Path, capsys, value: str) -> None:
    with pytest.raises(SystemExit) as caught:
        cli.main(["render", str(tmp_path), "-o", str(tmp_path / "o.exr"), f"--target-error={value}"])
    assert caught.value.code == 2 and "--target-error" in capsys.readouterr().err


@pytest.mark.parametrize("value", ["nan", "inf"])
def test_non_finite_time_limits_are_refused(tmp_path: Path, capsys, value: str) -> None:
    with pytest.raises(SystemExit):
        cli.main(["render", str(tmp_path), "-o", str(tmp_path / "o.exr"), f"--time-limit={value}"])
    assert "--time-limit" in capsys.readouterr().err


@pytest.mark.parametrize("workers", [1, 2])
def test_ctrl_c_writes_the_partial_image_and_exits_130(tmp_path: Path, workers: int) -> None:
    save_scene(cornell_fog(size=16, spp=1_000_000), tmp_path / "scene")
    out = tmp_path / "out.exr"
    log = tmp_path / "stderr.txt"
    command = [sys.executable, "-m", "renderer", "render", str(tmp_path / "scene"), "-o", str(out),
               "--workers", str(workers)]
    with open(log, "w") as stderr:
        # A session of its own, so SIGINT can go to the whole process group as a terminal's
        # Ctrl-C does (the worker processes get it too).
        process = subprocess.Popen(command, cwd=ROOT, stderr=stderr, stdout=subprocess.DEVNULL,
                                   start_new_session=True)
        try:
            _wait_for_progress(log, process, timeout=600)
            os.killpg(process.pid, signal.SIGINT)
            code = process.wait(timeout=60)
        finally:
            if process.poll() is None:
                process.kill()
    text = log.read_text()
    assert code == 130, text
    assert "interrupted" in text and "Traceback" not in text
    image = read_exr(out)
    assert image.shape == (16, 16, 3) and np.isfinite(image).all() and image.mean() > 0


def _wait_for_progress(log: Path, process: subprocess.Popen, timeout: float) -> None:
    """Until the render has printed a progress bar (so samples exist), or fail."""
    deadline = time.monotonic() + timeout
    while "spp" not in log.read_text():
        assert process.poll() is None, log.read_text()
        assert time.monotonic() < deadline, "no progress within the timeout"
        time.sleep(0.2)
