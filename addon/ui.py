"""Haze's Render Properties panels, and Blender's own panels enabled for Haze.

Blender's generic panels (output, format, colour management, camera, lights, material and
world node views...) test `context.engine in COMPAT_ENGINES`; adding "HAZE" to those sets is
how external engines reuse them. Panels that show settings Haze ignores are left out.
"""

from __future__ import annotations

import bpy

ENGINE = "HAZE"

# Blender panels that fit Haze although they are not marked as generic ('BLENDER_RENDER').
EXTRA_PANELS = (
    "EEVEE_MATERIAL_PT_context_material",
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_MATERIAL_PT_volume",
    "EEVEE_WORLD_PT_surface",
    "EEVEE_WORLD_PT_volume",
    "DATA_PT_EEVEE_light",
)

# Generic panels for features Haze does not have.
EXCLUDED_PANELS = {
    "DATA_PT_light",  # replaced by DATA_PT_EEVEE_light, which shows power, colour and size
    "NODE_DATA_PT_light",
    "DATA_PT_preview",
    "RENDER_PT_freestyle",
}
EXCLUDED_PREFIXES = ("VIEWLAYER_PT_freestyle", "DATA_PT_lightprobe", "DATA_PT_context_lightprobe")


def is_reused(panel: type) -> bool:
    name = panel.__name__
    if name in EXCLUDED_PANELS or name.startswith(EXCLUDED_PREFIXES):
        return False
    return name in EXTRA_PANELS or "BLENDER_RENDER" in panel.COMPAT_ENGINES


def reused_panels() -> list[type]:
    panels = []
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if isinstance(engines, set) and is_reused(panel):
            panels.append(panel)
    return panels


class HazeRenderPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context) -> bool:
        return context.engine in cls.COMPAT_ENGINES


class HAZE_RENDER_PT_sampling(HazeRenderPanel, bpy.types.Panel):
    bl_label = "Sampling"

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.haze
        column = layout.column(align=True)
        column.prop(settings, "samples")
        column.prop(settings, "target_error")
        column.prop(settings, "time_limit")
        layout.prop(settings, "seed")
        layout.prop(settings, "use_denoising")


class HAZE_RENDER_PT_light_paths(HazeRenderPanel, bpy.types.Panel):
    bl_label = "Light Paths"

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.haze, "max_bounces")


class HAZE_RENDER_PT_integrator(HazeRenderPanel, bpy.types.Panel):
    bl_label = "Integrator"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.haze
        layout.prop(settings, "sampling")
        column = layout.column(heading="Volumes")
        column.prop(settings, "distance_sampling")
        column.prop(settings, "transmittance")
        column.prop(settings, "equiangular")
        column.prop(settings, "majorant_grid")


class HAZE_RENDER_PT_performance(HazeRenderPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.haze, "workers")
        layout.prop(context.scene.haze, "cluster")
        layout.operator("haze.test_cluster", icon="NETWORK_DRIVE")


class HAZE_VIEWLAYER_PT_passes(HazeRenderPanel, bpy.types.Panel):
    """The passes Haze renders (View Layer > Passes): the toggles are Blender's and Cycles'
    own, so a scene set up for Cycles asks Haze for the same passes."""

    bl_context = "view_layer"
    bl_label = "Passes"

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        view_layer = context.view_layer
        column = layout.column(heading="Data", align=True)
        column.prop(view_layer, "use_pass_combined")
        column.prop(view_layer, "use_pass_z")
        column.prop(view_layer, "use_pass_mist")
        column.prop(view_layer, "use_pass_position")
        column.prop(view_layer, "use_pass_normal")
        cycles = getattr(view_layer, "cycles", None)
        if cycles is not None:
            column.prop(cycles, "denoising_store_passes", text="Denoising Data")
        column = layout.column(heading="Light", align=True)
        column.prop(view_layer, "use_pass_diffuse_color", text="Diffuse Color")
        column.prop(view_layer, "use_pass_glossy_color", text="Glossy Color")
        column.prop(view_layer, "use_pass_transmission_color", text="Transmission Color")
        if cycles is not None:
            column.prop(cycles, "use_pass_volume_direct", text="Volume Direct")
            column.prop(cycles, "use_pass_volume_indirect", text="Volume Indirect")
        column.prop(view_layer, "use_pass_emit", text="Emission")


CLASSES = (
    HAZE_RENDER_PT_sampling,
    HAZE_RENDER_PT_light_paths,
    HAZE_RENDER_PT_integrator,
    HAZE_RENDER_PT_performance,
    HAZE_VIEWLAYER_PT_passes,
)

_enabled_panels: list[type] = []  # Blender panels we added HAZE to, to undo exactly that


def register() -> None:
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    for panel in reused_panels():
        if ENGINE not in panel.COMPAT_ENGINES:
            panel.COMPAT_ENGINES.add(ENGINE)
            _enabled_panels.append(panel)


def unregister() -> None:
    for panel in _enabled_panels:
        panel.COMPAT_ENGINES.discard(ENGINE)
    _enabled_panels.clear()
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
