"""Blender runs from the host (a pytest or bench process): `run_blender` writes a script,
runs it with bpy in a subprocess and returns its JSON result.

Everything touching bpy runs in a subprocess, so a crash in Blender fails one test or one
measurement instead of the whole run, and each run gets fresh HOME / BLENDER_USER_RESOURCES
folders so nothing of the developer's own Blender setup is read or changed. The scripts run
with tests/ and examples/ on their sys.path (not the repository root: Haze, and with it
`renderer`, comes from the installed extension), so they import the Blender-side helpers of
examples/bpy_helpers.py (enable_addon, configure_cycles, render_exr, scene builders).
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TESTS = REPO / "tests"
EXAMPLES = REPO / "examples"
PYTHON = sys.executable

# Packages the installed extension must bring itself (never taken from the test venv).
BUNDLED_MODULES = ("numba", "llvmlite", "embreex", "OpenEXR", "Imath", "openexr", "renderer",
                   # cluster rendering (packaging, zipp and importlib_metadata stay: others use them)
                   "dask", "distributed", "click", "cloudpickle", "fsspec", "jinja2", "lazy_importer",
                   "locket", "partd", "sortedcontainers", "tblib", "toolz", "zict", "msgpack", "psutil",
                   "yaml", "_yaml", "pyyaml", "tornado", "markupsafe")

PRELUDE = """\
import json, os, sys
for _path in {paths!r}:
    if _path not in sys.path:
        sys.path.insert(0, _path)
"""

ADDON_MODE_ENV = "HAZE_TEST_ADDON"  # examples/bpy_helpers.py reads it on the Blender side

EPILOGUE = """
if __name__ == "__main__":
    _result = main()
    with open(os.environ["HAZE_TEST_RESULT"], "w") as _file:
        json.dump(_result if _result is not None else {}, _file)
"""


@dataclass
class BlenderRun:
    returncode: int
    stdout: str
    stderr: str
    result: dict

    def describe(self) -> str:
        return f"exit code {self.returncode}\n--- stdout ---\n{self.stdout[-6000:]}\n" \
               f"--- stderr ---\n{self.stderr[-6000:]}"


def blender_environment(tmp: Path, numba_cache: Path | None) -> dict[str, str]:
    """Environment of a Blender subprocess: private user folders, shared numba cache."""
    home = tmp / "home"
    user = tmp / "blender_user"
    home.mkdir(parents=True, exist_ok=True)
    user.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_", "NUMBA_", "PYTHON", "HAZE_"))}
    env.update(HOME=str(home), BLENDER_USER_RESOURCES=str(user), XDG_CACHE_HOME=str(home / ".cache"),
               XDG_CONFIG_HOME=str(home / ".config"), PYTHONUNBUFFERED="1")
    # No background compile at add-on enable unless a test asks for it (HAZE_BACKGROUND_COMPILE=1;
    # headless Blender has it off by default anyway): it would compete for the two cores.
    env["HAZE_BACKGROUND_COMPILE"] = "0"
    if numba_cache is not None:
        env["NUMBA_CACHE_DIR"] = str(numba_cache)
    return env


def shared_numba_cache() -> Path:
    """Numba cache for dev-mode Blender runs, kept between test sessions.

    Compiling the renderer takes a minute or more, so the cache is reused - but only for the
    exact renderer sources it was built from (numba does not notice edits in called modules),
    hence one folder per hash of those sources, under build/ (never committed).
    """
    digest = hashlib.sha256()
    for path in sorted((REPO / "renderer").rglob("*.py")):
        digest.update(path.relative_to(REPO).as_posix().encode())
        digest.update(path.read_bytes())
    folder = REPO / "build" / "numba-test-cache" / digest.hexdigest()[:16]
    folder.mkdir(parents=True, exist_ok=True)
    return folder


def isolated_site(tmp: Path) -> Path:
    """A site folder with the venv's packages except those the extension must bundle.

    Run with `python -S` and this folder on sys.path, Blender can only find numba, embreex,
    OpenEXR and the renderer in the extension's own wheels.
    """
    site = tmp / "site"
    site.mkdir(parents=True, exist_ok=True)
    venv_site = Path(np.__file__).resolve().parents[1]
    for entry in venv_site.iterdir():
        lowered = entry.name.lower()
        if entry.name.endswith(".pth") or entry.name == "__pycache__":
            continue
        if any(lowered.startswith(name.lower()) for name in BUNDLED_MODULES):
            continue
        (site / entry.name).symlink_to(entry)
    return site


def addon_mode() -> str:
    """How Blender runs get Haze: "installed" (the default, and CI's: the extension zip built
    from this checkout, installed into the run's user folder, with its bundled renderer wheel)
    or "clone" (HAZE_TEST_ADDON=clone: the checkout's addon/ and renderer/, for quick local
    iteration only; no figure or CI run uses it)."""
    mode = os.environ.get(ADDON_MODE_ENV, "installed")
    if mode not in ("installed", "clone"):
        raise ValueError(f"{ADDON_MODE_ENV} must be 'installed' or 'clone', not {mode!r}")
    return mode


def run_blender(body: str, tmp: Path, *, timeout: float = 900.0, numba_cache: Path | None = None,
                dev_paths: bool = True, site: Path | None = None, env: dict[str, str] | None = None
                ) -> BlenderRun:
    """Run `body` (Python source defining `main() -> dict`) with bpy in a subprocess.

    dev_paths: the run may enable Haze (bpy_helpers.enable_addon) and import tests/ and
    examples/; Haze is the installed extension (copied into the run's user folder, the
    process isolated from the venv's copies of the bundled packages) unless addon_mode() is
    "clone", where the repository goes on sys.path. dev_paths=False: only tests/, examples/
    and `site`, for tests that install a zip themselves. site: run isolated (python -S) with only this
    site folder for packages. env: extra environment variables.
    """
    tmp.mkdir(parents=True, exist_ok=True)
    mode = addon_mode() if dev_paths else "none"
    paths = [str(TESTS), str(EXAMPLES)]  # the tests' helpers, and examples/bpy_helpers.py
    if mode == "clone":
        paths.append(str(REPO))
    if mode == "installed" and site is None:
        site = isolated_site(tmp)
    if site is not None:
        paths.append(str(site))
    script = tmp / "blender_script.py"
    script.write_text(PRELUDE.format(paths=paths) + textwrap.dedent(body) + EPILOGUE)
    result_file = tmp / "result.json"
    extra = env or {}
    env = blender_environment(tmp, numba_cache)
    env.update(extra, HAZE_TEST_RESULT=str(result_file), **{ADDON_MODE_ENV: mode})
    if mode == "installed":  # into the user folder the run really uses (a test may share one)
        from bench.installed import copy_install, installed_user_folder

        copy_install(installed_user_folder(), Path(env["BLENDER_USER_RESOURCES"]))
    command = [PYTHON, "-S", str(script)] if site is not None else [PYTHON, str(script)]
    process = subprocess.run(command, cwd=tmp, env=env, capture_output=True, text=True, timeout=timeout)
    result = json.loads(result_file.read_text()) if result_file.is_file() else {}
    return BlenderRun(process.returncode, process.stdout, process.stderr, result)
