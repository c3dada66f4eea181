"""The add-on's Preferences panel: the kernel compile's state, the cache and its Clear button."""

from __future__ import annotations

import bpy

from . import background, bootstrap, kernel_cache, session

ADDON_ID = __package__  # "bl_ext.user_default.haze" as an extension, "haze" or "addon" from a clone
REDRAW_SECONDS = 1.0


class HAZE_OT_clear_kernel_cache(bpy.types.Operator):
    """Delete Haze's compiled kernels (every build's); the next render compiles them again"""

    bl_idname = "haze.clear_kernel_cache"
    bl_label = "Clear Kernel Cache"
    bl_options = {"INTERNAL"}

    def execute(self, context):
        busy = self.busy()
        if busy:
            self.report({"ERROR"}, f"Clear Kernel Cache: {busy}; try again when it has finished")
            return {"CANCELLED"}
        root = bootstrap.haze_cache_root()
        try:
            count, freed = kernel_cache.clear(root)
        except OSError as error:
            self.report({"ERROR"}, f"Clear Kernel Cache: {error}")
            return {"CANCELLED"}
        background.forget()  # "ready" would no longer be true
        self.report({"INFO"}, f"Haze: deleted {count} kernel folders ({kernel_cache.megabytes(freed)}) "
                              f"in {root}")
        return {"FINISHED"}

    @staticmethod
    def busy() -> str:
        """Why clearing now would pull the cache from under a compile or a render, or ''."""
        if background.running():
            return "the kernels are being compiled in the background"
        if session.rendering():
            return "a render is running"
        return ""


class HAZE_OT_compile_kernels(bpy.types.Operator):
    """Compile the kernels of common scenes now, in a background process"""

    bl_idname = "haze.compile_kernels"
    bl_label = "Compile Kernels"
    bl_options = {"INTERNAL"}

    def execute(self, context):
        if background.running():
            self.report({"INFO"}, "Haze: the kernels are already being compiled")
            return {"CANCELLED"}
        job = background.start(asked=True)
        if job is None or job.process is None:
            detail = job.error if job is not None else "not started"
            self.report({"ERROR"}, f"Compile Kernels: {detail}")
            return {"CANCELLED"}
        keep_panel_current()
        return {"FINISHED"}


class HazePreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON_ID

    def draw(self, context) -> None:
        layout = self.layout
        state = background.state()
        box = layout.box()
        box.label(text=kernel_cache.state_text(state), icon=STATE_ICONS.get(state.kind, "INFO"))
        if state.kind in {"failed", "checking", "compiling"}:
            box.label(text=f"Log: {state.log}")
        root = bootstrap.haze_cache_root()
        column = layout.column(align=True)
        column.label(text=f"Kernel cache: {root}")
        column.label(text=f"Size: {kernel_cache.cache_text(root)}")
        row = layout.row()
        compile_button = row.row()
        compile_button.enabled = not background.running()
        compile_button.operator(HAZE_OT_compile_kernels.bl_idname, icon="FILE_REFRESH")
        clear_button = row.row()
        clear_button.enabled = not HAZE_OT_clear_kernel_cache.busy()
        clear_button.operator(HAZE_OT_clear_kernel_cache.bl_idname, icon="TRASH")


STATE_ICONS = {"ready": "CHECKMARK", "failed": "ERROR", "compiling": "SORTTIME", "checking": "SORTTIME"}


def redraw_while_compiling() -> float | None:
    """Timer: keep the panel's seconds counting while the background compile runs."""
    window_manager = getattr(bpy.context, "window_manager", None)
    for window in getattr(window_manager, "windows", []):
        for area in window.screen.areas:
            if area.type == "PREFERENCES":
                area.tag_redraw()
    return REDRAW_SECONDS if background.running() else None


CLASSES = (HAZE_OT_clear_kernel_cache, HAZE_OT_compile_kernels, HazePreferences)


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister() -> None:
    if bpy.app.timers.is_registered(redraw_while_compiling):
        bpy.app.timers.unregister(redraw_while_compiling)
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)


def start_background_compile() -> None:
    """Start compiling the common scenes' kernels, and keep the panel's state current."""
    if background.start(headless=bpy.app.background) is not None:
        keep_panel_current()


def keep_panel_current() -> None:
    """Redraw the preferences once a second while the compile runs (a UI only)."""
    if not bpy.app.background and not bpy.app.timers.is_registered(redraw_while_compiling):
        bpy.app.timers.register(redraw_while_compiling, first_interval=REDRAW_SECONDS)
