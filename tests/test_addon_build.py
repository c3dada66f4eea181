"""The extension package: manifest, renderer wheel, and the built zip installed in Blender.

The install test runs Blender with a site folder that lacks numba, llvmlite, embreex,
OpenEXR and the renderer, so a successful render proves they were imported from the
extension's bundled wheels (their __file__ paths are checked too).
"""

from __future__ import annotations

import base64
import csv
import hashlib
import importlib.metadata
import importlib.util
import io
import tomllib
import zipfile
from pathlib import Path

import pytest

from bench.blender import REPO, isolated_site, run_blender
from bench.installed import built_zip as built_zip_once
from renderer.imageio import read_exr

MANIFEST = tomllib.loads((REPO / "blender_manifest.toml").read_text())
THIRD_PARTY = {"embreex": "embreex", "openexr": "OpenEXR", "numba": "numba", "llvmlite": "llvmlite"}
# Cluster rendering: dask, distributed and their dependencies (wheel name -> distribution).
CLUSTER = {name: name for name in (
    "dask", "distributed", "click", "cloudpickle", "fsspec", "importlib_metadata", "jinja2", "lazy_importer",
    "locket", "packaging", "partd", "sortedcontainers", "tblib", "toolz", "zict", "zipp",
    "msgpack", "psutil", "pyyaml", "tornado", "markupsafe")}
BUNDLED = THIRD_PARTY | CLUSTER


def load_build_tool():
    spec = importlib.util.spec_from_file_location("build_extension", REPO / "tools" / "build_extension.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


build_tool = load_build_tool()


def wheel_names() -> list[str]:
    return [Path(w).name for w in MANIFEST["wheels"]]


def test_manifest_basics():
    assert MANIFEST["schema_version"] == "1.0.0" and MANIFEST["id"] == "haze" and MANIFEST["name"] == "Haze"
    assert MANIFEST["type"] == "add-on" and MANIFEST["blender_version_min"] == "4.2.0"
    assert MANIFEST["license"] == ["SPDX:GPL-3.0-or-later"] and "files" in MANIFEST["permissions"]


def test_bundled_wheels_are_the_tested_versions_for_every_platform():
    """One wheel per dependency and platform, of the version installed in this environment."""
    found: dict[tuple[str, str], str] = {}
    for name in wheel_names():
        distribution, version = name.split("-")[:2]
        platforms = build_tool.wheel_platforms(name)
        if distribution == build_tool.RENDERER_DIST:
            assert platforms is None and version == MANIFEST["version"]
            continue
        assert distribution in BUNDLED, f"unexpected bundled wheel {name} (numpy comes with Blender)"
        assert platforms is None or "cp311" in name or "abi3" in name, name
        assert version == importlib.metadata.version(BUNDLED[distribution]), name
        for platform in platforms or MANIFEST["platforms"]:  # a pure-Python wheel serves all
            assert (distribution, platform) not in found, f"two {distribution} wheels for {platform}"
            found[(distribution, platform)] = name
    expected = {(d, p) for d in BUNDLED for p in MANIFEST["platforms"]}
    assert set(found) == expected


def test_staged_manifest_keeps_only_the_chosen_platforms():
    text = (REPO / "blender_manifest.toml").read_text()
    wheels = build_tool.selected_wheels(MANIFEST, ["linux-x64"])
    staged = tomllib.loads(build_tool.staged_manifest(text, ["linux-x64"], [f"./wheels/{w}" for w in wheels]))
    assert staged["platforms"] == ["linux-x64"]
    assert len(staged["wheels"]) == 1 + len(BUNDLED)  # the renderer's and one of each dependency
    assert all("win" not in w and "macos" not in w for w in staged["wheels"])
    assert {k: v for k, v in staged.items() if k not in ("platforms", "wheels")} == \
        {k: v for k, v in MANIFEST.items() if k not in ("platforms", "wheels")}


def test_renderer_wheel_records_every_file(tmp_path):
    wheel = build_tool.renderer_wheel(MANIFEST["version"], tmp_path)
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
        info = f"{build_tool.RENDERER_DIST}-{MANIFEST['version']}.dist-info"
        rows = list(csv.reader(io.StringIO(archive.read(f"{info}/RECORD").decode())))
        for path, digest, size in rows:
            if path.endswith("RECORD"):
                continue
            data = archive.read(path)
            expected = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
            assert digest == f"sha256={expected}" and int(size) == len(data), path
    assert "renderer/scene.py" in names and "renderer/render.py" in names
    assert not [n for n in names if "__pycache__" in n or n.endswith(".pyc")]
    assert sorted(r[0] for r in rows) == sorted(names)


INSTALL_BODY = r'''
import glob
import bpy


def main():
    zip_path = os.environ["HAZE_ZIP"]
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    import addon_utils
    enabled = [m.__name__ for m in addon_utils.modules() if m.__name__.endswith(".haze")]
    import bpy_helpers as H
    scene = bpy.context.scene
    for obj in list(scene.collection.all_objects):
        if obj.type == "MESH":
            obj.data.materials.clear()  # the default cube, grey diffuse
    H.configure_haze(scene, 2, 2, seed=1, workers=1)
    scene.render.resolution_x = scene.render.resolution_y = 8
    scene.render.resolution_percentage = 100
    path = os.path.join(os.getcwd(), "installed.exr")
    H.render_exr(scene, path)
    import embreex, numba, llvmlite, OpenEXR, renderer, renderer.render
    import dask, distributed, msgpack, psutil, tornado, yaml  # cluster rendering
    bundled = (embreex, numba, llvmlite, OpenEXR, renderer, dask, distributed, msgpack, psutil, tornado, yaml)
    modules = {m.__name__: m.__file__ for m in bundled}
    package = next(name for name in enabled)
    extension_dir = os.path.dirname(sys.modules[package].__file__)
    cache = os.environ.get("NUMBA_CACHE_DIR", "")
    engines = {getattr(e, "bl_idname", "") for e in bpy.types.RenderEngine.__subclasses__()}
    return {
        "enabled": enabled,
        "has_settings": hasattr(bpy.types.Scene, "haze"),
        "engine_registered": "HAZE" in engines,
        "modules": modules,
        "extension_dir": extension_dir,
        "numba_cache": cache,
        "cache_files": len(glob.glob(os.path.join(cache, "kernels-*", "**", "*.nbi"), recursive=True)),
        "exr": path,
    }
'''


@pytest.fixture(scope="module")
def built_zip() -> Path:
    return built_zip_once()  # `make extension` of this checkout, built once per source (or HAZE_TEST_ZIP)


def test_zip_holds_addon_and_wheels_only(built_zip):
    with zipfile.ZipFile(built_zip) as archive:
        names = archive.namelist()
    assert built_zip.name == f"haze-{MANIFEST['version']}.zip"
    assert "blender_manifest.toml" in names and "__init__.py" in names and "export/nodes.py" in names
    assert sorted(n for n in names if n.startswith("wheels/")) == \
        sorted(f"wheels/{w}" for w in build_tool.selected_wheels(MANIFEST, ["linux-x64"]))
    banned = ("tests/", "examples/", "__pycache__", ".pyc", "README", "renderer/")
    assert not [n for n in names if any(b in n for b in banned)]


@pytest.mark.bpy
@pytest.mark.slow
def test_built_extension_installs_and_renders_with_bundled_wheels(built_zip, tmp_path):
    site = isolated_site(tmp_path)
    run = run_blender(INSTALL_BODY.replace('os.environ["HAZE_ZIP"]', repr(str(built_zip))), tmp_path / "run",
                      timeout=900, dev_paths=False, site=site)
    assert run.returncode == 0 and run.result, run.describe()
    result = run.result
    assert result["enabled"] == ["bl_ext.user_default.haze"]
    assert result["has_settings"] and result["engine_registered"]
    user = (tmp_path / "run" / "blender_user").resolve()
    bundled = user / "extensions" / ".local" / "lib" / "python3.11" / "site-packages"
    for name, file in result["modules"].items():
        assert Path(file).resolve().is_relative_to(bundled), f"{name} imported from {file}"
    # The kernels go to the command line's per-user cache (~/.cache/haze), never into the extension.
    home = (tmp_path / "run" / "home").resolve()
    assert Path(result["numba_cache"]).resolve() == home / ".cache" / "haze"
    assert result["cache_files"] > 0
    extension_dir = Path(result["extension_dir"])
    assert not list(extension_dir.rglob("*.nbi")) and not list(bundled.rglob("*.nbi"))
    image = read_exr(result["exr"])
    assert image.shape == (8, 8, 3) and image.mean() > 0.0
