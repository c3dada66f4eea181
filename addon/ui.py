"""Haze's Render Properties panels, and Blender's own panels enabled for Haze.

Blender's generic panels (output, format, colour management, camera, lights, material and
world node views...) test `context.engine in COMPAT_ENGINES`; adding "HAZE" to those sets is
how external engines reuse them. Every panel whose settings Haze renders is shown; panels
that show only settings Haze ignores are left out, and where Haze renders part of a panel
it has its own (Light, Film, Panorama), the rest greyed out with what Haze does instead.
tests/test_addon_panels.py holds the expected choice for every panel Cycles or Haze shows.
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
    "EEVEE_WORLD_PT_mist",  # the Mist pass's start, depth and falloff
    "MATERIAL_PT_preview",  # Haze renders material previews (engine.bl_use_preview)
    "DATA_PT_camera_dof",  # focus object or distance
    "DATA_PT_camera_dof_aperture",  # f-stop, blades, rotation, ratio
)

# Generic panels for features Haze does not have.
EXCLUDED_PANELS = {
    "DATA_PT_light",  # replaced by HAZE_DATA_PT_light
    "NODE_DATA_PT_light",
    "DATA_PT_preview",
    "RENDER_PT_freestyle",
    "RENDER_PT_gpencil",  # Grease Pencil objects are not rendered
    "RENDER_PT_simplify_greasepencil",
    "PARTICLE_PT_hair_shape",  # hair particles are not rendered (the export says so)
    "PARTICLE_PT_render_path",
    "PARTICLE_PT_render_path_timing",
}
EXCLUDED_PREFIXES = ("VIEWLAYER_PT_freestyle", "DATA_PT_lightprobe", "DATA_PT_context_lightprobe",
                     "RENDER_PT_grease_pencil", "PARTICLE_PT_hair_dynamics")


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


class HAZE_RENDER_PT_film(HazeRenderPanel, bpy.types.Panel):
    bl_label = "Film"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        layout.prop(context.scene.render, "film_transparent", text="Transparent")
        row = layout.row()
        row.active = False
        row.label(text="Pixel filter: box, 1 pixel wide")


class HazeDataPanel:
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "data"
    COMPAT_ENGINES = {ENGINE}


def greyed(layout, data, name: str, note: str, **options) -> None:
    """A setting Haze reads but does not render yet: shown inactive, with what Haze does."""
    column = layout.column()
    column.active = False
    column.prop(data, name, **options)
    column.label(text=note, icon="INFO")


class HAZE_DATA_PT_light(HazeDataPanel, bpy.types.Panel):
    """Blender's light settings as Haze renders them (export/lights.py)."""

    bl_label = "Light"

    @classmethod
    def poll(cls, context) -> bool:
        return context.light is not None and context.engine in cls.COMPAT_ENGINES

    def draw(self, context) -> None:
        layout = self.layout
        light = context.light
        layout.row().prop(light, "type", expand=True)
        layout.use_property_split = True
        layout.use_property_decorate = False
        column = layout.column()
        row = column.row(heading="Temperature")
        row.prop(light, "use_temperature", text="")
        sub = row.row()
        sub.active = light.use_temperature
        sub.prop(light, "temperature", text="")
        column.prop(light, "color", text="Tint" if light.use_temperature else "Color")
        column = layout.column()
        column.prop(light, "energy")
        column.prop(light, "exposure")
        column.prop(light, "normalize")
        column = layout.column()
        if light.type in {"POINT", "SPOT"}:
            greyed(column, light, "shadow_soft_size", "Haze renders point and spot lamps as points",
                   text="Radius")
        elif light.type == "SUN":
            column.prop(light, "angle")
        elif light.type == "AREA":
            column.prop(light, "shape")
            sub = column.column(align=True)
            if light.shape in {"SQUARE", "DISK"}:
                sub.prop(light, "size")
            else:
                sub.prop(light, "size", text="Size X")
                sub.prop(light, "size_y", text="Y")
            greyed(column, light, "spread", "Haze renders every area lamp with 180 degrees spread")


# Blender's panorama types Haze renders (export/camera.py PANORAMA_TYPES), and the camera
# settings each one reads.
PANORAMA_SETTINGS = {
    "EQUIRECTANGULAR": ("latitude_min", "latitude_max", "longitude_min", "longitude_max"),
    "FISHEYE_EQUIDISTANT": ("fisheye_fov",),
    "FISHEYE_EQUISOLID": ("fisheye_lens", "fisheye_fov"),
    "MIRRORBALL": (),
}


class HAZE_DATA_PT_panorama(HazeDataPanel, bpy.types.Panel):
    """The panorama type and its settings (Blender's Lens panel draws them for Cycles only)."""

    bl_label = "Panorama"
    bl_parent_id = "DATA_PT_lens"

    @classmethod
    def poll(cls, context) -> bool:
        camera = context.camera
        return camera is not None and camera.type == "PANO" and context.engine in cls.COMPAT_ENGINES

    def draw(self, context) -> None:
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        camera = context.camera
        layout.prop(camera, "panorama_type")
        if camera.panorama_type not in PANORAMA_SETTINGS:
            layout.label(text="Haze cannot render this panorama type", icon="ERROR")
            return
        column = layout.column(align=True)
        for name in PANORAMA_SETTINGS[camera.panorama_type]:
            column.prop(camera, name)


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
    HAZE_RENDER_PT_film,
    HAZE_DATA_PT_light,
    HAZE_DATA_PT_panorama,
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
