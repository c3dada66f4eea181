"""Haze as a user gets it: the extension zip, installed into a Blender user folder.

The tests' Blender runs and the benchmarks that report product figures render through this,
never through the clone's `addon` package:

    template = installed_user_folder()        # builds the zip (tools/build_extension.py) and
                                              # installs it once per source version
    copy_install(template, my_user_dir)       # a fresh user folder with its own copy of it
    env["BLENDER_USER_RESOURCES"] = str(my_user_dir)

and, in the Blender process, `addon_utils.enable(PACKAGE)`. Blender puts the extension's
bundled wheels (`extensions/.local/lib/python3.11/site-packages`) on sys.path itself at
start-up, so `renderer`, numba and embreex come from the zip's wheels.

The zip is kept under build/installed/<key>/, where the key hashes everything it is built
from, and its install under build/installed/zip-<hash of the zip>/, so a developer's next
run reuses both until a source changes. A file lock makes concurrent processes
(pytest-xdist) build and install once.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
import subprocess
import sys
import tomllib
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
INSTALLS = REPO / "build" / "installed"
REPOSITORY = "user_default"  # Blender's default local extension repository
PACKAGE = f"bl_ext.{REPOSITORY}.haze"  # the add-on's package name once installed
ZIP_ENV = "HAZE_TEST_ZIP"  # a built zip to install instead of building one
# What the zip is made of: a change to any of these makes a new zip.
ZIP_SOURCES = ("addon", "renderer", "blender_manifest.toml", "pyproject.toml", "tools/build_extension.py",
               "tools/wheel_backend.py")
COMPLETE = "installed.ok"

INSTALL = """\
import sys, bpy
bpy.ops.extensions.package_install_files(filepath=sys.argv[1], repo={repo!r}, enable_on_install=True)
"""


def source_key() -> str:
    """A short hash of every file the zip is built from."""
    digest = hashlib.sha256()
    for name in ZIP_SOURCES:
        path = REPO / name
        files = sorted(p for p in path.rglob("*") if p.is_file() and "__pycache__" not in p.parts) \
            if path.is_dir() else [path] if path.is_file() else []
        for file in files:
            digest.update(file.relative_to(REPO).as_posix().encode() + b"\0" + file.read_bytes() + b"\0")
    return digest.hexdigest()[:16]


def file_key(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()[:16]


def version() -> str:
    return tomllib.loads((REPO / "blender_manifest.toml").read_text())["version"]


@contextmanager
def _locked() -> Iterator[None]:
    """One process at a time builds or installs (pytest-xdist runs two)."""
    INSTALLS.mkdir(parents=True, exist_ok=True)
    with open(INSTALLS / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def built_zip() -> Path:
    """The extension zip: HAZE_TEST_ZIP if set, else `make extension`'s zip of this checkout,
    built once per source key and kept as build/installed/<key>/haze-<version>.zip."""
    if os.environ.get(ZIP_ENV):
        return Path(os.environ[ZIP_ENV]).resolve()
    kept = INSTALLS / source_key() / f"haze-{version()}.zip"
    with _locked():
        if not kept.is_file():
            subprocess.run([sys.executable, str(REPO / "tools" / "build_extension.py")], check=True,
                           stdout=subprocess.DEVNULL)
            kept.parent.mkdir(parents=True, exist_ok=True)
            partial = kept.with_suffix(".partial")
            shutil.copy2(REPO / "dist" / kept.name, partial)
            partial.replace(kept)
    return kept


def install(zip_path: Path, folder: Path) -> None:
    """Install the zip headless, as a user's Blender does, into folder/user (HOME folder/home)."""
    home, user = folder / "home", folder / "user"
    home.mkdir(parents=True, exist_ok=True)
    user.mkdir(parents=True, exist_ok=True)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("BLENDER_", "PYTHON"))}
    env.update(HOME=str(home), BLENDER_USER_RESOURCES=str(user))
    done = subprocess.run([sys.executable, "-c", INSTALL.format(repo=REPOSITORY), str(zip_path)], env=env,
                          capture_output=True, text=True, timeout=600)
    # Enabled on install, as a user's Blender does: that extracts the bundled wheels into
    # extensions/.local, which Blender puts on sys.path at every later start.
    init = user / "extensions" / REPOSITORY / "haze" / "__init__.py"
    wheels = user / "extensions" / ".local" / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}"
    if done.returncode != 0 or not init.is_file() or not (wheels / "site-packages" / "renderer").is_dir():
        raise RuntimeError(f"installing {zip_path} failed (exit {done.returncode}):\n"
                           f"{done.stdout[-3000:]}\n{done.stderr[-3000:]}")


def installed_user_folder() -> Path:
    """A Blender user folder (for BLENDER_USER_RESOURCES) with built_zip() installed, once
    per zip (build/installed/zip-<hash of the zip>/user)."""
    zip_path = built_zip()
    folder = INSTALLS / f"zip-{file_key(zip_path)}"
    with _locked():
        if not (folder / COMPLETE).is_file():
            shutil.rmtree(folder, ignore_errors=True)  # a half-made install of our own
            install(zip_path, folder)
            (folder / COMPLETE).write_text(f"{zip_path}\n")
    return folder / "user"


def _link_or_copy(source: str, target: str) -> None:
    """Hard links for the install's files (fast, and Blender replaces rather than edits them),
    real copies for its bookkeeping (repository index, caches) and across file systems."""
    if ".blender_ext" not in Path(source).parts and ".cache" not in Path(source).parts:
        try:
            os.link(source, target)
            return
        except OSError:
            pass
    shutil.copy2(source, target)


def copy_install(template: Path, user: Path) -> Path:
    """Make `user` a Blender user folder holding its own copy of the template's install: a
    render may disable the extension, and Blender then deletes its bundled wheels. Returns
    `user`."""
    user.mkdir(parents=True, exist_ok=True)
    with _locked():  # two processes may share one user folder
        if not (user / "extensions").exists():
            shutil.copytree(template / "extensions", user / "extensions", symlinks=True,
                            copy_function=_link_or_copy)
    return user


def blender_environment(user: Path, base: dict[str, str] | None = None) -> dict[str, str]:
    """Environment of a Blender process that runs Haze from the installed zip: `user` (made
    here, with its own copy of the install) as BLENDER_USER_RESOURCES, no PYTHONPATH."""
    copy_install(installed_user_folder(), user)
    env = {k: v for k, v in (base if base is not None else os.environ).items() if k != "PYTHONPATH"}
    env["BLENDER_USER_RESOURCES"] = str(user)
    return env


def enable_installed():
    """Blender side: enable the installed extension as a user does and return its package,
    after checking that `renderer` is its bundled wheel (not a checkout on sys.path)."""
    import importlib.util

    import addon_utils

    def fail(error):
        raise error

    package = addon_utils.enable(PACKAGE, default_set=True, handle_error=fail)
    origin = Path(importlib.util.find_spec("renderer").origin).resolve()
    extensions = Path(os.environ["BLENDER_USER_RESOURCES"]).resolve() / "extensions"
    if not origin.is_relative_to(extensions):
        raise RuntimeError(f"renderer would come from {origin}, not from the installed extension")
    return package
