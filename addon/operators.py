"""File > Export > Haze Scene: write the scene folder the `python -m renderer` CLI renders."""

from __future__ import annotations

import os
import traceback
from pathlib import Path

import bpy
from bpy.props import StringProperty
from bpy_extras.io_utils import ExportHelper

from .export.messages import ExportError
from .export.validate import export_validated


def export_to_folder(context, folder: Path) -> list[str]:
    """Export the evaluated scene into `folder` (see export/folder.py); returns the warnings."""
    from .export.folder import write_export

    exported = export_validated(context.evaluated_depsgraph_get(), render_depsgraph=False)
    write_export(exported.scene, folder)
    return exported.warnings


class HAZE_OT_export_scene(bpy.types.Operator, ExportHelper):
    """Export the scene as a Haze scene folder (scene.json and arrays) for the command-line renderer"""

    bl_idname = "export_scene.haze"
    bl_label = "Export Haze Scene"
    bl_options = {"PRESET"}

    filename_ext = ""
    check_extension = None
    filter_glob: StringProperty(default="", options={"HIDDEN"})

    def execute(self, context):
        from .export.folder import ExportFolderError, target_problem

        folder = Path(bpy.path.abspath(self.filepath)).resolve()
        problem = target_problem(folder)  # checked before the (slow) export too
        if problem:
            self.report({"ERROR"}, f"Export Haze Scene: {problem}")
            return {"CANCELLED"}
        try:
            warnings = export_to_folder(context, folder)
        except (ExportError, ExportFolderError, OSError) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        except Exception as error:  # a bug of ours must not look like a Blender crash
            traceback.print_exc()
            self.report({"ERROR"}, f"Export Haze Scene failed: {type(error).__name__}: {error}")
            return {"CANCELLED"}
        for text in warnings:
            self.report({"WARNING"}, text)
        self.report({"INFO"}, f"Haze scene written to {folder}{os.sep}")
        return {"FINISHED"}


def menu_export(self, context) -> None:
    self.layout.operator(HAZE_OT_export_scene.bl_idname, text="Haze Scene")


def register() -> None:
    bpy.utils.register_class(HAZE_OT_export_scene)
    bpy.types.TOPBAR_MT_file_export.append(menu_export)


def unregister() -> None:
    bpy.types.TOPBAR_MT_file_export.remove(menu_export)
    bpy.utils.unregister_class(HAZE_OT_export_scene)
