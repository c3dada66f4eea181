"""Which of Blender's panels a Haze user sees: every panel whose settings Haze renders, none
whose settings it ignores (run in the installed extension, as a user's Blender has it).

PANELS is the expected choice for every panel that Cycles or Haze shows, by name pattern
(first match wins). A panel that matches nothing fails the test, so a new Blender version's
panels get a decision; EQUIVALENTS names, for each Cycles-only panel whose settings Haze
renders, the panel that shows them with Haze.
"""

from __future__ import annotations

from fnmatch import fnmatch

import pytest

from helpers.blender_runs import blender_fixture

pytestmark = [pytest.mark.bpy]

SHOWN, HIDDEN = True, False

# (pattern, shown with Haze, why). Order matters: the first pattern that matches decides.
PANELS: list[tuple[str, bool, str]] = [
    ("HAZE_*", SHOWN, "Haze's own panels"),
    # Cycles-only panels: their settings are Cycles' (EQUIVALENTS lists the ones Haze shows otherwise).
    ("CYCLES_*", HIDDEN, "Cycles' own settings"),
    ("NODE_CYCLES_*", HIDDEN, "Cycles' own settings"),
    ("CyclesPresetPanel", HIDDEN, "Cycles' presets"),
    # Camera: lens, sensor, clipping, shift, depth of field, display and safe areas.
    ("DATA_PT_camera_dof*", SHOWN, "depth of field and the aperture's shape"),
    ("DATA_PT_camera_stereoscopy", SHOWN, "Blender's multiview (each view rendered)"),
    ("DATA_PT_camera*", SHOWN, "camera settings and viewport display"),
    ("CAMERA_PT_*presets", SHOWN, "camera presets"),
    ("DATA_PT_lens", SHOWN, "lens (the panorama types in HAZE_DATA_PT_panorama)"),
    # Lights: Haze's own panel (radius and spread greyed out), spot shape, light nodes hidden.
    ("DATA_PT_EEVEE_light*", HIDDEN, "EEVEE's light settings; HAZE_DATA_PT_light instead"),
    ("NODE_DATA_PT_EEVEE_light", HIDDEN, "EEVEE's light settings"),
    ("DATA_PT_light", HIDDEN, "replaced by HAZE_DATA_PT_light"),
    ("NODE_DATA_PT_light", HIDDEN, "replaced by HAZE_DATA_PT_light"),
    ("DATA_PT_spot", SHOWN, "spot size and blend"),
    ("DATA_PT_light_animation", SHOWN, "animation"),
    ("DATA_PT_preview", HIDDEN, "Haze renders no light previews"),
    ("DATA_PT_*lightprobe*", HIDDEN, "light probes are EEVEE's"),
    # Object data: meshes, curves, point clouds, volumes, speakers (data, not render settings).
    ("DATA_PT_volume_*", SHOWN, "volume file, grids, render and display settings"),
    ("DATA_PT_context_*", SHOWN, "the datablock selector"),
    ("DATA_PT_custom_props_*", SHOWN, "custom properties"),
    ("DATA_PT_*", SHOWN, "object data (mesh, curves, point cloud, speaker, texture space)"),
    ("NODE_PT_texture_mapping", SHOWN, "texture node mapping"),
    # Materials and worlds: node views, preview, mist.
    ("EEVEE_MATERIAL_PT_context_material", SHOWN, "material slots"),
    ("EEVEE_MATERIAL_PT_surface", SHOWN, "the Surface node view"),
    ("EEVEE_MATERIAL_PT_volume", SHOWN, "the Volume node view"),
    ("EEVEE_MATERIAL_PT_viewport_settings", SHOWN, "viewport display colour"),
    ("MATERIAL_PT_preview", SHOWN, "material preview (Haze renders it)"),
    ("MATERIAL_PT_freestyle_line", SHOWN, "a line style colour, harmless"),
    ("MATERIAL_PT_gpencil*", HIDDEN, "Grease Pencil materials"),
    ("MATERIAL_PT_*", SHOWN, "animation and custom properties"),
    ("EEVEE_WORLD_PT_mist", SHOWN, "the Mist pass's start, depth and falloff"),
    ("EEVEE_WORLD_PT_surface", SHOWN, "the Surface node view"),
    ("EEVEE_WORLD_PT_volume", SHOWN, "the Volume node view"),
    ("EEVEE_*", HIDDEN, "EEVEE's settings"),
    ("WORLD_PT_*", SHOWN, "world selector, animation, custom properties"),
    # Objects and particles.
    ("OBJECT_PT_shadow_terminator", HIDDEN, "Haze has no shadow terminator offsets"),
    ("OBJECT_PT_*", SHOWN, "visibility (hide in renders), shading and custom properties"),
    ("PARTICLE_PT_hair_*", HIDDEN, "hair particles are not rendered (the export warns)"),
    ("PARTICLE_PT_render_path*", HIDDEN, "hair strands are not rendered"),
    ("PARTICLE_PT_*", SHOWN, "particles instance objects and collections"),
    # Render and output.
    ("RENDER_PT_color_management*", SHOWN, "view transform, look, exposure (Blender applies them)"),
    ("RENDER_PT_simplify_greasepencil", HIDDEN, "Grease Pencil is not rendered"),
    ("RENDER_PT_simplify*", SHOWN, "simplify (the depsgraph evaluates with it)"),
    ("RENDER_PT_gpencil", HIDDEN, "Grease Pencil is not rendered"),
    ("RENDER_PT_grease_pencil*", HIDDEN, "Grease Pencil is not rendered"),
    ("RENDER_PT_freestyle", HIDDEN, "Freestyle is not rendered"),
    ("RENDER_PT_post_processing", SHOWN, "compositing and sequencer switches"),
    ("RENDER_PT_*", SHOWN, "output, format, frame range, stamp, encoding, views"),
    ("SEQUENCER_PT_custom_props", SHOWN, "custom properties"),
    ("STRIP_PT_custom_props", SHOWN, "custom properties"),
    ("TEXTURE_PT_*", SHOWN, "textures of modifiers, particles and brushes (the depsgraph evaluates them)"),
    ("VIEWLAYER_PT_freestyle*", HIDDEN, "Freestyle is not rendered"),
    ("VIEWLAYER_PT_layer_passes*", HIDDEN, "EEVEE's passes; HAZE_VIEWLAYER_PT_passes instead"),
    ("VIEWLAYER_PT_layer", SHOWN, "use for rendering, render single layer"),
    ("VIEWLAYER_PT_context_layer", SHOWN, "the view layer selector"),
    ("VIEWLAYER_PT_*", HIDDEN, "EEVEE's, Workbench's or Cycles' view layer settings"),
    ("VIEW3D_PT_*", HIDDEN, "viewport shading of other engines"),
    ("PHYSICS_PT_*", SHOWN, "simulations (their caches are read)"),
]

# Cycles-only panels whose settings Haze renders, and the panel that shows them with Haze.
EQUIVALENTS = {
    "CYCLES_RENDER_PT_sampling": "HAZE_RENDER_PT_sampling",
    "CYCLES_RENDER_PT_light_paths": "HAZE_RENDER_PT_light_paths",
    "CYCLES_RENDER_PT_film": "HAZE_RENDER_PT_film",
    "CYCLES_RENDER_PT_performance": "HAZE_RENDER_PT_performance",
    "CYCLES_RENDER_PT_passes": "HAZE_VIEWLAYER_PT_passes",
    "CYCLES_CAMERA_PT_dof": "DATA_PT_camera_dof",
    "CYCLES_CAMERA_PT_dof_aperture": "DATA_PT_camera_dof_aperture",
    "CYCLES_LIGHT_PT_light": "HAZE_DATA_PT_light",
    "CYCLES_PT_context_material": "EEVEE_MATERIAL_PT_context_material",
    "CYCLES_MATERIAL_PT_surface": "EEVEE_MATERIAL_PT_surface",
    "CYCLES_MATERIAL_PT_volume": "EEVEE_MATERIAL_PT_volume",
    "CYCLES_MATERIAL_PT_preview": "MATERIAL_PT_preview",
    "CYCLES_WORLD_PT_surface": "EEVEE_WORLD_PT_surface",
    "CYCLES_WORLD_PT_volume": "EEVEE_WORLD_PT_volume",
    "CYCLES_WORLD_PT_mist": "EEVEE_WORLD_PT_mist",
}

BODY = r'''
import types

import bpy
import bpy_helpers as H


class Layout:
    """Stands in for a UILayout (the gpu module cannot draw in background mode): records each
    property a panel draws, and fails on one its datablock does not have."""

    def __init__(self, drawn):
        self.drawn = drawn

    def __getattr__(self, name):
        return lambda *args, **kwargs: self  # row, column, label, separator, operator...

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)

    def prop(self, data, name, **kwargs):
        if name not in data.bl_rna.properties:
            raise AttributeError(f"{type(data).__name__} has no property {name!r}")
        self.drawn.append(name)
        return self


class Context:
    def __init__(self, scene, light=None, camera=None):
        self.scene, self.light, self.camera, self.engine = scene, light, camera, "HAZE"
        self.view_layer = scene.view_layers[0]


def draw_haze_panels(ui):
    """Draw each of Haze's panels for every light type, area shape and panorama type."""
    drawn = {}

    def draw(context):
        for cls in ui.CLASSES:
            if cls.poll(context):
                panel = types.SimpleNamespace(layout=Layout(drawn.setdefault(cls.__name__, [])))
                cls.draw(panel, context)  # the plain function, on a stand-in for the Panel

    scene = bpy.context.scene
    draw(Context(scene))
    for kind in ("POINT", "SPOT", "SUN", "AREA"):
        light = bpy.data.lights.new(kind, kind)
        for shape in ("SQUARE", "RECTANGLE", "DISK", "ELLIPSE") if kind == "AREA" else (None,):
            if shape:
                light.shape = shape
            draw(Context(scene, light=light))
    camera = bpy.data.cameras.new("Camera")
    camera.type = "PANO"
    for kind in ("EQUIRECTANGULAR", "FISHEYE_EQUIDISTANT", "FISHEYE_EQUISOLID", "MIRRORBALL",
                 "CENTRAL_CYLINDRICAL"):
        camera.panorama_type = kind
        draw(Context(scene, camera=camera))
    return {name: sorted(set(names)) for name, names in drawn.items()}


def main():
    H.enable_addon()
    ui, camera = H.addon_module("ui"), H.addon_module("export.camera")
    panels = {}
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if isinstance(engines, set) and ("CYCLES" in engines or "HAZE" in engines):
            panels[panel.__name__] = {"haze": "HAZE" in engines, "parent": getattr(panel, "bl_parent_id", "")}
    return {"panels": panels, "drawn": draw_haze_panels(ui),
            "panorama_ui": sorted(getattr(ui, "PANORAMA_SETTINGS", ())),
            "panorama_export": sorted(camera.PANORAMA_TYPES),
            "limits": {name: bpy.context.scene.haze.bl_rna.properties[name].hard_max
                       for name in ("samples", "max_bounces")}}
'''


panels = blender_fixture(BODY, "panels", timeout=600)


def expected(name: str) -> tuple[bool, str] | None:
    for pattern, shown, why in PANELS:
        if fnmatch(name, pattern):
            return shown, why
    return None


def test_every_panel_has_a_decision(panels):
    missing = sorted(name for name in panels["panels"] if expected(name) is None)
    assert not missing, f"panels with no decision in PANELS: {missing}"


def test_haze_shows_exactly_the_panels_it_renders(panels):
    wrong = [f"{name}: expected {'shown' if expected(name)[0] else 'hidden'} ({expected(name)[1]})"
             for name, info in sorted(panels["panels"].items())
             if expected(name) is not None and info["haze"] != expected(name)[0]]
    assert not wrong, "\n".join(wrong)


def test_cycles_settings_haze_renders_have_a_haze_panel(panels):
    found = panels["panels"]
    for cycles_panel, haze_panel in EQUIVALENTS.items():
        assert cycles_panel in found, f"{cycles_panel} is gone from Blender: update EQUIVALENTS"
        assert found.get(haze_panel, {}).get("haze"), f"{cycles_panel}'s settings have no panel with Haze"


def test_the_features_artists_asked_for_are_reachable(panels):
    shown = {name for name, info in panels["panels"].items() if info["haze"]}
    for name in ("DATA_PT_camera_dof", "DATA_PT_camera_dof_aperture", "HAZE_RENDER_PT_film",
                 "EEVEE_WORLD_PT_mist", "HAZE_DATA_PT_panorama", "MATERIAL_PT_preview", "HAZE_DATA_PT_light"):
        assert name in shown
    assert panels["panels"]["HAZE_DATA_PT_panorama"]["parent"] == "DATA_PT_lens"
    assert panels["panorama_ui"] == panels["panorama_export"]  # the panel offers what the export renders


def test_haze_panels_draw_blender_properties(panels):
    """Each panel draws (with every light type and panorama type) and names only properties
    Blender 5.0 has; the settings Haze renders are among them."""
    drawn = panels["drawn"]
    assert set(drawn) >= {"HAZE_RENDER_PT_film", "HAZE_DATA_PT_light", "HAZE_DATA_PT_panorama"}
    assert "film_transparent" in drawn["HAZE_RENDER_PT_film"]
    light = {"energy", "color", "angle", "size", "size_y", "shadow_soft_size", "spread"}
    assert light <= set(drawn["HAZE_DATA_PT_light"])
    panorama = {"panorama_type", "fisheye_fov", "fisheye_lens", "latitude_min"}
    assert panorama <= set(drawn["HAZE_DATA_PT_panorama"])


def test_settings_stop_where_the_renderer_refuses(panels):
    """A value the validator would refuse at F12 cannot be typed into the panel."""
    from renderer.validate.scene import MAX_BOUNCES, MAX_SPP

    assert panels["limits"] == {"samples": MAX_SPP, "max_bounces": MAX_BOUNCES}
