"""The Haze render engine (F12 and bpy.ops.render.render).

A render exports the evaluated scene, runs the progressive renderer and shows its image
about once a second; the work is done by session.RenderSession.
"""

from __future__ import annotations

import bpy

from .passes import requested_passes
from .session import RenderSession


class HazeRenderEngine(bpy.types.RenderEngine):
    bl_idname = "HAZE"
    bl_label = "Haze"
    bl_use_preview = True  # the Material tab's preview and material icons (session.preview_settings)
    bl_use_shading_nodes_custom = False  # use Blender's standard shader nodes, like Cycles
    bl_use_eevee_viewport = True  # Material Preview in the viewport uses EEVEE

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)

    def render(self, depsgraph) -> None:
        RenderSession(self, depsgraph).run()

    def update_render_passes(self, scene=None, renderlayer=None) -> None:
        """Tell Blender which passes a render of this view layer has (the View Layer >
        Passes toggles), so they reach the compositor and multilayer EXRs."""
        for spec in requested_passes(scene, renderlayer):
            self.register_pass(scene, renderlayer, spec.name, len(spec.channels), spec.channels, spec.kind)


def register() -> None:
    bpy.utils.register_class(HazeRenderEngine)


def unregister() -> None:
    bpy.utils.unregister_class(HazeRenderEngine)
