"""Build the Haze Blender extension: dist/haze-<version>.zip.

Steps:
1. Stage build/extension/haze/: the add-on (addon/), the manifest restricted to the chosen
   platforms, and wheels/: the renderer wheel, built by the project's own build backend
   (tools/wheel_backend.py, so it is byte for byte what `pip wheel .` makes; the add-on and
   any worker process import it as the top-level `renderer` package) plus the exact
   third-party wheels the manifest lists, fetched with `pip download` into a cache
   (build/wheels/). No tests, examples, caches or __pycache__ go in. Blender unpacks the
   bundled wheels itself and does not resolve their Requires-Dist.
2. Run Blender's extension tool (shipped in the bpy wheel) to `validate` and `build` it.

Usage: .venv/bin/python tools/build_extension.py [--platform linux-x64 ...] [--all-platforms]
"""

from __future__ import annotations

import argparse
import importlib.util
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MANIFEST = ROOT / "blender_manifest.toml"
BUILD = ROOT / "build"
STAGE = BUILD / "extension" / "haze"
WHEEL_CACHE = BUILD / "wheels"
DIST = ROOT / "dist"
IGNORED = shutil.ignore_patterns("__pycache__", "*.pyc", "*.pyo", "README-section.md", ".*")


def load_wheel_backend():
    """tools/wheel_backend.py, loaded by path (this file is itself run or loaded by path)."""
    spec = importlib.util.spec_from_file_location("wheel_backend", ROOT / "tools" / "wheel_backend.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


wheel_backend = load_wheel_backend()
RENDERER_DIST = wheel_backend.distribution_name()  # haze_renderer, from pyproject.toml's [project]


def extension_cli() -> Path:
    """blender_ext.py inside the installed bpy wheel."""
    spec = importlib.util.find_spec("bpy")  # located, not imported: importing bpy is slow
    package = Path(spec.origin).parent if spec is not None and spec.origin else None
    matches = sorted(package.glob("*/scripts/addons_core/bl_pkg/cli/blender_ext.py")) if package else []
    if not matches:
        raise SystemExit("Blender's extension tool (bl_pkg/cli/blender_ext.py) was not found; "
                         "install the bpy package in this Python")
    return matches[-1]


def wheel_platforms(filename: str) -> frozenset[str] | None:
    """Blender platforms of a wheel from its tag (None = pure Python, any platform). A macOS
    universal2 wheel (tornado's only one) serves both macOS platforms."""
    tag = filename.removesuffix(".whl").split("-")[-1]
    if tag == "any":
        return None
    if "manylinux" in tag or "linux" in tag:
        return frozenset({"linux-arm64" if "aarch64" in tag else "linux-x64"})
    if tag.startswith("win"):
        return frozenset({"windows-arm64" if "arm64" in tag else "windows-x64"})
    if tag.startswith("macosx"):
        if tag.endswith("universal2"):
            return frozenset({"macos-arm64", "macos-x64"})
        return frozenset({"macos-arm64" if "arm64" in tag else "macos-x64"})
    raise SystemExit(f"unknown platform tag in wheel {filename}")


def pip_requirement(filename: str) -> tuple[str, list[str]]:
    """('name==version', [pip platform tags]) to download exactly this wheel file."""
    name, version, *_rest, platform_tag = filename.removesuffix(".whl").split("-")
    return f"{name}=={version}", platform_tag.split(".")


def download_wheel(filename: str) -> Path:
    """The third-party wheel `filename` from the cache, fetched with pip when missing."""
    target = WHEEL_CACHE / filename
    if target.is_file():
        return target
    requirement, platforms = pip_requirement(filename)
    command = [sys.executable, "-m", "pip", "download", "--only-binary=:all:", "--no-deps",
               "--python-version", "3.11", "--dest", str(WHEEL_CACHE), requirement]
    for platform in platforms:
        command += ["--platform", platform]
    print("fetching", filename)
    subprocess.run(command, check=True)
    if not target.is_file():
        found = sorted(p.name for p in WHEEL_CACHE.glob(f"{requirement.split('==')[0]}-*.whl"))
        raise SystemExit(f"pip did not produce {filename} (found: {found}); update blender_manifest.toml")
    return target


def renderer_wheel(version: str, dest: Path) -> Path:
    """The renderer wheel (the pip wheel of this repository), reproducibly, in `dest`.
    `version` is the manifest's: pyproject.toml's [project] version must equal it."""
    project_version = wheel_backend.project()["version"]
    if project_version != version:
        raise SystemExit(f"pyproject.toml's version {project_version} is not "
                         f"blender_manifest.toml's {version}")
    return wheel_backend.write_wheel(dest)


def toml_list(values: list[str]) -> str:
    return "[\n" + "".join(f'  "{v}",\n' for v in values) + "]"


def staged_manifest(text: str, platforms: list[str], wheels: list[str]) -> str:
    """The repository manifest with `platforms` and `wheels` limited to this build."""
    text = re.sub(r"(?ms)^platforms = \[.*?\]", f"platforms = {toml_list(platforms)}", text, count=1)
    return re.sub(r"(?ms)^wheels = \[.*?\]", f"wheels = {toml_list(wheels)}", text, count=1)


def selected_wheels(manifest: dict, platforms: list[str]) -> list[str]:
    names = [Path(w).name for w in manifest["wheels"]]
    return [n for n in names if wheel_platforms(n) is None or wheel_platforms(n) & set(platforms)]


def stage(platforms: list[str]) -> Path:
    text = MANIFEST.read_text()
    manifest = tomllib.loads(text)
    unknown = sorted(set(platforms) - set(manifest["platforms"]))
    if unknown:
        raise SystemExit(f"platforms {unknown} are not in blender_manifest.toml ({manifest['platforms']})")
    if STAGE.exists():
        shutil.rmtree(STAGE)  # our own staging folder, rebuilt every time
    shutil.copytree(ROOT / "addon", STAGE, ignore=IGNORED)
    wheels_dir = STAGE / "wheels"
    wheels_dir.mkdir()
    WHEEL_CACHE.mkdir(parents=True, exist_ok=True)
    wheels = selected_wheels(manifest, platforms)
    for name in wheels:
        if name.startswith(f"{RENDERER_DIST}-"):
            built = renderer_wheel(manifest["version"], wheels_dir)
            if built.name != name:
                raise SystemExit(f"manifest lists {name} but the renderer wheel is {built.name}")
        else:
            shutil.copy2(download_wheel(name), wheels_dir / name)
    (STAGE / "blender_manifest.toml").write_text(
        staged_manifest(text, platforms, [f"./wheels/{n}" for n in wheels]))
    return STAGE


def run_cli(*arguments: str) -> None:
    subprocess.run([sys.executable, str(extension_cli()), *arguments], check=True)


def parse_arguments(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description="Build the Haze Blender extension zip.")
    parser.add_argument("--platform", action="append", dest="platforms",
                        help="Blender platform to bundle wheels for (repeatable; default linux-x64)")
    parser.add_argument("--all-platforms", action="store_true", help="every platform of the manifest")
    return parser.parse_args(argv)


def main(argv: list[str]) -> Path:
    arguments = parse_arguments(argv)
    platforms = arguments.platforms or ["linux-x64"]
    if arguments.all_platforms:
        platforms = tomllib.loads(MANIFEST.read_text())["platforms"]
    source = stage(platforms)
    run_cli("validate", str(source))
    DIST.mkdir(exist_ok=True)
    version = tomllib.loads(MANIFEST.read_text())["version"]
    output = DIST / f"haze-{version}.zip"  # the tool's default name: {id}-{version}.zip
    run_cli("build", "--source-dir", str(source), "--output-dir", str(DIST))
    if not output.is_file():
        raise SystemExit(f"the extension tool did not write {output}")
    print(f"built {output} for {', '.join(platforms)}")
    return output


if __name__ == "__main__":
    main(sys.argv[1:])
