"""Export, then validate: the one way from a depsgraph to a Scene the renderer accepts.

Used by F12 (session.py) and by File > Export > Haze Scene (operators.py). The renderer's
validator names a problem by its path in the scene ("meshes[3].indices"); the message the
user gets names the Blender object instead. Like `messages`, this module is safe to import
any time: the renderer is imported only once the bootstrap has found it.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING

from .. import bootstrap
from .messages import ExportError

if TYPE_CHECKING:
    from .scene import ExportResult


def describe_scene_error(error, export_result) -> str:
    """A renderer SceneError ("meshes[3].indices: ...") phrased with the Blender object's name."""
    path, problem = getattr(error, "path", ""), getattr(error, "problem", str(error))
    for collection, names in (("meshes", [m.name for m in export_result.scene.meshes]),
                              ("materials", [m.name for m in export_result.scene.materials]),
                              ("media", [m.name for m in export_result.scene.media]),
                              ("lights", export_result.light_names)):
        prefix = f"{collection}["
        if path.startswith(prefix):
            index = int(path[len(prefix):path.index("]")])
            if index < len(names):
                return f"'{names[index]}' ({path}): {problem}"
    return f"{path}: {problem}" if path else str(error)


def export_validated(depsgraph, size: tuple[int, int] | None = None, *, render_depsgraph: bool = True,
                     exporter: Callable | None = None, on_start: Callable[[], None] | None = None,
                     on_warnings: Callable[[list[str]], None] | None = None) -> ExportResult:
    """The ExportResult of `depsgraph`, its scene validated; raises ExportError otherwise.

    `size` (width, height) overrides the scene's output size; `exporter(depsgraph, film)`
    stands in for export_scene (tests). `on_start` runs once the renderer is known to be
    importable; `on_warnings` gets the export's warnings before validation, so the render
    shows them even for an invalid scene.
    """
    problem = bootstrap.renderer_problem()
    if problem:
        raise ExportError("Haze", problem)
    from renderer.errors import SceneError
    from renderer.scene import Film
    from renderer.validate import validate_scene

    from . import scene

    if exporter is None:  # looked up now, not at import: tests replace scene.export_scene
        exporter = partial(scene.export_scene, render_depsgraph=render_depsgraph)
    if on_start is not None:
        on_start()
    exported = exporter(depsgraph, Film(*size) if size is not None else None)
    if on_warnings is not None:
        on_warnings(exported.warnings)
    try:
        validate_scene(exported.scene)
    except SceneError as error:
        raise ExportError("Haze scene", describe_scene_error(error, exported)) from error
    return exported
