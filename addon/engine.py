"""The Haze render engine (F12 and bpy.ops.render.render).

A render exports the evaluated scene, runs the progressive renderer and shows its image
about once a second; the work is done by session.RenderSession.
"""

from __future__ import annotations

import bpy

from .session import RenderSession


class HazeRenderEngine(bpy.types.RenderEngine):
    bl_idname = "HAZE"
    bl_label = "Haze"
    bl_use_preview = False  # material previews are rendered by EEVEE
    bl_use_shading_nodes_custom = False  # use Blender's standard shader nodes, like Cycles
    bl_use_eevee_viewport = True  # Material Preview in the viewport uses EEVEE

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)

    def render(self, depsgraph) -> None:
        RenderSession(self, depsgraph).run()


def register() -> None:
    bpy.utils.register_class(HazeRenderEngine)


def unregister() -> None:
    bpy.utils.unregister_class(HazeRenderEngine)
