"""Export of Blender scenes to Haze scenes: geometry, camera, lights, materials, world.

One Blender subprocess builds the test scenes, exports them (through the real F12 path for
the main scene, so the render-mode depsgraph is used), saves each export as a Haze scene
folder and reports the warnings; the tests below load those folders and check them against
values computed independently (Blender's own projection, Cycles' formulas).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bench.blender import BlenderRun
from helpers.blender_runs import blender_fixture, blender_result
from renderer.scenefile import load_scene
from renderer.shading.program import BIND_FIELDS

pytestmark = pytest.mark.bpy

BODY = r'''
import math
from dataclasses import replace
import bpy
import bpy_helpers as H
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

OUT = os.getcwd()
captured = {}


class Captured(Exception):
    pass


def capture_render_export():
    """Make F12 stop right after the export and keep the exported scene."""
    export_module = H.addon_module("export.scene")
    original = export_module.export_scene

    def capturing(*args, **kwargs):
        export_module.export_scene = original  # capture once
        captured["result"] = original(*args, **kwargs)
        raise Captured("export captured")
    export_module.export_scene = capturing


def node_material(name):
    material = bpy.data.materials.new(name)
    H.ensure_nodes(material)
    tree = material.node_tree
    tree.nodes.clear()
    return material, tree, tree.nodes.new("ShaderNodeOutputMaterial")


def link(tree, a, b):
    tree.links.new(a, b)


def build_materials():
    m = {}
    m["principled"] = H.principled_material(
        "Principled", Base_Color=(0.8, 0.2, 0.1), Metallic=0.3, Roughness=0.4, IOR=1.45,
        Transmission_Weight=0.2, Alpha=0.9, Emission_Color=(1.0, 0.5, 0.25), Emission_Strength=2.0)
    m["level"] = H.principled_material("SpecularLevel", Specular_IOR_Level=0.25, IOR=1.5)
    # Backfacing mix: red diffuse in front, glossy behind.
    material, tree, out = node_material("TwoSided")
    geo = tree.nodes.new("ShaderNodeNewGeometry")
    red = tree.nodes.new("ShaderNodeBsdfDiffuse"); red.inputs["Color"].default_value = (1, 0, 0, 1)
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy"); glossy.inputs["Roughness"].default_value = 0.3
    mix = tree.nodes.new("ShaderNodeMixShader")
    link(tree, geo.outputs["Backfacing"], mix.inputs[0])
    link(tree, red.outputs[0], mix.inputs[1]); link(tree, glossy.outputs[0], mix.inputs[2])
    link(tree, mix.outputs[0], out.inputs["Surface"])
    m["two_sided"] = material
    # Folded constants: Value 0.25 x 2 -> mix factor 0.5; colour Mix node at 0.25.
    material, tree, out = node_material("Folded")
    value = tree.nodes.new("ShaderNodeValue"); value.outputs[0].default_value = 0.25
    math_node = tree.nodes.new("ShaderNodeMath"); math_node.operation = "MULTIPLY"
    math_node.inputs[1].default_value = 2.0
    link(tree, value.outputs[0], math_node.inputs[0])
    color_mix = tree.nodes.new("ShaderNodeMix"); color_mix.data_type = "RGBA"
    inputs = {s.identifier: s for s in color_mix.inputs}
    inputs["A_Color"].default_value = (1, 0, 0, 1)
    inputs["B_Color"].default_value = (0, 0, 1, 1)
    link(tree, value.outputs[0], inputs["Factor_Float"])
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    link(tree, {s.identifier: s for s in color_mix.outputs}["Result_Color"], diffuse.inputs["Color"])
    emission = tree.nodes.new("ShaderNodeEmission"); emission.inputs["Strength"].default_value = 4.0
    mix = tree.nodes.new("ShaderNodeMixShader")
    link(tree, math_node.outputs[0], mix.inputs[0])
    link(tree, diffuse.outputs[0], mix.inputs[1]); link(tree, emission.outputs[0], mix.inputs[2])
    link(tree, mix.outputs[0], out.inputs["Surface"])
    m["folded"] = material
    # A texture Haze does not compile (Gabor) feeding two inputs: one warning, both inputs
    # keep their own values.
    material = H.principled_material("Textured", Base_Color=(0.1, 0.6, 0.3), Roughness=0.7)
    tree = material.node_tree
    texture = tree.nodes.new("ShaderNodeTexGabor"); texture.name = "Rust Texture"
    bsdf = tree.nodes["Principled BSDF"]
    link(tree, texture.outputs["Value"], bsdf.inputs["Base Color"])
    link(tree, texture.outputs["Intensity"], bsdf.inputs["Roughness"])
    m["textured"] = material
    # A Checker as Mix Shader factor between a diffuse and an emission (the program weighs
    # both per point), and a Noise-mixed volume (homogeneous: folded).
    material, tree, out = node_material("Textured Mix")
    checker = tree.nodes.new("ShaderNodeTexChecker")
    red = tree.nodes.new("ShaderNodeBsdfDiffuse"); red.inputs["Color"].default_value = (1, 0, 0, 1)
    glow = tree.nodes.new("ShaderNodeEmission"); glow.inputs["Strength"].default_value = 2.0
    mix = tree.nodes.new("ShaderNodeMixShader"); mix.name = "Textured Factor"
    link(tree, checker.outputs["Fac"], mix.inputs[0])
    link(tree, red.outputs[0], mix.inputs[1]); link(tree, glow.outputs[0], mix.inputs[2])
    link(tree, mix.outputs[0], out.inputs["Surface"])
    noise = tree.nodes.new("ShaderNodeTexNoise"); noise.name = "Fog Noise"
    scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    absorb = tree.nodes.new("ShaderNodeVolumeAbsorption")
    vmix = tree.nodes.new("ShaderNodeMixShader")
    link(tree, noise.outputs["Fac"], vmix.inputs[0])
    link(tree, scatter.outputs[0], vmix.inputs[1]); link(tree, absorb.outputs[0], vmix.inputs[2])
    link(tree, vmix.outputs[0], out.inputs["Volume"])
    m["textured_mix"] = material
    # Principled with a textured Transmission Weight: glass weighted by t, the rest by 1 - t.
    material = H.principled_material("Textured Glass", Base_Color=(0.9, 0.9, 0.9), Roughness=0.0)
    tree = material.node_tree
    gradient = tree.nodes.new("ShaderNodeTexGradient")
    link(tree, gradient.outputs["Fac"], tree.nodes["Principled BSDF"].inputs["Transmission Weight"])
    m["textured_glass"] = material
    # Fog: Volume Scatter + Volume Absorption, no surface.
    material, tree, out = node_material("Fog")
    scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    scatter.inputs["Color"].default_value = (0.9, 0.8, 0.7, 1); scatter.inputs["Density"].default_value = 2.0
    scatter.inputs["Anisotropy"].default_value = 0.4
    absorb = tree.nodes.new("ShaderNodeVolumeAbsorption")
    absorb.inputs["Color"].default_value = (0.5, 0.6, 0.7, 1); absorb.inputs["Density"].default_value = 0.5
    add = tree.nodes.new("ShaderNodeAddShader")
    link(tree, scatter.outputs[0], add.inputs[0]); link(tree, absorb.outputs[0], add.inputs[1])
    link(tree, add.outputs[0], out.inputs["Volume"])
    m["fog"] = material
    # Principled Volume with emission.
    material, tree, out = node_material("Smoke")
    volume = tree.nodes.new("ShaderNodeVolumePrincipled")
    volume.inputs["Color"].default_value = (0.5, 0.6, 0.7, 1); volume.inputs["Density"].default_value = 3.0
    volume.inputs["Absorption Color"].default_value = (0.2, 0.3, 0.4, 1)
    volume.inputs["Emission Strength"].default_value = 2.0
    volume.inputs["Emission Color"].default_value = (1.0, 0.5, 0.0, 1)
    link(tree, volume.outputs[0], out.inputs["Volume"])
    m["smoke"] = material
    m["plain"] = H.principled_material("Plain", Base_Color=(0.3, 0.4, 0.5), Specular_IOR_Level=0.0)
    material, tree, out = node_material("Empty Output")
    m["empty"] = material
    # A node group computing 0.5 x its input, a muted Math node (passes its first input
    # through) and an unsupported closure (Translucent BSDF: diffuse fallback of its colour).
    group = bpy.data.node_groups.new("Halve", "ShaderNodeTree")
    group.interface.new_socket("Value", in_out="INPUT", socket_type="NodeSocketFloat")
    group.interface.new_socket("Value", in_out="OUTPUT", socket_type="NodeSocketFloat")
    group_in = group.nodes.new("NodeGroupInput"); group_out = group.nodes.new("NodeGroupOutput")
    halve = group.nodes.new("ShaderNodeMath")
    halve.operation, halve.inputs[1].default_value = "MULTIPLY", 0.5
    group.links.new(group_in.outputs[0], halve.inputs[0])
    group.links.new(halve.outputs[0], group_out.inputs[0])
    material, tree, out = node_material("Grouped")
    group_node = tree.nodes.new("ShaderNodeGroup"); group_node.node_tree = group
    group_node.inputs[0].default_value = 0.8
    muted = tree.nodes.new("ShaderNodeMath"); muted.operation = "POWER"; muted.mute = True
    link(tree, group_node.outputs[0], muted.inputs[0])
    glossy = tree.nodes.new("ShaderNodeBsdfGlossy")
    link(tree, muted.outputs[0], glossy.inputs["Roughness"])
    translucent = tree.nodes.new("ShaderNodeBsdfTranslucent"); translucent.name = "Leaf"
    translucent.inputs["Color"].default_value = (0.2, 0.7, 0.1, 1)
    add = tree.nodes.new("ShaderNodeAddShader")
    link(tree, glossy.outputs[0], add.inputs[0]); link(tree, translucent.outputs[0], add.inputs[1])
    link(tree, add.outputs[0], out.inputs["Surface"])
    m["grouped"] = material
    return m


def cube(name, center, half, material, skip_face=None):
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return H.new_object(name, [(center[0] + sx * half, center[1] + sy * half, center[2] + sz * half)
                               for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)],
                        [f for i, f in enumerate(faces) if i != skip_face], material)


def build_main_scene():
    scene = bpy.context.scene
    for obj in list(scene.collection.all_objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    m = build_materials()
    for key in ("principled", "level", "two_sided", "folded", "textured", "plain", "empty", "grouped",
                "textured_glass"):
        H.floor_plane(f"Plane {key}", 0.5, m[key], z=-5.0)
    cube("Textured Mix Box", (6, 0, 0), 0.5, m["textured_mix"])
    cube("Fog Box", (0, 0, 0), 1.0, m["fog"])
    cube("Smoke Box", (3, 0, 0), 0.5, m["smoke"])
    cube("Open Box", (0, 3, 0), 0.5, m["fog"], skip_face=1)
    subdivided = cube("Subdivided", (0, -3, 0), 0.5, None)
    modifier = subdivided.modifiers.new("Subdivision", "SUBSURF")
    modifier.levels, modifier.render_levels = 1, 2
    mirrored = cube("Mirrored", (0, 0, 5), 0.5, None); mirrored.scale = (-1, 1, 1)
    hidden = cube("Hidden", (5, 5, 5), 0.5, None); hidden.hide_render = True
    H.uv_sphere("Sphere", (-3, 0, 0), 0.5, None, rings=8, segments=16)
    # A material as bpy.data.materials.new() makes it, and an object whose only slot is empty.
    H.floor_plane("Plane new default", 0.5, bpy.data.materials.new("New Default"), z=-6.0)
    empty_slot = cube("Empty Slot", (0, 6, 0), 0.5, None); empty_slot.data.materials.append(None)
    two = cube("TwoMaterials", (6, 0, 0), 0.5, m["principled"]); two.data.materials.append(m["plain"])
    for index, polygon in enumerate(two.data.polygons):
        polygon.material_index = index % 2
    text_data = bpy.data.curves.new("Text", "FONT"); text_data.body = "Hz"
    text = bpy.data.objects.new("Text", text_data); scene.collection.objects.link(text)
    # Two instances of a collection holding one cube.
    source = bpy.data.collections.new("Source")
    item = bpy.data.objects.new("Item", cube("tmp", (0, 0, 0), 0.25, None).data)
    bpy.data.objects.remove(bpy.data.objects["tmp"], do_unlink=True)
    source.objects.link(item)
    for i, x in enumerate((10.0, 12.0)):
        empty = bpy.data.objects.new(f"Instancer{i}", None)
        empty.instance_type = "COLLECTION"; empty.instance_collection = source
        empty.location = (x, 0, 0); scene.collection.objects.link(empty)
    H.add_light("POINT", "Point", (1, 2, 3), energy=100.0, color=(1.0, 0.5, 0.25), exposure=1.0,
                shadow_soft_size=0.0)
    H.add_light("POINT", "Soft Point", (1, 2, 3), energy=10.0, shadow_soft_size=0.25)
    H.add_light("SPOT", "Spot", (0, 0, 4), (30, 0, 0), energy=50.0, spot_size=math.radians(60),
                spot_blend=0.2, shadow_soft_size=0.0)
    H.add_light("SUN", "Sun", (0, 0, 10), (0, 45, 0), energy=3.0, angle=math.radians(0.5))
    square = H.add_light("AREA", "Square", (0, 0, 3), energy=40.0, size=2.0); square.scale = (0.5, 0.5, 1)
    H.add_light("AREA", "Disk", (2, 0, 3), energy=40.0, shape="DISK", size=1.0)
    H.add_light("AREA", "Unnormalized", (4, 0, 3), energy=40.0, size=2.0, normalize=False)
    H.add_light("AREA", "Zero", (6, 0, 3), energy=40.0, size=0.0)
    camera_data = bpy.data.cameras.new("Camera")
    camera = bpy.data.objects.new("Camera", camera_data); camera.location = (0, -10, 1)
    camera.rotation_euler = (math.radians(90), 0, 0); scene.collection.objects.link(camera)
    scene.camera = camera
    world = bpy.data.worlds.new("Sky World"); H.ensure_nodes(world)
    tree = world.node_tree
    background = tree.nodes["Background"]
    background.inputs["Color"].default_value = (0.1, 0.2, 0.3, 1)
    background.inputs["Strength"].default_value = 2.0
    sky = tree.nodes.new("ShaderNodeTexSky"); sky.name = "Sky Texture"
    tree.links.new(sky.outputs[0], background.inputs["Color"])
    world_scatter = tree.nodes.new("ShaderNodeVolumeScatter")
    world_scatter.inputs["Density"].default_value = 0.01
    tree.links.new(world_scatter.outputs[0], tree.nodes["World Output"].inputs["Volume"])
    scene.world = world
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 8, 8, 100
    return scene


def save(result, name):
    from renderer.scenefile import save_scene
    folder = os.path.join(OUT, name)
    save_scene(result.scene, folder)
    return {"folder": folder, "warnings": result.warnings, "light_names": result.light_names}


def export_viewport():
    export_scene = H.addon_module("export.scene").export_scene
    return export_scene(bpy.context.evaluated_depsgraph_get(), render_depsgraph=False)


def camera_cases(scene):
    """Exported cameras with Blender's own projection of test points (the oracle)."""
    camera = scene.camera
    camera.location = (0.3, -6.0, 1.2)
    camera.rotation_euler = (math.radians(80), math.radians(5), math.radians(10))
    camera.scale = (2.0, 2.0, 2.0)
    points = [(0.0, 0.0, 0.0), (0.5, 1.0, 1.5), (-1.0, 0.5, 2.0), (1.0, -1.0, 0.2)]
    cases = []
    for fit, (w, h, percent), shift in (("AUTO", (200, 100, 50), (0.0, 0.0)),
                                        ("AUTO", (100, 200, 100), (0.1, -0.05)),
                                        ("HORIZONTAL", (100, 200, 100), (0.1, 0.2)),
                                        ("VERTICAL", (300, 200, 100), (-0.1, 0.05))):
        camera.data.sensor_fit = fit
        camera.data.sensor_width, camera.data.sensor_height, camera.data.lens = 36.0, 20.0, 40.0
        camera.data.shift_x, camera.data.shift_y = shift
        scene.render.resolution_x, scene.render.resolution_y = w, h
        scene.render.resolution_percentage = percent
        bpy.context.view_layer.update()
        result = export_viewport()
        frame = [list(world_to_camera_view(scene, camera, Vector(p)))[:2] for p in points]
        case = save(result, f"camera_{len(cases)}")
        case.update(points=points, frame=frame, size=[w * percent // 100, h * percent // 100])
        cases.append(case)
    scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = 8, 8, 100
    return cases


def error_cases(scene):
    ExportError = H.addon_module("export.messages").ExportError
    errors = {}
    camera = scene.camera
    camera.data.type = "PANO"
    camera.data.panorama_type = "CENTRAL_CYLINDRICAL"
    try:
        export_viewport()
    except ExportError as error:
        errors["cylindrical"] = str(error)
    camera.data.type = "PERSP"
    scene.camera = None
    try:
        export_viewport()
    except ExportError as error:
        errors["no_camera"] = str(error)
    scene.camera = camera
    return errors


def main():
    H.enable_addon()
    capture_render_export()
    scene = build_main_scene()
    scene.render.engine = "HAZE"
    render_error = ""
    try:
        bpy.ops.render.render()
    except RuntimeError as error:  # the capture stops the render with an error report
        render_error = str(error)
    report = {"render_error": render_error, "main": save(captured["result"], "main")}
    report["viewport"] = save(export_viewport(), "viewport")
    report["cameras"] = camera_cases(scene)
    report["errors"] = error_cases(scene)
    return report
'''


def with_scenes(run: BlenderRun, folder: Path) -> dict:
    """The run's report with the two scenes it exported, loaded."""
    report = run.result
    report["main_scene"] = load_scene(report["main"]["folder"])
    report["viewport_scene"] = load_scene(report["viewport"]["folder"])
    return report


exported = blender_fixture(BODY, "export", timeout=600, read=with_scenes)


def mesh(scene, name):
    matches = [m for m in scene.meshes if m.name == name]
    assert matches, f"no mesh {name!r} in {[m.name for m in scene.meshes]}"
    return matches[0]


def material(scene, name):
    matches = [m for m in scene.materials if m.name == name]
    assert matches, f"no material {name!r} in {[m.name for m in scene.materials]}"
    return matches[0]


def lobes_by_kind(mat):
    return {lobe.kind: lobe for lobe in mat.lobes}


def signed_volume(m) -> float:
    v = m.vertices.astype(np.float64)[m.indices]
    return float(np.einsum("ij,ij->i", v[:, 0], np.cross(v[:, 1], v[:, 2])).sum() / 6.0)


def test_render_capture_happened(exported):
    assert "export captured" in exported["render_error"]


def test_render_depsgraph_applies_modifiers_and_skips_hidden(exported):
    scene = exported["main_scene"]
    names = {m.name for m in scene.meshes}
    assert "Hidden" not in names
    # Subdivision render level 2 on a cube: 6 x 4^2 quads = 192 triangles.
    assert mesh(scene, "Subdivided").indices.shape == (192, 3)
    # The viewport export (operator) uses the viewport level 1 and also skips hide_render objects.
    viewport = exported["viewport_scene"]
    assert mesh(viewport, "Subdivided").indices.shape == (48, 3)
    assert "Hidden" not in {m.name for m in viewport.meshes}


def test_mirrored_object_keeps_outward_fronts(exported):
    scene = exported["main_scene"]
    assert signed_volume(mesh(scene, "Mirrored")) == pytest.approx(1.0, rel=1e-5)
    assert signed_volume(mesh(scene, "Subdivided")) > 0


def test_instances_are_merged_per_instancer_and_placed(exported):
    scene = exported["main_scene"]
    for name, x in (("Instancer0/Item", 10.0), ("Instancer1/Item", 12.0)):
        m = mesh(scene, name)
        assert m.indices.shape == (12, 3)
        assert m.vertices[:, 0].mean() == pytest.approx(x, abs=1e-5)


def test_smooth_sphere_has_radial_normals(exported):
    sphere = mesh(exported["main_scene"], "Sphere")
    assert sphere.normals is not None
    radial = sphere.vertices - np.array([-3.0, 0.0, 0.0], np.float32)
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    assert np.min(np.einsum("ij,ij->i", radial, sphere.normals)) > 0.999
    assert mesh(exported["main_scene"], "Subdivided").normals is None  # flat shaded


def test_material_ids_follow_slots_and_text_is_meshed(exported):
    scene = exported["main_scene"]
    two = mesh(scene, "TwoMaterials")
    assert two.materials == ["Principled", "Plain"]
    # Each quad becomes two triangles with its face's slot: faces alternate 0, 1.
    assert list(two.material_ids) == [0, 0, 1, 1] * 3
    assert mesh(scene, "Text").indices.shape[0] > 10
    assert mesh(scene, "Instancer0/Item").materials == ["Haze Default Surface"]
    assert mesh(scene, "Empty Slot").materials == ["Haze Default Surface"]


def test_objects_without_a_material_get_a_new_materials_surface(exported):
    """Cycles renders an object without a material (or with an empty slot) exactly as one
    with a material fresh from bpy.data.materials.new(): a default Principled BSDF."""
    scene = exported["main_scene"]
    default, new = material(scene, "Haze Default Surface"), material(scene, "New Default")
    assert [lobe.kind for lobe in default.lobes] == ["plastic"]
    assert replace(default, name=new.name) == new


def project(camera, film, point):
    """Frame coordinates (0..1, y up) of a world point through an exported Haze camera."""
    to_camera = np.linalg.inv(camera.to_world)
    p = to_camera @ np.array([*point, 1.0])
    x, y = p[0] / -p[2], p[1] / -p[2]
    t = math.tan(math.radians(camera.fov) / 2.0)
    aspect = film.width / film.height
    half = (t, t / aspect) if camera.fov_axis == "x" else (t * aspect, t)
    shift = np.array(camera.shift) * 2.0 * max(half)
    return [((x - shift[0]) / half[0] + 1.0) / 2.0, ((y - shift[1]) / half[1] + 1.0) / 2.0]


def test_camera_matches_blender_projection(exported):
    for case in exported["cameras"]:
        scene = load_scene(case["folder"])
        assert [scene.film.width, scene.film.height] == case["size"]
        for point, expected in zip(case["points"], case["frame"]):
            assert project(scene.camera, scene.film, point) == pytest.approx(expected, abs=1e-5), case


def test_camera_errors_name_the_problem(exported):
    errors = exported["errors"]
    assert "Object 'Camera'" in errors["cylindrical"] and "central cylindrical" in errors["cylindrical"]
    assert "no active camera" in errors["no_camera"]


def lights_by_name(exported):
    scene = exported["main_scene"]
    return dict(zip(exported["main"]["light_names"], scene.lights))


def test_point_and_spot_lights_in_cycles_units(exported):
    lights = lights_by_name(exported)
    point = lights["Point"]
    # 100 W x colour x 2^exposure(1) / (4 pi) W/sr.
    expected = 100.0 * 2.0 / (4.0 * math.pi) * np.array([1.0, 0.5, 0.25])
    assert point.intensity == pytest.approx(tuple(expected), rel=1e-6)
    assert point.position == pytest.approx((1.0, 2.0, 3.0))
    spot = lights["Spot"]
    assert spot.intensity == pytest.approx((50.0 / (4.0 * math.pi),) * 3, rel=1e-6)
    assert spot.spot_size == pytest.approx(60.0) and spot.blend == pytest.approx(0.2)
    # Rotated 30 degrees about X: the cone axis -Z turns toward +Y.
    angle = math.radians(30)
    assert spot.direction == pytest.approx((0.0, math.sin(angle), -math.cos(angle)), abs=1e-6)


def test_sun_light(exported):
    sun = lights_by_name(exported)["Sun"]
    assert sun.irradiance == pytest.approx((3.0, 3.0, 3.0))
    assert sun.angle == pytest.approx(0.5)
    half = math.radians(45)
    assert sun.direction == pytest.approx((math.sin(half), 0.0, math.cos(half)), abs=1e-6)


def area_emitter(scene, name):
    m = mesh(scene, f"{name} (area light)")
    mat = material(scene, m.materials[0])
    v = m.vertices.astype(np.float64)[m.indices]
    normals = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    return m, mat, 0.5 * np.linalg.norm(normals, axis=1).sum(), normals


def test_area_lights_are_one_sided_emitters_with_cycles_radiance(exported):
    scene = exported["main_scene"]
    _, square, area, normals = area_emitter(scene, "Square")
    assert area == pytest.approx(1.0, rel=1e-6)  # 2 m square scaled by 0.5
    assert square.emission == pytest.approx((40.0 / math.pi,) * 3, rel=1e-6)  # P / (pi A)
    assert square.emission_sides == "front"
    # A Cycles light lets rays through: a clear transparent lobe on both faces.
    lobes = [(lobe.kind, lobe.color, lobe.sides) for lobe in square.lobes]
    assert lobes == [("transparent", (1, 1, 1), "both")]
    assert np.all(normals[:, 2] < 0)  # emits along the light's -Z
    _, disk, disk_area, _ = area_emitter(scene, "Disk")
    assert disk_area == pytest.approx(math.pi / 4.0, rel=1e-6)
    assert disk.emission == pytest.approx((40.0 / (math.pi * math.pi / 4.0),) * 3, rel=1e-6)
    _, unnormalized, _, _ = area_emitter(scene, "Unnormalized")
    assert unnormalized.emission == pytest.approx((40.0 / math.pi,) * 3, rel=1e-6)


def test_zero_size_area_light_and_soft_point_are_warned(exported):
    warnings = exported["main"]["warnings"]
    assert "Object 'Zero': area light has zero size, so it emits nothing; it is skipped" in warnings
    assert not any(m.name.startswith("Zero") for m in exported["main_scene"].meshes)
    assert any(w.startswith("Object 'Soft Point': radius 0.25 m is ignored") for w in warnings)


def test_principled_bsdf_follows_cycles_layering(exported):
    mat = material(exported["main_scene"], "Principled")
    lobes = lobes_by_kind(mat)
    alpha, metallic, transmission = 0.9, 0.3, 0.2
    assert lobes["transparent"].weight == pytest.approx((1 - alpha,) * 3)
    metal = lobes["rough_conductor"]
    assert metal.weight == pytest.approx((alpha * metallic,) * 3)
    assert metal.color == pytest.approx((0.8, 0.2, 0.1)) and metal.roughness == pytest.approx(0.4)
    assert metal.fresnel == "f82" and metal.tint == pytest.approx((1.0, 1.0, 1.0))  # F0 = base, F82 tint
    assert metal.multiscatter  # the node's default distribution, Multiscatter GGX
    glass = lobes["dielectric"]
    assert glass.weight == pytest.approx((alpha * (1 - metallic) * transmission,) * 3)
    # Cycles tints the refraction by sqrt(base) and leaves the reflection white.
    assert glass.color == pytest.approx(tuple(np.sqrt([0.8, 0.2, 0.1])), rel=1e-6)
    assert glass.tint == pytest.approx((1.0, 1.0, 1.0))
    assert glass.ior == pytest.approx(1.45)
    base = lobes["plastic"]
    assert base.weight == pytest.approx((alpha * (1 - metallic) * (1 - transmission),) * 3)
    assert base.ior == pytest.approx(1.45) and base.color == pytest.approx((0.8, 0.2, 0.1))
    assert base.multiscatter and base.tint == pytest.approx((1.0, 1.0, 1.0))  # Specular Tint's default
    assert mat.emission == pytest.approx((alpha * 2.0, alpha * 1.0, alpha * 0.5))
    assert mat.emission_sides == "both"
    # Specular IOR Level 0.25 halves F0 = ((n-1)/(n+1))^2 of IOR 1.5.
    level = lobes_by_kind(material(exported["main_scene"], "SpecularLevel"))["plastic"]
    f0 = 0.5 * ((1.5 - 1) / (1.5 + 1)) ** 2
    assert level.ior == pytest.approx((1 + math.sqrt(f0)) / (1 - math.sqrt(f0)), rel=1e-6)
    warnings = exported["main"]["warnings"]
    assert any("Material 'Principled', node 'Principled BSDF': rough transmission" in w for w in warnings)


def test_backfacing_mix_splits_faces(exported):
    mat = material(exported["main_scene"], "TwoSided")
    summary = sorted((lobe.kind, lobe.sides) for lobe in mat.lobes)
    assert summary == [("diffuse", "front"), ("rough_conductor", "back")]


def test_value_math_and_mix_nodes_are_folded(exported):
    mat = material(exported["main_scene"], "Folded")
    (diffuse,) = mat.lobes
    assert diffuse.weight == pytest.approx((0.5, 0.5, 0.5))  # mix factor 0.25 x 2
    assert diffuse.color == pytest.approx((0.75, 0.0, 0.25))  # red -> blue at 0.25
    assert mat.emission == pytest.approx((2.0, 2.0, 2.0))  # 4 x 0.5
    # Emission is on both faces, so the surface stays opaque where it has lobes: no black filler.
    assert diffuse.sides == "both"


def test_unsupported_node_warns_once_and_uses_socket_values(exported):
    warnings = [w for w in exported["main"]["warnings"] if "Rust Texture" in w]
    assert warnings == ["Material 'Textured', node 'Rust Texture': Gabor Texture nodes are not supported "
                        "by Haze; the inputs it feeds use their own values"]
    plastic = lobes_by_kind(material(exported["main_scene"], "Textured"))["plastic"]
    assert plastic.color == pytest.approx((0.1, 0.6, 0.3)) and plastic.roughness == pytest.approx(0.7)


def test_textured_mix_factor_is_a_program_for_lobes_and_emission_volume_uses_the_socket_value(exported):
    scene = exported["main_scene"]
    mat = material(scene, "Textured Mix")
    assert mat.program is not None and len(mat.program.code) > 0
    assert mat.program.attributes == ["generated"]  # the Checker's default coordinates
    emission_field = BIND_FIELDS.index("emission")
    rows = [tuple(int(v) for v in row) for row in mat.program.bindings]
    assert {row[4] for row in rows if row[1] != emission_field} == {1}  # lobe weight scales
    # One emission row (no lobe) sets the radiance per point: 2 x the checker's factor.
    assert [(row[0], row[4]) for row in rows if row[1] == emission_field] == [(-1, 0)]
    assert mat.emission == pytest.approx((1.0, 1.0, 1.0))  # light sampling's reference radiance
    assert not any("emission cannot vary" in w for w in exported["main"]["warnings"])
    box = mesh(scene, "Textured Mix Box")
    assert box.attributes and box.attributes[0].name == "generated"
    assert box.attributes[0].values.shape == (12, 3, 3)
    generated = box.attributes[0].values
    assert generated.min() == pytest.approx(0.0) and generated.max() == pytest.approx(1.0)  # texture space
    medium = {m.name: m for m in scene.media}[box.medium]
    assert medium.sigma_s == pytest.approx((0.4, 0.4, 0.4))  # Fac 0.5 x colour 0.8 x density 1 (folded)
    warnings = exported["main"]["warnings"]
    assert any("'Fog Noise': Noise Texture nodes are not supported" in w for w in warnings)
    assert mesh(scene, "Plane plain").attributes == []  # constant materials export no attributes


def test_textured_transmission_weighs_glass_and_the_layer_under_it(exported):
    mat = material(exported["main_scene"], "Textured Glass")
    kinds = [lobe.kind for lobe in mat.lobes]
    assert kinds == ["dielectric", "plastic"]
    assert [lobe.weight for lobe in mat.lobes] == [(1.0, 1.0, 1.0)] * 2  # the program scales them
    rows = {int(row[0]): row for row in mat.program.bindings}
    assert set(rows) == {0, 1} and all(int(r[4]) == 1 for r in rows.values())  # weight scales
    assert rows[0][3] != rows[1][3]  # t and 1 - t


def test_volume_only_material_is_an_interface_with_cycles_coefficients(exported):
    scene = exported["main_scene"]
    fog = material(scene, "Fog")
    assert fog.lobes == [] and fog.emission == (0.0, 0.0, 0.0)
    box = mesh(scene, "Fog Box")
    medium = {m.name: m for m in scene.media}[box.medium]
    assert medium.sigma_s == pytest.approx((1.8, 1.6, 1.4))  # colour x density
    assert medium.sigma_a == pytest.approx((0.25, 0.2, 0.15))  # (1 - colour) x density
    assert medium.g == pytest.approx(0.4)
    smoke = {m.name: m for m in scene.media}[mesh(scene, "Smoke Box").medium]
    color, absorption = np.array([0.5, 0.6, 0.7]), np.array([0.2, 0.3, 0.4])
    assert smoke.sigma_s == pytest.approx(tuple(3.0 * color))
    assert smoke.sigma_a == pytest.approx(tuple(3.0 * (1 - color) * (1 - np.sqrt(absorption))), rel=1e-6)
    assert smoke.emission == pytest.approx((2.0, 1.0, 0.0))  # not scaled by density


def test_plain_and_empty_materials(exported):
    scene = exported["main_scene"]
    (plain,) = material(scene, "Plain").lobes  # Specular IOR Level 0: no specular layer
    assert plain.kind == "diffuse" and plain.color == pytest.approx((0.3, 0.4, 0.5))
    (black,) = material(scene, "Empty Output").lobes
    assert black.color == (0.0, 0.0, 0.0) and black.sides == "both"


def test_open_volume_mesh_is_warned(exported):
    warnings = exported["main"]["warnings"]
    assert any(w.startswith("Object 'Open Box': encloses the volume 'Fog (volume)' but is not closed (4 open")
               for w in warnings), warnings
    assert not any(w.startswith("Object 'Fog Box'") for w in warnings)


def test_world_background_volume_and_unsupported_texture(exported):
    scene = exported["main_scene"]
    assert scene.environment.radiance == pytest.approx((0.2, 0.4, 0.6))  # socket colour x strength
    world_medium = {m.name: m for m in scene.media}[scene.medium]
    assert world_medium.sigma_s == pytest.approx((0.008, 0.008, 0.008))  # 0.8 x 0.01
    assert any(w.startswith("World 'Sky World', node 'Sky Texture': Sky Texture nodes are not supported")
               for w in exported["main"]["warnings"])


def test_groups_muted_nodes_and_unsupported_closures(exported):
    lobes = lobes_by_kind(material(exported["main_scene"], "Grouped"))
    assert lobes["rough_conductor"].roughness == pytest.approx(0.4)  # 0.8 halved; the muted POWER passes it
    assert lobes["rough_conductor"].fresnel == "constant"  # Glossy BSDF: the colour at every angle
    assert lobes["diffuse"].color == pytest.approx((0.2, 0.7, 0.1))  # Translucent's fallback
    assert "Material 'Grouped', node 'Leaf': Translucent BSDF shaders are not supported by Haze; " \
           "rendered as a Diffuse BSDF of its Color" in exported["main"]["warnings"]


REGISTER_BODY = r'''
import bpy
import bpy_helpers as H


def engine_selectable():
    render = bpy.context.scene.render
    previous = render.engine
    try:
        render.engine = "HAZE"
    except TypeError:  # not a registered engine
        return False
    selected = render.engine == "HAZE"
    render.engine = previous
    return selected


def compat(name):
    return "HAZE" in getattr(bpy.types, name).COMPAT_ENGINES


def state():
    return {
        "engine": engine_selectable(),
        "settings": hasattr(bpy.types.Scene, "haze"),
        "operator": hasattr(bpy.types, "EXPORT_SCENE_OT_haze"),
        "panels": {name: compat(name) for name in ("RENDER_PT_format", "RENDER_PT_color_management",
                                                   "DATA_PT_lens", "EEVEE_MATERIAL_PT_surface",
                                                   "EEVEE_WORLD_PT_volume", "DATA_PT_camera_dof",
                                                   "DATA_PT_EEVEE_light", "DATA_PT_light",
                                                   "RENDER_PT_freestyle")},
        "own_panel": hasattr(bpy.types, "HAZE_RENDER_PT_sampling"),
    }


def main():
    addon = H.enable_addon()  # registers it
    registered = state()
    addon.unregister()
    unregistered = state()
    addon.register()  # a second cycle works too (add-on disabled and enabled again)
    again = state()
    addon.unregister()
    return {"registered": registered, "unregistered": unregistered, "again": again}
'''


def test_register_and_unregister_cleanly(tmp_path):
    run = blender_result(REGISTER_BODY, tmp_path, timeout=300, compiles=False)
    registered, unregistered = run.result["registered"], run.result["unregistered"]
    assert all(registered[key] for key in ("engine", "settings", "own_panel", "operator"))
    assert registered["panels"] == {"RENDER_PT_format": True, "RENDER_PT_color_management": True,
                                    "DATA_PT_lens": True, "EEVEE_MATERIAL_PT_surface": True,
                                    "EEVEE_WORLD_PT_volume": True, "DATA_PT_camera_dof": True,
                                    # Haze's own Light panel (HAZE_DATA_PT_light) replaces both:
                                    "DATA_PT_EEVEE_light": False, "DATA_PT_light": False,
                                    "RENDER_PT_freestyle": False}
    assert not any(unregistered[key] for key in ("engine", "settings", "own_panel", "operator"))
    assert not any(unregistered["panels"].values())
    assert run.result["again"] == registered
