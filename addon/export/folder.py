"""Where File > Export > Haze Scene may write, and writing there without risking anyone's files.

The exporter writes only into a new folder, an empty one, or a previous Haze export, which
it recognises by reading the "generator" mark its scene.json carries (a `scene.json` alone
proves nothing: web projects have them too). The scene is written into a fresh sibling
folder and swapped into place only once complete, so:

* an export that fails halfway leaves the previous export as it was;
* nothing is ever written through a symbolic link planted in the old folder (the new
  files are created in a folder the exporter just made), and the old `arrays/` is removed
  without following links in it;
* files the user added to a previous export (renders, notes) are moved into the new one.

Importing this module does not need bpy, so the rules are tested without Blender.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

from renderer.scenefile import ARRAY_DIR, EXPORT_GENERATOR, SCENE_FILE, read_generator, save_scene

# What the exporter writes in a folder (and so replaces); everything else is the user's.
EXPORT_ENTRIES = frozenset({SCENE_FILE, ARRAY_DIR})


class ExportFolderError(ValueError):
    """The chosen folder cannot take an export without risking the user's files."""


def is_previous_export(folder: Path) -> bool:
    """Whether `folder` holds an export of ours: a real scene.json whose generator is ours."""
    scene_file = folder / SCENE_FILE
    if scene_file.is_symlink() or not scene_file.is_file():
        return False
    return read_generator(folder) == EXPORT_GENERATOR


def target_problem(folder: Path) -> str | None:
    """Why exporting into `folder` could destroy the user's files, or None if it is safe."""
    try:
        return _target_problem(folder)
    except OSError as error:  # e.g. a folder we may not list: not ours to write into
        return f"cannot inspect '{folder}': {error.strerror or error}"


def _target_problem(folder: Path) -> str | None:
    if folder.is_symlink():
        return f"'{folder}' is a symbolic link; choose the folder it points to instead"
    if folder.exists() and not folder.is_dir():
        return f"'{folder}' is a file, not a folder"
    if not folder.exists() or not any(folder.iterdir()) or is_previous_export(folder):
        return None
    if (folder / SCENE_FILE).exists() or (folder / SCENE_FILE).is_symlink():
        return (f"'{folder}' holds a {SCENE_FILE} that Haze's exporter did not write; "
                "choose a new or empty folder")
    return f"'{folder}' already holds other files; choose a new or empty folder"


def write_export(scene, folder: Path) -> None:
    """Write `scene` (a renderer.scene.Scene) as a scene folder at `folder`, all or nothing."""
    problem = target_problem(folder)
    if problem:
        raise ExportFolderError(f"Export Haze Scene: {problem}")
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(dir=folder.parent, prefix=f".{folder.name}.haze-new-"))
    try:
        save_scene(scene, staging, generator=EXPORT_GENERATOR)
        _swap_into_place(staging, folder)
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _swap_into_place(staging: Path, folder: Path) -> None:
    """Make the complete `staging` folder the export at `folder`, retiring the old one."""
    if not folder.exists():
        os.rename(staging, folder)
        return
    # A name beside staging that does not exist yet (staging's random part makes it unique);
    # renaming onto an existing folder is not portable.
    retired = staging.with_name(staging.name.replace(".haze-new-", ".haze-old-", 1))
    os.rename(folder, retired)
    try:
        os.rename(staging, folder)
    except BaseException:
        os.rename(retired, folder)  # put the previous export back as it was
        raise
    _move_user_entries(retired, folder)
    # rmtree removes links themselves and never what they point to.
    shutil.rmtree(retired, ignore_errors=True)


def _move_user_entries(retired: Path, folder: Path) -> None:
    """Carry files the user added to the previous export over into the new one."""
    for entry in retired.iterdir():
        if entry.name not in EXPORT_ENTRIES:
            os.rename(entry, folder / entry.name)  # moves a link as a link
